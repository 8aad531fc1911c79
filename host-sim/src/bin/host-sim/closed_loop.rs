//! `host-sim closed-loop`: the shared closed loop holding a real plate at one operating point:
//! the drive it identified beside the plant file's, how well it kept the plate centred, and its
//! feed rate beside the ideal plate's; a verdict against fixed criteria.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use feeder_shared::closed_loop::Identified;
use host_sim::closed_loop::{
    run_closed_loop, ClosedLoopOptions, ClosedLoopRun, CycleRecord, FEED_RATE_TOLERANCE,
    GAIN_TOLERANCE, MEAN_POSITION_LIMIT_M,
};
use host_sim::plate::{EndStop, PlantFile, PlateParams};
use host_sim::{OperatingPoint, SimError, Timing};
use serde::Serialize;

use crate::args::{count, ContactArgs, OutputArgs, TimingArgs, WaveArgs};
use crate::output::{emit, file_name, say};
use crate::plot::{self, Mark, Panel, Series};

/// Cycles the loop runs when not told: 60 s at 50 Hz.
const DEFAULT_CYCLES: u64 = 3_000;
/// Most cycles of `--cycles`: half an hour at 50 Hz.
const MAX_CYCLES: u64 = 100_000;
/// Cycles of the soft start when not told.
const DEFAULT_RAMP_CYCLES: u16 = 25;
/// Longest soft start of `--ramp-cycles`.
const MAX_RAMP_CYCLES: u16 = 1_000;

/// The flags of `host-sim closed-loop`.
#[derive(Args)]
#[command(
    after_help = "Exit code 0 when the run passes the criteria (worst |cycle mean position| ≤ \
                  50 µm, feed rate within 1 % of the ideal plate's, both identified gains within \
                  1 % of the plant file's, no end stop), 1 when it fails them, 2 when the run \
                  cannot be made or the loop gives up."
)]
pub struct ClosedLoopArgs {
    /// The plate as a TOML plant file (host-sim/plants/); the loop reads its `[sensors.encoder]`.
    #[arg(long, value_name = "FILE")]
    plant: PathBuf,
    #[command(flatten)]
    wave: WaveArgs,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    timing: TimingArgs,
    /// Cycles the feeder runs after the probe and the centring, soft start included (at most
    /// 100 000).
    #[arg(
        long,
        value_name = "N",
        default_value_t = DEFAULT_CYCLES,
        value_parser = count(1, MAX_CYCLES),
        allow_hyphen_values = true
    )]
    cycles: u64,
    /// Cycles of the soft start (at most 1 000).
    #[arg(
        long,
        value_name = "N",
        default_value_t = DEFAULT_RAMP_CYCLES,
        value_parser = count(1, MAX_RAMP_CYCLES),
        allow_hyphen_values = true
    )]
    ramp_cycles: u16,
    /// Ask for a new plan at the start of this cycle (counted from 0, the soft start's first;
    /// below --cycles): duty --to-duty, the same frequency and stroke (or a_max). The feed rate
    /// is that of the last 50 cycles, compared with the ideal plate's at the new duty.
    #[arg(
        long,
        value_name = "CYCLE",
        value_parser = count(0, MAX_CYCLES),
        allow_hyphen_values = true
    )]
    change_duty_at: Option<u64>,
    /// The duty of the plan --change-duty-at asks for.
    #[arg(long, value_name = "D", allow_hyphen_values = true)]
    to_duty: Option<f64>,
    #[command(flatten)]
    output: OutputArgs,
}

/// A drive as the loop sees it: identified, or the plant file's true values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct Drive {
    gain_positive: f64,
    gain_negative: f64,
    offset_mps2: f64,
    /// The current loop's time constant.
    lag_s: f64,
    /// Slide Coulomb friction as a deceleration.
    coulomb_mps2: f64,
    /// Slide viscous friction as a rate.
    viscous_per_s: f64,
    /// The identification's root-mean-square fit residual; null for the plant file.
    residual_m: Option<f64>,
}

impl Drive {
    fn identified(found: &Identified) -> Self {
        Drive {
            gain_positive: found.gain_positive,
            gain_negative: found.gain_negative,
            offset_mps2: found.offset_mps2,
            lag_s: found.lag_s,
            coulomb_mps2: found.coulomb_mps2,
            viscous_per_s: found.viscous_per_s,
            residual_m: Some(found.residual_m),
        }
    }

