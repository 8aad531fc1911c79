//! The event functions on a chunk, `g(τ) = S(τ) + γ·e^{−ρτ}`, and their zeros: the pieces
//! between the zeros of `Q = ρ·S + S′` on which `e^{ρτ}·g` is monotone, and the first zero or
//! every sign change over them.

use crate::plate::linear::{State, U, V};
use crate::plate::model::{ContactEvent, Part, Slide};
use crate::plate::roots::{horner, jet, refine, zeros, Times, EXACT, TURN};

use super::super::slide::{FreeSlide, Poly, FALLING, TERMS};
use super::{Chunk, Function, Mode};

impl Chunk {
    /// The function `w·X^(d) + c + s·τ` with the current loop's part of `x^(d)` weighted alike,
    /// watched from `from`, where it is `start`.
    pub(super) fn function(
        &mut self,
        order: usize,
        weight: f64,
        constant: f64,
        slope: f64,
        from: f64,
        start: f64,
    ) -> Function {
        let mode = match self.modes[order] {
            Some(mode) => mode,
            None => *self.modes[order].insert(self.mode(order)),
        };
        let fast = weight * self.phi_n * self.mode_share(order);
        let at_end = match order {
            0 => self.end.0,
            1 => self.end.1,
            _ => self.plate_at(self.length_s, self.phi_end_n, true).2,
        };
        Function {
            order,
            mode,
            weight,
            constant,
            slope,
            fast,
            from,
            start,
            end: weight * at_end + constant + slope * self.length_s,
        }
    }

    /// The part's first event in `[from, L]` from the state `z` at `from` (or the plate's first
    /// contact with an end stop, if that comes first).
    #[inline(never)]
    pub fn part_event(
        &mut self,
        free: &FreeSlide,
        part: Part,
        z: &State,
        from: f64,
    ) -> Option<(ContactEvent, f64)> {
        let mut first: Option<(ContactEvent, f64)> = None;
        match part {
            Part::Sliding(sigma) => {
                let accel = free.model.sliding_part_accel_mps2(sigma);
                let constant = sigma * (z[U] - accel * from);
                let start = -sigma * z[V] + sigma * z[U];
                let meet = self.function(1, -sigma, constant, sigma * accel, from, start);
                let pieces = self.pieces(&meet);
                first = self
                    .first_zero(&meet, &pieces)
                    .map(|t| (ContactEvent::PartMeetsPlate, t));
            }
            Part::Stuck => {
                let contact = &free.model.contact;
                let start_accel_mps2 = free.model.plate_accel_mps2(Slide::Free, z);
                for sign in [1.0, -1.0] {
                    let constant = contact.static_accel_mps2() + sign * contact.force_accel_mps2();
                    let start = -sign * start_accel_mps2 + constant;
                    let away = self.function(2, -sign, constant, 0.0, from, start);
                    let pieces = self.pieces(&away);
                    if let Some(t) = self.first_zero(&away, &pieces) {
                        if first.is_none_or(|(_, at)| t < at) {
                            first = Some((ContactEvent::PartBreaksAway, t));
                        }
                    }
                }
            }
        }
        if let Some(t) = self.end_stop {
            if t >= from && first.is_none_or(|(_, at)| t < at) {
                first = Some((ContactEvent::EndStop, t));
            }
        }
        first
    }

    /// The Taylor coefficient of `τ^m` in `ρ·X^(d) + X^(d+1)`.
    fn mode_coefficient(&self, order: usize, m: usize) -> f64 {
        self.lag_per_s * self.series[order][m] + self.series[order + 1][m]
    }

    /// `ρ·X^(d) + X^(d+1)` over the chunk.
    fn mode(&self, order: usize) -> Mode {
        let length_s = self.length_s;
        let len = self.terms - order;
        // `Σ_{m≥2} |c_m|·L^(m−2)` and `Σ_{m≥2} m·|c_m|·L^(m−2)`, by Horner's scheme.
        let (mut tail, mut slope_tail) = (0.0, 0.0);
        let rho = self.lag_per_s;
        let lower = &self.series[order][2..len];
        let higher = &self.series[order + 1][2..len];
        for ((l, h), m) in lower.iter().zip(higher).zip(&FALLING[1][2..len]).rev() {
            let c = (rho * l + h).abs();
            tail = tail * length_s + c;
            slope_tail = slope_tail * length_s + m * c;
        }
        Mode {
            order,
            low: [
                self.mode_coefficient(order, 0),
                self.mode_coefficient(order, 1),
            ],
            len,
            tail: tail * length_s * length_s,
            slope_tail: slope_tail * length_s,
        }
    }

    /// The Taylor coefficients of `Q = ρ·S + S′` for a function of weight `w` whose `Q` starts
    /// `q0 + q1·τ`, as many as its mode has.
    fn q_poly(&self, w: f64, mode: &Mode, [q0, q1]: [f64; 2]) -> Poly {
        let rho = self.lag_per_s;
        let len = mode.len;
        let lower = &self.series[mode.order][..len];
        let higher = &self.series[mode.order + 1][..len];
        let mut out = [0.0; TERMS];
        for ((c, l), h) in out[..len].iter_mut().zip(lower).zip(higher) {
            *c = w * (rho * l + h);
        }
        out[0] = q0;
        out[1] = q1;
        out
    }

