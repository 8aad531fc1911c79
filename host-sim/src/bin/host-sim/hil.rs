//! `host-sim hil`: read a running firmware's decoded event stream, check every edge against the
//! shared scheduler and simulate the part on the recorded edges; with a plant that is not ideal,
//! also on its plate, whose trace on the actual edges the CSV and the chart then show.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use clap::Args;
use feeder_emulator::{ICOUNT_SHIFT, NS_PER_INSTRUCTION};
use host_sim::hil::{
    self, CheckReport, Checker, EdgeTimes, EdgeWork, Event, HaltPoint, PartReport,
};
use host_sim::plate::{EndStop, PlatePoint};
use host_sim::SimError;
use serde::Serialize;

use crate::args::{ContactArgs, OutputArgs, PlantArgs};
use crate::output::{emit, say};
use crate::plot::{self, Mark, Moment, Panel, Series};
use crate::simulate::{end_stop_failure, print_plant, PlantReport};
use crate::trace::plot_plate_trace;

/// The flags of `host-sim hil`.
#[derive(Args)]
#[command(
    after_help = "Exit code 0 when the run passes: every edge present and as planned, none \
                  missed, no change away from a cycle boundary, the run ended (unless \
                  --open-ended), no firmware error and, with --plant, no end stop on the actual \
                  edges; 1 when it fails them (the report names each); 2 when the run cannot be \
                  checked. The latency of the actual edges is measured, not judged: the part \
                  runs on them."
)]
pub struct HilArgs {
    /// Decoded event stream (defmt-print or probe-rs output); standard input by default.
    #[arg(long, value_name = "FILE")]
    input: Option<PathBuf>,
    /// The log was cut off by hand (a board run): do not require the `end` event.
    #[arg(long)]
    open_ended: bool,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    output: OutputArgs,
}

#[derive(Serialize)]
struct HilReport<'a> {
    passed: bool,
    /// Empty when the run passed; else each criterion it missed.
    failures: Vec<String>,
    /// The verdict as one line.
    verdict_line: String,
    edges: u64,
    matched: u64,
    missing: u64,
    unexpected: u64,
    glitches: u64,
    /// Edges the output missed: each a late preload, which the timer answered by playing the
    /// segment again.
    missed_edges: Vec<MissedEdge>,
    motion_cycles: u64,
    max_deviation_ticks: i64,
    /// `[deviation in ticks, edges]`, ascending.
    deviation_histogram: Vec<(i64, u64)>,
    /// The least preload slack of a segment that began, and the planned tick of that segment.
    min_slack_ticks: Option<i64>,
    min_slack_at_tick: Option<u64>,
    /// `[lowest slack, highest slack, edges]` in ticks, ascending, in power-of-two buckets.
    slack_histogram: Vec<(i64, i64, u64)>,
    /// Work per edge, when the firmware reports it (QEMU).
    edge_work: Option<WorkSummary>,
    /// Where each halt left the plate, on the actual edges.
    halts: Vec<HaltPoint>,
    problems: Vec<String>,
    firmware_errors: Vec<String>,
    clock_hz: u32,
    /// The part on the edges' actual times.
    actual: &'a PartReport,
    /// The part on the scheduler's planned ticks.
    planned: &'a PartReport,
    /// A plant that is not ideal: the part's feed rate on its plate, on the actual edges and
    /// on the planned ticks (each until an end stop).
    #[serde(skip_serializing_if = "Option::is_none")]
    plant_feed_rate_mps: Option<PlantFeedRates>,
    /// A plant that is not ideal: its plate under the actual edges.
    #[serde(flatten)]
    plant: Option<PlantReport>,
}

/// The part's feed rate on a real plate, over its last cycles.
#[derive(Serialize)]
struct PlantFeedRates {
    actual: f64,
    planned: f64,
}

#[derive(Serialize)]
struct MissedEdge {
    /// When the edge was due: the timer played the segment again from here.
    tick: u64,
    /// The late preload's slack (negative); absent if none was tried.
    slack_ticks: Option<i64>,
    /// The segment played again.
    replayed_cycle: u64,
    replayed_kind: &'static str,
    replayed_ticks: u32,
}

/// Work per edge in time and in QEMU instructions.
#[derive(Serialize)]
struct WorkSummary {
    edges: u64,
    max_ns: f64,
    mean_ns: f64,
    /// At [`NS_PER_INSTRUCTION`] ns each.
    max_instructions: f64,
    mean_instructions: f64,
}

