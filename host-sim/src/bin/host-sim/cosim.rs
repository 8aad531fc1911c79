//! `host-sim cosim`: the emulated firmware (the QEMU `cosim` image) driving a real plate in
//! lockstep: every level its output applies moves the plate from its tick on, and at every cycle
//! start the firmware reads the plate's encoder. The image with the plant's encoder (`--features
//! encoder`) runs the closed loop, judged at the end (`closed loop: PASSED` or `FAILED (…)`);
//! without it (`--open-loop`) the command runs as planned, and the run fails where the plate hit
//! an end stop (`open loop: FAILED (end stop …)`). Exit code 1 for a failed run.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;
use feeder_emulator::plant_link::{Plant, TICK_HZ};
use feeder_shared::DacCalibration;
use host_sim::closed_loop::Verdict;
use host_sim::cosim::{
    closed_loop_lines, cycles, judge, CosimCycle, LoopLog, PlatePlant, PlateSample, PlateState,
    RunOut, RunOutcome, Timeline,
};
use host_sim::plate::{EndStop, PlantFile};
use host_sim::SimError;
use indicatif::ProgressBar;
use serde::Serialize;

use crate::args::{ContactArgs, OutputArgs};
use crate::output::{check_writable, emit, file_name, join_failures, say, spinner};
use crate::plot::{self, Mark, Panel, Series};
use crate::simulate::end_stop_failure;

/// The longest co-simulation before it is stopped.
const LIMIT: Duration = Duration::from_secs(3600);

/// The flags of `host-sim cosim`.
#[derive(Args)]
#[command(
    after_help = "Exit code 0 when the run passes (the closed loop's criteria, as closed-loop \
                  judges them; with --open-loop, no end stop), 1 when it fails them, 2 when it \
                  cannot be run or an output file could not be written (after the report)."
)]
pub struct CosimArgs {
    /// The firmware image: an ELF built with `--features cosim-encoder` (the closed loop) or, with
    /// `--open-loop`, `--features cosim`.
    #[arg(long, value_name = "FILE")]
    elf: PathBuf,
    /// The plate as a TOML plant file with a `[sensors.encoder]` table.
    #[arg(long, value_name = "FILE")]
    plant: PathBuf,
    /// The image has no encoder: its command runs as planned, with no correction; the report
    /// shows where the plate went.
    #[arg(long)]
    open_loop: bool,
    /// Also write the firmware's decoded event log to this file (for `host-sim hil --input`).
    #[arg(long, value_name = "FILE")]
    log: Option<PathBuf>,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    output: OutputArgs,
    /// Settings of the emulated run's scripted operator, after `--` (`cargo xtask run --help`
    /// lists them).
    #[arg(last = true, value_name = "KEY=VALUE", allow_hyphen_values = true)]
    scenario: Vec<String>,
}

#[derive(Serialize)]
struct CosimReport {
    /// The closed loop's verdict; in open loop, true unless the plate hit an end stop.
    passed: bool,
    /// The verdict as one line.
    verdict_line: String,
    plant: PathBuf,
    open_loop: bool,
    /// Cycle starts at which the firmware read the encoder.
    samples: usize,
    /// The firmware's time at the last sample.
    simulated_s: f64,
    wall_s: f64,
    plate_peak_excursion_m: f64,
    /// The plate where the run ended: at rest once a stop has been carried out.
    plate_at_end: PlateState,
    /// The plate run on from there, its drive as the firmware left it, until it rests.
    plate_after_end: RunOut,
    /// When the plate hit an end stop; null if it never did.
    end_stop_after_s: Option<f64>,
    end_stop: Option<EndStop>,
    firmware_exit_code: Option<i32>,
    /// The closed loop: what the firmware logged of it, and the verdict.
    closed_loop: Option<ClosedLoopReport>,
}

#[derive(Serialize)]
struct ClosedLoopReport {
    log: LoopLog,
    verdict: Verdict,
}

/// How long the plate is run on after the firmware's end, at most, to see it come to rest.
const RUN_OUT_LIMIT_S: f64 = 2.0;

/// The plate served to the firmware, showing on a spinner how far the run has come: the cycle
/// starts the firmware has sampled and the plate's time, against the wall time.
struct Watched {
    plant: PlatePlant,
    bar: ProgressBar,
    cycle_starts: u64,
}

impl Plant for Watched {
    fn level(&mut self, tick: u64, code: i32) {
        self.plant.level(tick, code);
    }

