//! The event stream for firmware-in-the-loop checks (`hil-trace` feature): one `EVT` line per
//! level change and per request, in the format `host-sim hil` replays against the scheduler.
//! Requests carry the scheduler's next segment start (`tick`), so the replay applies them at
//! the same point. Without the feature every function here compiles to nothing.

use feeder_shared::{Segment, WaveformSpec};

use crate::output::SegmentStart;

/// A request the control loop passed to the scheduler.
#[derive(Clone, Copy, defmt::Format)]
pub enum Request {
    Start,
    Stop,
    Halt,
    QuickStop,
}

#[cfg(feature = "hil-trace")]
mod stream {
    use super::*;
    use feeder_shared::Drive;

    pub fn segment(segment: &Segment, start: SegmentStart) {
        match start.slack_ticks {
            Some(slack_ticks) => defmt::println!(
                "EVT seg cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16} slack={=u32}",
                segment.cycle,
                segment.kind.name(),
                segment.start_tick,
                start.tick,
                segment.ticks,
                segment.level.sign(),
                segment.amplitude.step,
                segment.amplitude.steps,
                slack_ticks
            ),
            None => defmt::println!(
                "EVT seg cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16}",
                segment.cycle,
                segment.kind.name(),
                segment.start_tick,
                start.tick,
                segment.ticks,
                segment.level.sign(),
                segment.amplitude.step,
                segment.amplitude.steps
            ),
        }
    }

    pub fn plan(tick: u64, spec: &WaveformSpec, clock_hz: u32, ramp_cycles: u16) {
        match spec.drive {
            Drive::Stroke { stroke_m } => defmt::println!(
                "EVT plan tick={=u64} period_s={=f64} duty={=f64} stroke_m={=f64} clock_hz={=u32} ramp={=u16}",
                tick, spec.period_s, spec.duty, stroke_m, clock_hz, ramp_cycles
            ),
            Drive::Accel { accel_mps2 } => defmt::println!(
                "EVT plan tick={=u64} period_s={=f64} duty={=f64} accel_mps2={=f64} clock_hz={=u32} ramp={=u16}",
                tick, spec.period_s, spec.duty, accel_mps2, clock_hz, ramp_cycles
            ),
        }
    }

    pub fn request(tick: u64, request: Request) {
        let name = match request {
            Request::Start => "start",
            Request::Stop => "stop",
            Request::Halt => "halt",
            Request::QuickStop => "quickstop",
        };
        defmt::println!("EVT {=str} tick={=u64}", name, tick);
    }

    /// The end of a scripted run (QEMU without the console).
    #[cfg(all(feature = "board-qemu", not(feature = "console")))]
    pub fn end(tick: u64) {
        defmt::println!("EVT end tick={=u64}", tick);
    }

    /// A missed edge on the emulated output: its timer found no new segment at `actual_tick`
    /// and played `segment`, the one playing, again. `slack_ticks` is the late preload's slack
    /// (negative), `None` if software had not tried yet.
    #[cfg(feature = "board-qemu")]
    pub fn replay(segment: &Segment, actual_tick: u64, slack_ticks: Option<i64>) {
        match slack_ticks {
            Some(slack_ticks) => defmt::println!(
                "EVT replay cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16} slack={=i64}",
                segment.cycle,
                segment.kind.name(),
                segment.start_tick,
                actual_tick,
                segment.ticks,
                segment.level.sign(),
                segment.amplitude.step,
                segment.amplitude.steps,
                slack_ticks
            ),
            None => defmt::println!(
                "EVT replay cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16}",
                segment.cycle,
                segment.kind.name(),
                segment.start_tick,
                actual_tick,
                segment.ticks,
                segment.level.sign(),
                segment.amplitude.step,
                segment.amplitude.steps
            ),
        }
    }

    /// The emulated output went to zero at `actual_tick` (a halt), or holds the zero code at the
    /// end of a failed run.
    #[cfg(feature = "board-qemu")]
    pub fn zero(actual_tick: u64) {
        defmt::println!("EVT zero actual={=u64}", actual_tick);
    }

    /// The emulated driver enable at `actual_tick`, at the end of a failed run.
    #[cfg(feature = "board-qemu")]
    pub fn enable(actual_tick: u64, enabled: bool) {
        let state = if enabled { "on" } else { "off" };
        defmt::println!("EVT enable state={=str} actual={=u64}", state, actual_tick);
    }

    /// Work per edge over a scripted run: from each edge to the preload of the next segment, in
    /// cycles of a `clock_hz` clock, over the `edges` whose next segment was preloaded in time.
    #[cfg(all(feature = "board-qemu", not(feature = "console")))]
    pub fn work(edges: u32, max_cycles: u32, total_cycles: u64, clock_hz: u32) {
        defmt::println!(
            "EVT work edges={=u32} max_cycles={=u32} total_cycles={=u64} clock_hz={=u32}",
            edges,
            max_cycles,
            total_cycles,
            clock_hz
        );
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
