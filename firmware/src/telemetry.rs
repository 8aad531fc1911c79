//! The parts of the telemetry record (`feeder_shared::telemetry`) that the tasks publish, each
//! below the edge path, and the record the console assembles from them when the link has room
//! for a line.

use core::cell::Cell;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use feeder_shared::closed_loop::{Stage, Trims};
use feeder_shared::telemetry::Record;
use feeder_shared::RunState;

use crate::status;

/// What the closed loop saw of the cycle it measured last and decided.
#[derive(Clone, Copy)]
struct LoopPart {
    stage: Stage,
    /// Mean and farthest position over the cycle, m.
    positions: Option<(f64, f64)>,
    trims: Option<Trims>,
}

/// What the monitor measured of the edges over its last report period.
#[derive(Clone, Copy)]
struct CostPart {
    max_cycles: u32,
    load_pct: f64,
}

static LOOP: Mutex<CriticalSectionRawMutex, Cell<Option<LoopPart>>> = Mutex::new(Cell::new(None));
static COST: Mutex<CriticalSectionRawMutex, Cell<Option<CostPart>>> = Mutex::new(Cell::new(None));

/// The closed loop's part: its stage, the cycle's mean and farthest position (`positions`, m)
/// and the trims it decided last.
pub fn publish_loop(stage: Stage, positions: Option<(f64, f64)>, trims: Option<Trims>) {
    LOOP.lock(|part| {
        part.set(Some(LoopPart {
            stage,
            positions,
            trims,
        }))
    });
}

/// The monitor's part: the most cycles from an edge to its preload and the edges' CPU load.
pub fn publish_cost(max_cycles: u32, load_pct: f64) {
    COST.lock(|part| {
        part.set(Some(CostPart {
            max_cycles,
            load_pct,
        }))
    });
}

/// The record of the cycle begun last, at `uptime_ms`.
#[cfg(feature = "console")]
pub fn record(uptime_ms: u64) -> Record {
    let published = status::get();
    let fault = match published.state {
        RunState::Faulted(fault) => Some(fault),
        _ => None,
    };
    let mut record = Record::new(published.cycle, uptime_ms, published.phase, fault);
    record.slack_ticks = published.least_slack_ticks;
    if let Some(part) = LOOP.lock(Cell::get) {
        record.stage = Some(part.stage);
        record.mean_m = part.positions.map(|(mean_m, _)| mean_m);
        record.peak_m = part.positions.map(|(_, peak_m)| peak_m);
        record.trim_positive = part.trims.map(|trims| trims.positive);
        record.trim_negative = part.trims.map(|trims| trims.negative);
        record.bias_mps2 = part.trims.map(|trims| trims.bias_mps2);
    }
    if let Some(part) = COST.lock(Cell::get) {
        record.edge_work_cycles = Some(part.max_cycles);
        record.cpu_load_pct = Some(part.load_pct);
    }
    if let Some(track) = status::track() {
        record.track = Some(track.state);
        record.parts_per_minute = Some(track.parts_per_minute);
    }
    record
}