impl From<&EdgeWork> for WorkSummary {
    fn from(work: &EdgeWork) -> Self {
        WorkSummary {
            edges: work.edges,
            max_ns: work.max_ns(),
            mean_ns: work.mean_ns(),
            max_instructions: work.max_ns() / f64::from(NS_PER_INSTRUCTION),
            mean_instructions: work.mean_ns() / f64::from(NS_PER_INSTRUCTION),
        }
    }
}

/// Runs `host-sim hil`; false when the run failed its check (the report is out).
pub fn run(args: &HilArgs) -> Result<bool, SimError> {
    args.output.check()?;
    let contact = args.contact.contact()?;
    let plate = args.plant.plate()?;
    let source = args
        .input
        .as_ref()
        .map_or("standard input".into(), |path| path.display().to_string());
    let unreadable = |reason: String| SimError::Input {
        source: source.clone(),
        reason,
    };
    let stream = match &args.input {
        Some(path) => {
            let file = File::open(path).map_err(|error| unreadable(error.to_string()))?;
            hil::read_stream(BufReader::new(file))
        }
        None => hil::read_stream(std::io::stdin().lock()),
    }
    .map_err(|error| unreadable(error.to_string()))?;
    if !stream
        .events
        .iter()
        .any(|event| matches!(event, Event::Segment(_)))
    {
        return Err(SimError::NoSegments {
            source,
            firmware_error: stream.errors.first().map(|line| hil::excerpt(line)),
        });
    }
    let (check, edges, clock_hz) = Checker::check_events(&stream.events, !args.open_ended);
    let actual = hil::simulate(&edges, clock_hz, &contact, EdgeTimes::Actual);
    let planned = hil::simulate(&edges, clock_hz, &contact, EdgeTimes::Planned);
    // The real plate on the actual edges, traced when the CSV or the chart shows it.
    let traced = args.output.csv.is_some() || args.output.plot.is_some();
    let (plant_feed_rate_mps, plant, plate_trace) = match plate {
        Some((path, params)) if !params.is_ideal() => {
            let (actual, trace) = if traced {
                let (run, trace) =
                    hil::trace_plate(&edges, clock_hz, &contact, EdgeTimes::Actual, &params)?;
                (run, Some((path, trace)))
            } else {
                let run =
                    hil::simulate_plate(&edges, clock_hz, &contact, EdgeTimes::Actual, &params)?;
                (run, None)
            };
            let planned =
                hil::simulate_plate(&edges, clock_hz, &contact, EdgeTimes::Planned, &params)?;
            let rates = PlantFeedRates {
                actual: actual.feed_rate_mps,
                planned: planned.feed_rate_mps,
            };
            (Some(rates), Some(PlantReport::new(path, &actual)), trace)
        }
        _ => (None, None, None),
    };
    let mut failures = check.failures();
    if !stream.errors.is_empty() {
        failures.push(format!("{} firmware error(s)", stream.errors.len()));
    }
    if let Some(stop) = plant.as_ref().and_then(|plant| plant.end_stop) {
        failures.push(format!("{} on the actual edges", end_stop_failure(&stop)));
    }
    let report = HilReport {
        passed: failures.is_empty(),
        verdict_line: verdict_line(&failures),
        failures,
        edges: check.edges,
        matched: check.matched,
        missing: check.missing,
        unexpected: check.unexpected,
        glitches: check.glitches,
        missed_edges: check
            .missed
            .iter()
            .map(|replayed| MissedEdge {
                tick: replayed.actual_tick,
                slack_ticks: replayed.slack_ticks,
                replayed_cycle: replayed.cycle,
                replayed_kind: replayed.kind.name(),
                replayed_ticks: replayed.ticks,
            })
            .collect(),
        motion_cycles: check.motion_cycles,
        max_deviation_ticks: check.max_deviation_ticks(),
        deviation_histogram: check
            .deviation_histogram
            .iter()
            .map(|(d, n)| (*d, *n))
            .collect(),
        min_slack_ticks: check.min_slack.map(|(slack, _)| slack),
        min_slack_at_tick: check.min_slack.map(|(_, tick)| tick),
        slack_histogram: check
            .slack_histogram
            .iter()
            .map(|(lowest, edges)| (*lowest, (2 * lowest - 1).max(0), *edges))
            .collect(),
        edge_work: check.edge_work.as_ref().map(WorkSummary::from),
        halts: actual.halts.clone(),
        problems: check.problems.clone(),
        firmware_errors: stream.errors.clone(),
        clock_hz,
        actual: &actual,
        planned: &planned,
        plant_feed_rate_mps,
        plant,
    };
    let shown = if plate_trace.is_some() {
        "the real plate and its part on the actual edges"
    } else {
        "per-cycle means on the ideal plate"
    };
    let report_text = || print_report(&report, &check, &args.output, shown);
    let moments = run_moments(&stream.events, clock_hz);
    let passed = report.passed;
    match &plate_trace {
        Some((plant, trace)) => emit(
            &args.output,
            trace,
            |path| {
                let end_stop = report.plant.as_ref().and_then(|plant| plant.end_stop);
                plot_plate_run(path, plant, trace, &moments, end_stop)
            },
            &report,
            report_text,
        ),
        None => emit(
            &args.output,
            &actual.cycles,
            |path| plot_run(path, &actual, &planned, &moments),
            &report,
            report_text,
        ),
    }?;
    Ok(passed)
}

