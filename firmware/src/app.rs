//! The application: control loop, button, status LED and watchdog monitor. Board-independent;
//! the board hands over its parts (`crate::ports`) and runs the executors.

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, AtomicU8, Ordering};

use defmt::{error, info, unwrap, warn};
use embassy_executor::SendSpawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Ticker, Timer};
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal_async::digital::Wait;
use feeder_shared::{
    Error, Fault, Led, MotionRequest, Phase, RunState, Scheduler, Segment, SegmentKind,
    StopCategory, Supervisor, SupervisorEvent, TickClock, TickPlan, Waveform, WaveformSpec,
};

use crate::board;
use crate::config;
use crate::output::SegmentOutput;
use crate::ports::{Board, Operator, Parts, Watchdog};
use crate::trace;

type Output = <board::Hardware as Parts>::Output;
type DriverEnable = <board::Hardware as Parts>::DriverEnable;
type Button = <board::Hardware as Parts>::Button;
type LedPin = <board::Hardware as Parts>::Led;
/// The board's watchdog.
type BoardWatchdog = <board::Hardware as Parts>::Watchdog;

/// How often the monitor checks progress and feeds the watchdog.
const MONITOR_PERIOD_US: u64 = <BoardWatchdog as Watchdog>::MONITOR_PERIOD_US;
/// Whether the monitor runs above thread mode and watches it (see [`spawn_monitor`]).
const WATCHES_THREAD_MODE: bool = <BoardWatchdog as Watchdog>::WATCHES_THREAD_MODE;

/// What an operator (the button, a script, a command line) asks of the control loop.
#[derive(Clone, Copy, defmt::Format)]
pub enum OperatorRequest {
    /// The start/stop button: start when stopped, soft stop when running.
    Toggle,
    #[cfg(any(feature = "board-qemu", feature = "console"))]
    Start,
    #[cfg(any(feature = "board-qemu", feature = "console"))]
    Stop,
    /// Acknowledge a latched fault.
    #[cfg(any(feature = "board-qemu", feature = "console"))]
    Reset,
}

/// A validated waveform planned on the output's clock, with its ramp length: all the arithmetic
/// of a change, done by the task that received it, so that the control loop only swaps it in.
#[derive(Clone, Copy)]
pub struct ReadyPlan {
    pub spec: WaveformSpec,
    pub plan: TickPlan,
    pub ramp_cycles: u16,
}

/// Operator requests, taken by the control loop at the next edge.
static REQUESTS: Channel<CriticalSectionRawMutex, OperatorRequest, 4> = Channel::new();
/// The newest plan the control loop has not taken yet. A newer one replaces it, so changes that
/// arrive faster than edges coalesce: the last accepted one runs from the next cycle boundary.
static NEXT_PLAN: Mutex<CriticalSectionRawMutex, Cell<Option<ReadyPlan>>> =
    Mutex::new(Cell::new(None));

/// What the status LED shows ([`Led`] as `u8`), published by the control loop.
static LED: AtomicU8 = AtomicU8::new(LED_OFF);
/// Cycles begun so far (low 32 bits), published by the control loop.
static CYCLE: AtomicU32 = AtomicU32::new(0);
/// The supervisor's state ([`RunState`] as `u8`, see [`encode_state`]), published by the control
/// loop.
static STATE: AtomicU8 = AtomicU8::new(STATE_STOPPED);
/// Phase of the cycle being output (index in [`PHASES`]), published by the control loop.
static PHASE: AtomicU8 = AtomicU8::new(Phase::Stopped as u8);
/// Set when the DWT cycle counter runs, so that edge costs are measured.
static CYCLE_COUNTER_RUNS: AtomicBool = AtomicBool::new(false);
/// Counts the control loop's progress (segment starts, or parking ticks).
static HEARTBEAT: AtomicU32 = AtomicU32::new(0);
/// Counts thread mode's progress (see [`thread_heartbeat_task`]).
static THREAD_HEARTBEAT: AtomicU32 = AtomicU32::new(0);
/// CPU cost of the work per edge since the last report.
static COST: EdgeCost = EdgeCost::new();

const LED_OFF: u8 = 0;
const LED_ON: u8 = 1;
const LED_BLINK: u8 = 2;

