//! `host-sim viscosity`: steady velocity vs external force and the least-squares viscosity K
//! (Fig. 10, Eq. 10).

use std::path::Path;

use clap::Args;
use feeder_shared::{Drive, WaveformSpec};
use host_sim::figures::{self, Viscosity, ViscosityPoint};
use host_sim::SimError;

use crate::args::{
    evenly_spaced, CountArg, FrequencyArgs, FrictionArgs, OutputArgs, TimingArgs, MAX_POINTS,
};
use crate::output::{emit, say};
use crate::plot::{self, Labels, Mark, Series};

/// The flags of `host-sim viscosity`; the defaults are the paper's Section IV.C.
#[derive(Args)]
#[command(
    mut_arg("freq_hz", |arg| arg
        .default_value("100")
        .help("The paper's Section IV.C: T = 0.01 s")),
    mut_arg("mu", |arg| arg.default_value("0.5"))
)]
pub struct ViscosityArgs {
    #[command(flatten)]
    frequency: FrequencyArgs,
    /// d ≈ 0.5484, implied by the paper's fitted intercept through Eq. 15.
    #[arg(long, default_value_t = 0.5484, allow_hyphen_values = true)]
    duty: f64,
    #[arg(long, default_value_t = 100.0, allow_hyphen_values = true)]
    accel_mps2: f64,
    #[command(flatten)]
    friction: FrictionArgs,
    /// Smallest force (−15 dyn by default).
    #[arg(long, default_value_t = -1.5e-4, allow_hyphen_values = true)]
    force_min_n: f64,
    /// Largest force (15 dyn by default).
    #[arg(long, default_value_t = 1.5e-4, allow_hyphen_values = true)]
    force_max_n: f64,
    /// Number of forces (2 to 10 000), evenly spaced including both ends.
    #[arg(long, default_value_t = 31, count_in = (2, MAX_POINTS))]
    points: usize,
    #[command(flatten)]
    timing: TimingArgs,
    #[command(flatten)]
    output: OutputArgs,
}

/// Runs `host-sim viscosity`.
pub fn run(args: &ViscosityArgs) -> Result<(), SimError> {
    args.output.check()?;
    let spec = WaveformSpec {
        period_s: args.frequency.period_s()?,
        duty: args.duty,
        drive: Drive::Accel {
            accel_mps2: args.accel_mps2,
        },
    };
    let contact = args.friction.contact(0.0)?;
    let forces = evenly_spaced(
        args.force_min_n,
        args.force_max_n,
        args.points,
        ["--force-min-n", "--force-max-n"],
    )?;
    let fit = figures::viscosity(spec, &contact, &forces, args.timing.clock_hz())?;
    emit(
        &args.output,
        &fit.points,
        |path| plot_viscosity(path, &fit),
        &fit,
        || print_fit(&fit),
    )
}

fn print_fit(fit: &Viscosity) {
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
}

fn plot_viscosity(path: &Path, fit: &Viscosity) -> Result<(), SimError> {
    let labels = Labels {
        title: "External force vs steady velocity",
        x: "velocity v′ (mm/s)",
        y: "f_ext (mN)",
    };
    plot::chart(path, labels, &viscosity_series(fit))
}

/// The sliding and the sticking points (the latter only where there are any) and the fitted line.
fn viscosity_series(fit: &Viscosity) -> Vec<Series> {
    let (sliding, sticking): (Vec<_>, Vec<_>) = fit.points.iter().partition(|p| !p.sticks);
    let to_points = |points: &[&ViscosityPoint]| -> Vec<(f64, f64)> {
        points
            .iter()
            .map(|p| (p.velocity_mps * 1e3, p.force_n * 1e3))
            .collect()
    };
    let velocities = fit.points.iter().map(|p| p.velocity_mps);
    let (low, high) = velocities.fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
    let line = |v: f64| (v * 1e3, (fit.k_ns_per_m * v + fit.intercept_n) * 1e3);
    let mut series = vec![Series {
        name: "simulated, sliding".into(),
        points: to_points(&sliding),
        mark: Mark::Points,
        color: 0,
    }];
    if !sticking.is_empty() {
        series.push(Series {
            name: "simulated, sticks".into(),
            points: to_points(&sticking),
            mark: Mark::Points,
            color: 1,
        });
    }
    series.push(Series {
        name: format!(
            "fit K = {:.4e} N·s/m (Eq. 10: {:.4e})",
            fit.k_ns_per_m, fit.model_k_ns_per_m
        ),
        points: vec![line(low), line(high)],
        mark: Mark::Line,
        color: 2,
    });
    series
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(force_n: f64, sticks: bool) -> ViscosityPoint {
        ViscosityPoint {
            force_n,
            velocity_mps: 0.02 + force_n,
            model_velocity_mps: None,
            stick_fraction: 0.0,
            sticks,
            converged: true,
        }
    }

    /// The legend names the sticking points only where the chart draws some.
    #[test]
    fn the_sticking_points_are_named_only_where_there_are_some() {
        let mut fit = Viscosity {
            k_ns_per_m: 2e-3,
            intercept_n: -5e-5,
            model_k_ns_per_m: 2e-3,
            model_feed_rate_mps: 0.025,
            points: vec![point(-1e-4, false), point(1e-4, false)],
        };
        let names = |fit: &Viscosity| -> Vec<String> {
            viscosity_series(fit)
                .into_iter()
                .map(|series| series.name)
                .collect()
        };
        assert!(!names(&fit).iter().any(|name| name.contains("sticks")));
        fit.points.push(point(3e-4, true));
        assert!(names(&fit).iter().any(|name| name.contains("sticks")));
    }
}
