//! The control loop: runs the shared scheduler into the board's output stage, one preload per
//! edge, and applies the supervisor's decisions.

use core::cell::Cell;
use core::sync::atomic::Ordering;

use defmt::{error, info, warn};
use embassy_time::Timer;
use embedded_hal::digital::OutputPin;
use feeder_shared::closed_loop::{CycleTrims, LateTrims, Trims};
use feeder_shared::{
    Fault, MotionRequest, Phase, RunState, Scheduler, Segment, SegmentKind, StopCategory,
    Supervisor, SupervisorEvent, TickPlan,
};

use super::monitor::{cycles, COST, HEARTBEAT};
use super::regulate::{self, Boundary, Ruling, BOUNDARY, RULING};
use crate::board;
use crate::mailbox::{ReadyPlan, NEXT_PLAN, REQUESTS};
use crate::output::{SegmentOutput, TrimmedCycle};
use crate::ports::{Parts, PositionSensor};
use crate::status::{self, Status};
use crate::trace;
use crate::{config, configured};

/// Runs the scheduler into the output stage and applies the supervisor's decisions.
pub struct ControlLoop<O, E> {
    output: O,
    driver_enable: E,
    supervisor: Supervisor,
    /// Phase of the segment playing.
    phase: Phase,
    /// The cycle (or idle period) begun last.
    cycle: u64,
    /// The status as last published.
    published: Status,
    /// The closed loop's trims as each cycle takes them.
    trims: CycleTrims,
    /// The closed loop's course stopped: it runs again only after a reset of the board.
    loop_stopped: bool,
    /// The segment playing belongs to an idle period.
    idle: bool,
    /// The configuration wants the closed loop (see [`Self::closed_loop`]).
    loop_configured: bool,
    /// The least preload slack so far in the cycle playing, and over the one before it.
    cycle_slack_ticks: Option<u32>,
    least_slack_ticks: Option<u32>,
}

impl<O: SegmentOutput, E: OutputPin> ControlLoop<O, E> {
    pub fn new(output: O, driver_enable: E, latched_at_power_up: Option<Fault>) -> Self {
        Self {
            output,
            driver_enable,
            supervisor: Supervisor::new(latched_at_power_up),
            phase: Phase::Stopped,
            cycle: 0,
            published: Status::POWER_UP,
            trims: CycleTrims::NONE,
            loop_stopped: false,
            idle: true,
            loop_configured: configured::get().closed_loop,
            cycle_slack_ticks: None,
            least_slack_ticks: None,
        }
    }

    pub async fn run(mut self) -> ! {
        self.report_latched_fault();
        self.publish();
        // An output that failed its self-test never starts, not even its idle timeline.
        if let RunState::Faulted(fault) = self.supervisor.state() {
            if !fault.acknowledgeable() {
                self.park(fault).await
            }
        }
        match self.plan() {
            Some(plan) => self.run_plan(plan).await,
            None => self.park(Fault::InvalidSettings).await,
        }
    }

    /// The configured waveform planned on the output's clock, or `None` if it is refused.
    fn plan(&mut self) -> Option<TickPlan> {
        let startup = configured::get().startup;
        let plan = match ReadyPlan::new(self.output.clock(), &startup.spec(), startup.ramp_cycles) {
            Ok(ready) => ready.plan,
            Err(err) => {
                error!("waveform refused: {}", err);
                return None;
            }
        };
        if let Err(err) = self.output.set_peak_accel(plan.waveform.accel_mps2) {
            error!("output calibration refused: {}", err);
            return None;
        }
        trace::plan(0, &startup.spec(), plan.clock_hz, startup.ramp_cycles);
        Some(plan)
    }

    /// Invalid settings, or an output that failed its self-test (`fault`): stay at zero with the
    /// driver disabled, the output's timer never started; only a reset helps. Beats for the
    /// monitor well within its window, so that the watchdog stays fed.
    async fn park(mut self, fault: Fault) -> ! {
        self.handle(SupervisorEvent::Fault(fault), None);
        self.publish();
        loop {
            HEARTBEAT.fetch_add(1, Ordering::Relaxed);
            Timer::after_millis(config::PARK_HEARTBEAT_MS).await;
        }
    }

    /// One preload per edge; the status is published after it, while the segment plays.
    async fn run_plan(mut self, plan: TickPlan) -> ! {
        let ramp_cycles = configured::get().startup.ramp_cycles;
        let mut scheduler = Scheduler::new(plan, ramp_cycles);
        if self.closed_loop() {
            // The course settles the plate before every start from rest, then probes and
            // centres on held cycles.
            scheduler.hold_step(regulate::probe_step(ramp_cycles));
            scheduler.settle_before_start(regulate::settle_segments());
        }
        let mut queued = self.resync(&mut scheduler);
        loop {
            self.publish();
            let edge = self.output.wait_edge().await;
            let work_start = cycles();
            if edge.is_err() {
                queued = self.fail(Fault::EdgeMissed, queued, &mut scheduler);
                continue;
            }
            self.begin(&queued, &mut scheduler);
            queued = scheduler.next_segment();
            self.trim(&queued, &mut scheduler);
            if let Err(fault) = self.prepare(&queued) {
                queued = self.fail(fault, queued, &mut scheduler);
                continue;
            }
            COST.record(cycles().wrapping_sub(work_start));
        }
    }