    /// The plant file's values in the identification's terms.
    fn truth(plate: &PlateParams) -> Self {
        Drive {
            gain_positive: plate.gain_positive,
            gain_negative: plate.gain_negative,
            offset_mps2: plate.zero_offset_fraction * plate.full_scale_accel_mps2,
            lag_s: plate
                .current_bandwidth_hz
                .map_or(0.0, |hz| 1.0 / (2.0 * std::f64::consts::PI * hz)),
            coulomb_mps2: plate.coulomb_friction_n / plate.mass_kg,
            viscous_per_s: plate.viscous_friction_nspm / plate.mass_kg,
            residual_m: None,
        }
    }
}

/// The new plan of `--change-duty-at`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct DutyChange {
    at_cycle: u64,
    duty: f64,
    stroke_m: f64,
    accel_mps2: f64,
}

#[derive(Serialize)]
struct ClosedLoopReport {
    plant: PathBuf,
    freq_hz: f64,
    duty: f64,
    stroke_m: f64,
    accel_mps2: f64,
    mu: f64,
    mu_static: f64,
    gravity_mps2: f64,
    mass_kg: f64,
    force_n: f64,
    clock_hz: u32,
    cycles: u64,
    ramp_cycles: u16,
    duty_change: Option<DutyChange>,
    /// Cycles (and idle periods) of the course before the release of the soft start: the idle
    /// period before the start, the probe, the identification and the centring.
    centring_cycles: usize,
    /// Simulated time from the probe's start to the run's end.
    simulated_s: f64,
    identified: Drive,
    plant_drive: Drive,
    /// `identified / plant − 1` of each gain.
    gain_positive_error: f64,
    gain_negative_error: f64,
    /// The largest `|cycle mean position|` over the running cycles …
    worst_mean_position_m: f64,
    /// … the cycle where it was …
    worst_cycle: Option<u64>,
    /// … and the largest from the end of the soft start on (null if the run ends before).
    worst_after_ramp_m: Option<f64>,
    /// The last cycles the feed rate is averaged over.
    average_cycles: u64,
    feed_rate_mps: f64,
    /// The ideal plate's steady feed rate at the final duty on the same tick plan.
    ideal_feed_rate_mps: f64,
    /// `feed_rate / ideal − 1`; null when the ideal plate does not feed.
    feed_rate_difference: Option<f64>,
    end_stop: Option<EndStop>,
    passed: bool,
    verdict: String,
    reasons: Vec<String>,
    wall_time_s: f64,
}

/// One cycle of the loop, for the CSV.
#[derive(Serialize)]
struct CycleRow {
    time_s: f64,
    cycle: u64,
    centring: bool,
    idle: bool,
    start_m: f64,
    mean_position_m: f64,
    part_m: f64,
    positive_trim: f64,
    negative_trim: f64,
    bias_mps2: f64,
}

impl From<&CycleRecord> for CycleRow {
    fn from(record: &CycleRecord) -> Self {
        CycleRow {
            time_s: record.time_s,
            cycle: record.cycle,
            centring: record.centring,
            idle: record.idle,
            start_m: record.start_m,
            mean_position_m: record.mean_position_m,
            part_m: record.part_m,
            positive_trim: record.positive_trim,
            negative_trim: record.negative_trim,
            bias_mps2: record.bias_mps2,
        }
    }
}

