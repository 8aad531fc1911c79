//! The cycle-rate loop: at every cycle boundary, from the plate positions sampled at the
//! cycle's start tick and at its turning tick, the trims of the next cycle's levels.
//!
//! The command of the next cycle's segment `k` is `+a·s₊·m + b + f_k`, `b + f_k` or
//! `−a·s₋·m + b + f_k` as its plan is `+a`, zero or `−a`. Feedforward from the identification:
//! `s± = 1/ĝ±` undo the drive's gains, the bias `b` holds `−ê` against its zero offset, and `f_k`
//! the slide's Coulomb and viscous friction and spring over the segment's planned motion
//! ([`SegmentMotion::slide_mps2`]). Feedback: `m` is integral action on the stroke of
//! full-amplitude cycles (latched `τ` after the start and after the turn, less the drift between
//! two starts), held where the plate at the feed's amplitude shows it ([`super::feed`]), and the
//! centring correction `δ` is added to `b`.
//!
//! Centring. Over a cycle a constant `δ` moves a free plate `δ·T²/2` and changes its velocity
//! by `δ·T`; in units of `ũ = δ·T²/2` the cycle-start position `x` and `w = T·v` obey
//! `x⁺ = x + w + ũ + d`, `w⁺ = w + 2(ũ + d)` with `d` what the feedforward leaves. A centring
//! spring and viscous friction turn and damp the plate's deviation from its plan within the
//! cycle: in general `s⁺ = Φ·s + Γ·(ũ + d)` about the plan's reference ([`CycleMap`], the free
//! plate's `Φ = [[1, 1], [0, 1]]`, `Γ = (1, 2)`). The correction decided at boundary `k` runs in
//! cycle `k + 1`, so the loop estimates `d` from three starts (for a free plate the second
//! difference, `x_k − 2x_{k−1} + x_{k−2} = ũ_{k−1} + ũ_{k−2} + d_{k−1} + d_{k−2}`;
//! [`CycleMap::second_difference_weights`] in general), taken by [`Disturbance`], which tells an
//! offset from a gain error that grows with the levels; it reconstructs `w_k`, predicts the
//! state at `k + 1`, cancels `d̂` and places both poles of the prediction at 0.3 for a free
//! plate (`ũ = −0.245·x − 0.5775·w − d̂`), a mount's at its own angle and a radius up to 0.7
//! ([`CycleMap::gains`]). The target is each
//! cycle's mean position at the centre: a start at `−mean − w/2`, known two cycles ahead, so a
//! soft start or a new plan moves the target and the loop follows it at its speed. The plan's
//! mean is not quite the plate's (the current loop and friction round every segment): the mean
//! measured from positions latched through each full-amplitude cycle moves the target by 0.05 of
//! its error a cycle, and a spring's pull at a target so moved is held by `κ·x*`. On the
//! per-cycle linear model the loop is stable for a drive gain from 0.5 to 1.25 times the
//! identified one (`shared/tests/closed_loop.rs`), far wider than the identification's error.

mod limits;
mod scale;
mod trims;

pub use limits::{LoopError, LoopLimits};
pub use trims::{Stroke, Trims};

use libm::fabs;

use scale::Scale;

use super::cycle_map::CycleMap;
use super::disturbance::Disturbance;
use super::feed::FeedCompensation;
use super::identify::Identified;
use super::shape::{CommandSegment, CycleShape, SegmentMotion};

/// Both poles of the centring loop on a free plate ([`CycleMap::gains`]).
const POLE: f64 = 0.3;
/// The mean's offset moves by this fraction of each measured mean.
const MEAN_GAIN: f64 = 0.05;
/// The amplitude trim moves by this fraction of the relative stroke error each cycle.
const AMPLITUDE_GAIN: f64 = 0.3;
/// The share of the slide fed forward rises by this a cycle after a new drive.
const SLIDE_STEP: f64 = 0.05;

/// What a cycle's trims add to the plate by its end, in the loop's units: position `x`, and
/// `w = T·v`. A bias `δ` adds `x = δ·T²/2` and `w = δ·T²`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Input {
    x_m: f64,
    w_m: f64,
}

