//! `cargo xtask <command>`: the project's two main entry points (`run`, `test`), the tasks around
//! them, and their helpers.
//!
//! * `run`  — the main job: the firmware under QEMU drives the simulated plate and part.
//! * `test` — the whole test suite: host tests, the `no_std` crate and the firmware for
//!   `thumbv7em-none-eabihf`, the firmware size budget, and the firmware-in-the-loop scenarios
//!   under QEMU.
//! * `size` — the firmware's flash and static RAM use against the budget.
//! * `console` — live control: the QEMU console image at the `feeder-ctl` prompt, then
//!   `host-sim hil` on what happened.
//! * `soak` — only the random-operator soak against the QEMU console image, at any length.
//! * `bless` — makes the expected outputs the tests compare with anew (`tests/expected/`, the
//!   command-line snapshots) and says which changed.
//!
//! Each command installs what it needs (the thumb target, flip-link, qemu-system-arm,
//! defmt-print; see `tools`) so it works on a fresh machine.

mod bless;
mod console;
mod progress;
mod qemu;
mod size;
mod tools;

use std::fmt;
use std::io::{self, IsTerminal};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::thread;

use clap::{Args, Parser, Subcommand};
use feeder_emulator::{Board, Serial};
use feeder_shared::scenario::{parse_setting, qemu_clock, Scenario, SCENARIO_KEYS};
use feeder_shared::DacCalibration;
use host_sim::plate::PlantFile;

use progress::Meter;

const THUMB_TARGET: &str = "thumbv7em-none-eabihf";

/// Why a command did not succeed.
#[derive(Debug)]
enum Failure {
    /// The input was refused before anything was installed, built or started (exit code 2).
    Refused(String),
    /// A step failed (exit code 1).
    Failed(String),
}

impl Failure {
    fn exit_code(&self) -> ExitCode {
        match self {
            Failure::Refused(_) => ExitCode::from(2),
            Failure::Failed(_) => ExitCode::FAILURE,
        }
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::Refused(message) | Failure::Failed(message) => f.write_str(message),
        }
    }
}

impl From<String> for Failure {
    fn from(message: String) -> Self {
        Failure::Failed(message)
    }
}

impl From<&str> for Failure {
    fn from(message: &str) -> Self {
        Failure::Failed(message.to_string())
    }
}

type Result<T = ()> = std::result::Result<T, Failure>;

#[derive(Parser)]
#[command(
    name = "cargo xtask",
    bin_name = "cargo xtask",
    about = "The feeder's main job, its test suite, live control and the firmware size report",
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
    /// Live control: the QEMU console image with the `feeder-ctl` prompt on this terminal and
    /// its decoded log in target/console-run.log; on leaving the prompt (`quit`, `exit`,
    /// Ctrl-D), `host-sim hil` checks the run.
    Console,
    /// The random-operator soak against the QEMU console image alone (also part of `test`).
    Soak(SoakArgs),
    /// The closed loop on the seeded plant family across its envelope (`host-sim family`:
    /// 500 plants inside, 50 just outside, each at four operating points); its flags after `--`.
    Family(FamilyArgs),
    /// Makes the expected outputs anew after an intended change (tests/expected/: the QEMU
    /// golden log, the figures' CSVs; the command-line snapshots) and lists the files that
    /// changed.
    Bless,
}

#[derive(Args)]
struct SoakArgs {
    /// Motion cycles to run (default: FEEDER_SOAK_CYCLES, else 20000).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    cycles: Option<u64>,
    /// Seed of the operator's script (default: FEEDER_SOAK_SEED, else random).
    #[arg(long, value_name = "SEED")]
    seed: Option<u64>,
}

#[derive(Args)]
struct FamilyArgs {
    /// `host-sim family` flags (`-- --seed 7 --json`).
    #[arg(last = true, value_name = "FLAGS", allow_hyphen_values = true)]
    flags: Vec<String>,
}

