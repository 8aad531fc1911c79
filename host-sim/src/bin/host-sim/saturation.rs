//! `host-sim saturation`: saturation duty d_sat,nqs vs a_max for several μ, model and simulation
//! (Fig. 7, Eq. 16).

use std::path::Path;

use clap::Args;
use feeder_shared::model::STANDARD_GRAVITY_MPS2;
use host_sim::figures::{self, SaturationPoint};
use host_sim::{Contact, SimError};

use crate::args::{check_grid, evenly_spaced, CountArg, FrequencyArgs, OutputArgs, MAX_POINTS};
use crate::output::{emit, progress, say};
use crate::plot::{self, Labels, Mark, Series};

/// The flags of `host-sim saturation`.
#[derive(Args)]
pub struct SaturationArgs {
    #[command(flatten)]
    frequency: FrequencyArgs,
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
    #[arg(long, default_value_t = 20, count_in = (2, MAX_POINTS))]
    points: usize,
    #[arg(long, default_value_t = STANDARD_GRAVITY_MPS2, allow_hyphen_values = true)]
    gravity_mps2: f64,
    #[command(flatten)]
    output: OutputArgs,
}

/// Runs `host-sim saturation`.
pub fn run(args: &SaturationArgs) -> Result<(), SimError> {
    args.output.check()?;
    let period_s = args.frequency.period_s()?;
    check_grid(args.mu.len(), args.points, ["--mu", "--points"])?;
    let accels = evenly_spaced(
        args.accel_min_mps2,
        args.accel_max_mps2,
        args.points,
        ["--accel-min-mps2", "--accel-max-mps2"],
    )?;
    // Each curve takes its own μ.
    let contact = Contact::paper_part(1.0, args.gravity_mps2)?;
    let progress = progress(accels.len() * args.mu.len(), args.output.json);
    let points = figures::saturation(period_s, &accels, &args.mu, &contact, &|| progress.inc(1))?;
    progress.finish_and_clear();
    emit(
        &args.output,
        &points,
        |path| plot_saturation(path, args, &points),
        &points,
        || print_table(&points),
    )
}

fn print_table(points: &[SaturationPoint]) {
    say!(
        "{:>6} {:>10} {:>12} {:>12}",
        "μ",
        "a_max",
        "Eq. 16",
        "simulated"
    );
    for point in points {
        say!(
            "{:>6} {:>10.2} {:>12.8} {:>12.8}",
            point.mu,
            point.accel_mps2,
            point.model_duty,
            point.duty
        );
    }
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
