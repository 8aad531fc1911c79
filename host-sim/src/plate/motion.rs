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
//! They are sampled every `h ≤ min(1/(8ρ), 1/‖A‖)` (`ρ` the fastest rate: `2π·f_c`, `√(k/M)`,
//! `(c + b)/M`), and every interval is checked for a sign change of `g` and for an interior
//! minimum of `g` (a sign change of `g′ = c·A·z`) that dips to zero. A root can be missed only if
//! `g` had two extrema within one interval; its modes (decays at rates ≤ ρ, oscillations of
//! half-period `π/ω ≥ 8π·h`, and polynomials of degree ≤ 2 in the quantities the events test)
//! exclude that. Sample points follow from `z(t_{i+1}) = e^{A·h}·z(t_i)` ([`Steppers`] keeps
//! `e^{A·h}` of every regime met); inside an interval `z(t) = e^{A·(t − t_i)}·z(t_i)` with
//! `‖A‖·(t − t_i) ≤ 1` is summed on the vector ([`linear::exp_apply_short`]), roots are bracketed
//! and refined to adjacent floats, and the regime's end state is taken at the root.

use crate::plant::Contact;

use super::linear::{self, Matrix, State, F, ONE, P, Q, U, V, X};
use super::params::PlateParams;

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
}

impl Model {
    pub fn new(params: PlateParams, contact: Contact) -> Self {
        let lag_per_s = params
            .current_bandwidth_hz
            .map(|f_c| 2.0 * std::f64::consts::PI * f_c);
        let damping_per_s =
            (params.spring_damping_nspm + params.viscous_friction_nspm) / params.mass_kg;
        let natural_per_s = (params.spring_npm / params.mass_kg).sqrt();
        let fastest_per_s = lag_per_s
            .unwrap_or(0.0)
            .max(damping_per_s)
            .max(natural_per_s);
        Model {
            params,
            contact,
            lag_per_s,
            fastest_per_s,
        }
    }

    /// `A` of the regime.
    pub fn matrix(&self, slide: Slide, part: Part, target_n: f64) -> Matrix {
        let p = &self.params;
        let mut a = linear::zero();
        let coulomb_sign = match slide {
            Slide::Moving(s) => Some(s),
            Slide::Free => Some(0.0),
            Slide::Stuck => None,
        };
        if let Some(s) = coulomb_sign {
            let m = p.mass_kg;
            a[X][V] = 1.0;
            a[V][X] = -p.spring_npm / m;
            a[V][V] = -(p.spring_damping_nspm + p.viscous_friction_nspm) / m;
            a[V][F] = 1.0 / m;
            a[V][ONE] = -p.coulomb_friction_n * s / m;
        }
        if let Some(lag) = self.lag_per_s {
            a[F][F] = -lag;
            a[F][ONE] = lag * target_n;
        }
        match part {
            Part::Sliding(sigma) => {
                a[U][ONE] =
                    -sigma * self.contact.kinetic_accel_mps2() + self.contact.force_accel_mps2();
            }
            Part::Stuck => a[U] = a[V],
        }
        a[P][U] = 1.0;
        a[Q][X] = 1.0;
        a
    }

