//! The watchdog monitor: feeds the board's watchdog while the application makes progress, and
//! measures the CPU cost of the work per edge with the DWT cycle counter.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use defmt::{info, unwrap, warn};
use embassy_executor::SendSpawner;
use embassy_time::{Duration, Ticker};

use crate::board;
use crate::ports::{Parts, Watchdog};
use crate::{config, configured};

/// The board's watchdog.
type BoardWatchdog = <board::Hardware as Parts>::Watchdog;

/// How often the monitor checks progress and feeds the watchdog.
const MONITOR_PERIOD_US: u64 = <BoardWatchdog as Watchdog>::MONITOR_PERIOD_US;
/// Whether the monitor runs above the tasks' executor and watches it (see [`spawn`]).
const WATCHES_TASKS: bool = <BoardWatchdog as Watchdog>::WATCHES_TASKS;

/// Counts the control loop's progress (segment starts, or parking ticks).
pub static HEARTBEAT: AtomicU32 = AtomicU32::new(0);
/// Counts the tasks' executor's progress (see [`tasks_heartbeat_task`]).
static TASKS_HEARTBEAT: AtomicU32 = AtomicU32::new(0);
/// CPU cost of the work per edge since the last report.
pub static COST: EdgeCost = EdgeCost::new();
/// Set when the DWT cycle counter runs, so that edge costs are measured.
static CYCLE_COUNTER_RUNS: AtomicBool = AtomicBool::new(false);

/// Monitor periods between two reports of the CPU cost of the edges.
const REPORT_EVERY_MONITOR_PERIODS: u32 = (config::REPORT_PERIOD_US / MONITOR_PERIOD_US) as u32;

/// Spawns the monitor. Where the watchdog's timeout ([`config::WATCHDOG_TIMEOUT_US`] on the board)
/// is shorter than the longest work of a task (a recipe write, tens of milliseconds), the monitor
/// runs on the control executor and the tasks' executor, `spawner`'s (thread mode, or with a
/// position sensor the task executor), beats for it; otherwise it runs on `spawner` with the
/// other tasks.
pub fn spawn(spawner: SendSpawner, control_spawner: SendSpawner, watchdog: BoardWatchdog) {
    if WATCHES_TASKS {
        control_spawner.spawn(unwrap!(monitor_task(watchdog)));
        spawner.spawn(unwrap!(tasks_heartbeat_task()));
    } else {
        spawner.spawn(unwrap!(monitor_task(watchdog)));
    }
}

/// Feeds the watchdog every monitor period while the application makes progress, runs the
/// board's hook after each feed (`board::after_feed`), and logs the CPU cost of the edges.
///
/// The control loop beats at every segment start, so it may go a whole segment without one: the
/// monitor stops feeding (and warns, once) only when it has not beaten for
/// [`config::control_progress_window_us`] at the configured lowest frequency. Where the monitor
/// runs above the tasks' executor (see [`spawn`]), that executor beats for it too.
#[embassy_executor::task]
async fn monitor_task(mut watchdog: BoardWatchdog) {
    let mut ticker = Ticker::every(Duration::from_micros(MONITOR_PERIOD_US));
    let mut control = Progress::new(
        &HEARTBEAT,
        config::control_progress_window_us(configured::get().limits.min_frequency_hz),
    );
    let mut tasks = WATCHES_TASKS
        .then(|| Progress::new(&TASKS_HEARTBEAT, config::TASKS_PROGRESS_WINDOW_US));
    let mut periods = 0u32;
    let mut report_start = cycles();
    loop {
        ticker.next().await;
        let control_alive = control.check("control loop");
        let tasks_alive = tasks
            .as_mut()
            .is_none_or(|progress| progress.check("the tasks"));
        if control_alive && tasks_alive && watchdog.feed() {
            board::after_feed();
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

/// Beats for the monitor from the tasks' executor, where the button, the LED and the console
/// run.
#[embassy_executor::task]
async fn tasks_heartbeat_task() {
    let mut ticker = Ticker::every(Duration::from_millis(config::TASKS_HEARTBEAT_MS));
    loop {
        TASKS_HEARTBEAT.fetch_add(1, Ordering::Relaxed);
        ticker.next().await;
    }
}

/// Reads the DWT cycle counter (enabled by [`enable_cycle_counter`]).
pub fn cycles() -> u32 {
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
pub struct EdgeCost {
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

    pub fn record(&self, cycles: u32) {
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
        #[cfg(feature = "console")]
        crate::telemetry::publish_cost(max_cycles, load_ppm as f64 / 1e4);
    }
}
