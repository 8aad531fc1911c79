//! Flash and static RAM use of a firmware ELF, as `size` reports them (text + data, data + bss).

use object::{Object, ObjectSection, SectionKind};
use std::fmt;
use std::path::Path;

/// Flash and static RAM an image may use.
pub struct Budget {
    pub flash_bytes: u64,
    pub ram_bytes: u64,
}

/// The board firmware without the serial console.
pub const DEFAULT_BUDGET: Budget = Budget {
    flash_bytes: 32 * 1024,
    ram_bytes: 16 * 1024,
};
/// With the serial console (`console` feature): command parsing, validation on the target and
/// the recipe flash driver.
pub const CONSOLE_BUDGET: Budget = Budget {
    flash_bytes: 64 * 1024,
    ram_bytes: 16 * 1024,
};

/// Start of RAM on the STM32G474RE (`memory.x`).
const RAM_ORIGIN: u64 = 0x2000_0000;

pub struct SizeReport {
    pub flash_bytes: u64,
    pub ram_bytes: u64,
}

/// Flash holds every allocated section with contents (code, read-only data and the initial
/// values of `.data`); RAM holds every allocated section placed at or above `RAM_ORIGIN`.
pub fn measure(elf: &Path) -> Result<SizeReport, String> {
    let bytes =
        std::fs::read(elf).map_err(|error| format!("cannot read {}: {error}", elf.display()))?;
    let file = object::File::parse(&*bytes)
        .map_err(|error| format!("{} is not an ELF file: {error}", elf.display()))?;
    let mut report = SizeReport {
        flash_bytes: 0,
        ram_bytes: 0,
    };
    for section in file.sections() {
        let in_ram = section.address() >= RAM_ORIGIN;
        match section.kind() {
            SectionKind::Text | SectionKind::ReadOnlyData | SectionKind::ReadOnlyString => {
                report.flash_bytes += section.size();
            }
            SectionKind::Data => {
                report.flash_bytes += section.size();
                if in_ram {
                    report.ram_bytes += section.size();
                }
            }
            SectionKind::UninitializedData | SectionKind::UninitializedTls if in_ram => {
                report.ram_bytes += section.size();
            }
            _ => {}
        }
    }
    Ok(report)
}

impl SizeReport {
    pub fn check(&self, budget: &Budget) -> Result<(), String> {
        if self.flash_bytes > budget.flash_bytes || self.ram_bytes > budget.ram_bytes {
            Err(format!("over budget: {}", self.against(budget)))
        } else {
            Ok(())
        }
    }

    pub fn against<'a>(&'a self, budget: &'a Budget) -> impl fmt::Display + 'a {
        Against {
            report: self,
            budget,
        }
    }
}

struct Against<'a> {
    report: &'a SizeReport,
    budget: &'a Budget,
}

impl fmt::Display for Against<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (used, budget) = (self.report, self.budget);
        write!(
            f,
            "flash {} B of {} B ({:.1} %), static RAM {} B of {} B ({:.1} %)",
            used.flash_bytes,
            budget.flash_bytes,
            100.0 * used.flash_bytes as f64 / budget.flash_bytes as f64,
            used.ram_bytes,
            budget.ram_bytes,
            100.0 * used.ram_bytes as f64 / budget.ram_bytes as f64
        )
    }
}
