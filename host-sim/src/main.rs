//! `host-sim`: predict a feeder before building it, and reproduce the paper's figures.

/// Prints a line to stdout; a closed pipe (`host-sim … | head`) ends the output quietly.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

mod hil_cli;
mod plot;

use std::fmt::Display;
use std::io::{IsTerminal, Write as _};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::str::FromStr;
use std::time::Instant;

use clap::error::ErrorKind;
use clap::{Args, Parser, Subcommand};
use feeder_shared::model::{Regime, STANDARD_GRAVITY_MPS2};
use feeder_shared::number::Significant;
use feeder_shared::{Drive, WaveformSpec};
use host_sim::figures::{self, SaturationPoint, SweepPoint, Viscosity};
use host_sim::sim::TracePoint;
use host_sim::{Contact, OperatingPoint, RunOptions, SimError, Timing};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use plot::{Labels, Mark, Series};
use serde::Serialize;

/// Timer clock of the tick plan when neither `--clock-hz` nor `--exact-times` is given.
const DEFAULT_CLOCK_HZ: u32 = 1_000_000;
/// Upper end of the swept duties: closer to 1 the first `+a` segment, `T(1 − d)²/(2(d + P/T))`,
/// gets shorter than a tick of a 1 MHz clock at 50 Hz and the tick plan is refused.
const SWEEP_MAX_DUTY: f64 = 0.98;
/// Cycles of steady motion drawn by `simulate --plot`.
const PLOT_CYCLES: u64 = 3;
/// Most operating points one command simulates to steady state: a_max values × duties for
/// `sweep`, forces for `viscosity`, a_max values × μ values for `saturation` (40 runs each).
const MAX_POINTS: usize = 10_000;
/// Most cycles of `simulate --cycles`: about a second of simulation, a few more with `--csv`.
const MAX_SIMULATE_CYCLES: u64 = 10_000_000;
/// Most cycles of `trace`, which keeps every event for the report and the plot.
const MAX_TRACE_CYCLES: u64 = 10_000;

#[derive(Parser)]
#[command(
    name = "host-sim",
    version,
    about = "Exact stick–slip simulator of the vibrating-plate parts feeder"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate one operating point to steady state (or for --cycles N).
    Simulate(SimulateArgs),
    /// Feed rate vs duty for one or more a_max, beside the models (Fig. 4, Fig. 9).
    Sweep(SweepArgs),
    /// Steady velocity vs external force and the least-squares viscosity K (Fig. 10, Eq. 10).
    Viscosity(ViscosityArgs),
    /// Saturation duty d_sat,nqs vs a_max for several μ, model and simulation (Fig. 7, Eq. 16).
    Saturation(SaturationArgs),
    /// Plate and part velocity through N cycles (Fig. 3, 5, 6, 8).
    Trace(TraceArgs),
    /// Check a running firmware's decoded event stream against the shared scheduler, edge by
    /// edge, and simulate the part on its actual edge times.
    Hil(hil_cli::HilArgs),
}

#[derive(Args, Clone)]
struct WaveArgs {
    /// Vibration frequency 1/T.
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true)]
    freq_hz: f64,
    /// Duty cycle d = F/T of the plate's velocity profile, in (0.5, 1).
    #[arg(long, default_value_t = 0.586, allow_hyphen_values = true)]
    duty: f64,
    /// Peak-to-peak plate stroke x_max (a_max follows from Eq. 5); default 2.5 mm.
    #[arg(long, conflicts_with = "accel_mps2", allow_hyphen_values = true)]
    stroke_m: Option<f64>,
    /// Peak plate acceleration a_max (the stroke follows from Eq. 5).
    #[arg(long, allow_hyphen_values = true)]
    accel_mps2: Option<f64>,
}

