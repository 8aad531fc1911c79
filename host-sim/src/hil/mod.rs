//! Firmware-in-the-loop checking: the decoded event stream of a running firmware (QEMU or a real
//! board) replayed against the shared scheduler.
//!
//! The events and their text are the shared crate's ([`feeder_shared::event`]). Every `seg`
//! event is compared with the segment the shared scheduler produces for the same requests: start
//! tick, length, kind, level and amplitude must match exactly. `actual` is when the level took
//! effect on the output's own timeline, which a restart after a halt shifts against the plan;
//! `slack` (optional) is how many ticks before its start the segment was preloaded.
//!
//! The emulated board (QEMU) also reports what its hardware-timed output did by itself: a missed
//! edge (`replay`: the preload came after the deadline, `slack` < 0, so the timer played the
//! playing segment again from `actual`), the output's zero at a halt (`zero`), and the work per
//! edge over the run (`work`: timer cycles from an edge to the preload of the next segment).
//! A run that ends with a failure (a panic, a HardFault, a fault that stops the script) ends with
//! the output's state as its registers hold it: `zero` if it holds the zero code, and the driver
//! enable (`enable`, `state=on` or `off`).
//!
//! [`stream`] reads a decoded log, [`check`] replays it, [`report`] is what the replay found,
//! [`edge`] the edges it kept, and [`part`] the part simulated on them.

pub mod check;
pub mod edge;
pub mod part;
pub mod report;
pub mod stream;

pub use check::Checker;
pub use edge::{Edge, EdgeSource, EdgeTimes};
pub use feeder_shared::event::{Event, SegmentEvent, EVENT_MARKER};
pub use part::{
    simulate, simulate_plate, trace_plate, CyclePoint, HaltPoint, PartReport, STEADY_WINDOW_CYCLES,
};
pub use report::{slack_bucket, CheckReport, EdgeWork};
pub use stream::{
    excerpt, parse_line, read_line, read_stream, HilError, LogLine, ParseError, Stream,
    MAX_LINE_BYTES, SHOWN_LINE_CHARS,
};
