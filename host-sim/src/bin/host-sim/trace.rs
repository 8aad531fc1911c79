//! `host-sim trace`: plate and part velocity through N cycles from rest (Fig. 3, 5, 6, 8), and
//! the velocity chart `simulate --plot` draws too.

use std::path::Path;

use clap::Args;
use host_sim::ideal::simulator::TracePoint;
use host_sim::plate::{self, EndStop, PlateParams, PlatePoint, PlateRunOptions};
use host_sim::{OperatingPoint, RunOptions, SimError};

use crate::args::{CountArg, OutputArgs, PlantArgs, PointArgs};
use crate::output::{emit, say};
use crate::plot::{self, Labels, Mark, Moment, Panel, Series};

/// Most cycles of `--cycles`: every event is kept for the report and the plot.
const MAX_CYCLES: u64 = 10_000;

/// The flags of `host-sim trace`.
#[derive(Args)]
pub struct TraceArgs {
    #[command(flatten)]
    point: PointArgs,
    /// Cycles to trace from rest (at most 10 000).
    #[arg(long, default_value_t = 5, count_in = (1, MAX_CYCLES))]
    cycles: u64,
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    output: OutputArgs,
}

/// Runs `host-sim trace`.
pub fn run(args: &TraceArgs) -> Result<(), SimError> {
    args.output.check()?;
    let point = args.point.point()?;
    if let Some((_, params)) = args.plant.plate()? {
        if !params.is_ideal() {
            return run_real_plate(args, &point, &params);
        }
    }
    let options = RunOptions {
        fixed_cycles: Some(args.cycles),
        trace: true,
        ..RunOptions::converge(point.default_criteria())
    };
    let run = point.run(&options);
    let plot = |path: &Path| {
        let title = title("Plate and part velocity", &point);
        plot_trace(path, &title, &run.trace, None)
    };
    emit(&args.output, &run.trace, plot, &run.trace, || {
        print_trace(&run.trace)
    })
}

/// The trace of a plate with non-idealities, from rest, for `--cycles` or until an end stop.
fn run_real_plate(
    args: &TraceArgs,
    point: &OperatingPoint,
    params: &PlateParams,
) -> Result<(), SimError> {
    let options = PlateRunOptions {
        cycles: args.cycles,
        average_cycles: args.cycles,
    };
    let (run, trace) = plate::trace(params, &point.contact, point.segments(), &options)?;
    let plot = |path: &Path| {
        let title = title("Real plate, open loop", point);
        plot_plate_trace(path, &title, &trace, &[], run.end_stop)
    };
    emit(&args.output, &trace, plot, &trace, || {
        print_plate_trace(&trace)
    })
}

/// A chart's title: `what`, then the operating point's frequency, duty, a_max and μ.
fn title(what: &str, point: &OperatingPoint) -> String {
    format!(
        "{what}: {} Hz, d = {}, a_max = {:.1} m/s², μ = {}",
        point.waveform.frequency_hz(),
        point.waveform.duty,
        point.waveform.accel_mps2,
        point.contact.mu
    )
}

fn print_plate_trace(trace: &[PlatePoint]) {
    say!(
        "{:>12} {:>14} {:>14} {:>14} {:>14}",
        "time ms",
        "plate mm",
        "plate mm/s",
        "part mm/s",
        "command m/s²"
    );
    for p in trace {
        say!(
            "{:>12.6} {:>14.6} {:>14.6} {:>14.6} {:>14.3}",
            p.time_s * 1e3,
            p.plate_position_m * 1e3,
            p.plate_velocity_mps * 1e3,
            p.part_velocity_mps * 1e3,
            p.command_mps2
        );
    }
}

/// Plate and part velocity through a real plate's `trace` above, the plate's position that
/// shows its drift below, each on its own scale, with `moments` (their times in s) and the end
/// stop, if the plate hit one, marked on both.
pub fn plot_plate_trace(
    path: &Path,
    title: &str,
    trace: &[PlatePoint],
    moments: &[Moment],
    end_stop: Option<EndStop>,
) -> Result<(), SimError> {
    let end_stop = end_stop.map(|stop| Moment {
        x: stop.time_s,
        name: format!("end stop at {:.3} s", stop.time_s),
    });
    let moments: Vec<Moment> = moments
        .iter()
        .chain(&end_stop)
        .map(|moment| Moment {
            x: moment.x * 1e3,
            ..moment.clone()
        })
        .collect();
    let line = |name: &str, color, value: fn(&PlatePoint) -> f64| Series {
        name: name.into(),
        points: trace.iter().map(|p| (p.time_s * 1e3, value(p))).collect(),
        mark: Mark::Line,
        color,
    };
    let mut velocity = vec![
        line("plate", 0, |p| p.plate_velocity_mps * 1e3),
        line("part", 1, |p| p.part_velocity_mps * 1e3),
    ];
    let mut position = vec![line("plate", 0, |p| p.plate_position_m * 1e3)];
    velocity.extend(plot::moment_lines(&moments, &velocity, 3));
    position.extend(plot::moment_lines(&moments, &position, 3));
    plot::stacked(
        path,
        title,
        "time (ms)",
        &[
            Panel {
                y: "velocity (mm/s)",
                series: velocity,
            },
            Panel {
                y: "plate position (mm)",
                series: position,
            },
        ],
    )
}

fn print_trace(trace: &[TracePoint]) {
    say!(
        "{:>12} {:>14} {:>14}  event",
        "time ms",
        "plate mm/s",
        "part mm/s"
    );
    for p in trace {
        say!(
            "{:>12.6} {:>14.6} {:>14.6}  {:?}",
            p.time_s * 1e3,
            p.plate_velocity_mps * 1e3,
            p.part_velocity_mps * 1e3,
            p.event
        );
    }
}

/// Plate and part velocity through `trace`, with the mean part velocity `feed_rate_mps` if given.
pub fn plot_trace(
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
