//! The plate the drive's lag and the slide make of a cycle's plan, integrated through one
//! periodic cycle: the lag exact at every step, the slide's forces by the step's start (a change
//! of the velocity's sign placed inside its step), the feedforward of each segment on top, and a
//! bias and a start velocity, as the loop's centring applies them, that make the motion periodic
//! and free of drift.

use libm::exp;

use crate::closed_loop::identify::Identified;
use crate::closed_loop::shape::{
    lagged_start_mps2, sign, CommandSegment, CycleShape, SegmentMotion,
};

/// Steps of the integration per cycle: the feed's amplitude found is within 3·10⁻⁴ of 4000
/// steps' at 150 Hz of bandwidth, 50–100 Hz and d = 0.53–0.61, and a mount's cycle within 0.1 %
/// of the stroke of a fine integration's.
pub const STEPS_PER_CYCLE: usize = 250;

/// What moves the plate besides the command: the drive's lag and the slide, each force over
/// the moving mass.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlateModel {
    pub lag_s: f64,
    pub coulomb_mps2: f64,
    pub viscous_per_s: f64,
    pub spring_per_s2: f64,
}

impl PlateModel {
    /// The ideal plate: it follows the plan.
    pub const IDEAL: PlateModel = PlateModel {
        lag_s: 0.0,
        coulomb_mps2: 0.0,
        viscous_per_s: 0.0,
        spring_per_s2: 0.0,
    };

    /// The plate of an identified drive.
    pub fn of(drive: &Identified) -> Self {
        PlateModel {
            lag_s: drive.lag_s,
            coulomb_mps2: drive.coulomb_mps2,
            viscous_per_s: drive.viscous_per_s,
            spring_per_s2: drive.spring_per_s2,
        }
    }
}

/// The plate's periodic motion through one cycle of `segments` on a plate model, with the
/// slide's forces fed forward segment by segment.
#[derive(Debug, Clone, Copy)]
pub(super) struct PlateCycle<'a> {
    segments: &'a [CommandSegment],
    model: PlateModel,
    /// The lag's output at the cycle's start, periodic.
    start_accel_mps2: f64,
    /// The plate's position at the start, about the cycle's mean.
    start_m: f64,
    /// The slide's feedforward in each segment, and the bias that keeps the velocity periodic.
    feedforward_mps2: [f64; 4],
    bias_mps2: f64,
    /// What the start's velocity has beside the lag's: the plate does not drift.
    start_shift_mps: f64,
    /// The plan's turn (the stroke's far end).
    turn_s: f64,
}

impl<'a> PlateCycle<'a> {
    pub(super) fn new(segments: &'a [CommandSegment], model: PlateModel) -> Self {
        let lag_s = if model.lag_s > 0.0 { model.lag_s } else { 0.0 };
        let shape = CycleShape::new(segments);
        let motion = shape.map_or([SegmentMotion::default(); 4], |shape| shape.segment_motion);
        let feedforward_mps2 = motion
            .map(|m| m.slide_mps2(model.coulomb_mps2, model.viscous_per_s, model.spring_per_s2));
        // The feedforward is part of the command: it goes through the lag with the plan's level.
        let mut commanded = [CommandSegment {
            duration_s: 0.0,
            accel_mps2: 0.0,
        }; 4];
        let count = segments.len().min(4);
        for ((commanded, segment), fed_mps2) in
            commanded.iter_mut().zip(segments).zip(feedforward_mps2)
        {
            *commanded = CommandSegment {
                accel_mps2: segment.accel_mps2 + fed_mps2,
                ..*segment
            };
        }
        let mut cycle = PlateCycle {
            segments,
            model: PlateModel { lag_s, ..model },
            start_accel_mps2: if lag_s > 0.0 {
                lagged_start_mps2(&commanded[..count], lag_s)
            } else {
                commanded[..count].first().map_or(0.0, |s| s.accel_mps2)
            },
            start_m: shape.map_or(0.0, |shape| -shape.mean_m),
            feedforward_mps2,
            bias_mps2: 0.0,
            start_shift_mps: 0.0,
            turn_s: shape.map_or(0.0, |shape| shape.turn_s),
        };
        // The centring's bias and the start's velocity: the velocity periodic, and no drift
        // (the loop keeps the plate's mean at the centre). Exact in one round without a slide;
        // with one, the second takes up what the slide's forces make of the first's change.
        let period_s = cycle.period_s();
        if model.spring_per_s2 > 0.0 {
            cycle.centre_on_mount();
            return cycle;
        }
        let slide = model.coulomb_mps2 != 0.0 || model.viscous_per_s != 0.0;
        for _ in 0..if slide { 2 } else { 1 } {
            let (mut end_v, mut end_m) = (cycle.start_velocity_mps(), cycle.start_m);
            cycle.for_each_step(|_, v, _, x| (end_v, end_m) = (v, x));
            cycle.bias_mps2 -= (end_v - cycle.start_velocity_mps()) / period_s;
            cycle.start_shift_mps -= (end_m - cycle.start_m) / period_s;
        }
        cycle
    }

