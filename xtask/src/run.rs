//! `cargo xtask run`: the main job. The prediction at the paper's operating point, then the
//! firmware under QEMU driving the simulated part, checked edge by edge by `host-sim hil`; with
//! `--plant`, the firmware driving a real plate in lockstep with `host-sim cosim`.

use std::io::{self, IsTerminal};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::thread;

use clap::Args;
use feeder_emulator::{Board, Serial};
use feeder_shared::scenario::{parse_setting, qemu_clock, Scenario, SCENARIO_KEYS};
use feeder_shared::DacCalibration;
use feeder_shared::Friction;
use host_sim::plate::PlantFile;

use crate::command::{cargo, exec, exec_output, host_sim, root, shown};
use crate::failure::{Failure, Result};
use crate::progress::Meter;
use crate::{qemu, tools, twin};

/// The flags of `cargo xtask run`.
#[derive(Args)]
#[command(after_help = scenario_help())]
pub struct RunArgs {
    /// The board that runs the firmware: QEMU's mps2-an386 with the emulated board's image, or
    /// the NUCLEO-G474RE's own release image on the register-level twin (`twin/`), started and
    /// stopped with its user button (the scenario takes `cycles=N` alone).
    #[arg(long, value_enum, default_value_t = BoardChoice::Qemu)]
    board: BoardChoice,
    /// With `--board g474`: the image's features, as `cd firmware && cargo build --release
    /// --features …` takes them (`output-pwm` for the PWM stage).
    #[arg(long, value_delimiter = ',', value_name = "FEATURES")]
    features: Vec<String>,
    /// Drive a real plate from this plant file (host-sim/plants/) instead: the QEMU image with
    /// the plant's encoder, running the closed loop, in lockstep with `host-sim cosim`, which
    /// reports the plate's motion and ends with `closed loop: PASSED` or `FAILED (…)`; with
    /// `--board g474`, the G474's encoder image on the twin with the plate on its pins, judged
    /// alike.
    #[arg(long, value_name = "FILE")]
    plant: Option<PathBuf>,
    /// With --plant: the image without an encoder, whose command runs as planned, with no
    /// correction; the report shows where the plate went.
    #[arg(long, requires = "plant")]
    open_loop: bool,
    /// Settings of the emulated run's scripted operator (keys below).
    #[arg(value_name = "KEY=VALUE", value_parser = scenario_word)]
    pub scenario: Vec<String>,
    /// Flags for `host-sim hil`, after `--` (e.g. `-- --json`).
    #[arg(last = true, value_name = "HIL FLAGS")]
    pub hil_flags: Vec<String>,
}

/// Where `cargo xtask run` runs the firmware.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum BoardChoice {
    Qemu,
    G474,
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
pub fn run(args: &RunArgs) -> Result {
    if args.board == BoardChoice::G474 {
        if args.plant.is_some() && (args.open_loop || !args.hil_flags.is_empty()) {
            return Err(Failure::Refused(
                "--plant on the twin runs the encoder image's closed loop, judged by the twin \
                 itself: it takes neither --open-loop nor flags after --"
                    .into(),
            ));
        }
        return match &args.plant {
            Some(plant) => twin::run_plant(plant, &args.scenario, &args.features),
            None => twin::run(&args.scenario, &args.features, &args.hil_flags),
        };
    }
    if !args.features.is_empty() {
        return Err(Failure::Refused(
            "--features chooses the G474 image's features: it needs --board g474".into(),
        ));
    }
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
    let mut board = Board::start(
        &elf,
        &args.scenario,
        Serial::None,
        Stdio::piped(),
        &root().join("target"),
    )
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
    // The part the firmware is configured for, unless the flags name another.
    if !args.hil_flags.iter().any(|flag| flag == "--mu") {
        cosim.args(["--mu", &Friction::CONFIGURED.mu.to_string()]);
    }
    exec_output(cosim.args(&args.hil_flags).arg("--").args(&args.scenario))
}
