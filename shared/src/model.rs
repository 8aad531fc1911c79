//! Analytic models of the part's motion (paper, Section III), with the errata applied.
//!
//! The part is a point mass under Coulomb friction `μmg` (static coefficient equal to the kinetic
//! one). All functions take SI units and a validated [`Waveform`].
//!
//! Errata implemented here (see `shared/README.md`):
//! * Eq. 8 in its removable form, finite at `r = 1/4`.
//! * The true saturated feed rate is Eq. 18, from `d_sat,nqs` (Eq. 16) on, not `v_max` from 5/8.
//! * Eq. 10's sign: `f_ext = +K·(v′ − v_eq)`.
//! * Eq. 17's inequality reversed: the part saturates when `a/(μg)` is *below* the bound.
//! * `a ≤ μg`: the part never slips and does not feed.

use crate::error::{finite, positive, Error, Quantity};
use crate::waveform::{Drive, Limits, Waveform, WaveformSpec};
use libm::sqrt;

/// Quasi-static saturation duty, `d_sat = 5/8` (Section III.A.1).
pub const DUTY_SAT_QUASI_STATIC: f64 = 0.625;
/// Duty giving `v_eq = v_max/2` in the quasi-static model, `d_opt = 2 − √2`.
pub const DUTY_OPT: f64 = 2.0 - core::f64::consts::SQRT_2;
/// Standard gravity, the default for `g`.
pub const STANDARD_GRAVITY_MPS2: f64 = 9.80665;

/// Coulomb friction between plate and part.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Friction {
    pub mu: f64,
    pub gravity_mps2: f64,
}

impl Friction {
    /// The part the firmware is configured for: μ = 0.3, typical of small metal parts on a steel
    /// plate, under standard gravity. The closed loop compensates the feed for it, so the
    /// firmware in the loop carries it.
    pub const CONFIGURED: Friction = Friction {
        mu: 0.3,
        gravity_mps2: STANDARD_GRAVITY_MPS2,
    };

    pub fn new(mu: f64, gravity_mps2: f64) -> Result<Self, Error> {
        Ok(Friction {
            mu: positive(Quantity::FrictionCoefficient, mu)?,
            gravity_mps2: positive(Quantity::GravityMps2, gravity_mps2)?,
        })
    }

    /// `μg`, the part's acceleration while it slides.
    pub fn accel_mps2(&self) -> f64 {
        self.mu * self.gravity_mps2
    }
}

/// Eq. 7: quasi-static `r = v_eq / v_max` for `0.5 ≤ d ≤ 5/8`.
pub fn velocity_ratio_quasi_static(duty: f64) -> f64 {
    let root = sqrt(2.0 * duty - 1.0);
    (2.0 * duty - 1.0) / (2.0 * (1.0 - duty) * (1.0 - duty)) * (duty + root)
}

/// Eq. 8 in removable form (errata 2): the duty giving `v_eq = r·v_max`,
/// `d = (1 + 2√r + 2r) / (2(1 + √r)²)`.
pub fn duty_for_velocity_ratio(ratio: f64) -> f64 {
    let root = sqrt(ratio);
    (1.0 + 2.0 * root + 2.0 * ratio) / (2.0 * (1.0 + root) * (1.0 + root))
}

/// Eq. 9 with its quasi-static saturated branch: `aT(2d − 1)/4` up to `d = 5/8`, `v_max` above.
pub fn feed_rate_quasi_static_mps(waveform: &Waveform) -> f64 {
    if waveform.duty <= DUTY_SAT_QUASI_STATIC {
        feed_rate_sliding_mps(waveform)
    } else {
        waveform.v_max_mps
    }
}

/// Eq. 15 (equal to Eq. 9's linear branch): `aT(2d − 1)/4`, exact while the part slides.
pub fn feed_rate_sliding_mps(waveform: &Waveform) -> f64 {
    waveform.accel_mps2 * waveform.period_s * (2.0 * waveform.duty - 1.0) / 4.0
}

/// Eq. 16: the duty above which the part sticks on the plateau every cycle,
/// `d_sat,nqs = (5a² + μg(μg − 2a)) / (8a²)`.
pub fn duty_sat_non_quasi_static(accel_mps2: f64, friction: &Friction) -> f64 {
    let mu_g = friction.accel_mps2();
    (5.0 * accel_mps2 * accel_mps2 + mu_g * (mu_g - 2.0 * accel_mps2))
        / (8.0 * accel_mps2 * accel_mps2)
}

/// Eq. 17, corrected (errata 5): for `d < 5/8` the part saturates when `a/(μg)` is below
/// `(1 + 2√(2d − 1)) / (5 − 8d)`; at `d ≥ 5/8` it always does.
pub fn saturation_accel_ratio(duty: f64) -> f64 {
    if duty >= DUTY_SAT_QUASI_STATIC {
        f64::INFINITY
    } else {
        (1.0 + 2.0 * sqrt(2.0 * duty - 1.0)) / (5.0 - 8.0 * duty)
    }
}

