//! The general solver: the plate and the part between events in closed form, whatever the slide.
//!
//! Within a regime the state obeys `z' = A·z` ([`super::model`]), solved exactly by the matrix
//! exponential `z(t) = e^{A·t}·z(0)` ([`linear`]). Events are zeros of linear functionals
//! `g(t) = c·z(t)`, each positive while its regime holds.
//! [`Dynamics`] splits the current loop's fast mode off every functional exactly, so that what is
//! left moves only at the slide's slower rates and is sampled on a coarse step; a step on which
//! a functional cannot be shown to stay positive is halved, down to a fine step
//! `h ≤ min(1/(8ρ), 1/‖A‖)` (`ρ` the fastest rate: `2π·f_c`, `√(k/M)`, `(c + b)/M`). There the
//! functional, summed as its Taylor series, is checked for a sign change and for an interior
//! minimum (a sign change of `g′`) that dips to zero. A root can be missed only if `g` had two
//! extrema within one step; its modes (decays at rates ≤ ρ, oscillations of half-period
//! `π/ω ≥ 8π·h`, and polynomials of degree ≤ 2 in the quantities the events test) exclude that.
//! Roots are bracketed and refined to adjacent floats ([`roots`]), and the regime's end state is
//! taken at the root.

use super::dynamics::{Dynamics, DynamicsCache, Functional, Watch, MAX_FUNCTIONALS, TAYLOR_ROWS};
use super::linear::{self, State};
use super::model::{ContactEvent, Part, PlateModel, Slide};
use super::roots;
use super::solver::{Solver, StretchEnd};

/// The general solver: the dynamics of the regimes it meets, and the segment under way.
#[derive(Debug)]
pub struct GeneralSolver {
    model: PlateModel,
    cache: DynamicsCache,
    target_n: f64,
    duration_s: f64,
}

impl GeneralSolver {
    pub fn new(model: &PlateModel) -> Self {
        GeneralSolver {
            model: *model,
            cache: DynamicsCache::default(),
            target_n: 0.0,
            duration_s: 0.0,
        }
    }
}

impl Solver for GeneralSolver {
    fn begin(&mut self, target_n: f64, duration_s: f64, _holds_s: f64) {
        self.target_n = target_n;
        self.duration_s = duration_s;
    }

    fn next_event(
        &mut self,
        slide: Slide,
        part: Part,
        z: &State,
        offset_s: f64,
        peak_m: &mut f64,
    ) -> StretchEnd {
        let dynamics = self.cache.get(&self.model, slide, part, self.target_n);
        let rest_s = (self.duration_s - offset_s).max(0.0);
        let turn = |x: f64| *peak_m = peak_m.max(x.abs());
        first_event(dynamics, z, rest_s, turn)
    }
}

