//! A chunk of the plate's motion on a free slide: its slow part's Taylor series from a state,
//! its end, its reach, and the state at any time in it; the event functions on it and their
//! zeros are [`search`]'s.

mod search;

use crate::plate::linear::{State, F, P, Q, U, V, X};
use crate::plate::model::Part;
use crate::plate::roots::{horner, horner_pair, weighted, Times};

use super::end_maps::Ends;
use super::slide::{FreeSlide, Poly, FALLING, INVERSE, TERMS};

/// An event function `g(τ) = w·X^(d)(τ) + c + s·τ + γ·e^{−ρτ}`: a weighted derivative of the
/// slow position (`d = 0, 1, 2`: position, velocity, acceleration), a line, and the current
/// loop's mode. `Q = ρ·S + S′ = w·(ρ·X^(d) + X^(d+1)) + ρ·c + s + ρ·s·τ`.
#[derive(Debug, Clone, Copy)]
struct Function {
    order: usize,
    /// `ρ·X^(d) + X^(d+1)` over the chunk.
    mode: Mode,
    weight: f64,
    constant: f64,
    slope: f64,
    fast: f64,
    /// The time from which it is watched.
    from: f64,
    /// `g(from)` from the state itself, exactly zero where the regime was entered on its
    /// boundary.
    start: f64,
    /// `g` at the chunk's end.
    end: f64,
}

/// `ρ·X^(d) + X^(d+1)` over a chunk: its order `d`, its two lowest Taylor coefficients, how
/// many it has, and the bounds of its terms from `τ²` on over the chunk, `Σ_{m≥2} |c_m|·L^m`
/// and `Σ_{m≥2} m·|c_m|·L^{m−1}`, which bound `Q`'s and `Q′`'s variation for every function on
/// this derivative.
#[derive(Debug, Clone, Copy)]
struct Mode {
    order: usize,
    low: [f64; 2],
    len: usize,
    tail: f64,
    slope_tail: f64,
}

/// The plate's motion from a state, over one chunk, with its turning points and its first
/// contact with an end stop there.
#[derive(Debug, Clone, Default)]
pub struct Chunk {
    target_n: f64,
    /// `ρ` and `r_x` of the free slide.
    lag_per_s: f64,
    mode_m_per_n: f64,
    /// `φ₀`.
    phi_n: f64,
    /// Taylor coefficients of the slow position `X` and of its first three derivatives:
    /// `series[d][m]` is the coefficient of `τ^m` in `X^(d)`.
    series: [Poly; 4],
    /// `∫X` at the start.
    q0: f64,
    /// The chunk's length `L` and the plate's `(x, v)` then.
    pub length_s: f64,
    end: (f64, f64),
    /// `∫X` over the chunk and a bound of the change in `X″` over it, if its end came from a
    /// map.
    end_integral: Option<f64>,
    accel_spread: Option<f64>,
    /// `φ(L)`.
    phi_end_n: f64,
    /// Taylor coefficients summed: the first `n` with `(ω·L)ⁿ/n!` below `2⁻⁵⁶` for the chunk's
    /// length `L`, at least 4 (a plate without spring or damping is a cubic).
    terms: usize,
    /// `ρ·X^(d) + X^(d+1)` for `d = 0, 1, 2`, as the functions watched need them.
    modes: [Option<Mode>; 3],
    /// The plate's turning points in `(0, L]`.
    pub turns: Times,
    /// The first time the plate reaches an end stop in `[0, L]`.
    end_stop: Option<f64>,
}

