//! `host-sim simulate`: one operating point to steady state (or for `--cycles N`), beside the
//! analytic models.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use feeder_shared::model::Regime;
use host_sim::plate::{EndStop, PlateParams, PlateRun};
use host_sim::{OperatingPoint, RunOptions, SimError, Timing};
use serde::Serialize;

use crate::args::{
    plate_options, CountArg, DriveLimitArgs, OutputArgs, PlantArgs, PointArgs, PLATE_CYCLES,
};
use crate::output::{emit, say};
use crate::trace::plot_trace;

/// Cycles of steady motion drawn by `--plot`.
const PLOT_CYCLES: u64 = 3;
/// Most cycles of `--cycles`: about a second of simulation, a few more with `--csv`.
const MAX_CYCLES: u64 = 10_000_000;

/// The flags of `host-sim simulate`.
#[derive(Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    point: PointArgs<DriveLimitArgs>,
    /// Run exactly N cycles (at most 10 000 000) instead of detecting steady state.
    #[arg(long, count_in = (1, MAX_CYCLES))]
    cycles: Option<u64>,
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    output: OutputArgs,
}

/// What `--plant` adds: the plate's own motion under the open-loop command.
#[derive(Serialize)]
pub struct PlantReport {
    plant: PathBuf,
    open_loop: bool,
    /// Mean plate position over the last averaged cycles.
    plate_mean_position_m: f64,
    /// Largest distance of the plate from the centre over the run.
    plate_peak_excursion_m: f64,
    /// When the plate hit an end stop; null if it never did.
    end_stop_after_s: Option<f64>,
    pub end_stop: Option<EndStop>,
}

impl PlantReport {
    pub fn new(path: &Path, run: &PlateRun) -> Self {
        PlantReport {
            plant: path.to_path_buf(),
            open_loop: true,
            plate_mean_position_m: run.mean_position_m,
            plate_peak_excursion_m: run.peak_excursion_m,
            end_stop_after_s: run.end_stop.map(|stop| stop.time_s),
            end_stop: run.end_stop,
        }
    }
}

#[derive(Serialize)]
struct SimulateReport {
    feed_rate_mps: f64,
    model_feed_rate_mps: Option<f64>,
    quasi_static_feed_rate_mps: f64,
    regime: &'static str,
    /// Null on a real plate, whose solver does not count it.
    stick_fraction: Option<f64>,
    model_stick_fraction: f64,
    cycles: u64,
    converged: bool,
    freq_hz: f64,
    duty: f64,
    accel_mps2: f64,
    stroke_m: f64,
    duty_sat_nqs: f64,
    /// Why the waveform is beyond the machine's drive limits (run with --no-drive-limits); null
    /// within them.
    beyond_drive_limits: Option<String>,
    mu: f64,
    mu_static: f64,
    gravity_mps2: f64,
    mass_kg: f64,
    force_n: f64,
    clock_hz: Option<u32>,
    /// The ideal plate's peak-to-peak travel; null on a real plate (see its own fields).
    plate_excursion_m: Option<f64>,
    cycles_per_s: f64,
    #[serde(flatten)]
    plant: Option<PlantReport>,
}

/// What a run measured, beside the operating point and the model.
struct Measured {
    feed_rate_mps: f64,
    stick_fraction: Option<f64>,
    cycles: u64,
    converged: bool,
    plate_excursion_m: Option<f64>,
    cycles_per_s: f64,
}

impl SimulateReport {
    /// The report of `measured` at `point`, with the shared model's prediction beside it.
    fn new(
        point: &OperatingPoint,
        measured: Measured,
        beyond_drive_limits: Option<String>,
        plant: Option<PlantReport>,
    ) -> Self {
        let prediction = point.model();
        SimulateReport {
            feed_rate_mps: measured.feed_rate_mps,
            model_feed_rate_mps: prediction.feed_rate_mps,
            quasi_static_feed_rate_mps: prediction.quasi_static_feed_rate_mps,
            regime: regime_name(prediction.regime),
            stick_fraction: measured.stick_fraction,
            model_stick_fraction: prediction.stick_fraction,
            cycles: measured.cycles,
            converged: measured.converged,
            freq_hz: point.waveform.frequency_hz(),
            duty: point.waveform.duty,
            accel_mps2: point.waveform.accel_mps2,
            stroke_m: point.waveform.stroke_m,
            duty_sat_nqs: prediction.duty_sat_nqs,
            beyond_drive_limits,
            mu: point.contact.mu,
            mu_static: point.contact.mu_static,
            gravity_mps2: point.contact.gravity_mps2,
            mass_kg: point.contact.mass_kg,
            force_n: point.contact.force_n,
            clock_hz: clock_hz(point),
            plate_excursion_m: measured.plate_excursion_m,
            cycles_per_s: measured.cycles_per_s,
            plant,
        }
    }
}