    fn enable(&mut self, tick: u64, on: bool) {
        self.plant.enable(tick, on);
    }

    fn sample(&mut self, tick: u64) -> i32 {
        self.cycle_starts += 1;
        if !self.bar.is_hidden() {
            self.bar.set_message(format!(
                "co-simulation: cycle start {}, {:.2} s of plate time",
                self.cycle_starts,
                tick as f64 / f64::from(TICK_HZ)
            ));
        }
        self.plant.sample(tick)
    }

    fn configure(&mut self, interval_ticks: u64, resolution_nm: i32) -> Result<(), String> {
        self.plant.configure(interval_ticks, resolution_nm)
    }

    fn stream(&mut self, tick: u64) -> Vec<(u64, i32)> {
        self.plant.stream(tick)
    }
}

/// Runs `host-sim cosim`; false when the closed loop failed its figures (the report is out).
pub fn run(args: &CosimArgs) -> Result<bool, SimError> {
    args.output.check()?;
    if let Some(path) = &args.log {
        check_writable(path)?;
    }
    let plant_file = PlantFile::from_path(&args.plant)?;
    let plant = PlatePlant::new(
        &plant_file,
        &args.contact.contact()?,
        DacCalibration::DEFAULT,
        TICK_HZ,
    )?;
    let started = Instant::now();
    let watched = Watched {
        plant,
        bar: spinner(args.output.json),
        cycle_starts: 0,
    };
    let mut run = feeder_emulator::run_with_plant(&args.elf, &args.scenario, LIMIT, watched)
        .map_err(|error| SimError::Request(format!("the co-simulation failed: {error}")))?;
    run.plant.bar.finish_and_clear();
    let wall_s = started.elapsed().as_secs_f64();
    let log_written = args.log.as_deref().map_or(Ok(()), |path| {
        std::fs::write(path, &run.run.log).map_err(|error| SimError::Output {
            path: path.display().to_string(),
            reason: error.to_string(),
        })
    });
    let plate = &run.plant.plant;
    if let Some(error) = plate.error() {
        return join_failures([Err(error.clone()), log_written]).map(|()| false);
    }
    let samples = plate.samples().to_vec();
    let levels = plate.levels().to_vec();
    let closed_loop = match args.open_loop {
        true => None,
        false => {
            let (log, verdict) = judge(
                &run.run.log,
                plate,
                &plant_file,
                &args.contact.contact()?,
                Timeline::SAME,
            )?;
            Some(ClosedLoopReport { log, verdict })
        }
    };
    let simulated_s = samples
        .last()
        .map_or(0.0, |s| s.tick as f64 / f64::from(TICK_HZ));
    let (passed, verdict_line) = match &closed_loop {
        Some(report) => (report.verdict.passed, report.verdict.line()),
        None => open_loop_verdict(plate.end_stop(), simulated_s, plate.peak_excursion_m()),
    };
    let (peak_excursion_m, plate_at_end, end_stop) = (
        plate.peak_excursion_m(),
        plate.last_state(),
        plate.end_stop(),
    );
    let plate_after_end = run.plant.plant.run_out(RUN_OUT_LIMIT_S);
    let report = CosimReport {
        passed,
        verdict_line,
        plant: args.plant.clone(),
        open_loop: args.open_loop,
        samples: samples.len(),
        simulated_s,
        wall_s,
        plate_peak_excursion_m: peak_excursion_m,
        plate_at_end,
        plate_after_end,
        end_stop_after_s: end_stop.map(|stop| stop.time_s),
        end_stop,
        firmware_exit_code: run.run.status.code(),
        closed_loop,
    };
    let cycles = cycles(&samples, &levels);
    let emitted = emit(
        &args.output,
        &cycles,
        |path| plot_run(path, &report, &cycles),
        &report,
        || print_report(&report, &samples),
    );
    join_failures([emitted, log_written]).map(|()| passed)
}