impl WaveArgs {
    fn spec(&self) -> Result<WaveformSpec, SimError> {
        let drive = match (self.accel_mps2, self.stroke_m) {
            (Some(accel_mps2), _) => Drive::Accel { accel_mps2 },
            (None, stroke_m) => Drive::Stroke {
                stroke_m: stroke_m.unwrap_or(0.0025),
            },
        };
        Ok(WaveformSpec {
            period_s: period_s(self.freq_hz)?,
            duty: self.duty,
            drive,
        })
    }
}

/// The period of a frequency from the command line, which must be finite and above zero.
fn period_s(frequency_hz: f64) -> Result<f64, SimError> {
    if frequency_hz.is_finite() && frequency_hz > 0.0 {
        Ok(1.0 / frequency_hz)
    } else {
        Err(SimError::BadFrequency { frequency_hz })
    }
}

/// A clap parser for a count from `min` to `max`; a refusal names the range.
fn count<T>(min: T, max: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static
where
    T: FromStr + PartialOrd + Display + Copy + Send + Sync + 'static,
{
    move |text| {
        text.parse()
            .ok()
            .filter(|count| (min..=max).contains(count))
            .ok_or_else(|| format!("expected a whole number from {min} to {max}"))
    }
}

/// Refuses `rows × columns` operating points beyond [`MAX_POINTS`]; `what` names the two flags.
fn check_grid(rows: usize, columns: usize, what: [&str; 2]) -> Result<(), SimError> {
    let points = rows.saturating_mul(columns);
    if points <= MAX_POINTS {
        return Ok(());
    }
    Err(SimError::Request(format!(
        "{rows} {} values × {} {columns} make {points} operating points; a run computes at most \
         {MAX_POINTS}",
        what[0], what[1]
    )))
}

#[derive(Args, Clone)]
struct ContactArgs {
    /// Kinetic friction coefficient μ.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    mu: f64,
    /// Static friction coefficient μ_s ≥ μ (default μ).
    #[arg(long, allow_hyphen_values = true)]
    mu_static: Option<f64>,
    #[arg(long, default_value_t = STANDARD_GRAVITY_MPS2, allow_hyphen_values = true)]
    gravity_mps2: f64,
    /// Part mass (the paper's 0.1 g by default).
    #[arg(long, default_value_t = 1e-4, allow_hyphen_values = true)]
    mass_kg: f64,
    /// Constant external force on the part along the feed direction.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    force_n: f64,
}

impl ContactArgs {
    fn contact(&self) -> Result<Contact, SimError> {
        let mu_static = self.mu_static.unwrap_or(self.mu);
        Contact::new(
            self.mu,
            mu_static,
            self.gravity_mps2,
            self.mass_kg,
            self.force_n,
        )
    }
}

#[derive(Args, Clone)]
struct TimingArgs {
    /// Drive the plate with the shared scheduler's tick plan at this timer clock (default 1 MHz).
    #[arg(long, conflicts_with = "exact_times", allow_hyphen_values = true)]
    clock_hz: Option<u32>,
    /// Use the waveform's exact real-valued switching times instead of a tick plan.
    #[arg(long)]
    exact_times: bool,
}

impl TimingArgs {
    fn clock_hz(&self) -> Option<u32> {
        if self.exact_times {
            None
        } else {
            Some(self.clock_hz.unwrap_or(DEFAULT_CLOCK_HZ))
        }
    }
}

#[derive(Args, Clone)]
struct OutputArgs {
    /// Print one JSON document instead of the human-readable report.
    #[arg(long)]
    json: bool,
    /// Also write the data as CSV to this file.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// Also draw a chart to this file (.svg or .png).
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
}

impl OutputArgs {
    /// Refuses a plot file format that cannot be written, before anything is computed.
    fn check(&self) -> Result<(), SimError> {
        self.plot.as_deref().map_or(Ok(()), plot::check_path)
    }
}

#[derive(Args)]
struct SimulateArgs {
    #[command(flatten)]
    wave: WaveArgs,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    timing: TimingArgs,
    /// Run exactly N cycles (at most 10 000 000) instead of detecting steady state.
    #[arg(
        long,
        value_name = "N",
        value_parser = count(1, MAX_SIMULATE_CYCLES),
        allow_hyphen_values = true
    )]
    cycles: Option<u64>,
    #[command(flatten)]
    output: OutputArgs,
}