impl Input {
    const NONE: Input = Input { x_m: 0.0, w_m: 0.0 };
}

/// The cycle-rate loop's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleLoop {
    feedforward: Trims,
    /// The identified slide: Coulomb friction `F_c/M`, viscous friction `b/M` and a spring
    /// `k/M`, fed forward segment by segment through the planned motion.
    slide: [f64; 3],
    /// How much of the slide is fed forward: it rises by [`SLIDE_STEP`] a cycle after a new
    /// drive, so that the disturbance estimate, made without it, follows.
    slide_share: f64,
    /// The identified current loop's lag: the plan's strokes are read behind it.
    lag_s: f64,
    /// How the plate's deviation from the plan moves over a cycle (the spring and viscous
    /// friction act on it in full, fed forward or not), its period, and the gains that place
    /// the loop's poles on it.
    map: CycleMap,
    map_period_s: f64,
    gains: [f64; 2],
    limits: LoopLimits,
    amplitude: f64,
    /// The factor on the levels (the feed's amplitude and the excitation): the trim's range is
    /// about it, and the plate's motion is the plan's times it, its stroke times
    /// `stroke_factor` more ([`CycleLoop::plan`]).
    scale: Scale,
    stroke_factor: f64,
    /// What the trims of the cycle running now, of the one before and of the one before that
    /// add to the plate (in the loop's units), and the previous start position.
    running: Input,
    previous: Input,
    earlier: Input,
    previous_x_m: Option<f64>,
    /// The start before the previous one.
    earlier_x_m: Option<f64>,
    /// The plate rests at the next start (after a settle): that start gives its velocity too.
    at_rest: bool,
    /// The plans of the cycles that began at those two starts.
    previous_shape: Option<CycleShape>,
    earlier_shape: Option<CycleShape>,
    /// What the feedforward leaves, estimated so far.
    disturbance: Disturbance,
    /// How far the plate's measured mean has stood from the plan's: the targets move by it.
    mean_offset_m: f64,
    /// The output's smallest step of a level (0: continuous): the bias is rounded to it, and
    /// the correction the loop counts is the one the rounded bias applies.
    level_step_mps2: f64,
    trims: Trims,
}

impl CycleLoop {
    /// A loop that starts from the identified drive: its gains undone, its offset cancelled.
    pub fn new(identified: &Identified, limits: LoopLimits) -> Self {
        let feedforward = Trims {
            positive: 1.0 / identified.gain_positive,
            negative: 1.0 / identified.gain_negative,
            bias_mps2: -identified.offset_mps2,
            segments_mps2: [0.0; 4],
        };
        CycleLoop {
            feedforward,
            slide: [
                identified.coulomb_mps2,
                identified.viscous_per_s,
                identified.spring_per_s2,
            ],
            slide_share: 1.0,
            lag_s: identified.lag_s,
            map: CycleMap::FREE,
            map_period_s: 0.0,
            gains: [0.0; 2],
            limits,
            amplitude: 1.0,
            scale: Scale::ONE,
            stroke_factor: 1.0,
            running: Input::NONE,
            previous: Input::NONE,
            earlier: Input::NONE,
            previous_x_m: None,
            earlier_x_m: None,
            at_rest: false,
            previous_shape: None,
            earlier_shape: None,
            disturbance: Disturbance::new(),
            mean_offset_m: 0.0,
            level_step_mps2: 0.0,
            trims: feedforward,
        }
    }

    /// A loop for an output whose levels move in steps of `level_step_mps2` (a DAC's counts):
    /// the bias is rounded to a whole step, so that every level of a cycle carries the same
    /// bias error, and the loop counts the correction the rounded bias applies.
    pub fn with_level_step(self, level_step_mps2: f64) -> Self {
        CycleLoop {
            level_step_mps2: if level_step_mps2.is_finite() && level_step_mps2 > 0.0 {
                level_step_mps2
            } else {
                0.0
            },
            ..self
        }
    }

