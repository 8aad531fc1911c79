//! The soak's view of the decoded firmware log, on the log thread: every line goes to a file,
//! every event to the firmware-in-the-loop checker, and the motion cycles and the first firmware
//! error are published for the operator while it runs.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use feeder_shared::{SegmentKind, WaveformSpec};
use host_sim::hil::{self, CheckReport, Checker, Edge, Event, LogLine};

use crate::support::LogSink;

/// Log lines kept to show what led up to a firmware error.
const CONTEXT_LINES: usize = 16;

/// What the log thread tells the operator while the soak runs.
#[derive(Default)]
pub struct Progress {
    motion_cycles: AtomicU64,
    first_error: Mutex<Option<FirmwareError>>,
}

impl Progress {
    /// Motion cycles (not idle periods) the firmware has completed.
    pub fn motion_cycles(&self) -> u64 {
        self.motion_cycles.load(Ordering::Relaxed)
    }

    /// The first error the firmware logged, if any.
    pub fn first_error(&self) -> Option<FirmwareError> {
        self.first_error.lock().expect("not poisoned").clone()
    }
}

/// An error line of the firmware's log and the lines before it.
#[derive(Debug, Clone)]
pub struct FirmwareError {
    pub line: String,
    pub context: Vec<String>,
}

/// A plan the firmware reported (`EVT plan`).
#[derive(Debug, Clone, Copy)]
pub struct Plan {
    pub spec: WaveformSpec,
    pub clock_hz: u32,
    pub ramp_cycles: u16,
}

/// Everything the log showed, once QEMU has ended.
pub struct Summary {
    pub report: CheckReport,
    /// The edges as reported, with the plan in force at each (from the checker's replay).
    pub edges: Vec<Edge>,
    pub clock_hz: u32,
    /// The plans in the order reported: the power-up plan first.
    pub plans: Vec<Plan>,
    /// Error lines of the firmware (defmt's error level, a panic).
    pub firmware_errors: Vec<String>,
    /// Event lines the checker could not read.
    pub unreadable: Vec<String>,
    /// The checker's replay panicked on this event (with this message) and took no more.
    pub checker_panic: Option<String>,
    pub path: PathBuf,
}

/// The [`LogSink`] of the soak.
pub struct SoakLog {
    file: BufWriter<File>,
    path: PathBuf,
    checker: Checker,
    checker_panic: Option<String>,
    plans: Vec<Plan>,
    firmware_errors: Vec<String>,
    unreadable: Vec<String>,
    recent: VecDeque<String>,
    progress: Arc<Progress>,
}

impl SoakLog {
    /// A sink writing the log to `path`, and the progress it publishes.
    pub fn create(path: &Path) -> (Self, Arc<Progress>) {
        let file = File::create(path)
            .unwrap_or_else(|error| panic!("cannot create {}: {error}", path.display()));
        let progress = Arc::new(Progress::default());
        let sink = SoakLog {
            file: BufWriter::new(file),
            path: path.to_path_buf(),
            checker: Checker::new(),
            checker_panic: None,
            plans: Vec::new(),
            firmware_errors: Vec::new(),
            unreadable: Vec::new(),
            recent: VecDeque::with_capacity(CONTEXT_LINES),
            progress: Arc::clone(&progress),
        };
        (sink, progress)
    }

    /// The checker's verdict on the whole stream (a console run has no `end` event).
    pub fn finish(mut self) -> Summary {
        self.file
            .flush()
            .unwrap_or_else(|error| panic!("cannot write {}: {error}", self.path.display()));
        let (report, edges, clock_hz) = self.checker.finish(false);
        Summary {
            report,
            edges,
            clock_hz,
            plans: self.plans,
            firmware_errors: self.firmware_errors,
            unreadable: self.unreadable,
            checker_panic: self.checker_panic,
            path: self.path,
        }
    }

    fn event(&mut self, event: &Event) {
        match event {
            Event::Plan {
                spec,
                clock_hz,
                ramp_cycles,
                ..
            } => self.plans.push(Plan {
                spec: *spec,
                clock_hz: *clock_hz,
                ramp_cycles: *ramp_cycles,
            }),
            Event::Segment(segment) if segment.kind == SegmentKind::Return => {
                self.progress.motion_cycles.fetch_add(1, Ordering::Relaxed);
            }
            _ => {}
        }
        self.check(event);
    }

    /// Feeds `event` to the checker. A panic in its replay (the shared scheduler's code) is
    /// kept for the report instead of ending the log thread; the checker takes nothing more.
    fn check(&mut self, event: &Event) {
        if self.checker_panic.is_some() {
            return;
        }
        let checker = &mut self.checker;
        if let Err(payload) = panic::catch_unwind(AssertUnwindSafe(|| checker.feed(event))) {
            let message = payload
                .downcast_ref::<&str>()
                .map(|text| text.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            self.checker_panic = Some(format!("{message:?} at {event:?}"));
        }
    }

    fn firmware_error(&mut self, line: String) {
        let mut first = self.progress.first_error.lock().expect("not poisoned");
        if first.is_none() {
            *first = Some(FirmwareError {
                line: line.clone(),
                context: self.recent.iter().cloned().collect(),
            });
        }
        self.firmware_errors.push(line);
    }
}

impl LogSink for SoakLog {
    fn line(&mut self, line: &str) {
        if let Err(error) = writeln!(self.file, "{line}") {
            panic!("cannot write {}: {error}", self.path.display());
        }
        // Read as `host-sim hil` reads each line of a log: its event, or a firmware error.
        match hil::read_line(line) {
            Ok(LogLine::Event(event)) => self.event(&event),
            Ok(LogLine::FirmwareError) => self.firmware_error(line.trim_end().to_string()),
            Ok(LogLine::Other) => {}
            Err(error) => self.unreadable.push(format!("{error}: {line}")),
        }
        if self.recent.len() == CONTEXT_LINES {
            self.recent.pop_front();
        }
        self.recent.push_back(line.to_string());
    }
}
