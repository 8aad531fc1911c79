//! The waveform scheduler: which level, for how many ticks, forever.
//!
//! The scheduler is a deterministic state machine over a [`TickPlan`]. Each call to
//! [`Scheduler::next_segment`] returns the next segment to output with its absolute start tick.
//! Requests (start, stop, a new plan, a new ramp length) are only recorded when made; they take
//! effect at the next cycle boundary, where the plate is at rest. While stopped the scheduler emits
//! idle periods of level `0`, so time and the cycle count advance uniformly.
//!
//! Soft start and soft stop scale the amplitude by `step / steps` with `steps = max(ramp_cycles, 1)`:
//! starting runs cycles at `1/steps, 2/steps, …, 1`; stopping runs `(steps−1)/steps, …, 1/steps`
//! and then idles. Every cycle, scaled or not, ends at rest, and its displacement residual (see
//! [`crate::plan`]) is fed back through the choice of the next cycle's variant.

use crate::error::Error;
use crate::plan::TickPlan;
use crate::segment::SegmentKind;
use crate::waveform::Level;
use libm::round;

/// Amplitude of a segment as the fraction `step / steps` of the plan's `a_max`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Amplitude {
    pub step: u16,
    pub steps: u16,
}

impl Amplitude {
    pub fn fraction(self) -> f64 {
        f64::from(self.step) / f64::from(self.steps)
    }
}

/// What the scheduler is doing in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Phase {
    Stopped,
    Starting,
    Running,
    Stopping,
}

impl Phase {
    /// The phase's word in replies and telemetry.
    pub const fn name(self) -> &'static str {
        match self {
            Phase::Stopped => "stopped",
            Phase::Starting => "starting",
            Phase::Running => "running",
            Phase::Stopping => "stopping",
        }
    }
}

/// One segment of output: hold `level` at `amplitude` for `ticks`, from `start_tick`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Segment {
    /// Absolute tick (since the scheduler was created) at which the level is applied.
    pub start_tick: u64,
    pub ticks: u32,
    /// Index of the cycle (or idle period) this segment belongs to.
    pub cycle: u64,
    pub kind: SegmentKind,
    pub level: Level,
    pub amplitude: Amplitude,
    /// `a_max` of the plan in force, before the amplitude fraction.
    pub peak_accel_mps2: f64,
    pub phase: Phase,
    /// True on the first segment of the first cycle that runs a newly requested plan.
    pub plan_applied: bool,
}

impl Segment {
    /// Commanded plate acceleration during this segment.
    pub fn accel_mps2(&self) -> f64 {
        f64::from(self.level.sign()) * self.peak_accel_mps2 * self.amplitude.fraction()
    }

    /// True for the first segment of a cycle, idle period or settle segment.
    pub fn starts_cycle(&self) -> bool {
        self.kind.starts_cycle()
    }

    pub fn end_tick(&self) -> u64 {
        self.start_tick + u64::from(self.ticks)
    }
}

/// The one waveform scheduler, shared by the firmware and the simulator.
#[derive(Debug, Clone)]
pub struct Scheduler {
    plan: TickPlan,
    pending_plan: Option<TickPlan>,
    ramp_steps: u16,
    pending_ramp_steps: Option<u16>,
    run_requested: bool,
    /// A controlled stop is requested: the next boundary idles without a ramp.
    quick_stop: bool,
    /// While running, cycles stay at this step instead of ramping (the closed loop's probe).
    held_step: Option<u16>,
    /// A hold asked for in steps of the pending ramp length, taken with it.
    pending_held_step: Option<u16>,
    step: u16,
    phase: Phase,
    cycle: u64,
    /// Index of the next segment within the cycle (0 at a boundary).
    segment_index: usize,
    variant: usize,
    next_tick: u64,
    /// Accumulated displacement at the last boundary, in units of `(a/steps)·tick²`.
    residual: i64,
    /// Settle segments before each start from rest ([`Self::settle_before_start`]) …
    settle_segments: u16,
    /// … how many of the start in progress are still to come …
    settle_left: u16,
    /// … and whether that start has had its count.
    settle_counted: bool,
}

impl Scheduler {
    /// A stopped scheduler at tick 0 that will ramp over `ramp_cycles` cycles.
    pub fn new(plan: TickPlan, ramp_cycles: u16) -> Self {
        Scheduler {
            plan,
            pending_plan: None,
            ramp_steps: ramp_cycles.max(1),
            pending_ramp_steps: None,
            run_requested: false,
            quick_stop: false,
            held_step: None,
            pending_held_step: None,
            step: 0,
            phase: Phase::Stopped,
            cycle: 0,
            segment_index: 0,
            variant: 0,
            next_tick: 0,
            residual: 0,
            settle_segments: 0,
            settle_left: 0,
            settle_counted: false,
        }
    }

