//! What the feedforward leaves, estimated cycle by cycle: a constant acceleration `e` (the
//! identification's offset and friction errors) and a gain error `ε` that acts in proportion to
//! the cycle's levels. A soft start scales the levels cycle by cycle, so the gain error's part
//! grows with them; an estimate of one constant alone would lag that ramp.
//!
//! A cycle of period `T` whose `+a` level is `a₊` with the position moment `L₊` (its effect on
//! the position at the cycle's end per m/s², [`CycleShape::level_effects`]) moves the plate by
//! `d = (T²/2)·(e + ε·a₊·L₊/(T²/2)) = (T²/2)·h·θ` more than planned, with `h = [1, a₊·L₊/(T²/2)]`
//! and `θ = [e, ε]`. Each boundary measures the mean `d` of the last two cycles from the second
//! difference of their starts; a Kalman filter with `θ` a random walk takes it.

use super::shape::CycleShape;

/// The prior spread of `e` (m/s²) and `ε`.
const PRIOR: [f64; 2] = [1.0, 0.02];
/// How far `e` (m/s²) and `ε` may wander a cycle.
const WANDER: [f64; 2] = [0.05, 5e-4];
/// The spread of one measurement of `d`, as an acceleration over the cycle (m/s²).
const MEASUREMENT_MPS2: f64 = 0.1;

/// The estimate of `θ = [e, ε]` and its covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disturbance {
    theta: [f64; 2],
    covariance: [[f64; 2]; 2],
}

/// `h` of a cycle of `shape` and its `T²/2`.
fn regressor(shape: &CycleShape) -> ([f64; 2], f64) {
    let half_period_squared = shape.period_s * shape.period_s / 2.0;
    let level = if half_period_squared > 0.0 {
        shape.positive_mps2 * shape.level_effects[0][1] / half_period_squared
    } else {
        0.0
    };
    ([1.0, level], half_period_squared)
}

impl Disturbance {
    /// Nothing known yet.
    pub const fn new() -> Self {
        Disturbance {
            theta: [0.0; 2],
            covariance: [[PRIOR[0] * PRIOR[0], 0.0], [0.0, PRIOR[1] * PRIOR[1]]],
        }
    }

    /// Forgets the gain error for a drive fed forward anew (its gains changed): `ε` back to 0,
    /// both parts' spreads back to their priors (the constant part took up the old gain error
    /// at the levels held, and moves with `ε` when the levels move).
    pub fn forget_gain(&mut self) {
        self.theta[1] = 0.0;
        self.covariance = [[PRIOR[0] * PRIOR[0], 0.0], [0.0, PRIOR[1] * PRIOR[1]]];
    }

    /// The displacement `d` it adds to a cycle of `shape`, in m.
    pub fn of(&self, shape: &CycleShape) -> f64 {
        let (h, half_period_squared) = regressor(shape);
        half_period_squared * (h[0] * self.theta[0] + h[1] * self.theta[1])
    }

    /// Takes a measurement `measured_m` of the mean `d` of the two cycles of `shapes`.
    pub fn measure(&mut self, measured_m: f64, shapes: [&CycleShape; 2]) {
        let ((a, half_a), (b, half_b)) = (regressor(shapes[0]), regressor(shapes[1]));
        let scale = (half_a + half_b) / 2.0;
        if scale <= 0.0 || !measured_m.is_finite() {
            return;
        }
        let h = [
            (half_a * a[0] + half_b * b[0]) / (2.0 * scale),
            (half_a * a[1] + half_b * b[1]) / (2.0 * scale),
        ];
        let z = measured_m / scale;
        let p = &mut self.covariance;
        for (k, wander) in WANDER.iter().enumerate() {
            p[k][k] += wander * wander;
        }
        let ph = [
            p[0][0] * h[0] + p[0][1] * h[1],
            p[1][0] * h[0] + p[1][1] * h[1],
        ];
        let spread = h[0] * ph[0] + h[1] * ph[1] + MEASUREMENT_MPS2 * MEASUREMENT_MPS2;
        let gain = [ph[0] / spread, ph[1] / spread];
        let innovation = z - (h[0] * self.theta[0] + h[1] * self.theta[1]);
        self.theta[0] += gain[0] * innovation;
        self.theta[1] += gain[1] * innovation;
        let before = *p;
        for i in 0..2 {
            for j in 0..2 {
                p[i][j] = before[i][j] - gain[i] * ph[j];
            }
        }
    }
}

impl Default for Disturbance {
    fn default() -> Self {
        Self::new()
    }
}
