//! `host-sim family`: the closed loop on a seeded family of plants across its envelope and just
//! outside it, each at the family's operating points: per point the pass rate, the worst
//! start-up peak, the worst cycle mean and the worst feed error, which criteria the failures
//! missed, and how many outside plants were refused by cause.

use std::collections::BTreeMap;
use std::time::Instant;

use clap::Args;
use feeder_shared::closed_loop::Cause;
use host_sim::closed_loop::family::{self, FamilyPoint, FamilyRun, Member, CYCLES, POINTS};
use host_sim::closed_loop::verdict::STARTUP_PEAK_LIMIT_M;
use host_sim::closed_loop::MEAN_POSITION_LIMIT_M;
use host_sim::SimError;
use rayon::prelude::*;
use serde::Serialize;

use crate::args::{CountArg, OutputArgs};
use crate::output::{emit, progress, say};
use crate::plot::{self, Mark, Panel, Series};

/// The flags of `host-sim family`.
#[derive(Args)]
#[command(
    after_help = "Exit code 0 when every inside plant passes at every point and every outside \
                  plant is refused by its cause before it moves 0.5 mm, 1 otherwise."
)]
pub struct FamilyArgs {
    /// The family's seed: member i depends on it and on i alone.
    #[arg(long, default_value_t = 1, allow_hyphen_values = true)]
    seed: u64,
    /// Plants drawn inside the envelope.
    #[arg(long, default_value_t = 500, count_in = (0_usize, 100_000))]
    inside: usize,
    /// Plants drawn just outside it, one property past its limit, the causes in turn.
    #[arg(long, default_value_t = 50, count_in = (0_usize, 100_000))]
    outside: usize,
    #[command(flatten)]
    output: OutputArgs,
}

/// The figures of one operating point over the inside plants.
#[derive(Debug, Clone, Serialize)]
struct PointSummary {
    point: FamilyPoint,
    runs: usize,
    passed: usize,
    worst_startup_peak_m: f64,
    worst_mean_position_m: f64,
    worst_feed_error: f64,
    /// How many runs missed each criterion (a run may miss several).
    missed: BTreeMap<&'static str, usize>,
    /// How many runs the course said, before the release, would feed less than the ideal
    /// plate: the drive's range cannot give the compensation.
    feed_limited: usize,
}

#[derive(Serialize)]
struct FamilyReport {
    seed: u64,
    inside: usize,
    outside: usize,
    cycles: u64,
    points: Vec<PointSummary>,
    /// Outside runs refused by cause before 0.5 mm, of all outside runs, by cause.
    refused: BTreeMap<&'static str, [usize; 2]>,
    /// Runs the simulator could not make: member, point and why.
    errors: Vec<String>,
    passed: bool,
    wall_time_s: f64,
}

/// One run, for the CSV: the plant beside its verdict.
#[derive(Serialize)]
struct FamilyRow {
    member: usize,
    outside: &'static str,
    freq_hz: f64,
    duty: f64,
    passed: bool,
    refused_by_cause: bool,
    startup_peak_m: f64,
    worst_mean_position_m: Option<f64>,
    feed_rate_difference: Option<f64>,
    /// The feed the course said it would give, where the drive's range limits it.
    feed_limited_mps: Option<f64>,
    failures: String,
    mass_kg: f64,
    zero_offset_fraction: f64,
    gain_positive: f64,
    gain_negative: f64,
    current_bandwidth_hz: Option<f64>,
    coulomb_friction_n: f64,
    viscous_friction_nspm: f64,
    spring_npm: f64,
    spring_damping_nspm: f64,
    end_stop_m: Option<f64>,
    resolution_m: Option<f64>,
}

impl FamilyRow {
    fn new(run: &FamilyRun, member: &Member) -> Self {
        let plate = &member.plant.plate;
        FamilyRow {
            member: run.member,
            outside: run.outside.map_or("", Cause::name),
            freq_hz: run.point.freq_hz,
            duty: run.point.duty,
            passed: run.passed,
            refused_by_cause: run.refused_by_cause,
            startup_peak_m: run.verdict.startup_peak_m,
            worst_mean_position_m: run.verdict.worst_mean_position_m,
            feed_rate_difference: run.verdict.feed_rate_difference,
            feed_limited_mps: run.feed_limited_mps,
            failures: run.verdict.failures.join("; "),
            mass_kg: plate.mass_kg,
            zero_offset_fraction: plate.zero_offset_fraction,
            gain_positive: plate.gain_positive,
            gain_negative: plate.gain_negative,
            current_bandwidth_hz: plate.current_bandwidth_hz,
            coulomb_friction_n: plate.coulomb_friction_n,
            viscous_friction_nspm: plate.viscous_friction_nspm,
            spring_npm: plate.spring_npm,
            spring_damping_nspm: plate.spring_damping_nspm,
            end_stop_m: plate.end_stop_m,
            resolution_m: member.plant.sensors.encoder.map(|e| e.resolution_m),
        }
    }
}

