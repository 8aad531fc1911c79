//! `cargo xtask test`: the whole test suite. The host tests, a type check of the fuzz targets,
//! the `no_std` crate and the firmware for the thumb target, the firmware size budget, then the
//! firmware-in-the-loop scenarios under QEMU, the G474 image on its twin, and the soak.

use std::io;
use std::process::Command;

use crate::command::{cargo, cargo_test, exec, ignored_tests, root, workspace_test, THUMB_TARGET};
use crate::failure::Result;
use crate::soak::{soak, SoakArgs};
use crate::{qemu, size, tools, twin};

/// The soak's seed in `test`, so that every run sends the same operator lines (the firmware's
/// timing against them still varies); `FEEDER_SOAK_SEED` or `cargo xtask soak` choose others.
const TEST_SOAK_SEED: u64 = 3_709_873_859_707_123_073;

/// The soak's motion cycles in `test` (about 40 s under QEMU on 2 cores), to keep the test
/// command within its time; `FEEDER_SOAK_CYCLES` or `cargo xtask soak` (20,000 by default)
/// run longer ones.
const TEST_SOAK_CYCLES: u64 = 8_000;

/// Runs every test, step by step; the first step that fails ends it.
pub fn test() -> Result {
    exec(&mut workspace_test())?;
    exec(&mut fuzz_check())?;
    exec(cargo_test("run_output").args(["--", "--ignored"]))?;
    tools::ensure_linker()?;
    for features in ["", "defmt"] {
        exec(cargo().args([
            "build",
            "--locked",
            "--package",
            "feeder-shared",
            "--target",
            THUMB_TARGET,
            "--features",
            features,
        ]))?;
    }
    size::firmware_size(&mut io::stderr())?;
    tools::ensure_emulation()?;
    let scripted = qemu::build_firmware(qemu::Image::Scripted)?;
    exec(&mut ignored_tests("qemu", &scripted))?;
    let cosim = qemu::build_firmware(qemu::Image::Cosim)?;
    let closed_loop = qemu::build_firmware(qemu::Image::ClosedLoop)?;
    exec(
        ignored_tests("cosim", &cosim)
            .env("FEEDER_COSIM_ELF", &cosim)
            .env("FEEDER_CLOSED_LOOP_ELF", &closed_loop),
    )?;
    let console = qemu::build_firmware(qemu::Image::Console)?;
    exec(&mut ignored_tests("qemu_session", &console))?;
    // The console image's Modbus port under a real master, then its seeded random soak
    // (FEEDER_SOAK_SEED, else its own fixed seed), whose summary is shown.
    exec(&mut ignored_tests("qemu_modbus", &console))?;
    exec(ignored_tests("modbus_soak", &console).arg("--nocapture"))?;
    let console_with_plate = qemu::build_firmware(qemu::Image::ClosedLoopConsole)?;
    exec(
        ignored_tests("qemu_plant", &console_with_plate)
            .env("FEEDER_CLOSED_LOOP_CONSOLE_ELF", &console_with_plate),
    )?;
    g474_twin()?;
    let unset = |name: &str| std::env::var_os(name).is_none();
    soak(
        &console,
        &SoakArgs {
            cycles: unset("FEEDER_SOAK_CYCLES").then_some(TEST_SOAK_CYCLES),
            seed: unset("FEEDER_SOAK_SEED").then_some(TEST_SOAK_SEED),
            modbus_requests: None,
        },
    )
}

/// The G474's own image on the register-level twin: the twin's models, the register values
/// the review checked, a button run checked on the twin's DAC, the encoder image's closed loop
/// on `realistic.toml`'s plate, the console image's replies on LPUART1, the fault drills judged
/// on the twin's pins, and the README's
/// `--board g474` run judged by `host-sim hil`, with the DAC and with the PWM stage.
fn g474_twin() -> Result {
    let drills = twin::build_drills()?;
    let encoder = twin::build_image(&["encoder"])?;
    let console = twin::build_image(&["console"])?;
    let image = twin::build_image(&[])?;
    twin::build_twin()?;
    exec(
        cargo()
            .args(["test", "--release", "--locked", "--manifest-path"])
            .arg(root().join("twin").join("Cargo.toml"))
            .args(["--", "--include-ignored"])
            .env("FEEDER_G474_ELF", &image)
            .env("FEEDER_G474_DRILLS", &drills)
            .env("FEEDER_G474_ENCODER_ELF", &encoder)
            .env("FEEDER_G474_CONSOLE_ELF", &console)
            .env_remove("CARGO_TARGET_DIR"),
    )?;
    twin::run(&["cycles=100".to_string()], &[], &[])?;
    twin::run(&["cycles=50".to_string()], &["output-pwm".to_string()], &[])
}

/// A type check of every fuzz target (`fuzz/`, its own workspace) on the stable toolchain:
/// without libFuzzer, which only `cargo +nightly fuzz` builds and links.
fn fuzz_check() -> Command {
    let mut command = cargo();
    command
        .args(["check", "--locked", "--bins", "--no-default-features"])
        .arg("--manifest-path")
        .arg(root().join("fuzz").join("Cargo.toml"));
    command
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    #[test]
    fn the_fuzz_targets_are_checked_on_stable_without_libfuzzer() {
        let command = fuzz_check();
        let arguments: Vec<_> = command.get_args().collect();
        assert_eq!(
            arguments[..4],
            ["check", "--locked", "--bins", "--no-default-features"]
        );
        assert!(!arguments
            .iter()
            .any(|a| a.to_string_lossy().starts_with('+')));
        let manifest = Path::new(arguments[5]);
        assert_eq!(manifest, root().join("fuzz").join("Cargo.toml"));
        let text = std::fs::read_to_string(manifest).expect("fuzz/Cargo.toml");
        assert!(text.contains("default-features = false"), "{text}");
    }
}