/// The plate's cycle mean position and the levels the firmware applied, cycle by cycle: the
/// zero level (the loop's bias) and the `±a` levels.
fn plot_run(path: &Path, report: &CosimReport, cycles: &[CosimCycle]) -> Result<(), SimError> {
    let over_time = |value: fn(&CosimCycle) -> f64| -> Vec<(f64, f64)> {
        cycles.iter().map(|c| (c.time_s, value(c))).collect()
    };
    let end_s = cycles.last().map_or(0.0, |c| c.time_s);
    let panels = [
        plot::mean_position_panel(
            "plate's mean position over each cycle",
            over_time(|c| c.mean_position_m * 1e6),
            report.closed_loop.as_ref().map(|_| 0.0..end_s),
        ),
        Panel {
            y: "zero level (m/s²)",
            series: vec![Series::new(
                "the zero level as applied: the loop's bias",
                over_time(|c| c.zero_mps2),
                Mark::ThinLine,
                2,
            )],
        },
        Panel {
            y: "±a levels (m/s²)",
            series: vec![
                Series::new(
                    "+a as applied",
                    over_time(|c| c.positive_mps2),
                    Mark::ThinLine,
                    3,
                ),
                Series::new(
                    "−a as applied (magnitude)",
                    over_time(|c| -c.negative_mps2),
                    Mark::ThinLine,
                    4,
                ),
            ],
        },
    ];
    let plant = file_name(&report.plant);
    let mode = if report.open_loop {
        "open loop"
    } else {
        "closed loop"
    };
    let title = format!("Emulated firmware on {plant}, {mode}, in lockstep");
    plot::stacked(path, &title, "time (s)", &panels)
}

fn print_report(report: &CosimReport, samples: &[PlateSample]) {
    say!("plant             {}", report.plant.display());
    say!(
        "run               {} cycle starts, {:.3} s simulated in {:.2} s ({:.1}× real time)",
        report.samples,
        report.simulated_s,
        report.wall_s,
        report.simulated_s / report.wall_s.max(1e-9)
    );
    if let (Some(first), Some(last)) = (samples.first(), samples.last()) {
        say!(
            "plate             {:.1} µm at the first cycle start, {:.1} µm at the last, peak |x| {:.3} mm",
            first.position_m * 1e6,
            last.position_m * 1e6,
            report.plate_peak_excursion_m * 1e3
        );
    }
    let end = report.plate_at_end;
    say!(
        "plate at the end  {:.1} µm, {:.1} mm/s at {:.3} s",
        end.position_m * 1e6,
        end.velocity_mps * 1e3,
        end.time_s
    );
    let out = report.plate_after_end;
    let driver = if out.driver_enabled { "on" } else { "off" };
    let position_um = out.state.position_m * 1e6;
    say!(
        "after the end     driver {driver}: {}",
        match out.outcome {
            RunOutcome::AtRest => format!(
                "the plate at rest at {position_um:.1} µm, {:.3} s on",
                out.after_s
            ),
            RunOutcome::EndStop => format!("the plate in its end stop {:.3} s on", out.after_s),
            RunOutcome::StillMoving => format!(
                "the plate still moving at {:.1} mm/s at {position_um:.1} µm, {:.3} s on",
                out.state.velocity_mps * 1e3,
                out.after_s
            ),
        }
    );
    say!(
        "firmware          exit code {}",
        report
            .firmware_exit_code
            .map_or("none (killed)".to_string(), |code| code.to_string())
    );
    if let Some(closed) = &report.closed_loop {
        print_closed_loop(closed);
    }
    say!("{}", report.verdict_line);
}

/// The open-loop run's verdict and its line: it fails where the plate hit an end stop.
fn open_loop_verdict(
    end_stop: Option<EndStop>,
    simulated_s: f64,
    peak_excursion_m: f64,
) -> (bool, String) {
    match end_stop {
        Some(stop) => (
            false,
            format!("open loop: FAILED ({})", end_stop_failure(&stop)),
        ),
        None => (
            true,
            format!(
                "open loop: PASSED (no end stop in {simulated_s:.3} s, peak |x| {:.3} mm)",
                peak_excursion_m * 1e3
            ),
        ),
    }
}

fn print_closed_loop(closed: &ClosedLoopReport) {
    for line in closed_loop_lines(&closed.log, &closed.verdict) {
        say!("{line}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_open_loop_run_into_an_end_stop_fails_naming_it() {
        let stop = EndStop {
            time_s: 0.1828,
            position_m: 0.005,
            velocity_mps: 0.157,
        };
        assert_eq!(
            open_loop_verdict(Some(stop), 2.0, 0.005),
            (
                false,
                "open loop: FAILED (end stop at +5.0 mm after 0.1828 s, at +0.157 m/s)".into()
            )
        );
        assert_eq!(
            open_loop_verdict(None, 2.0, 0.0023),
            (
                true,
                "open loop: PASSED (no end stop in 2.000 s, peak |x| 2.300 mm)".into()
            )
        );
    }
}