const STATE_STOPPED: u8 = 0;
const STATE_RUNNING: u8 = 1;
const STATE_STOPPING: u8 = 2;
/// Faulted: this plus the index of the cause in [`FAULTS`].
const STATE_FAULTED: u8 = 3;
const FAULTS: [Fault; 3] = [
    Fault::EdgeMissed,
    Fault::WatchdogReset,
    Fault::InvalidSettings,
];
const PHASES: [Phase; 4] = [
    Phase::Stopped,
    Phase::Starting,
    Phase::Running,
    Phase::Stopping,
];

/// Queues a request for the control loop; `false` if the queue is full and it was dropped.
pub fn request(request: OperatorRequest) -> bool {
    REQUESTS.try_send(request).is_ok()
}

/// Validates `spec` against the machine's limits and plans it on the output's `clock`, in the
/// caller's task.
pub fn plan(clock: TickClock, spec: &WaveformSpec, ramp_cycles: u16) -> Result<ReadyPlan, Error> {
    let waveform = Waveform::new(*spec, &config::LIMITS)?;
    let plan = TickPlan::new(&waveform, clock)?;
    info!(
        "plan: {=f64} Hz ({=u32} ticks of {=u32} Hz), d = {=f64}, a_max = {=f64} m/s², \
         x_max = {=f64} m, drift bound {=f64} m",
        plan.realized_frequency_hz(),
        plan.period_ticks,
        plan.clock_hz,
        waveform.duty,
        waveform.accel_mps2,
        waveform.stroke_m,
        plan.drift_bound_m
    );
    Ok(ReadyPlan {
        spec: *spec,
        plan,
        ramp_cycles,
    })
}

/// Hands a ready plan to the control loop, replacing any it has not taken yet.
#[cfg(any(feature = "board-qemu", feature = "console"))]
pub fn offer(ready: ReadyPlan) {
    NEXT_PLAN.lock(|next| next.set(Some(ready)));
}

/// Queues a request for the control loop, waiting for room in the queue.
#[cfg(feature = "console")]
pub async fn submit(request: OperatorRequest) {
    REQUESTS.send(request).await
}

/// Cycles (and idle periods) the output has begun, modulo 2³².
#[cfg(any(feature = "board-qemu", feature = "console"))]
pub fn cycles_begun() -> u32 {
    CYCLE.load(Ordering::Relaxed)
}

/// The run state as the scripted operator sees it.
#[cfg(all(feature = "board-qemu", not(feature = "console")))]
#[derive(Clone, Copy, PartialEq, Eq, defmt::Format)]
#[repr(u8)]
pub enum OperatorView {
    Stopped,
    /// Running or ramping down.
    Moving,
    Faulted,
}

/// The supervisor's state as last published by the control loop.
#[cfg(all(feature = "board-qemu", not(feature = "console")))]
pub fn state() -> OperatorView {
    match STATE.load(Ordering::Relaxed) {
        STATE_STOPPED => OperatorView::Stopped,
        STATE_RUNNING | STATE_STOPPING => OperatorView::Moving,
        _ => OperatorView::Faulted,
    }
}

/// The feeder as last published by the control loop, for the command console.
#[cfg(feature = "console")]
pub fn snapshot() -> feeder_shared::Snapshot {
    let phase = PHASES
        .get(usize::from(PHASE.load(Ordering::Relaxed)))
        .copied()
        .unwrap_or(Phase::Stopped);
    feeder_shared::Snapshot {
        state: run_state(),
        phase,
        uptime_ms: embassy_time::Instant::now().as_millis(),
        cycles: u64::from(cycles_begun()),
    }
}

#[cfg(feature = "console")]
fn run_state() -> RunState {
    match STATE.load(Ordering::Relaxed) {
        STATE_STOPPED => RunState::Stopped,
        STATE_RUNNING => RunState::Running,
        STATE_STOPPING => RunState::Stopping,
        faulted => RunState::Faulted(
            FAULTS
                .get(usize::from(faulted - STATE_FAULTED))
                .copied()
                .unwrap_or(Fault::InvalidSettings),
        ),
    }
}

fn encode_state(state: RunState) -> u8 {
    match state {
        RunState::Stopped => STATE_STOPPED,
        RunState::Running => STATE_RUNNING,
        RunState::Stopping => STATE_STOPPING,
        RunState::Faulted(fault) => STATE_FAULTED + index_of(&FAULTS, fault),
    }
}

/// Position of `value` in `table` (all tables here are short and complete).
fn index_of<T: PartialEq, const N: usize>(table: &[T; N], value: T) -> u8 {
    table.iter().position(|entry| *entry == value).unwrap_or(0) as u8
}

