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

    /// True when [`CheckReport::failures`] finds nothing.
    pub fn passed(&self) -> bool {
        self.failures().is_empty()
    }

    /// Each criterion the run missed, in words: it must report edges, each one present and as
    /// planned (kind, planned tick, length, level, amplitude), none missed, none changing the
    /// amplitude or the plan away from a cycle boundary, with no other problem, and end (where an
    /// end is required). The deviation of an edge's actual tick from its planned one is measured
    /// ([`CheckReport::deviation_histogram`]), not judged: the part is simulated on the actual
    /// ticks, so its effect shows in the feed rate and the plate's drift.
    pub fn failures(&self) -> Vec<String> {
        let mut failures = Vec::new();
        let mut count = |number: u64, what: &str| {
            if number > 0 {
                failures.push(format!("{number} {what}"));
            }
        };
        count(self.missing, "missing edge(s)");
        count(self.unexpected, "unexpected edge(s)");
        count(self.glitches, "change(s) away from a cycle boundary");
        count(self.missed.len() as u64, "missed edge(s)");
        if self.edges == 0 {
            failures.push("no edges reported".into());
        }
        let unended = self.end_required && !self.ended;
        if failures.is_empty() && !unended && !self.problems.is_empty() {
            failures.push(format!("{} problem(s)", self.problems.len()));
        }
        if unended {
            failures.push("the run did not end (no `end` event)".into());
        }
        failures
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

#[cfg(test)]
mod tests {
    use super::*;

    fn clean() -> CheckReport {
        CheckReport {
            edges: 4,
            matched: 4,
            deviation_histogram: BTreeMap::from([(0, 4)]),
            ended: true,
            end_required: true,
            ..CheckReport::default()
        }
    }

    #[test]
    fn a_run_whose_edges_are_all_as_planned_passes() {
        assert_eq!(clean().failures(), Vec::<String>::new());
        assert!(clean().passed());
    }

    #[test]
    fn each_missed_criterion_is_named() {
        let broken = CheckReport {
            matched: 1,
            missing: 1,
            unexpected: 2,
            glitches: 1,
            problems: vec!["missing edge at tick 9".into()],
            // Measured, not judged.
            deviation_histogram: BTreeMap::from([(0, 3), (-2, 1)]),
            ..clean()
        };
        assert_eq!(
            broken.failures(),
            [
                "1 missing edge(s)",
                "2 unexpected edge(s)",
                "1 change(s) away from a cycle boundary"
            ]
        );
    }

    #[test]
    fn a_run_without_its_end_fails_unless_cut_off_by_hand() {
        let cut = CheckReport {
            ended: false,
            problems: vec!["the stream has no `end` event: the firmware stopped early".into()],
            ..clean()
        };
        assert_eq!(cut.failures(), ["the run did not end (no `end` event)"]);
        let by_hand = CheckReport {
            end_required: false,
            problems: Vec::new(),
            ..cut
        };
        assert!(by_hand.passed());
    }
}
