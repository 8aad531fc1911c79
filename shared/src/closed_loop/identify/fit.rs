//! The least-squares fit of the probe's model at one lag, and the search for the lag whose fit
//! leaves the least residual, solved from its normal equations.

use libm::{fabs, sqrt};

use super::lag::lagged_rows;
use super::latched::Latch;
use super::refusal::IdentifyError;
use crate::closed_loop::shape::CommandSegment;

/// Unknowns of the fit: `x₀, v₀, e, g₊, g₋, F_c/M, b/M, k/M`.
pub(super) const UNKNOWNS: usize = 8;

/// Longest current-loop lag searched.
pub(super) const LAG_MAX_S: f64 = 5e-3;

/// Golden-section steps: the lag to `LAG_MAX_S·0.618²⁴ ≈ 5·10⁻⁸ s`, a three-thousandth of a
/// 1 kHz current loop's time constant (0.16 ms).
const LAG_STEPS: usize = 24;

/// Latches a fit takes at most.
pub const MAX_LATCHES: usize = 512;

/// Which drive the fit describes.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Model {
    /// A bare slide: every unknown but the spring (`k/M = 0`).
    Slide,
    /// A slide on a centring spring.
    Sprung,
}

impl Model {
    /// The unknowns it fits, the first of [`UNKNOWNS`].
    fn columns(self) -> usize {
        match self {
            Model::Slide => UNKNOWNS - 1,
            Model::Sprung => UNKNOWNS,
        }
    }
}

/// What the fit takes: the probe's commanded segments, the latches, their friction and spring
/// regressors (which do not depend on the lag), and what is known of the gains beforehand.
#[derive(Clone, Copy)]
pub(super) struct Problem<'a> {
    pub(super) probe: &'a [CommandSegment],
    pub(super) latches: &'a [Latch],
    pub(super) motion: &'a [[f64; 3]; MAX_LATCHES],
    pub(super) gains: Option<GainPrior>,
}

/// The gains' half difference over their mean, `ε = (g₊ − g₋)/(g₊ + g₋)`, as the settle's
/// dither read it, to within `spread`, and the spread of one latch about the fit (m): the fit
/// weighs the one against the other. The probe's few short cycles barely tell the gains'
/// difference from the slide's friction; the dither reads it well.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainPrior {
    pub half_difference: f64,
    pub spread: f64,
    pub latch_spread_m: f64,
}

/// The least-squares fit of `model` for one lag, with its residual sum of squares.
pub(super) fn fit(
    problem: &Problem<'_>,
    lag_s: f64,
    model: Model,
) -> Option<([f64; UNKNOWNS], f64)> {
    let Problem {
        probe,
        latches,
        motion,
        gains,
    } = *problem;
    let columns = model.columns();
    let mut lagged = [[0.0; 3]; MAX_LATCHES];
    lagged_rows(probe, latches, lag_s, |i, r, _| lagged[i] = r);
    let row = |i: usize| -> [f64; UNKNOWNS] {
        let [p, n, e] = lagged[i];
        let [c, x, spring] = motion[i];
        [1.0, latches[i].t_s, e, p, n, c, x, spring]
    };
    // Columns scaled to a largest value of 1.
    let mut scale = [0.0_f64; UNKNOWNS];
    for i in 0..latches.len() {
        for (s, r) in scale.iter_mut().zip(row(i)) {
            *s = s.max(fabs(r));
        }
    }
    let mut inverse = [1.0; UNKNOWNS];
    for (inverse, s) in inverse.iter_mut().zip(scale) {
        if s > 0.0 {
            *inverse = 1.0 / s;
        }
    }
    let mut normal = [[0.0; UNKNOWNS]; UNKNOWNS];
    let mut right = [0.0; UNKNOWNS];
    for (i, latch) in latches.iter().enumerate() {
        let mut r = row(i);
        for (r, inverse) in r.iter_mut().zip(inverse) {
            *r *= inverse;
        }
        r[columns..].fill(0.0);
        for a in 0..columns {
            right[a] += r[a] * latch.position_m;
            for b in a..columns {
                normal[a][b] += r[a] * r[b];
            }
        }
    }
    if let Some(prior) = gains.filter(|p| p.spread > 0.0 && p.half_difference.is_finite()) {
        // `g₊·(1 − ε) − g₋·(1 + ε)` is `2·(ε_true − ε)` about: a measurement of it, 0, with
        // twice the prior's spread, as many latches' worth as the spreads say (in the scaled
        // unknowns).
        let epsilon = prior.half_difference;
        let (a, b) = (inverse[3] * (1.0 - epsilon), -inverse[4] * (1.0 + epsilon));
        let ratio = prior.latch_spread_m / (2.0 * prior.spread);
        let weight = ratio * ratio;
        if weight.is_finite() {
            normal[3][3] += weight * a * a;
            normal[3][4] += weight * a * b;
            normal[4][4] += weight * b * b;
        }
    }
    let upper = normal;
    for (a, row) in normal.iter_mut().enumerate() {
        for (b, entry) in row.iter_mut().enumerate().take(a) {
            *entry = upper[b][a];
        }
    }
    let mut theta = cholesky_solve(normal, right, columns)?;
    for (t, inverse) in theta.iter_mut().zip(inverse) {
        *t *= inverse;
    }
    // Summed latch by latch: the normal equations' `yᵀy − θᵀAᵀy` cancels to noise where the
    // fit is exact.
    let squares = latches
        .iter()
        .enumerate()
        .map(|(i, latch)| {
            let fitted: f64 = row(i).iter().zip(theta).map(|(r, t)| r * t).sum();
            (fitted - latch.position_m) * (fitted - latch.position_m)
        })
        .sum();
    Some((theta, squares))
}

