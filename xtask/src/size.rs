//! Flash and static RAM use of a firmware ELF, as `size` reports them (text + data, data + bss).

use object::{Object, ObjectSection, SectionKind};
use std::fmt;
use std::path::Path;

/// The release image must fit these.
pub const FLASH_BUDGET_BYTES: u64 = 32 * 1024;
pub const RAM_BUDGET_BYTES: u64 = 16 * 1024;

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
    pub fn check_budget(&self) -> Result<(), String> {
        if self.flash_bytes > FLASH_BUDGET_BYTES || self.ram_bytes > RAM_BUDGET_BYTES {
            Err(format!("firmware over budget: {self}"))
        } else {
            Ok(())
        }
    }
}

impl fmt::Display for SizeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "firmware size: flash {} B of {} B ({:.1} %), static RAM {} B of {} B ({:.1} %)",
            self.flash_bytes,
            FLASH_BUDGET_BYTES,
            100.0 * self.flash_bytes as f64 / FLASH_BUDGET_BYTES as f64,
            self.ram_bytes,
            RAM_BUDGET_BYTES,
            100.0 * self.ram_bytes as f64 / RAM_BUDGET_BYTES as f64
        )
    }
}