/// The verdict as one line: `PASSED`, or `FAILED` with each criterion the run missed.
fn verdict_line(failures: &[String]) -> String {
    if failures.is_empty() {
        "firmware in the loop: PASSED".into()
    } else {
        format!("firmware in the loop: FAILED ({})", failures.join("; "))
    }
}

/// The report; `shown` says what the CSV and the chart, if written, hold.
fn print_report(report: &HilReport, check: &CheckReport, output: &OutputArgs, shown: &str) {
    let microseconds = |ticks: i64| ticks as f64 * 1e6 / f64::from(report.clock_hz.max(1));
    say!("{}", report.verdict_line);
    say!(
        "  edges           {} reported, {} exactly as planned, {} missing, {} unexpected, {} glitches, {} missed",
        report.edges, report.matched, report.missing, report.unexpected, report.glitches,
        report.missed_edges.len()
    );
    say!("  motion cycles   {}", report.motion_cycles);
    say!(
        "  edge latency    max {} ticks ({:.1} µs) at {} Hz; histogram (ticks: edges) {}",
        report.max_deviation_ticks,
        microseconds(report.max_deviation_ticks),
        report.clock_hz,
        report
            .deviation_histogram
            .iter()
            .map(|(ticks, edges)| format!("{ticks}: {edges}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if let (Some(slack), Some(tick)) = (report.min_slack_ticks, report.min_slack_at_tick) {
        say!(
            "  preload slack   min {slack} ticks ({:.1} µs) before the edge at tick {tick}; histogram (ticks: edges) {}",
            microseconds(slack),
            report
                .slack_histogram
                .iter()
                .map(|(lowest, highest, edges)| if lowest == highest {
                    format!("{lowest}: {edges}")
                } else {
                    format!("{lowest}–{highest}: {edges}")
                })
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if let Some(work) = &report.edge_work {
        say!(
            "  edge work       max {:.2} µs, mean {:.2} µs from an edge to the next preload over {} edges \
             (max {:.0}, mean {:.0} instructions at {NS_PER_INSTRUCTION} ns, QEMU -icount shift={ICOUNT_SHIFT})",
            work.max_ns / 1e3,
            work.mean_ns / 1e3,
            work.edges,
            work.max_instructions,
            work.mean_instructions
        );
    }
    for halt in &report.halts {
        say!(
            "  halt            output zeroed at tick {} ({:.6} s) with the plate at {:+.6} mm, moving {:+.3} mm/s (actual edges)",
            halt.tick,
            halt.time_s,
            halt.plate_position_m * 1e3,
            halt.plate_velocity_mps * 1e3
        );
    }
    for (name, part) in [
        ("actual edges ", &report.actual),
        ("planned ticks", &report.planned),
    ] {
        say!(
            "  {name}   feed {:.3} mm/s ({:.3} mm/s relative to the plate, last {} cycles), stick {:.1} %, \
             part travel {:.1} mm, plate excursion {:.4} mm, plate drift {:+.6} mm over {:.2} s",
            part.feed_rate_mps * 1e3,
            part.feed_rate_relative_mps * 1e3,
            part.steady_cycles,
            part.stick_fraction * 100.0,
            part.part_travel_m * 1e3,
            part.plate_excursion_m * 1e3,
            part.plate_drift_m * 1e3,
            part.duration_s
        );
    }
    if let Some(rates) = &report.plant_feed_rate_mps {
        say!(
            "  real plate      feed {:.3} mm/s on the actual edges, {:.3} mm/s on the planned ticks",
            rates.actual * 1e3,
            rates.planned * 1e3
        );
    }
    if let Some(plant) = &report.plant {
        print_plant(plant);
    }
    for problem in &check.problems {
        say!("  problem: {problem}");
    }
    for error in &report.firmware_errors {
        say!("  firmware: {error}");
    }
    for (what, path) in output.files() {
        say!("  {what:<16}{} ({shown})", path.display());
    }
}

/// The real plate and its part through the run on the actual edges, until the edges end or an
/// end stop, with the run's moments and the end stop marked.
fn plot_plate_run(
    path: &Path,
    plant: &Path,
    trace: &[PlatePoint],
    moments: &[Moment],
    end_stop: Option<EndStop>,
) -> Result<(), SimError> {
    let title = format!(
        "Firmware in the loop on {}, open loop: actual edges",
        plant.display()
    );
    plot_plate_trace(path, &title, trace, moments, end_stop)
}

/// The moments a chart of the run marks, in s: the start, each new duty taken while running, the
/// stop and a halt.
fn run_moments(events: &[Event], clock_hz: u32) -> Vec<Moment> {
    let seconds = |tick: u64| tick as f64 / f64::from(clock_hz.max(1));
    let mut moments = Vec::new();
    let mut duty = None;
    let mut running = false;
    for event in events {
        let (tick, name) = match event {
            Event::Plan { tick, spec, .. } => {
                let before = duty.replace(spec.duty);
                match before {
                    Some(before) if running && before != spec.duty => {
                        (*tick, format!("d = {before} → {}", spec.duty))
                    }
                    _ => continue,
                }
            }
            Event::Start { tick } => {
                running = true;
                (*tick, "start".to_owned())
            }
            Event::Stop { tick } => (*tick, "stop".to_owned()),
            Event::Halt { tick } => (*tick, "halt".to_owned()),
            _ => continue,
        };
        moments.push(Moment {
            x: seconds(tick),
            name: format!("{name} at {:.3} s", seconds(tick)),
        });
    }
    moments
}

/// Per-cycle mean velocities through the run, each at its cycle's middle, the run's moments
/// marked: the part on both timings above, the plate's drift (a few µm/s from the edges'
/// rounding) below on its own scale.
fn plot_run(
    path: &Path,
    actual: &PartReport,
    planned: &PartReport,
    moments: &[Moment],
) -> Result<(), SimError> {
    let series =
        |name: &str, part: &PartReport, value: fn(&hil::CyclePoint) -> f64, mark, color| Series {
            name: name.into(),
            points: part
                .cycles
                .iter()
                .map(|cycle| (cycle.start_s + cycle.duration_s / 2.0, value(cycle)))
                .collect(),
            mark,
            color,
        };
    let mut part = vec![
        series(
            "actual edges",
            actual,
            |c| c.part_velocity_mps * 1e3,
            Mark::Line,
            0,
        ),
        series(
            "planned ticks",
            planned,
            |c| c.part_velocity_mps * 1e3,
            Mark::DashedLine,
            2,
        ),
    ];
    let mut plate = vec![series(
        "actual edges",
        actual,
        |c| c.plate_velocity_mps * 1e6,
        Mark::Line,
        1,
    )];
    part.extend(plot::moment_lines(moments, &part, 3));
    plate.extend(plot::moment_lines(moments, &plate, 3));
    plot::stacked(
        path,
        "Firmware in the loop: mean velocity per cycle",
        "time (s)",
        &[
            Panel {
                y: "part (mm/s)",
                series: part,
            },
            Panel {
                y: "plate (µm/s)",
                series: plate,
            },
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chart marks the start, the new duty taken while running and the stop, not the plans
    /// taken before the start or one that keeps the duty.
    #[test]
    fn the_run_is_marked_where_it_starts_changes_duty_and_stops() {
        let text = "EVT plan tick=0 period_s=0.02 duty=0.586 stroke_m=0.0025 clock_hz=1000000 ramp=25\n\
                    EVT plan tick=0 period_s=0.02 duty=0.6 stroke_m=0.0025 clock_hz=1000000 ramp=25\n\
                    EVT start tick=40000\n\
                    EVT plan tick=40000 period_s=0.02 duty=0.6 stroke_m=0.0025 clock_hz=1000000 ramp=4\n\
                    EVT plan tick=215860 period_s=0.02 duty=0.606 stroke_m=0.0025 clock_hz=1000000 ramp=4\n\
                    EVT stop tick=416060\n";
        let stream = hil::read_stream(text.as_bytes()).unwrap();
        let moments = run_moments(&stream.events, 1_000_000);
        let names: Vec<&str> = moments.iter().map(|moment| moment.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "start at 0.040 s",
                "d = 0.6 → 0.606 at 0.216 s",
                "stop at 0.416 s"
            ]
        );
        assert_eq!(moments[1].x, 0.21586);
    }
}