impl Chunk {
    /// Makes this the chunk of `length_s` from the state `z0`, with its turning points if the
    /// plate may pass `peak_m` in it; its end from the map in `ends` if its length has one.
    /// Out of line, as [`Chunk::part_event`]: inlined, they crowd the course's loop (7 % more
    /// instructions a cycle).
    #[inline(never)]
    pub fn start(
        &mut self,
        free: &FreeSlide,
        target_n: f64,
        z0: &State,
        length_s: f64,
        peak_m: f64,
        ends: &mut Ends,
    ) {
        let rho = free.lag_per_s;
        let r_x = free.mode_m_per_n;
        let phi_n = if rho > 0.0 { z0[F] - target_n } else { 0.0 };
        // `ω·L ≤ 1`, so `(ω·L)^(n−1)/(n−1)!` falls with `n`.
        let reach = free.model.slow_per_s * length_s;
        let mut terms = 4;
        while terms < TERMS && reach >= free.reach_limits[terms] {
            terms += 1;
        }
        self.target_n = target_n;
        self.lag_per_s = rho;
        self.mode_m_per_n = r_x;
        self.phi_n = phi_n;
        self.q0 = if rho > 0.0 {
            z0[Q] + r_x / rho * phi_n
        } else {
            z0[Q]
        };
        self.length_s = length_s;
        let map = ends.get(free, length_s, terms).copied();
        self.phi_end_n = match map {
            _ if phi_n == 0.0 => 0.0,
            Some(map) => phi_n * map.decay,
            None => phi_n * (-rho * length_s).exp(),
        };
        self.terms = terms;
        self.modes = [None; 3];
        self.end_stop = None;
        let x0 = z0[X] - r_x * phi_n;
        let v0 = z0[V] + rho * r_x * phi_n;
        let [from_x, from_v, from_force] = &free.basis;
        let [position, velocity, accel, jerk] = &mut self.series;
        for (n, c) in position.iter_mut().enumerate() {
            *c = x0 * from_x[n] + v0 * from_v[n] + target_n * from_force[n];
        }
        for (d, derivative) in [velocity, accel, jerk].into_iter().enumerate() {
            let d = d + 1;
            let (low, high) = derivative.split_at_mut(TERMS - d);
            for ((c, p), k) in low.iter_mut().zip(&position[d..]).zip(&FALLING[d][d..]) {
                *c = k * p;
            }
            high.fill(0.0);
        }
        self.end = match map {
            Some(map) => {
                let slow = |c: [f64; 3]| c[0] * x0 + c[1] * v0 + c[2] * target_n;
                self.end_integral = Some(slow(map.integral));
                let [x, v, force] = map.accel_spread;
                self.accel_spread = Some(x * x0.abs() + v * v0.abs() + force * target_n.abs());
                (
                    slow(map.position) + self.mode_share(0) * self.phi_end_n,
                    slow(map.velocity) + self.mode_share(1) * self.phi_end_n,
                )
            }
            None => {
                self.end_integral = None;
                self.accel_spread = None;
                let (x, v, _) = self.plate_at(length_s, self.phi_end_n, false);
                (x, v)
            }
        };
        let x_lim = free.model.params.end_stop_m;
        let reach_m = if peak_m > 0.0 || x_lim.is_some() {
            self.reach_m() * (1.0 + REACH_MARGIN)
        } else {
            f64::INFINITY
        };
        self.turns = if reach_m < peak_m {
            Times::default()
        } else {
            let turn = self.function(1, 1.0, 0.0, 0.0, 0.0, z0[V]);
            let pieces = self.pieces(&turn);
            self.sign_changes(&turn, &pieces)
        };
        if let Some(x_lim) = x_lim.filter(|&x_lim| reach_m >= x_lim) {
            for sign in [1.0, -1.0] {
                let stop = self.function(0, -sign, x_lim, 0.0, 0.0, x_lim - sign * z0[X]);
                let pieces = self.pieces(&stop);
                if let Some(t) = self.first_zero(&stop, &pieces) {
                    if self.end_stop.is_none_or(|at| t < at) {
                        self.end_stop = Some(t);
                    }
                }
            }
        }
    }

    /// A bound of the plate's distance from the centre over the chunk: the slow part's from
    /// parabolas through either end with the bounds of its acceleration `X″` (exact where `X″`
    /// keeps a sign: the far side is then at an end), and the current loop's mode's at most
    /// `|r_x·φ₀|`. `X″` strays from its start by at most `Σ_{n≥1} |X″_n|·Lⁿ`, or the map's
    /// bound.
    fn reach_m(&self) -> f64 {
        let length_s = self.length_s;
        let accel = self.derivative(2);
        let spread = self.accel_spread.unwrap_or_else(|| {
            let terms = accel[1..].iter().rev();
            length_s * terms.fold(0.0, |sum, c| sum * length_s + c.abs())
        });
        let (low, high) = (accel[0] - spread, accel[0] + spread);
        let start = (self.series[0][0], self.series[1][0]);
        let end = (
            self.end.0 - self.mode_share(0) * self.phi_end_n,
            self.end.1 - self.mode_share(1) * self.phi_end_n,
        );
        let above = farthest(start, end, high, low, length_s);
        let below = farthest(
            (-start.0, -start.1),
            (-end.0, -end.1),
            -low,
            -high,
            length_s,
        );
        larger(above, below) + (self.mode_share(0) * self.phi_n).abs()
    }

