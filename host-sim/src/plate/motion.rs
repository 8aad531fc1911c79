//! The plate's motion and the part riding on it between events, in closed form.
//!
//! Within a regime (fixed slide and part contact states, fixed driver target `F*`) the state
//! `z = (x, v, F, u, p, q, 1)` obeys a linear ODE with constant input, `z' = A·z`, solved exactly
//! by the matrix exponential `z(t) = e^{A·t}·z(0)` ([`linear`]):
//!
//! * drive: `F' = 2π·f_c·(F* − F)` (without a current loop `F = F*` from the segment's start);
//! * plate: `M·v' = F − k·x − (c + b)·v − F_c·sign(v)`, `x' = v`; a stuck slide has `x' = v' = 0`;
//! * part: sliding with `w = u − v` of sign `σ`, `u' = −σ·μg + φ`; stuck, `u' = v'`; `p' = u`;
//! * `q' = x`, for the plate's mean position.
//!
//! Events are zeros of linear functionals `g(t) = c·z(t)`, each positive while its regime holds.
//! [`Regime`] splits the current loop's fast mode off every functional exactly, so that what is
//! left moves only at the slide's slower rates and is sampled on a coarse step; a step on which
//! a functional cannot be shown to stay positive is halved, down to a fine step
//! `h ≤ min(1/(8ρ), 1/‖A‖)` (`ρ` the fastest rate: `2π·f_c`, `√(k/M)`, `(c + b)/M`). There the
//! functional, summed as its Taylor series, is checked for a sign change and for an interior
//! minimum (a sign change of `g′`) that dips to zero. A root can be missed only if `g` had two
//! extrema within one step; its modes (decays at rates ≤ ρ, oscillations of half-period
//! `π/ω ≥ 8π·h`, and polynomials of degree ≤ 2 in the quantities the events test) exclude that.
//! Roots are bracketed and refined to adjacent floats, and the regime's end state is taken at
//! the root.

use crate::contact::Contact;

use super::linear::{self, Matrix, State, F, ONE, P, Q, U, V, X};
use super::params::PlateParams;
use super::regime::{Functional, Regime, Watch, MAX_FUNCTIONALS, TAYLOR_ROWS};

/// The slide's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Slide {
    /// No Coulomb friction: the slide never sticks.
    Free,
    /// Moving with velocity of this sign (±1).
    Moving(f64),
    Stuck,
}

/// The part's contact with the plate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Part {
    /// Sliding with `w = u − v` of this sign (±1).
    Sliding(f64),
    Stuck,
}

/// What ends a stretch of a regime.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    SlideStops,
    SlideBreaksAway,
    PartMeetsPlate,
    PartBreaksAway,
    EndStop,
}

/// The plate and part model with the parameters folded in.
#[derive(Debug, Clone, Copy)]
pub struct Model {
    pub params: PlateParams,
    pub contact: Contact,
    /// `2π·f_c`, if the current loop lags.
    pub lag_per_s: Option<f64>,
    /// Fastest rate of the plate's dynamics (0 for the ideal plate).
    pub fastest_per_s: f64,
    /// Fastest rate of the slide's own modes, the current loop left out: `√(k/M)`, `(c + b)/M`.
    pub slow_per_s: f64,
}

impl Model {
    pub fn new(params: PlateParams, contact: Contact) -> Self {
        let lag_per_s = params
            .current_bandwidth_hz
            .map(|f_c| 2.0 * std::f64::consts::PI * f_c);
        let damping_per_s =
            (params.spring_damping_nspm + params.viscous_friction_nspm) / params.mass_kg;
        let natural_per_s = (params.spring_npm / params.mass_kg).sqrt();
        let slow_per_s = damping_per_s.max(natural_per_s);
        let fastest_per_s = lag_per_s.unwrap_or(0.0).max(slow_per_s);
        Model {
            params,
            contact,
            lag_per_s,
            fastest_per_s,
            slow_per_s,
        }
    }

