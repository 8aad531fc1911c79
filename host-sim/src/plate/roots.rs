//! Root finding on the plate's event functions, for both solvers: polynomials summed by
//! Horner's scheme (in `t²` on the even and odd powers apart, or term by term), weighted sums and
//! jets `(p, p′)`; a polynomial's zeros bracketed through its derivatives; refinement inside a
//! bracket by Newton's steps ([`refine`]) or by the Illinois variant of regula falsi
//! ([`illinois`]); and the first crossing of a function known at both ends of a step
//! ([`crossing`]).

/// Coefficients of the longest polynomial handled here.
const MAX_LEN: usize = 24;

/// Zeros at most that [`zeros`] finds on an interval (one of `Q″`, two of `Q′`).
pub const MAX_ZEROS: usize = 3;

/// `n` for `n < MAX_LEN`: the weight of `p_n` in `p′`'s coefficient of `τ^(n−1)`.
const ORDINAL: [f64; MAX_LEN] = {
    let mut out = [0.0; MAX_LEN];
    let mut n = 0;
    while n < MAX_LEN {
        out[n] = n as f64;
        n += 1;
    }
    out
};

/// A few sorted times.
#[derive(Debug, Clone, Copy, Default)]
pub struct Times {
    len: usize,
    at: [f64; MAX_ZEROS + 2],
}

impl Times {
    pub fn push(&mut self, t: f64) {
        if self.len < self.at.len() {
            self.at[self.len] = t;
            self.len += 1;
        }
    }

    pub fn as_slice(&self) -> &[f64] {
        &self.at[..self.len]
    }
}

/// `Σ_n w_n·p_n·tⁿ` over the shorter of `p` and `w`, as [`horner`] sums.
#[inline]
pub fn weighted(p: &[f64], w: &[f64], t: f64) -> f64 {
    let len = p.len().min(w.len());
    let (p, w) = (&p[..len], &w[..len]);
    let t2 = t * t;
    let (mut even, mut odd) = (0.0, 0.0);
    let pairs = p.chunks_exact(2).zip(w.chunks_exact(2));
    if len % 2 == 1 {
        even = p[len - 1] * w[len - 1];
    }
    for (pair, weight) in pairs.rev() {
        odd = odd * t2 + pair[1] * weight[1];
        even = even * t2 + pair[0] * weight[0];
    }
    even + t * odd
}

/// `p(t)` by Horner's scheme in `t²` on the even and the odd powers apart: two chains of half
/// the length, which the processor runs side by side.
#[inline]
pub fn horner(p: &[f64], t: f64) -> f64 {
    let t2 = t * t;
    let (mut even, mut odd) = (0.0, 0.0);
    let pairs = p.chunks_exact(2);
    if let [last] = pairs.remainder() {
        even = *last;
    }
    for pair in pairs.rev() {
        odd = odd * t2 + pair[1];
        even = even * t2 + pair[0];
    }
    even + t * odd
}

/// `p(t)` and `q(t)` for two polynomials of one length, each as [`horner`] sums it.
#[inline]
pub fn horner_pair(p: &[f64], q: &[f64], t: f64) -> (f64, f64) {
    let t2 = t * t;
    let (mut p_even, mut p_odd, mut q_even, mut q_odd) = (0.0, 0.0, 0.0, 0.0);
    let pairs = p.chunks_exact(2).zip(q.chunks_exact(2));
    if let ([p_last], [q_last]) = (p.chunks_exact(2).remainder(), q.chunks_exact(2).remainder()) {
        p_even = *p_last;
        q_even = *q_last;
    }
    for (p_pair, q_pair) in pairs.rev() {
        p_odd = p_odd * t2 + p_pair[1];
        p_even = p_even * t2 + p_pair[0];
        q_odd = q_odd * t2 + q_pair[1];
        q_even = q_even * t2 + q_pair[0];
    }
    (p_even + t * p_odd, q_even + t * q_odd)
}

/// `p(t)` and `p′(t)`.
#[inline]
pub fn jet(p: &[f64], t: f64) -> (f64, f64) {
    (horner(p, t), weighted(&p[1..], &ORDINAL[1..], t))
}

