//! The data of the paper's figures, simulated beside the shared analytic models.
//!
//! * [`sweep`]: feed rate vs duty for several `a_max` (Fig. 4, Fig. 9); [`plate_sweep`] the same
//!   on a real plate in open loop.
//! * [`open_loop_drift`]: what each non-ideality of a real plate does to one operating point in
//!   open loop ([`open_loop_cases`]).
//! * [`viscosity`]: steady velocity vs external force and the least-squares `K` (Fig. 10, Eq. 10).
//! * [`saturation`]: `d_sat,nqs` vs `a_max` for several `μ` (Fig. 7, Eq. 16).

use feeder_shared::model;
use feeder_shared::{Drive, WaveformSpec};
use rayon::prelude::*;
use serde::Serialize;

use crate::contact::Contact;
use crate::error::SimError;
use crate::operating_point::OperatingPoint;
use crate::plate::{self, EndStop, PlateParams, PlatePoint, PlateRunOptions};

/// One point of a duty sweep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SweepPoint {
    pub accel_mps2: f64,
    pub duty: f64,
    /// Simulated steady feed rate.
    pub feed_rate_mps: f64,
    /// Non-quasi-static model: Eq. 15 below `d_sat,nqs`, Eq. 18 above (Eq. 10 under a force,
    /// `None` where that linear law does not hold).
    pub model_feed_rate_mps: Option<f64>,
    /// Quasi-static model: Eq. 9 with `v_max` above 5/8.
    pub quasi_static_feed_rate_mps: f64,
    pub stick_fraction: f64,
    pub cycles: u64,
    pub converged: bool,
}

/// `count` duties evenly inside `(low, high)`, both ends excluded.
pub fn duty_grid(low: f64, high: f64, count: usize) -> Vec<f64> {
    (1..=count)
        .map(|i| low + (high - low) * i as f64 / (count + 1) as f64)
        .collect()
}

/// Simulates every (`a_max`, duty) pair to steady state, in parallel. `on_point` is called once
/// per finished point (from worker threads), for progress reporting.
pub fn sweep(
    period_s: f64,
    accels_mps2: &[f64],
    duties: &[f64],
    contact: &Contact,
    clock_hz: Option<u32>,
    on_point: &(dyn Fn() + Sync),
) -> Result<Vec<SweepPoint>, SimError> {
    let points = sweep_grid(period_s, accels_mps2, duties, contact, clock_hz)?;
    Ok(points
        .par_iter()
        .map(|point| {
            let run = point.steady();
            let prediction = point.model();
            on_point();
            SweepPoint {
                accel_mps2: point.waveform.accel_mps2,
                duty: point.waveform.duty,
                feed_rate_mps: run.feed_rate_mps,
                model_feed_rate_mps: prediction.feed_rate_mps,
                quasi_static_feed_rate_mps: prediction.quasi_static_feed_rate_mps,
                stick_fraction: run.stick_fraction,
                cycles: run.cycles,
                converged: run.converged,
            }
        })
        .collect())
}

/// One point of a duty sweep on a real plate under the open-loop command.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlateSweepPoint {
    pub accel_mps2: f64,
    pub duty: f64,
    /// The part's mean velocity over the averaged cycles on the real plate.
    pub feed_rate_mps: f64,
    /// The ideal plate's non-quasi-static model (as in [`SweepPoint`]), for comparison.
    pub model_feed_rate_mps: Option<f64>,
    /// The plate's mean position over the averaged cycles.
    pub mean_position_m: f64,
    /// Largest distance of the plate from the centre over the run.
    pub peak_excursion_m: f64,
    /// Cycles completed: fewer than asked for when an end stop ended the run.
    pub cycles: u64,
    /// When the plate hit an end stop; `None` if it never did.
    pub end_stop_after_s: Option<f64>,
}

/// Runs every (`a_max`, duty) pair on the real plate `plate` from rest for `options`, in
/// parallel; `on_point` as in [`sweep`].
#[allow(clippy::too_many_arguments)]
pub fn plate_sweep(
    period_s: f64,
    accels_mps2: &[f64],
    duties: &[f64],
    contact: &Contact,
    clock_hz: Option<u32>,
    plate: &PlateParams,
    options: &PlateRunOptions,
    on_point: &(dyn Fn() + Sync),
) -> Result<Vec<PlateSweepPoint>, SimError> {
    let points = sweep_grid(period_s, accels_mps2, duties, contact, clock_hz)?;
    points
        .par_iter()
        .map(|point| {
            let run = point.run_plate(plate, options)?;
            on_point();
            Ok(PlateSweepPoint {
                accel_mps2: point.waveform.accel_mps2,
                duty: point.waveform.duty,
                feed_rate_mps: run.feed_rate_mps,
                model_feed_rate_mps: point.model().feed_rate_mps,
                mean_position_m: run.mean_position_m,
                peak_excursion_m: run.peak_excursion_m,
                cycles: run.cycles,
                end_stop_after_s: run.end_stop.map(|stop| stop.time_s),
            })
        })
        .collect()
}