    /// The trims of a cycle of `shape` with its `±a` levels scaled by `positive` and `negative`,
    /// `bias_mps2` added to every segment and `slide_mps2` to each in its place, each segment's
    /// level rounded to the output's step, down or up, whichever way leaves the plate least off
    /// by the cycle's end; with what that rounding adds. The segments' choices together move
    /// the plate several times finer than one step.
    fn rounded_trims(
        &self,
        shape: &CycleShape,
        positive: f64,
        negative: f64,
        bias_mps2: f64,
        slide_mps2: [f64; 4],
    ) -> (Trims, Input) {
        let exact = Trims {
            positive,
            negative,
            bias_mps2,
            segments_mps2: slide_mps2,
        };
        let step = self.level_step_mps2;
        if step <= 0.0 || shape.period_s <= 0.0 {
            return (exact, Input::NONE);
        }
        let levels: [f64; 4] =
            core::array::from_fn(|place| exact.level(place, shape.segment_accel_mps2[place]));
        let floors = levels.map(|level| libm::floor(level / step) * step);
        let mut best = (f64::INFINITY, levels, Input::NONE);
        for choice in 0..16 {
            let mut rounded = floors;
            let mut added = Input::NONE;
            for place in 0..4 {
                if choice >> place & 1 == 1 {
                    rounded[place] += step;
                }
                let error = rounded[place] - levels[place];
                let [velocity_s, position_s2] = shape.segment_effects[place];
                added.x_m += error * position_s2;
                added.w_m += error * velocity_s * shape.period_s;
            }
            let size = added.x_m * added.x_m + added.w_m * added.w_m;
            if size < best.0 {
                best = (size, rounded, added);
            }
        }
        let (rounded, added) = (best.1, best.2);
        let trims = Trims {
            segments_mps2: core::array::from_fn(|place| {
                slide_mps2[place] + rounded[place] - levels[place]
            }),
            ..exact
        };
        (trims, added)
    }

    /// What each segment of a cycle of `shape` adds to `bias_mps2` so that the bias and the
    /// slide's forces `slide_mps2` reach the plate as planned: the drive multiplies the whole
    /// command by the gain of its sign, so both are divided by it as the `±a` levels are (a
    /// zero level's by the sign of what it carries).
    fn through_gains(&self, shape: &CycleShape, bias_mps2: f64, slide_mps2: [f64; 4]) -> [f64; 4] {
        core::array::from_fn(|place| {
            let carried_mps2 = bias_mps2 + slide_mps2[place];
            let planned_mps2 = shape.segment_accel_mps2[place];
            let positive = if planned_mps2 == 0.0 {
                carried_mps2 >= 0.0
            } else {
                planned_mps2 > 0.0
            };
            let undo = if positive {
                self.feedforward.positive
            } else {
                self.feedforward.negative
            };
            carried_mps2 * undo - bias_mps2
        })
    }

    /// The cycle map and its gains for cycles of `period_s`, made afresh where the period or the
    /// drive changed.
    fn refresh_map(&mut self, period_s: f64) -> Result<(), LoopError> {
        if self.map_period_s == period_s {
            return Ok(());
        }
        let [_, viscous_per_s, spring_per_s2] = self.slide;
        let map = CycleMap::new(spring_per_s2, viscous_per_s, period_s);
        self.gains = map.gains(POLE).ok_or(LoopError::Unsteerable {
            spring_per_s2,
            period_s,
        })?;
        self.map = map;
        self.map_period_s = period_s;
        Ok(())
    }

    /// `bias_mps2` to the output's step.
    fn rounded(&self, bias_mps2: f64) -> f64 {
        if self.level_step_mps2 > 0.0 {
            libm::round(bias_mps2 / self.level_step_mps2) * self.level_step_mps2
        } else {
            bias_mps2
        }
    }

    /// The trims that undo the drive alone: its gains and offset.
    pub fn feedforward(&self) -> Trims {
        Trims {
            bias_mps2: self.rounded(self.feedforward.bias_mps2),
            ..self.feedforward
        }
    }

