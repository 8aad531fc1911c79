//! `cargo xtask run --board g474`: the NUCLEO-G474RE's own release image (with the event
//! stream, `hil-trace`) on the register-level twin (`twin/`, built apart: its CPU engine is
//! GPL), as an operator with the user button runs it, checked edge by edge by `host-sim hil`;
//! the twin checks every segment on its DAC's output itself. With `--plant`, the encoder image
//! closes its loop on the plant file's plate on the twin's pins, and the twin judges it.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use feeder_shared::scenario::{parse_setting, ScenarioSetting};
use host_sim::plate::PlantFile;

use crate::command::{
    cargo, exec, firmware_cargo, firmware_dir, host_sim, root, shown, THUMB_TARGET,
};
use crate::failure::{Failure, Result};
use crate::tools;

/// Motion cycles of the button's run when the scenario names none.
const DEFAULT_CYCLES: u32 = 200;
/// … and of the closed loop's run on a plant file: the course releases the soft start after
/// about 530 cycles on `realistic.toml`, and the verdict's feed rate takes the last 50 before
/// the stop.
const PLANT_CYCLES: u32 = 700;

/// The target directory every G474 image for the twin is built in, the board's own (where
/// `cargo xtask size` builds the images as flashed): they differ in the firmware's own
/// features only, so the dependencies are built once.
fn image_target_dir() -> PathBuf {
    firmware_dir().join("target")
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

/// The motion cycles of `words` (`default` where they name none): the button's run takes
/// `cycles=N` alone (a board without a console has no operator for the rest).
fn button_cycles(words: &[String], default: u32) -> Result<u32> {
    let mut cycles = default;
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

/// Features of the G474 image the twin runs without a plate: the PWM stage (the encoder's image
/// runs with one, `run_plant`).
const TWIN_FEATURES: [&str; 1] = ["output-pwm"];

/// The run of the image with `features`: the twin's log piped into `host-sim hil` (with
/// `hil_flags`).
pub fn run(scenario: &[String], features: &[String], hil_flags: &[String]) -> Result {
    let cycles = button_cycles(scenario, DEFAULT_CYCLES)?;
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

/// The encoder image (with `features` besides) on the twin with the plate of `plant` on its
/// pins, for `cycles=N` of the scenario (700 where it names none): the twin's report ends with
/// the closed loop's verdict, its decoded log in target/twin-plant-run.log.
pub fn run_plant(plant: &Path, scenario: &[String], features: &[String]) -> Result {
    PlantFile::from_path(plant).map_err(|error| Failure::Refused(error.to_string()))?;
    let cycles = button_cycles(scenario, PLANT_CYCLES)?;
    if let Some(other) = features.first() {
        return Err(Failure::Refused(format!(
            "the twin closes the loop on the encoder image with its DAC; not with {other}"
        )));
    }
    tools::ensure_linker()?;
    let elf = build_image(&["encoder"])?;
    let twin = build_twin()?;
    let log = root().join("target").join("twin-plant-run.log");
    let mut run = Command::new(&twin);
    run.arg(&elf)
        .args(["--cycles", &cycles.to_string(), "--plant"])
        .arg(std::path::absolute(plant).map_err(|error| error.to_string())?)
        .arg("--log")
        .arg(&log);
    eprintln!(
        "\nThe G474 encoder image on the twin, its loop closed on {}:\nxtask: running {}",
        plant.display(),
        shown(&run)
    );
    let status = run
        .status()
        .map_err(|error| format!("cannot run the twin: {error}"))?;
    if !status.success() {
        return Err(format!("the closed loop on the twin failed ({status})").into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_button_run_takes_cycles_alone() {
        let words = |w: &[&str]| w.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            button_cycles(&words(&[]), DEFAULT_CYCLES).ok(),
            Some(DEFAULT_CYCLES)
        );
        assert_eq!(
            button_cycles(&words(&["cycles=40"]), DEFAULT_CYCLES).ok(),
            Some(40)
        );
        let refused = button_cycles(&words(&["cycles=40", "freq_hz=100"]), DEFAULT_CYCLES);
        assert!(
            matches!(&refused, Err(Failure::Refused(why)) if why.contains("freq_hz=100")),
            "{:?}",
            refused.err().map(|f| f.to_string())
        );
        assert!(matches!(
            button_cycles(&words(&["cycles=x"]), DEFAULT_CYCLES),
            Err(Failure::Refused(_))
        ));
        assert_eq!(
            button_cycles(&words(&[]), PLANT_CYCLES).ok(),
            Some(PLANT_CYCLES),
            "a plant's run without cycles=N runs long enough to be judged"
        );
    }
}