/// Runs `host-sim closed-loop`; `Ok(false)` when the run fails the criteria.
pub fn run(args: &ClosedLoopArgs) -> Result<bool, SimError> {
    args.output.check()?;
    let clock_hz = args.timing.clock_hz().ok_or(SimError::BadRange {
        what: "the closed loop trims the shared scheduler's tick plan cycle by cycle: leave out \
               --exact-times",
    })?;
    let contact = args.contact.contact()?;
    let point = OperatingPoint::new(args.wave.spec()?, contact, Some(clock_hz))?;
    let change = match (args.change_duty_at, args.to_duty) {
        (Some(at), Some(duty)) => {
            if at >= args.cycles {
                return Err(SimError::Request(format!(
                    "--change-duty-at {at} is not a cycle of the run: the loop runs cycles 0 to \
                     {} (--cycles {})",
                    args.cycles - 1,
                    args.cycles
                )));
            }
            let mut wave = args.wave.clone();
            wave.duty = duty;
            Some((
                at,
                OperatingPoint::new(wave.spec()?, contact, Some(clock_hz))?,
            ))
        }
        (None, None) => None,
        (Some(_), None) | (None, Some(_)) => {
            return Err(SimError::BadRange {
                what: "--change-duty-at CYCLE says when the plan changes and --to-duty D to \
                       which duty: give both or neither",
            })
        }
    };
    let plant = PlantFile::from_path(&args.plant)?;
    let plan = |point: &OperatingPoint| match point.timing {
        Timing::Ticks(plan) => Ok(plan),
        Timing::Exact => Err(SimError::BadRange {
            what: "the closed loop needs a tick plan",
        }),
    };
    let mut options = ClosedLoopOptions::new(args.cycles);
    options.ramp_cycles = args.ramp_cycles;
    options.plan_change = match &change {
        Some((at, new_point)) => Some((*at, plan(new_point)?)),
        None => None,
    };
    let started = Instant::now();
    let run = run_closed_loop(&plant, &point.contact, plan(&point)?, &options)?;
    let final_point = change.map_or(point, |(_, new_point)| new_point);
    let ideal_feed_rate_mps = final_point.steady().feed_rate_mps;
    let wall_time_s = started.elapsed().as_secs_f64();
    let report = ClosedLoopReport::new(ReportInputs {
        path: &args.plant,
        point: &point,
        clock_hz,
        options: &options,
        change: change.map(|(at, new_point)| DutyChange {
            at_cycle: at,
            duty: new_point.waveform.duty,
            stroke_m: new_point.waveform.stroke_m,
            accel_mps2: new_point.waveform.accel_mps2,
        }),
        plate: &plant.plate,
        run: &run,
        ideal_feed_rate_mps,
        velocity_scale_mps: final_point.velocity_scale_mps(),
        wall_time_s,
    });
    let rows: Vec<CycleRow> = run.cycles.iter().map(CycleRow::from).collect();
    emit(
        &args.output,
        &rows,
        |path| plot_run(path, &report, &run),
        &report,
        || print_report(&report, &args.output),
    )?;
    Ok(report.passed)
}

/// What a report is made of.
struct ReportInputs<'a> {
    path: &'a Path,
    point: &'a OperatingPoint,
    clock_hz: u32,
    options: &'a ClosedLoopOptions,
    change: Option<DutyChange>,
    plate: &'a PlateParams,
    run: &'a ClosedLoopRun,
    ideal_feed_rate_mps: f64,
    velocity_scale_mps: f64,
    wall_time_s: f64,
}

