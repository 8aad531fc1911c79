//! `cargo xtask <command>`: the project's two entry points and their helpers.
//!
//! * `run`  — the main job: the firmware under QEMU drives the simulated plate and part.
//! * `test` — the whole test suite: host tests, the `no_std` crate and the firmware for
//!   `thumbv7em-none-eabihf`, the firmware size budget, and the firmware-in-the-loop scenarios
//!   under QEMU.
//! * `size` — the firmware's flash and static RAM use against the budget.
//!
//! Each command installs what it needs (the thumb target, qemu-system-arm, defmt-print) so it
//! works on a fresh machine.

mod qemu;
mod size;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

const THUMB_TARGET: &str = "thumbv7em-none-eabihf";

type Result<T = ()> = std::result::Result<T, String>;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let outcome = match args.first().map(String::as_str) {
        Some("run") => run(&args[1..]),
        Some("test") => test(),
        Some("size") => firmware_size(),
        _ => Err(USAGE.to_string()),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("xtask: {message}");
            ExitCode::FAILURE
        }
    }
}

const USAGE: &str =
    "usage: cargo xtask <run [--board] [scenario key=value…] [-- hil flags…] | test | size>";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

fn firmware_dir() -> PathBuf {
    root().join("firmware")
}

/// Runs a command to completion, failing with its description if it fails.
fn exec(command: &mut Command) -> Result {
    eprintln!("xtask: running {command:?}");
    let status = command
        .status()
        .map_err(|error| format!("cannot start {command:?}: {error}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{command:?} failed with {status}"))
    }
}

fn cargo() -> Command {
    let mut command = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    command.current_dir(root());
    command
}

/// `cargo` for the firmware workspace, which keeps its own target directory.
fn firmware_cargo() -> Command {
    let mut command = cargo();
    command
        .current_dir(firmware_dir())
        .env_remove("CARGO_TARGET_DIR");
    command
}

/// `host-sim` (release build) with the arguments that follow.
fn host_sim() -> Command {
    let mut command = cargo();
    command.args([
        "run",
        "--quiet",
        "--release",
        "--locked",
        "--package",
        "host-sim",
        "--",
    ]);
    command
}

fn ensure_thumb_target() -> Result {
    let installed = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .map_err(|error| format!("cannot run rustup: {error}"))?;
    if String::from_utf8_lossy(&installed.stdout)
        .lines()
        .any(|line| line.trim() == THUMB_TARGET)
    {
        return Ok(());
    }
    exec(Command::new("rustup").args(["target", "add", THUMB_TARGET]))
}

/// The prediction at the paper's operating point (`host-sim simulate`, with a plot), then the
/// firmware under QEMU piped through the defmt decoder into `host-sim hil`, which checks every
/// edge and simulates the part on the actual edge times. Scenario settings (`key=value`) come
/// first, `hil` flags after `--`.
fn run(args: &[String]) -> Result {
    let (scenario, hil_flags) = match args.iter().position(|arg| arg == "--") {
        Some(split) => (&args[..split], &args[split + 1..]),
        None => (args, &[][..]),
    };
    ensure_thumb_target()?;
    qemu::ensure_tools()?;
    let elf = qemu::build_firmware(qemu::Image::Scripted)?;
    exec(cargo().args(["build", "--release", "--locked", "--package", "host-sim"]))?;
    println!("Prediction at the paper's operating point (50 Hz, d = 0.586, 2.5 mm, μ = 1):");
    exec(
        host_sim()
            .args(["simulate", "--plot"])
            .arg(root().join("target").join("paper-operating-point.svg")),
    )?;
    println!("\nThe firmware under QEMU driving the simulated part:");
    let mut hil = host_sim();
    hil.arg("hil");
    if !hil_flags.iter().any(|flag| flag == "--plot") {
        hil.arg("--plot")
            .arg(root().join("target").join("hil-run.svg"));
    }
    hil.args(hil_flags);
    let (mut emulator, mut decoder) = qemu::spawn_decoded(&elf, scenario)?;
    hil.stdin(decoder.stdout.take().ok_or("no decoder output")?);
    let report = hil
        .status()
        .map_err(|error| format!("cannot run host-sim hil: {error}"))?;
    let firmware_status = emulator.wait().map_err(|error| error.to_string())?;
    decoder.wait().map_err(|error| error.to_string())?;
    if !firmware_status.success() {
        return Err(format!("the firmware ended with {firmware_status}"));
    }
    if !report.success() {
        return Err("the firmware-in-the-loop check failed".into());
    }
    Ok(())
}

fn test() -> Result {
    ensure_thumb_target()?;
    exec(cargo().args(["test", "--workspace", "--locked"]))?;
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
    exec(firmware_cargo().args(["build", "--release", "--locked"]))?;
    exec(
        firmware_cargo()
            .args(["build", "--release", "--locked", "--features", "console"])
            .args(["--target-dir", "target/console"]),
    )?;
    firmware_size()?;
    qemu::ensure_tools()?;
    let scripted = qemu::build_firmware(qemu::Image::Scripted)?;
    ignored_tests("feeder-tests", "qemu", &scripted)?;
    let console = qemu::build_firmware(qemu::Image::Console)?;
    ignored_tests("feeder-ctl", "qemu_session", &console)
}

/// Runs the tests of `package`'s `test` target that need the QEMU firmware `elf`.
fn ignored_tests(package: &str, test: &str, elf: &Path) -> Result {
    exec(
        cargo()
            .args([
                "test",
                "--locked",
                "--package",
                package,
                "--test",
                test,
                "--",
                "--ignored",
            ])
            .env("FEEDER_QEMU_ELF", elf),
    )
}

fn firmware_size() -> Result {
    for (image, directory, budget) in [
        ("default", "target", size::DEFAULT_BUDGET),
        ("console", "target/console", size::CONSOLE_BUDGET),
    ] {
        let elf = firmware_dir()
            .join(directory)
            .join(THUMB_TARGET)
            .join("release")
            .join("feeder-firmware");
        let report = size::measure(&elf)?;
        println!("{image} image: {}", report.against(&budget));
        report
            .check(&budget)
            .map_err(|error| format!("{image} image: {error}"))?;
    }
    Ok(())
}