    /// Goes on with another drive (the identified one after the settle's): its gains, offset
    /// and friction fed forward from the next update on. The disturbance estimate goes on too:
    /// the settle's drive is close to the identified one, so what the old feedforward left is
    /// the better start for what the new one leaves.
    pub fn set_drive(&mut self, identified: &Identified) {
        let other = CycleLoop::new(identified, self.limits);
        self.feedforward = other.feedforward;
        self.slide = other.slide;
        self.slide_share = 0.0;
        self.lag_s = other.lag_s;
        self.map_period_s = 0.0;
        self.disturbance.forget_gain();
    }

    /// Goes on toward the amplitude that gives the ideal plate's feed on the identified plate
    /// ([`super::feed`]), 0.5 % a cycle from the next update on, so that the plate's
    /// mean moves as gently as in a soft start; the trim moves with it, and the stroke is held
    /// where that plate shows it.
    pub fn set_feed(&mut self, found: &FeedCompensation) {
        if found.amplitude.is_finite() && found.amplitude > 0.0 && found.stroke_factor > 0.0 {
            self.scale.feed_target = found.amplitude;
            self.stroke_factor = found.stroke_factor;
        }
    }

    /// Holds against the drive as the settle found it: a zero offset `offset_mps2`, gains
    /// `1 ± gain_half_difference` (their mean is left to the stroke's trim) and a centring
    /// spring `spring_per_s2`, fed forward as the identified one is.
    pub fn hold_drive(&mut self, offset_mps2: f64, gain_half_difference: f64, spring_per_s2: f64) {
        self.feedforward = Trims {
            positive: 1.0 / (1.0 + gain_half_difference),
            negative: 1.0 / (1.0 - gain_half_difference),
            bias_mps2: -offset_mps2,
            segments_mps2: [0.0; 4],
        };
        self.trims = self.feedforward();
        self.slide = [0.0, 0.0, spring_per_s2];
        self.slide_share = 0.0;
        self.map_period_s = 0.0;
    }

    /// Forgets the cycle starts seen so far: the next [`CycleLoop::update`] takes its position
    /// only, as the first one does. For the cycle after an idle period, which ran the
    /// feedforward instead of the last correction decided.
    pub fn restart(&mut self) {
        self.running = Input::NONE;
        self.previous = Input::NONE;
        self.earlier = Input::NONE;
        self.previous_x_m = None;
        self.earlier_x_m = None;
        self.at_rest = false;
        self.previous_shape = None;
        self.earlier_shape = None;
        self.trims = self.feedforward();
    }

    /// [`CycleLoop::restart`] where the plate rests at the next start (a settle held it there):
    /// that start gives its velocity too, so the loop decides from it on.
    pub fn restart_at_rest(&mut self) {
        self.restart();
        self.at_rest = true;
    }

    /// Scales the levels by a factor that rises to `peak` and falls back to 1, 0.05
    /// a cycle, once the slide is fed forward in full: what the feedforward leaves then shows
    /// at two levels, so that the disturbance estimate tells the part that grows with the
    /// levels (a gain's error) from the part that does not, before a soft start raises them.
    pub fn excite(&mut self, peak: f64) {
        if peak.is_finite() && peak > 1.0 {
            self.scale.excitation_peak = Some(peak);
        }
    }

    /// Whether an excitation is under way ([`CycleLoop::excite`]).
    pub fn exciting(&self) -> bool {
        self.scale.excitation_peak.is_some() || self.scale.excitation != 1.0
    }

    /// The scale `cycles` boundaries on: the slide's share rises as the scale steps.
    fn scale_ahead(&self, cycles: u32) -> Scale {
        let mut scale = self.scale;
        let mut share = self.slide_share;
        for _ in 0..cycles {
            scale = scale.stepped(share >= 1.0);
            share = (share + SLIDE_STEP).min(1.0);
        }
        scale
    }

    /// The plan of a cycle of `segments` as the loop aims at it: its shape, with its stroke as
    /// read behind the identified current loop, and its motion (mean, stroke, each segment's)
    /// and its `±a` levels as the plate makes them at the amplitude the feed needs
    /// ([`CycleLoop::set_feed`]) and the excitation's. Its segments' levels stay the plan's:
    /// the trims scale those.
    pub fn plan(&self, segments: &[CommandSegment]) -> Option<CycleShape> {
        self.plan_ahead(segments, 0)
    }