#[derive(Args)]
#[command(after_help = scenario_help())]
struct RunArgs {
    /// Drive a real plate from this plant file (host-sim/plants/) instead: the QEMU image with
    /// the plant's encoder, running the closed loop, in lockstep with `host-sim cosim`, which
    /// reports the plate's motion and ends with `closed loop: PASSED` or `FAILED (…)`.
    #[arg(long, value_name = "FILE")]
    plant: Option<PathBuf>,
    /// With --plant: the image without an encoder, whose command runs as planned, with no
    /// correction; the report shows where the plate went.
    #[arg(long, requires = "plant")]
    open_loop: bool,
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
fn scenario_word(word: &str) -> std::result::Result<String, String> {
    parse_setting(word)
        .map(|_| word.to_string())
        .map_err(|error| error.to_string())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = tools::isolate().and_then(|()| match cli.task {
        Task::Run(args) => run(&args),
        Task::Test => test(),
        Task::Size => firmware_size(&mut io::stdout()),
        Task::Console => console::console(),
        Task::Soak(args) => soak_alone(&args),
        Task::Family(args) => exec_output(host_sim().arg("family").args(&args.flags)),
        Task::Bless => bless::bless(),
    });
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            eprintln!("xtask: {failure}");
            failure.exit_code()
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

/// Runs a command to completion, its standard output going to standard error with the rest of
/// what xtask says while it works; fails with its description if it fails.
fn exec(command: &mut Command) -> Result {
    exec_output(command.stdout(io::stderr()))
}

/// Runs a command to completion with its standard output on xtask's: the result of the task
/// (a report, or JSON alone); fails with its description if it fails.
fn exec_output(command: &mut Command) -> Result {
    let shown = shown(command);
    eprintln!("xtask: running {shown}");
    let status = command
        .status()
        .map_err(|error| format!("cannot start {shown}: {error}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{} failed with {status}", brief(command)).into())
    }
}

/// `command` in a few words, for its failure after [`shown`] has printed it whole: the program,
/// its first argument and, for cargo, the package and what runs after `--`.
fn brief(command: &Command) -> String {
    let arguments: Vec<_> = command.get_args().map(|a| a.to_string_lossy()).collect();
    let program = Path::new(command.get_program());
    let mut words = vec![program
        .file_name()
        .unwrap_or(program.as_os_str())
        .to_string_lossy()];
    words.extend(arguments.first().cloned());
    let after = |flag: &str| {
        let at = arguments.iter().position(|a| a == flag)?;
        arguments.get(at + 1).cloned()
    };
    if let Some(package) = after("--package") {
        words.extend(["--package".into(), package]);
    }
    if let Some(program) = after("--").filter(|_| arguments.first().is_some_and(|a| a == "run")) {
        words.extend(["--".into(), program]);
    }
    words.join(" ")
}

/// `command` as one would type it in a shell: the directory it runs in when that is not the
/// workspace root, the program's file name (xtask's `PATH` finds it), and the arguments, each
/// in single quotes only where a shell needs them.
fn shown(command: &Command) -> String {
    let root = root();
    let mut words = Vec::new();
    if let Some(dir) = command.get_current_dir().filter(|dir| *dir != root) {
        let dir = dir.strip_prefix(&root).unwrap_or(dir);
        words.extend([
            "cd".to_string(),
            quoted(&dir.to_string_lossy()),
            "&&".into(),
        ]);
    }
    let program = Path::new(command.get_program());
    let name = program.file_name().unwrap_or(program.as_os_str());
    words.push(quoted(&name.to_string_lossy()));
    words.extend(command.get_args().map(|arg| quoted(&arg.to_string_lossy())));
    words.join(" ")
}

/// `word` as a shell reads it back: as it is if it holds only characters no shell treats
/// specially, otherwise in single quotes (a quote inside written `'\''`).
fn quoted(word: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./:=,+@%".contains(c);
    if !word.is_empty() && word.chars().all(plain) {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', r"'\''"))
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

/// A binary of the host workspace (release build, through `cargo run`) with the arguments
/// that follow.
fn workspace_binary(package: &str) -> Command {
    let mut command = cargo();
    command.args([
        "run",
        "--quiet",
        "--release",
        "--locked",
        "--package",
        package,
        "--",
    ]);
    command
}

/// `host-sim` (release build) with the arguments that follow.
fn host_sim() -> Command {
    workspace_binary("host-sim")
}

/// The scenario of `words`, refused (exit code 2) unless the firmware takes it and both of its
/// waveforms play on the QEMU board as the firmware plans them, with the closed loop's room in
/// the DAC's linear range where it runs (`closed_loop`).
fn checked_scenario(words: &[String], closed_loop: bool) -> Result<Scenario> {
    let scenario = Scenario::parse(words.iter().map(String::as_str))
        .map_err(|error| Failure::Refused(error.to_string()))?;
    let loop_linear_mps2 = closed_loop.then(|| DacCalibration::DEFAULT.linear_limit_mps2());
    scenario
        .check(qemu_clock(), loop_linear_mps2)
        .map_err(|refusal| Failure::Refused(format!("scenario refused: {refusal}")))?;
    Ok(scenario)
}

/// The prediction at the paper's operating point (`host-sim simulate`, with a plot), then the
/// firmware under QEMU piped through the defmt decoder into `host-sim hil`, which checks every
/// edge and simulates the part on the actual edge times. Scenario settings (`key=value`) come
/// first, `hil` flags after `--`. The scenario (and with `--plant`, the plant file) is checked
/// before anything is installed, built or started. Only `hil`'s report (or JSON) goes to
/// standard output; the prediction, the builds and the run's progress go to standard error.
fn run(args: &RunArgs) -> Result {
    if let Some(plant) = &args.plant {
        return run_plant(plant, args);
    }
    let scenario = checked_scenario(&args.scenario, false)?;
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
    let elf = qemu::build_firmware(qemu::Image::Scripted)?;
    exec(cargo().args(["build", "--release", "--locked", "--package", "host-sim"]))?;
    eprintln!("Prediction at the paper's operating point (50 Hz, d = 0.586, 2.5 mm, μ = 1):");
    exec(
        host_sim()
            .args(["simulate", "--plot"])
            .arg(root().join("target").join("paper-operating-point.svg")),
    )?;
    eprintln!("\nThe firmware under QEMU driving the simulated part:");
    let mut hil = host_sim();
    hil.arg("hil");
    if !args.hil_flags.iter().any(|flag| flag == "--plot") {
        hil.arg("--plot")
            .arg(root().join("target").join("hil-run.svg"));
    }
    hil.args(&args.hil_flags).stdin(Stdio::piped());
    let mut board = Board::start(&elf, &args.scenario, Serial::None, Stdio::piped())
        .map_err(|error| error.to_string())?;
    let log = board.decoded_log().map_err(|error| error.to_string())?;
    eprintln!("xtask: running {}", shown(&hil));
    let mut hil = hil
        .spawn()
        .map_err(|error| format!("cannot run host-sim hil: {error}"))?;
    let hil_input = hil
        .stdin
        .take()
        .ok_or("no standard input to host-sim hil")?;
    let mut meter = Meter::new(
        io::stderr(),
        io::stderr().is_terminal(),
        scenario.stop_after_cycles,
    );
    let relay = thread::spawn(move || {
        let mut hil_input = hil_input;
        let relayed = feeder_emulator::relay(log, &mut hil_input, |progress| meter.show(progress));
        // The line is erased before hil sees the end of its input and writes its report.
        meter.finish();
        relayed
    });
    let report = hil
        .wait()
        .map_err(|error| format!("cannot run host-sim hil: {error}"))?;
    let relayed = relay
        .join()
        .map_err(|_| "the log relay to host-sim hil panicked")?;
    let firmware_status = board.wait().map_err(|error| error.to_string())?;
    if !firmware_status.success() {
        return Err(format!("the firmware ended with {firmware_status}").into());
    }
    if !report.success() {
        return Err("the firmware-in-the-loop check failed".into());
    }
    relayed.map_err(|error| format!("cannot pass the log on to host-sim hil: {error}"))?;
    Ok(())
}

/// The closed-loop image (or with `--open-loop` the `cosim` image) under QEMU driving the plate
/// of `plant` in lockstep (`host-sim cosim`); its decoded log goes to target/cosim-run.log, for
/// `host-sim hil --input`. The plant file and the scenario are checked first.
fn run_plant(plant: &Path, args: &RunArgs) -> Result {
    PlantFile::from_path(plant).map_err(|error| Failure::Refused(error.to_string()))?;
    checked_scenario(&args.scenario, !args.open_loop)?;
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
    let image = match args.open_loop {
        true => qemu::Image::Cosim,
        false => qemu::Image::ClosedLoop,
    };
    let elf = qemu::build_firmware(image)?;
    exec(cargo().args(["build", "--release", "--locked", "--package", "host-sim"]))?;
    let mut cosim = host_sim();
    cosim
        .args(["cosim", "--elf"])
        .arg(&elf)
        .arg("--plant")
        .arg(std::path::absolute(plant).map_err(|error| error.to_string())?)
        .arg("--log")
        .arg(root().join("target").join("cosim-run.log"));
    if args.open_loop {
        cosim.arg("--open-loop");
    }
    exec_output(cosim.args(&args.hil_flags).arg("--").args(&args.scenario))
}

fn test() -> Result {
    exec(cargo().args(["test", "--workspace", "--locked"]))?;
    exec(&mut fuzz_check())?;
    exec(
        cargo()
            .args([
                "test",
                "--locked",
                "--package",
                "xtask",
                "--test",
                "run_output",
            ])
            .args(["--", "--ignored"]),
    )?;
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
    exec(firmware_cargo().args(["build", "--release", "--locked"]))?;
    exec(
        firmware_cargo()
            .args(["build", "--release", "--locked", "--features", "console"])
            .args(["--target-dir", "target/console"]),
    )?;
    firmware_size(&mut io::stderr())?;
    tools::ensure_emulation()?;
    let scripted = qemu::build_firmware(qemu::Image::Scripted)?;
    exec(&mut ignored_tests("feeder-tests", "qemu", &scripted))?;
    let cosim = qemu::build_firmware(qemu::Image::Cosim)?;
    let closed_loop = qemu::build_firmware(qemu::Image::ClosedLoop)?;
    exec(
        ignored_tests("feeder-tests", "cosim", &cosim)
            .env("FEEDER_COSIM_ELF", &cosim)
            .env("FEEDER_CLOSED_LOOP_ELF", &closed_loop),
    )?;
    let console = qemu::build_firmware(qemu::Image::Console)?;
    exec(&mut ignored_tests("feeder-ctl", "qemu_session", &console))?;
    let seed = std::env::var_os("FEEDER_SOAK_SEED")
        .is_none()
        .then_some(TEST_SOAK_SEED);
    soak(&console, &SoakArgs { cycles: None, seed })
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

/// The soak's seed in `test`, so that every run sends the same operator lines (the firmware's
/// timing against them still varies); `FEEDER_SOAK_SEED` or `cargo xtask soak` choose others.
const TEST_SOAK_SEED: u64 = 3_709_873_859_707_123_073;

/// `cargo test` of the tests of `package`'s `test` target that need the QEMU firmware `elf`.
fn ignored_tests(package: &str, test: &str, elf: &Path) -> Command {
    let mut command = cargo();
    command
        .args(["test", "--locked", "--package", package, "--test", test])
        .args(["--", "--ignored"])
        .env("FEEDER_QEMU_ELF", elf);
    command
}

/// Builds the console image and runs the soak on it.
fn soak_alone(args: &SoakArgs) -> Result {
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
    let elf = qemu::build_firmware(qemu::Image::Console)?;
    soak(&elf, args)
}

/// The random-operator soak (`ctl/tests/soak`) against the console image `elf`, its progress
/// shown as it runs; unset arguments leave FEEDER_SOAK_CYCLES and FEEDER_SOAK_SEED to the
/// environment.
fn soak(elf: &Path, args: &SoakArgs) -> Result {
    let mut command = ignored_tests("feeder-ctl", "soak", elf);
    command.arg("--nocapture");
    if let Some(cycles) = args.cycles {
        command.env("FEEDER_SOAK_CYCLES", cycles.to_string());
    }
    if let Some(seed) = args.seed {
        command.env("FEEDER_SOAK_SEED", seed.to_string());
    }
    exec(&mut command)
}

/// Writes the flash and static RAM of both board images against their budgets to `out`; fails
/// if one is over.
fn firmware_size(out: &mut dyn io::Write) -> Result {
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
        writeln!(out, "{image} image: {}", report.against(&budget))
            .map_err(|error| format!("cannot write the size report: {error}"))?;
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
    fn console_takes_no_arguments() {
        assert!(matches!(
            parse(&["console"]).expect("accepted").task,
            Task::Console
        ));
        assert!(parse(&["console", "cycles=5"]).is_err());
    }

    #[test]
    fn bless_takes_no_arguments() {
        assert!(matches!(
            parse(&["bless"]).expect("accepted").task,
            Task::Bless
        ));
        assert!(parse(&["bless", "cycles=5"]).is_err());
    }

    #[test]
    fn a_soak_of_zero_cycles_is_refused() {
        let Task::Soak(args) = parse(&["soak", "--cycles", "1000000", "--seed", "7"])
            .expect("accepted")
            .task
        else {
            panic!("not a soak");
        };
        assert_eq!((args.cycles, args.seed), (Some(1_000_000), Some(7)));
        assert!(parse(&["soak", "--cycles", "0"]).is_err());
    }

    #[test]
    fn a_command_is_shown_as_typed_in_a_shell() {
        let mut command = Command::new("/toolchain/bin/cargo");
        command.current_dir(root().join("firmware")).args([
            "run",
            "--",
            "--tcp",
            "127.0.0.1:42493",
            "a b",
            "it's",
            "",
        ]);
        assert_eq!(
            shown(&command),
            r"cd firmware && cargo run -- --tcp 127.0.0.1:42493 'a b' 'it'\''s' ''"
        );
        let mut command = cargo();
        command.arg("line\nbreak");
        assert_eq!(shown(&command), "cargo 'line\nbreak'");
    }

    #[test]
    fn a_failed_command_is_named_in_a_few_words() {
        let mut cosim = host_sim();
        cosim.args(["cosim", "--elf", "fw.elf", "--plant", "plate.toml"]);
        assert_eq!(brief(&cosim), "cargo run --package host-sim -- cosim");
        assert_eq!(
            brief(firmware_cargo().args(["build", "--release", "--locked"])),
            "cargo build"
        );
    }

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

    #[test]
    fn a_negative_scenario_value_is_refused_with_the_word_named() {
        let error = parse(&["run", "cycles=-5"])
            .err()
            .expect("refused")
            .to_string();
        assert!(
            error.contains("cycles=-5: cycles must be a whole number from 1"),
            "{error}"
        );
        let error = parse(&["run", "duty=-inf"])
            .err()
            .expect("refused")
            .to_string();
        assert!(error.contains("duty=-inf"), "{error}");
    }
}
