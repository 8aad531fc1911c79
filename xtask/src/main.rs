//! `cargo xtask <command>`: the project's two entry points and their helpers.
//!
//! * `run`  — the main job: the firmware under QEMU drives the simulated plate and part.
//! * `test` — the whole test suite: host tests, the `no_std` crate and the firmware for
//!   `thumbv7em-none-eabihf`, the firmware size budget, and the firmware-in-the-loop scenarios
//!   under QEMU.
//! * `size` — the firmware's flash and static RAM use against the budget.
//!
//! Each command installs what it needs (the thumb target, flip-link, qemu-system-arm,
//! defmt-print; see `tools`) so it works on a fresh machine.

mod qemu;
mod size;
mod tools;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use clap::{Args, Parser, Subcommand};
use feeder_shared::scenario::{parse_setting, SCENARIO_KEYS};

const THUMB_TARGET: &str = "thumbv7em-none-eabihf";

type Result<T = ()> = std::result::Result<T, String>;

#[derive(Parser)]
#[command(
    name = "cargo xtask",
    bin_name = "cargo xtask",
    about = "The feeder's main job, its whole test suite and the firmware size report",
    allow_negative_numbers = true
)]
struct Cli {
    #[command(subcommand)]
    task: Task,
}

#[derive(Subcommand)]
enum Task {
    /// The main job: the prediction at the paper's operating point, then the firmware under
    /// QEMU driving the simulated part, checked edge by edge by `host-sim hil`.
    Run(RunArgs),
    /// The whole test suite: host tests, the thumb builds, size budgets, QEMU scenarios.
    Test,
    /// Flash and static RAM of both board images against their budgets.
    Size,
}

#[derive(Args)]
#[command(after_help = scenario_help())]
struct RunArgs {
    /// Settings of the emulated run's scripted operator (keys below).
    #[arg(value_name = "KEY=VALUE", value_parser = scenario_word)]
    scenario: Vec<String>,
    /// Flags for `host-sim hil`, after `--` (e.g. `-- --json`).
    #[arg(last = true, value_name = "HIL FLAGS")]
    hil_flags: Vec<String>,
}

fn scenario_help() -> String {
    let mut help = String::from("Scenario keys:");
    for (key, meaning) in SCENARIO_KEYS {
        help.push_str(&format!("\n  {key:<10} {meaning}"));
    }
    help
}

/// A scenario word, checked by the parser the firmware uses.
fn scenario_word(word: &str) -> Result<String> {
    parse_setting(word)
        .map(|_| word.to_string())
        .map_err(|error| error.to_string())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let launch_path = std::env::var_os("PATH").unwrap_or_default();
    let outcome = tools::isolate().and_then(|()| {
        tools::ensure_thumb_target(&launch_path)?;
        match cli.task {
            Task::Run(args) => run(&args),
            Task::Test => test(),
            Task::Size => firmware_size(),
        }
    });
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("xtask: {message}");
            ExitCode::FAILURE
        }
    }
}

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

/// The prediction at the paper's operating point (`host-sim simulate`, with a plot), then the
/// firmware under QEMU piped through the defmt decoder into `host-sim hil`, which checks every
/// edge and simulates the part on the actual edge times. Scenario settings (`key=value`) come
/// first, `hil` flags after `--`.
fn run(args: &RunArgs) -> Result {
    let (scenario, hil_flags) = (&args.scenario, &args.hil_flags);
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
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
    tools::ensure_linker()?;
    exec(firmware_cargo().args(["build", "--release", "--locked"]))?;
    exec(
        firmware_cargo()
            .args(["build", "--release", "--locked", "--features", "console"])
            .args(["--target-dir", "target/console"]),
    )?;
    firmware_size()?;
    tools::ensure_emulation()?;
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

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> std::result::Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("cargo xtask").chain(args.iter().copied()))
    }

    #[test]
    fn negative_values_after_a_space_reach_hil_as_typed() {
        let Task::Run(args) = parse(&["run", "cycles=50", "--", "--force-n", "-0.0001"])
            .expect("accepted")
            .task
        else {
            panic!("not a run");
        };
        assert_eq!(args.scenario, ["cycles=50"]);
        assert_eq!(args.hil_flags, ["--force-n", "-0.0001"]);
    }

    #[test]
    fn a_negative_scenario_value_is_refused_with_the_word_named() {
        let error = parse(&["run", "cycles=-5"]).err().expect("refused").to_string();
        assert!(
            error.contains("cycles=-5: cycles must be a whole number from 1"),
            "{error}"
        );
        let error = parse(&["run", "duty=-inf"]).err().expect("refused").to_string();
        assert!(error.contains("duty=-inf"), "{error}");
    }
}