/// Eq. 18: the saturated steady feed rate, `(aT/2)·((a − μg)/(a + μg))²·(d − √(2d − 1))`.
pub fn feed_rate_saturated_mps(waveform: &Waveform, friction: &Friction) -> f64 {
    let a = waveform.accel_mps2;
    let mu_g = friction.accel_mps2();
    let ratio = (a - mu_g) / (a + mu_g);
    a * waveform.period_s / 2.0 * ratio * ratio * (waveform.duty - sqrt(2.0 * waveform.duty - 1.0))
}

/// How the part moves in steady state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Regime {
    /// `a ≤ μg`: the part follows the plate and does not feed.
    Stuck,
    /// `d ≤ d_sat,nqs`: the part slides all cycle (Eq. 15).
    Sliding,
    /// `d > d_sat,nqs`: the part sticks on the plateau for part of every cycle (Eq. 18).
    Saturated,
}

/// Steady-state motion predicted by the non-quasi-static model.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SteadyState {
    pub regime: Regime,
    /// Mean part velocity over a cycle.
    pub feed_rate_mps: f64,
    /// Time per cycle the part sticks to the plate (`L` of Fig. 8).
    pub stick_s: f64,
    /// `stick_s / T`.
    pub stick_fraction: f64,
}

/// The steady state for zero external force: Eq. 15 below `d_sat,nqs`, Eq. 18 above it.
///
/// In the saturated regime the part leaves the plateau at `t2` with `v_max`, decelerates at `μg`
/// until it meets the rising plate edge `a(t − T)` at `τ = (v_max − μg(T − t2))/(a + μg)`
/// (relative to the next cycle start), then accelerates at `μg` back to `v_max` and sticks until
/// `t2`: `L = t2 − τ − (v_max − aτ)/(μg)`.
pub fn steady_state(waveform: &Waveform, friction: &Friction) -> SteadyState {
    let a = waveform.accel_mps2;
    let mu_g = friction.accel_mps2();
    let period_s = waveform.period_s;
    if a <= mu_g {
        return SteadyState {
            regime: Regime::Stuck,
            feed_rate_mps: 0.0,
            stick_s: period_s,
            stick_fraction: 1.0,
        };
    }
    if waveform.duty <= duty_sat_non_quasi_static(a, friction) {
        return SteadyState {
            regime: Regime::Sliding,
            feed_rate_mps: feed_rate_sliding_mps(waveform),
            stick_s: 0.0,
            stick_fraction: 0.0,
        };
    }
    let v_max = waveform.v_max_mps;
    let meet_s = (v_max - mu_g * (period_s - waveform.t2_s)) / (a + mu_g);
    let stick_s = waveform.t2_s - meet_s - (v_max - a * meet_s) / mu_g;
    SteadyState {
        regime: Regime::Saturated,
        feed_rate_mps: feed_rate_saturated_mps(waveform, friction),
        stick_s,
        stick_fraction: stick_s / period_s,
    }
}

/// Eq. 10: the viscosity constant `K = 4μmg/(aT)` in N·s/m.
pub fn viscosity_ns_per_m(
    waveform: &Waveform,
    friction: &Friction,
    mass_kg: f64,
) -> Result<f64, Error> {
    let mass_kg = positive(Quantity::MassKg, mass_kg)?;
    Ok(4.0 * friction.mu * mass_kg * friction.gravity_mps2
        / (waveform.accel_mps2 * waveform.period_s))
}

/// Steady velocity under a constant external force, `v′ = v_eq + f_ext/K` (Eq. 10 with the
/// corrected sign), exact while the part slides all cycle.
///
/// With `φ = f/m` the part accelerates at `p = μg + φ` below the plate and decelerates at
/// `q = μg − φ` above it; its velocity swings by `Δ = T·p·q/(p + q)` about `v′`. The law holds while
/// `a > μg + |φ|` and the swing stays inside the plate's profile: `v′ + Δ/2 ≤ v_max`,
/// `v′ − Δ/2 ≥ v_min`. Outside that the part sticks and the call is refused.
pub fn feed_rate_under_force_mps(
    waveform: &Waveform,
    friction: &Friction,
    mass_kg: f64,
    force_n: f64,
) -> Result<f64, Error> {
    let force_n = finite(Quantity::ForceN, force_n)?;
    let viscosity = viscosity_ns_per_m(waveform, friction, mass_kg)?;
    let mu_g = friction.accel_mps2();
    if waveform.accel_mps2 <= mu_g {
        return Err(Error::NoSlip {
            accel_mps2: waveform.accel_mps2,
            friction_accel_mps2: mu_g,
        });
    }
    let force_accel = force_n / mass_kg;
    let outside = Error::OutsideViscousRange { force_n };
    if force_accel.abs() >= mu_g || waveform.accel_mps2 <= mu_g + force_accel.abs() {
        return Err(outside);
    }
    let velocity = feed_rate_sliding_mps(waveform) + force_n / viscosity;
    let rising = mu_g + force_accel;
    let falling = mu_g - force_accel;
    let half_swing = waveform.period_s * rising * falling / (rising + falling) / 2.0;
    if velocity + half_swing > waveform.v_max_mps || velocity - half_swing < waveform.v_min_mps {
        return Err(outside);
    }
    Ok(velocity)
}