/// `p(t)` by Horner's scheme term by term, from the highest coefficient.
pub fn horner_serial(p: &[f64], t: f64) -> f64 {
    p.iter().rev().fold(0.0, |acc, c| acc * t + c)
}

/// `p′(t)` by Horner's scheme term by term, from the highest coefficient.
pub fn slope_serial(p: &[f64], t: f64) -> f64 {
    p[1..]
        .iter()
        .enumerate()
        .rev()
        .fold(0.0, |acc, (k, c)| acc * t + (k + 1) as f64 * c)
}

/// Steps of [`refine`] end below this fraction of the time: a few units in the last place.
pub const EXACT: f64 = 4.0 * f64::EPSILON;

/// Steps of [`refine`] for a turning point end below this fraction of the time: the plate's
/// position is stationary there, so its error is of the order of the square of the time's.
pub const TURN: f64 = 1e-9;

/// The zero of `f` in `[lo, hi]`, given `f(lo) > 0 ≥ f(hi)` (or the reverse) and a single sign
/// change between: Newton's steps from the secant's point, kept inside the shrinking bracket
/// (bisecting where a step would leave it), until a step is below `relative` of the time, or
/// until two Newton steps in a row shrink so fast that the next, `|s_k|³/|s_{k−1}|²` for
/// quadratic convergence, would be (then the last step is taken unevaluated). `f_df` gives `f`
/// and `f′`.
pub fn refine(
    f_df: impl Fn(f64) -> (f64, f64),
    (mut lo, f_lo): (f64, f64),
    (mut hi, f_hi): (f64, f64),
    relative: f64,
) -> f64 {
    let lo_positive = f_lo > 0.0;
    let mut t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    if !(t > lo && t < hi) {
        t = 0.5 * (lo + hi);
    }
    // The last step if it was Newton's, else 0.
    let mut last_step = 0.0;
    for _ in 0..200 {
        let (f, df) = f_df(t);
        if f == 0.0 {
            return t;
        }
        if (f > 0.0) == lo_positive {
            lo = t;
        } else {
            hi = t;
        }
        let step = f / df;
        let tolerance = relative * t.abs();
        if step.abs() <= tolerance {
            return t;
        }
        let newton = t - step;
        let inside = newton > lo && newton < hi;
        if inside && step.abs().powi(3) <= tolerance * last_step * last_step {
            return newton;
        }
        (t, last_step) = if inside {
            (newton, step.abs())
        } else {
            (0.5 * (lo + hi), 0.0)
        };
        if t <= lo || t >= hi {
            break;
        }
    }
    hi
}

/// The Taylor coefficients of `p′`.
fn derivative(p: &[f64]) -> [f64; MAX_LEN] {
    let mut out = [0.0; MAX_LEN];
    for n in 0..p.len() - 1 {
        out[n] = (n + 1) as f64 * p[n + 1];
    }
    out
}

/// The zeros of `Q` in `[0, length_s]` at which it changes sign, sorted: `Q″` has at most one
/// there (as on a chunk of the free slide, `super::free`), bracketed by its signs at the ends; `Q′` is monotone on each
/// side of it and `Q` on each side of `Q′`'s zeros. The derivatives' zeros only split the level
/// below into monotone pieces, to 10⁻⁹ of the time: a split off by that could hide only a double
/// zero of rounding size.
pub fn zeros(q: &[f64], length_s: f64) -> Times {
    let len = q.len();
    let slope = derivative(q);
    let curvature = derivative(&slope[..len]);
    let mut found = Times::default();
    for (p, tolerance) in [(&curvature[..len], TURN), (&slope[..len], TURN), (q, EXACT)] {
        let mut next = Times::default();
        let mut left = 0.0;
        let mut f_left = p[0];
        for right in found.as_slice().iter().copied().chain([length_s]) {
            let f_right = horner(p, right);
            if (f_left > 0.0) != (f_right > 0.0) {
                next.push(refine(
                    |t| jet(p, t),
                    (left, f_left),
                    (right, f_right),
                    tolerance,
                ));
            }
            left = right;
            f_left = f_right;
        }
        found = next;
    }
    found
}

