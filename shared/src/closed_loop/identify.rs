//! Identification at start-up: the drive's ± gains and zero offset from plate positions read
//! during a few low-amplitude probe cycles.
//!
//! The drive's force follows its target through the current loop, a first-order lag `τ`, so
//! from the probe's start the plate moves as
//! `x(t) = x₀ + v₀·t + e·E(t) + g₊·P(t) + g₋·N(t) − (F_c/M)·C(t) − (b/M)·X(t)`:
//! `P`, `N` and `E` the double integrals of the lagged positive part of the command, its negative
//! part and of 1 (the zero offset `e` goes through the lag too, settled before the probe: the
//! drive is on at zero command first), `C` the double integral of the
//! sign of the plate's velocity (slide friction `F_c`) and `X` the integral of its displacement
//! (viscous friction `b`), both taken from the latched positions. For a given `τ` the seven
//! unknowns enter linearly and are fitted by least squares; `τ` is the one that leaves the least
//! residual (Brent's search), the fit at it the result. The sums over the latches that the lag
//! does not change are made once per search.

mod fit;
mod lag;
mod latched;
mod refit;
mod refusal;

pub use fit::{GainPrior, MAX_LATCHES};
pub use latched::Latch;
pub use refusal::{IdentifyError, IdentifyLimits};

use core::cell::Cell;

use libm::{fabs, sqrt};

use super::shape::CommandSegment;
use fit::{best_lag, fit, Model, Problem, LAG_FITS_MAX, LAG_MAX_S, UNKNOWNS};
use latched::{latched_velocity, motion_rows};
use refit::fitted_velocity;

/// What a probe found.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Identified {
    /// Gain on a positive command (1 is ideal).
    pub gain_positive: f64,
    /// Gain on a negative command (1 is ideal).
    pub gain_negative: f64,
    /// Constant acceleration at zero command.
    pub offset_mps2: f64,
    /// The current loop's lag `τ`.
    pub lag_s: f64,
    /// Slide friction as a deceleration `F_c/M`.
    pub coulomb_mps2: f64,
    /// Viscous friction (and a spring's damping) as a rate `b/M`.
    pub viscous_per_s: f64,
    /// A centring spring's stiffness as `k/M`, the square of its natural angular frequency.
    pub spring_per_s2: f64,
    /// Root-mean-square difference between the fitted and the latched positions.
    pub residual_m: f64,
}

impl Identified {
    /// The drive as planned: gains 1, no offset, no lag, no friction.
    pub const NOMINAL: Identified = Identified {
        gain_positive: 1.0,
        gain_negative: 1.0,
        offset_mps2: 0.0,
        lag_s: 0.0,
        coulomb_mps2: 0.0,
        viscous_per_s: 0.0,
        spring_per_s2: 0.0,
        residual_m: 0.0,
    };
}

/// A spring softer than this (`k/M`, 1/s²: 3.2 Hz) is taken for none: over a probe of a few
/// cycles it moves the plate little more than the fit's other unknowns can tell apart (a bare
/// slide's probe at 1 mm reads up to about 190), and the loop holds it as the disturbance it
/// is; searching the lag again for it would double the identification's time.
const SPRING_MIN_PER_S2: f64 = 400.0;

/// A spring is taken where the fit with it leaves less than this share of the residual sum of
/// squares of the fit without it.
const SPRING_SHOWN: f64 = 0.8;

/// Fits the probe's model to `latches` (at most [`MAX_LATCHES`], the first at the probe's start)
/// and checks it against `limits`.
pub fn identify(
    probe: &[CommandSegment],
    latches: &[Latch],
    limits: &IdentifyLimits,
) -> Result<Identified, IdentifyError> {
    identify_given(probe, latches, limits, None)
}

/// The most fits an identification makes: the lag's two searches (a bare slide's, then a
/// sprung plate's), each with its fit at no lag, the spring's test between them, the refit on
/// the fitted motion's friction signs and the bare slide's fit after it, and the fitted
/// motion's velocity, which costs one.
pub const FITS_MAX: u32 = 2 * (LAG_FITS_MAX as u32 + 1) + 4;

/// An identification's outcome and its work: the fits it made, each a pass over the probe's
/// latches. The course holds the plate for it as long as that work takes on the slowest board
/// ([`CourseConfig::identify_hold_s`](super::CourseConfig::identify_hold_s)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Identification {
    pub result: Result<Identified, IdentifyError>,
    pub fits: u32,
}

/// [`identify`] with what the settle's dither read of the gains' difference
/// ([`Settle::gain_half_difference`](super::Settle::gain_half_difference)), where it did: the
/// fit weighs it with the positions, which give the gains' mean.
pub fn identify_given(
    probe: &[CommandSegment],
    latches: &[Latch],
    limits: &IdentifyLimits,
    gains: Option<GainPrior>,
) -> Result<Identified, IdentifyError> {
    identify_counted(probe, latches, limits, gains).result
}

/// [`identify_given`] with the work it took.
pub fn identify_counted(
    probe: &[CommandSegment],
    latches: &[Latch],
    limits: &IdentifyLimits,
    gains: Option<GainPrior>,
) -> Identification {
    let fits = Cell::new(0);
    let result = identify_with_count(probe, latches, limits, gains, &fits);
    Identification {
        result,
        fits: fits.get(),
    }
}