/// Spawns the tasks: the control loop on the board's control executor, above the others; the
/// button, the LED, the monitor and the operator on `spawner` (the monitor where the board's
/// watchdog needs it).
pub fn start(spawner: SendSpawner, board: Board<board::Hardware>) {
    enable_cycle_counter();
    board::announce();
    let clock = board.output.clock();
    let control = ControlLoop {
        output: board.output,
        driver_enable: board.driver_enable,
        supervisor: Supervisor::new(board.after_watchdog_reset),
        last_phase: Phase::Stopped,
    };
    board.control_spawner.spawn(unwrap!(control_task(control)));
    spawner.spawn(unwrap!(button_task(board.button)));
    spawner.spawn(unwrap!(led_task(board.led)));
    spawn_monitor(spawner, board.control_spawner, board.watchdog);
    board.operator.spawn(spawner, clock);
}

/// Spawns the monitor. Where the watchdog's timeout is shorter than the longest thread-mode work
/// (a recipe write, tens of milliseconds), the monitor runs on the control executor and thread
/// mode beats for it; otherwise it runs on `spawner` with the other tasks.
fn spawn_monitor(spawner: SendSpawner, control_spawner: SendSpawner, watchdog: BoardWatchdog) {
    if WATCHES_THREAD_MODE {
        control_spawner.spawn(unwrap!(monitor_task(watchdog)));
        spawner.spawn(unwrap!(thread_heartbeat_task()));
    } else {
        spawner.spawn(unwrap!(monitor_task(watchdog)));
    }
}

#[embassy_executor::task]
async fn control_task(control: ControlLoop<Output, DriverEnable>) {
    control.run().await
}

/// Turns debounced presses of the start/stop button into requests for the control loop.
#[embassy_executor::task]
async fn button_task(mut button: Button) {
    loop {
        if Wait::wait_for_rising_edge(&mut button).await.is_err() {
            continue;
        }
        Timer::after_millis(config::DEBOUNCE_MS).await;
        if InputPin::is_high(&mut button) == Ok(true) {
            request(OperatorRequest::Toggle);
            while Wait::wait_for_low(&mut button).await.is_err() {}
            Timer::after_millis(config::DEBOUNCE_MS).await;
        }
    }
}

/// Off when stopped, on while moving, blinking on a fault.
#[embassy_executor::task]
async fn led_task(mut led: LedPin) {
    let mut lit = false;
    loop {
        lit = match LED.load(Ordering::Relaxed) {
            LED_ON => true,
            LED_BLINK => !lit,
            _ => false,
        };
        // Board pins are infallible; a failed write only leaves the LED as it was.
        let _ = if lit {
            OutputPin::set_high(&mut led)
        } else {
            OutputPin::set_low(&mut led)
        };
        Timer::after_millis(config::BLINK_HALF_PERIOD_MS).await;
    }
}

/// Feeds the watchdog every monitor period while the application makes progress, and logs the
/// CPU cost of the edges.
///
/// The control loop beats at every segment start, so it may go a whole segment without one: the
/// monitor stops feeding (and warns, once) only when it has not beaten for
/// [`config::CONTROL_PROGRESS_WINDOW_US`]. Where the monitor runs above thread mode (see
/// [`spawn_monitor`]), thread mode beats for it too.
#[embassy_executor::task]
async fn monitor_task(mut watchdog: BoardWatchdog) {
    let mut ticker = Ticker::every(Duration::from_micros(MONITOR_PERIOD_US));
    let mut control = Progress::new(&HEARTBEAT, config::CONTROL_PROGRESS_WINDOW_US);
    let mut thread_mode = WATCHES_THREAD_MODE
        .then(|| Progress::new(&THREAD_HEARTBEAT, config::THREAD_PROGRESS_WINDOW_US));
    let mut periods = 0u32;
    let mut report_start = cycles();
    loop {
        ticker.next().await;
        let control_alive = control.check("control loop");
        let thread_mode_alive = thread_mode
            .as_mut()
            .is_none_or(|progress| progress.check("thread mode"));
        if control_alive && thread_mode_alive {
            watchdog.feed();
        }
        periods += 1;
        if periods == REPORT_EVERY_MONITOR_PERIODS && CYCLE_COUNTER_RUNS.load(Ordering::Relaxed) {
            periods = 0;
            let now = cycles();
            COST.report(now.wrapping_sub(report_start));
            report_start = now;
        }
    }
}