    /// The closed loop's course runs (`super::regulate`): the board has a position sensor
    /// (known at compile time, so a board without one carries none of it) and the configuration
    /// wants the loop.
    fn closed_loop(&self) -> bool {
        <<board::Hardware as Parts>::Sensor as PositionSensor>::PRESENT && self.loop_configured
    }

    /// Preloads `segment`, switching the output levels first when it starts a new plan.
    fn prepare(&mut self, segment: &Segment) -> Result<(), Fault> {
        if segment.plan_applied {
            if let Err(err) = self.output.set_peak_accel(segment.peak_accel_mps2) {
                error!("output calibration refused: {}", err);
                return Err(Fault::InvalidSettings);
            }
        }
        self.output.preload(segment).map_err(|_| Fault::EdgeMissed)
    }

    /// With the closed loop, gives the output the trimmed levels of the cycle `segment` begins:
    /// the ones decided for it or, after an idle period, the feedforward. A running cycle whose
    /// trims are not there is one the loop did not decide in time: it runs the feedforward and
    /// the closed loop's fault stops the feeder at its end. Once the course has stopped, every
    /// start ends so after one cycle at the plan's levels, until a reset of the board.
    fn trim(&mut self, segment: &Segment, scheduler: &mut Scheduler) {
        if !self.closed_loop() || !segment.starts_cycle() {
            return;
        }
        let trims = match self.trims.for_cycle(segment, self.idle) {
            Ok(None) => return,
            _ if self.loop_stopped => {
                error!("closed loop: its course stopped earlier; reset the board to run it again");
                self.handle(SupervisorEvent::Fault(Fault::ClosedLoop), Some(scheduler));
                Trims::NONE
            }
            Ok(Some(trims)) => trims,
            Err(LateTrims { cycle }) => {
                error!("closed loop: no trims for cycle {=u64} in time", cycle);
                self.handle(SupervisorEvent::Fault(Fault::ClosedLoop), Some(scheduler));
                self.trims.feedforward()
            }
        };
        let trimmed = TrimmedCycle {
            cycle: segment.cycle,
            levels_mps2: trims.cycle_levels(segment.peak_accel_mps2 * segment.amplitude.fraction()),
        };
        if let Err(err) = self.output.trim(&trimmed) {
            error!("closed loop: trimmed levels refused: {}", err);
            self.handle(SupervisorEvent::Fault(Fault::ClosedLoop), Some(scheduler));
        }
    }

    /// Takes the closed loop's newest ruling: the trims of a cycle to come, the end of the
    /// hold, or a stop.
    fn take_ruling(&mut self, scheduler: &mut Scheduler) {
        match RULING.lock(Cell::take) {
            Some(Ruling::Trim {
                decision,
                feedforward,
            }) => {
                if decision.release {
                    scheduler.release_hold();
                }
                self.trims.take(&decision, feedforward);
            }
            Some(Ruling::Stop) => {
                self.loop_stopped = true;
                self.handle(SupervisorEvent::Fault(Fault::ClosedLoop), Some(scheduler));
            }
            None => {}
        }
    }

    /// Restarts the output with the scheduler's next segment and preloads the one after it.
    /// Returns the preloaded segment.
    fn resync(&mut self, scheduler: &mut Scheduler) -> Segment {
        let playing = scheduler.next_segment();
        self.output.restart(&playing);
        self.begin(&playing, scheduler);
        let queued = scheduler.next_segment();
        if self.prepare(&queued).is_err() {
            // Nothing can be timed: stop here and let the watchdog reset the board.
            self.output.halt();
            error!("output cannot be restarted; waiting for the watchdog");
        }
        queued
    }

    /// Fault stop in the fault's category (see [`Fault::stop_category`]), with the fault
    /// latched. Immediate: zero output and driver off now, then idle output from a fresh start.
    /// Controlled: `queued`, the segment that could not be prepared, is preloaded at zero (the
    /// stage outputs zero while its levels are refused), so the segment playing ends as planned
    /// and the plate comes to rest at the next cycle boundary, where the scheduler idles.
    /// Returns the segment now preloaded.
    fn fail(&mut self, fault: Fault, queued: Segment, scheduler: &mut Scheduler) -> Segment {
        if fault.stop_category() == StopCategory::Immediate {
            self.output.halt();
            self.set_driver(false);
        }
        error!("fault: {} (stop: {})", fault, fault.stop_category());
        if self.handle(SupervisorEvent::Fault(fault), Some(scheduler)) == MotionRequest::QuickStop {
            if self.output.preload(&queued).is_ok() {
                return queued;
            }
            // Not even a zero segment could be preloaded: nothing is left to finish the cycle.
            self.handle(SupervisorEvent::Fault(Fault::EdgeMissed), Some(scheduler));
        }
        self.output.halt();
        self.set_driver(false);
        self.resync(scheduler)
    }

