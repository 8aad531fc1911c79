//! The firmware's event stream (`EVT` lines): one type, its text encoding and its parser.
//!
//! The firmware prints one event per line, as a defmt frame of its own
//! ([`print_event!`](crate::print_event)); a decoded log carries it anywhere in a line, after the
//! marker [`EVENT_MARKER`]:
//!
//! ```text
//! EVT plan tick=0 period_s=0.02 duty=0.586 stroke_m=0.0025 clock_hz=1000000 ramp=4
//! EVT start tick=20000
//! EVT seg cycle=1 kind=accelerate planned=20000 actual=20000 ticks=1713 level=1 step=1 steps=4 slack=19830
//! EVT replay cycle=9 kind=return planned=195860 actual=200000 ticks=4140 level=1 step=4 steps=4 slack=-51
//! EVT zero actual=200057
//! EVT enable state=off actual=200060
//! EVT stop tick=1000000
//! EVT halt tick=1000000
//! EVT work edges=90 max_cycles=4236 total_cycles=151414 clock_hz=25000000
//! EVT end tick=1200000
//! ```
//!
//! `tick` on a request is the scheduler's next segment start when the request was made;
//! `accel_mps2=` may stand for `stroke_m=`. `actual` is when a level took effect on the output's
//! own timeline, `slack` (optional) how many ticks before its start a segment was preloaded.
//!
//! Each event's text is written once, in [`event_text!`](crate::event_text), as a defmt format
//! string with defmt's typed parameters (`{=u64}`, `{=f64}`, `{=str}` …). The same strings give
//! the firmware's frames ([`print_event!`](crate::print_event)), [`Event`]'s `defmt::Format`
//! (feature `defmt`) and its `Display`, which writes each parameter as defmt's decoder prints
//! it; [`parse_line`] reads that text back. An event of a new kind is a variant of [`Event`], an
//! arm in `event_text!` and in `encode!`, and one in the parser.
//!
//! The text and the parser stay clear of core's generic string code that the firmware
//! instantiates too (`str` slicing and comparison, `split_whitespace`): a second instantiation
//! changes what link-time optimisation makes of the firmware, and so the timing of its edge path,
//! which the emulated board's log records.

use crate::{Segment, SegmentKind, WaveformSpec};

/// The marker that starts an event inside a log line.
pub const EVENT_MARKER: &str = "EVT ";

/// One event of the firmware's stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// A plan the scheduler takes at `tick` (`0`: the power-up plan).
    Plan {
        tick: u64,
        spec: WaveformSpec,
        clock_hz: u32,
        ramp_cycles: u16,
    },
    Start {
        tick: u64,
    },
    Stop {
        tick: u64,
    },
    /// Fault stop: output zeroed at once.
    Halt {
        tick: u64,
    },
    /// Controlled fault stop: the cycle in progress ends at rest, then idle.
    QuickStop {
        tick: u64,
    },
    /// A level change.
    Segment(SegmentEvent),
    /// A missed edge: the output played the segment again from `actual_tick`.
    Replay(SegmentEvent),
    /// The output went to zero (a halt), or holds zero at the end of a failed run.
    Zero {
        actual_tick: u64,
    },
    /// The driver enable at the end of a failed run.
    Enable {
        actual_tick: u64,
        enabled: bool,
    },
    /// Work per edge over a scripted run.
    Work(EdgeWork),
    /// The end of a scripted run.
    End {
        tick: u64,
    },
}

impl Event {
    /// The event's name, the first word after the marker.
    pub const fn name(&self) -> &'static str {
        match self {
            Event::Plan { .. } => "plan",
            Event::Start { .. } => Request::Start.name(),
            Event::Stop { .. } => Request::Stop.name(),
            Event::Halt { .. } => Request::Halt.name(),
            Event::QuickStop { .. } => Request::QuickStop.name(),
            Event::Segment(_) => "seg",
            Event::Replay(_) => "replay",
            Event::Zero { .. } => "zero",
            Event::Enable { .. } => "enable",
            Event::Work(_) => "work",
            Event::End { .. } => "end",
        }
    }
}

/// A request the control loop passed to the scheduler: the events `start`, `stop`, `halt` and
/// `quickstop`, which share one text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    Start,
    Stop,
    Halt,
    QuickStop,
}

impl Request {
    /// The request's event name.
    pub const fn name(self) -> &'static str {
        match self {
            Request::Start => "start",
            Request::Stop => "stop",
            Request::Halt => "halt",
            Request::QuickStop => "quickstop",
        }
    }
}

