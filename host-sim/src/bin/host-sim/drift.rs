//! `host-sim drift`: what each non-ideality of a real plate does to one operating point in open
//! loop: the feed rate, where the plate goes and whether it reaches an end stop.

use std::path::Path;

use clap::Args;
use host_sim::figures::{self, DriftCase, CASE_PLATE_MASS_KG};
use host_sim::{SimError, Timing};
use serde::Serialize;

use crate::args::{plate_options, CountArg, DriveLimitArgs, OutputArgs, PointArgs, PLATE_CYCLES};
use crate::output::{emit, say};
use crate::plot::{self, Labels, Mark, Options, Series, YAxis};

/// Most cycles of `--cycles`: every case is traced for `--csv` and `--plot`.
const MAX_CYCLES: u64 = 1_000;
/// Samples per cycle of each case's plate position on the chart: finer than its pixels.
const PLOT_SAMPLES_PER_CYCLE: f64 = 16.0;

/// The flags of `host-sim drift`.
#[derive(Args)]
pub struct DriftArgs {
    #[command(flatten)]
    point: PointArgs<DriveLimitArgs>,
    /// Cycles each plate runs from rest (at most 1 000), unless it hits an end stop.
    #[arg(long, default_value_t = PLATE_CYCLES, count_in = (1, MAX_CYCLES))]
    cycles: u64,
    #[command(flatten)]
    output: OutputArgs,
}

#[derive(Serialize)]
struct DriftReport<'a> {
    freq_hz: f64,
    duty: f64,
    accel_mps2: f64,
    stroke_m: f64,
    /// Why the waveform is beyond the machine's drive limits (run with --no-drive-limits); null
    /// within them.
    beyond_drive_limits: Option<String>,
    mu: f64,
    clock_hz: Option<u32>,
    cycles: u64,
    /// The last cycles the feed rate and the mean position are averaged over.
    average_cycles: u64,
    plate_mass_kg: f64,
    cases: &'a [DriftCase],
}

/// One instant of one case, for the CSV.
#[derive(Serialize)]
struct DriftSample {
    case: &'static str,
    time_s: f64,
    plate_position_m: f64,
    plate_velocity_mps: f64,
    part_velocity_mps: f64,
}

/// Runs `host-sim drift`.
pub fn run(args: &DriftArgs) -> Result<(), SimError> {
    args.output.check()?;
    let (point, beyond_drive_limits) = args.point.limited_point()?;
    let options = plate_options(args.cycles);
    let traced = args.output.csv.is_some() || args.output.plot.is_some();
    let cases = figures::open_loop_drift(&point, &figures::open_loop_cases()?, &options, traced)?;
    let samples: Vec<DriftSample> = cases
        .iter()
        .flat_map(|case| {
            case.trace.iter().map(|p| DriftSample {
                case: case.name,
                time_s: p.time_s,
                plate_position_m: p.plate_position_m,
                plate_velocity_mps: p.plate_velocity_mps,
                part_velocity_mps: p.part_velocity_mps,
            })
        })
        .collect();
    let report = DriftReport {
        freq_hz: point.waveform.frequency_hz(),
        duty: point.waveform.duty,
        accel_mps2: point.waveform.accel_mps2,
        stroke_m: point.waveform.stroke_m,
        beyond_drive_limits,
        mu: point.contact.mu,
        clock_hz: match point.timing {
            Timing::Exact => None,
            Timing::Ticks(plan) => Some(plan.clock_hz),
        },
        cycles: options.cycles,
        average_cycles: options.average_cycles,
        plate_mass_kg: CASE_PLATE_MASS_KG,
        cases: &cases,
    };
    emit(
        &args.output,
        &samples,
        |path| plot_drift(path, &report),
        &report,
        || print_table(&report),
    )
}

/// The feed rate, with the cycles it is averaged over when an end stop cut the run short.
fn feed_rate(case: &DriftCase, average_cycles: u64) -> String {
    let feed = format!("{:.2} mm/s", case.feed_rate_mps * 1e3);
    if case.cycles < average_cycles {
        format!("{feed} ({} cycles)", case.cycles)
    } else {
        feed
    }
}