/// The operating points of a sweep, `a_max` by `a_max`, each over every duty.
fn sweep_grid(
    period_s: f64,
    accels_mps2: &[f64],
    duties: &[f64],
    contact: &Contact,
    clock_hz: Option<u32>,
) -> Result<Vec<OperatingPoint>, SimError> {
    if accels_mps2.is_empty() || duties.is_empty() {
        return Err(SimError::BadRange {
            what: "a sweep needs at least one a_max and one duty",
        });
    }
    let mut points = Vec::with_capacity(accels_mps2.len() * duties.len());
    for &accel_mps2 in accels_mps2 {
        for &duty in duties {
            let spec = WaveformSpec {
                period_s,
                duty,
                drive: Drive::Accel { accel_mps2 },
            };
            points.push(OperatingPoint::new(spec, *contact, clock_hz)?);
        }
    }
    Ok(points)
}

/// One point of the force sweep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ViscosityPoint {
    pub force_n: f64,
    /// Simulated steady mean velocity.
    pub velocity_mps: f64,
    /// `v_eq + f/K` where the linear law holds.
    pub model_velocity_mps: Option<f64>,
    pub stick_fraction: f64,
    /// The part sticks during the cycle: outside the linear viscous law, left out of the fit.
    pub sticks: bool,
    pub converged: bool,
}

/// The force sweep and its least-squares fit `f = K·v′ + c`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Viscosity {
    /// Fitted slope `K` over the points where the part slides all cycle.
    pub k_ns_per_m: f64,
    /// Fitted intercept `c = −K·v_eq`.
    pub intercept_n: f64,
    /// Eq. 10: `K = 4μmg/(aT)`.
    pub model_k_ns_per_m: f64,
    /// Eq. 15: the zero-force feed rate `v_eq`.
    pub model_feed_rate_mps: f64,
    pub points: Vec<ViscosityPoint>,
}

/// Steady velocity for each force, in parallel, and the fit over the sliding points.
pub fn viscosity(
    spec: WaveformSpec,
    contact: &Contact,
    forces_n: &[f64],
    clock_hz: Option<u32>,
) -> Result<Viscosity, SimError> {
    let base = OperatingPoint::new(spec, *contact, clock_hz)?;
    let friction = contact.friction();
    let model_k_ns_per_m = model::viscosity_ns_per_m(&base.waveform, &friction, contact.mass_kg)?;
    let mut points_in = Vec::with_capacity(forces_n.len());
    for &force_n in forces_n {
        let contact = Contact::new(
            contact.mu,
            contact.mu_static,
            contact.gravity_mps2,
            contact.mass_kg,
            force_n,
        )?;
        points_in.push(OperatingPoint { contact, ..base });
    }
    let points: Vec<ViscosityPoint> = points_in
        .par_iter()
        .map(|point| {
            let run = point.steady();
            ViscosityPoint {
                force_n: point.contact.force_n,
                velocity_mps: run.feed_rate_mps,
                model_velocity_mps: point.model().feed_rate_mps,
                stick_fraction: run.stick_fraction,
                sticks: run.stick_fraction > 0.0,
                converged: run.converged,
            }
        })
        .collect();
    let sliding: Vec<(f64, f64)> = points
        .iter()
        .filter(|point| !point.sticks && point.converged)
        .map(|point| (point.velocity_mps, point.force_n))
        .collect();
    let (k_ns_per_m, intercept_n) = least_squares(&sliding).ok_or(SimError::BadRange {
        what: "the viscosity fit needs at least two forces at which the part keeps sliding",
    })?;
    Ok(Viscosity {
        k_ns_per_m,
        intercept_n,
        model_k_ns_per_m,
        model_feed_rate_mps: model::feed_rate_sliding_mps(&base.waveform),
        points,
    })
}

/// Least-squares line `y = slope·x + intercept` through `(x, y)` pairs.
pub fn least_squares(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = points.len() as f64;
    if points.len() < 2 {
        return None;
    }
    let mean_x = points.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_y = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mean_x) * (p.0 - mean_x)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mean_x) * (p.1 - mean_y)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some((slope, mean_y - slope * mean_x))
}

/// One point of the saturation curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SaturationPoint {
    pub mu: f64,
    pub accel_mps2: f64,
    /// Eq. 16.
    pub model_duty: f64,
    /// The smallest duty at which the simulated part sticks in steady state (bisection).
    pub duty: f64,
}

/// Bisection steps of [`saturation`] on the duty interval (0.5, 1).
const SATURATION_BISECTIONS: u32 = 40;

