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

/// The output of a lag `τ = lag_s > 0` at the start of `segments` played periodically: the
/// fixed point of one period's recursion `a ← u + (a − u)·e^{−d/τ}`, linear in the start value.
pub(crate) fn lagged_start_mps2(segments: &[CommandSegment], lag_s: f64) -> f64 {
    let (mut slope, mut constant) = (1.0, 0.0);
    for segment in segments {
        let decay = libm::exp(-segment.duration_s / lag_s);
        slope *= decay;
        constant = segment.accel_mps2 + (constant - segment.accel_mps2) * decay;
    }
    constant / (1.0 - slope)
}

/// One commanded segment of a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommandSegment {
    pub duration_s: f64,
    pub accel_mps2: f64,
}

impl CommandSegment {
    /// The four segments of one cycle of `waveform` at its exact durations (Fig. 2a).
    pub fn cycle_of(waveform: &crate::waveform::Waveform) -> [CommandSegment; 4] {
        waveform.segments().map(|segment| CommandSegment {
            duration_s: segment.duration_s,
            accel_mps2: f64::from(segment.level.sign()) * waveform.accel_mps2,
        })
    }

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
    /// The stroke a plate behind the drive's current loop shows, read `lag_s` after the start
    /// and after the turn ([`CycleShape::behind_lag`]); `stroke_m` without a lag.
    pub latched_stroke_m: f64,
    /// The current loop's lag `τ` that delays the motion.
    pub lag_s: f64,
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
    /// The same for each segment in its place in the cycle.
    pub segment_effects: [[f64; 2]; 4],
    /// The planned level of each segment in its place (0 past the cycle's last).
    pub segment_accel_mps2: [f64; 4],
    /// The planned motion through each segment in its place: the mean of the velocity's sign,
    /// of the velocity and of the position less the cycle's mean. A plate that follows the plan
    /// meets the slide's forces through these.
    pub segment_motion: [SegmentMotion; 4],
}

/// The planned motion through one segment, as the slide's forces meet it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SegmentMotion {
    pub sign_mean: f64,
    pub velocity_mean_mps: f64,
    /// About the cycle's mean position.
    pub position_mean_m: f64,
}

impl SegmentMotion {
    /// The mean acceleration that cancels, through this segment, a slide of Coulomb friction
    /// `coulomb_mps2` and viscous friction `viscous_per_s` and a centring spring `spring_per_s2`
    /// (each over the moving mass) on a plate at the cycle's centre.
    pub fn slide_mps2(&self, coulomb_mps2: f64, viscous_per_s: f64, spring_per_s2: f64) -> f64 {
        coulomb_mps2 * self.sign_mean
            + viscous_per_s * self.velocity_mean_mps
            + spring_per_s2 * self.position_mean_m
    }
}

