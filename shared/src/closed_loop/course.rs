//! The closed loop's course from the first start to feeding, one state machine for the firmware
//! and the simulator:
//!
//! 0. **Settle**: a start from rest begins with the scheduler's settle segments
//!    ([`CourseConfig::settle_segments`]), fractions of a period at level zero, in which
//!    [`Settle`] holds the plate through a bias alone, shakes it with a dither to learn the
//!    drive's zero offset and the difference of its gains, and brings it to where the first
//!    cycle should start. The cycles take that drive as their feedforward.
//! 1. **Probe**: the soft start rises to the scheduler's held step, a low one, with the
//!    cycle-rate loop trimming every cycle from the first, so that what the settle did not find
//!    grows with the levels and is caught while small; the positions sampled through the first
//!    `probe_cycles` held cycles and the levels they and the cycle before were commanded are
//!    kept ([`Probe`]).
//! 2. **Identify**: held cycles go on, still on the settle's drive, while the drive is identified
//!    from the probe ([`Probe::identify`], long: the firmware runs it below the loop) and handed
//!    back ([`Course::set_identified`]). The course takes it at the first boundary
//!    [`CourseConfig::identify_hold_s`] after the probe's end, however early it came, so that
//!    every runner holds the plate as long.
//! 3. **Centre**: the loop, now on the identified drive, trims held cycles, their levels excited
//!    to [`CourseConfig::excitation_peak`] and back so that what the identification left shows
//!    at two levels, until the plate has started `centred_cycles` of them in a row within
//!    `centred_m` of where it should.
//! 4. **Feed**: the hold is released at the boundary after that (the first cycle to rise is
//!    then the one after next, which the loop already aims at), the soft start goes on from the
//!    held step, and the loop trims every cycle from then on.
//!
//! At every cycle, idle period or settle segment that begins, [`Course::boundary`] takes the segment begun, the
//! scheduler right after it (a copy: the plans of the cycles ahead), the position sampled at its
//! start tick and the positions sampled at a fixed interval since the previous start. It returns
//! the trims of the next cycle (after a settle segment, of the one after it: [`Decision`]) and
//! whether the hold ends. The caller applies both at the next
//! segment it begins: the firmware decides below the edge path, so the decision is there at the
//! earliest then, and the simulator applies it at the same point. The cycle after an idle period
//! was made before its trims were decided: it runs the feedforward alone
//! ([`Course::feedforward`]), and the loop starts its history afresh from its start; after a
//! settle it starts from the plate at rest.

mod config;
mod decision;
mod error;
mod lookahead;
mod measure;
mod probe;
mod stage;

pub use config::CourseConfig;
pub use decision::{CycleTrims, Decision, LateTrims};
pub use error::CourseError;
pub use measure::{mean_position_m, PositionSample};
pub use probe::{Probe, PROBE_CYCLES_MAX, PROBE_POSITIONS_MAX};
pub use stage::{LoopReport, Stage};

use super::cycle_loop::{CycleLoop, Stroke, Trims};
use super::envelope::ENVELOPE;
use super::feed::{FeedCompensation, FeedRequest};
use super::identify::{Identification, Identified, IdentifyError, FITS_MAX};
use super::settle::Settle;
use super::shape::{CommandSegment, CycleShape};
use crate::scheduler::{Scheduler, Segment};
use crate::segment::SegmentKind;
use crate::waveform::Waveform;
use lookahead::{next_shape, next_shape_from, rest_of_cycle};
use measure::{fitted_accel_mps2, position_near_m, turn_position_m, Begun};

/// The start of a cycle or idle period as [`Course::boundary`] takes it.
struct At<'a> {
    begun: &'a Segment,
    ahead: &'a Scheduler,
    start: PositionSample,
    samples: &'a [PositionSample],
}

/// Where the identification's hold is counted from: the probe's end and its clock.
#[derive(Debug, Clone, Copy, Default)]
struct ProbeEnd {
    tick: u64,
    clock_hz: u32,
}

impl ProbeEnd {
    /// The tick `hold_s` after the probe's end.
    fn after(&self, hold_s: f64) -> u64 {
        let ticks = libm::round(hold_s * f64::from(self.clock_hz));
        self.tick.saturating_add(ticks as u64)
    }
}