/// A segment as the output played it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentEvent {
    pub cycle: u64,
    pub kind: SegmentKind,
    /// The scheduler's start tick.
    pub planned_tick: u64,
    /// When it took effect on the output's timeline.
    pub actual_tick: u64,
    pub ticks: u32,
    /// The level's sign: `-1`, `0` or `1`.
    pub level: i8,
    pub step: u16,
    pub steps: u16,
    /// Ticks from the preload to the start: the segment's deadline minus the moment it was
    /// preloaded. A segment that began was preloaded in time (`0 ..= u32::MAX`); only a replay
    /// reports a late one (negative). `None` where the firmware does not report it (a restart).
    pub slack_ticks: Option<i64>,
}

impl SegmentEvent {
    /// `segment` as the output played it from `actual_tick`.
    pub fn played(segment: &Segment, actual_tick: u64, slack_ticks: Option<i64>) -> Self {
        SegmentEvent {
            cycle: segment.cycle,
            kind: segment.kind,
            planned_tick: segment.start_tick,
            actual_tick,
            ticks: segment.ticks,
            level: segment.level.sign(),
            step: segment.amplitude.step,
            steps: segment.amplitude.steps,
            slack_ticks,
        }
    }

    /// True for the first segment of a cycle, idle period or settle segment.
    pub fn starts_cycle(&self) -> bool {
        self.kind.starts_cycle()
    }

    /// The slack of a segment that began, as its `seg` line carries it (`{=u32}`): a negative
    /// slack, which only a replay has, reads as `0`.
    fn began_slack_ticks(slack_ticks: i64) -> u32 {
        u32::try_from(slack_ticks.max(0)).unwrap_or(u32::MAX)
    }
}

/// Work per edge over a run: from each edge (when the output switched) to the preload of the
/// next segment, wake-up included, in cycles of a `clock_hz` clock, over the `edges` whose next
/// segment was preloaded in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgeWork {
    pub edges: u32,
    pub max_cycles: u32,
    pub total_cycles: u64,
    pub clock_hz: u32,
}

/// The wire format, the one statement of each event's text: `$emit!` gets the event's defmt
/// format string (defmt's typed parameters: `{=u64}`, `{=f64}`, `{=str}` …) and its arguments,
/// after `$sink` if one is given. The event is written as its [`event::Event`](crate::event::Event)
/// variant with every field named, in order; a field is any expression of the field's type (a
/// request's `request` an [`event::Request`](crate::event::Request), a segment's `level` its
/// sign, its `slack_ticks` an `Option<u32>` for `Segment` and `Option<i64>` for `Replay`).
#[macro_export]
macro_rules! event_text {
    ($($emit:ident)::+ ($($sink:expr)?), Plan {
        tick: $tick:expr, spec: $spec:expr, clock_hz: $clock_hz:expr, ramp_cycles: $ramp:expr $(,)?
    }) => {
        match $spec.drive {
            $crate::Drive::Stroke { stroke_m } => $($emit)::+!(
                $($sink,)?
                "EVT plan tick={=u64} period_s={=f64} duty={=f64} stroke_m={=f64} clock_hz={=u32} ramp={=u16}",
                $tick, $spec.period_s, $spec.duty, stroke_m, $clock_hz, $ramp
            ),
            $crate::Drive::Accel { accel_mps2 } => $($emit)::+!(
                $($sink,)?
                "EVT plan tick={=u64} period_s={=f64} duty={=f64} accel_mps2={=f64} clock_hz={=u32} ramp={=u16}",
                $tick, $spec.period_s, $spec.duty, accel_mps2, $clock_hz, $ramp
            ),
        }
    };
    ($($emit:ident)::+ ($($sink:expr)?), Request { request: $request:expr, tick: $tick:expr $(,)? }) => {
        $($emit)::+!($($sink,)? "EVT {=str} tick={=u64}", $request.name(), $tick)
    };
    ($($emit:ident)::+ ($($sink:expr)?), $variant:ident {
        cycle: $cycle:expr, kind: $kind:expr, planned_tick: $planned:expr, actual_tick: $actual:expr,
        ticks: $ticks:expr, level: $level:expr, step: $step:expr, steps: $steps:expr,
        slack_ticks: $slack:expr $(,)?
    }) => {
        $crate::event_text!(@played $variant, $($emit)::+ ($($sink)?), $slack,
            $cycle, $kind.name(), $planned, $actual, $ticks, $level, $step, $steps)
    };
    ($($emit:ident)::+ ($($sink:expr)?), Zero { actual_tick: $actual:expr $(,)? }) => {
        $($emit)::+!($($sink,)? "EVT zero actual={=u64}", $actual)
    };
    ($($emit:ident)::+ ($($sink:expr)?), Enable { actual_tick: $actual:expr, enabled: $enabled:expr $(,)? }) => {
        $($emit)::+!(
            $($sink,)?
            "EVT enable state={=str} actual={=u64}",
            if $enabled { "on" } else { "off" },
            $actual
        )
    };
    ($($emit:ident)::+ ($($sink:expr)?), Work {
        edges: $edges:expr, max_cycles: $max:expr, total_cycles: $total:expr, clock_hz: $clock_hz:expr $(,)?
    }) => {
        $($emit)::+!(
            $($sink,)?
            "EVT work edges={=u32} max_cycles={=u32} total_cycles={=u64} clock_hz={=u32}",
            $edges, $max, $total, $clock_hz
        )
    };
    ($($emit:ident)::+ ($($sink:expr)?), End { tick: $tick:expr $(,)? }) => {
        $($emit)::+!($($sink,)? "EVT end tick={=u64}", $tick)
    };
    // A segment as the output played it (`Segment` or `Replay`): its two lines, with and without
    // the slack, spelt out whole because defmt takes only a literal as its format string.
    (@played Segment, $($rest:tt)+) => {
        $crate::event_text!(@played_lines
            "EVT seg cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16} slack={=u32}",
            "EVT seg cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16}",
            $($rest)+)
    };
    (@played Replay, $($rest:tt)+) => {
        $crate::event_text!(@played_lines
            "EVT replay cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16} slack={=i64}",
            "EVT replay cycle={=u64} kind={=str} planned={=u64} actual={=u64} ticks={=u32} level={=i8} step={=u16} steps={=u16}",
            $($rest)+)
    };
    (@played_lines $with_slack:tt, $without_slack:tt, $($emit:ident)::+ ($($sink:expr)?), $slack:expr,
        $($field:expr),+) => {
        match $slack {
            Some(slack_ticks) => $($emit)::+!($($sink,)? $with_slack, $($field,)+ slack_ticks),
            None => $($emit)::+!($($sink,)? $without_slack, $($field),+),
        }
    };
}

