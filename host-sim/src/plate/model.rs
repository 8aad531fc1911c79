//! The plate and the part riding on it as one linear system per contact state.
//!
//! Within a regime (fixed slide and part contact states, fixed driver target `F*`) the state
//! `z = (x, v, F, u, p, q, 1)` obeys a linear ODE with constant input, `z' = A·z` ([`linear`]):
//!
//! * drive: `F' = 2π·f_c·(F* − F)` (without a current loop `F = F*` from the segment's start);
//! * plate: `M·v' = F − k·x − (c + b)·v − F_c·sign(v)`, `x' = v`; a stuck slide has `x' = v' = 0`;
//! * part: sliding with `w = u − v` of sign `σ`, `u' = −σ·μg + φ`; stuck, `u' = v'`; `p' = u`;
//! * `q' = x`, for the plate's mean position.
//!
//! Events are zeros of linear functionals `g(t) = c·z(t)`, each positive while its regime holds;
//! [`PlateModel`] applies them and settles the contacts at a regime's start.

use crate::contact::Contact;

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
pub enum ContactEvent {
    SlideStops,
    SlideBreaksAway,
    PartMeetsPlate,
    PartBreaksAway,
    EndStop,
}

/// The plate and part model with the parameters folded in.
#[derive(Debug, Clone, Copy)]
pub struct PlateModel {
    pub params: PlateParams,
    pub contact: Contact,
    /// `2π·f_c`, if the current loop lags.
    pub lag_per_s: Option<f64>,
    /// Fastest rate of the plate's dynamics (0 for the ideal plate).
    pub fastest_per_s: f64,
    /// Fastest rate of the slide's own modes, the current loop left out: `√(k/M)`, `(c + b)/M`.
    pub slow_per_s: f64,
}

impl PlateModel {
    pub fn new(params: PlateParams, contact: Contact) -> Self {
        let lag_per_s = params
            .current_bandwidth_hz
            .map(|f_c| 2.0 * std::f64::consts::PI * f_c);
        let damping_per_s =
            (params.spring_damping_nspm + params.viscous_friction_nspm) / params.mass_kg;
        let natural_per_s = (params.spring_npm / params.mass_kg).sqrt();
        let slow_per_s = damping_per_s.max(natural_per_s);
        let fastest_per_s = lag_per_s.unwrap_or(0.0).max(slow_per_s);
        PlateModel {
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
    ) -> Vec<(ContactEvent, [f64; linear::N])> {
        let mut out = Vec::with_capacity(6);
        let mut c = [0.0; linear::N];
        match slide {
            Slide::Free => {}
            Slide::Moving(s) => {
                c[V] = s;
                out.push((ContactEvent::SlideStops, c));
            }
            Slide::Stuck => {
                // F_c ∓ (F − k·x) ≥ 0.
                for sign in [1.0, -1.0] {
                    let mut c = [0.0; linear::N];
                    c[ONE] = self.params.coulomb_friction_n;
                    c[F] = -sign;
                    c[X] = sign * self.params.spring_npm;
                    out.push((ContactEvent::SlideBreaksAway, c));
                }
            }
        }
        match part {
            Part::Sliding(sigma) => {
                let mut c = [0.0; linear::N];
                c[U] = sigma;
                c[V] = -sigma;
                out.push((ContactEvent::PartMeetsPlate, c));
            }
            Part::Stuck => {
                // μ_s·g ∓ (a_plate − φ) ≥ 0, with a_plate = A[V]·z.
                let hold = self.contact.static_accel_mps2();
                let phi = self.contact.force_accel_mps2();
                for sign in [1.0, -1.0] {
                    let mut c = a[V].map(|x| -sign * x);
                    c[ONE] += hold + sign * phi;
                    out.push((ContactEvent::PartBreaksAway, c));
                }
            }
        }
        if let Some(x_lim) = self.params.end_stop_m {
            for sign in [1.0, -1.0] {
                let mut c = [0.0; linear::N];
                c[ONE] = x_lim;
                c[X] = -sign;
                out.push((ContactEvent::EndStop, c));
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
    pub fn apply(&self, event: ContactEvent, z: &mut State, slide: &mut Slide, part: &mut Part) {
        match event {
            ContactEvent::SlideStops => {
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
            ContactEvent::SlideBreaksAway => {
                let net = z[F] - self.params.spring_npm * z[X];
                *slide = Slide::Moving(net.signum());
            }
            ContactEvent::PartMeetsPlate => {
                z[U] = z[V];
                *part = self.release(z, *slide);
            }
            ContactEvent::PartBreaksAway => {
                let need = self.plate_accel_mps2(*slide, z) - self.contact.force_accel_mps2();
                *part = Part::Sliding(-need.signum());
            }
            ContactEvent::EndStop => {}
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
}