/// A settle in progress.
#[derive(Debug, Clone, Copy)]
struct SettleRun {
    settle: Settle,
    target_m: f64,
    /// A refusal found early, raised at the settle's end with the plate held at rest.
    refusal: Option<CourseError>,
}

/// The course's state.
#[derive(Debug, Clone)]
pub struct Course {
    config: CourseConfig,
    stage: Stage,
    /// Why the course stopped, once it has.
    failure: Option<CourseError>,
    probe_step: u16,
    /// The probe, begun at the first held cycle of each start (complete once the stage is
    /// [`Stage::Identifying`]).
    probe: Probe,
    probe_cycles: u32,
    identified: Option<Identified>,
    /// The identification handed over, with the start tick of the boundary before it came,
    /// until the course takes it at the end of its hold …
    handed: Option<(Identification, u64)>,
    /// … counted from the probe's end, in ticks of its clock.
    probe_end: ProbeEnd,
    /// The start tick of the last boundary.
    last_tick: u64,
    cycle_loop: CycleLoop,
    /// The settle of the start in progress, where it holds the plate and where the probe's
    /// first cycle starts, and the settle segments begun.
    settle: Option<SettleRun>,
    /// The cycle begun at the last boundary: its start tick and its levels as commanded, the
    /// probe's lead-in.
    lead_in: Option<(u64, [CommandSegment; 4], usize)>,
    /// The trims last decided, for the cycle after the one begun at the last boundary.
    decided: Trims,
    centred: u32,
    centring_cycles: u32,
    /// The plate is centred and the feed known: the soft start is released at the next
    /// boundary, so that the first cycle to rise is the one after next and the loop has a cycle
    /// to move the plate toward that cycle's start.
    release_due: bool,
    /// The gains' half difference the last settle's dither measured, for the probe's fit.
    settled_gain_half_difference: Option<f64>,
    last: Option<Begun>,
    /// The plan of the cycles ahead, as of the last boundary.
    waveform: Option<Waveform>,
    /// The feed's compensation taken last, and what it was asked for …
    feed: Option<(FeedRequest, FeedCompensation)>,
    /// … the one asked for now, taken at the first boundary from its tick on …
    feed_asked: Option<(FeedRequest, u64)>,
    /// … and its answer, once handed over.
    feed_handed: Option<FeedCompensation>,
}

impl Course {
    /// A course for a scheduler of `ramp_steps` soft-start steps, which must be held at
    /// [`Course::probe_step`] before its first start.
    pub fn new(config: CourseConfig, ramp_steps: u16) -> Self {
        Course {
            probe_step: config.probe_step(ramp_steps),
            config,
            stage: Stage::Waiting,
            failure: None,
            probe: Probe::new(),
            probe_cycles: 0,
            identified: None,
            handed: None,
            probe_end: ProbeEnd::default(),
            last_tick: 0,
            cycle_loop: CycleLoop::new(&Identified::NOMINAL, config.loop_limits)
                .with_level_step(config.level_step_mps2),
            settle: None,
            lead_in: None,
            decided: Trims::NONE,
            centred: 0,
            release_due: false,
            settled_gain_half_difference: None,
            centring_cycles: 0,
            last: None,
            waveform: None,
            feed: None,
            feed_asked: None,
            feed_handed: None,
        }
    }

