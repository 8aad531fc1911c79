//! `cargo xtask run --board g474`: the NUCLEO-G474RE's own release image (with the event
//! stream, `hil-trace`) on the register-level twin (`twin/`, built apart: its CPU engine is
//! GPL), as an operator with the user button runs it, checked edge by edge by `host-sim hil`;
//! the twin checks every segment on its DAC's output itself.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use feeder_shared::scenario::{parse_setting, ScenarioSetting};

use crate::command::{
    cargo, exec, firmware_cargo, firmware_dir, host_sim, root, shown, THUMB_TARGET,
};
use crate::failure::{Failure, Result};
use crate::tools;

/// Motion cycles of the button's run when the scenario names none.
const DEFAULT_CYCLES: u32 = 200;

/// The target directory every G474 image for the twin is built in: they differ in the
/// firmware's own features only, so the dependencies are built once.
fn image_target_dir() -> PathBuf {
    firmware_dir().join("target").join("g474-twin")
}

/// Builds the G474 image with the event stream, `features` and the fault drill `drill`, and
/// copies it to `copy`.
fn build_copy(features: &[&str], drill: Option<&str>, copy: &Path) -> Result<PathBuf> {
    let mut all = vec!["hil-trace"];
    all.extend_from_slice(features);
    let target_dir = image_target_dir();
    let mut build = firmware_cargo();
    build
        .args([
            "build",
            "--release",
            "--locked",
            "--features",
            &all.join(","),
            "--target-dir",
        ])
        .arg(&target_dir);
    match drill {
        Some(drill) => build.env("FEEDER_FAULT_DRILL", drill),
        None => build.env_remove("FEEDER_FAULT_DRILL"),
    };
    exec(&mut build)?;
    let elf = target_dir
        .join(THUMB_TARGET)
        .join("release")
        .join("feeder-firmware");
    if let Some(directory) = copy.parent() {
        std::fs::create_dir_all(directory)
            .map_err(|error| format!("cannot make {}: {error}", directory.display()))?;
    }
    std::fs::copy(&elf, copy).map_err(|error| {
        format!(
            "cannot copy {} to {}: {error}",
            elf.display(),
            copy.display()
        )
    })?;
    Ok(copy.to_path_buf())
}

/// Builds the G474 image with the event stream and `features` and returns the ELF's path
/// (`target/g474-images/`).
pub fn build_image(features: &[&str]) -> Result<PathBuf> {
    let name = match features {
        [] => "default".to_string(),
        _ => features.join("-"),
    };
    let copy = root()
        .join("target")
        .join("g474-images")
        .join(format!("{name}.elf"));
    build_copy(features, None, &copy)
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
    let drills = root().join("target").join("g474-drills");
    for drill in DRILLS {
        build_copy(&[], Some(drill), &drills.join(format!("{drill}.elf")))?;
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

/// Features of the G474 image the twin runs: the PWM stage; the encoder's image runs only its
/// register checks here (the twin has no plate to close its loop on).
const TWIN_FEATURES: [&str; 1] = ["output-pwm"];

/// The run of the image with `features`: the twin's log piped into `host-sim hil` (with
/// `hil_flags`).
pub fn run(scenario: &[String], features: &[String], hil_flags: &[String]) -> Result {
    let cycles = button_cycles(scenario)?;
    if let Some(other) = features
        .iter()
        .find(|f| !TWIN_FEATURES.contains(&f.as_str()))
    {
        return Err(Failure::Refused(format!(
            "the twin runs the G474 image with {}; not with {other}",
            TWIN_FEATURES.join(", ")
        )));
    }
    tools::ensure_linker()?;
    let features: Vec<&str> = features.iter().map(String::as_str).collect();
    let elf = build_image(&features)?;
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
