//! The least-squares fit of the probe's model at one lag, and the search for the lag whose fit
//! leaves the least residual, solved from its normal equations.

use core::cell::Cell;

use libm::{fabs, sqrt};

use super::lag::lagged_rows;
use super::latched::Latch;
use super::refusal::IdentifyError;
use crate::closed_loop::shape::CommandSegment;

/// Unknowns of the fit: `x₀, v₀, e, g₊, g₋, F_c/M, b/M, k/M`.
pub(super) const UNKNOWNS: usize = 8;

/// Longest current-loop lag searched.
pub(super) const LAG_MAX_S: f64 = 5e-3;

/// The lag is searched to within this (5·10⁻⁸ s, a three-thousandth of a 1 kHz current loop's
/// time constant, 0.16 ms) …
const LAG_TOLERANCE_S: f64 = 5e-8;

/// … in at most this many fits: Brent's search needs about a dozen on a probe's residual (a
/// golden-section search alone 27); near the interval's top, where a lag found is refused
/// anyway, it ends here short of the tolerance. This bounds the identification's work
/// ([`FITS_MAX`](super::FITS_MAX)).
pub(super) const LAG_FITS_MAX: usize = 20;

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

/// The unknowns whose regressors the lag shapes: `e, g₊, g₋`; the others' (`x₀, v₀` and the
/// motion's `F_c/M, b/M, k/M`) do not depend on it.
const LAGGED: [usize; 3] = [2, 3, 4];

/// What the fit takes: the probe's commanded segments, the latches, their friction and spring
/// regressors, what is known of the gains beforehand, and the sums over the latches that do not
/// depend on the lag.
pub(super) struct Problem<'a> {
    probe: &'a [CommandSegment],
    latches: &'a [Latch],
    motion: &'a [[f64; 3]; MAX_LATCHES],
    gains: Option<GainPrior>,
    fixed: Sums,
    /// The fits made so far, counted for the identification's work.
    fits: &'a Cell<u32>,
}

/// Sums over the latches of the unscaled regressors: their products (upper triangle), their
/// products with the positions, and each one's largest magnitude.
#[derive(Clone, Copy)]
struct Sums {
    normal: [[f64; UNKNOWNS]; UNKNOWNS],
    right: [f64; UNKNOWNS],
    scale: [f64; UNKNOWNS],
}

impl<'a> Problem<'a> {
    /// The problem of `latches` under `probe`, with the regressors of their motion; each fit
    /// made of it counts one in `fits`.
    pub(super) fn new(
        probe: &'a [CommandSegment],
        latches: &'a [Latch],
        motion: &'a [[f64; 3]; MAX_LATCHES],
        gains: Option<GainPrior>,
        fits: &'a Cell<u32>,
    ) -> Self {
        let mut fixed = Sums {
            normal: [[0.0; UNKNOWNS]; UNKNOWNS],
            right: [0.0; UNKNOWNS],
            scale: [0.0; UNKNOWNS],
        };
        for (i, latch) in latches.iter().enumerate() {
            let r = row(latch, [0.0; 3], motion[i]);
            for a in (0..UNKNOWNS).filter(|a| !LAGGED.contains(a)) {
                fixed.scale[a] = fixed.scale[a].max(fabs(r[a]));
                fixed.right[a] += r[a] * latch.position_m;
                for b in (a..UNKNOWNS).filter(|b| !LAGGED.contains(b)) {
                    fixed.normal[a][b] += r[a] * r[b];
                }
            }
        }
        Problem {
            probe,
            latches,
            motion,
            gains,
            fixed,
            fits,
        }
    }
}

/// A latch's regressors, in the order of the unknowns, with its lagged ones `[P, N, E]` and
/// its motion's `[C, X, S]`.
fn row(latch: &Latch, [p, n, e]: [f64; 3], [c, x, spring]: [f64; 3]) -> [f64; UNKNOWNS] {
    [1.0, latch.t_s, e, p, n, c, x, spring]
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
        fixed,
        fits,
    } = problem;
    fits.set(fits.get() + 1);
    let columns = model.columns();
    let mut lagged = [[0.0; 3]; MAX_LATCHES];
    // The lagged regressors' sums added to the fixed ones: their products with every
    // regressor and with the positions.
    let mut sums = *fixed;
    lagged_rows(probe, latches, lag_s, |i, r, _| {
        lagged[i] = r;
        let latch = &latches[i];
        let r = row(latch, r, motion[i]);
        for a in LAGGED {
            sums.scale[a] = sums.scale[a].max(fabs(r[a]));
            sums.right[a] += r[a] * latch.position_m;
            for b in 0..columns {
                if !LAGGED.contains(&b) || b >= a {
                    let (low, high) = (a.min(b), a.max(b));
                    sums.normal[low][high] += r[a] * r[b];
                }
            }
        }
    });
    // Columns scaled to a largest value of 1.
    let mut inverse = [1.0; UNKNOWNS];
    for (inverse, s) in inverse.iter_mut().zip(sums.scale) {
        if s > 0.0 {
            *inverse = 1.0 / s;
        }
    }
    let mut normal = [[0.0; UNKNOWNS]; UNKNOWNS];
    let mut right = [0.0; UNKNOWNS];
    for a in 0..columns {
        right[a] = sums.right[a] * inverse[a];
        for b in a..columns {
            normal[a][b] = sums.normal[a][b] * inverse[a] * inverse[b];
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
            let fitted: f64 = row(latch, lagged[i], motion[i])
                .iter()
                .zip(theta)
                .map(|(r, t)| r * t)
                .sum();
            (fitted - latch.position_m) * (fitted - latch.position_m)
        })
        .sum();
    Some((theta, squares))
}

