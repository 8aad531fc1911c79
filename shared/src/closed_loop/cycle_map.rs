//! How the plate's deviation from its plan moves from one cycle start to the next, in the
//! cycle-rate loop's units: the position `x` and `w = T·v`, a constant acceleration `δ` over the
//! cycle counted as `ũ = δ·T²/2`.
//!
//! The feedforward cancels the slide's forces along the planned motion, so the deviation `e`
//! obeys `ë = −(k/M)·e − (b/M)·ė + δ`: a centring spring pulls it back and viscous friction damps
//! it. Over a period `T` that is `s⁺ = Φ·s + Γ·ũ` with `s = (x, w)`; a free mass
//! (`k = b = 0`) gives `Φ = [[1, 1], [0, 1]]`, `Γ = (1, 2)`. The loop's gains place both poles
//! of the closed loop `Φ − Γ·K` by Ackermann's formula, `K = [0 1]·[Γ ΦΓ]⁻¹·p(Φ)`.

use libm::fabs;

/// The map of one cycle: `s⁺ = Φ·s + Γ·ũ`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleMap {
    pub phi: [[f64; 2]; 2],
    pub gamma: [f64; 2],
}

/// Terms of the exponential's Taylor series after scaling to a norm of at most 1/2: the
/// remainder is below `2⁻¹⁸/18! < 10⁻²¹`.
const TAYLOR_TERMS: usize = 18;

/// The radius [`CycleMap::gains`] gives the poles of a mount that turns the plate a quarter
/// around or more in a cycle.
pub const SPRUNG_POLE: f64 = 0.7;

impl CycleMap {
    /// A free mass.
    pub const FREE: CycleMap = CycleMap {
        phi: [[1.0, 1.0], [0.0, 1.0]],
        gamma: [1.0, 2.0],
    };

    /// The map of a plate on a spring `spring_per_s2 = k/M` with viscous friction
    /// `viscous_per_s = b/M` over a cycle of `period_s`; a free mass where both are zero or
    /// the period is not positive.
    pub fn new(spring_per_s2: f64, viscous_per_s: f64, period_s: f64) -> Self {
        let valid = |v: f64| v.is_finite() && v >= 0.0;
        if !(valid(spring_per_s2) && valid(viscous_per_s) && period_s > 0.0 && period_s.is_finite())
            || (spring_per_s2 == 0.0 && viscous_per_s == 0.0)
        {
            return CycleMap::FREE;
        }
        // The state (x, v, u) with the acceleration u held: ẋ = v, v̇ = −k·x − b·v + u, u̇ = 0.
        let t = period_s;
        let generator = [
            [0.0, t, 0.0],
            [-spring_per_s2 * t, -viscous_per_s * t, t],
            [0.0, 0.0, 0.0],
        ];
        let e = exponential(generator);
        // To (x, w = T·v), the input per ũ = u·T²/2.
        let per_u = 2.0 / (t * t);
        CycleMap {
            phi: [[e[0][0], e[0][1] / t], [e[1][0] * t, e[1][1]]],
            gamma: [e[0][2] * per_u, e[1][2] * t * per_u],
        }
    }

    /// `Φ·s`.
    pub fn apply(&self, s: [f64; 2]) -> [f64; 2] {
        [
            self.phi[0][0] * s[0] + self.phi[0][1] * s[1],
            self.phi[1][0] * s[0] + self.phi[1][1] * s[1],
        ]
    }

    /// The gains `K` that place both poles of `Φ − Γ·K`: at `pole` for a free plate; where a
    /// mount turns the plate by `θ` a cycle (`Φ`'s poles `r·e^{±iθ}`), at the same angle and a
    /// radius from `pole` (`θ = 0`) to [`SPRUNG_POLE`] (`θ` from 90°), so that the loop damps
    /// the mount's swing instead of stopping it within a cycle, which takes gains several times
    /// the free plate's and makes them the more sensitive to the mount's stiffness as it is
    /// identified. `None` where one cycle's constant acceleration cannot steer both position
    /// and velocity (`[Γ ΦΓ]` singular: a spring that turns the plate half around in a cycle).
    pub fn gains(&self, pole: f64) -> Option<[f64; 2]> {
        let (radius, cos_angle) = self.target_poles(pole);
        self.placing(-2.0 * radius * cos_angle, radius * radius)
    }