/// The first event of the regime within `duration_s` of the state `z0`, with its time, and
/// the state then (at `duration_s` if no event comes first); the plate's turning points
/// (`v = 0`) before it are passed to `turn` with their position.
///
/// Steps go down the regime's ladder where a functional cannot be shown to stay positive
/// over a step (`stays_positive`) and back up where they can; a functional shown positive
/// up to a time is not checked again before it. On the finest step each functional still in
/// doubt is checked for a zero (`crossing`) on its Taylor series.
fn first_event(
    dynamics: &Dynamics,
    z0: &State,
    duration_s: f64,
    mut turn: impl FnMut(f64),
) -> StretchEnd {
    let count = dynamics.functionals.len();
    let finest = dynamics.levels();
    let mut level = 0;
    // Position in finest steps, so that sample times do not accumulate rounding.
    let mut position = 0_u64;
    let mut lo_z = *z0;
    let mut lo_jets = [Jet::default(); MAX_FUNCTIONALS];
    let mut hi_jets = [Jet::default(); MAX_FUNCTIONALS];
    // Whether `lo_jets[i]` is at `lo_z`; the time up to which functional `i` is positive.
    let mut fresh = [false; MAX_FUNCTIONALS];
    let mut positive_until_s = [f64::NEG_INFINITY; MAX_FUNCTIONALS];
    loop {
        let lo = position as f64 * dynamics.step_s(finest);
        let rest_s = duration_s - lo;
        if rest_s <= 0.0 {
            return (None, lo_z);
        }
        // What is left, in one step if it is shorter than this level's.
        let last = dynamics.step_s(level) >= rest_s;
        let (hi, hi_z) = if last {
            (duration_s, dynamics.advance(rest_s, &lo_z))
        } else {
            (lo + dynamics.step_s(level), dynamics.step(level, &lo_z))
        };
        let mut checked = [false; MAX_FUNCTIONALS];
        let mut unsure = [false; MAX_FUNCTIONALS];
        for i in 0..count {
            if positive_until_s[i] >= hi {
                continue;
            }
            if !fresh[i] {
                lo_jets[i] = Jet::at(dynamics, i, &lo_z, None);
                fresh[i] = true;
            }
            hi_jets[i] = Jet::at(dynamics, i, &hi_z, Some(lo_jets[i].sign));
            checked[i] = true;
            if stays_positive(dynamics, i, lo, &lo_jets[i], hi, &hi_jets[i]) {
                positive_until_s[i] = hi;
            } else {
                unsure[i] = true;
            }
        }
        let fine = level == finest || (last && rest_s <= dynamics.step_s(finest));
        if !fine && unsure.contains(&true) {
            level += 1;
            continue;
        }
        let mut first: Option<(ContactEvent, f64)> = None;
        let mut turned: Option<f64> = None;
        for (i, functional) in dynamics.functionals.iter().enumerate() {
            if !unsure[i] {
                continue;
            }
            let series = TaylorSeries::new(functional, lo_jets[i].sign, &lo_z);
            let (at_lo, at_hi) = (&lo_jets[i].value, &hi_jets[i].value);
            let Some(t) = roots::crossing(
                &|t| series.value(t - lo),
                &|t| series.slope(t - lo),
                lo,
                at_lo[0],
                at_lo[1],
                hi,
                at_hi[0],
                at_hi[1],
            ) else {
                continue;
            };
            match functional.watch {
                Watch::Event(event) => {
                    if first.is_none_or(|(_, best)| t < best) {
                        first = Some((event, t));
                    }
                }
                Watch::Turn => turned = Some(t),
            }
        }
        if let Some(t) = turned {
            if first.is_none_or(|(_, best)| t <= best) {
                turn(dynamics.advance_short(t - lo, &lo_z)[linear::X]);
            }
        }
        if let Some((_, t)) = first {
            return (first, dynamics.advance_short(t - lo, &lo_z));
        }
        if last {
            return (None, hi_z);
        }
        position += 1 << (finest - level);
        while level > 0 && position % (1 << (finest - level + 1)) == 0 {
            level -= 1;
        }
        lo_z = hi_z;
        for i in 0..count {
            fresh[i] = checked[i];
            if checked[i] {
                lo_jets[i] = hi_jets[i].resigned();
            }
        }
    }
}

/// A functional's value and first two derivatives at a state, signed to be positive while its
/// regime holds, and the current loop's part of each.
#[derive(Debug, Clone, Copy, Default)]
struct Jet {
    /// `±1`: the plate's velocity is watched with the sign it has at a step's start.
    sign: f64,
    /// `g, g′, g″`.
    value: [f64; 3],
    /// `(c·r)·φ, −ρ·(c·r)·φ, ρ²·(c·r)·φ`: the current loop's mode in `value`.
    fast: [f64; 3],
}

