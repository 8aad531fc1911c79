//! `cargo xtask size`: the board images built, then their flash and static RAM use, as `size`
//! reports them (text + data, data + bss), against their budgets.

use object::{Object, ObjectSection, SectionKind};
use std::fmt;
use std::io;
use std::path::Path;

use crate::command::{exec, firmware_cargo, firmware_dir, THUMB_TARGET};
use crate::{failure, tools};

/// Flash and static RAM an image may use.
pub struct Budget {
    pub flash_bytes: u64,
    pub ram_bytes: u64,
}

/// The board firmware without the serial console, which reads and checks the configuration
/// saved in flash at power-up.
const DEFAULT_BUDGET: Budget = Budget {
    flash_bytes: 48 * 1024,
    ram_bytes: 16 * 1024,
};
/// With the serial console (`console` feature): command parsing, validation on the target, the
/// configuration's keys and the flash driver for it and the recipes, and the telemetry stream.
const CONSOLE_BUDGET: Budget = Budget {
    flash_bytes: 96 * 1024,
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
fn measure(elf: &Path) -> Result<SizeReport, String> {
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

/// The board images, as flashed: name, cargo features and budget. Both are built in
/// `firmware/target`, one after the other, so that the dependencies they share are built once;
/// each is measured right after its build.
const IMAGES: [(&str, &[&str], Budget); 2] = [
    ("default", &[], DEFAULT_BUDGET),
    ("console", &["--features", "console"], CONSOLE_BUDGET),
];

/// Builds both board images (release, as flashed), then writes their flash and static RAM
/// against their budgets to `out`; fails if one is over.
pub fn firmware_size(out: &mut dyn io::Write) -> failure::Result {
    tools::ensure_linker()?;
    for (image, features, budget) in IMAGES {
        exec(
            firmware_cargo()
                .args(["build", "--release", "--locked"])
                .args(features)
                .args(["--target-dir", "target"]),
        )?;
        let elf = firmware_dir()
            .join("target")
            .join(THUMB_TARGET)
            .join("release")
            .join("feeder-firmware");
        let report = measure(&elf)?;
        writeln!(out, "{image} image: {}", report.against(&budget))
            .map_err(|error| format!("cannot write the size report: {error}"))?;
        report
            .check(&budget)
            .map_err(|error| format!("{image} image: {error}"))?;
    }
    Ok(())
}