    /// The plate's acceleration as a functional of the state: `A`'s row for `v`.
    pub(super) fn plate_accel_row(&self, slide: Slide) -> [f64; linear::N] {
        let p = &self.params;
        let mut row = [0.0; linear::N];
        let coulomb_sign = match slide {
            Slide::Moving(s) => s,
            Slide::Free => 0.0,
            Slide::Stuck => return row,
        };
        let m = p.mass_kg;
        row[X] = -p.spring_npm / m;
        row[V] = -(p.spring_damping_nspm + p.viscous_friction_nspm) / m;
        row[F] = 1.0 / m;
        row[ONE] = -p.coulomb_friction_n * coulomb_sign / m;
        row
    }

    /// The plate's acceleration at the state `z`.
    pub(super) fn plate_accel_mps2(&self, slide: Slide, z: &State) -> f64 {
        linear::dot(&self.plate_accel_row(slide), z)
    }

    /// `u′` of a part sliding with `w = u − v` of sign `σ`.
    pub(super) fn sliding_part_accel_mps2(&self, sigma: f64) -> f64 {
        -sigma * self.contact.kinetic_accel_mps2() + self.contact.force_accel_mps2()
    }

    /// `A` of the regime.
    pub fn matrix(&self, slide: Slide, part: Part, target_n: f64) -> Matrix {
        let mut a = linear::zero();
        if slide != Slide::Stuck {
            a[X][V] = 1.0;
        }
        a[V] = self.plate_accel_row(slide);
        if let Some(lag) = self.lag_per_s {
            a[F][F] = -lag;
            a[F][ONE] = lag * target_n;
        }
        match part {
            Part::Sliding(sigma) => a[U][ONE] = self.sliding_part_accel_mps2(sigma),
            Part::Stuck => a[U] = a[V],
        }
        a[P][U] = 1.0;
        a[Q][X] = 1.0;
        a
    }

    /// The event functionals of a regime, each positive while it holds.
    pub(super) fn events(
        &self,
        slide: Slide,
        part: Part,
        a: &Matrix,
    ) -> Vec<(Event, [f64; linear::N])> {
        let mut out = Vec::with_capacity(6);
        let mut c = [0.0; linear::N];
        match slide {
            Slide::Free => {}
            Slide::Moving(s) => {
                c[V] = s;
                out.push((Event::SlideStops, c));
            }
            Slide::Stuck => {
                // F_c ∓ (F − k·x) ≥ 0.
                for sign in [1.0, -1.0] {
                    let mut c = [0.0; linear::N];
                    c[ONE] = self.params.coulomb_friction_n;
                    c[F] = -sign;
                    c[X] = sign * self.params.spring_npm;
                    out.push((Event::SlideBreaksAway, c));
                }
            }
        }
        match part {
            Part::Sliding(sigma) => {
                let mut c = [0.0; linear::N];
                c[U] = sigma;
                c[V] = -sigma;
                out.push((Event::PartMeetsPlate, c));
            }
            Part::Stuck => {
                // μ_s·g ∓ (a_plate − φ) ≥ 0, with a_plate = A[V]·z.
                let hold = self.contact.static_accel_mps2();
                let phi = self.contact.force_accel_mps2();
                for sign in [1.0, -1.0] {
                    let mut c = a[V].map(|x| -sign * x);
                    c[ONE] += hold + sign * phi;
                    out.push((Event::PartBreaksAway, c));
                }
            }
        }
        if let Some(x_lim) = self.params.end_stop_m {
            for sign in [1.0, -1.0] {
                let mut c = [0.0; linear::N];
                c[ONE] = x_lim;
                c[X] = -sign;
                out.push((Event::EndStop, c));
            }
        }
        out
    }

    /// The consistent contact states at the start of a regime: a stuck slide breaks away when
    /// `|F − k·x| > F_c`, a stuck part when `|a_plate − φ| > μ_s·g` (see `release`).
    pub fn settle(&self, z: &mut State, slide: &mut Slide, part: &mut Part) {
        if *slide == Slide::Stuck {
            let net = z[F] - self.params.spring_npm * z[X];
            if net.abs() > self.params.coulomb_friction_n {
                *slide = Slide::Moving(net.signum());
            }
        }
        if *part == Part::Stuck {
            *part = self.release(z, *slide);
        }
    }