/// Runs `host-sim simulate`.
pub fn run(args: &SimulateArgs) -> Result<(), SimError> {
    args.output.check()?;
    let (point, beyond) = args.point.limited_point()?;
    match args.plant.plate()? {
        Some((path, params)) if !params.is_ideal() => {
            run_real_plate(args, &point, beyond, path, &params)
        }
        ideal => run_ideal_plate(args, &point, beyond, ideal),
    }
}

/// Today's exact piecewise-linear simulator; with an ideal `--plant`, also the plate's motion.
fn run_ideal_plate(
    args: &SimulateArgs,
    point: &OperatingPoint,
    beyond_drive_limits: Option<String>,
    plant: Option<(&Path, PlateParams)>,
) -> Result<(), SimError> {
    let options = RunOptions {
        fixed_cycles: args.cycles,
        record_cycles: args.output.csv.is_some(),
        ..RunOptions::converge(point.default_criteria())
    };
    let started = Instant::now();
    let run = point.run(&options);
    let elapsed_s = started.elapsed().as_secs_f64().max(1e-9);
    let plant = match plant {
        Some((path, params)) => {
            let plate_run = point.run_plate(&params, &plate_options(run.cycles))?;
            Some(PlantReport::new(path, &plate_run))
        }
        None => None,
    };
    let report = SimulateReport::new(
        point,
        Measured {
            feed_rate_mps: run.feed_rate_mps,
            stick_fraction: Some(run.stick_fraction),
            cycles: run.cycles,
            converged: run.converged,
            plate_excursion_m: Some(run.plate_excursion_m),
            cycles_per_s: run.cycles as f64 / elapsed_s,
        },
        beyond_drive_limits,
        plant,
    );
    // Continues from the final state for a few cycles with the event trace on.
    let plot = |path: &Path| {
        let steady = RunOptions {
            fixed_cycles: Some(PLOT_CYCLES),
            trace: true,
            initial_rel_velocity_mps: run.final_rel_velocity_mps,
            ..RunOptions::converge(point.default_criteria())
        };
        let title = format!(
            "Steady state: {} Hz, d = {}, a_max = {:.1} m/s², μ = {} — feed {:.2} mm/s",
            report.freq_hz,
            report.duty,
            report.accel_mps2,
            report.mu,
            report.feed_rate_mps * 1e3
        );
        plot_trace(
            path,
            &title,
            &point.run(&steady).trace,
            Some(report.feed_rate_mps),
        )
    };
    emit(&args.output, &run.cycle_stats, plot, &report, || {
        print_simulation(&report, point, &args.output)
    })
}

/// A plate with non-idealities under the open-loop command, for `--cycles` or until an end stop.
fn run_real_plate(
    args: &SimulateArgs,
    point: &OperatingPoint,
    beyond_drive_limits: Option<String>,
    path: &Path,
    params: &PlateParams,
) -> Result<(), SimError> {
    if args.output.csv.is_some() || args.output.plot.is_some() {
        return Err(SimError::BadRange {
            what: "--csv and --plot show the ideal plate's cycles: leave them out with a plant \
                   that is not ideal",
        });
    }
    let started = Instant::now();
    let run = point.run_plate(params, &plate_options(args.cycles.unwrap_or(PLATE_CYCLES)))?;
    let elapsed_s = started.elapsed().as_secs_f64().max(1e-9);
    let report = SimulateReport::new(
        point,
        Measured {
            feed_rate_mps: run.feed_rate_mps,
            stick_fraction: None,
            cycles: run.cycles,
            converged: false,
            plate_excursion_m: None,
            cycles_per_s: run.cycles as f64 / elapsed_s,
        },
        beyond_drive_limits,
        Some(PlantReport::new(path, &run)),
    );
    let rows: [(); 0] = [];
    emit(
        &args.output,
        &rows,
        |_| Ok(()),
        &report,
        || print_simulation(&report, point, &args.output),
    )
}