    /// Each start from rest begins with `segments` settle segments ([`SegmentKind::Settle`],
    /// [`TickPlan::settle_ticks`] each, level zero, every one its own cycle) before its first
    /// cycle: the closed loop holds the plate through their bias while it learns the drive's
    /// offset. A stop requested meanwhile idles at the next of them. 0 (the default): none.
    pub fn settle_before_start(&mut self, segments: u16) {
        self.settle_segments = segments;
    }

    /// Request motion; it begins (or a soft stop reverses) at the next cycle boundary.
    pub fn start(&mut self) {
        self.run_requested = true;
    }

    /// Request a soft stop; it begins at the next cycle boundary.
    pub fn stop(&mut self) {
        self.run_requested = false;
    }

    /// Controlled stop (stop category 1): the cycle in progress runs to its end, where the plate
    /// is at rest within the plan's drift bound, and the output idles from there, without the
    /// soft stop's ramp. For faults that leave the output working; [`Self::halt`] is for an
    /// output that no longer can be timed.
    pub fn quick_stop(&mut self) {
        self.run_requested = false;
        self.quick_stop = true;
    }

    /// Hold the amplitude at `step / ramp_cycles` (at most all) while motion is requested: a
    /// start's soft start rises to it one step a cycle and stays there, and a running plan drops
    /// to it at the next cycle boundary; step 0 idles while motion stays requested. The closed
    /// loop probes the drive and centres the plate on held cycles. With a new ramp length pending
    /// ([`Self::set_ramp_cycles`]), `step` counts the new ramp's steps and replaces the held step
    /// when the new length takes effect.
    pub fn hold_step(&mut self, step: u16) {
        if self.pending_ramp_steps.is_some() {
            self.pending_held_step = Some(step);
        } else {
            self.held_step = Some(step);
        }
    }

    /// The step held, in steps of the ramp in force (a new ramp length scales it), if any.
    pub fn held_step(&self) -> Option<u16> {
        self.held_step
    }

    /// End a hold: from the next cycle boundary the soft start goes on from the held step.
    pub fn release_hold(&mut self) {
        self.held_step = None;
        self.pending_held_step = None;
    }

    /// Replace the plan at the next cycle boundary. The clock must be the running one.
    pub fn set_plan(&mut self, plan: TickPlan) -> Result<(), Error> {
        if plan.clock_hz != self.plan.clock_hz {
            return Err(Error::ClockMismatch {
                running_hz: self.plan.clock_hz,
                requested_hz: plan.clock_hz,
            });
        }
        self.pending_plan = Some(plan);
        Ok(())
    }

    /// Change the soft start/stop length at the next cycle boundary.
    pub fn set_ramp_cycles(&mut self, ramp_cycles: u16) {
        self.pending_ramp_steps = Some(ramp_cycles.max(1));
    }

    /// Fault stop: drop to idle immediately, abandoning the rest of the cycle. The caller must
    /// already have driven the output to zero; the next segment is an idle period starting where
    /// the last emitted segment ended. Not for normal stops, which use [`Self::stop`].
    pub fn halt(&mut self) {
        self.run_requested = false;
        self.quick_stop = false;
        self.step = 0;
        self.phase = Phase::Stopped;
        self.residual = 0;
        if self.segment_index != 0 {
            self.segment_index = 0;
            self.cycle += 1;
        }
    }

    /// The next segment to output.
    pub fn next_segment(&mut self) -> Segment {
        let mut plan_applied = false;
        if self.segment_index == 0 {
            if self.settle_due() {
                return self.settle_segment();
            }
            plan_applied = self.begin_cycle();
        }
        let (kind, level, ticks) = if self.step == 0 {
            (SegmentKind::Idle, Level::Zero, self.plan.period_ticks)
        } else {
            let cycle = &self.plan.variants[self.variant];
            let (kind, level) = CYCLE[self.segment_index];
            (kind, level, cycle.segment_ticks(self.segment_index))
        };
        let segment = Segment {
            start_tick: self.next_tick,
            ticks,
            cycle: self.cycle,
            kind,
            level,
            amplitude: Amplitude {
                step: self.step,
                steps: self.ramp_steps,
            },
            peak_accel_mps2: self.plan.waveform.accel_mps2,
            phase: self.phase,
            plan_applied,
        };
        self.next_tick = self.next_tick.saturating_add(u64::from(ticks));
        if self.step == 0 || self.segment_index == CYCLE.len() - 1 {
            let residual = self.plan.variants[self.variant].residual;
            if self.step > 0 {
                self.residual = self
                    .residual
                    .saturating_add(residual.saturating_mul(i64::from(self.step)));
            }
            self.segment_index = 0;
            self.cycle += 1;
        } else {
            self.segment_index += 1;
        }
        segment
    }