#[derive(Args)]
struct SweepArgs {
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true)]
    freq_hz: f64,
    /// Peak accelerations to sweep, comma-separated (the paper's Fig. 9 by default).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "100,150,200",
        allow_hyphen_values = true
    )]
    accel_mps2: Vec<f64>,
    /// Number of duties, evenly spaced strictly inside (0.5, 0.98); at most 10 000 points in all.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 50,
        value_parser = count(1, MAX_POINTS),
        allow_hyphen_values = true
    )]
    duties: usize,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    timing: TimingArgs,
    #[command(flatten)]
    output: OutputArgs,
}

#[derive(Args)]
struct ViscosityArgs {
    /// The paper's Section IV.C: T = 0.01 s.
    #[arg(long, default_value_t = 100.0, allow_hyphen_values = true)]
    freq_hz: f64,
    /// d ≈ 0.5484, implied by the paper's fitted intercept (errata 10).
    #[arg(long, default_value_t = 0.5484, allow_hyphen_values = true)]
    duty: f64,
    #[arg(long, default_value_t = 100.0, allow_hyphen_values = true)]
    accel_mps2: f64,
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    mu: f64,
    #[arg(long, allow_hyphen_values = true)]
    mu_static: Option<f64>,
    #[arg(long, default_value_t = STANDARD_GRAVITY_MPS2, allow_hyphen_values = true)]
    gravity_mps2: f64,
    #[arg(long, default_value_t = 1e-4, allow_hyphen_values = true)]
    mass_kg: f64,
    /// Smallest force (−15 dyn by default).
    #[arg(long, default_value_t = -1.5e-4, allow_hyphen_values = true)]
    force_min_n: f64,
    /// Largest force (15 dyn by default).
    #[arg(long, default_value_t = 1.5e-4, allow_hyphen_values = true)]
    force_max_n: f64,
    /// Number of forces (2 to 10 000), evenly spaced including both ends.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 31,
        value_parser = count(2, MAX_POINTS),
        allow_hyphen_values = true
    )]
    points: usize,
    #[command(flatten)]
    timing: TimingArgs,
    #[command(flatten)]
    output: OutputArgs,
}

#[derive(Args)]
struct SaturationArgs {
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true)]
    freq_hz: f64,
    /// Friction coefficients, comma-separated, one curve each (the paper's Fig. 7 by default).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1,0.5,0.25",
        allow_hyphen_values = true
    )]
    mu: Vec<f64>,
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    accel_min_mps2: f64,
    #[arg(long, default_value_t = 200.0, allow_hyphen_values = true)]
    accel_max_mps2: f64,
    /// Number of a_max values (2 or more), evenly spaced including both ends; at most 10 000
    /// points in all.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 20,
        value_parser = count(2, MAX_POINTS),
        allow_hyphen_values = true
    )]
    points: usize,
    #[arg(long, default_value_t = STANDARD_GRAVITY_MPS2, allow_hyphen_values = true)]
    gravity_mps2: f64,
    #[command(flatten)]
    output: OutputArgs,
}

#[derive(Args)]
struct TraceArgs {
    #[command(flatten)]
    wave: WaveArgs,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    timing: TimingArgs,
    /// Cycles to trace from rest (at most 10 000).
    #[arg(
        long,
        value_name = "N",
        default_value_t = 5,
        value_parser = count(1, MAX_TRACE_CYCLES),
        allow_hyphen_values = true
    )]
    cycles: u64,
    #[command(flatten)]
    output: OutputArgs,
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error)
            if error.use_stderr()
                && error.kind() != ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand =>
        {
            return refuse(&usage_error(&error));
        }
        Err(error) => error.exit(),
    };
    let outcome = match cli.command {
        Command::Simulate(args) => simulate(&args),
        Command::Sweep(args) => sweep(&args),
        Command::Viscosity(args) => viscosity(&args),
        Command::Saturation(args) => saturation(&args),
        Command::Trace(args) => trace(&args),
        Command::Hil(args) => hil_cli::hil(&args),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => refuse(&format!("error: {error}")),
    }
}