impl Jet {
    /// The jet of functional `i` of `regime` at `z`, with `sign`, or with the sign that makes a
    /// watched velocity positive (or rising from zero).
    fn at(dynamics: &Dynamics, i: usize, z: &State, sign: Option<f64>) -> Jet {
        let functional = &dynamics.functionals[i];
        let raw = [0, 1, 2].map(|k| linear::dot(&functional.rows[k], z));
        let sign = sign.unwrap_or(match functional.watch {
            Watch::Event(_) => 1.0,
            Watch::Turn if raw[0] != 0.0 => raw[0].signum(),
            Watch::Turn => raw[1].signum(),
        });
        let (phi, rate) = dynamics
            .lag
            .map_or((0.0, 0.0), |lag| (lag.phi_n(z), lag.rate_per_s));
        let fast = sign * functional.fast * phi;
        Jet {
            sign,
            value: raw.map(|x| sign * x),
            fast: [fast, -rate * fast, rate * rate * fast],
        }
    }

    /// The same jet, a watched velocity turned positive (or rising from zero).
    fn resigned(self) -> Jet {
        let flip = self.value[0] < 0.0 || (self.value[0] == 0.0 && self.value[1] < 0.0);
        if flip {
            Jet {
                sign: -self.sign,
                value: self.value.map(|x| -x),
                fast: self.fast.map(|x| -x),
            }
        } else {
            self
        }
    }
}

/// `1/k!` for `k < TAYLOR_ROWS`.
const INVERSE_FACTORIAL: [f64; TAYLOR_ROWS] = {
    let mut out = [1.0; TAYLOR_ROWS];
    let mut k = 1;
    while k < TAYLOR_ROWS {
        out[k] = out[k - 1] / k as f64;
        k += 1;
    }
    out
};

/// A functional's Taylor series about a state: `g(τ) = Σ c_k·τ^k` with `c_k = g^(k)/k!`.
struct TaylorSeries {
    coefficients: [f64; TAYLOR_ROWS],
}

impl TaylorSeries {
    fn new(functional: &Functional, sign: f64, z: &State) -> TaylorSeries {
        let mut coefficients = [0.0; TAYLOR_ROWS];
        for ((c, row), scale) in coefficients
            .iter_mut()
            .zip(&functional.rows)
            .zip(INVERSE_FACTORIAL)
        {
            *c = sign * scale * linear::dot(row, z);
        }
        TaylorSeries { coefficients }
    }

    /// `g(τ)`, to `τ^(TAYLOR_ROWS − 2)`.
    fn value(&self, tau: f64) -> f64 {
        roots::horner_serial(&self.coefficients[..TAYLOR_ROWS - 1], tau)
    }

    /// `g′(τ)`, to the same order.
    fn slope(&self, tau: f64) -> f64 {
        roots::slope_serial(&self.coefficients, tau)
    }
}

/// Whether functional `i` can be shown to stay positive over `[lo, hi]` (a watched velocity:
/// not to change sign) from its jets at both ends. Its slow part `g_s` has at most one extremum
/// in a step; its minimum is at an end, unless `g_s` falls then rises, where, convex at both
/// ends, it lies above both tangents. The current loop's part is monotone, so it is least at an
/// end.
fn stays_positive(
    dynamics: &Dynamics,
    i: usize,
    lo: f64,
    at_lo: &Jet,
    hi: f64,
    at_hi: &Jet,
) -> bool {
    let slow = |jet: &Jet| -> [f64; 3] { [0, 1, 2].map(|k| jet.value[k] - jet.fast[k]) };
    let [a, da, dda] = slow(at_lo);
    let [b, db, ddb] = slow(at_hi);
    let slow_min = if da >= 0.0 && db >= 0.0 {
        a
    } else if da <= 0.0 && db <= 0.0 {
        b
    } else if da > 0.0 {
        a.min(b)
    } else if dda >= 0.0 && ddb >= 0.0 {
        let t = (b - a + da * lo - db * hi) / (da - db);
        a + da * (t - lo)
    } else {
        return false;
    };
    let least = slow_min + at_lo.fast[0].min(at_hi.fast[0]);
    match dynamics.functionals[i].watch {
        Watch::Event(_) => least > 0.0,
        Watch::Turn => least >= 0.0,
    }
}
