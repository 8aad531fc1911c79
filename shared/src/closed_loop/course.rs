//! The closed loop's course from the first start to feeding, one state machine for the firmware
//! and the simulator:
//!
//! 1. **Probe**: the scheduler holds its soft start at a low step. The cycle-rate loop runs from
//!    the first held cycle on a nominal drive (gains 1, no offset, no friction), so that an
//!    unknown offset cannot walk the plate away; the positions sampled through the first
//!    `probe_cycles` cycles and the levels they were commanded are kept ([`Probe`]).
//! 2. **Identify**: held cycles go on, still on the nominal drive, while the drive is identified
//!    from the probe ([`Probe::identify`], long: the firmware runs it below the loop) and handed
//!    back ([`Course::set_identified`]).
//! 3. **Centre**: the loop, now on the identified drive, trims held cycles until the plate has
//!    started `centred_cycles` of them in a row within `centred_m` of where it should.
//! 4. **Feed**: the hold is released, the soft start goes on from the held step, and the loop
//!    trims every cycle from then on.
//!
//! At every cycle or idle period that begins, [`Course::boundary`] takes the segment begun, the
//! scheduler right after it (a copy: the plans of the cycles ahead), the position sampled at its
//! start tick and the positions sampled at a fixed interval since the previous start. It returns
//! the trims of the next cycle and whether the hold ends. The caller applies both at the next
//! segment it begins: the firmware decides below the edge path, so the decision is there at the
//! earliest then, and the simulator applies it at the same point. The cycle after an idle period
//! was made before its trims were decided: it runs the feedforward alone
//! ([`Course::feedforward`]), and the loop starts its history afresh from its start.

use super::cycle_loop::{CycleLoop, LoopError, LoopLimits, Stroke, Trims};
use super::envelope::Cause;
use super::identify::{identify, Identified, IdentifyError, IdentifyLimits, Latch};
use super::shape::{CommandSegment, CycleShape};
use crate::scheduler::{Scheduler, Segment};
use crate::segment::SegmentKind;

/// The most positions a probe keeps (the identification takes at most 512).
pub const PROBE_POSITIONS_MAX: usize = 512;
/// The most probe cycles.
pub const PROBE_CYCLES_MAX: u32 = 8;
/// The most segments in the probe's cycles.
const PROBE_SEGMENTS_MAX: usize = 4 * PROBE_CYCLES_MAX as usize;

/// A plate position sampled at a tick of the output's timeline.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PositionSample {
    pub tick: u64,
    pub position_m: f64,
}

/// How the course runs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CourseConfig {
    /// Held cycles the probe keeps (1 to [`PROBE_CYCLES_MAX`]).
    pub probe_cycles: u32,
    /// The held step as a fraction of the soft start's steps (at least one step).
    pub probe_fraction: f64,
    /// The position sensor's resolution: the probe must move the plate 20 of them.
    pub resolution_m: f64,
    /// The plate counts as centred within this of where a cycle should start …
    pub centred_m: f64,
    /// … for this many held cycles in a row.
    pub centred_cycles: u32,
    /// Centring that takes more held cycles than this fails.
    pub centring_cycles_max: u32,
    pub loop_limits: LoopLimits,
    /// The output's smallest step of a level (a DAC count), 0 for a continuous one
    /// ([`CycleLoop::with_level_step`]).
    pub level_step_mps2: f64,
}

impl CourseConfig {
    /// 4 probe cycles at 30 % of the levels; centred within 25 µm for 3 cycles, in at most 250
    /// cycles; the loop may add up to 50 m/s² (a quarter of the envelope's full scale: a spring
    /// or slide friction at its limit needs that much), trim the stroke by ±20 % and gives up
    /// 4 mm from centre; levels in steps of `level_step_mps2`.
    pub fn new(resolution_m: f64, level_step_mps2: f64) -> Self {
        CourseConfig {
            probe_cycles: 4,
            probe_fraction: 0.3,
            resolution_m,
            centred_m: 25e-6,
            centred_cycles: 3,
            centring_cycles_max: 250,
            loop_limits: LoopLimits {
                correction_max_mps2: 50.0,
                amplitude_max: 0.2,
                position_error_max_m: 4e-3,
            },
            level_step_mps2,
        }
    }

    /// The held step of a soft start of `ramp_steps` steps.
    pub fn probe_step(&self, ramp_steps: u16) -> u16 {
        let step = libm::round(self.probe_fraction * f64::from(ramp_steps));
        (step as u16).clamp(1, ramp_steps.max(1))
    }
}