/// Prints `message` as one line on stderr, control characters escaped, and exits with code 2.
fn refuse(message: &str) -> ExitCode {
    let mut line = String::with_capacity(message.len());
    for c in message.chars() {
        if c.is_control() {
            line.extend(c.escape_default());
        } else {
            line.push(c);
        }
    }
    let _ = writeln!(std::io::stderr().lock(), "{line}");
    ExitCode::from(2)
}

/// Clap's refusal as one line: the message and its tips, without the usage and the pointer to
/// `--help` that follow.
fn usage_error(error: &clap::Error) -> String {
    let rendered = error.render().to_string();
    let mut line = String::new();
    for part in rendered
        .lines()
        .map(str::trim)
        .take_while(|part| !part.starts_with("Usage:") && !part.starts_with("For more information"))
        .filter(|part| !part.is_empty())
    {
        if !line.is_empty() {
            line.push_str(if line.ends_with(':') { " " } else { "; " });
        }
        line.push_str(part);
    }
    line
}

#[derive(Serialize)]
struct SimulateReport {
    feed_rate_mps: f64,
    model_feed_rate_mps: Option<f64>,
    quasi_static_feed_rate_mps: f64,
    regime: &'static str,
    stick_fraction: f64,
    model_stick_fraction: f64,
    cycles: u64,
    converged: bool,
    freq_hz: f64,
    duty: f64,
    accel_mps2: f64,
    stroke_m: f64,
    duty_sat_nqs: f64,
    mu: f64,
    mu_static: f64,
    gravity_mps2: f64,
    mass_kg: f64,
    force_n: f64,
    clock_hz: Option<u32>,
    plate_excursion_m: f64,
    cycles_per_s: f64,
}

fn simulate(args: &SimulateArgs) -> Result<(), SimError> {
    args.output.check()?;
    let point = OperatingPoint::new(
        args.wave.spec()?,
        args.contact.contact()?,
        args.timing.clock_hz(),
    )?;
    let options = RunOptions {
        fixed_cycles: args.cycles,
        record_cycles: args.output.csv.is_some(),
        ..RunOptions::converge(point.default_criteria())
    };
    let started = Instant::now();
    let run = point.run(&options);
    let elapsed_s = started.elapsed().as_secs_f64().max(1e-9);
    let prediction = point.model();
    let report = SimulateReport {
        feed_rate_mps: run.feed_rate_mps,
        model_feed_rate_mps: prediction.feed_rate_mps,
        quasi_static_feed_rate_mps: prediction.quasi_static_feed_rate_mps,
        regime: regime_name(prediction.regime),
        stick_fraction: run.stick_fraction,
        model_stick_fraction: prediction.stick_fraction,
        cycles: run.cycles,
        converged: run.converged,
        freq_hz: point.waveform.frequency_hz(),
        duty: point.waveform.duty,
        accel_mps2: point.waveform.accel_mps2,
        stroke_m: point.waveform.stroke_m,
        duty_sat_nqs: prediction.duty_sat_nqs,
        mu: point.contact.mu,
        mu_static: point.contact.mu_static,
        gravity_mps2: point.contact.gravity_mps2,
        mass_kg: point.contact.mass_kg,
        force_n: point.contact.force_n,
        clock_hz: match point.timing {
            Timing::Exact => None,
            Timing::Ticks(plan) => Some(plan.clock_hz),
        },
        plate_excursion_m: run.plate_excursion_m,
        cycles_per_s: run.cycles as f64 / elapsed_s,
    };
    if let Some(path) = &args.output.csv {
        write_csv(path, &run.cycle_stats)?;
    }
    if let Some(path) = &args.output.plot {
        // Continue from the final state for a few cycles with the event trace on.
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
        )?;
    }
    if args.output.json {
        print_json(&report)
    } else {
        print_simulation(&report, &point, &args.output);
        Ok(())
    }
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
    say!(
        "stick fraction    {:.6} (model {:.6})",
        report.stick_fraction,
        report.model_stick_fraction
    );
    say!(
        "cycles            {} ({})",
        report.cycles,
        if report.converged {
            "converged"
        } else {
            "not converged"
        }
    );
    say!("plate excursion   {:.6} mm", report.plate_excursion_m * 1e3);
    say!(
        "speed             {:.3e} simulated cycles/s",
        report.cycles_per_s
    );
    for (what, path) in [("csv", &output.csv), ("plot", &output.plot)] {
        if let Some(path) = path {
            say!("{what:<18}{}", path.display());
        }
    }
}