impl ClosedLoopReport {
    fn new(inputs: ReportInputs<'_>) -> Self {
        let ReportInputs {
            path,
            point,
            clock_hz,
            options,
            change,
            plate,
            run,
            ideal_feed_rate_mps,
            velocity_scale_mps,
            wall_time_s,
        } = inputs;
        let identified = Drive::identified(&run.identified);
        let plant_drive = Drive::truth(plate);
        let gain_positive_error = identified.gain_positive / plant_drive.gain_positive - 1.0;
        let gain_negative_error = identified.gain_negative / plant_drive.gain_negative - 1.0;
        let feed_rate_difference =
            (ideal_feed_rate_mps != 0.0).then(|| run.feed_rate_mps / ideal_feed_rate_mps - 1.0);
        let mut reasons = Vec::new();
        if !within(run.worst_mean_position_m, MEAN_POSITION_LIMIT_M) {
            reasons.push(format!(
                "worst mean position {:.1} µm: over {:.0} µm",
                run.worst_mean_position_m * 1e6,
                MEAN_POSITION_LIMIT_M * 1e6
            ));
        }
        match feed_rate_difference {
            Some(difference) if !within(difference, FEED_RATE_TOLERANCE) => reasons.push(format!(
                "feed rate {:.2} % {} the ideal plate's: over {:.0} %",
                difference.abs() * 1e2,
                if difference < 0.0 { "below" } else { "above" },
                FEED_RATE_TOLERANCE * 1e2
            )),
            // Where the ideal part does not move, the real one must not either: within the
            // same share of the velocity scale a_max·T/4.
            None if !within(run.feed_rate_mps, FEED_RATE_TOLERANCE * velocity_scale_mps) => reasons
                .push(format!(
                    "feed rate {:.2} mm/s where the ideal plate's part does not move",
                    run.feed_rate_mps * 1e3
                )),
            _ => {}
        }
        for (sign, error) in [("+", gain_positive_error), ("−", gain_negative_error)] {
            if !within(error, GAIN_TOLERANCE) {
                reasons.push(format!(
                    "gain {sign} identified {:.2} % {}: over {:.0} %",
                    error.abs() * 1e2,
                    if error < 0.0 { "low" } else { "high" },
                    GAIN_TOLERANCE * 1e2
                ));
            }
        }
        if let Some(stop) = run.end_stop {
            reasons.push(format!(
                "end stop at {:+.1} mm after {:.3} s",
                stop.position_m * 1e3,
                stop.time_s
            ));
        }
        let passed = reasons.is_empty();
        let verdict = if passed {
            "closed loop: PASSED".to_owned()
        } else {
            format!("closed loop: FAILED ({})", reasons.join(", "))
        };
        let period_s = point.waveform.period_s;
        ClosedLoopReport {
            plant: path.to_path_buf(),
            freq_hz: point.waveform.frequency_hz(),
            duty: point.waveform.duty,
            stroke_m: point.waveform.stroke_m,
            accel_mps2: point.waveform.accel_mps2,
            mu: point.contact.mu,
            mu_static: point.contact.mu_static,
            gravity_mps2: point.contact.gravity_mps2,
            mass_kg: point.contact.mass_kg,
            force_n: point.contact.force_n,
            clock_hz,
            cycles: options.cycles,
            ramp_cycles: options.ramp_cycles,
            duty_change: change,
            centring_cycles: run.cycles.iter().filter(|c| c.centring).count(),
            simulated_s: run.end_stop.map_or_else(
                || run.cycles.last().map_or(0.0, |c| c.time_s + period_s),
                |stop| stop.time_s,
            ),
            identified,
            plant_drive,
            gain_positive_error,
            gain_negative_error,
            worst_mean_position_m: run.worst_mean_position_m,
            worst_cycle: worst_cycle(run, 0).map(|c| c.cycle),
            worst_after_ramp_m: worst_cycle(run, u64::from(options.ramp_cycles))
                .map(|c| c.mean_position_m.abs()),
            average_cycles: options.average_cycles,
            feed_rate_mps: run.feed_rate_mps,
            ideal_feed_rate_mps,
            feed_rate_difference,
            end_stop: run.end_stop,
            passed,
            verdict,
            reasons,
            wall_time_s,
        }
    }
}

/// The running cycle from `from` on (not idle, before any end stop) whose mean position is the
/// farthest from the centre.
fn worst_cycle(run: &ClosedLoopRun, from: u64) -> Option<&CycleRecord> {
    let end_s = run.end_stop.map_or(f64::INFINITY, |stop| stop.time_s);
    run.cycles
        .iter()
        .filter(|c| !c.centring && !c.idle && c.cycle >= from && c.time_s < end_s)
        .max_by(|a, b| a.mean_position_m.abs().total_cmp(&b.mean_position_m.abs()))
}

/// `|value| ≤ limit`; false for NaN.
fn within(value: f64, limit: f64) -> bool {
    value.abs() <= limit
}