/// Where the course is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Waiting for the first held cycle.
    Waiting,
    /// Keeping the positions of the probe's cycles.
    Probing,
    /// The probe complete, waiting for [`Course::set_identified`].
    Identifying,
    /// Held cycles, trimmed on the identified drive, until the plate is centred.
    Centring,
    /// The soft start released; every cycle trimmed.
    Feeding,
    /// The course stopped with an error; only a new course helps.
    Failed,
}

impl Stage {
    /// The stage's name in replies and logs.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Waiting => "waiting",
            Stage::Probing => "probing",
            Stage::Identifying => "identifying",
            Stage::Centring => "centring",
            Stage::Feeding => "feeding",
            Stage::Failed => "failed",
        }
    }
}

/// What the closed loop reports (the console's `status`): where the course is and, once
/// identified, the drive.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopReport {
    pub stage: Stage,
    pub drive: Option<Identified>,
}

/// The course's decision at a boundary.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decision {
    /// The cycle these trims are for: the one after the cycle begun.
    pub cycle: u64,
    pub trims: Trims,
    /// The plate is centred: release the scheduler's hold ([`Scheduler::release_hold`]).
    pub release: bool,
    /// The probe is complete: identify the drive from [`Course::probe`].
    pub identify: bool,
}

impl Decision {
    /// `trims` for the cycle after the one `begun` starts, nothing else.
    fn trims(begun: &Segment, trims: Trims) -> Self {
        Decision {
            cycle: begun.cycle + 1,
            trims,
            release: false,
            identify: false,
        }
    }
}

/// The trims each cycle runs, as the output takes them (the firmware's control loop and the
/// simulator both): a decision is taken at the segment after the boundary that made it, and a
/// cycle's trims are fixed when its first segment is made. That is the cycle's decided trims;
/// after an idle period, whose first segment was made before the decision, the feedforward. An
/// idle period runs the plan's zero level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleTrims {
    decided: Option<(u64, Trims)>,
    feedforward: Trims,
}

/// A running cycle that follows a running cycle has no trims decided for it: the closed loop
/// did not keep up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LateTrims {
    pub cycle: u64,
}

impl CycleTrims {
    /// Before any decision: the plan's levels.
    pub const NONE: CycleTrims = CycleTrims {
        decided: None,
        feedforward: Trims::NONE,
    };

    /// Takes the course's `decision` and its feedforward of the moment.
    pub fn take(&mut self, decision: &Decision, feedforward: Trims) {
        self.decided = Some((decision.cycle, decision.trims));
        self.feedforward = feedforward;
    }

    /// The trims of the cycle `first` begins, made while a cycle or idle period (`after_idle`)
    /// plays: `None` for an idle period.
    pub fn for_cycle(&self, first: &Segment, after_idle: bool) -> Result<Option<Trims>, LateTrims> {
        if first.kind == SegmentKind::Idle {
            return Ok(None);
        }
        match self.decided {
            Some((cycle, trims)) if cycle == first.cycle => Ok(Some(trims)),
            _ if after_idle => Ok(Some(self.feedforward)),
            _ => Err(LateTrims { cycle: first.cycle }),
        }
    }

    /// The feedforward last taken: what a cycle without its own trims runs.
    pub fn feedforward(&self) -> Trims {
        self.feedforward
    }
}

/// Why the course stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CourseError {
    Identify(IdentifyError),
    Loop(LoopError),
    /// The plate did not settle at the centre within the allowed held cycles.
    Centring {
        error_m: f64,
    },
    /// A cycle of the plan never turns back.
    Plan,
    /// The boundary of this cycle reached the course too late or not at all.
    MissedBoundary {
        cycle: u64,
    },
    /// The position sensor had no capture at this cycle start tick.
    NoCapture {
        tick: u64,
    },
}

impl CourseError {
    /// The envelope's property it names, if any.
    pub fn cause(&self) -> Option<Cause> {
        match self {
            CourseError::Identify(error) => error.cause(),
            _ => None,
        }
    }
}

impl core::fmt::Display for CourseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            CourseError::Identify(error) => write!(f, "identification: {error}"),
            CourseError::Loop(error) => write!(f, "closed loop: {error}"),
            CourseError::Centring { error_m } => write!(
                f,
                "the plate is still {error_m} m from its centre after the centring's last cycle"
            ),
            CourseError::Plan => f.write_str("a planned cycle does not turn back"),
            CourseError::MissedBoundary { cycle } => write!(
                f,
                "the closed loop missed the start of cycle {cycle}: it cannot keep up with the output"
            ),
            CourseError::NoCapture { tick } => write!(
                f,
                "the position sensor has no capture at the cycle start tick {tick}"
            ),
        }
    }
}