    /// Times `from = t₀ < t₁ < … < L` between which `H = e^{ρτ}·g` is monotone, as far as the
    /// zeros of `g` after `from` need them: where `Q = ρ·S + S′` is monotone, its zero only if
    /// `H`'s extremum there turns towards zero between ends of one sign (or leaves zero from the
    /// start); else every zero of `Q`.
    pub(super) fn pieces(&self, function: &Function) -> Times {
        let mode = &function.mode;
        let length_s = self.length_s;
        let rho = self.lag_per_s;
        let w = function.weight;
        let from = function.from;
        let q0 = w * mode.low[0] + rho * function.constant + function.slope;
        let q1 = w * mode.low[1] + rho * function.slope;
        let tail = w.abs() * mode.tail;
        let slope_rest = w.abs() * mode.slope_tail;
        let mut pieces = Times::default();
        pieces.push(from);
        // `Q` lies above `q0 + q1·τ − tail·(τ/L)²` (below its mirror), which is concave, so its
        // least value on the chunk is at an end.
        let q_end = q0 + q1 * length_s;
        let zero_free = if q0 > 0.0 {
            q_end - tail > 0.0
        } else if q0 < 0.0 {
            q_end + tail < 0.0
        } else {
            q1 == 0.0 && tail == 0.0
        };
        let monotone = q1.abs() > slope_rest || (q1 == 0.0 && slope_rest == 0.0);
        let q_poly = || self.q_poly(w, mode, [q0, q1]);
        let len = mode.len;
        if !zero_free {
            if !monotone {
                let q = q_poly();
                for &t in zeros(&q[..len], length_s).as_slice() {
                    if t > from && t < length_s {
                        pieces.push(t);
                    }
                }
            } else {
                // A monotone `Q` changes sign after `from` only if `Q(from)` and `Q(L)` differ
                // in sign; `H` then rises and falls where `Q(from) > 0`, a maximum, else falls
                // and rises.
                let mut q = None;
                let q_from = if from > 0.0 {
                    horner(&q.insert(q_poly())[..len], from)
                } else {
                    q0
                };
                let maximum = q_from > 0.0;
                let (g_lo, g_hi) = (function.start, function.end);
                // From zero, the extremum matters only if `g` ends on its other side.
                let needed = if g_lo == 0.0 {
                    if maximum {
                        g_hi <= 0.0
                    } else {
                        g_hi >= 0.0
                    }
                } else {
                    (g_lo > 0.0) == (g_hi > 0.0) && (g_lo > 0.0) != maximum
                };
                if needed {
                    let q = &q.get_or_insert_with(q_poly)[..len];
                    let q_hi = horner(q, length_s);
                    if maximum != (q_hi > 0.0) {
                        let t = refine(|t| jet(q, t), (from, q_from), (length_s, q_hi), EXACT);
                        pieces.push(t);
                    }
                }
            }
        }
        pieces.push(length_s);
        pieces
    }

    /// `g` and `g′` at `τ > 0`.
    fn jet(&self, function: &Function, t: f64) -> (f64, f64) {
        let (value, derivative) = self.derivative_pair(function.order, t);
        let slow = function.weight * value + function.constant + function.slope * t;
        let slope = function.weight * derivative + function.slope;
        if function.fast == 0.0 {
            (slow, slope)
        } else {
            let fast = function.fast * (-self.lag_per_s * t).exp();
            (slow + fast, slope - self.lag_per_s * fast)
        }
    }

    fn value(&self, function: &Function, t: f64) -> f64 {
        if t == function.from {
            function.start
        } else if t == self.length_s {
            function.end
        } else {
            self.jet(function, t).0
        }
    }

    /// The first time at which `g` reaches zero from above, over pieces on each of which it has
    /// at most one zero. A function that starts at zero (a regime entered on its own boundary, as
    /// a part that has just met the plate) ends its regime at once only if it is positive at no
    /// end of a piece of the chunk: a dip of rounding size is no event.
    pub(super) fn first_zero(&self, function: &Function, pieces: &Times) -> Option<f64> {
        let g = |t: f64| self.value(function, t);
        let points = pieces.as_slice();
        let g_start = g(points[0]);
        if g_start < 0.0 {
            return Some(points[0]);
        }
        let mut rest = points[1..].iter();
        let (mut left, mut g_left) = (points[0], g_start);
        if g_start == 0.0 {
            match rest
                .by_ref()
                .map(|&t| (t, g(t)))
                .find(|&(_, g_t)| g_t > 0.0)
            {
                Some(positive) => (left, g_left) = positive,
                None => return Some(points[0]),
            }
        }
        for &right in rest {
            let g_right = g(right);
            if g_right <= 0.0 {
                return Some(self.zero(function, (left, g_left), (right, g_right), EXACT));
            }
            left = right;
            g_left = g_right;
        }
        None
    }

    /// The zero of `g` between two ends of opposite sign ([`refine`]).
    fn zero(&self, function: &Function, lo: (f64, f64), hi: (f64, f64), relative: f64) -> f64 {
        refine(|t| self.jet(function, t), lo, hi, relative)
    }

    /// Every sign change of `g` over the pieces.
    pub(super) fn sign_changes(&self, function: &Function, pieces: &Times) -> Times {
        let g = |t: f64| self.value(function, t);
        let points = pieces.as_slice();
        let mut out = Times::default();
        let mut left = points[0];
        let mut g_left = g(left);
        for &right in &points[1..] {
            let g_right = g(right);
            if g_right == 0.0 {
                out.push(right);
            } else if g_left != 0.0 && (g_left > 0.0) != (g_right > 0.0) {
                out.push(self.zero(function, (left, g_left), (right, g_right), TURN));
            }
            left = right;
            g_left = g_right;
        }
        out
    }
}