/// The lag whose fit of `model` leaves the least residual (a golden-section search over
/// `[0, LAG_MAX_S]`, and 0 itself), with that fit.
pub(super) fn best_lag(
    problem: &Problem<'_>,
    model: Model,
) -> Result<(f64, ([f64; UNKNOWNS], f64)), IdentifyError> {
    let residual = |lag_s: f64| fit(problem, lag_s, model).map_or(f64::INFINITY, |(_, r)| r);
    let golden = 0.5 * (sqrt(5.0) - 1.0);
    let (mut lo, mut hi) = (0.0, LAG_MAX_S);
    let (mut a, mut b) = (hi - golden * (hi - lo), lo + golden * (hi - lo));
    let (mut fa, mut fb) = (residual(a), residual(b));
    for _ in 0..LAG_STEPS {
        if fa <= fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - golden * (hi - lo);
            fa = residual(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + golden * (hi - lo);
            fb = residual(b);
        }
    }
    // The search closes in on its interval's end without reaching it: a drive without a lag
    // (an ideal one, or a current loop far faster than the latches) is tried at 0 itself.
    let (lag_s, inside) = if fa <= fb { (a, fa) } else { (b, fb) };
    let lag_s = if residual(0.0) <= inside { 0.0 } else { lag_s };
    let fitted = fit(problem, lag_s, model).ok_or(IdentifyError::Singular)?;
    Ok((lag_s, fitted))
}

/// Solves the symmetric positive definite `a·x = b` in its first `n` unknowns (the rest stay
/// 0); `None` if a pivot is not clearly positive (or not a number).
fn cholesky_solve(
    mut a: [[f64; UNKNOWNS]; UNKNOWNS],
    mut b: [f64; UNKNOWNS],
    n: usize,
) -> Option<[f64; UNKNOWNS]> {
    let largest = (0..n).map(|i| a[i][i]).fold(0.0, f64::max);
    let dot = |x: &[f64], y: &[f64]| -> f64 { x.iter().zip(y).map(|(p, q)| p * q).sum() };
    for j in 0..n {
        let d = a[j][j] - dot(&a[j][..j], &a[j][..j]);
        if d.is_nan() || d <= 1e-13 * largest {
            return None;
        }
        let d = sqrt(d);
        a[j][j] = d;
        for i in j + 1..n {
            a[i][j] = (a[i][j] - dot(&a[i][..j], &a[j][..j])) / d;
        }
    }
    for i in 0..n {
        b[i] = (b[i] - dot(&a[i][..i], &b[..i])) / a[i][i];
    }
    for i in (0..n).rev() {
        let later: f64 = (i + 1..n).map(|k| a[k][i] * b[k]).sum();
        b[i] = (b[i] - later) / a[i][i];
    }
    b[n..].fill(0.0);
    Some(b)
}
