//! `host-sim closed-loop`: the shared closed loop holding a real plate at one operating point:
//! the drive it identified beside the plant file's, how well it kept the plate centred, and its
//! feed rate beside the ideal plate's; a verdict against fixed criteria.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::Args;
use feeder_shared::closed_loop::{FeedCompensation, Identified};
use feeder_shared::Settings;
use host_sim::closed_loop::{
    feed_compensation_line, run_closed_loop, ClosedLoopOptions, ClosedLoopRun, CycleRecord, Verdict,
};
use host_sim::plate::{PlantFile, PlateParams};
use host_sim::{OperatingPoint, SimError, Timing};
use serde::Serialize;

use crate::args::{check_drive_limits, CountArg, OutputArgs, PointArgs};
use crate::output::{emit, file_name, say};
use crate::plot::{self, Mark, Moment, Panel, Series};

/// Cycles the loop runs when not told: 60 s at 50 Hz.
const DEFAULT_CYCLES: u64 = 3_000;
/// Most cycles of `--cycles`: half an hour at 50 Hz.
const MAX_CYCLES: u64 = 100_000;
/// Cycles of the soft start when not told: the firmware's power-up setting.
const DEFAULT_RAMP_CYCLES: u16 = Settings::DEFAULT.ramp_cycles;
/// Longest soft start of `--ramp-cycles`.
const MAX_RAMP_CYCLES: u16 = 1_000;

/// The flags of `host-sim closed-loop`.
#[derive(Args)]
#[command(
    after_help = "Exit code 0 when the run passes the criteria (worst |cycle mean position| ≤ \
                  50 µm from the release on, feed rate within 1 % of the ideal plate's, both \
                  identified gains within 1 % of the plant file's, no end stop), 1 when it fails \
                  them, 2 when the loop gives up (its report, --json and --csv are written all \
                  the same), the run cannot be made or an output file could not be written \
                  (after the report)."
)]
pub struct ClosedLoopArgs {
    /// The plate as a TOML plant file (host-sim/plants/); the loop reads its `[sensors.encoder]`.
    #[arg(long, value_name = "FILE")]
    plant: PathBuf,
    #[command(flatten)]
    point: PointArgs,
    /// Cycles the feeder runs after the one that releases the soft start, soft start included,
    /// as the firmware's scenario counts `cycles=N` (at most 100 000).
    #[arg(long, default_value_t = DEFAULT_CYCLES, count_in = (1, MAX_CYCLES))]
    cycles: u64,
    /// Cycles of the soft start (at most 1 000).
    #[arg(long, default_value_t = DEFAULT_RAMP_CYCLES, count_in = (1, MAX_RAMP_CYCLES))]
    ramp_cycles: u16,
    /// Ask for a new plan at the start of this cycle (counted from 0, the soft start's first;
    /// below --cycles): duty --to-duty, the same frequency and stroke (or a_max). The feed rate
    /// is that of the last 50 cycles, compared with the ideal plate's at the new duty.
    #[arg(long, count_in = (0, MAX_CYCLES), value_name = "CYCLE")]
    change_duty_at: Option<u64>,
    /// The duty of the plan --change-duty-at asks for.
    #[arg(long, value_name = "D", allow_hyphen_values = true)]
    to_duty: Option<f64>,
    #[command(flatten)]
    output: OutputArgs,
}

/// The feed's compensation of the drive's lag as the report gives it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct FeedCompensated {
    /// The factor on every level.
    amplitude: f64,
    /// The feed at that amplitude on the identified drive, and the ideal plate's.
    feed_mps: f64,
    ideal_mps: f64,
    /// The ideal feed needs more than the drive's linear range: `feed_mps` is what the feeder
    /// gives instead.
    limited: bool,
}