    /// On a mount the spring pulls by where the plate is, and a velocity added at the start
    /// swings it rather than moving it along: the start's position and velocity and the bias
    /// are found together, the motion periodic and its mean at the centre, by Newton steps on
    /// the cycle's map (linear but for the slide's friction turning with the velocity: its
    /// Jacobian is taken once, by a step of each).
    fn centre_on_mount(&mut self) {
        const STEPS: usize = 3;
        let scale = [1e-4, 1e-2, 1.0];
        let residual = |cycle: &PlateCycle<'_>| {
            let period_s = cycle.period_s();
            let (mut end_v, mut end_m, mut mean_m) =
                (cycle.start_velocity_mps(), cycle.start_m, 0.0);
            cycle.for_each_step(|h, v, _, x| {
                (end_v, end_m) = (v, x);
                mean_m += x * h / period_s;
            });
            [
                end_m - cycle.start_m,
                end_v - cycle.start_velocity_mps(),
                mean_m,
            ]
        };
        let moved = |cycle: &PlateCycle<'a>, by: [f64; 3]| PlateCycle {
            start_m: cycle.start_m + by[0],
            start_shift_mps: cycle.start_shift_mps + by[1],
            bias_mps2: cycle.bias_mps2 + by[2],
            ..*cycle
        };
        let at = residual(self);
        let mut jacobian = [[0.0; 3]; 3];
        for (column, step) in scale.iter().enumerate() {
            let mut by = [0.0; 3];
            by[column] = *step;
            let stepped = residual(&moved(self, by));
            for row in 0..3 {
                jacobian[row][column] = (stepped[row] - at[row]) / step;
            }
        }
        let mut now = at;
        for _ in 0..STEPS {
            let Some(step) = solve(jacobian, now.map(|r| -r)) else {
                return;
            };
            *self = moved(self, step);
            now = residual(self);
        }
    }

    pub(super) fn period_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
    }

    /// The plate's velocity at the cycle's start: `v_u = 0` there.
    pub(super) fn start_velocity_mps(&self) -> f64 {
        -self.model.lag_s * self.start_accel_mps2 + self.start_shift_mps
    }

    /// Calls `step(h, velocity, acceleration, position)` with the plate's state at the end of
    /// every step of the cycle.
    pub(super) fn for_each_step(&self, mut step: impl FnMut(f64, f64, f64, f64)) {
        let period_s = self.period_s();
        let PlateModel {
            lag_s,
            coulomb_mps2,
            viscous_per_s,
            spring_per_s2,
        } = self.model;
        let (mut lagged, mut v, mut x) = (
            self.start_accel_mps2,
            self.start_velocity_mps(),
            self.start_m,
        );
        for (place, segment) in self.segments.iter().enumerate() {
            let u = segment.accel_mps2 + self.feedforward_mps2.get(place).copied().unwrap_or(0.0);
            let count = libm::ceil(segment.duration_s / period_s * STEPS_PER_CYCLE as f64).max(1.0);
            let h = segment.duration_s / count;
            let decay = if lag_s > 0.0 { exp(-h / lag_s) } else { 0.0 };
            // The lag's output averaged over a step, as a share of its distance from `u`.
            let mean_share = if lag_s > 0.0 {
                (1.0 - decay) * lag_s / h
            } else {
                0.0
            };
            for _ in 0..count as usize {
                let drive = u + (lagged - u) * mean_share;
                lagged = u + (lagged - u) * decay;
                // The drag and the spring at the step's middle, as a first estimate of the
                // step puts it: the step is exact to second order in its length.
                let start_accel = drive + self.bias_mps2
                    - coulomb_mps2 * sign(v)
                    - viscous_per_s * v
                    - spring_per_s2 * x;
                let (middle_v, middle_x) = (v + start_accel * h / 2.0, x + v * h / 2.0);
                let smooth =
                    drive + self.bias_mps2 - viscous_per_s * middle_v - spring_per_s2 * middle_x;
                let mut next_v = v + (smooth - coulomb_mps2 * sign(v)) * h;
                if v * next_v < 0.0 {
                    // The slide's friction turns with the velocity inside the step.
                    let fraction = v / (v - next_v);
                    let signed = sign(v) * fraction + sign(next_v) * (1.0 - fraction);
                    next_v = v + (smooth - coulomb_mps2 * signed) * h;
                }
                let accel = (next_v - v) / h;
                x += (v + next_v) / 2.0 * h;
                v = next_v;
                step(h, v, accel, x);
            }
        }
    }

    /// The stroke read `τ` after the start and `τ` after the plan's turn, as the loop reads it.
    pub(super) fn latched_stroke_m(&self) -> f64 {
        let (start_at, turn_at) = (self.model.lag_s, self.turn_s + self.model.lag_s);
        let (mut t, mut x_prev) = (0.0, self.start_m);
        let (mut start_m, mut turn_m) = (self.start_m, self.start_m);
        self.for_each_step(|h, _, _, x| {
            for (at, read) in [(start_at, &mut start_m), (turn_at, &mut turn_m)] {
                if t <= at && at < t + h {
                    *read = x_prev + (x - x_prev) * (at - t) / h;
                }
            }
            t += h;
            x_prev = x;
        });
        turn_m - start_m
    }

    /// The plate's lowest and highest velocity through the cycle.
    pub(super) fn velocity_range(&self) -> (f64, f64) {
        let start_v = self.start_velocity_mps();
        let (mut low, mut high) = (start_v, start_v);
        self.for_each_step(|_, v, _, _| {
            low = low.min(v);
            high = high.max(v);
        });
        (low, high)
    }
}