/// Monitor periods between two reports of the CPU cost of the edges.
const REPORT_EVERY_MONITOR_PERIODS: u32 = (config::REPORT_PERIOD_US / MONITOR_PERIOD_US) as u32;

/// Beats of one part of the application, as the monitor sees them.
struct Progress {
    beats: &'static AtomicU32,
    last_beat: u32,
    /// Monitor periods since the last beat.
    quiet_periods: u32,
    /// Monitor periods without a beat after which the part counts as stuck.
    window_periods: u32,
}

impl Progress {
    fn new(beats: &'static AtomicU32, window_us: u64) -> Self {
        Self {
            beats,
            last_beat: beats.load(Ordering::Relaxed),
            quiet_periods: 0,
            window_periods: window_us.div_ceil(MONITOR_PERIOD_US) as u32,
        }
    }

    /// True while the part has beaten within its window; warns once when it stops.
    fn check(&mut self, part: &str) -> bool {
        let beat = self.beats.load(Ordering::Relaxed);
        if beat != self.last_beat {
            self.last_beat = beat;
            self.quiet_periods = 0;
            return true;
        }
        self.quiet_periods = self.quiet_periods.saturating_add(1);
        if self.quiet_periods == self.window_periods {
            warn!(
                "{=str} made no progress for {=u64} µs: the watchdog is no longer fed",
                part,
                u64::from(self.quiet_periods) * MONITOR_PERIOD_US
            );
        }
        self.quiet_periods < self.window_periods
    }
}

/// Beats for the monitor from thread mode, where the button, the LED and the console run.
#[embassy_executor::task]
async fn thread_heartbeat_task() {
    let mut ticker = Ticker::every(Duration::from_millis(config::THREAD_HEARTBEAT_MS));
    loop {
        THREAD_HEARTBEAT.fetch_add(1, Ordering::Relaxed);
        ticker.next().await;
    }
}

/// Reads the DWT cycle counter (enabled by [`enable_cycle_counter`]).
fn cycles() -> u32 {
    cortex_m::peripheral::DWT::cycle_count()
}

/// Starts the DWT cycle counter used to measure the work per edge.
pub fn enable_cycle_counter() {
    match cortex_m::Peripherals::take() {
        Some(mut core) => {
            core.DCB.enable_trace();
            core.DWT.enable_cycle_counter();
            let start = cycles();
            cortex_m::asm::delay(100);
            if cycles() != start {
                CYCLE_COUNTER_RUNS.store(true, Ordering::Relaxed);
            } else {
                warn!("no DWT cycle counter: edge cost is not measured");
            }
        }
        None => warn!("core peripherals taken: edge cost is not measured"),
    }
}

/// Sums of the CPU cycles spent per edge, reset at every report.
struct EdgeCost {
    edges: AtomicU32,
    cycles: AtomicU32,
    max_cycles: AtomicU32,
}

impl EdgeCost {
    const fn new() -> Self {
        Self {
            edges: AtomicU32::new(0),
            cycles: AtomicU32::new(0),
            max_cycles: AtomicU32::new(0),
        }
    }

    fn record(&self, cycles: u32) {
        self.edges.fetch_add(1, Ordering::Relaxed);
        self.cycles.fetch_add(cycles, Ordering::Relaxed);
        self.max_cycles.fetch_max(cycles, Ordering::Relaxed);
    }

    /// Logs and clears the sums; `elapsed_cycles` is the CPU time since the last report.
    fn report(&self, elapsed_cycles: u32) {
        let edges = self.edges.swap(0, Ordering::Relaxed);
        let cycles = self.cycles.swap(0, Ordering::Relaxed);
        let max_cycles = self.max_cycles.swap(0, Ordering::Relaxed);
        let mean_cycles = cycles.checked_div(edges).unwrap_or(0);
        let load_ppm = (u64::from(cycles) * 1_000_000)
            .checked_div(u64::from(elapsed_cycles))
            .unwrap_or(0);
        info!(
            "edges: {=u32}, cycles per edge: mean {=u32} max {=u32}, CPU load {=u64} ppm",
            edges, mean_cycles, max_cycles, load_ppm
        );
    }
}

/// Runs the scheduler into the output stage and applies the supervisor's decisions.
struct ControlLoop<O, E> {
    output: O,
    driver_enable: E,
    supervisor: Supervisor,
    last_phase: Phase,
}

impl<O: SegmentOutput, E: OutputPin> ControlLoop<O, E> {
    async fn run(mut self) -> ! {
        self.publish();
        match self.plan() {
            Some(plan) => self.run_plan(plan).await,
            None => self.park().await,
        }
    }