    /// The contact of a part at the plate's velocity: stuck if `|a_plate − φ| ≤ μ_s·g`, else
    /// sliding behind the plate (`a_plate − φ > 0`) or ahead of it.
    fn release(&self, z: &mut State, slide: Slide) -> Part {
        let need = self.plate_accel_mps2(slide, z) - self.contact.force_accel_mps2();
        if need.abs() <= self.contact.static_accel_mps2() {
            z[U] = z[V];
            Part::Stuck
        } else {
            Part::Sliding(-need.signum())
        }
    }

    /// Applies `event` at the state `z` reached exactly at it.
    pub fn apply(&self, event: Event, z: &mut State, slide: &mut Slide, part: &mut Part) {
        match event {
            Event::SlideStops => {
                z[V] = 0.0;
                let net = z[F] - self.params.spring_npm * z[X];
                *slide = if net.abs() <= self.params.coulomb_friction_n {
                    Slide::Stuck
                } else {
                    Slide::Moving(net.signum())
                };
                if *part == Part::Stuck {
                    z[U] = 0.0;
                }
            }
            Event::SlideBreaksAway => {
                let net = z[F] - self.params.spring_npm * z[X];
                *slide = Slide::Moving(net.signum());
            }
            Event::PartMeetsPlate => {
                z[U] = z[V];
                *part = self.release(z, *slide);
            }
            Event::PartBreaksAway => {
                let need = self.plate_accel_mps2(*slide, z) - self.contact.force_accel_mps2();
                *part = Part::Sliding(-need.signum());
            }
            Event::EndStop => {}
        }
    }

