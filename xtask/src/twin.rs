//! `cargo xtask run --board g474`: the NUCLEO-G474RE's own release image (with the event
//! stream, `hil-trace`) on the register-level twin (`twin/`, built apart: its CPU engine is
//! GPL), as an operator with the user button runs it, checked edge by edge by `host-sim hil`;
//! the twin checks every segment on its DAC's output itself.

use std::path::PathBuf;
use std::process::{Command, Stdio};

use feeder_shared::scenario::{parse_setting, ScenarioSetting};

use crate::command::{
    cargo, exec, firmware_cargo, firmware_dir, host_sim, root, shown, THUMB_TARGET,
};
use crate::failure::{Failure, Result};
use crate::tools;

/// Motion cycles of the button's run when the scenario names none.
const DEFAULT_CYCLES: u32 = 200;

/// Builds the G474 image with the event stream and `features`, in a target directory of its
/// own, and returns the ELF's path.
pub fn build_image(features: &[&str]) -> Result<PathBuf> {
    let mut all = vec!["hil-trace"];
    all.extend_from_slice(features);
    let features = all.join(",");
    let target_dir = firmware_dir()
        .join("target")
        .join(format!("g474-twin-{}", features.replace(',', "-")));
    exec(
        firmware_cargo()
            .args([
                "build",
                "--release",
                "--locked",
                "--features",
                &features,
                "--target-dir",
            ])
            .arg(&target_dir),
    )?;
    Ok(target_dir
        .join(THUMB_TARGET)
        .join("release")
        .join("feeder-firmware"))
}

/// The fault drills the G474 image builds with `FEEDER_FAULT_DRILL`
/// (`firmware/src/board/g474/drill.rs`).
const DRILLS: [&str; 5] = [
    "panic",
    "stack-overflow",
    "critical-section",
    "hang",
    "lockup",
];

/// Builds an image per fault drill (with the event stream) and returns the directory that holds
/// them, `<drill>.elf` each.
pub fn build_drills() -> Result<PathBuf> {
    let target_dir = firmware_dir().join("target").join("g474-twin-drills");
    let drills = root().join("target").join("g474-drills");
    std::fs::create_dir_all(&drills)
        .map_err(|error| format!("cannot make {}: {error}", drills.display()))?;
    for drill in DRILLS {
        exec(
            firmware_cargo()
                .args([
                    "build",
                    "--release",
                    "--locked",
                    "--features",
                    "hil-trace",
                    "--target-dir",
                ])
                .arg(&target_dir)
                .env("FEEDER_FAULT_DRILL", drill),
        )?;
        let elf = target_dir
            .join(THUMB_TARGET)
            .join("release")
            .join("feeder-firmware");
        let copy = drills.join(format!("{drill}.elf"));
        std::fs::copy(&elf, &copy).map_err(|error| {
            format!(
                "cannot copy {} to {}: {error}",
                elf.display(),
                copy.display()
            )
        })?;
    }
    Ok(drills)
}

/// Builds the twin (after what its engine's build needs) and returns its binary's path.
pub fn build_twin() -> Result<PathBuf> {
    tools::ensure_twin_build()?;
    let manifest = root().join("twin").join("Cargo.toml");
    exec(
        cargo()
            .args(["build", "--release", "--locked", "--manifest-path"])
            .arg(&manifest)
            .env_remove("CARGO_TARGET_DIR"),
    )?;
    Ok(root()
        .join("twin")
        .join("target")
        .join("release")
        .join("feeder-twin"))
}

/// The motion cycles of `words`: the button's run takes `cycles=N` alone (a board without a
/// console has no operator for the rest).
fn button_cycles(words: &[String]) -> Result<u32> {
    let mut cycles = DEFAULT_CYCLES;
    for word in words {
        match parse_setting(word).map_err(|error| Failure::Refused(error.to_string()))? {
            ScenarioSetting::Cycles(n) => cycles = n,
            _ => {
                return Err(Failure::Refused(format!(
                    "the G474 image without a console has only its button: a run on the twin \
                     takes cycles=N alone, not {word}"
                )))
            }
        }
    }
    Ok(cycles)
}

/// The run: the twin's log piped into `host-sim hil` (with `hil_flags`).
pub fn run(scenario: &[String], hil_flags: &[String]) -> Result {
    let cycles = button_cycles(scenario)?;
    tools::ensure_linker()?;
    let elf = build_image(&[])?;
    let twin = build_twin()?;
    exec(cargo().args(["build", "--release", "--locked", "--package", "host-sim"]))?;
    let mut run = Command::new(&twin);
    run.arg(&elf)
        .args(["--cycles", &cycles.to_string()])
        .stdout(Stdio::piped());
    eprintln!(
        "\nThe G474 image on the twin driving the simulated part:\nxtask: running {}",
        shown(&run)
    );
    let mut board = run
        .spawn()
        .map_err(|error| format!("cannot run the twin: {error}"))?;
    let log = board.stdout.take().ok_or("no log from the twin")?;
    let mut hil = host_sim();
    hil.arg("hil");
    if !hil_flags.iter().any(|flag| flag == "--plot") {
        hil.arg("--plot")
            .arg(root().join("target").join("hil-run-g474.svg"));
    }
    hil.args(hil_flags).stdin(Stdio::from(log));
    let report = hil
        .status()
        .map_err(|error| format!("cannot run host-sim hil: {error}"))?;
    let twin_status = board
        .wait()
        .map_err(|error| format!("cannot wait for the twin: {error}"))?;
    if !twin_status.success() {
        return Err(format!("the twin's run failed ({twin_status})").into());
    }
    if !report.success() {
        return Err("the firmware-in-the-loop check failed".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_button_run_takes_cycles_alone() {
        let words = |w: &[&str]| w.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(button_cycles(&words(&[])).ok(), Some(DEFAULT_CYCLES));
        assert_eq!(button_cycles(&words(&["cycles=40"])).ok(), Some(40));
        let refused = button_cycles(&words(&["cycles=40", "freq_hz=100"]));
        assert!(
            matches!(&refused, Err(Failure::Refused(why)) if why.contains("freq_hz=100")),
            "{:?}",
            refused.err().map(|f| f.to_string())
        );
        assert!(matches!(
            button_cycles(&words(&["cycles=x"])),
            Err(Failure::Refused(_))
        ));
    }
}