fn end_stop(case: &DriftCase) -> String {
    case.end_stop.map_or("—".into(), |stop| {
        format!(
            "{:+.0} mm after {:.4} s at {:.3} m/s",
            stop.position_m * 1e3,
            stop.time_s,
            stop.velocity_mps
        )
    })
}

/// The operating point, then one Markdown table row per case.
fn print_table(report: &DriftReport) {
    let timing = report
        .clock_hz
        .map_or("exact switching times".into(), |hz| {
            format!("tick plan at {hz} Hz")
        });
    say!(
        "open loop: {} Hz, d = {}, stroke {:.4} mm (a_max {:.3} m/s²), μ = {}, {timing}; {} \
         cycles from rest on a {} kg plate without end stops (realistic.toml: its own)",
        report.freq_hz,
        report.duty,
        report.stroke_m * 1e3,
        report.accel_mps2,
        report.mu,
        report.cycles,
        report.plate_mass_kg
    );
    if let Some(reason) = &report.beyond_drive_limits {
        say!("beyond the machine's drive limits, lifted by --no-drive-limits: {reason}");
    }
    say!("");
    say!(
        "| non-ideality | feed rate (last {} cycles) | plate's mean position | end stop |",
        report.average_cycles
    );
    say!("|---|---|---|---|");
    for case in report.cases {
        say!(
            "| {} | {} | {:.2} mm | {} |",
            case.name,
            feed_rate(case, report.average_cycles),
            case.mean_position_m * 1e3,
            end_stop(case)
        );
    }
}

/// Each case's plate position through its run, one thin line each; the legend gives its feed
/// rate, the change from the first (ideal) case and its mean position.
fn plot_drift(path: &Path, report: &DriftReport) -> Result<(), SimError> {
    let ideal_mps = report.cases.first().map_or(0.0, |case| case.feed_rate_mps);
    let step_s = 1.0 / (report.freq_hz * PLOT_SAMPLES_PER_CYCLE);
    let series: Vec<Series> = report
        .cases
        .iter()
        .enumerate()
        .map(|(index, case)| {
            let change = if ideal_mps != 0.0 {
                format!(
                    " ({:+.1} %)",
                    (case.feed_rate_mps / ideal_mps - 1.0) * 100.0
                )
            } else {
                String::new()
            };
            let stop = case.end_stop.map_or(String::new(), |stop| {
                format!(", end stop at {:.4} s", stop.time_s)
            });
            Series {
                name: format!(
                    "{}: feed {:.1} mm/s{change}, mean {:.2} mm{stop}",
                    case.name,
                    case.feed_rate_mps * 1e3,
                    case.mean_position_m * 1e3
                ),
                points: thinned(case, step_s),
                mark: Mark::ThinLine,
                color: index,
            }
        })
        .collect();
    let title = format!(
        "Plate position in open loop: {} Hz, d = {}, stroke {:.1} mm, μ = {}",
        report.freq_hz,
        report.duty,
        report.stroke_m * 1e3,
        report.mu
    );
    plot::chart_with(
        path,
        Labels {
            title: &title,
            x: "time (s)",
            y: "plate position (mm, logarithmic beyond ±0.1 mm)",
        },
        &series,
        &Options {
            y_axis: YAxis::SymLog {
                linear_within: POSITION_LINEAR_WITHIN_MM,
            },
            ..Options::default()
        },
    )
}

/// The plate positions the drift chart draws to scale; beyond them its axis is logarithmic, so
/// that the stroke's 2.5 mm and metres of drift are read off one axis.
const POSITION_LINEAR_WITHIN_MM: f64 = 0.1;

/// The case's plate position (mm) at the first traced instant of every `step_s`, and its last.
fn thinned(case: &DriftCase, step_s: f64) -> Vec<(f64, f64)> {
    let mut points = Vec::new();
    let mut next_s = f64::NEG_INFINITY;
    for (index, p) in case.trace.iter().enumerate() {
        if p.time_s >= next_s || index + 1 == case.trace.len() {
            points.push((p.time_s, p.plate_position_m * 1e3));
            next_s = p.time_s + step_s;
        }
    }
    points
}