    /// Work at the start of every segment: supervision and pending requests. A ready plan is
    /// queued at a cycle's start, before the closed loop is told of it, so that the course
    /// decides the next cycle, the plan's first, on that plan.
    fn begin(&mut self, playing: &Segment, scheduler: &mut Scheduler) {
        HEARTBEAT.fetch_add(1, Ordering::Relaxed);
        let started = self.output.started(playing);
        trace::segment(playing, started);
        if playing.starts_cycle() {
            self.least_slack_ticks = self.cycle_slack_ticks.take();
            if let Some(ready) = NEXT_PLAN.lock(Cell::take) {
                self.adopt(&ready, scheduler);
            }
            self.cycle = playing.cycle;
            let idle = !playing.kind.drives();
            if idle != self.idle {
                self.idle = idle;
                self.apply_driver();
            }
            if self.closed_loop() {
                BOUNDARY.signal(Boundary {
                    begun: *playing,
                    ahead: scheduler.clone(),
                    start_tick: started.tick,
                });
            }
        }
        if let Some(slack) = started.slack_ticks {
            self.cycle_slack_ticks = Some(
                self.cycle_slack_ticks
                    .map_or(slack, |least| least.min(slack)),
            );
        }
        if self.closed_loop() {
            self.take_ruling(scheduler);
        }
        if playing.phase != self.phase {
            info!("cycle {=u64}: {}", playing.cycle, playing.phase);
            self.phase = playing.phase;
        }
        if playing.kind == SegmentKind::Idle {
            self.handle(SupervisorEvent::OutputIdle, Some(scheduler));
        }
        while let Ok(request) = REQUESTS.try_receive() {
            self.handle(request, Some(scheduler));
        }
    }

    /// Queues a ready plan for the next cycle boundary: O(1), no arithmetic.
    fn adopt(&mut self, ready: &ReadyPlan, scheduler: &mut Scheduler) {
        match scheduler.set_plan(ready.plan) {
            Ok(()) => {
                scheduler.set_ramp_cycles(ready.ramp_cycles);
                if self.closed_loop() && scheduler.held_step().is_some() {
                    // The course's hold for the new ramp length, as a course made for it holds.
                    scheduler.hold_step(ready.hold_step);
                }
                trace::plan(
                    scheduler.next_tick(),
                    &ready.spec,
                    ready.plan.clock_hz,
                    ready.ramp_cycles,
                );
            }
            Err(err) => warn!("new plan refused: {}", err),
        }
    }

    /// Feeds `event` to the supervisor, carries out its decision and returns it.
    fn handle(
        &mut self,
        event: SupervisorEvent,
        scheduler: Option<&mut Scheduler>,
    ) -> MotionRequest {
        let before = self.supervisor.state();
        let request = self.supervisor.handle(event);
        if let Some(scheduler) = scheduler {
            let traced = match request {
                MotionRequest::Keep => None,
                MotionRequest::Start => {
                    scheduler.start();
                    Some(trace::Request::Start)
                }
                MotionRequest::Stop => {
                    scheduler.stop();
                    Some(trace::Request::Stop)
                }
                MotionRequest::Halt => {
                    scheduler.halt();
                    Some(trace::Request::Halt)
                }
                MotionRequest::QuickStop => {
                    scheduler.quick_stop();
                    Some(trace::Request::QuickStop)
                }
            };
            if let Some(traced) = traced {
                trace::request(scheduler.next_tick(), traced);
            }
        }
        self.apply_driver();
        let after = self.supervisor.state();
        if after != before {
            info!("{} -> {}", before, after);
            self.report_latched_fault();
        }
        request
    }

    /// The driver is enabled while the supervisor lets it and the segment playing drives
    /// ([`SegmentKind::drives`]).
    fn apply_driver(&mut self) {
        self.set_driver(self.supervisor.driver_enabled() && !self.idle);
    }

    fn set_driver(&mut self, enabled: bool) {
        // Board pins are infallible; the fault path also drops the enable through the registers.
        let _ = if enabled {
            self.driver_enable.set_high()
        } else {
            self.driver_enable.set_low()
        };
    }

    fn report_latched_fault(&self) {
        if let RunState::Faulted(fault) = self.supervisor.state() {
            warn!("fault latched: {}", fault);
        }
    }

    /// Publishes the status, if it changed, for the tasks below the control loop, which run only
    /// once it waits.
    fn publish(&mut self) {
        let status = Status {
            state: self.supervisor.state(),
            led: self.supervisor.led(),
            phase: self.phase,
            cycle: self.cycle,
            least_slack_ticks: self.least_slack_ticks,
        };
        if status != self.published {
            status::publish(status);
            self.published = status;
        }
    }
}