/// [`identify_given`], each fit counted in `fits`.
fn identify_with_count(
    probe: &[CommandSegment],
    latches: &[Latch],
    limits: &IdentifyLimits,
    gains: Option<GainPrior>,
    fits: &Cell<u32>,
) -> Result<Identified, IdentifyError> {
    let valid_probe = probe
        .iter()
        .all(|s| s.duration_s.is_finite() && s.duration_s >= 0.0 && s.accel_mps2.is_finite());
    if !valid_probe
        || !probe.iter().any(|s| s.accel_mps2 > 0.0)
        || !probe.iter().any(|s| s.accel_mps2 < 0.0)
    {
        return Err(IdentifyError::Probe);
    }
    let length_s: f64 = probe.iter().map(|s| s.duration_s).sum();
    let ordered = latches.windows(2).all(|w| w[0].t_s < w[1].t_s);
    // The probe's length is a sum of segment lengths, a latch's time a quotient of ticks: they
    // may differ in the last bits.
    let end_s = length_s * (1.0 + 4.0 * f64::EPSILON);
    let inside = latches
        .iter()
        .all(|l| l.t_s >= 0.0 && l.t_s <= end_s && l.position_m.is_finite());
    if latches.len() < 2 * UNKNOWNS || latches.len() > MAX_LATCHES || !ordered || !inside {
        return Err(IdentifyError::Latches);
    }
    let first_m = latches[0].position_m;
    let excursion_m = latches
        .iter()
        .map(|l| fabs(l.position_m - first_m))
        .fold(0.0, f64::max);
    if excursion_m.is_nan() || excursion_m < limits.min_excursion_m {
        return Err(IdentifyError::NoMotion { excursion_m });
    }
    let mut motion = [[0.0; 3]; MAX_LATCHES];
    motion_rows(
        latches,
        |i| latched_velocity(latches, i),
        |i, r, _| motion[i] = r,
    );
    // The lag of a bare slide first; a spring found at that lag is searched for again with it.
    let (lag_s, mut fitted, model) = {
        let problem = Problem::new(probe, latches, &motion, gains, fits);
        let (lag_s, fitted) = best_lag(&problem, Model::Slide)?;
        let (sprung, sprung_squares) =
            fit(&problem, lag_s, Model::Sprung).ok_or(IdentifyError::Singular)?;
        // A spring is searched for at its own lag only where it explains the positions: the
        // search is as long as the slide's, and a spurious one bends the gains.
        if -sprung[UNKNOWNS - 1] >= SPRING_MIN_PER_S2 && sprung_squares < SPRING_SHOWN * fitted.1 {
            let (lag_s, fitted) = best_lag(&problem, Model::Sprung)?;
            (lag_s, fitted, Model::Sprung)
        } else {
            (lag_s, fitted, Model::Slide)
        }
    };
    // Differences of quantised latches read a slow plate as standing, or as turning, where it
    // does not: the friction's signs are taken again from the fitted motion's velocity, and
    // that fit is kept where it explains the latches better.
    let velocity = fitted_velocity(probe, latches, &fitted.0, lag_s);
    fits.set(fits.get() + 1);
    motion_rows(latches, |i| velocity[i], |i, r, _| motion[i] = r);
    let problem = Problem::new(probe, latches, &motion, gains, fits);
    if let Some(refit) = fit(&problem, lag_s, model) {
        if refit.1 < fitted.1 {
            fitted = refit;
        }
    }
    // A spring the friction's new signs no longer show is none: the slide's fit at that lag.
    if model == Model::Sprung && -fitted.0[UNKNOWNS - 1] < SPRING_MIN_PER_S2 {
        fitted = fit(&problem, lag_s, Model::Slide).ok_or(IdentifyError::Singular)?;
    }
    let (theta, squares) = fitted;
    let [_, _, offset_mps2, gain_positive, gain_negative, friction, viscous, spring] = theta;
    let identified = Identified {
        gain_positive,
        gain_negative,
        offset_mps2,
        lag_s,
        coulomb_mps2: -friction,
        viscous_per_s: -viscous,
        spring_per_s2: 0.0 - spring,
        residual_m: sqrt(squares / latches.len() as f64),
    };
    // A lag at the search's end is no lag found: the positions do not determine the drive.
    if identified.lag_s.is_nan() || identified.lag_s >= 0.99 * LAG_MAX_S {
        return Err(IdentifyError::Singular);
    }
    // A slow current loop is named first: it rounds the probe's levels, which then read as
    // gains off their range.
    if identified.lag_s > limits.lag_max_s {
        return Err(IdentifyError::Lag {
            lag_s: identified.lag_s,
            limit_s: limits.lag_max_s,
        });
    }
    for (positive, gain) in [(true, gain_positive), (false, gain_negative)] {
        if !(limits.gain_min..=limits.gain_max).contains(&gain) {
            return Err(IdentifyError::Gain { positive, gain });
        }
    }
    if offset_mps2.is_nan() || fabs(offset_mps2) > limits.offset_max_mps2 {
        return Err(IdentifyError::Offset {
            offset_mps2,
            limit_mps2: limits.offset_max_mps2,
        });
    }
    if identified.spring_per_s2.is_nan() || identified.spring_per_s2 > limits.spring_max_per_s2 {
        return Err(IdentifyError::Spring {
            spring_per_s2: identified.spring_per_s2,
            limit_per_s2: limits.spring_max_per_s2,
        });
    }
    Ok(identified)
}
