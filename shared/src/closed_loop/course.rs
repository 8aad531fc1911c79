//! The closed loop's course from the first start to feeding, one state machine for the firmware
//! and the simulator:
//!
//! 1. **Probe**: the scheduler holds its soft start at a low step. The cycle-rate loop runs from
//!    the first held cycle on a nominal drive (gains 1, no offset, no friction), so that an
//!    unknown offset cannot walk the plate away; the positions sampled through the first
//!    `probe_cycles` cycles and the levels they were commanded are kept ([`Probe`]).
//! 2. **Identify**: held cycles go on, still on the nominal drive, while the drive is identified
//!    from the probe ([`Probe::identify`], long: the firmware runs it below the loop) and handed
//!    back ([`Course::set_identified`]). The course takes it at the first boundary
//!    [`CourseConfig::identify_hold_s`] after the probe's end, however early it came, so that
//!    every runner holds the plate as long.
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
pub use measure::PositionSample;
pub use probe::{Probe, PROBE_CYCLES_MAX, PROBE_POSITIONS_MAX};
pub use stage::{LoopReport, Stage};

use super::cycle_loop::{CycleLoop, Stroke, Trims};
use super::identify::{Identified, IdentifyError};
use super::shape::{CommandSegment, CycleShape};
use crate::scheduler::{Scheduler, Segment};
use crate::segment::SegmentKind;
use lookahead::{next_shape, rest_of_cycle};
use measure::{mean_position_m, turn_position_m, Begun};

/// The start of a cycle or idle period as [`Course::boundary`] takes it.
struct At<'a> {
    begun: &'a Segment,
    ahead: &'a Scheduler,
    start: PositionSample,
    samples: &'a [PositionSample],
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
    /// The identification handed over, until the course takes it …
    handed: Option<Result<Identified, IdentifyError>>,
    /// … at the first boundary from this tick on.
    identify_tick: u64,
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
            handed: None,
            identify_tick: 0,
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

    /// Hands over the identification of [`Course::probe`], which the course takes at the end
    /// of its hold ([`CourseConfig::identify_hold_s`]): then the loop goes on with the drive
    /// found and the centring begins, or a refusal stops the course. Ignored at any other stage.
    pub fn set_identified(&mut self, result: Result<Identified, IdentifyError>) {
        if self.stage == Stage::Identifying {
            self.handed = Some(result);
        }
    }

    /// At the end of the identification's hold, the drive handed over.
    fn take_identified(&mut self) -> Result<(), CourseError> {
        match self.handed.take() {
            Some(Ok(identified)) => {
                self.identified = Some(identified);
                self.cycle_loop.set_drive(&identified);
                self.stage = Stage::Centring;
                Ok(())
            }
            Some(Err(error)) => Err(CourseError::Identify(error)),
            None => Err(CourseError::IdentifyLate {
                hold_s: self.config.identify_hold_s,
            }),
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
        if result.is_err() {
            self.stage = Stage::Failed;
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
        if self.stage == Stage::Identifying && start.tick >= self.identify_tick {
            self.take_identified()?;
        }
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
                let hold_ticks =
                    libm::round(self.config.identify_hold_s * f64::from(plan.clock_hz));
                self.identify_tick = start.tick.saturating_add(hold_ticks as u64);
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