/// The lag whose fit of `model` leaves the least residual (Brent's search over
/// `[0, LAG_MAX_S]`, and 0 itself), with that fit.
pub(super) fn best_lag(
    problem: &Problem<'_>,
    model: Model,
) -> Result<(f64, ([f64; UNKNOWNS], f64)), IdentifyError> {
    let mut best: Option<(f64, ([f64; UNKNOWNS], f64))> = None;
    let mut residual = |lag_s: f64| {
        let fitted = fit(problem, lag_s, model);
        let squares = fitted.map_or(f64::INFINITY, |(_, r)| r);
        if let Some(fitted) = fitted.filter(|_| best.is_none_or(|(_, (_, r))| squares < r)) {
            best = Some((lag_s, fitted));
        }
        squares
    };
    // The search closes in on its interval's end without reaching it: a drive without a lag
    // (an ideal one, or a current loop far faster than the latches) is tried at 0 itself, first,
    // so that it stands against any lag that fits no better.
    residual(0.0);
    minimise(&mut residual, 0.0, LAG_MAX_S);
    best.ok_or(IdentifyError::Singular)
}

/// Brent's minimisation of `f` on `[lo, hi]`: a parabola through the three best points so far
/// where it falls inside the bracket and shrinks the step, a golden-section step where it does
/// not; ends once the best point is known to within [`LAG_TOLERANCE_S`], or after
/// [`LAG_FITS_MAX`] evaluations.
fn minimise(f: &mut impl FnMut(f64) -> f64, lo: f64, hi: f64) {
    let golden = 0.5 * (3.0 - sqrt(5.0));
    let tolerance = LAG_TOLERANCE_S;
    let (mut a, mut b) = (lo, hi);
    let mut x = a + golden * (b - a);
    let mut fx = f(x);
    let (mut w, mut fw, mut v, mut fv) = (x, fx, x, fx);
    // The step taken last, and the one before it.
    let (mut step, mut previous) = (0.0_f64, 0.0_f64);
    for _ in 1..LAG_FITS_MAX {
        let middle = 0.5 * (a + b);
        if fabs(x - middle) <= 2.0 * tolerance - 0.5 * (b - a) {
            break;
        }
        let mut parabolic = None;
        if fabs(previous) > tolerance {
            let r = (x - w) * (fx - fv);
            let q = (x - v) * (fx - fw);
            let p = (x - v) * q - (x - w) * r;
            let q = 2.0 * (q - r);
            let (p, q) = if q > 0.0 { (-p, q) } else { (p, -q) };
            if fabs(p) < fabs(0.5 * q * previous) && p > q * (a - x) && p < q * (b - x) {
                parabolic = Some(p / q);
            }
        }
        match parabolic {
            Some(d) => {
                previous = step;
                let u = x + d;
                step = if u - a < 2.0 * tolerance || b - u < 2.0 * tolerance {
                    tolerance.copysign(middle - x)
                } else {
                    d
                };
            }
            None => {
                previous = if x < middle { b - x } else { a - x };
                step = golden * previous;
            }
        }
        let u = x + if fabs(step) >= tolerance {
            step
        } else {
            tolerance.copysign(step)
        };
        let fu = f(u);
        if fu <= fx {
            if u < x {
                b = x;
            } else {
                a = x;
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The search on a smooth, skewed valley with its floor anywhere in the interval, at its
    /// ends included: inside, the floor to within twice the tolerance in fewer than half the
    /// 27 fits a golden-section search takes to the same interval; at the ends, within a
    /// microsecond in at most the search's fits.
    #[test]
    fn the_lag_search_finds_a_valleys_floor_in_few_fits() {
        for floor_s in [
            0.0,
            2e-7,
            1.59e-4,
            8e-4,
            2.3e-3,
            LAG_MAX_S - 1e-7,
            LAG_MAX_S,
        ] {
            let valley = |lag_s: f64| {
                let d = (lag_s - floor_s) / LAG_MAX_S;
                d * d * (1.0 + 0.5 * d) + 1e-3
            };
            let mut fits = 0;
            let mut best = (f64::NAN, f64::INFINITY);
            minimise(
                &mut |lag_s| {
                    fits += 1;
                    let value = valley(lag_s);
                    if value < best.1 {
                        best = (lag_s, value);
                    }
                    value
                },
                0.0,
                LAG_MAX_S,
            );
            let inside = floor_s > 1e-6 && floor_s < LAG_MAX_S - 1e-6;
            let (within_s, most) = match inside {
                true => (2.0 * LAG_TOLERANCE_S, 12),
                false => (1e-6, LAG_FITS_MAX),
            };
            assert!(
                fabs(best.0 - floor_s) <= within_s,
                "floor at {floor_s} s found at {} s",
                best.0
            );
            assert!(fits <= most, "floor at {floor_s} s: {fits} fits");
        }
    }
}