    /// [`CycleLoop::plan`] for the cycle `cycles` after the one beginning at the next
    /// boundary: at the scale it will run at.
    pub fn plan_ahead(&self, segments: &[CommandSegment], cycles: u32) -> Option<CycleShape> {
        let shape = CycleShape::new(segments)?.behind_lag(segments, self.lag_s);
        let scale = self.scale_ahead(cycles).factor();
        Some(CycleShape {
            positive_mps2: shape.positive_mps2 * scale,
            negative_mps2: shape.negative_mps2 * scale,
            mean_m: shape.mean_m * scale,
            latched_stroke_m: shape.latched_stroke_m * scale * self.stroke_factor,
            segment_motion: shape.segment_motion.map(|motion| SegmentMotion {
                velocity_mean_mps: motion.velocity_mean_mps * scale,
                position_mean_m: motion.position_mean_m * scale,
                ..motion
            }),
            ..shape
        })
    }

    /// The trims for the cycle that starts now (decided at the previous boundary).
    pub fn trims(&self) -> Trims {
        self.trims
    }

    /// At a cycle boundary: `start_m` latched at the start tick of the cycle beginning now,
    /// whose plan is `shape`, the stroke and the mean position (from positions latched through
    /// it) of the cycle that just ended (`None` where not measured), and the planned mean displacements of the next two cycles
    /// (`next`); the trims returned are for the first of them. The loop centres each
    /// cycle's mean position: its start target is `−mean`, so a target that moves (a soft start,
    /// a new plan) is known two cycles ahead and followed at the speed it moves.
    pub fn update(
        &mut self,
        start_m: f64,
        stroke: Option<Stroke>,
        measured_mean_m: Option<f64>,
        shape: &CycleShape,
        next: [&CycleShape; 2],
    ) -> Result<Trims, LoopError> {
        let stroke_valid = stroke.is_none_or(|s| s.measured_m.is_finite());
        if !start_m.is_finite() || !stroke_valid || measured_mean_m.is_some_and(|m| !m.is_finite())
        {
            return Err(LoopError::Sensor);
        }
        let error_m = start_m + shape.mean_m;
        if fabs(error_m) > self.limits.position_error_max_m {
            return Err(LoopError::Position { error_m });
        }
        let mut amplitude = self.amplitude;
        if let Some(stroke) = stroke {
            if stroke.planned_m > 0.0 {
                amplitude -=
                    AMPLITUDE_GAIN * amplitude * (stroke.measured_m / stroke.planned_m - 1.0);
            }
        }
        if fabs(amplitude / self.scale.factor() - 1.0) > self.limits.amplitude_max {
            return Err(LoopError::Amplitude { amplitude });
        }
        // `w = T·v` at this start, from the last two starts and the correction between them;
        // the first start only gives the position, and the next cycle runs the feedforward.
        if core::mem::take(&mut self.at_rest) {
            // At rest: as if the plate had stood here through a cycle without command.
            // Its reference where it stands: the spring's pull the settle held is the bias's.
            self.previous_x_m = Some(start_m);
            self.previous_shape = Some(CycleShape {
                mean_m: -start_m,
                ..CycleShape::idle(shape.period_s)
            });
        }
        let (Some(previous_x_m), Some(previous_shape)) = (self.previous_x_m, self.previous_shape)
        else {
            self.previous_x_m = Some(start_m);
            self.previous_shape = Some(*shape);
            self.amplitude = amplitude;
            return Ok(self.trims);
        };
        // The cycle after next runs its levels at the next step of the scale: the plan of the
        // cycle beginning now was made at the scale its trims were decided at.
        let before = self.scale.factor();
        let scale = self.scale.stepped(self.slide_share >= 1.0);
        amplitude *= scale.factor() / before;
        // What the feedforward leaves adds `d` to every `ũ`: the second difference of the starts
        // is `ũ_{k−1} + ũ_{k−2} + d_{k−1} + d_{k−2}`.
        self.refresh_map(shape.period_s)?;
        let map = self.map;
        let [[p00, p01], [p10, p11]] = map.phi;
        // Each start's deviation from its own cycle's reference (`ε`, the reference starting at
        // `−mean`) and the arrival's from the cycle before's (`y`).
        let previous_deviation_m = previous_x_m + previous_shape.mean_m;
        let arrival_m = start_m + previous_shape.mean_m;
        let mut disturbance = self.disturbance;
        if let (Some(earlier_x_m), Some(earlier_shape)) = (self.earlier_x_m, self.earlier_shape) {
            let [late, early] = map.second_difference_weights();
            let measured = (arrival_m
                - p00 * previous_deviation_m
                - p11 * (previous_x_m + earlier_shape.mean_m)
                + map.determinant() * (earlier_x_m + earlier_shape.mean_m)
                - self.previous.x_m
                + p11 * self.earlier.x_m
                - p01 * self.earlier.w_m)
                / (late + early);
            disturbance.measure(measured, [&previous_shape, &earlier_shape]);
        }
        let previous_d = disturbance.of(&previous_shape);
        let previous_w = (arrival_m
            - p00 * previous_deviation_m
            - self.previous.x_m
            - map.gamma[0] * previous_d)
            / p01;
        let w = p10 * previous_deviation_m
            + p11 * previous_w
            + self.previous.w_m
            + map.gamma[1] * previous_d;
        // The plan's mean is not quite the plate's: friction and the current loop round every
        // segment. Where the plate's mean is measured, the target moves against its error.
        let mean_offset_m = self.mean_offset_m + MEAN_GAIN * measured_mean_m.unwrap_or(0.0);
        let [next_target_m, after_target_m] = next.map(|shape| -shape.mean_m - mean_offset_m);
        let target_w = after_target_m - next_target_m;
        // A cycle that starts at `x` with `w` has its mean at `x + mean + w/2 + (ũ + d)/3`.
        let now_m = disturbance.of(shape);
        let [moved_x, moved_w] = map.apply([start_m + shape.mean_m, w]);
        let predicted_x = moved_x - shape.mean_m + self.running.x_m + map.gamma[0] * now_m
            - (next_target_m - target_w / 2.0);
        let predicted_w = moved_w + self.running.w_m + map.gamma[1] * now_m - target_w;
        let [position_gain, velocity_gain] = self.gains;
        let half_period_squared = next[0].period_s * next[0].period_s / 2.0;
        // A target off the plan's reference (the measured mean moved it) is held against the
        // spring's pull there: `δ = κ·x*` keeps a deviation `x*` still.
        let held_m = self.slide[2] * (next_target_m + next[0].mean_m) * half_period_squared;
        let correction =
            -position_gain * predicted_x - velocity_gain * predicted_w - disturbance.of(next[0])
                + held_m;
        let correction_mps2 = correction / half_period_squared;
        if fabs(correction_mps2) > self.limits.correction_max_mps2 {
            return Err(LoopError::Correction { correction_mps2 });
        }
        let [coulomb_mps2, viscous_per_s, spring_per_s2] = self.slide.map(|k| k * self.slide_share);
        let slide_mps2 = next[0]
            .segment_motion
            .map(|motion| motion.slide_mps2(coulomb_mps2, viscous_per_s, spring_per_s2));
        let bias_mps2 = self.feedforward.bias_mps2 + correction_mps2;
        let (trims, rounding) = self.rounded_trims(
            next[0],
            self.feedforward.positive * amplitude,
            self.feedforward.negative * amplitude,
            bias_mps2,
            self.through_gains(next[0], bias_mps2, slide_mps2),
        );
        self.amplitude = amplitude;
        self.scale = scale;
        self.mean_offset_m = mean_offset_m;
        self.earlier_x_m = Some(previous_x_m);
        self.previous_x_m = Some(start_m);
        self.earlier_shape = Some(previous_shape);
        self.previous_shape = Some(*shape);
        self.disturbance = disturbance;
        self.earlier = self.previous;
        self.previous = self.running;
        self.running = Input {
            x_m: map.gamma[0] * correction + rounding.x_m,
            w_m: map.gamma[1] * correction + rounding.w_m,
        };
        self.trims = trims;
        self.slide_share = (self.slide_share + SLIDE_STEP).min(1.0);
        Ok(self.trims)
    }
}