impl From<&FeedCompensation> for FeedCompensated {
    fn from(found: &FeedCompensation) -> Self {
        FeedCompensated {
            amplitude: found.amplitude,
            feed_mps: found.feed_mps,
            ideal_mps: found.ideal_mps,
            limited: found.limited,
        }
    }
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
    /// Slide viscous friction (and the spring's damping) as a rate.
    viscous_per_s: f64,
    /// The centring spring as `k/M`.
    spring_per_s2: f64,
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
            spring_per_s2: found.spring_per_s2,
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
            viscous_per_s: (plate.viscous_friction_nspm + plate.spring_damping_nspm)
                / plate.mass_kg,
            spring_per_s2: plate.spring_npm / plate.mass_kg,
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
    /// Simulated time from power-up to the run's end.
    simulated_s: f64,
    /// The drive identified (null if it never was) and the plant file's.
    identified: Option<Drive>,
    plant_drive: Drive,
    /// The amplitude that gives the ideal plate's feed behind the identified drive's lag, and
    /// the feed it gives (null before the drive is identified).
    feed_compensation: Option<FeedCompensated>,
    /// The plant file's end stops (null: none).
    plant_end_stop_m: Option<f64>,
    /// The verdict and every figure it judged.
    #[serde(flatten)]
    verdict: Verdict,
    /// The verdict as one line.
    verdict_line: String,
    wall_time_s: f64,
}