fn sweep(args: &SweepArgs) -> Result<(), SimError> {
    args.output.check()?;
    let period_s = period_s(args.freq_hz)?;
    check_grid(
        args.accel_mps2.len(),
        args.duties,
        ["--accel-mps2", "--duties"],
    )?;
    let contact = args.contact.contact()?;
    let duties = figures::duty_grid(0.5, SWEEP_MAX_DUTY, args.duties);
    let progress = progress(args.accel_mps2.len() * duties.len(), args.output.json);
    let points = figures::sweep(
        period_s,
        &args.accel_mps2,
        &duties,
        &contact,
        args.timing.clock_hz(),
        &|| progress.inc(1),
    )?;
    progress.finish_and_clear();
    if emit(&args.output, &points, |path| {
        plot_sweep(path, args, &points)
    })? {
        return Ok(());
    }
    say!(
        "{:>10} {:>7} {:>12} {:>12} {:>12} {:>8} {:>7}",
        "a_max",
        "duty",
        "sim mm/s",
        "nqs mm/s",
        "qs mm/s",
        "stick",
        "cycles"
    );
    for point in &points {
        say!(
            "{:>10.1} {:>7.4} {:>12.5} {:>12} {:>12.5} {:>8.4} {:>7}{}",
            point.accel_mps2,
            point.duty,
            point.feed_rate_mps * 1e3,
            point
                .model_feed_rate_mps
                .map_or("-".into(), |v| format!("{:.5}", v * 1e3)),
            point.quasi_static_feed_rate_mps * 1e3,
            point.stick_fraction,
            point.cycles,
            if point.converged {
                ""
            } else {
                " (not converged)"
            }
        );
    }
    Ok(())
}

fn plot_sweep(path: &Path, args: &SweepArgs, points: &[SweepPoint]) -> Result<(), SimError> {
    let mut series = Vec::new();
    for (index, &accel) in args.accel_mps2.iter().enumerate() {
        let of_accel: Vec<&SweepPoint> = points.iter().filter(|p| p.accel_mps2 == accel).collect();
        let pick = |f: &dyn Fn(&SweepPoint) -> Option<f64>| -> Vec<(f64, f64)> {
            of_accel
                .iter()
                .filter_map(|p| f(p).map(|v| (p.duty, v * 1e3)))
                .collect()
        };
        series.push(Series {
            name: format!("simulated, a = {accel} m/s²"),
            points: pick(&|p| Some(p.feed_rate_mps)),
            mark: Mark::Points,
            color: index,
        });
        series.push(Series {
            name: format!("non-quasi-static (Eq. 15/18), a = {accel}"),
            points: pick(&|p| p.model_feed_rate_mps),
            mark: Mark::Line,
            color: index,
        });
        series.push(Series {
            name: format!("quasi-static (Eq. 9), a = {accel}"),
            points: pick(&|p| Some(p.quasi_static_feed_rate_mps)),
            mark: Mark::DashedLine,
            color: index,
        });
    }
    let title = format!(
        "Feed rate vs duty at {} Hz, μ = {}",
        args.freq_hz, args.contact.mu
    );
    plot::chart(
        path,
        Labels {
            title: &title,
            x: "duty d",
            y: "feed rate (mm/s)",
        },
        &series,
    )
}