/// The probe's record: the levels its cycles were commanded and the positions sampled through
/// them, timed from its first start.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    start_tick: u64,
    clock_hz: u32,
    /// The plan's period.
    period_s: f64,
    resolution_m: f64,
    positions: [Latch; PROBE_POSITIONS_MAX],
    position_count: usize,
    segments: [CommandSegment; PROBE_SEGMENTS_MAX],
    segment_count: usize,
}

impl Probe {
    fn new(start_tick: u64, clock_hz: u32, period_s: f64, resolution_m: f64) -> Self {
        let latch = Latch {
            t_s: 0.0,
            position_m: 0.0,
        };
        let segment = CommandSegment {
            duration_s: 0.0,
            accel_mps2: 0.0,
        };
        Probe {
            start_tick,
            clock_hz,
            period_s,
            resolution_m,
            positions: [latch; PROBE_POSITIONS_MAX],
            position_count: 0,
            segments: [segment; PROBE_SEGMENTS_MAX],
            segment_count: 0,
        }
    }

    /// Keeps `sample` if it is later than the last one kept (and there is room).
    fn keep_position(&mut self, sample: PositionSample) {
        let Some(ticks) = sample.tick.checked_sub(self.start_tick) else {
            return;
        };
        let t_s = ticks as f64 / f64::from(self.clock_hz);
        let later = self.positions[..self.position_count]
            .last()
            .is_none_or(|kept| t_s > kept.t_s);
        if later && self.position_count < PROBE_POSITIONS_MAX {
            self.positions[self.position_count] = Latch {
                t_s,
                position_m: sample.position_m,
            };
            self.position_count += 1;
        }
    }

    fn keep_segment(&mut self, segment: CommandSegment) {
        if self.segment_count < PROBE_SEGMENTS_MAX {
            self.segments[self.segment_count] = segment;
            self.segment_count += 1;
        }
    }

    /// The positions kept.
    pub fn positions(&self) -> &[Latch] {
        &self.positions[..self.position_count]
    }

    /// The levels commanded, trims included.
    pub fn segments(&self) -> &[CommandSegment] {
        &self.segments[..self.segment_count]
    }

    /// The drive identified from the probe, within [`IdentifyLimits::for_probe`].
    pub fn identify(&self) -> Result<Identified, IdentifyError> {
        let limits = IdentifyLimits::for_probe(self.resolution_m, self.period_s);
        identify(self.segments(), self.positions(), &limits)
    }
}

/// A cycle begun, as the course keeps it until the next boundary.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Begun {
    start: PositionSample,
    shape: CycleShape,
    /// Runs at the plan's full amplitude: only those cycles' strokes and means are held.
    full: bool,
    idle: bool,
    clock_hz: u32,
}

/// The course's state.
#[derive(Debug, Clone)]
pub struct Course {
    config: CourseConfig,
    stage: Stage,
    probe_step: u16,
    probe: Option<Probe>,
    probe_cycles: u32,
    identified: Option<Identified>,
    cycle_loop: CycleLoop,
    /// The trims last decided, for the cycle after the one begun at the last boundary.
    decided: Trims,
    centred: u32,
    centring_cycles: u32,
    last: Option<Begun>,
}

impl Course {
    /// A course for a scheduler of `ramp_steps` soft-start steps, which must be held at
    /// [`Course::probe_step`] before its first start.
    pub fn new(config: CourseConfig, ramp_steps: u16) -> Self {
        Course {
            probe_step: config.probe_step(ramp_steps),
            config,
            stage: Stage::Waiting,
            probe: None,
            probe_cycles: 0,
            identified: None,
            cycle_loop: CycleLoop::new(&Identified::NOMINAL, config.loop_limits)
                .with_level_step(config.level_step_mps2),
            decided: Trims::NONE,
            centred: 0,
            centring_cycles: 0,
            last: None,
        }
    }

    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The stage and the identified drive.
    pub fn report(&self) -> LoopReport {
        LoopReport {
            stage: self.stage,
            drive: self.identified,
        }
    }

    /// The step the scheduler holds for the probe and the centring.
    pub fn probe_step(&self) -> u16 {
        self.probe_step
    }

    /// The drive as identified, once it is.
    pub fn identified(&self) -> Option<&Identified> {
        self.identified.as_ref()
    }