/// Runs `host-sim family`; false when a plant misses its expectation.
pub fn run(args: &FamilyArgs) -> Result<bool, SimError> {
    args.output.check()?;
    let started = Instant::now();
    let members = family::members(args.seed, args.inside, args.outside);
    let jobs: Vec<(&Member, FamilyPoint)> = members
        .iter()
        .flat_map(|member| POINTS.iter().map(move |point| (member, *point)))
        .collect();
    let bar = progress(jobs.len(), args.output.json);
    let results: Vec<(&Member, FamilyPoint, Result<FamilyRun, SimError>)> = jobs
        .par_iter()
        .map(|&(member, point)| {
            let result = family::run_member(member, point);
            bar.inc(1);
            (member, point, result)
        })
        .collect();
    bar.finish_and_clear();
    let mut errors = Vec::new();
    let mut runs = Vec::new();
    for (member, point, result) in results {
        match result {
            Ok(run) => runs.push((member, run)),
            Err(error) => errors.push(format!(
                "member {} at {} Hz, d = {}: {error}",
                member.index, point.freq_hz, point.duty
            )),
        }
    }
    let points: Vec<PointSummary> = POINTS
        .iter()
        .map(|point| summary(*point, runs.iter().map(|(_, run)| run)))
        .collect();
    let mut refused: BTreeMap<&'static str, [usize; 2]> = BTreeMap::new();
    for (_, run) in &runs {
        if let Some(cause) = run.outside {
            let tally = refused.entry(cause.name()).or_default();
            tally[0] += usize::from(run.refused_by_cause);
            tally[1] += 1;
        }
    }
    let passed = errors.is_empty()
        && points.iter().all(|p| p.passed == p.runs)
        && refused.values().all(|[by_cause, all]| by_cause == all);
    let report = FamilyReport {
        seed: args.seed,
        inside: args.inside,
        outside: args.outside,
        cycles: CYCLES,
        points,
        refused,
        errors,
        passed,
        wall_time_s: started.elapsed().as_secs_f64(),
    };
    let rows: Vec<FamilyRow> = runs
        .iter()
        .map(|(member, run)| FamilyRow::new(run, member))
        .collect();
    emit(
        &args.output,
        &rows,
        |path| plot_family(path, &report, &runs),
        &report,
        || print_report(&report),
    )?;
    Ok(report.passed)
}

/// The figures of `point` over the inside plants' runs among `runs`.
fn summary<'a>(point: FamilyPoint, runs: impl Iterator<Item = &'a FamilyRun>) -> PointSummary {
    let mut summary = PointSummary {
        point,
        runs: 0,
        passed: 0,
        worst_startup_peak_m: 0.0,
        worst_mean_position_m: 0.0,
        worst_feed_error: 0.0,
        missed: BTreeMap::new(),
        feed_limited: 0,
    };
    for run in runs.filter(|run| run.point == point && run.outside.is_none()) {
        let verdict = &run.verdict;
        summary.runs += 1;
        summary.passed += usize::from(run.passed);
        summary.worst_startup_peak_m = summary.worst_startup_peak_m.max(verdict.startup_peak_m);
        if let Some(mean_m) = verdict.worst_mean_position_m {
            summary.worst_mean_position_m = summary.worst_mean_position_m.max(mean_m);
        }
        if let Some(error) = verdict.feed_rate_difference {
            summary.worst_feed_error = summary.worst_feed_error.max(error.abs());
        }
        for name in run.missed() {
            *summary.missed.entry(name).or_default() += 1;
        }
        summary.feed_limited += usize::from(run.feed_limited_mps.is_some());
    }
    summary
}

