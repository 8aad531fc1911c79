//! The application: control loop, button, status LED and watchdog monitor. Board-independent;
//! the board hands over its parts (`crate::ports`) and runs the executors. This module holds what
//! the tasks share: the control loop's mailbox (requests, ready plans) and what it publishes.

mod control;
mod monitor;
mod panel;

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, AtomicU8};

use defmt::{info, unwrap};
use embassy_executor::SendSpawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use feeder_shared::{Error, Fault, Phase, RunState, TickClock, TickPlan, Waveform, WaveformSpec};

use crate::board;
use crate::config;
use crate::output::SegmentOutput;
use crate::ports::{Board, Operator, Parts};
use control::ControlLoop;
use monitor::EdgeCost;

type Output = <board::Hardware as Parts>::Output;
type DriverEnable = <board::Hardware as Parts>::DriverEnable;

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
/// Counts thread mode's progress (see `monitor`'s thread heartbeat).
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
    CYCLE.load(core::sync::atomic::Ordering::Relaxed)
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
    match STATE.load(core::sync::atomic::Ordering::Relaxed) {
        STATE_STOPPED => OperatorView::Stopped,
        STATE_RUNNING | STATE_STOPPING => OperatorView::Moving,
        _ => OperatorView::Faulted,
    }
}

/// The feeder as last published by the control loop, for the command console.
#[cfg(feature = "console")]
pub fn snapshot() -> feeder_shared::Snapshot {
    let phase = PHASES
        .get(usize::from(
            PHASE.load(core::sync::atomic::Ordering::Relaxed),
        ))
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
    match STATE.load(core::sync::atomic::Ordering::Relaxed) {
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
    monitor::enable_cycle_counter();
    board::announce();
    let clock = board.output.clock();
    let control = ControlLoop::new(
        board.output,
        board.driver_enable,
        board.after_watchdog_reset,
    );
    board.control_spawner.spawn(unwrap!(control_task(control)));
    spawner.spawn(unwrap!(panel::button_task(board.button)));
    spawner.spawn(unwrap!(panel::led_task(board.led)));
    monitor::spawn(spawner, board.control_spawner, board.watchdog);
    board.operator.spawn(spawner, clock);
}

#[embassy_executor::task]
async fn control_task(control: ControlLoop<Output, DriverEnable>) {
    control.run().await
}