fn viscosity(args: &ViscosityArgs) -> Result<(), SimError> {
    args.output.check()?;
    let spec = WaveformSpec {
        period_s: period_s(args.freq_hz)?,
        duty: args.duty,
        drive: Drive::Accel {
            accel_mps2: args.accel_mps2,
        },
    };
    let contact = Contact::new(
        args.mu,
        args.mu_static.unwrap_or(args.mu),
        args.gravity_mps2,
        args.mass_kg,
        0.0,
    )?;
    let forces =
        evenly_spaced(args.force_min_n, args.force_max_n, args.points).ok_or_else(|| {
            SimError::Request(format!(
                "--force-max-n {} must be above --force-min-n {}",
                Significant(args.force_max_n),
                Significant(args.force_min_n)
            ))
        })?;
    let fit = figures::viscosity(spec, &contact, &forces, args.timing.clock_hz())?;
    if let Some(path) = &args.output.csv {
        write_csv(path, &fit.points)?;
    }
    if let Some(path) = &args.output.plot {
        plot_viscosity(path, &fit)?;
    }
    if args.output.json {
        return print_json(&fit);
    }
    say!(
        "{:>12} {:>14} {:>14} {:>8}",
        "force mN",
        "sim mm/s",
        "model mm/s",
        "stick"
    );
    for point in &fit.points {
        say!(
            "{:>12.5} {:>14.6} {:>14} {:>8.4}{}",
            point.force_n * 1e3,
            point.velocity_mps * 1e3,
            point
                .model_velocity_mps
                .map_or("-".into(), |v| format!("{:.6}", v * 1e3)),
            point.stick_fraction,
            if point.sticks {
                "  sticks: outside the linear law"
            } else {
                ""
            }
        );
    }
    say!(
        "K fitted {:.9e} N·s/m, Eq. 10 {:.9e} N·s/m ({:.2e} relative); intercept {:.6e} N",
        fit.k_ns_per_m,
        fit.model_k_ns_per_m,
        fit.k_ns_per_m / fit.model_k_ns_per_m - 1.0,
        fit.intercept_n
    );
    Ok(())
}

fn plot_viscosity(path: &Path, fit: &Viscosity) -> Result<(), SimError> {
    let (sliding, sticking): (Vec<_>, Vec<_>) = fit.points.iter().partition(|p| !p.sticks);
    let to_points = |points: &[&figures::ViscosityPoint]| -> Vec<(f64, f64)> {
        points
            .iter()
            .map(|p| (p.velocity_mps * 1e3, p.force_n * 1e3))
            .collect()
    };
    let velocities = fit.points.iter().map(|p| p.velocity_mps);
    let (low, high) = velocities.fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
    let line = |v: f64| (v * 1e3, (fit.k_ns_per_m * v + fit.intercept_n) * 1e3);
    let series = vec![
        Series {
            name: "simulated, sliding".into(),
            points: to_points(&sliding),
            mark: Mark::Points,
            color: 0,
        },
        Series {
            name: "simulated, sticks".into(),
            points: to_points(&sticking),
            mark: Mark::Points,
            color: 1,
        },
        Series {
            name: format!(
                "fit K = {:.4e} N·s/m (Eq. 10: {:.4e})",
                fit.k_ns_per_m, fit.model_k_ns_per_m
            ),
            points: vec![line(low), line(high)],
            mark: Mark::Line,
            color: 2,
        },
    ];
    let labels = Labels {
        title: "External force vs steady velocity",
        x: "velocity v′ (mm/s)",
        y: "f_ext (mN)",
    };
    plot::chart(path, labels, &series)
}

