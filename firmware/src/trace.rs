//! The event stream for firmware-in-the-loop checks (`hil-trace` feature): one `EVT` line per
//! level change and per request, in the shared wire format ([`feeder_shared::event`]) that
//! `host-sim hil` replays against the scheduler. Requests carry the scheduler's next segment
//! start (`tick`), so the replay applies them at the same point. Each event is printed from
//! the values where they lie ([`feeder_shared::print_event!`]), at the cost of one
//! `defmt::println!`. Without the feature every function here compiles to nothing.

pub use feeder_shared::event::Request;
use feeder_shared::{Segment, WaveformSpec};

use crate::output::SegmentStart;

#[cfg(feature = "hil-trace")]
mod stream {
    use super::*;
    use feeder_shared::print_event;

    pub fn segment(segment: &Segment, start: SegmentStart) {
        print_event!(Segment {
            cycle: segment.cycle,
            kind: segment.kind,
            planned_tick: segment.start_tick,
            actual_tick: start.tick,
            ticks: segment.ticks,
            level: segment.level.sign(),
            step: segment.amplitude.step,
            steps: segment.amplitude.steps,
            slack_ticks: start.slack_ticks,
        })
    }

    pub fn plan(tick: u64, spec: &WaveformSpec, clock_hz: u32, ramp_cycles: u16) {
        print_event!(Plan {
            tick: tick,
            spec: spec,
            clock_hz: clock_hz,
            ramp_cycles: ramp_cycles,
        })
    }

    pub fn request(tick: u64, request: Request) {
        print_event!(Request {
            request: request,
            tick: tick,
        })
    }

    /// The end of a scripted run (QEMU without the console).
    #[cfg(all(feature = "board-qemu", not(feature = "console")))]
    pub fn end(tick: u64) {
        print_event!(End { tick: tick })
    }

    /// A missed edge on the emulated output: its timer found no new segment at `actual_tick`
    /// and played `segment`, the one playing, again. `slack_ticks` is the late preload's slack
    /// (negative), `None` if software had not tried yet.
    #[cfg(feature = "board-qemu")]
    pub fn replay(segment: &Segment, actual_tick: u64, slack_ticks: Option<i64>) {
        print_event!(Replay {
            cycle: segment.cycle,
            kind: segment.kind,
            planned_tick: segment.start_tick,
            actual_tick: actual_tick,
            ticks: segment.ticks,
            level: segment.level.sign(),
            step: segment.amplitude.step,
            steps: segment.amplitude.steps,
            slack_ticks: slack_ticks,
        })
    }

    /// The emulated output went to zero at `actual_tick` (a halt), or holds the zero code at the
    /// end of a failed run.
    #[cfg(feature = "board-qemu")]
    pub fn zero(actual_tick: u64) {
        print_event!(Zero {
            actual_tick: actual_tick
        })
    }

    /// The emulated driver enable at `actual_tick`, at the end of a failed run.
    #[cfg(feature = "board-qemu")]
    pub fn enable(actual_tick: u64, enabled: bool) {
        print_event!(Enable {
            actual_tick: actual_tick,
            enabled: enabled,
        })
    }

    /// Work per edge over a scripted run: from each edge to the preload of the next segment, in
    /// cycles of a `clock_hz` clock, over the `edges` whose next segment was preloaded in time.
    #[cfg(all(feature = "board-qemu", not(feature = "console")))]
    pub fn work(edges: u32, max_cycles: u32, total_cycles: u64, clock_hz: u32) {
        print_event!(Work {
            edges: edges,
            max_cycles: max_cycles,
            total_cycles: total_cycles,
            clock_hz: clock_hz,
        })
    }
}

#[cfg(not(feature = "hil-trace"))]
mod stream {
    use super::*;

    pub fn segment(_: &Segment, _: SegmentStart) {}
    pub fn plan(_: u64, _: &WaveformSpec, _: u32, _: u16) {}
    pub fn request(_: u64, _: Request) {}
}

pub use stream::*;
