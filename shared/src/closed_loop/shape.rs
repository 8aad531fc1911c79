//! What the plan says one cycle does to the plate, from rest: its period, where its velocity
//! turns (the far end of the stroke), its stroke and its mean position.

/// `1`, `−1` or `0` as `v` is positive, negative or zero (`f64::signum` gives `1` for zero).
pub(crate) fn sign(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// One commanded segment of a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommandSegment {
    pub duration_s: f64,
    pub accel_mps2: f64,
}

/// A cycle's planned motion from rest at its start, integrated exactly segment by segment.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleShape {
    pub period_s: f64,
    /// First time after the start at which the velocity returns to zero from positive.
    pub turn_s: f64,
    /// Displacement at `turn_s`.
    pub stroke_m: f64,
    /// Mean displacement over the cycle.
    pub mean_m: f64,
    /// Mean over the cycle of the sign of the velocity: slide friction `F_c` changes the
    /// plate's velocity by `−(F_c/M)·T·velocity_sign_mean` a cycle.
    pub velocity_sign_mean: f64,
}

impl CycleShape {
    /// An idle period: no command, no motion.
    pub fn idle(period_s: f64) -> Self {
        CycleShape {
            period_s,
            turn_s: period_s,
            stroke_m: 0.0,
            mean_m: 0.0,
            velocity_sign_mean: 0.0,
        }
    }

    /// The shape of `segments` (the velocity must leave zero upwards, as the paper's cycle does);
    /// `None` if it never turns.
    pub fn new(segments: &[CommandSegment]) -> Option<Self> {
        let (mut t, mut v, mut x, mut area) = (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
        let mut signed_s = 0.0;
        let mut turn: Option<(f64, f64)> = None;
        for segment in segments {
            let (d, a) = (segment.duration_s, segment.accel_mps2);
            // The velocity `v + a·s` changes sign at most once in a segment.
            let crossing_s = if a != 0.0 && v * a < 0.0 {
                -v / a
            } else {
                f64::INFINITY
            };
            if turn.is_none() && v > 0.0 && a < 0.0 && crossing_s <= d {
                let s = crossing_s;
                turn = Some((t + s, x + v * s + a * s * s / 2.0));
            }
            signed_s += if crossing_s < d {
                sign(v) * crossing_s + sign(a) * (d - crossing_s)
            } else {
                sign(v + a * d / 2.0) * d
            };
            area += x * d + v * d * d / 2.0 + a * d * d * d / 6.0;
            x += v * d + a * d * d / 2.0;
            v += a * d;
            t += d;
        }
        let (turn_s, stroke_m) = turn?;
        (t > 0.0).then(|| CycleShape {
            period_s: t,
            turn_s,
            stroke_m,
            mean_m: area / t,
            velocity_sign_mean: signed_s / t,
        })
    }
}
