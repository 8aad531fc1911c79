//! The work per edge, measured on the clock timer, and the late preload a script may provoke.

use core::cell::Cell;
use core::sync::atomic::{AtomicU32, Ordering};

use critical_section::Mutex;
use feeder_shared::Segment;

use super::time_driver::{self, CYCLES_PER_TICK};

/// Cycle whose first segment the output stage preloads late, once (`u32::MAX`: none).
static LATE_PRELOAD_CYCLE: AtomicU32 = AtomicU32::new(u32::MAX);
/// How far past its deadline the provoked late preload comes.
const LATE_PRELOAD_TICKS: u64 = 50;
/// The work per edge so far.
static EDGE_WORK: Mutex<Cell<EdgeWork>> = Mutex::new(Cell::new(EdgeWork {
    edges: 0,
    max_cycles: 0,
    total_cycles: 0,
}));

/// Work per edge: timer cycles from an edge (when the output switched) to the preload of the
/// next segment, wake-up included, over the edges whose next segment was preloaded in time.
#[derive(Clone, Copy)]
pub struct EdgeWork {
    pub edges: u32,
    pub max_cycles: u32,
    pub total_cycles: u64,
}

/// Makes the software preload the first segment of `cycle` after its deadline, as an overrun
/// would: the missed edge of a scripted run.
#[cfg(not(feature = "console"))]
pub fn provoke_late_preload(cycle: u32) {
    LATE_PRELOAD_CYCLE.store(cycle, Ordering::Relaxed);
}

/// The work per edge of the run so far.
#[cfg(not(feature = "console"))]
pub fn edge_work() -> EdgeWork {
    critical_section::with(|cs| EDGE_WORK.borrow(cs).get())
}

/// Holds the software up past `deadline_cycles` if `segment` is the one whose late preload the
/// scenario provoked: an overrun of the control loop.
pub fn overrun_if_provoked(segment: &Segment, deadline_cycles: u64) {
    let provoked = segment.starts_cycle()
        && LATE_PRELOAD_CYCLE
            .compare_exchange(
                segment.cycle as u32,
                u32::MAX,
                Ordering::Relaxed,
                Ordering::Relaxed,
            )
            .is_ok();
    if provoked {
        let late_cycles = deadline_cycles + LATE_PRELOAD_TICKS * CYCLES_PER_TICK;
        while time_driver::now_cycles() < late_cycles {}
    }
}

/// Adds one edge's work, in timer cycles, to the run's.
pub fn record_edge_work(cycles: u64) {
    let cycles = u32::try_from(cycles).unwrap_or(u32::MAX);
    critical_section::with(|cs| {
        let work = EDGE_WORK.borrow(cs);
        let mut sums = work.get();
        sums.edges += 1;
        sums.max_cycles = sums.max_cycles.max(cycles);
        sums.total_cycles += u64::from(cycles);
        work.set(sums);
    })
}