fn clock_hz(point: &OperatingPoint) -> Option<u32> {
    match point.timing {
        Timing::Exact => None,
        Timing::Ticks(plan) => Some(plan.clock_hz),
    }
}

pub fn print_plant(plant: &PlantReport) {
    say!("plant             {} (open loop)", plant.plant.display());
    say!(
        "plate position    mean {:.6} mm over the last cycles, peak {:.6} mm from the centre",
        plant.plate_mean_position_m * 1e3,
        plant.plate_peak_excursion_m * 1e3
    );
    match plant.end_stop {
        Some(stop) => say!(
            "end stop          HIT after {:.6} s at {:+.3} mm, plate at {:+.4} m/s: the run ends there",
            stop.time_s,
            stop.position_m * 1e3,
            stop.velocity_mps
        ),
        None => say!("end stop          not reached"),
    }
}

/// An end stop as a verdict names it.
pub fn end_stop_failure(stop: &EndStop) -> String {
    format!(
        "end stop at {:+.1} mm after {:.4} s, at {:+.3} m/s",
        stop.position_m * 1e3,
        stop.time_s,
        stop.velocity_mps
    )
}

fn regime_name(regime: Regime) -> &'static str {
    match regime {
        Regime::Stuck => "stuck",
        Regime::Sliding => "sliding",
        Regime::Saturated => "saturated",
    }
}

fn print_simulation(report: &SimulateReport, point: &OperatingPoint, output: &OutputArgs) {
    let drive = format!(
        "stroke {:.4} mm, a_max {:.3} m/s² ({:.2} g)",
        report.stroke_m * 1e3,
        report.accel_mps2,
        report.accel_mps2 / report.gravity_mps2
    );
    say!(
        "operating point   {} Hz, d = {}, {drive}",
        report.freq_hz,
        report.duty
    );
    if let Some(reason) = &report.beyond_drive_limits {
        say!("drive limits      beyond them, lifted by --no-drive-limits: {reason}");
    }
    say!(
        "contact           μ = {}, μ_s = {}, g = {} m/s², m = {} kg, f_ext = {} N",
        report.mu,
        report.mu_static,
        report.gravity_mps2,
        report.mass_kg,
        report.force_n
    );
    match point.timing {
        Timing::Exact => say!("timing            exact switching times"),
        Timing::Ticks(plan) => say!(
            "timing            tick plan, {} Hz clock, {} ticks per period",
            plan.clock_hz,
            plan.period_ticks
        ),
    }
    let equation = match point.model().regime {
        Regime::Stuck => "a ≤ μg",
        Regime::Sliding => "Eq. 15",
        Regime::Saturated => "Eq. 18",
    };
    say!(
        "feed rate         {:.6} mm/s (simulated)",
        report.feed_rate_mps * 1e3
    );
    match report.model_feed_rate_mps {
        Some(model) => {
            say!(
                "model             {:.6} mm/s ({equation}, {} regime, d_sat,nqs = {:.4})",
                model * 1e3,
                report.regime,
                report.duty_sat_nqs
            );
            if model != 0.0 {
                say!(
                    "difference        {:.2e} relative",
                    report.feed_rate_mps / model - 1.0
                );
            }
        }
        None => say!("model             outside the linear viscous law (the part sticks)"),
    }
    say!(
        "quasi-static      {:.6} mm/s (Eq. 9)",
        report.quasi_static_feed_rate_mps * 1e3
    );
    if let Some(stick_fraction) = report.stick_fraction {
        say!(
            "stick fraction    {stick_fraction:.6} (model {:.6})",
            report.model_stick_fraction
        );
    }
    say!(
        "cycles            {} ({})",
        report.cycles,
        if report.converged {
            "converged"
        } else {
            "not converged"
        }
    );
    if let Some(excursion_m) = report.plate_excursion_m {
        say!("plate excursion   {:.6} mm", excursion_m * 1e3);
    }
    if let Some(plant) = &report.plant {
        print_plant(plant);
    }
    say!(
        "speed             {:.3e} simulated cycles/s",
        report.cycles_per_s
    );
    for (what, path) in output.files() {
        say!("{what:<18}{}", path.display());
    }
}