/// One panel an operating point: every inside plant's worst cycle mean against its start-up
/// peak, those that passed apart from those that failed, beside the two bounds; the runs the
/// loop gave up on have no cycle mean and are counted in the legend.
fn plot_family(
    path: &std::path::Path,
    report: &FamilyReport,
    runs: &[(&Member, FamilyRun)],
) -> Result<(), SimError> {
    let panels: Vec<Panel<'_>> = report
        .points
        .iter()
        .map(|summary| {
            let inside: Vec<&FamilyRun> = runs
                .iter()
                .map(|(_, run)| run)
                .filter(|run| run.point == summary.point && run.outside.is_none())
                .collect();
            let drawn = |passed: bool| -> Vec<(f64, f64)> {
                inside
                    .iter()
                    .filter(|run| run.passed == passed)
                    .filter_map(|run| {
                        let verdict = &run.verdict;
                        verdict
                            .worst_mean_position_m
                            .map(|mean_m| (verdict.startup_peak_m * 1e6, mean_m * 1e6))
                    })
                    .collect()
            };
            let (passed, failed) = (drawn(true), drawn(false));
            let undrawn = inside.len() - passed.len() - failed.len();
            let right_um = failed
                .iter()
                .chain(&passed)
                .map(|(x, _)| *x)
                .fold(STARTUP_PEAK_LIMIT_M * 1e6 * 1.2, f64::max);
            let top_um = failed
                .iter()
                .chain(&passed)
                .map(|(_, y)| *y)
                .fold(MEAN_POSITION_LIMIT_M * 1e6 * 1.2, f64::max);
            let limit_x = STARTUP_PEAK_LIMIT_M * 1e6;
            let limit_y = MEAN_POSITION_LIMIT_M * 1e6;
            Panel {
                y: "worst cycle mean (µm)",
                series: vec![
                    Series {
                        name: format!(
                            "{} Hz, d = {}: held ({})",
                            summary.point.freq_hz,
                            summary.point.duty,
                            passed.len()
                        ),
                        points: passed,
                        mark: Mark::Points,
                        color: 2,
                    },
                    Series {
                        name: format!(
                            "not held ({}; below both bounds: feed, gains or a stop); {undrawn} \
                             gave up",
                            failed.len()
                        ),
                        points: failed,
                        mark: Mark::OpenPoints,
                        color: 1,
                    },
                    Series {
                        name: format!("start-up bound {limit_x:.0} µm"),
                        points: vec![(limit_x, 0.0), (limit_x, top_um)],
                        mark: Mark::DashedLine,
                        color: 0,
                    },
                    Series {
                        name: format!("cycle-mean bound {limit_y:.0} µm"),
                        points: vec![(0.0, limit_y), (right_um, limit_y)],
                        mark: Mark::DashedLine,
                        color: 3,
                    },
                ],
            }
        })
        .collect();
    let title = format!(
        "Closed loop on {} plants of the envelope, seed {}",
        report.inside, report.seed
    );
    plot::stacked(path, &title, "start-up peak |x| (µm)", &panels)
}

fn print_report(report: &FamilyReport) {
    say!(
        "family            seed {}: {} plants inside the envelope, {} outside, {} operating \
         points, {} cycles after each course; {:.1} s",
        report.seed,
        report.inside,
        report.outside,
        POINTS.len(),
        report.cycles,
        report.wall_time_s
    );
    say!("point             passed               worst start-up peak  worst cycle mean  worst feed error");
    for p in &report.points {
        let share = if p.runs > 0 {
            100.0 * p.passed as f64 / p.runs as f64
        } else {
            0.0
        };
        say!(
            "{:<17} {:<20} {:<20} {:<17} {}",
            format!("{} Hz, d = {}", p.point.freq_hz, p.point.duty),
            format!("{}/{} ({share:.1} %)", p.passed, p.runs),
            format!("{:.0} µm", p.worst_startup_peak_m * 1e6),
            format!("{:.1} µm", p.worst_mean_position_m * 1e6),
            format!("{:.2} %", p.worst_feed_error * 1e2),
        );
        let missed: Vec<String> = p
            .missed
            .iter()
            .map(|(name, n)| format!("{name} {n}"))
            .collect();
        if !missed.is_empty() {
            say!("  missed          {}", missed.join(", "));
        }
        if p.feed_limited > 0 {
            say!(
                "  feed limited    {} runs: the drive's range cannot give the feed's compensation, \
                 said before the release",
                p.feed_limited
            );
        }
    }
    for (cause, [by_cause, all]) in &report.refused {
        say!("outside: {cause:<8} {by_cause}/{all} refused by cause before 0.5 mm");
    }
    for error in &report.errors {
        say!("error             {error}");
    }
    say!(
        "family: {}",
        if report.passed { "PASSED" } else { "FAILED" }
    );
}