    /// The probe, once complete ([`Decision::identify`]).
    pub fn probe(&self) -> Option<&Probe> {
        self.probe
            .as_ref()
            .filter(|_| self.stage == Stage::Identifying)
    }

    /// The trims of a cycle whose own were not decided: the drive's gains and offset undone as
    /// far as they are known, nothing more.
    pub fn feedforward(&self) -> Trims {
        self.cycle_loop.feedforward()
    }

    /// Hands over the identification of [`Course::probe`]: the loop goes on with the drive
    /// found, and the centring begins. A refusal stops the course.
    pub fn set_identified(
        &mut self,
        result: Result<Identified, IdentifyError>,
    ) -> Result<(), CourseError> {
        if self.stage != Stage::Identifying {
            return Ok(());
        }
        match result {
            Ok(identified) => {
                self.identified = Some(identified);
                self.cycle_loop.set_drive(&identified);
                self.stage = Stage::Centring;
                Ok(())
            }
            Err(error) => {
                self.stage = Stage::Failed;
                Err(CourseError::Identify(error))
            }
        }
    }

    /// At the start of a cycle or idle period: `begun` its first segment, `ahead` the scheduler
    /// right after it, `start` the position at its start tick, `samples` the positions sampled
    /// since the previous start (in time order, before `start`).
    pub fn boundary(
        &mut self,
        begun: &Segment,
        ahead: &Scheduler,
        start: PositionSample,
        samples: &[PositionSample],
    ) -> Result<Decision, CourseError> {
        if self.stage == Stage::Failed {
            return Ok(Decision::trims(begun, Trims::NONE));
        }
        let result = self.step(begun, ahead, start, samples);
        if result.is_err() {
            self.stage = Stage::Failed;
        }
        result
    }

    fn step(
        &mut self,
        begun: &Segment,
        ahead: &Scheduler,
        start: PositionSample,
        samples: &[PositionSample],
    ) -> Result<Decision, CourseError> {
        let mut lookahead = ahead.clone();
        let (segments, count) = rest_of_cycle(begun, &mut lookahead);
        let segments = &segments[..count];
        let plan = ahead.plan();
        let idle = begun.kind == SegmentKind::Idle;
        let now = Begun {
            start,
            shape: self.shape(segments, idle)?,
            full: !idle && begun.amplitude.step == begun.amplitude.steps,
            idle,
            clock_hz: plan.clock_hz,
        };
        let last = self.last.replace(now);
        // The trims this cycle runs: decided at the last boundary, unless that began an idle
        // period (then this cycle's first segment was made before them).
        let applied = match last {
            Some(last) if !last.idle => self.decided,
            _ => self.feedforward(),
        };
        let held = !idle && ahead.held_step() == Some(begun.amplitude.step);
        let mut decision = Decision::trims(begun, self.feedforward());
        match self.stage {
            Stage::Waiting | Stage::Probing if !held => {
                // A stop (or anything but the held cycles) before the probe is complete: it
                // begins again at the next held cycle.
                self.stage = Stage::Waiting;
                self.probe = None;
                self.probe_cycles = 0;
                self.cycle_loop.restart();
                self.decided = decision.trims;
                return Ok(decision);
            }
            Stage::Waiting => {
                self.stage = Stage::Probing;
                self.probe = Some(Probe::new(
                    start.tick,
                    plan.clock_hz,
                    plan.ticks_to_s(u64::from(plan.period_ticks)),
                    self.config.resolution_m,
                ));
            }
            _ => {}
        }
        if let (Stage::Probing, Some(probe)) = (self.stage, self.probe.as_mut()) {
            for sample in samples {
                probe.keep_position(*sample);
            }
            probe.keep_position(start);
            if self.probe_cycles == self.config.probe_cycles.clamp(1, PROBE_CYCLES_MAX) {
                self.stage = Stage::Identifying;
                decision.identify = true;
            } else {
                for segment in segments {
                    probe.keep_segment(CommandSegment {
                        accel_mps2: applied.apply(segment.accel_mps2),
                        ..*segment
                    });
                }
                self.probe_cycles += 1;
            }
        }
        decision.trims = self.close_loop(&lookahead, now, last, samples, &mut decision)?;
        if decision.release {
            self.stage = Stage::Feeding;
        }
        self.decided = decision.trims;
        Ok(decision)
    }