/// `points` values from `low` to `high`, both included; `None` unless `points ≥ 2` and
/// `high > low` (NaN bounds included).
fn evenly_spaced(low: f64, high: f64, points: usize) -> Option<Vec<f64>> {
    if points < 2 || high.partial_cmp(&low) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let span = high - low;
    Some(
        (0..points)
            .map(|i| low + span * (i as f64 / (points - 1) as f64))
            .collect(),
    )
}

fn saturation(args: &SaturationArgs) -> Result<(), SimError> {
    args.output.check()?;
    let period_s = period_s(args.freq_hz)?;
    check_grid(args.mu.len(), args.points, ["--mu", "--points"])?;
    let accels =
        evenly_spaced(args.accel_min_mps2, args.accel_max_mps2, args.points).ok_or_else(|| {
            SimError::Request(format!(
                "--accel-max-mps2 {} must be above --accel-min-mps2 {}",
                Significant(args.accel_max_mps2),
                Significant(args.accel_min_mps2)
            ))
        })?;
    let contact = Contact::new(1.0, 1.0, args.gravity_mps2, 1e-4, 0.0)?;
    let progress = progress(accels.len() * args.mu.len(), args.output.json);
    let points = figures::saturation(period_s, &accels, &args.mu, &contact, &|| progress.inc(1))?;
    progress.finish_and_clear();
    if emit(&args.output, &points, |path| {
        plot_saturation(path, args, &points)
    })? {
        return Ok(());
    }
    say!(
        "{:>6} {:>10} {:>12} {:>12}",
        "μ",
        "a_max",
        "Eq. 16",
        "simulated"
    );
    for point in &points {
        say!(
            "{:>6} {:>10.2} {:>12.8} {:>12.8}",
            point.mu,
            point.accel_mps2,
            point.model_duty,
            point.duty
        );
    }
    Ok(())
}

fn plot_saturation(
    path: &Path,
    args: &SaturationArgs,
    points: &[SaturationPoint],
) -> Result<(), SimError> {
    let mut series = Vec::new();
    for (index, &mu) in args.mu.iter().enumerate() {
        let of_mu: Vec<&SaturationPoint> = points.iter().filter(|p| p.mu == mu).collect();
        series.push(Series {
            name: format!("Eq. 16, μ = {mu}"),
            points: of_mu.iter().map(|p| (p.accel_mps2, p.model_duty)).collect(),
            mark: Mark::Line,
            color: index,
        });
        series.push(Series {
            name: format!("simulated, μ = {mu}"),
            points: of_mu.iter().map(|p| (p.accel_mps2, p.duty)).collect(),
            mark: Mark::Points,
            color: index,
        });
    }
    let labels = Labels {
        title: "Saturation duty d_sat,nqs vs a_max",
        x: "a_max (m/s²)",
        y: "d_sat,nqs",
    };
    plot::chart(path, labels, &series)
}

fn trace(args: &TraceArgs) -> Result<(), SimError> {
    args.output.check()?;
    let point = OperatingPoint::new(
        args.wave.spec()?,
        args.contact.contact()?,
        args.timing.clock_hz(),
    )?;
    let options = RunOptions {
        fixed_cycles: Some(args.cycles),
        trace: true,
        ..RunOptions::converge(point.default_criteria())
    };
    let run = point.run(&options);
    if let Some(path) = &args.output.csv {
        write_csv(path, &run.trace)?;
    }
    if let Some(path) = &args.output.plot {
        let title = format!(
            "Plate and part velocity: {} Hz, d = {}, a_max = {:.1} m/s², μ = {}",
            point.waveform.frequency_hz(),
            point.waveform.duty,
            point.waveform.accel_mps2,
            point.contact.mu
        );
        plot_trace(path, &title, &run.trace, None)?;
    }
    if args.output.json {
        return print_json(&run.trace);
    }
    say!(
        "{:>12} {:>14} {:>14}  event",
        "time ms",
        "plate mm/s",
        "part mm/s"
    );
    for p in &run.trace {
        say!(
            "{:>12.6} {:>14.6} {:>14.6}  {:?}",
            p.time_s * 1e3,
            p.plate_velocity_mps * 1e3,
            p.part_velocity_mps * 1e3,
            p.event
        );
    }
    Ok(())
}