/// A point of `(lo, hi]` next to a sign change of `f`, given `f(lo) > 0 ≥ f(hi)` (or the
/// reverse): the Illinois variant of regula falsi, falling back to bisection when the bracket
/// does not at least halve, stopped when `lo` and `hi` are adjacent floats. Returns the end of
/// the final bracket with the sign of `f(hi)`.
pub fn illinois(
    f: impl Fn(f64) -> f64,
    mut lo: f64,
    mut f_lo: f64,
    mut hi: f64,
    mut f_hi: f64,
) -> f64 {
    let mut side = 0_i8;
    for _ in 0..200 {
        let width = hi - lo;
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi || f_hi == 0.0 {
            break;
        }
        let secant = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
        let t = if secant > lo && secant < hi {
            secant
        } else {
            mid
        };
        let f_t = f(t);
        if (f_t > 0.0) == (f_lo > 0.0) {
            lo = t;
            f_lo = f_t;
            if side == -1 {
                f_hi *= 0.5;
            }
            side = -1;
        } else {
            hi = t;
            f_hi = f_t;
            if side == 1 {
                f_lo *= 0.5;
            }
            side = 1;
        }
        if hi - lo > 0.5 * width {
            let mid = 0.5 * (lo + hi);
            let f_mid = f(mid);
            if (f_mid > 0.0) == (f_lo > 0.0) {
                lo = mid;
                f_lo = f_mid;
            } else {
                hi = mid;
                f_hi = f_mid;
            }
            side = 0;
        }
    }
    hi
}

/// The first time in `[lo, hi]` at which `g` (value and slope given at both ends) reaches zero
/// from above, if any. A regime entered on its own boundary (`g(lo) = 0`, as a slide that has
/// just stopped or a part that has just met the plate) ends at once only if `g` is negative at
/// `hi` without a positive maximum in between: a slope of rounding size at `lo` is no event.
#[allow(clippy::too_many_arguments)]
pub fn crossing(
    g: &impl Fn(f64) -> f64,
    dg: &impl Fn(f64) -> f64,
    lo: f64,
    g_lo: f64,
    dg_lo: f64,
    hi: f64,
    g_hi: f64,
    dg_hi: f64,
) -> Option<f64> {
    if g_lo < 0.0 {
        return Some(lo);
    }
    // An interior extremum, found only where it matters: a maximum when leaving zero, a
    // minimum that may dip to zero.
    let extremum = || {
        ((dg_lo > 0.0) != (dg_hi > 0.0) && dg_lo != 0.0).then(|| {
            let t = illinois(dg, lo, dg_lo, hi, dg_hi);
            (t, g(t))
        })
    };
    if g_lo > 0.0 {
        if g_hi <= 0.0 {
            return Some(illinois(g, lo, g_lo, hi, g_hi));
        }
        if dg_lo >= 0.0 {
            return None;
        }
        return match extremum() {
            Some((t, g_t)) if g_t <= 0.0 => Some(illinois(g, lo, g_lo, t, g_t)),
            _ => None,
        };
    }
    if g_hi >= 0.0 {
        return None;
    }
    match extremum() {
        Some((t, g_t)) if g_t > 0.0 => Some(illinois(g, t, g_t, hi, g_hi)),
        _ => Some(lo),
    }
}

#[cfg(test)]
mod tests {
    /// `Q = (τ − 0.1)·(τ − 0.5)·(τ − 0.9)` on `[0, 1]`: `Q″ = 6τ − 3` has its one zero at 0.5, `Q′`
    /// two (`0.5 ± √0.0533…`) where `Q` is positive at both ends, and `Q` all three of its zeros.
    #[test]
    fn all_three_zeros_of_q_are_found_through_its_derivatives() {
        let q = [-0.045, 0.59, -1.5, 1.0];
        let found = super::zeros(&q, 1.0);
        let found = found.as_slice();
        assert_eq!(found.len(), 3, "{found:?}");
        for (t, expected) in found.iter().zip([0.1, 0.5, 0.9]) {
            assert!((t - expected).abs() < 1e-14, "{found:?}");
        }
    }
}