fn print_report(report: &ClosedLoopReport, output: &OutputArgs) {
    say!(
        "operating point   {} Hz, d = {}, stroke {:.4} mm, a_max {:.3} m/s², tick plan at {} Hz",
        report.freq_hz,
        report.duty,
        report.stroke_m * 1e3,
        report.accel_mps2,
        report.clock_hz
    );
    if let Some(change) = report.duty_change {
        say!(
            "plan change       d = {} from cycle {} (stroke {:.4} mm, a_max {:.3} m/s²)",
            change.duty,
            change.at_cycle,
            change.stroke_m * 1e3,
            change.accel_mps2
        );
    }
    say!("plant             {}", report.plant.display());
    say!(
        "run               {} cycles after {} of probe, identification and centring, soft start \
         over {}; {:.2} s simulated",
        report.cycles,
        report.centring_cycles,
        report.ramp_cycles,
        report.simulated_s
    );
    say!("drive             identified   plant file   gain error");
    let (found, truth) = (&report.identified, &report.plant_drive);
    say!(
        "  gain +          {:<12.5} {:<12.5} {:+.3} %",
        found.gain_positive,
        truth.gain_positive,
        report.gain_positive_error * 1e2
    );
    say!(
        "  gain −          {:<12.5} {:<12.5} {:+.3} %",
        found.gain_negative,
        truth.gain_negative,
        report.gain_negative_error * 1e2
    );
    let row = |what: &str, found: f64, truth: f64, unit: &str| {
        say!(
            "  {what:<15} {:<12} {}",
            format!("{found:.3} {unit}"),
            format!("{truth:.3} {unit}")
        );
    };
    row("offset", found.offset_mps2, truth.offset_mps2, "m/s²");
    row("lag", found.lag_s * 1e3, truth.lag_s * 1e3, "ms");
    row("Coulomb", found.coulomb_mps2, truth.coulomb_mps2, "m/s²");
    row("viscous", found.viscous_per_s, truth.viscous_per_s, "1/s");
    if let Some(residual_m) = found.residual_m {
        say!("  fit residual    {:.2} µm", residual_m * 1e6);
    }
    let at = report
        .worst_cycle
        .map_or(String::new(), |cycle| format!(" (cycle {cycle})"));
    let after = report.worst_after_ramp_m.map_or(String::new(), |worst_m| {
        format!(", {:.1} µm after the soft start", worst_m * 1e6)
    });
    say!(
        "mean position     worst |cycle mean| {:.1} µm over the running cycles{at}{after}",
        report.worst_mean_position_m * 1e6
    );
    let difference = report
        .feed_rate_difference
        .map_or(String::new(), |d| format!(" ({:+.2} %)", d * 1e2));
    say!(
        "feed rate         {:.2} mm/s over the last {} cycles, ideal plate {:.2} mm/s{difference}",
        report.feed_rate_mps * 1e3,
        report.average_cycles,
        report.ideal_feed_rate_mps * 1e3
    );
    match report.end_stop {
        Some(stop) => say!(
            "end stop          HIT after {:.3} s at {:+.1} mm, plate at {:+.3} m/s: the run ends \
             there",
            stop.time_s,
            stop.position_m * 1e3,
            stop.velocity_mps
        ),
        None => say!("end stop          not reached"),
    }
    say!("wall time         {:.2} s", report.wall_time_s);
    for (what, path) in [("csv", &output.csv), ("plot", &output.plot)] {
        if let Some(path) = path {
            say!("{what:<18}{}", path.display());
        }
    }
    say!("{}", report.verdict);
}

/// Three panels over time from the soft start (the centring before it, far from the centre, is
/// left out): the plate's mean position over every cycle, the bias and the two level trims the
/// loop applied in it.
fn plot_run(path: &Path, report: &ClosedLoopReport, run: &ClosedLoopRun) -> Result<(), SimError> {
    let running: Vec<&CycleRecord> = run.cycles.iter().filter(|c| !c.centring).collect();
    let over_time = |value: fn(&CycleRecord) -> f64| -> Vec<(f64, f64)> {
        running.iter().map(|c| (c.time_s, value(c))).collect()
    };
    let start_s = running.first().map_or(0.0, |c| c.time_s);
    let end_s = running.last().map_or(0.0, |c| c.time_s);
    let limit_um = MEAN_POSITION_LIMIT_M * 1e6;
    let line = |name: String, points: Vec<(f64, f64)>, mark: Mark, color: usize| Series {
        name,
        points,
        mark,
        color,
    };
    let panels = [
        Panel {
            y: "cycle mean position (µm)",
            series: vec![
                line(
                    format!(
                        "plate's mean position over each cycle: worst {:.1} µm; feed {:.2} mm/s \
                         (ideal plate {:.2} mm/s)",
                        report.worst_mean_position_m * 1e6,
                        report.feed_rate_mps * 1e3,
                        report.ideal_feed_rate_mps * 1e3
                    ),
                    over_time(|c| c.mean_position_m * 1e6),
                    Mark::ThinLine,
                    0,
                ),
                line(
                    format!("+{limit_um:.0} µm"),
                    vec![(start_s, limit_um), (end_s, limit_um)],
                    Mark::DashedLine,
                    1,
                ),
                line(
                    format!("−{limit_um:.0} µm"),
                    vec![(start_s, -limit_um), (end_s, -limit_um)],
                    Mark::DashedLine,
                    1,
                ),
            ],
        },
        Panel {
            y: "bias (m/s²)",
            series: vec![line(
                "bias added to every level".into(),
                over_time(|c| c.bias_mps2),
                Mark::ThinLine,
                2,
            )],
        },
        Panel {
            y: "level trim",
            series: vec![
                line(
                    "factor on +a".into(),
                    over_time(|c| c.positive_trim),
                    Mark::ThinLine,
                    3,
                ),
                line(
                    "factor on −a".into(),
                    over_time(|c| c.negative_trim),
                    Mark::ThinLine,
                    4,
                ),
            ],
        },
    ];
    let plant = file_name(&report.plant);
    let duty = report.duty_change.map_or(format!("{}", report.duty), |c| {
        format!("{} → {} at cycle {}", report.duty, c.duty, c.at_cycle)
    });
    let title = format!(
        "Closed loop on {plant} from the soft start: {} Hz, d = {duty}",
        report.freq_hz
    );
    plot::stacked(path, &title, "time (s)", &panels)
}