    /// The Taylor coefficients of `X^(d)`, `d ≤ 3`.
    fn derivative(&self, d: usize) -> &[f64] {
        &self.series[d][..self.terms - d]
    }

    /// `X^(d)(τ)` and `X^(d+1)(τ)`, `d ≤ 2`, summed side by side (`X^(d+1)` to the length of
    /// `X^(d)`: its coefficient after its last is 0).
    fn derivative_pair(&self, d: usize, t: f64) -> (f64, f64) {
        let len = self.terms - d;
        horner_pair(&self.series[d][..len], &self.series[d + 1][..len], t)
    }

    /// `φ(τ)`.
    fn phi(&self, t: f64) -> f64 {
        if self.phi_n == 0.0 {
            0.0
        } else if t == self.length_s {
            self.phi_end_n
        } else {
            self.phi_n * (-self.lag_per_s * t).exp()
        }
    }

    /// The current loop's mode's part of `x^(d)` per newton of `φ`: `r_x·(−ρ)^d`, `d ≤ 2`.
    fn mode_share(&self, order: usize) -> f64 {
        let rho = self.lag_per_s;
        self.mode_m_per_n
            * match order {
                0 => 1.0,
                1 => -rho,
                _ => rho * rho,
            }
    }

    /// The plate's position at `τ`.
    pub fn position(&self, t: f64) -> f64 {
        horner(self.derivative(0), t) + self.mode_share(0) * self.phi(t)
    }

    /// The plate's `(x, v, a)` at `τ`, where `φ` is `phi`; `a` only if `accel` (else 0).
    fn plate_at(&self, t: f64, phi: f64, accel: bool) -> (f64, f64, f64) {
        let (x, v) = self.derivative_pair(0, t);
        let a = if accel {
            horner(self.derivative(2), t)
        } else {
            0.0
        };
        (
            x + self.mode_share(0) * phi,
            v + self.mode_share(1) * phi,
            a + self.mode_share(2) * phi,
        )
    }

    /// The whole state at `τ`, from the state `z` at `from` with the part in contact `part`.
    pub fn state(&self, free: &FreeSlide, t: f64, part: Part, z: &State, from: f64) -> State {
        let phi = self.phi(t);
        let (x, v) = if t == self.length_s {
            self.end
        } else {
            let (x, v, _) = self.plate_at(t, phi, false);
            (x, v)
        };
        let integral = match self.end_integral {
            Some(integral) if t == self.length_s => integral,
            _ => t * weighted(self.derivative(0), &INVERSE[1..], t),
        };
        let mut q = self.q0 + integral;
        if self.lag_per_s > 0.0 {
            q -= self.mode_m_per_n / self.lag_per_s * phi;
        }
        let mut out = *z;
        out[X] = x;
        out[V] = v;
        out[F] = self.target_n + phi;
        out[Q] = q;
        match part {
            Part::Sliding(sigma) => {
                let accel = free.model.sliding_part_accel_mps2(sigma);
                let dt = t - from;
                out[P] = z[P] + dt * (z[U] + 0.5 * accel * dt);
                out[U] = z[U] + accel * dt;
            }
            Part::Stuck => {
                out[P] = z[P] + (x - z[X]);
                out[U] = v;
            }
        }
        out
    }
}

/// Relative margin on [`Chunk::reach_m`] for the rounding of the values it is built from.
const REACH_MARGIN: f64 = 1e-12;

/// The highest `X` over `[0, L]` from its `(X, X′)` at both ends and bounds `low ≤ X″ ≤ high`:
/// at an end where `X` is convex, else the lower of the two parabolas' highest points.
fn farthest(start: (f64, f64), end: (f64, f64), high: f64, low: f64, length_s: f64) -> f64 {
    if low >= 0.0 {
        return larger(start.0, end.0);
    }
    let (from_start, from_end) = (
        parabola_top(start, high, length_s),
        parabola_top((end.0, -end.1), high, length_s),
    );
    if from_start < from_end {
        from_start
    } else {
        from_end
    }
}

/// The highest point over `s ∈ [0, L]` of `x + v·s + a·s²/2`.
fn parabola_top((x, v): (f64, f64), a: f64, length_s: f64) -> f64 {
    if a < 0.0 && v > 0.0 && v < -a * length_s {
        x - 0.5 * v * v / a
    } else {
        larger(x, x + length_s * (v + 0.5 * a * length_s))
    }
}

/// The larger of two numbers that are not NaN.
fn larger(a: f64, b: f64) -> f64 {
    if a < b {
        b
    } else {
        a
    }
}