/// Scan resolution of [`duty_for_feed_rate`] before it bisects.
const INVERSE_SCAN_POINTS: u32 = 2048;
const INVERSE_BISECTIONS: u32 = 80;

/// The inverse model: the smallest duty whose waveform feeds at `target_mps` with the part
/// sliding (Eq. 15, the robust, linear regime), for a fixed stroke or a fixed peak acceleration
/// (`drive`'s value is held; its counterpart follows from Eq. 5) within `limits`.
///
/// Errors: [`Error::FeedRateAboveReach`] with the fastest admissible sliding feed rate, or
/// [`Error::FeedRateBelowReach`] when even the slowest admissible duty is too fast.
pub fn duty_for_feed_rate(
    period_s: f64,
    target_mps: f64,
    drive: Drive,
    friction: &Friction,
    limits: &Limits,
) -> Result<Waveform, Error> {
    let target_mps = positive(Quantity::FeedRateMps, target_mps)?;
    // Reports parameter errors (period, drive, limits) as they are, using a valid mid duty.
    Waveform::new(
        WaveformSpec {
            period_s,
            duty: DUTY_OPT,
            drive,
        },
        &Limits::NONE,
    )?;
    let evaluate = |duty: f64| -> Option<(Waveform, f64)> {
        let waveform = Waveform::new(
            WaveformSpec {
                period_s,
                duty,
                drive,
            },
            limits,
        )
        .ok()?;
        let state = steady_state(&waveform, friction);
        (state.regime == Regime::Sliding).then_some((waveform, state.feed_rate_mps))
    };
    let mut previous: Option<(f64, f64)> = None;
    let mut best_reach: Option<f64> = None;
    for index in 1..INVERSE_SCAN_POINTS {
        let duty = 0.5 + 0.5 * f64::from(index) / f64::from(INVERSE_SCAN_POINTS);
        match evaluate(duty) {
            Some((waveform, feed)) if feed >= target_mps => {
                let Some((low, _)) = previous else {
                    // Admissible from here, but already too fast: find where admissibility begins.
                    let low = 0.5 + 0.5 * f64::from(index - 1) / f64::from(INVERSE_SCAN_POINTS);
                    let first = bisect(low, duty, |d| evaluate(d).is_some());
                    let (slowest, min_mps) = evaluate(first).unwrap_or((waveform, feed));
                    return if min_mps <= target_mps {
                        Ok(slowest)
                    } else {
                        Err(Error::FeedRateBelowReach {
                            target_mps,
                            min_mps,
                        })
                    };
                };
                let crossing = bisect(low, duty, |d| {
                    evaluate(d).is_some_and(|(_, v)| v < target_mps)
                });
                return Ok(evaluate(crossing).map_or(waveform, |(w, _)| w));
            }
            Some((_, feed)) => {
                previous = Some((duty, feed));
                best_reach = Some(best_reach.map_or(feed, |best: f64| best.max(feed)));
            }
            None => {
                if let Some((low, _)) = previous.take() {
                    // Leaving the admissible sliding region: its edge may still reach the target.
                    let edge = bisect(low, duty, |d| evaluate(d).is_some());
                    if let Some((waveform, feed)) = evaluate(edge) {
                        if feed >= target_mps {
                            let crossing = bisect(low, edge, |d| {
                                evaluate(d).is_some_and(|(_, v)| v < target_mps)
                            });
                            return Ok(evaluate(crossing).map_or(waveform, |(w, _)| w));
                        }
                        best_reach = Some(best_reach.map_or(feed, |best: f64| best.max(feed)));
                    }
                }
            }
        }
    }
    Err(Error::FeedRateAboveReach {
        target_mps,
        max_mps: best_reach.unwrap_or(0.0),
    })
}

/// Bisects `[low, high]` where `holds(low)` and not `holds(high)`; returns the last point found
/// where it holds (or `high` if it held nowhere but `low` was never tested true).
fn bisect(mut low: f64, mut high: f64, holds: impl Fn(f64) -> bool) -> f64 {
    if !holds(low) {
        // The admissible side is `high`: search for the first point where it holds instead.
        for _ in 0..INVERSE_BISECTIONS {
            let mid = 0.5 * (low + high);
            if holds(mid) {
                high = mid;
            } else {
                low = mid;
            }
        }
        return high;
    }
    for _ in 0..INVERSE_BISECTIONS {
        let mid = 0.5 * (low + high);
        if holds(mid) {
            low = mid;
        } else {
            high = mid;
        }
    }
    low
}
