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

impl CommandSegment {
    /// A scheduler's `segment` of `plan` in seconds (ticks ÷ clock).
    pub fn of(segment: &crate::scheduler::Segment, plan: &crate::plan::TickPlan) -> Self {
        CommandSegment {
            duration_s: plan.ticks_to_s(u64::from(segment.ticks)),
            accel_mps2: segment.accel_mps2(),
        }
    }
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
    /// The planned `+a` and `−a` levels' magnitudes.
    pub positive_mps2: f64,
    pub negative_mps2: f64,
    /// What a small error `e` in the `+`, zero and `−` level does by the cycle's end: the
    /// velocity `e·[k][0]` and the position `e·[k][1]` (the time each is commanded, and its
    /// first moment about the end).
    pub level_effects: [[f64; 2]; 3],
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
            positive_mps2: 0.0,
            negative_mps2: 0.0,
            level_effects: [[0.0; 2], [period_s, period_s * period_s / 2.0], [0.0; 2]],
        }
    }

    /// The shape of `segments` (the velocity must leave zero upwards, as the paper's cycle does);
    /// `None` if it never turns.
    pub fn new(segments: &[CommandSegment]) -> Option<Self> {
        Self::under_friction(segments, 0.0, 0.0)
    }

    /// The shape of `segments` with `bias_mps2` added to every level, on a slide whose Coulomb
    /// friction decelerates the plate by `coulomb_mps2` while it moves and holds it while the net
    /// command is no more than that. Integrated exactly piece by piece: a piece ends where the
    /// velocity reaches zero.
    pub fn under_friction(
        segments: &[CommandSegment],
        coulomb_mps2: f64,
        bias_mps2: f64,
    ) -> Option<Self> {
        let (mut t, mut v, mut x, mut area, mut signed_s) = (0.0_f64, 0.0_f64, 0.0, 0.0, 0.0);
        let mut turn: Option<(f64, f64)> = None;
        for segment in segments {
            let net = segment.accel_mps2 + bias_mps2;
            let mut rest_s = segment.duration_s;
            while rest_s > 0.0 {
                let direction = if v != 0.0 {
                    sign(v)
                } else if net.abs() > coulomb_mps2 {
                    sign(net)
                } else {
                    0.0
                };
                let a = net - coulomb_mps2 * direction;
                let a = if direction == 0.0 { 0.0 } else { a };
                let stop_s = if v * a < 0.0 { -v / a } else { f64::INFINITY };
                let s = stop_s.min(rest_s);
                area += x * s + v * s * s / 2.0 + a * s * s * s / 6.0;
                signed_s += direction * s;
                x += v * s + a * s * s / 2.0;
                v += a * s;
                t += s;
                rest_s -= s;
                if stop_s <= s {
                    if turn.is_none() && direction > 0.0 {
                        turn = Some((t, x));
                    }
                    v = 0.0;
                }
            }
        }
        let (turn_s, stroke_m) = turn?;
        let (mut positive_mps2, mut negative_mps2) = (0.0_f64, 0.0_f64);
        let mut level_effects = [[0.0; 2]; 3];
        let mut begins_s = 0.0;
        for segment in segments {
            let level = if segment.accel_mps2 > 0.0 {
                positive_mps2 = positive_mps2.max(segment.accel_mps2);
                0
            } else if segment.accel_mps2 < 0.0 {
                negative_mps2 = negative_mps2.max(-segment.accel_mps2);
                2
            } else {
                1
            };
            let d = segment.duration_s;
            level_effects[level][0] += d;
            level_effects[level][1] += d * (t - begins_s - d / 2.0);
            begins_s += d;
        }
        (t > 0.0).then(|| CycleShape {
            period_s: t,
            turn_s,
            stroke_m,
            mean_m: area / t,
            velocity_sign_mean: signed_s / t,
            positive_mps2,
            negative_mps2,
            level_effects,
        })
    }
}