/// Prints an event as a defmt frame of its own (`defmt::println!`), written as in
/// [`event_text!`]: `print_event!(Zero { actual_tick: now_ticks })`. Each field is read where it
/// lies when the frame is written, so printing costs what one `defmt::println!` of those
/// expressions costs, with no [`event::Event`](crate::event::Event) value built first: the
/// firmware's edge path, which the emulated board times to the instruction, prints this way.
/// Needs `defmt` in the calling crate.
#[macro_export]
macro_rules! print_event {
    ($($event:tt)+) => {
        $crate::event_text!(defmt::println(), $($event)+)
    };
}

/// The text of `$event` (an `&Event`) through [`event_text!`].
macro_rules! encode {
    ($event:expr, $($emit:tt)+) => {{
        use $crate::event::{Event, Request, SegmentEvent};
        match $event {
            Event::Plan { tick, spec, clock_hz, ramp_cycles } => $crate::event_text!($($emit)+, Plan {
                tick: *tick, spec: spec, clock_hz: *clock_hz, ramp_cycles: *ramp_cycles,
            }),
            Event::Start { tick } => {
                $crate::event_text!($($emit)+, Request { request: Request::Start, tick: *tick })
            }
            Event::Stop { tick } => {
                $crate::event_text!($($emit)+, Request { request: Request::Stop, tick: *tick })
            }
            Event::Halt { tick } => {
                $crate::event_text!($($emit)+, Request { request: Request::Halt, tick: *tick })
            }
            Event::QuickStop { tick } => {
                $crate::event_text!($($emit)+, Request { request: Request::QuickStop, tick: *tick })
            }
            Event::Segment(segment) => $crate::event_text!($($emit)+, Segment {
                cycle: segment.cycle, kind: segment.kind, planned_tick: segment.planned_tick,
                actual_tick: segment.actual_tick, ticks: segment.ticks, level: segment.level,
                step: segment.step, steps: segment.steps,
                slack_ticks: segment.slack_ticks.map(SegmentEvent::began_slack_ticks),
            }),
            Event::Replay(segment) => $crate::event_text!($($emit)+, Replay {
                cycle: segment.cycle, kind: segment.kind, planned_tick: segment.planned_tick,
                actual_tick: segment.actual_tick, ticks: segment.ticks, level: segment.level,
                step: segment.step, steps: segment.steps, slack_ticks: segment.slack_ticks,
            }),
            Event::Zero { actual_tick } => {
                $crate::event_text!($($emit)+, Zero { actual_tick: *actual_tick })
            }
            Event::Enable { actual_tick, enabled } => $crate::event_text!($($emit)+, Enable {
                actual_tick: *actual_tick, enabled: *enabled,
            }),
            Event::Work(work) => $crate::event_text!($($emit)+, Work {
                edges: work.edges, max_cycles: work.max_cycles, total_cycles: work.total_cycles,
                clock_hz: work.clock_hz,
            }),
            Event::End { tick } => $crate::event_text!($($emit)+, End { tick: *tick }),
        }
    }};
}

mod float;
#[cfg(feature = "defmt")]
mod frame;
mod parse;
mod text;

pub use parse::{parse_line, EventError};