#[cfg(test)]
mod tests {
    use feeder_shared::{Drive as WaveDrive, WaveformSpec};
    use host_sim::Contact;

    use super::*;

    fn report(run: &ClosedLoopRun, ideal_feed_rate_mps: f64) -> ClosedLoopReport {
        let spec =
            WaveformSpec::from_frequency(50.0, 0.586, WaveDrive::Stroke { stroke_m: 2.5e-3 });
        let point =
            OperatingPoint::new(spec, Contact::kinetic(1.0, 1e-4).unwrap(), Some(1_000_000))
                .unwrap();
        let plate = PlateParams {
            gain_positive: 1.02,
            gain_negative: 0.98,
            ..PlateParams::default()
        };
        ClosedLoopReport::new(ReportInputs {
            path: Path::new("plant.toml"),
            point: &point,
            clock_hz: 1_000_000,
            options: &ClosedLoopOptions::new(100),
            change: None,
            plate: &plate,
            run,
            ideal_feed_rate_mps,
            velocity_scale_mps: point.velocity_scale_mps(),
            wall_time_s: 0.0,
        })
    }

    fn run(gain_positive: f64, worst_m: f64, feed_rate_mps: f64) -> ClosedLoopRun {
        ClosedLoopRun {
            identified: Identified {
                gain_positive,
                gain_negative: 0.98,
                offset_mps2: 0.0,
                lag_s: 0.0,
                coulomb_mps2: 0.0,
                viscous_per_s: 0.0,
                residual_m: 0.0,
            },
            cycles: Vec::new(),
            feed_rate_mps,
            worst_mean_position_m: worst_m,
            end_stop: None,
        }
    }

    #[test]
    fn a_run_within_every_criterion_passes() {
        let report = report(&run(1.02 * 1.009, 49e-6, 0.1009), 0.1);
        assert_eq!(report.verdict, "closed loop: PASSED");
        assert!(report.passed && report.reasons.is_empty());
    }

    #[test]
    fn a_failed_run_names_each_criterion_it_misses() {
        let mut missed = run(1.02 * 1.011, 51e-6, 0.0989);
        missed.end_stop = Some(EndStop {
            time_s: 1.5,
            position_m: -0.005,
            velocity_mps: -0.2,
        });
        let report = report(&missed, 0.1);
        assert!(!report.passed);
        assert_eq!(
            report.verdict,
            "closed loop: FAILED (worst mean position 51.0 µm: over 50 µm, feed rate 1.10 % below \
             the ideal plate's: over 1 %, gain + identified 1.10 % high: over 1 %, end stop at \
             -5.0 mm after 1.500 s)"
        );
        assert_eq!(report.reasons.len(), 4);
    }

    #[test]
    fn a_feed_rate_that_is_not_a_number_fails() {
        let report = report(&run(1.02, 0.0, f64::NAN), 0.1);
        assert_eq!(report.reasons.len(), 1, "{:?}", report.reasons);
    }
}
