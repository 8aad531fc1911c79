//! The edges the replay keeps: each level change with where it came from and what it commands,
//! on the output's actual timeline or the scheduler's planned one.

use feeder_shared::event::SegmentEvent;
use feeder_shared::SegmentKind;

/// Which instant of each edge the simulation uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeTimes {
    /// When the level took effect, as the firmware measured it.
    Actual,
    /// The scheduler's planned tick.
    Planned,
}

/// How an edge came about, and so on which timeline it lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeSource {
    /// A planned segment that began on the output: on both timelines.
    Played,
    /// A planned segment that never began because a missed edge halted the output: planned
    /// only, and at zero, as the halt would have been on time.
    Unplayed,
    /// The output's replay of the playing segment at a missed edge: actual only.
    Replayed,
    /// The output's zero at a halt: actual only.
    Zeroed,
}

impl EdgeSource {
    pub(super) fn on(self, times: EdgeTimes) -> bool {
        match self {
            EdgeSource::Played => true,
            EdgeSource::Unplayed => times == EdgeTimes::Planned,
            EdgeSource::Replayed | EdgeSource::Zeroed => times == EdgeTimes::Actual,
        }
    }
}

/// A level change with what the replay knows about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    pub source: EdgeSource,
    /// When it took effect on the output (an unplayed edge: its planned tick).
    pub actual_tick: u64,
    /// The scheduler's tick (an edge of the output alone: its actual tick).
    pub planned_tick: u64,
    /// The planned length, which the last edge holds for.
    pub ticks: u32,
    /// The plate acceleration it commands.
    pub accel_mps2: f64,
    /// It begins a cycle or idle period.
    pub starts_cycle: bool,
    /// It begins a cycle at its plan's full amplitude.
    pub full_amplitude: bool,
    /// How many plan changes had taken effect by this edge.
    pub plan_index: usize,
}

impl Edge {
    /// A segment as the firmware reported it, with `a_max` of the plan in force.
    pub(super) fn reported(
        source: EdgeSource,
        event: &SegmentEvent,
        peak_accel_mps2: f64,
        plan_index: usize,
    ) -> Self {
        let amplitude = f64::from(event.step) / f64::from(event.steps.max(1));
        Edge {
            source,
            actual_tick: event.actual_tick,
            planned_tick: event.planned_tick,
            ticks: event.ticks,
            accel_mps2: f64::from(event.level) * peak_accel_mps2 * amplitude,
            starts_cycle: event.starts_cycle() && source == EdgeSource::Played,
            full_amplitude: event.kind == SegmentKind::Accelerate && event.step == event.steps,
            plan_index,
        }
    }
}
