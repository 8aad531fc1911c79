//! What the replay found: how the recorded run compares with the shared scheduler, and the work
//! per edge the firmware reported.

use std::collections::BTreeMap;

use serde::Serialize;

use feeder_shared::event::{self, SegmentEvent};

/// Work per edge over a run: from each edge (when the output switched) to the preload of the
/// next segment, wake-up included, in cycles of a `clock_hz` clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct EdgeWork {
    pub edges: u64,
    pub max_cycles: u64,
    pub total_cycles: u64,
    pub clock_hz: u64,
}

impl EdgeWork {
    pub fn max_ns(&self) -> f64 {
        self.max_cycles as f64 * 1e9 / self.clock_hz.max(1) as f64
    }

    pub fn mean_ns(&self) -> f64 {
        if self.edges == 0 {
            return 0.0;
        }
        self.total_cycles as f64 * 1e9 / self.clock_hz.max(1) as f64 / self.edges as f64
    }
}

impl From<event::EdgeWork> for EdgeWork {
    fn from(work: event::EdgeWork) -> Self {
        EdgeWork {
            edges: work.edges.into(),
            max_cycles: work.max_cycles.into(),
            total_cycles: work.total_cycles,
            clock_hz: work.clock_hz.into(),
        }
    }
}

/// How the recorded run compares with the shared scheduler.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CheckReport {
    /// Segment events read.
    pub edges: u64,
    /// Events that matched the replay exactly.
    pub matched: u64,
    /// Planned segments the firmware never reported.
    pub missing: u64,
    /// Reported segments the replay did not produce (or produced differently).
    pub unexpected: u64,
    /// Amplitude or plan changes away from a cycle boundary.
    pub glitches: u64,
    /// Number of motion cycles (not idle periods) completed.
    pub motion_cycles: u64,
    /// `actual − planned` in ticks, after the shift of the last restart: count per value.
    pub deviation_histogram: BTreeMap<i64, u64>,
    /// Preload slack of the segments that began: count per bucket, keyed by its lower bound
    /// (see [`slack_bucket`]).
    pub slack_histogram: BTreeMap<i64, u64>,
    /// The smallest of those slacks and the planned tick of its segment.
    pub min_slack: Option<(i64, u64)>,
    /// The missed edges: each the output's replay of the segment playing.
    pub missed: Vec<SegmentEvent>,
    /// Work per edge, when the firmware reports it.
    pub edge_work: Option<EdgeWork>,
    /// The first problems found, in words.
    pub problems: Vec<String>,
    /// Whether the stream ended with an `end` event.
    pub ended: bool,
    /// Whether the run had to end with an `end` event (a scripted run does; a log of a board
    /// run cut off by hand does not).
    pub end_required: bool,
}

impl CheckReport {
    pub fn max_deviation_ticks(&self) -> i64 {
        self.deviation_histogram
            .keys()
            .map(|d| d.abs())
            .max()
            .unwrap_or(0)
    }

    /// True when every edge was present, exact, on time and glitch-free and the run ended.
    pub fn passed(&self) -> bool {
        (self.ended || !self.end_required)
            && self.edges > 0
            && self.missed.is_empty()
            && self.missing == 0
            && self.unexpected == 0
            && self.glitches == 0
            && self.problems.is_empty()
    }
}

/// The bucket of a slack in [`CheckReport::slack_histogram`]: 0 for no slack, else the power of
/// two at or below it (the bucket `2^k` holds `2^k ..= 2^(k+1) − 1`).
pub fn slack_bucket(slack_ticks: i64) -> i64 {
    if slack_ticks <= 0 {
        0
    } else {
        1 << slack_ticks.ilog2()
    }
}