/// Runs `host-sim closed-loop`: the report is out for every outcome, and the exit code says
/// which (0 passed, 1 failed, 2 the loop gave up).
pub fn run(args: &ClosedLoopArgs) -> Result<ExitCode, SimError> {
    args.output.check()?;
    let clock_hz = args.point.timing.clock_hz().ok_or(SimError::BadRange {
        what: "the closed loop trims the shared scheduler's tick plan cycle by cycle: leave out \
               --exact-times",
    })?;
    let contact = args.point.contact.contact()?;
    let spec = args.point.wave.spec()?;
    let point = OperatingPoint::new(spec, contact, Some(clock_hz))?;
    check_drive_limits(spec, "")?;
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
            let mut wave = args.point.wave.clone();
            wave.duty = duty;
            let new_spec = wave.spec()?;
            let new_point = OperatingPoint::new(new_spec, contact, Some(clock_hz))?;
            check_drive_limits(new_spec, "")?;
            Some((at, new_point))
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
    let verdict = run.verdict(
        &plant.plate,
        &options,
        final_point.steady().feed_rate_mps,
        final_point.velocity_scale_mps(),
    );
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
        verdict,
        wall_time_s,
    });
    emit(
        &args.output,
        &run.cycles,
        |path| plot_run(path, &report, &run),
        &report,
        || print_report(&report, &args.output),
    )?;
    Ok(if run.gave_up.is_some() {
        ExitCode::from(2)
    } else if report.verdict.passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
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
    verdict: Verdict,
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
            verdict,
            wall_time_s,
        } = inputs;
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
            simulated_s: run.simulated_s,
            identified: run.identified.as_ref().map(Drive::identified),
            plant_drive: Drive::truth(plate),
            feed_compensation: run.feed.as_ref().map(FeedCompensated::from),
            plant_end_stop_m: plate.end_stop_m,
            verdict_line: verdict.line(),
            verdict,
            wall_time_s,
        }
    }
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
        "run               {} cycles of probe, identification and centring, then {} fed from \
         the release to {} cycles after it, soft start over {}; {:.2} s simulated",
        report.centring_cycles,
        report.verdict.fed_cycles,
        report.cycles,
        report.ramp_cycles,
        report.simulated_s
    );
    let truth = &report.plant_drive;
    match (&report.identified, report.verdict.gain_errors) {
        (Some(found), Some([error_positive, error_negative])) => {
            say!("drive             identified   plant file   gain error");
            say!(
                "  gain +          {:<12.5} {:<12.5} {:+.3} %",
                found.gain_positive,
                truth.gain_positive,
                error_positive * 1e2
            );
            say!(
                "  gain −          {:<12.5} {:<12.5} {:+.3} %",
                found.gain_negative,
                truth.gain_negative,
                error_negative * 1e2
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
            row(
                "spring k/M",
                found.spring_per_s2,
                truth.spring_per_s2,
                "1/s²",
            );
            if let Some(residual_m) = found.residual_m {
                say!("  fit residual    {:.2} µm", residual_m * 1e6);
            }
        }
        _ => say!("drive             not identified"),
    }
    if let Some(found) = &report.feed_compensation {
        say!(
            "{}",
            feed_compensation_line(
                found.amplitude,
                found.ideal_mps,
                found.limited.then_some(found.feed_mps)
            )
        );
    }
    let verdict = &report.verdict;
    say!(
        "start-up          peak |x| {:.1} µm from power-up to the release (bound {:.0} µm), {:.1} \
         µm over the whole run",
        verdict.startup_peak_m * 1e6,
        verdict.startup_limit_m * 1e6,
        verdict.peak_excursion_m * 1e6
    );
    match verdict.worst_mean_position_m {
        Some(worst_m) => {
            let at = verdict
                .worst_cycle
                .map_or(String::new(), |cycle| format!(" (cycle {cycle})"));
            let after = verdict
                .settled_mean_position_m
                .map_or(String::new(), |settled_m| {
                    format!(", {:.1} µm after the soft start", settled_m * 1e6)
                });
            say!(
                "mean position     worst |cycle mean| {:.1} µm from the release on{at}{after}",
                worst_m * 1e6
            );
        }
        None => say!("mean position     no cycle after a release"),
    }
    match verdict.feed_rate_mps {
        Some(rate) => {
            let difference = verdict
                .feed_rate_difference
                .map_or(String::new(), |d| format!(" ({:+.2} %)", d * 1e2));
            say!(
                "feed rate         {:.2} mm/s over the last {} cycles, ideal plate {:.2} \
                 mm/s{difference}",
                rate * 1e3,
                verdict.feed_cycles,
                verdict.ideal_feed_rate_mps * 1e3
            );
        }
        None => say!(
            "feed rate         not measured: {} of {} cycles fed",
            verdict.fed_cycles,
            verdict.feed_cycles
        ),
    }
    match verdict.end_stop {
        Some(stop) => say!(
            "end stop          HIT after {:.3} s at {:+.1} mm, plate at {:+.3} m/s: the run ends \
             there",
            stop.time_s,
            stop.position_m * 1e3,
            stop.velocity_mps
        ),
        None => say!("end stop          not reached"),
    }
    if let Some(reason) = &verdict.gave_up {
        say!("gave up           {reason}");
    }
    say!("wall time         {:.2} s", report.wall_time_s);
    for (what, path) in output.files() {
        say!("{what:<18}{}", path.display());
    }
    say!("{}", report.verdict_line);
}