    /// The configured waveform planned on the output's clock, or `None` if it is refused.
    fn plan(&mut self) -> Option<TickPlan> {
        let plan = match plan(self.output.clock(), &config::WAVEFORM, config::RAMP_CYCLES) {
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
        trace::plan(0, &config::WAVEFORM, plan.clock_hz, config::RAMP_CYCLES);
        Some(plan)
    }

    /// Invalid settings: stay at zero with the driver disabled; only a reset helps. Beats for the
    /// monitor well within its window, so that the watchdog stays fed.
    async fn park(mut self) -> ! {
        self.handle(SupervisorEvent::Fault(Fault::InvalidSettings), None);
        loop {
            HEARTBEAT.fetch_add(1, Ordering::Relaxed);
            Timer::after_millis(config::PARK_HEARTBEAT_MS).await;
        }
    }

    async fn run_plan(mut self, plan: TickPlan) -> ! {
        let mut scheduler = Scheduler::new(plan, config::RAMP_CYCLES);
        let mut queued = self.resync(&mut scheduler);
        loop {
            let edge = self.output.wait_edge().await;
            let work_start = cycles();
            if edge.is_err() {
                queued = self.fail(Fault::EdgeMissed, queued, &mut scheduler);
                continue;
            }
            self.begin(&queued, &mut scheduler);
            queued = scheduler.next_segment();
            if let Err(fault) = self.prepare(&queued) {
                queued = self.fail(fault, queued, &mut scheduler);
                continue;
            }
            COST.record(cycles().wrapping_sub(work_start));
        }
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

    /// Work at the start of every segment: supervision and pending requests.
    fn begin(&mut self, playing: &Segment, scheduler: &mut Scheduler) {
        HEARTBEAT.fetch_add(1, Ordering::Relaxed);
        trace::segment(playing, self.output.started(playing));
        if playing.starts_cycle() {
            CYCLE.store(playing.cycle as u32, Ordering::Relaxed);
        }
        if playing.phase != self.last_phase {
            info!("cycle {=u64}: {}", playing.cycle, playing.phase);
            self.last_phase = playing.phase;
            PHASE.store(index_of(&PHASES, playing.phase), Ordering::Relaxed);
        }
        if playing.kind == SegmentKind::Idle {
            self.handle(SupervisorEvent::OutputIdle, Some(scheduler));
        }
        while let Ok(request) = REQUESTS.try_receive() {
            let event = match request {
                OperatorRequest::Toggle => SupervisorEvent::ButtonPressed,
                #[cfg(any(feature = "board-qemu", feature = "console"))]
                OperatorRequest::Start => SupervisorEvent::StartRequested,
                #[cfg(any(feature = "board-qemu", feature = "console"))]
                OperatorRequest::Stop => SupervisorEvent::StopRequested,
                #[cfg(any(feature = "board-qemu", feature = "console"))]
                OperatorRequest::Reset => SupervisorEvent::ResetRequested,
            };
            self.handle(event, Some(scheduler));
        }
        if let Some(ready) = NEXT_PLAN.lock(Cell::take) {
            self.adopt(&ready, scheduler);
        }
    }

    /// Queues a ready plan for the next cycle boundary: O(1), no arithmetic.
    fn adopt(&mut self, ready: &ReadyPlan, scheduler: &mut Scheduler) {
        match scheduler.set_plan(ready.plan) {
            Ok(()) => {
                scheduler.set_ramp_cycles(ready.ramp_cycles);
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
        self.set_driver(self.supervisor.driver_enabled());
        let after = self.supervisor.state();
        if after != before {
            info!("{} -> {}", before, after);
            self.publish();
        }
        request
    }

    fn set_driver(&mut self, enabled: bool) {
        // Board pins are infallible; the fault path also drops the enable through the registers.
        let _ = if enabled {
            self.driver_enable.set_high()
        } else {
            self.driver_enable.set_low()
        };
    }

    fn publish(&self) {
        let led = match self.supervisor.led() {
            Led::Off => LED_OFF,
            Led::On => LED_ON,
            Led::Blink => LED_BLINK,
        };
        LED.store(led, Ordering::Relaxed);
        STATE.store(encode_state(self.supervisor.state()), Ordering::Relaxed);
        if let RunState::Faulted(fault) = self.supervisor.state() {
            warn!("fault latched: {}", fault);
        }
    }
}