/// `d_sat,nqs` vs `a_max` for each `μ`: Eq. 16 beside the simulated onset of sticking. Points with
/// `a_max ≤ μg` (no slip at all) are left out.
pub fn saturation(
    period_s: f64,
    accels_mps2: &[f64],
    mus: &[f64],
    contact: &Contact,
    on_point: &(dyn Fn() + Sync),
) -> Result<Vec<SaturationPoint>, SimError> {
    let mut cases = Vec::new();
    for &mu in mus {
        let contact = Contact::new(
            mu,
            mu,
            contact.gravity_mps2,
            contact.mass_kg,
            contact.force_n,
        )?;
        for &accel_mps2 in accels_mps2 {
            let spec = WaveformSpec {
                period_s,
                duty: model::DUTY_OPT,
                drive: Drive::Accel { accel_mps2 },
            };
            feeder_shared::Waveform::new(spec, &feeder_shared::Limits::NONE)?;
            if accel_mps2 > contact.kinetic_accel_mps2() {
                cases.push((contact, accel_mps2));
            }
        }
    }
    if cases.is_empty() {
        return Err(SimError::BadRange {
            what: "no a_max above μg: the part never slips",
        });
    }
    cases
        .par_iter()
        .map(|&(contact, accel_mps2)| {
            let sticks = |duty: f64| -> Result<bool, SimError> {
                let spec = WaveformSpec {
                    period_s,
                    duty,
                    drive: Drive::Accel { accel_mps2 },
                };
                let run = OperatingPoint::new(spec, contact, None)?.steady();
                Ok(run.stick_fraction > 0.0)
            };
            let (mut low, mut high) = (0.5, 1.0);
            for _ in 0..SATURATION_BISECTIONS {
                let mid = 0.5 * (low + high);
                if sticks(mid)? {
                    high = mid;
                } else {
                    low = mid;
                }
            }
            on_point();
            Ok(SaturationPoint {
                mu: contact.mu,
                accel_mps2,
                model_duty: model::duty_sat_non_quasi_static(accel_mps2, &contact.friction()),
                duty: 0.5 * (low + high),
            })
        })
        .collect()
}

/// Moving mass of the plates of [`open_loop_cases`]: `realistic.toml`'s.
pub const CASE_PLATE_MASS_KG: f64 = 1.5;

/// A plate of [`open_loop_drift`], named for its report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateCase {
    pub name: &'static str,
    pub plate: PlateParams,
}

/// The ideal plate, each non-ideality of `host-sim/plants/realistic.toml` alone (the lag also
/// at 159 Hz) on a [`CASE_PLATE_MASS_KG`] plate without end stops, then `realistic.toml` itself.
pub fn open_loop_cases() -> Result<Vec<PlateCase>, SimError> {
    let ideal = PlateParams {
        mass_kg: CASE_PLATE_MASS_KG,
        full_scale_accel_mps2: 200.0,
        ..PlateParams::default()
    };
    let realistic = PlateParams::from_toml_str(include_str!("../plants/realistic.toml"))?;
    let case = |name, plate| PlateCase { name, plate };
    Ok(vec![
        case("none (ideal)", ideal),
        case(
            "zero offset 0.5 % of 200 m/s²",
            PlateParams {
                zero_offset_fraction: 0.005,
                ..ideal
            },
        ),
        case(
            "gains +2 % / −2 %",
            PlateParams {
                gain_positive: 1.02,
                gain_negative: 0.98,
                ..ideal
            },
        ),
        case(
            "current loop 1 kHz",
            PlateParams {
                current_bandwidth_hz: Some(1000.0),
                ..ideal
            },
        ),
        case(
            "current loop 159 Hz (ODrive's default)",
            PlateParams {
                current_bandwidth_hz: Some(159.0),
                ..ideal
            },
        ),
        case(
            "slide friction 2 N + 5 N·s/m",
            PlateParams {
                coulomb_friction_n: 2.0,
                viscous_friction_nspm: 5.0,
                ..ideal
            },
        ),
        case("realistic.toml", realistic),
    ])
}

/// One plate of [`open_loop_drift`] under the open-loop command.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriftCase {
    pub name: &'static str,
    /// The part's mean velocity over the averaged cycles.
    pub feed_rate_mps: f64,
    /// The plate's mean position over the same cycles.
    pub mean_position_m: f64,
    /// Largest distance of the plate from the centre over the run.
    pub peak_excursion_m: f64,
    /// Cycles completed: fewer than asked for when an end stop ended the run.
    pub cycles: u64,
    /// When the plate hit an end stop; `None` if it never did.
    pub end_stop_after_s: Option<f64>,
    pub end_stop: Option<EndStop>,
    /// The plate and the part through the run, if traced.
    #[serde(skip)]
    pub trace: Vec<PlatePoint>,
}

/// Runs `point`'s open-loop command on every plate of `cases` from rest for `options`, in
/// parallel; with `traced`, also records each run ([`crate::plate::trace`]).
pub fn open_loop_drift(
    point: &OperatingPoint,
    cases: &[PlateCase],
    options: &PlateRunOptions,
    traced: bool,
) -> Result<Vec<DriftCase>, SimError> {
    cases
        .par_iter()
        .map(|case| {
            let (run, trace) = if traced {
                plate::trace(&case.plate, &point.contact, point.segments(), options)?
            } else {
                (point.run_plate(&case.plate, options)?, Vec::new())
            };
            Ok(DriftCase {
                name: case.name,
                feed_rate_mps: run.feed_rate_mps,
                mean_position_m: run.mean_position_m,
                peak_excursion_m: run.peak_excursion_m,
                cycles: run.cycles,
                end_stop_after_s: run.end_stop.map(|stop| stop.time_s),
                end_stop: run.end_stop,
                trace,
            })
        })
        .collect()
}
