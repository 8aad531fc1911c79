//! `cargo xtask <command>`: the project's two entry points and their helpers.
//!
//! * `run`  — the main job (with no board attached: the simulator at the paper's operating point).
//! * `test` — the whole test suite: host tests, the `no_std` crate and the firmware for
//!   `thumbv7em-none-eabihf`, and the firmware size budget.
//! * `size` — the firmware's flash and static RAM use against the budget.
//!
//! Each command installs what it needs (the thumb target) so it works on a fresh machine.

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

const USAGE: &str = "usage: cargo xtask <run [host-sim args…] | test | size>";

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

fn run(host_sim_args: &[String]) -> Result {
    let mut command = cargo();
    command.args(["run", "--quiet", "--release", "--package", "host-sim", "--"]);
    if host_sim_args.is_empty() {
        let plot = root().join("target").join("paper-operating-point.svg");
        command.args(["simulate", "--plot"]).arg(plot);
    } else {
        command.args(host_sim_args);
    }
    exec(&mut command)
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
    firmware_size()
}

fn firmware_size() -> Result {
    let elf = firmware_dir()
        .join("target")
        .join(THUMB_TARGET)
        .join("release")
        .join("feeder-firmware");
    let report = size::measure(&elf)?;
    println!("{report}");
    report.check_budget()
}
