//! The paper's figures' data, regenerated through the library and compared with the CSVs the CLI
//! wrote into `tests/expected/` (`cargo xtask bless` writes them; what each is: the README there).
//!
//! Tolerance: the runs are deterministic and the CSV floats round-trip exactly, so on the machine
//! that wrote the files every value matches bit for bit. The 1e-9 relative allowance (with an
//! absolute floor of 1e-15 in SI units, for values that are zero up to rounding) only absorbs
//! last-bit differences of another platform's math library, amplified at most by the steady-state
//! detection (tolerance 1e-12) and by the saturation bisection (2⁻⁴¹ in duty). A change in the
//! physics moves the values by far more. Integers, booleans and event names must match exactly.

use std::path::{Path, PathBuf};

use feeder_shared::model::STANDARD_GRAVITY_MPS2;
use feeder_shared::{Drive, WaveformSpec};
use host_sim::figures;
use host_sim::ideal::simulator::RunOptions;
use host_sim::{Contact, OperatingPoint};
use serde::Serialize;

const REL_TOL: f64 = 1e-9;
const ABS_TOL: f64 = 1e-15;

/// The CLI's defaults: 50 Hz, a 0.1 g part, μ = μ_s = 1, standard gravity, no force.
const FREQ_HZ: f64 = 50.0;
const MASS_KG: f64 = 1e-4;
/// The CLI's sweep: duties strictly inside (0.5, 0.98).
const SWEEP_MAX_DUTY: f64 = 0.98;

fn figure_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("expected")
        .join(name)
}

fn default_contact(mu: f64) -> Contact {
    Contact::new(mu, mu, STANDARD_GRAVITY_MPS2, MASS_KG, 0.0).unwrap()
}

/// `count` values evenly spaced from `low` to `high`, both included, as the CLI spaces them.
fn linspace(low: f64, high: f64, count: usize) -> Vec<f64> {
    (0..count)
        .map(|i| low + i as f64 / (count - 1) as f64 * (high - low))
        .collect()
}

/// Serializes `rows` as the CLI does and compares them field by field with the checked-in file.
fn assert_matches_file<T: Serialize>(name: &str, rows: &[T]) {
    let mut writer = csv::Writer::from_writer(Vec::new());
    for row in rows {
        writer.serialize(row).unwrap();
    }
    let regenerated = writer.into_inner().unwrap();
    let mut fresh = csv::Reader::from_reader(regenerated.as_slice());
    let mut stored = csv::Reader::from_path(figure_path(name))
        .unwrap_or_else(|e| panic!("{name}: {e}; see tests/expected/README.md"));
    assert_eq!(
        fresh.headers().unwrap(),
        stored.headers().unwrap(),
        "{name}: columns"
    );
    let header = stored.headers().unwrap().clone();
    let fresh: Vec<csv::StringRecord> = fresh.records().map(Result::unwrap).collect();
    let stored: Vec<csv::StringRecord> = stored.records().map(Result::unwrap).collect();
    assert_eq!(fresh.len(), stored.len(), "{name}: rows");
    let mut compared = 0;
    for (row, (new, old)) in fresh.iter().zip(&stored).enumerate() {
        for ((column, new), old) in header.iter().zip(new).zip(old) {
            let is_float = old.contains(['.', 'e', 'E']) && old.parse::<f64>().is_ok();
            if is_float {
                let (a, b) = (new.parse::<f64>().unwrap(), old.parse::<f64>().unwrap());
                let allowed = REL_TOL * a.abs().max(b.abs()) + ABS_TOL;
                assert!(
                    (a - b).abs() <= allowed,
                    "{name} row {row} {column}: {new} now, {old} in the file"
                );
            } else {
                assert_eq!(new, old, "{name} row {row} {column}");
            }
            compared += 1;
        }
    }
    assert!(compared > 0, "{name} is empty");
}

#[test]
fn fig9_sweep_matches_its_regression_file() {
    let duties = figures::duty_grid(0.5, SWEEP_MAX_DUTY, 50);
    let points = figures::sweep(
        1.0 / FREQ_HZ,
        &[100.0, 150.0, 200.0],
        &duties,
        &default_contact(1.0),
        None,
        &|| {},
    )
    .unwrap();
    assert_eq!(points.len(), 150);
    assert!(points.iter().all(|point| point.converged));
    assert_matches_file("sweep.csv", &points);
}

#[test]
fn fig10_viscosity_matches_its_regression_file() {
    // The CLI's viscosity defaults: Section IV.C, −15..15 dyn.
    let spec = WaveformSpec::from_frequency(100.0, 0.5484, Drive::Accel { accel_mps2: 100.0 });
    let forces = linspace(-1.5e-4, 1.5e-4, 31);
    let fit = figures::viscosity(spec, &default_contact(0.5), &forces, None).unwrap();
    assert_matches_file("viscosity.csv", &fit.points);
}

#[test]
fn fig7_saturation_matches_its_regression_file() {
    let accels = linspace(10.0, 200.0, 20);
    let points = figures::saturation(
        1.0 / FREQ_HZ,
        &accels,
        &[1.0, 0.5, 0.25],
        &default_contact(1.0),
        &|| {},
    )
    .unwrap();
    assert_matches_file("saturation.csv", &points);
}

#[test]
fn fig8_trace_matches_its_regression_file() {
    let spec = WaveformSpec::from_frequency(FREQ_HZ, 0.7, Drive::Stroke { stroke_m: 0.0025 });
    let point = OperatingPoint::new(spec, default_contact(1.0), None).unwrap();
    let options = RunOptions {
        fixed_cycles: Some(5),
        trace: true,
        ..RunOptions::converge(point.default_criteria())
    };
    let run = point.run(&options);
    assert_matches_file("trace.csv", &run.trace);
}