fn plot_trace(
    path: &Path,
    title: &str,
    trace: &[TracePoint],
    feed_rate_mps: Option<f64>,
) -> Result<(), SimError> {
    let start = trace.first().map_or(0.0, |p| p.time_s);
    let end = trace.last().map_or(0.0, |p| p.time_s);
    let mut series = vec![
        Series {
            name: "plate".into(),
            points: trace
                .iter()
                .map(|p| (p.time_s * 1e3, p.plate_velocity_mps * 1e3))
                .collect(),
            mark: Mark::Line,
            color: 0,
        },
        Series {
            name: "part".into(),
            points: trace
                .iter()
                .map(|p| (p.time_s * 1e3, p.part_velocity_mps * 1e3))
                .collect(),
            mark: Mark::Line,
            color: 1,
        },
    ];
    if let Some(feed) = feed_rate_mps {
        series.push(Series {
            name: "feed rate (mean part velocity)".into(),
            points: vec![(start * 1e3, feed * 1e3), (end * 1e3, feed * 1e3)],
            mark: Mark::DashedLine,
            color: 2,
        });
    }
    plot::chart(
        path,
        Labels {
            title,
            x: "time (ms)",
            y: "velocity (mm/s)",
        },
        &series,
    )
}

/// A progress bar on stderr, hidden for `--json` or when stderr is not a terminal.
fn progress(total: usize, json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::hidden());
    }
    let bar = ProgressBar::new(total as u64);
    if let Ok(style) = ProgressStyle::with_template("{bar:40} {pos}/{len} points {elapsed}") {
        bar.set_style(style);
    }
    bar
}

/// Writes the CSV and the plot a command asked for, and prints the JSON; `true` when the JSON
/// replaces the human-readable report.
fn emit<T: Serialize>(
    output: &OutputArgs,
    rows: &[T],
    plot: impl FnOnce(&Path) -> Result<(), SimError>,
) -> Result<bool, SimError> {
    if let Some(path) = &output.csv {
        write_csv(path, rows)?;
    }
    if let Some(path) = &output.plot {
        plot(path)?;
    }
    if output.json {
        print_json(rows)?;
    }
    Ok(output.json)
}

fn print_json<T: Serialize + ?Sized>(value: &T) -> Result<(), SimError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| SimError::Output {
        path: "stdout".into(),
        reason: e.to_string(),
    })?;
    say!("{text}");
    Ok(())
}

fn write_csv<T: Serialize>(path: &Path, rows: &[T]) -> Result<(), SimError> {
    let failure = |reason: String| SimError::Output {
        path: path.display().to_string(),
        reason,
    };
    let mut writer = csv::Writer::from_path(path).map_err(|e| failure(e.to_string()))?;
    for row in rows {
        writer.serialize(row).map_err(|e| failure(e.to_string()))?;
    }
    writer.flush().map_err(|e| failure(e.to_string()))
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// Every flag that takes a number reads a negative one after a space (`--force-n -1e-5`);
    /// only file names are left to clap's usual reading.
    #[test]
    fn every_numeric_flag_takes_hyphen_values() {
        let cli = super::Cli::command();
        cli.clone().debug_assert();
        for command in cli.get_subcommands() {
            for arg in command.get_arguments() {
                let file = arg
                    .get_value_names()
                    .is_some_and(|names| names.iter().any(|name| name == "FILE"));
                if arg.get_action().takes_values() && !file {
                    assert!(
                        arg.is_allow_hyphen_values_set(),
                        "{} --{}",
                        command.get_name(),
                        arg.get_id()
                    );
                }
            }
        }
    }
}