    /// The event functionals of a regime, each positive while it holds.
    fn events(&self, slide: Slide, part: Part, a: &Matrix) -> Vec<(Event, [f64; linear::N])> {
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
    pub fn settle(&self, z: &mut State, slide: &mut Slide, part: &mut Part, target_n: f64) {
        if *slide == Slide::Stuck {
            let net = z[F] - self.params.spring_npm * z[X];
            if net.abs() > self.params.coulomb_friction_n {
                *slide = Slide::Moving(net.signum());
            }
        }
        if *part == Part::Stuck {
            *part = self.release(z, *slide, target_n);
        }
    }

    /// The contact of a part at the plate's velocity: stuck if `|a_plate − φ| ≤ μ_s·g`, else
    /// sliding behind the plate (`a_plate − φ > 0`) or ahead of it.
    fn release(&self, z: &mut State, slide: Slide, target_n: f64) -> Part {
        let a = self.matrix(slide, Part::Stuck, target_n);
        let need = linear::dot(&a[V], z) - self.contact.force_accel_mps2();
        if need.abs() <= self.contact.static_accel_mps2() {
            z[U] = z[V];
            Part::Stuck
        } else {
            Part::Sliding(-need.signum())
        }
    }

    /// Applies `event` at the state `z` reached exactly at it.
    pub fn apply(
        &self,
        event: Event,
        z: &mut State,
        slide: &mut Slide,
        part: &mut Part,
        target_n: f64,
    ) {
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
                *part = self.release(z, *slide, target_n);
            }
            Event::PartBreaksAway => {
                let a = self.matrix(*slide, Part::Stuck, target_n);
                let need = linear::dot(&a[V], z) - self.contact.force_accel_mps2();
                *part = Part::Sliding(-need.signum());
            }
            Event::EndStop => {}
        }
    }

    /// The sampling step of a regime: `min(1/(8ρ), 1/‖A‖)` (`‖A‖ ≥ 1`, so it is finite).
    fn sampling_step_s(&self, a: &Matrix) -> f64 {
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
    #[allow(clippy::too_many_arguments)]
    pub fn next_event(
        &self,
        steppers: &mut Steppers,
        a: &Matrix,
        z0: &State,
        slide: Slide,
        part: Part,
        duration_s: f64,
        mut turn: impl FnMut(f64),
    ) -> (Option<(Event, f64)>, State) {
        let events = self.events(slide, part, a);
        let slopes: Vec<[f64; linear::N]> = events
            .iter()
            .map(|(_, c)| linear::derivative(c, a))
            .collect();
        let values = |z: &State| -> Vec<(f64, f64)> {
            events
                .iter()
                .zip(&slopes)
                .map(|((_, c), slope)| (linear::dot(c, z), linear::dot(slope, z)))
                .collect()
        };
        let (step_s, stepper) = steppers.get(self, a);
        let mut lo_z = *z0;
        let mut lo_values = values(z0);
        let mut i = 0_u64;
        loop {
            let lo = i as f64 * step_s;
            // Within the interval, from its start: `‖A‖·(t − lo) ≤ 1`.
            let inside = |t: f64| linear::exp_apply_short(a, t - lo, &lo_z);
            let last = (i + 1) as f64 * step_s >= duration_s;
            let (hi, hi_z) = if last {
                (duration_s, inside(duration_s))
            } else {
                ((i + 1) as f64 * step_s, linear::apply(stepper, &lo_z))
            };
            let hi_values = values(&hi_z);
            let mut first: Option<(Event, f64)> = None;
            for (((event, c), slope), (&(g_lo, dg_lo), &(g_hi, dg_hi))) in events
                .iter()
                .zip(&slopes)
                .zip(lo_values.iter().zip(&hi_values))
            {
                let g = |t: f64| linear::dot(c, &inside(t));
                let dg = |t: f64| linear::dot(slope, &inside(t));
                let found = crossing(&g, &dg, lo, g_lo, dg_lo, hi, g_hi, dg_hi);
                if let Some(t) = found {
                    if first.is_none_or(|(_, best)| t < best) {
                        first = Some((*event, t));
                    }
                }
            }
            let until = first.map_or(hi, |(_, t)| t);
            if (lo_z[V] > 0.0) != (hi_z[V] > 0.0) && lo_z[V] != 0.0 {
                let v = |t: f64| inside(t)[V];
                let t = linear::root(v, lo, lo_z[V], hi, hi_z[V]);
                if t <= until {
                    turn(inside(t)[X]);
                }
            }
            if let Some((_, t)) = first {
                return (first, inside(t));
            }
            if last {
                return (None, hi_z);
            }
            lo_z = hi_z;
            lo_values = hi_values;
            i += 1;
        }
    }
}

/// `e^{A·h}` and `h` of the regimes met so far, `h` the regime's sampling step: regimes recur
/// every cycle, so each exponential is computed once.
#[derive(Debug, Default)]
pub struct Steppers {
    entries: Vec<(Matrix, f64, Matrix)>,
}

impl Steppers {
    const CAPACITY: usize = 32;

    fn get(&mut self, model: &Model, a: &Matrix) -> (f64, &Matrix) {
        let index = match self.entries.iter().position(|(key, _, _)| key == a) {
            Some(index) => index,
            None => {
                if self.entries.len() == Self::CAPACITY {
                    self.entries.clear();
                }
                let step_s = model.sampling_step_s(a);
                self.entries.push((*a, step_s, linear::exp(a, step_s)));
                self.entries.len() - 1
            }
        };
        let (_, step_s, stepper) = &self.entries[index];
        (*step_s, stepper)
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