/// Four panels over time: the largest `|x|` the encoder sampled in each cycle from power-up
/// (probe and centring included) against the start-up's bound and the end stops; then, from
/// the release on, the plate's mean position over every cycle, the bias and the two level
/// trims the loop applied in it.
fn plot_run(path: &Path, report: &ClosedLoopReport, run: &ClosedLoopRun) -> Result<(), SimError> {
    let verdict = &report.verdict;
    let running: Vec<&CycleRecord> = run.cycles.iter().filter(|c| !c.centring).collect();
    let over_time = |value: fn(&CycleRecord) -> f64| -> Vec<(f64, f64)> {
        running.iter().map(|c| (c.time_s, value(c))).collect()
    };
    let run_end_s = run.simulated_s;
    let start_s = running.first().map_or(run_end_s, |c| c.time_s);
    let mut excursion = vec![
        Series::new(
            if verdict.startup_peak_m == verdict.peak_excursion_m {
                format!(
                    "largest |x| per cycle: peak {:.0} µm",
                    verdict.startup_peak_m * 1e6
                )
            } else {
                format!(
                    "largest |x| per cycle: {:.0} µm to the release, {:.0} µm in all",
                    verdict.startup_peak_m * 1e6,
                    verdict.peak_excursion_m * 1e6
                )
            },
            run.cycles
                .iter()
                .map(|c| (c.time_s, c.peak_m * 1e6))
                .collect(),
            Mark::ThinLine,
            0,
        ),
        Series::level(
            format!("start-up bound {:.0} µm", verdict.startup_limit_m * 1e6),
            verdict.startup_limit_m * 1e6,
            0.0..run_end_s,
            1,
        ),
    ];
    if let Some(release) = running.first() {
        let top_um = report
            .plant_end_stop_m
            .unwrap_or(verdict.peak_excursion_m)
            .max(verdict.peak_excursion_m)
            * 1e6;
        excursion.push(Series::new(
            format!("soft start released at {:.2} s", release.time_s),
            vec![(release.time_s, 0.0), (release.time_s, top_um)],
            Mark::DashedLine,
            2,
        ));
    }
    if let Some(stop_m) = report.plant_end_stop_m {
        excursion.push(Series::level(
            format!("end stop {:.1} mm", stop_m * 1e3),
            stop_m * 1e6,
            0.0..run_end_s,
            5,
        ));
    }
    let mean = match verdict.worst_mean_position_m {
        Some(worst_m) => {
            let feed = verdict.feed_rate_mps.map_or(String::new(), |rate| {
                format!(
                    "; feed {:.2} mm/s (ideal {:.2})",
                    rate * 1e3,
                    verdict.ideal_feed_rate_mps * 1e3
                )
            });
            format!("mean per cycle: worst {:.1} µm{feed}", worst_m * 1e6)
        }
        None => "mean per cycle: the soft start was never released".into(),
    };
    let duty_change: Vec<Moment> = report
        .duty_change
        .and_then(|change| {
            let at = run.cycles.iter().find(|c| c.cycle == change.at_cycle)?;
            Some(Moment {
                x: at.time_s,
                name: format!(
                    "d = {} → {} at {:.2} s",
                    report.duty, change.duty, at.time_s
                ),
            })
        })
        .into_iter()
        .collect();
    let marked = |mut series: Vec<Series>| {
        series.extend(plot::moment_lines(&duty_change, &series, 6));
        series
    };
    let mut panels = [
        Panel {
            y: "largest |x| (µm)",
            series: excursion,
        },
        plot::mean_position_panel(
            mean,
            over_time(|c| c.mean_position_m * 1e6),
            Some(start_s..run_end_s),
        ),
        Panel {
            y: "bias (m/s²)",
            series: vec![Series::new(
                "bias added to every level",
                over_time(|c| c.bias_mps2),
                Mark::Dots,
                2,
            )],
        },
        Panel {
            y: "level trim",
            series: vec![
                Series::new(
                    "factor on +a",
                    over_time(|c| c.positive_trim),
                    Mark::Dots,
                    3,
                ),
                Series::new(
                    "factor on −a",
                    over_time(|c| c.negative_trim),
                    Mark::Dots,
                    4,
                ),
            ],
        },
    ];
    // The change is marked from the release on; the start-up's panel leaves it out.
    for panel in &mut panels[1..] {
        panel.series = marked(std::mem::take(&mut panel.series));
    }
    let plant = file_name(&report.plant);
    let duty = report.duty_change.map_or(format!("{}", report.duty), |c| {
        format!("{} → {} at cycle {}", report.duty, c.duty, c.at_cycle)
    });
    let title = format!(
        "Closed loop on {plant} from power-up: {} Hz, d = {duty}; {}",
        report.freq_hz,
        if verdict.passed { "passed" } else { "FAILED" }
    );
    plot::stacked(path, &title, "time (s)", &panels)
}
