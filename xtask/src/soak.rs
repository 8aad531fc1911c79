//! `cargo xtask soak`: the random-operator soak (`ctl/tests/soak`) against the QEMU console image,
//! at any length, and with `--modbus-requests` the random Modbus master's (`ctl/tests/modbus_soak`);
//! `cargo xtask test` runs both at their default lengths.

use std::path::Path;

use clap::Args;

use crate::command::{exec, ignored_tests};
use crate::failure::Result;
use crate::{qemu, tools};

/// The flags of `cargo xtask soak`.
#[derive(Args)]
pub struct SoakArgs {
    /// Motion cycles to run (default: FEEDER_SOAK_CYCLES, else 20000).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub cycles: Option<u64>,
    /// Seed of the operator's script (default: FEEDER_SOAK_SEED, else random).
    #[arg(long, value_name = "SEED")]
    pub seed: Option<u64>,
    /// Runs the Modbus master's soak with this many random requests instead (default length in
    /// `cargo xtask test`: 1500).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub modbus_requests: Option<u64>,
}

/// Builds the console image and runs the soak on it.
pub fn soak_alone(args: &SoakArgs) -> Result {
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
    let elf = qemu::build_firmware(qemu::Image::Console)?;
    soak(&elf, args)
}

/// The random-operator soak against the console image `elf`, its progress shown as it runs;
/// unset arguments leave FEEDER_SOAK_CYCLES and FEEDER_SOAK_SEED to the environment.
pub fn soak(elf: &Path, args: &SoakArgs) -> Result {
    let mut command = match args.modbus_requests {
        Some(_) => ignored_tests("modbus_soak", elf),
        None => ignored_tests("soak", elf),
    };
    command.arg("--nocapture");
    if let Some(requests) = args.modbus_requests {
        command.env("FEEDER_MODBUS_SOAK_REQUESTS", requests.to_string());
    }
    if let Some(cycles) = args.cycles {
        command.env("FEEDER_SOAK_CYCLES", cycles.to_string());
    }
    if let Some(seed) = args.seed {
        command.env("FEEDER_SOAK_SEED", seed.to_string());
    }
    exec(&mut command)
}