    pub fn config(&self) -> &CourseConfig {
        &self.config
    }

    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The stage and the identified drive.
    pub fn report(&self) -> LoopReport {
        LoopReport {
            stage: self.stage,
            drive: self.identified,
            feed: self.feed.map(|(_, found)| found),
            failure: self.failure,
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
        (self.stage == Stage::Identifying).then_some(&self.probe)
    }

    /// The trims of a cycle whose own were not decided: the drive's gains and offset undone as
    /// far as they are known, nothing more.
    pub fn feedforward(&self) -> Trims {
        self.cycle_loop.feedforward()
    }

    /// The feed's compensation the course needs and has not got: for the plan ahead on the
    /// identified drive, where the part is configured ([`CourseConfig::with_feed`]). The
    /// answer goes to [`Course::set_feed`]; the course takes it at the first boundary
    /// [`CourseConfig::feed_hold_s`] after it asked (the same boundary however fast it came),
    /// and until then the loop holds the last one's amplitude. The soft start is released only
    /// once the course has its answer.
    pub fn feed_request(&self) -> Option<FeedRequest> {
        let (asked, _) = self.feed_asked?;
        (self.feed.map(|(taken, _)| taken) != Some(asked)).then_some(asked)
    }

    /// Hands over the answer to a [`Course::feed_request`]; an answer to a request no longer
    /// current is dropped.
    pub fn set_feed(&mut self, request: FeedRequest, found: FeedCompensation) {
        if self.feed_request() == Some(request) {
            self.feed_handed = Some(found);
        }
    }

    /// At a boundary at `tick`: asks for the compensation of the plan ahead where it changed,
    /// and takes the answer handed over once its hold is over.
    fn update_feed(&mut self, tick: u64, clock_hz: u32) {
        let (Some(waveform), Some(drive)) = (self.waveform, self.identified) else {
            return;
        };
        if self.config.part_mps2 <= 0.0 {
            return;
        }
        let request = FeedRequest::new(
            &waveform,
            &drive,
            self.config.part_mps2,
            self.config.linear_mps2,
        );
        if self.feed_asked.map(|(asked, _)| asked) != Some(request) {
            let hold_ticks = libm::round(self.config.feed_hold_s * f64::from(clock_hz)) as u64;
            self.feed_asked = Some((request, tick.saturating_add(hold_ticks)));
            self.feed_handed = None;
        }
        if let Some((asked, _)) = self.feed_asked.filter(|(_, from)| tick >= *from) {
            if let Some(found) = self.feed_handed.take() {
                self.feed = Some((asked, found));
                self.cycle_loop.set_feed(&found);
            }
        }
    }

    /// Hands over the identification of [`Course::probe`], which the course takes at the end
    /// of its hold ([`CourseConfig::identify_hold_s`]): then the loop goes on with the drive
    /// found and the centring begins, or a refusal stops the course. Ignored at any other stage.
    pub fn set_identified(&mut self, identification: Identification) {
        if self.stage == Stage::Identifying {
            self.handed = Some((identification, self.last_tick));
        }
    }

    /// At a boundary at `tick` while identifying: the identification handed over, at the end
    /// of the hold its work is given; none by the hold of the most work, or one handed over
    /// only after its own hold ended, stops the course.
    fn check_identified(&mut self, tick: u64) -> Result<(), CourseError> {
        let hold_s = |fits: u32| self.config.identify_hold_s(fits);
        let due = |hold_s: f64| self.probe_end.after(hold_s);
        match self.handed {
            Some((identification, before)) => {
                let hold_s = hold_s(identification.fits);
                if before >= due(hold_s) {
                    return Err(CourseError::IdentifyLate { hold_s });
                }
                if tick < due(hold_s) {
                    return Ok(());
                }
                self.handed = None;
                let identified = identification.result.map_err(CourseError::Identify)?;
                self.identified = Some(identified);
                self.cycle_loop.set_drive(&identified);
                self.cycle_loop.excite(self.config.excitation_peak);
                self.stage = Stage::Centring;
                Ok(())
            }
            None => {
                let hold_s = hold_s(FITS_MAX);
                match tick >= due(hold_s) {
                    true => Err(CourseError::IdentifyLate { hold_s }),
                    false => Ok(()),
                }
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
        let result = self.step(At {
            begun,
            ahead,
            start,
            samples,
        });
        self.last_tick = start.tick;
        if let Err(error) = result {
            self.stage = Stage::Failed;
            self.failure = Some(error);
        }
        result
    }

    /// [`Course::boundary`] on a course that has not failed.
    fn step(&mut self, at: At<'_>) -> Result<Decision, CourseError> {
        let At {
            begun,
            ahead,
            start,
            samples,
        } = at;
        if self.stage == Stage::Identifying {
            self.check_identified(start.tick)?;
        }
        if begun.kind == SegmentKind::Settle {
            return self.settle(begun, ahead, start, samples);
        }
        self.settle = None;
        let mut lookahead = ahead.clone();
        let (segments, count) = rest_of_cycle(begun, &mut lookahead);
        let segments = &segments[..count];
        let plan = ahead.plan();
        self.waveform = Some(plan.waveform);
        self.update_feed(start.tick, plan.clock_hz);
        let idle = begun.kind == SegmentKind::Idle;
        let now = Begun {
            start,
            shape: self.shape(segments, idle)?,
            full: !idle && begun.amplitude.step == begun.amplitude.steps,
            idle,
            settle: false,
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
        let rising = !idle
            && !held
            && ahead
                .held_step()
                .is_some_and(|step| begun.amplitude.step < step);
        match self.stage {
            Stage::Waiting | Stage::Settling if rising => {}
            Stage::Waiting | Stage::Settling | Stage::Probing if !held => {
                // A stop (or anything but the held cycles) before the probe is complete: it
                // begins again at the next held cycle.
                self.stage = Stage::Waiting;
                self.probe_cycles = 0;
                self.cycle_loop.restart();
                self.decided = decision.trims;
                return Ok(decision);
            }
            Stage::Waiting | Stage::Settling => {
                self.stage = Stage::Probing;
                // The cycle before, commanded but not latched, leads the probe in: the current
                // loop's state at its first latch is then the commands' own.
                let (lead_in_tick, lead_in) = match &self.lead_in {
                    Some((tick, segments, count)) => (*tick, &segments[..*count]),
                    None => (start.tick, &[][..]),
                };
                self.probe.begin(
                    lead_in_tick,
                    start.tick,
                    plan.clock_hz,
                    self.config.resolution_m,
                    self.settled_gain_half_difference,
                );
                for segment in lead_in {
                    self.probe.keep_segment(*segment);
                }
            }
            _ => {}
        }
        let mut commanded = [CommandSegment {
            duration_s: 0.0,
            accel_mps2: 0.0,
        }; 4];
        for (place, (kept, segment)) in commanded.iter_mut().zip(segments).enumerate() {
            *kept = CommandSegment {
                accel_mps2: applied.level(place, segment.accel_mps2),
                ..*segment
            };
        }
        self.lead_in = (!idle).then_some((start.tick, commanded, segments.len()));
        if self.stage == Stage::Probing {
            let probe = &mut self.probe;
            for sample in samples {
                probe.keep_position(*sample);
            }
            probe.keep_position(start);
            if self.probe_cycles == self.config.probe_cycles.clamp(1, PROBE_CYCLES_MAX) {
                self.stage = Stage::Identifying;
                self.probe_end = ProbeEnd {
                    tick: start.tick,
                    clock_hz: plan.clock_hz,
                };
                decision.identify = true;
            } else {
                for segment in &commanded[..segments.len()] {
                    probe.keep_segment(*segment);
                }
                self.probe_cycles += 1;
            }
        }
        decision.trims = self.close_loop(&lookahead, now, last, samples, &mut decision)?;
        if decision.release {
            self.stage = Stage::Feeding;
            self.release_due = false;
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
        if now.idle || last.is_none_or(|last| last.idle || last.settle) {
            // The cycle after an idle period was made before this decision: it runs the
            // feedforward, and the loop starts again from its start; so does the cycle after a
            // settle, which ran the feedforward with the drive the settle found, from the plate
            // at rest.
            if last.is_some_and(|last| last.settle) {
                self.cycle_loop.restart_at_rest();
            } else {
                self.cycle_loop.restart();
            }
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
            // The soft start waits for the feed's compensation too: its amplitude, and the feed
            // where the drive's range limits it, are known before the feeder feeds.
            if self.release_due {
                lookahead.release_hold();
                decision.release = true;
            } else if self.centred >= self.config.centred_cycles
                && self.feed_request().is_none()
                && !self.cycle_loop.exciting()
            {
                self.release_due = true;
            }
        }
        let first = next_shape(&self.cycle_loop, &mut lookahead, 1)?;
        if self.release_due && !decision.release {
            // Released at the next boundary: the cycle after next rises.
            lookahead.release_hold();
        }
        let next = [first, next_shape(&self.cycle_loop, &mut lookahead, 2)?];
        // Stroke and mean are held on full-amplitude cycles only: friction shortens a soft
        // start's strokes, and moves its means, more than the full one's.
        let measured = last.filter(|last| last.full && self.stage == Stage::Feeding);
        // The drive's lag delays the whole motion: the stroke is read from the start and the
        // turn as much later (the start's capture and the one now still give the drift).
        let stroke = measured.map(|last| {
            let lag_s = last.shape.lag_s;
            let start_m = position_near_m(&last, samples, lag_s);
            Stroke::latched(
                start_m,
                turn_position_m(&last, samples, lag_s),
                now.start.position_m + start_m - last.start.position_m,
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

    /// At the start of a settle segment: the bias of the next segment, or after the last one
    /// the offset found handed to the loop and its feedforward for the probe's first cycle.
    fn settle(
        &mut self,
        begun: &Segment,
        ahead: &Scheduler,
        start: PositionSample,
        samples: &[PositionSample],
    ) -> Result<Decision, CourseError> {
        let plan = ahead.plan();
        let limit_m = ENVELOPE.resolution_max_m;
        if self.config.resolution_m > limit_m {
            // Known from the configuration: refused before anything moves.
            return Err(CourseError::Identify(IdentifyError::Sensor {
                resolution_m: self.config.resolution_m,
                limit_m,
            }));
        }
        if self.stage != Stage::Settling {
            // A new start from rest: the plate is held where the probe's first cycle starts.
            self.stage = Stage::Settling;
            self.probe_cycles = 0;
            self.cycle_loop.restart();
            let mut lookahead = ahead.clone();
            let mut first = lookahead.next_segment();
            while first.kind == SegmentKind::Settle {
                first = lookahead.next_segment();
            }
            let target_m = if first.kind == SegmentKind::Idle {
                0.0
            } else {
                -next_shape_from(&self.cycle_loop, first, &mut lookahead, 0)?.mean_m
            };
            self.settle = Some(SettleRun {
                settle: Settle::new(
                    self.config.loop_limits,
                    self.config.level_step_mps2,
                    self.feedforward().bias_mps2,
                ),
                target_m,
                refusal: None,
            });
        }
        let Some(run) = self.settle.as_mut() else {
            return Err(CourseError::Plan);
        };
        let segment_s = plan.ticks_to_s(u64::from(begun.ticks));
        // The settle segment that just ended, if the last boundary began one.
        let ended_mps2 = self
            .last
            .filter(|last| last.settle)
            .and_then(|last| fitted_accel_mps2(last.start, samples, start, plan.clock_hz));
        let bias_mps2 = run
            .settle
            .update(start.position_m, ended_mps2, segment_s, run.target_m)
            .map_err(CourseError::Loop)?;
        let (offset_mps2, gain_difference) = run.settle.drive();
        // The decision is for the segment after the next: once that is not a settle segment,
        // the probe's cycles take the offset found.
        let mut lookahead = ahead.clone();
        lookahead.next_segment();
        let settled = lookahead.next_segment().kind != SegmentKind::Settle;
        // An offset beyond the envelope is refused as soon as it shows: from the held pairs
        // (what acts on a plate at rest is never more than the offset), else from the dither.
        // An offset beyond the envelope is refused as soon as it shows in the held pairs (what
        // acts on a plate at rest is never more than the offset): the dither ends there and the
        // settle holds the plate where it rests, and the refusal stops the feeder at the
        // settle's end, with the plate at rest. Else the dither's reading is checked.
        let limit_mps2 = ENVELOPE.settled_offset_max_mps2();
        let refusal = |offset_mps2| {
            CourseError::Identify(IdentifyError::Offset {
                offset_mps2,
                limit_mps2,
            })
        };
        if let Some(held) = run
            .settle
            .held_mps2()
            .filter(|held| libm::fabs(*held) > limit_mps2)
        {
            if run.refusal.is_none() {
                run.refusal = Some(refusal(held));
                run.settle.hold();
            }
        }
        if settled {
            if let Some(error) = run.refusal {
                return Err(error);
            }
            if libm::fabs(offset_mps2) > limit_mps2 {
                return Err(refusal(offset_mps2));
            }
        }
        let trims = if settled {
            self.cycle_loop
                .hold_drive(offset_mps2, gain_difference, run.settle.spring_per_s2());
            self.settled_gain_half_difference = run.settle.gain_half_difference();
            self.feedforward()
        } else {
            Trims {
                bias_mps2,
                ..self.feedforward()
            }
        };
        self.last = Some(Begun {
            start,
            shape: CycleShape::idle(segment_s),
            full: false,
            idle: false,
            settle: true,
            clock_hz: plan.clock_hz,
        });
        self.decided = trims;
        Ok(Decision::trims(begun, trims))
    }

    fn shape(&self, segments: &[CommandSegment], idle: bool) -> Result<CycleShape, CourseError> {
        if idle {
            let period_s = segments.iter().map(|s| s.duration_s).sum();
            return Ok(CycleShape::idle(period_s));
        }
        self.cycle_loop.plan(segments).ok_or(CourseError::Plan)
    }
}