    /// The radius and the cosine of the angle of the poles [`CycleMap::gains`] places.
    fn target_poles(&self, pole: f64) -> (f64, f64) {
        let trace = self.phi[0][0] + self.phi[1][1];
        let det = self.determinant();
        if det <= 0.0 || trace * trace >= 4.0 * det {
            return (pole, 1.0);
        }
        let r = libm::sqrt(det);
        let cos_angle = (trace / (2.0 * r)).clamp(-1.0, 1.0);
        let turned = libm::acos(cos_angle) / core::f64::consts::FRAC_PI_2;
        (pole + (SPRUNG_POLE - pole) * turned.min(1.0), cos_angle)
    }

    /// The gains `K` that give `Φ − Γ·K` the characteristic polynomial `z² + c₁·z + c₀`
    /// (Ackermann's formula).
    fn placing(&self, c1: f64, c0: f64) -> Option<[f64; 2]> {
        let g = self.gamma;
        let pg = self.apply(g);
        let det = g[0] * pg[1] - pg[0] * g[1];
        let scale = (fabs(g[0]) + fabs(g[1])) * (fabs(pg[0]) + fabs(pg[1]));
        if fabs(det).is_nan() || fabs(det) <= 1e-3 * scale {
            return None;
        }
        // p(Φ) = Φ² + c₁·Φ + c₀·I.
        let p = self.phi;
        let square = [
            [
                p[0][0] * p[0][0] + p[0][1] * p[1][0],
                p[0][0] * p[0][1] + p[0][1] * p[1][1],
            ],
            [
                p[1][0] * p[0][0] + p[1][1] * p[1][0],
                p[1][0] * p[0][1] + p[1][1] * p[1][1],
            ],
        ];
        let poly: [[f64; 2]; 2] = core::array::from_fn(|i| {
            core::array::from_fn(|j| square[i][j] + c1 * p[i][j] + if i == j { c0 } else { 0.0 })
        });
        let row = [-g[1] / det, g[0] / det];
        Some([
            row[0] * poly[0][0] + row[1] * poly[1][0],
            row[0] * poly[0][1] + row[1] * poly[1][1],
        ])
    }

    /// The weights `[c₁, c₀]` of a constant `ũ` in the last cycle and in the one before in the
    /// relation of three cycle starts, `y₂ − Φ₀₀·ε₁ − Φ₁₁·y₁ + det Φ·ε₀ = c₁·ũ₁ + c₀·ũ₀`
    /// (Cayley–Hamilton; `ε` a start's deviation from its own cycle's reference, `y` from the
    /// cycle before's); `[1, 1]` for a free mass.
    pub fn second_difference_weights(&self) -> [f64; 2] {
        let p = self.phi;
        let g = self.gamma;
        [g[0], p[0][1] * g[1] - p[1][1] * g[0]]
    }

    /// `det Φ`.
    pub fn determinant(&self) -> f64 {
        self.phi[0][0] * self.phi[1][1] - self.phi[0][1] * self.phi[1][0]
    }
}

/// `e^M` of a 3×3 matrix by scaling and squaring.
fn exponential(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let norm = m
        .iter()
        .map(|row| row.iter().map(|v| fabs(*v)).sum::<f64>())
        .fold(0.0, f64::max);
    let mut squarings = 0;
    let mut scale = 1.0;
    while norm * scale > 0.5 && squarings < 64 {
        scale *= 0.5;
        squarings += 1;
    }
    let a: [[f64; 3]; 3] = m.map(|row| row.map(|v| v * scale));
    let mut sum = identity();
    let mut term = identity();
    for k in 1..=TAYLOR_TERMS {
        term = product(&term, &a).map(|row| row.map(|v| v / k as f64));
        for (s, t) in sum.iter_mut().zip(term) {
            for (s, t) in s.iter_mut().zip(t) {
                *s += t;
            }
        }
    }
    for _ in 0..squarings {
        sum = product(&sum, &sum);
    }
    sum
}

fn identity() -> [[f64; 3]; 3] {
    core::array::from_fn(|i| core::array::from_fn(|j| if i == j { 1.0 } else { 0.0 }))
}