    /// At a boundary: whether a settle segment comes next. A start from rest takes its count
    /// of them; anything but a start from rest ends the count.
    fn settle_due(&mut self) -> bool {
        let starting =
            self.step == 0 && self.run_requested && !self.quick_stop && self.held_step != Some(0);
        if !starting {
            self.settle_left = 0;
            self.settle_counted = false;
            return false;
        }
        if !self.settle_counted {
            self.settle_counted = true;
            self.settle_left = self.settle_segments;
        }
        if self.settle_left == 0 {
            return false;
        }
        self.settle_left -= 1;
        true
    }

    /// The next settle segment, a cycle of its own.
    fn settle_segment(&mut self) -> Segment {
        let ticks = self.plan.settle_ticks();
        let segment = Segment {
            start_tick: self.next_tick,
            ticks,
            cycle: self.cycle,
            kind: SegmentKind::Settle,
            level: Level::Zero,
            amplitude: Amplitude {
                step: 0,
                steps: self.ramp_steps,
            },
            peak_accel_mps2: self.plan.waveform.accel_mps2,
            phase: Phase::Starting,
            plan_applied: false,
        };
        self.next_tick = self.next_tick.saturating_add(u64::from(ticks));
        self.cycle += 1;
        segment
    }

    /// Applies pending requests at a cycle boundary and chooses the cycle's amplitude and variant.
    /// Returns whether a new plan took effect.
    fn begin_cycle(&mut self) -> bool {
        let plan_applied = self.pending_plan.is_some();
        if plan_applied || self.pending_ramp_steps.is_some() {
            // The accumulated displacement is carried over in metres into the new units.
            let residual_m = self.residual_m();
            if let Some(plan) = self.pending_plan.take() {
                self.plan = plan;
            }
            if let Some(steps) = self.pending_ramp_steps.take() {
                let old_steps = u32::from(self.ramp_steps);
                let scaled = (u32::from(self.step) * u32::from(steps) + old_steps / 2) / old_steps;
                self.step = if self.step > 0 {
                    scaled.max(1) as u16
                } else {
                    0
                };
                // A hold keeps its fraction of the amplitude, unless one was asked for in the new
                // length's steps.
                self.held_step = self.held_step.map(|held| {
                    let scaled = (u32::from(held) * u32::from(steps) + old_steps / 2) / old_steps;
                    if held > 0 {
                        scaled.max(1) as u16
                    } else {
                        0
                    }
                });
                if let Some(held) = self.pending_held_step.take() {
                    self.held_step = Some(held);
                }
                self.ramp_steps = steps;
            }
            self.residual = round(residual_m / self.residual_unit_m()) as i64;
        }
        self.step = if self.quick_stop {
            self.quick_stop = false;
            0
        } else if self.run_requested {
            match self.held_step {
                Some(held) => self.step.saturating_add(1).min(held).min(self.ramp_steps),
                None => self.step.saturating_add(1).min(self.ramp_steps),
            }
        } else {
            self.step.saturating_sub(1)
        };
        self.phase = match (self.run_requested, self.step) {
            (_, 0) => Phase::Stopped,
            (true, step) if step == self.ramp_steps => Phase::Running,
            (true, _) => Phase::Starting,
            (false, _) => Phase::Stopping,
        };
        self.variant = if self.residual <= 0 { 0 } else { 1 };
        plan_applied
    }

    fn residual_unit_m(&self) -> f64 {
        self.plan.residual_unit_m() / f64::from(self.ramp_steps)
    }

    /// Accumulated plate displacement at the last cycle boundary, from whole-tick integration.
    pub fn residual_m(&self) -> f64 {
        self.residual as f64 * self.residual_unit_m()
    }

    /// The plan in force.
    pub fn plan(&self) -> &TickPlan {
        &self.plan
    }

    /// The plan that will take effect at the next boundary, if any.
    pub fn pending_plan(&self) -> Option<&TickPlan> {
        self.pending_plan.as_ref()
    }

    /// Phase of the current (last begun) cycle.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Whether motion is requested (the state soft start/stop converges to).
    pub fn run_requested(&self) -> bool {
        self.run_requested
    }

    pub fn ramp_cycles(&self) -> u16 {
        self.ramp_steps
    }

    /// Number of cycles (including idle periods) begun so far.
    pub fn cycle(&self) -> u64 {
        self.cycle
    }

    /// Tick at which the next segment starts.
    pub fn next_tick(&self) -> u64 {
        self.next_tick
    }

    /// True when the next segment starts a cycle.
    pub fn at_boundary(&self) -> bool {
        self.segment_index == 0
    }
}

/// The segments of one cycle in output order (Fig. 2a), each at its
/// [`SegmentKind::place`].
pub const CYCLE: [(SegmentKind, Level); 4] = [
    (SegmentKind::Accelerate, Level::Positive),
    (SegmentKind::Plateau, Level::Zero),
    (SegmentKind::Reverse, Level::Negative),
    (SegmentKind::Return, Level::Positive),
];