    /// The loop at a boundary: the trims of the next cycle. `now` is the cycle begun, `last`
    /// the one that just ended and `samples` its positions.
    fn close_loop(
        &mut self,
        lookahead: &Scheduler,
        now: Begun,
        last: Option<Begun>,
        samples: &[PositionSample],
        decision: &mut Decision,
    ) -> Result<Trims, CourseError> {
        if now.idle || last.is_none_or(|last| last.idle) {
            // The cycle after an idle period was made before this decision: it runs the
            // feedforward, and the loop starts again from its start.
            self.cycle_loop.restart();
            if now.idle {
                return Ok(decision.trims);
            }
        }
        let mut lookahead = lookahead.clone();
        if self.stage == Stage::Centring {
            let error_m = now.start.position_m + now.shape.mean_m;
            self.centring_cycles += 1;
            if libm::fabs(error_m) <= self.config.centred_m {
                self.centred += 1;
            } else {
                self.centred = 0;
                if self.centring_cycles > self.config.centring_cycles_max {
                    return Err(CourseError::Centring { error_m });
                }
            }
            if self.centred >= self.config.centred_cycles {
                lookahead.release_hold();
                decision.release = true;
            }
        }
        let next = [
            next_shape(&self.cycle_loop, &mut lookahead)?,
            next_shape(&self.cycle_loop, &mut lookahead)?,
        ];
        // Stroke and mean are held on full-amplitude cycles only: friction shortens a soft
        // start's strokes, and moves its means, more than the full one's.
        let measured = last.filter(|last| last.full && self.stage == Stage::Feeding);
        let stroke = measured.map(|last| {
            Stroke::latched(
                last.start.position_m,
                turn_position_m(&last, samples),
                now.start.position_m,
                &last.shape,
            )
        });
        let mean_m = measured.map(|last| mean_position_m(last.start, samples, now.start));
        self.cycle_loop
            .update(
                now.start.position_m,
                stroke,
                mean_m,
                &now.shape,
                [&next[0], &next[1]],
            )
            .map_err(CourseError::Loop)
    }

    fn shape(&self, segments: &[CommandSegment], idle: bool) -> Result<CycleShape, CourseError> {
        if idle {
            let period_s = segments.iter().map(|s| s.duration_s).sum();
            return Ok(CycleShape::idle(period_s));
        }
        self.cycle_loop.plan(segments).ok_or(CourseError::Plan)
    }
}

/// The segments of the cycle `begun` starts, in seconds, with `scheduler` right after it
/// (advanced to the next boundary); an idle period is its one segment.
fn rest_of_cycle(begun: &Segment, scheduler: &mut Scheduler) -> ([CommandSegment; 4], usize) {
    let plan = *scheduler.plan();
    let mut segments = [CommandSegment::of(begun, &plan); 4];
    let mut count = 1;
    if begun.kind != SegmentKind::Idle {
        while !scheduler.at_boundary() && count < 4 {
            segments[count] = CommandSegment::of(&scheduler.next_segment(), &plan);
            count += 1;
        }
    }
    (segments, count)
}

/// The plan of the scheduler's next cycle as the loop aims at it.
fn next_shape(
    cycle_loop: &CycleLoop,
    scheduler: &mut Scheduler,
) -> Result<CycleShape, CourseError> {
    let first = scheduler.next_segment();
    let (segments, count) = rest_of_cycle(&first, scheduler);
    if first.kind == SegmentKind::Idle {
        return Ok(CycleShape::idle(segments[0].duration_s));
    }
    cycle_loop.plan(&segments[..count]).ok_or(CourseError::Plan)
}

/// The position sampled nearest the turning tick of cycle `last` (the velocity is zero there,
/// so the nearest sample is off by at most `a·Δt²/8`).
fn turn_position_m(last: &Begun, samples: &[PositionSample]) -> f64 {
    let turn_tick = last.start.tick as f64 + last.shape.turn_s * f64::from(last.clock_hz);
    samples
        .iter()
        .min_by(|a, b| {
            libm::fabs(a.tick as f64 - turn_tick).total_cmp(&libm::fabs(b.tick as f64 - turn_tick))
        })
        .map_or(last.start.position_m, |sample| sample.position_m)
}

/// The mean position from `start` to `end` through `samples` (trapezoids).
fn mean_position_m(start: PositionSample, samples: &[PositionSample], end: PositionSample) -> f64 {
    let mut area = 0.0;
    let mut previous = start;
    for sample in samples.iter().chain(core::iter::once(&end)) {
        let ticks = sample.tick.saturating_sub(previous.tick) as f64;
        area += ticks * (sample.position_m + previous.position_m) / 2.0;
        previous = *sample;
    }
    let ticks = end.tick.saturating_sub(start.tick) as f64;
    if ticks > 0.0 {
        area / ticks
    } else {
        start.position_m
    }
}
