//! What the control loop last published about the feeder, for the tasks below it: the LED, the
//! console and the scripted operator.

use core::cell::Cell;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use feeder_shared::closed_loop::{LoopReport, TrackReport};
use feeder_shared::{Led, Phase, RunState};

/// The feeder as the control loop sees it.
#[derive(Clone, Copy, PartialEq)]
pub struct Status {
    /// The supervisor's state, with the latched fault's cause.
    pub state: RunState,
    /// What the status LED shows.
    pub led: Led,
    /// Phase of the cycle being output.
    pub phase: Phase,
    /// The cycle (or idle period) begun last, counted from power-up.
    pub cycle: u64,
    /// The least preload slack over the cycle before it, in output ticks, where the stage reads
    /// it.
    pub least_slack_ticks: Option<u32>,
}

impl Status {
    /// Before the control loop has published anything: stopped, the LED off.
    pub const POWER_UP: Self = Self {
        state: RunState::Stopped,
        led: Led::Off,
        phase: Phase::Stopped,
        cycle: 0,
        least_slack_ticks: None,
    };
}

static STATUS: Mutex<CriticalSectionRawMutex, Cell<Status>> =
    Mutex::new(Cell::new(Status::POWER_UP));

/// Replaces the published status; the control loop's alone.
pub fn publish(status: Status) {
    STATUS.lock(|published| published.set(status));
}

/// The status as last published.
pub fn get() -> Status {
    STATUS.lock(Cell::get)
}

static CLOSED_LOOP: Mutex<CriticalSectionRawMutex, Cell<Option<LoopReport>>> =
    Mutex::new(Cell::new(None));

/// Replaces the closed loop's published report; the closed loop's alone.
pub fn publish_loop(report: LoopReport) {
    CLOSED_LOOP.lock(|published| published.set(Some(report)));
}

/// The closed loop's report as last published, for the console's `status` and the scripted
/// operator; `None` on a board that does not run one.
#[cfg(any(feature = "console", all(feature = "board-qemu", feature = "encoder")))]
pub fn closed_loop() -> Option<LoopReport> {
    CLOSED_LOOP.lock(Cell::get)
}

static TRACK: Mutex<CriticalSectionRawMutex, Cell<Option<TrackReport>>> =
    Mutex::new(Cell::new(None));

/// Replaces track control's published report; track control's alone.
pub fn publish_track(report: TrackReport) {
    TRACK.lock(|published| published.set(Some(report)));
}

/// Track control's report as last published, for the console's `status`; `None` on a board
/// without a part sensor.
#[cfg(feature = "console")]
pub fn track() -> Option<TrackReport> {
    TRACK.lock(Cell::get)
}

/// The feeder as the control loop last published it, as the operator's controller reads it.
#[cfg(feature = "console")]
pub fn snapshot() -> feeder_shared::Snapshot {
    let status = get();
    feeder_shared::Snapshot {
        state: status.state,
        phase: status.phase,
        uptime_ms: embassy_time::Instant::now().as_millis(),
        cycles: status.cycle,
        closed_loop: closed_loop(),
        track: track(),
    }
}
