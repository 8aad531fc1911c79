//! `host-sim sweep`: feed rate vs duty for one or more a_max, beside the models (Fig. 4, Fig. 9),
//! on the ideal plate or, with `--plant`, on a real one in open loop.

use std::path::Path;

use clap::Args;
use host_sim::figures::{self, PlateSweepPoint, SweepPoint};
use host_sim::plate::PlateParams;
use host_sim::{Contact, SimError};
use serde::Serialize;

use crate::args::{
    check_grid, plate_options, ContactArgs, CountArg, FrequencyArgs, OutputArgs, PlantArgs,
    TimingArgs, MAX_POINTS, PLATE_CYCLES,
};
use crate::output::{emit, progress, say};
use crate::plot::{self, Key, Labels, Mark, Options, Series};

/// Upper end of the swept duties: closer to 1 the first `+a` segment, `T(1 − d)²/(2(d + P/T))`,
/// gets shorter than a tick of a 1 MHz clock at 50 Hz and the tick plan is refused.
const MAX_DUTY: f64 = 0.98;
/// Most cycles of `--cycles`: each point of a real plate runs them all unless it hits an end stop.
const MAX_PLATE_CYCLES: u64 = 100_000;

/// The flags of `host-sim sweep`.
#[derive(Args)]
pub struct SweepArgs {
    #[command(flatten)]
    frequency: FrequencyArgs,
    /// Peak accelerations to sweep, comma-separated (the paper's Fig. 9 by default).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "100,150,200",
        allow_hyphen_values = true
    )]
    accel_mps2: Vec<f64>,
    /// Number of duties, evenly spaced strictly inside (0.5, 0.98); at most 10 000 points in all.
    #[arg(long, default_value_t = 50, count_in = (1, MAX_POINTS))]
    duties: usize,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    timing: TimingArgs,
    /// Cycles each point runs from rest on a plate that is not ideal (default 100, at most
    /// 100 000); the ideal plate runs each point to steady state.
    #[arg(long, count_in = (1, MAX_PLATE_CYCLES))]
    cycles: Option<u64>,
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    output: OutputArgs,
}

/// Runs `host-sim sweep`.
pub fn run(args: &SweepArgs) -> Result<(), SimError> {
    args.output.check()?;
    let period_s = args.frequency.period_s()?;
    check_grid(
        args.accel_mps2.len(),
        args.duties,
        ["--accel-mps2", "--duties"],
    )?;
    let contact = args.contact.contact()?;
    let duties = figures::duty_grid(0.5, MAX_DUTY, args.duties);
    match args.plant.plate()? {
        Some((_, params)) if !params.is_ideal() => {
            run_real_plate(args, period_s, &duties, &contact, &params)
        }
        _ if args.cycles.is_some() => Err(SimError::BadRange {
            what: "--cycles sets how long each point runs on a plate that is not ideal (--plant \
                   FILE); the ideal plate runs each point to steady state",
        }),
        _ => run_ideal_plate(args, period_s, &duties, &contact),
    }
}

/// Each point to steady state on the ideal plate, beside the models.
fn run_ideal_plate(
    args: &SweepArgs,
    period_s: f64,
    duties: &[f64],
    contact: &Contact,
) -> Result<(), SimError> {
    let sweep = |on_point: &(dyn Fn() + Sync)| {
        figures::sweep(
            period_s,
            &args.accel_mps2,
            duties,
            contact,
            args.timing.clock_hz(),
            on_point,
        )
    };
    emit_sweep(args, duties, sweep, plot_sweep, print_table)
}

/// Each point on the real plate `params` from rest, for `--cycles` or until an end stop.
fn run_real_plate(
    args: &SweepArgs,
    period_s: f64,
    duties: &[f64],
    contact: &Contact,
    params: &PlateParams,
) -> Result<(), SimError> {
    let options = plate_options(args.cycles.unwrap_or(PLATE_CYCLES));
    let sweep = |on_point: &(dyn Fn() + Sync)| {
        figures::plate_sweep(
            period_s,
            &args.accel_mps2,
            duties,
            contact,
            args.timing.clock_hz(),
            params,
            &options,
            on_point,
        )
    };
    emit_sweep(args, duties, sweep, plot_plate_sweep, print_plate_table)
}

/// The points `sweep` computes over every a_max and `duties`, a progress bar counting them,
/// written out as every command writes: `plot` draws their chart, `print` their table.
fn emit_sweep<P: Serialize>(
    args: &SweepArgs,
    duties: &[f64],
    sweep: impl FnOnce(&(dyn Fn() + Sync)) -> Result<Vec<P>, SimError>,
    plot: fn(&Path, &SweepArgs, &[P]) -> Result<(), SimError>,
    print: fn(&[P]),
) -> Result<(), SimError> {
    let progress = progress(args.accel_mps2.len() * duties.len(), args.output.json);
    let points = sweep(&|| progress.inc(1))?;
    progress.finish_and_clear();
    emit(
        &args.output,
        &points,
        |path| plot(path, args, &points),
        &points,
        || print(&points),
    )
}

fn print_plate_table(points: &[PlateSweepPoint]) {
    say!(
        "{:>10} {:>7} {:>12} {:>12} {:>12} {:>12} {:>7}",
        "a_max",
        "duty",
        "plate mm/s",
        "nqs mm/s",
        "mean x mm",
        "end stop s",
        "cycles"
    );
    for point in points {
        say!(
            "{:>10.1} {:>7.4} {:>12.5} {:>12} {:>12.5} {:>12} {:>7}",
            point.accel_mps2,
            point.duty,
            point.feed_rate_mps * 1e3,
            model_mm_per_s(point.model_feed_rate_mps),
            point.mean_position_m * 1e3,
            point
                .end_stop_after_s
                .map_or("-".into(), |t| format!("{t:.6}")),
            point.cycles
        );
    }
}