impl CycleShape {
    /// An idle period: no command, no motion.
    pub fn idle(period_s: f64) -> Self {
        CycleShape {
            period_s,
            turn_s: period_s,
            stroke_m: 0.0,
            latched_stroke_m: 0.0,
            lag_s: 0.0,
            mean_m: 0.0,
            velocity_sign_mean: 0.0,
            positive_mps2: 0.0,
            negative_mps2: 0.0,
            level_effects: [[0.0; 2], [period_s, period_s * period_s / 2.0], [0.0; 2]],
            segment_effects: [
                [period_s, period_s * period_s / 2.0],
                [0.0; 2],
                [0.0; 2],
                [0.0; 2],
            ],
            segment_accel_mps2: [0.0; 4],
            segment_motion: [SegmentMotion::default(); 4],
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
        let mut segment_effects = [[0.0; 2]; 4];
        let mut segment_accel_mps2 = [0.0; 4];
        for (place, segment) in segments.iter().take(4).enumerate() {
            let d = segment.duration_s;
            segment_effects[place] = [d, d * (t - begins_s - d / 2.0)];
            segment_accel_mps2[place] = segment.accel_mps2;
            begins_s += d;
        }
        let segment_motion = Self::segment_motion(segments, area / t);
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
            latched_stroke_m: stroke_m,
            lag_s: 0.0,
            mean_m: area / t,
            velocity_sign_mean: signed_s / t,
            positive_mps2,
            negative_mps2,
            level_effects,
            segment_effects,
            segment_accel_mps2,
            segment_motion,
        })
    }

    /// The planned motion from rest through each of `segments` (at most four), positions about
    /// `mean_m`: each segment integrated exactly, split where its velocity changes sign.
    fn segment_motion(segments: &[CommandSegment], mean_m: f64) -> [SegmentMotion; 4] {
        let mut motion = [SegmentMotion::default(); 4];
        let (mut v, mut x) = (0.0_f64, 0.0_f64);
        for (place, segment) in segments.iter().take(4).enumerate() {
            let (a, d) = (segment.accel_mps2, segment.duration_s);
            if d <= 0.0 {
                continue;
            }
            let end_v = v + a * d;
            // Time with the velocity's sign as at the segment's start, up to a change of sign.
            let turn_s = if v * end_v < 0.0 { -v / a } else { d };
            let start_sign = if v != 0.0 { sign(v) } else { sign(a) };
            let signed_s = start_sign * turn_s + sign(end_v) * (d - turn_s);
            motion[place] = SegmentMotion {
                sign_mean: signed_s / d,
                velocity_mean_mps: v + a * d / 2.0,
                position_mean_m: x + v * d / 2.0 + a * d * d / 6.0 - mean_m,
            };
            x += v * d + a * d * d / 2.0;
            v = end_v;
        }
        motion
    }

    /// The shape of `segments` (the ones it was made from) played through a current loop of lag
    /// `τ = lag_s`, a first-order lag `τ·ȧ + a = u`. In the periodic motion it settles into,
    /// integrating twice gives `v = v_u − τ·a` and `x = x_u − τ·v_u + τ²·a` plus a constant,
    /// with `x_u`, `v_u` the plan's own motion: the plate follows the plan `τ` late, and each
    /// step `Δu` of the command leaves `Δu·τ²/2` on its position. The stroke read `τ` after the
    /// start and after the turn is then the plan's less the steps between: `a·τ²` for the
    /// paper's cycle where the lag settles within each segment, less where it does not. The
    /// mean about the start moves by what those terms add: `−τ·x_u(T)/T + τ²·v_u(T)/T − τ²·a(0)`
    /// (on the paper's cycle, which ends where it starts, `−τ²·a(0)`: the start is in its
    /// return's `+a`, and the plate there stands `τ²·a` above the plan).
    pub fn behind_lag(self, segments: &[CommandSegment], lag_s: f64) -> Self {
        if lag_s.is_nan() || lag_s <= 0.0 || segments.is_empty() {
            return self;
        }
        let start_accel_mps2 = lagged_start_mps2(segments, lag_s);
        let at = |time_s: f64| {
            let (mut begins_s, mut x, mut v, mut lagged) = (0.0, 0.0, 0.0, start_accel_mps2);
            for segment in segments {
                let (u, d) = (segment.accel_mps2, segment.duration_s);
                let s = (time_s - begins_s).clamp(0.0, d);
                let decay = libm::exp(-s / lag_s);
                let (x_s, v_s) = (x + v * s + u * s * s / 2.0, v + u * s);
                let lagged_s = u + (lagged - u) * decay;
                if time_s <= begins_s + d {
                    return x_s - lag_s * v_s + lag_s * lag_s * lagged_s;
                }
                (x, v, lagged) = (x_s, v_s, lagged_s);
                begins_s += d;
            }
            x - lag_s * v + lag_s * lag_s * lagged
        };
        let (mut end_x, mut end_v) = (0.0, 0.0);
        for segment in segments {
            let (u, d) = (segment.accel_mps2, segment.duration_s);
            end_x += end_v * d + u * d * d / 2.0;
            end_v += u * d;
        }
        let moved_m = (-lag_s * end_x + lag_s * lag_s * end_v) / self.period_s
            - lag_s * lag_s * start_accel_mps2;
        CycleShape {
            latched_stroke_m: at(self.turn_s + lag_s) - at(lag_s),
            lag_s,
            mean_m: self.mean_m + moved_m,
            ..self
        }
    }
}