/// `x` with `a·x = b` by Cramer's rule; `None` where `a` is singular.
fn solve(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let whole = det(a);
    if whole == 0.0 || !whole.is_finite() {
        return None;
    }
    Some(core::array::from_fn(|column| {
        let mut replaced = a;
        for (row, value) in b.iter().enumerate() {
            replaced[row][column] = *value;
        }
        det(replaced) / whole
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::waveform::{Drive, Limits, Waveform, WaveformSpec};

    /// On a mount, the cycle found is the one the plate settles into: a fine integration of the
    /// same command, lag, slide and spring from rest, run until its swing has died away, starts
    /// its last cycle where the model's starts, and its mean is at the centre.
    #[test]
    fn on_a_mount_the_cycle_is_the_one_the_plate_settles_into() {
        for (frequency_hz, duty, spring_per_s2, viscous_per_s, coulomb_mps2, lag_s) in [
            (50.0, 0.53, 1.3e4, 15.0, 3.0, 3e-4),
            (50.0, 0.61, 2.2e4, 8.0, 4.5, 5e-4),
            (100.0, 0.53, 3.2e4, 25.0, 0.0, 2e-4),
        ] {
            let spec = WaveformSpec::from_frequency(
                frequency_hz,
                duty,
                Drive::Accel { accel_mps2: 140.0 },
            );
            let waveform = Waveform::new(spec, &Limits::NONE).unwrap();
            let segments = CommandSegment::cycle_of(&waveform);
            let model = PlateModel {
                lag_s,
                coulomb_mps2,
                viscous_per_s,
                spring_per_s2,
            };
            let cycle = PlateCycle::new(&segments, model);
            let steps = 20_000;
            let period_s = cycle.period_s();
            let dt = period_s / f64::from(steps);
            let command = |t: f64| {
                let mut end = 0.0;
                for (place, segment) in segments.iter().enumerate() {
                    end += segment.duration_s;
                    if t < end {
                        return segment.accel_mps2 + cycle.feedforward_mps2[place];
                    }
                }
                segments[3].accel_mps2 + cycle.feedforward_mps2[3]
            };
            let (mut a, mut v, mut x) = (0.0_f64, 0.0_f64, 0.0_f64);
            let (mut start, mut mean_m) = ((0.0, 0.0), 0.0);
            for round in 0..400 {
                if round == 399 {
                    start = (x, v);
                }
                for k in 0..steps {
                    let t = (f64::from(k) + 0.5) * dt;
                    a = command(t) + (a - command(t)) * libm::exp(-dt / lag_s);
                    let friction = if v == 0.0 {
                        0.0
                    } else {
                        coulomb_mps2 * v.signum()
                    };
                    let accel =
                        a + cycle.bias_mps2 - viscous_per_s * v - spring_per_s2 * x - friction;
                    v += accel * dt;
                    x += v * dt;
                    if round == 399 {
                        mean_m += x / f64::from(steps);
                    }
                }
            }
            let stroke_m = waveform.stroke_m;
            assert!(
                (start.0 - cycle.start_m).abs() < 2e-3 * stroke_m,
                "{frequency_hz} Hz: starts at {} m, the model at {} m",
                start.0,
                cycle.start_m
            );
            assert!(
                (start.1 - cycle.start_velocity_mps()).abs() < 2e-3 * stroke_m / period_s,
                "{frequency_hz} Hz: {} m/s against {} m/s",
                start.1,
                cycle.start_velocity_mps()
            );
            assert!(
                mean_m.abs() < 2e-3 * stroke_m,
                "{frequency_hz} Hz: mean {mean_m} m"
            );
        }
    }
}