/// The real plate's feed rate vs duty, hollow where the run ended at an end stop, beside the
/// ideal plate's model.
fn plot_plate_sweep(
    path: &Path,
    args: &SweepArgs,
    points: &[PlateSweepPoint],
) -> Result<(), SimError> {
    let mut series = Vec::new();
    let mut kinds = vec![("real plate", Mark::Points)];
    if points.iter().any(|p| p.end_stop_after_s.is_some()) {
        kinds.push(("real plate, ended at an end stop", Mark::OpenPoints));
    }
    kinds.push(("ideal plate (Eq. 15/18)", Mark::DashedLine));
    for (index, &accel) in args.accel_mps2.iter().enumerate() {
        let of_accel: Vec<&PlateSweepPoint> =
            points.iter().filter(|p| p.accel_mps2 == accel).collect();
        let feed = |stopped: bool| -> Vec<(f64, f64)> {
            of_accel
                .iter()
                .filter(|p| p.end_stop_after_s.is_some() == stopped)
                .map(|p| (p.duty, p.feed_rate_mps * 1e3))
                .collect()
        };
        for (name, stopped, mark) in [
            ("real plate", false, Mark::Points),
            ("real plate, ended at an end stop", true, Mark::OpenPoints),
        ] {
            let points = feed(stopped);
            if !points.is_empty() {
                series.push(Series {
                    name: format!("{name}, a = {accel} m/s²"),
                    points,
                    mark,
                    color: index,
                });
            }
        }
        series.push(Series {
            name: format!("ideal plate (Eq. 15/18), a = {accel}"),
            points: of_accel
                .iter()
                .filter_map(|p| p.model_feed_rate_mps.map(|v| (p.duty, v * 1e3)))
                .collect(),
            mark: Mark::DashedLine,
            color: index,
        });
    }
    feed_rate_chart(path, "on a real plate in open loop ", args, &series, &kinds)
}

/// A table's model feed rate in mm/s, `-` where the model has none.
fn model_mm_per_s(feed_rate_mps: Option<f64>) -> String {
    feed_rate_mps.map_or("-".into(), |v| format!("{:.5}", v * 1e3))
}

fn print_table(points: &[SweepPoint]) {
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
    for point in points {
        say!(
            "{:>10.1} {:>7.4} {:>12.5} {:>12} {:>12.5} {:>8.4} {:>7}{}",
            point.accel_mps2,
            point.duty,
            point.feed_rate_mps * 1e3,
            model_mm_per_s(point.model_feed_rate_mps),
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
    let kinds = [
        ("simulated", Mark::Points),
        ("non-quasi-static (Eq. 15/18)", Mark::Line),
        ("quasi-static (Eq. 9)", Mark::DashedLine),
    ];
    feed_rate_chart(path, "", args, &series, &kinds)
}

/// The chart of feed rate (mm/s) against duty, titled with the sweep's frequency and μ and
/// `what` (empty, or ending in a space). Its legend names each a_max by its colour and each
/// kind of series by its mark.
fn feed_rate_chart(
    path: &Path,
    what: &str,
    args: &SweepArgs,
    series: &[Series],
    kinds: &[(&str, Mark)],
) -> Result<(), SimError> {
    let title = format!(
        "Feed rate vs duty {what}at {} Hz, μ = {}",
        args.frequency.freq_hz, args.contact.friction.mu
    );
    plot::chart_with(
        path,
        Labels {
            title: &title,
            x: "duty d",
            y: "feed rate (mm/s)",
        },
        series,
        &Options {
            keys: Some(legend_keys(&args.accel_mps2, kinds)),
            ..Options::default()
        },
    )
}

/// One legend entry for each a_max in its colour, then one for each kind of series in its mark.
fn legend_keys(accels_mps2: &[f64], kinds: &[(&str, Mark)]) -> Vec<Key> {
    let accels = accels_mps2.iter().enumerate().map(|(index, accel)| Key {
        name: format!("a_max = {accel} m/s²"),
        mark: Mark::Line,
        color: Some(index),
    });
    let kinds = kinds.iter().map(|&(name, mark)| Key {
        name: name.to_owned(),
        mark,
        color: None,
    });
    accels.chain(kinds).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every legend entry has a swatch of its own: each a_max a colour, each kind of series a
    /// mark, the dashed quasi-static curve named.
    #[test]
    fn the_legend_names_each_colour_and_each_mark_once() {
        let kinds = [
            ("simulated", Mark::Points),
            ("non-quasi-static (Eq. 15/18)", Mark::Line),
            ("quasi-static (Eq. 9)", Mark::DashedLine),
        ];
        let keys = legend_keys(&[100.0, 150.0, 200.0], &kinds);
        assert_eq!(keys.len(), 6);
        for (index, key) in keys.iter().enumerate() {
            for other in &keys[index + 1..] {
                assert_ne!((key.mark, key.color), (other.mark, other.color), "{keys:?}");
            }
        }
        assert_eq!(keys[0].name, "a_max = 100 m/s²");
        assert!(keys
            .iter()
            .any(|key| key.name == "quasi-static (Eq. 9)" && key.mark == Mark::DashedLine));
    }
}