fn product(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    core::array::from_fn(|i| core::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use libm::{cos, exp, sin, sqrt};

    /// The free mass's map and gains: both poles at 0.3 give the loop's `K = (0.245, 0.5775)`.
    #[test]
    fn a_free_mass_is_a_double_integrator() {
        let map = CycleMap::new(0.0, 0.0, 0.02);
        assert_eq!(map, CycleMap::FREE);
        let k = map.gains(0.3).unwrap();
        assert!(
            fabs(k[0] - 0.245) < 1e-12 && fabs(k[1] - 0.5775) < 1e-12,
            "{k:?}"
        );
        assert_eq!(map.second_difference_weights(), [1.0, 1.0]);
    }

    /// Against the damped oscillator's closed form `x(t) = e^{−αt}(x₀·(cos βt + α/β·sin βt)
    /// + v₀/β·sin βt)` and the constant input's particular solution `u/ω²`.
    #[test]
    fn a_spring_turns_the_plate_as_the_damped_oscillator_does() {
        for (spring, viscous, period) in [(1e4, 2.0, 0.02), (3e4, 10.0, 0.01), (500.0, 0.5, 0.02)] {
            let map = CycleMap::new(spring, viscous, period);
            let alpha = viscous / 2.0;
            let beta = sqrt(spring - alpha * alpha);
            let decay = exp(-alpha * period);
            let (c, s) = (cos(beta * period), sin(beta * period));
            let x_from_x = decay * (c + alpha / beta * s);
            let x_from_v = decay * s / beta;
            let v_from_x = -spring * decay * s / beta;
            let v_from_v = decay * (c - alpha / beta * s);
            let close = |a: f64, b: f64| fabs(a - b) <= 1e-12 * (1.0 + fabs(b));
            assert!(close(map.phi[0][0], x_from_x));
            assert!(close(map.phi[0][1], x_from_v / period));
            assert!(close(map.phi[1][0], v_from_x * period));
            assert!(close(map.phi[1][1], v_from_v));
            // A constant u from rest: x = (u/ω²)(1 − x_from_x), v = −(u/ω²)·v_from_x.
            let u = 2.0 / (period * period);
            assert!(close(map.gamma[0], u / spring * (1.0 - x_from_x)));
            assert!(close(map.gamma[1], -u / spring * v_from_x * period));
        }
    }

    /// The gains place both eigenvalues of `Φ − ΓK`: at the pole for a free plate (trace `2p`,
    /// determinant `p²`); for a mount at the angle the damped oscillator turns in a cycle
    /// (`β·T` from its closed form, folded into `[0, π]`), at a radius from the pole to
    /// [`SPRUNG_POLE`] as that angle grows to 90°.
    #[test]
    fn the_gains_place_both_poles() {
        let viscous = 3.0;
        for spring in [0.0, 100.0, 2e3, 1e4, 4e4] {
            for period in [0.01, 0.02] {
                let map = CycleMap::new(spring, viscous, period);
                let Some(k) = map.gains(0.3) else {
                    continue;
                };
                let closed: [[f64; 2]; 2] = core::array::from_fn(|i| {
                    core::array::from_fn(|j| map.phi[i][j] - map.gamma[i] * k[j])
                });
                let trace = closed[0][0] + closed[1][1];
                let det = closed[0][0] * closed[1][1] - closed[0][1] * closed[1][0];
                let (radius, cos_angle) = if spring == 0.0 {
                    (0.3, 1.0)
                } else {
                    let beta = sqrt(spring - viscous * viscous / 4.0);
                    let turn = (beta * period) % (2.0 * core::f64::consts::PI);
                    let angle = turn.min(2.0 * core::f64::consts::PI - turn);
                    let share = (angle / core::f64::consts::FRAC_PI_2).min(1.0);
                    (0.3 + (SPRUNG_POLE - 0.3) * share, cos(angle))
                };
                assert!(
                    fabs(trace - 2.0 * radius * cos_angle) < 1e-9
                        && fabs(det - radius * radius) < 1e-9,
                    "{spring} {period}: trace {trace}, det {det}, radius {radius}"
                );
            }
        }
    }

    /// A spring that turns the plate half around in a cycle (`ωT = π`) leaves the velocity out
    /// of one constant's reach.
    #[test]
    fn half_a_turn_a_cycle_cannot_be_steered() {
        let period = 0.02;
        let omega = core::f64::consts::PI / period;
        assert_eq!(CycleMap::new(omega * omega, 0.0, period).gains(0.3), None);
    }
}