    /// The fine sampling step of a regime: `min(1/(8ρ), 1/‖A‖)` (`‖A‖ ≥ 1`, so it is finite).
    pub(super) fn fine_step_s(&self, a: &Matrix) -> f64 {
        let step_s = 1.0 / linear::norm(a);
        if self.fastest_per_s > 0.0 {
            step_s.min(0.125 / self.fastest_per_s)
        } else {
            step_s
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
    pub fn next_event(
        &self,
        regime: &Regime,
        z0: &State,
        duration_s: f64,
        mut turn: impl FnMut(f64),
    ) -> (Option<(Event, f64)>, State) {
        let count = regime.functionals.len();
        let finest = regime.levels();
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
            let lo = position as f64 * regime.step_s(finest);
            let rest_s = duration_s - lo;
            if rest_s <= 0.0 {
                return (None, lo_z);
            }
            // What is left, in one step if it is shorter than this level's.
            let last = regime.step_s(level) >= rest_s;
            let (hi, hi_z) = if last {
                (duration_s, regime.advance(rest_s, &lo_z))
            } else {
                (lo + regime.step_s(level), regime.step(level, &lo_z))
            };
            let mut checked = [false; MAX_FUNCTIONALS];
            let mut unsure = [false; MAX_FUNCTIONALS];
            for i in 0..count {
                if positive_until_s[i] >= hi {
                    continue;
                }
                if !fresh[i] {
                    lo_jets[i] = Jet::at(regime, i, &lo_z, None);
                    fresh[i] = true;
                }
                hi_jets[i] = Jet::at(regime, i, &hi_z, Some(lo_jets[i].sign));
                checked[i] = true;
                if stays_positive(regime, i, lo, &lo_jets[i], hi, &hi_jets[i]) {
                    positive_until_s[i] = hi;
                } else {
                    unsure[i] = true;
                }
            }
            let fine = level == finest || (last && rest_s <= regime.step_s(finest));
            if !fine && unsure.contains(&true) {
                level += 1;
                continue;
            }
            let mut first: Option<(Event, f64)> = None;
            let mut turned: Option<f64> = None;
            for (i, functional) in regime.functionals.iter().enumerate() {
                if !unsure[i] {
                    continue;
                }
                let series = Series::new(functional, lo_jets[i].sign, &lo_z);
                let (at_lo, at_hi) = (&lo_jets[i].value, &hi_jets[i].value);
                let Some(t) = crossing(
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
                    turn(regime.advance_short(t - lo, &lo_z)[linear::X]);
                }
            }
            if let Some((_, t)) = first {
                return (first, regime.advance_short(t - lo, &lo_z));
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
    fn at(regime: &Regime, i: usize, z: &State, sign: Option<f64>) -> Jet {
        let functional = &regime.functionals[i];
        let raw = [0, 1, 2].map(|k| linear::dot(&functional.rows[k], z));
        let sign = sign.unwrap_or(match functional.watch {
            Watch::Event(_) => 1.0,
            Watch::Turn if raw[0] != 0.0 => raw[0].signum(),
            Watch::Turn => raw[1].signum(),
        });
        let (phi, rate) = regime
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
struct Series {
    coefficients: [f64; TAYLOR_ROWS],
}

impl Series {
    fn new(functional: &Functional, sign: f64, z: &State) -> Series {
        let mut coefficients = [0.0; TAYLOR_ROWS];
        for ((c, row), scale) in coefficients
            .iter_mut()
            .zip(&functional.rows)
            .zip(INVERSE_FACTORIAL)
        {
            *c = sign * scale * linear::dot(row, z);
        }
        Series { coefficients }
    }

    /// `g(τ)`, to `τ^(TAYLOR_ROWS − 2)`.
    fn value(&self, tau: f64) -> f64 {
        self.coefficients[..TAYLOR_ROWS - 1]
            .iter()
            .rev()
            .fold(0.0, |acc, c| acc * tau + c)
    }

    /// `g′(τ)`, to the same order.
    fn slope(&self, tau: f64) -> f64 {
        self.coefficients[1..]
            .iter()
            .enumerate()
            .rev()
            .fold(0.0, |acc, (k, c)| acc * tau + (k + 1) as f64 * c)
    }
}

/// Whether functional `i` can be shown to stay positive over `[lo, hi]` (a watched velocity:
/// not to change sign) from its jets at both ends. Its slow part `g_s` has at most one extremum
/// in a step; its minimum is at an end, unless `g_s` falls then rises, where, convex at both
/// ends, it lies above both tangents. The current loop's part is monotone, so it is least at an
/// end.
fn stays_positive(regime: &Regime, i: usize, lo: f64, at_lo: &Jet, hi: f64, at_hi: &Jet) -> bool {
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
    match regime.functionals[i].watch {
        Watch::Event(_) => least > 0.0,
        Watch::Turn => least >= 0.0,
    }
}

/// The first time in `[lo, hi]` at which `g` (value and slope given at both ends) reaches zero
/// from above, if any. A regime entered on its own boundary (`g(lo) = 0`, as a slide that has
/// just stopped or a part that has just met the plate) ends at once only if `g` is negative at
/// `hi` without a positive maximum in between: a slope of rounding size at `lo` is no event.
#[allow(clippy::too_many_arguments)]
fn crossing(
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
            let t = linear::root(dg, lo, dg_lo, hi, dg_hi);
            (t, g(t))
        })
    };
    if g_lo > 0.0 {
        if g_hi <= 0.0 {
            return Some(linear::root(g, lo, g_lo, hi, g_hi));
        }
        if dg_lo >= 0.0 {
            return None;
        }
        return match extremum() {
            Some((t, g_t)) if g_t <= 0.0 => Some(linear::root(g, lo, g_lo, t, g_t)),
            _ => None,
        };
    }
    if g_hi >= 0.0 {
        return None;
    }
    match extremum() {
        Some((t, g_t)) if g_t > 0.0 => Some(linear::root(g, t, g_t, hi, g_hi)),
        _ => Some(lo),
    }
}
