//! Firmware-in-the-loop checking: the decoded event stream of a running firmware (QEMU or a real
//! board) replayed against the shared scheduler.
//!
//! The firmware prints one event per line (anywhere in the line, after the marker `EVT`):
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
//! `tick` on a request is the scheduler's next segment start when the request was made, so the
//! replay applies it at exactly the same point; `accel_mps2=` may stand for `stroke_m=`.
//! Every `seg` event is compared with the segment the shared scheduler produces for the same
//! requests: start tick, length, kind, level and amplitude must match exactly. `actual` is when
//! the level took effect on the output's own timeline, which a restart after a halt shifts
//! against the plan; `slack` (optional) is how many ticks before its start the segment was
//! preloaded.
//!
//! The emulated board (QEMU) also reports what its hardware-timed output did by itself: a missed
//! edge (`replay`: the preload came after the deadline, `slack` < 0, so the timer played the
//! playing segment again from `actual`), the output's zero at a halt (`zero`), and the work per
//! edge over the run (`work`: timer cycles from an edge to the preload of the next segment).
//! A run that ends with a failure (a panic, a HardFault, a fault that stops the script) ends with
//! the output's state as its registers hold it: `zero` if it holds the zero code, and the driver
//! enable (`enable`, `state=on` or `off`).

use std::collections::BTreeMap;
use std::fmt;
use std::io::{BufRead, Read};

use serde::Serialize;

use feeder_shared::{
    Drive, Limits, Scheduler, Segment, SegmentKind, TickClock, TickPlan, Waveform, WaveformSpec,
};

use crate::plant::{Contact, PlateSegment};
use crate::sim::{run_segments, Criteria, CycleStats, RunOptions};

/// The marker that starts an event inside a log line.
pub const EVENT_MARKER: &str = "EVT ";

/// One parsed firmware event.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
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
    Work(EdgeWork),
    End {
        tick: u64,
    },
}

/// A level change as the firmware reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentEvent {
    pub cycle: u64,
    pub kind: SegmentKind,
    pub planned_tick: u64,
    pub actual_tick: u64,
    pub ticks: u32,
    pub level: i8,
    pub step: u16,
    pub steps: u16,
    /// Ticks from the preload to the start: the segment's deadline minus the moment it was
    /// preloaded. `None` where the firmware does not report it (a restart, an older log).
    pub slack_ticks: Option<i64>,
}

/// QEMU's virtual time per instruction under `-icount shift=4`, as `cargo xtask` and the QEMU
/// tests run it.
pub const QEMU_NS_PER_INSTRUCTION: f64 = 16.0;

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

/// A line that carries the event marker but cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParseError {
    pub line: String,
    pub reason: String,
}

/// Characters of a log line a message shows.
pub const SHOWN_LINE_CHARS: usize = 120;

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unreadable event ({}): {}",
            self.reason,
            excerpt(&self.line)
        )
    }
}

/// `line` as a message shows it: at most [`SHOWN_LINE_CHARS`] characters, then `…`.
pub fn excerpt(line: &str) -> String {
    match line.char_indices().nth(SHOWN_LINE_CHARS) {
        Some((end, _)) => format!("{}…", &line[..end]),
        None => line.to_string(),
    }
}

impl std::error::Error for ParseError {}

/// Reads one log line: `Ok(None)` for lines without an event.
pub fn parse_line(line: &str) -> Result<Option<Event>, ParseError> {
    let Some(start) = line.find(EVENT_MARKER) else {
        return Ok(None);
    };
    let error = |reason: String| ParseError {
        line: line.trim_end().to_string(),
        reason,
    };
    let mut words = line[start + EVENT_MARKER.len()..].split_whitespace();
    let name = words.next().ok_or_else(|| error("no event name".into()))?;
    let fields: BTreeMap<&str, &str> = words.filter_map(|word| word.split_once('=')).collect();
    let field = |key: &str| {
        fields
            .get(key)
            .copied()
            .ok_or_else(|| error(format!("no `{key}`")))
    };
    let number = |key: &str| -> Result<u64, ParseError> {
        field(key)?
            .parse()
            .map_err(|_| error(format!("`{key}` is not a whole number")))
    };
    let real = |key: &str| -> Result<f64, ParseError> {
        field(key)?
            .parse()
            .map_err(|_| error(format!("`{key}` is not a number")))
    };
    let narrow = |key: &str, value: u64| -> Result<u32, ParseError> {
        u32::try_from(value).map_err(|_| error(format!("`{key}` is out of range")))
    };
    let event = match name {
        "plan" => {
            let drive = match (fields.get("stroke_m"), fields.get("accel_mps2")) {
                (Some(_), None) => Drive::Stroke {
                    stroke_m: real("stroke_m")?,
                },
                (None, Some(_)) => Drive::Accel {
                    accel_mps2: real("accel_mps2")?,
                },
                _ => {
                    return Err(error(
                        "needs exactly one of `stroke_m`, `accel_mps2`".into(),
                    ))
                }
            };
            let ramp = number("ramp")?;
            Event::Plan {
                tick: number("tick")?,
                spec: WaveformSpec {
                    period_s: real("period_s")?,
                    duty: real("duty")?,
                    drive,
                },
                clock_hz: narrow("clock_hz", number("clock_hz")?)?,
                ramp_cycles: u16::try_from(ramp)
                    .map_err(|_| error("`ramp` is out of range".into()))?,
            }
        }
        "start" => Event::Start {
            tick: number("tick")?,
        },
        "stop" => Event::Stop {
            tick: number("tick")?,
        },
        "halt" => Event::Halt {
            tick: number("tick")?,
        },
        "quickstop" => Event::QuickStop {
            tick: number("tick")?,
        },
        "end" => Event::End {
            tick: number("tick")?,
        },
        "work" => Event::Work(EdgeWork {
            edges: number("edges")?,
            max_cycles: number("max_cycles")?,
            total_cycles: number("total_cycles")?,
            clock_hz: number("clock_hz")?,
        }),
        "zero" => Event::Zero {
            actual_tick: number("actual")?,
        },
        "enable" => Event::Enable {
            actual_tick: number("actual")?,
            enabled: match field("state")? {
                "on" => true,
                "off" => false,
                _ => return Err(error("`state` must be on or off".into())),
            },
        },
        "seg" | "replay" => {
            let kind = match field("kind")? {
                "accelerate" => SegmentKind::Accelerate,
                "plateau" => SegmentKind::Plateau,
                "reverse" => SegmentKind::Reverse,
                "return" => SegmentKind::Return,
                "idle" => SegmentKind::Idle,
                other => return Err(error(format!("unknown segment kind `{other}`"))),
            };
            let small = |key: &str| -> Result<u16, ParseError> {
                u16::try_from(number(key)?).map_err(|_| error(format!("`{key}` is out of range")))
            };
            let level: i8 = field("level")?
                .parse()
                .ok()
                .filter(|level: &i8| (-1..=1).contains(level))
                .ok_or_else(|| error("`level` must be -1, 0 or 1".into()))?;
            // A segment that began was preloaded in time; only a replay reports a late one.
            let slack_ticks = match fields.get("slack") {
                None => None,
                Some(slack) => Some(if name == "seg" {
                    i64::from(
                        slack
                            .parse::<u32>()
                            .map_err(|_| error("`slack` is not a whole number".into()))?,
                    )
                } else {
                    slack
                        .parse()
                        .map_err(|_| error("`slack` is not an integer".into()))?
                }),
            };
            let segment = SegmentEvent {
                cycle: number("cycle")?,
                kind,
                planned_tick: number("planned")?,
                actual_tick: number("actual")?,
                ticks: narrow("ticks", number("ticks")?)?,
                level,
                step: small("step")?,
                steps: small("steps")?,
                slack_ticks,
            };
            if name == "seg" {
                Event::Segment(segment)
            } else {
                Event::Replay(segment)
            }
        }
        other => return Err(error(format!("unknown event `{other}`"))),
    };
    Ok(Some(event))
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

/// Problems listed in full; further ones are only counted.
const MAX_PROBLEMS: usize = 20;

/// Planned segments the replay passes over to reach one reported edge before the stream counts
/// as out of step and the replay stops: a garbled tick far ahead would otherwise replay for ages.
const MAX_SKIPPED_SEGMENTS: u64 = 100_000;

/// The bucket of a slack in [`CheckReport::slack_histogram`]: 0 for no slack, else the power of
/// two at or below it (the bucket `2^k` holds `2^k ..= 2^(k+1) − 1`).
pub fn slack_bucket(slack_ticks: i64) -> i64 {
    if slack_ticks <= 0 {
        0
    } else {
        1 << slack_ticks.ilog2()
    }
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
    fn on(self, times: EdgeTimes) -> bool {
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
    fn reported(
        source: EdgeSource,
        event: &SegmentEvent,
        peak_accel_mps2: f64,
        plan_index: usize,
    ) -> Self {
        let amplitude = f64::from(event.step) / f64::from(event.steps.max(1));
        let starts_cycle = matches!(event.kind, SegmentKind::Accelerate | SegmentKind::Idle);
        Edge {
            source,
            actual_tick: event.actual_tick,
            planned_tick: event.planned_tick,
            ticks: event.ticks,
            accel_mps2: f64::from(event.level) * peak_accel_mps2 * amplitude,
            starts_cycle: starts_cycle && source == EdgeSource::Played,
            full_amplitude: event.kind == SegmentKind::Accelerate && event.step == event.steps,
            plan_index,
        }
    }
}

/// Replays the firmware's requests on the shared scheduler and compares every edge.
#[derive(Debug, Default)]
pub struct Checker {
    replay: Option<Scheduler>,
    pending: Vec<Event>,
    previous: Option<SegmentEvent>,
    report: CheckReport,
    edges: Vec<Edge>,
    plan_index: usize,
    /// `a_max` of the plan of the last edge played.
    peak_accel_mps2: f64,
    clock_hz: u32,
    /// `actual − planned` since the last restart (set by its first edge).
    timeline_offset: Option<i128>,
    /// An edge was missed: the planned segments before the next reported one never began.
    missed_edge: bool,
    /// A reported edge lay too far past the plan; later edges are counted, not replayed.
    out_of_step: bool,
}

impl Checker {
    pub fn new() -> Self {
        Self::default()
    }

    fn problem(&mut self, text: String) {
        if self.report.problems.len() < MAX_PROBLEMS {
            self.report.problems.push(text);
        }
    }

    /// Takes the next event of the stream.
    pub fn feed(&mut self, event: &Event) {
        match event {
            Event::Segment(segment) => self.segment(segment),
            Event::Replay(replayed) => self.replayed(replayed),
            Event::Zero { actual_tick } => {
                self.edges.push(Edge {
                    source: EdgeSource::Zeroed,
                    actual_tick: *actual_tick,
                    planned_tick: *actual_tick,
                    ticks: 0,
                    accel_mps2: 0.0,
                    starts_cycle: false,
                    full_amplitude: false,
                    plan_index: self.plan_index,
                });
                // The restart that follows shifts the plan against the output's timeline.
                self.timeline_offset = None;
            }
            Event::Work(work) => self.report.edge_work = Some(*work),
            Event::Enable { .. } => {}
            Event::End { .. } => self.report.ended = true,
            Event::Plan {
                tick: 0,
                spec,
                clock_hz,
                ramp_cycles,
            } if self.replay.is_none() => match plan_for(spec, *clock_hz) {
                Ok(plan) => {
                    self.clock_hz = *clock_hz;
                    self.replay = Some(Scheduler::new(plan, *ramp_cycles));
                }
                Err(reason) => self.problem(format!("initial plan refused: {reason}")),
            },
            request => self.pending.push(request.clone()),
        }
    }

    /// Applies the requests the firmware made before the replay's next segment was prepared.
    fn apply_requests(&mut self) {
        let Some(replay) = self.replay.as_mut() else {
            return;
        };
        let next_tick = replay.next_tick();
        let mut problems = Vec::new();
        self.pending.retain(|request| {
            let tick = match request {
                Event::Plan { tick, .. }
                | Event::Start { tick }
                | Event::Stop { tick }
                | Event::Halt { tick }
                | Event::QuickStop { tick } => *tick,
                _ => return false,
            };
            if tick > next_tick {
                return true;
            }
            if tick < next_tick {
                problems.push(format!(
                    "request at tick {tick} arrived after tick {next_tick}"
                ));
            }
            match request {
                Event::Start { .. } => replay.start(),
                Event::Stop { .. } => replay.stop(),
                Event::Halt { .. } => replay.halt(),
                Event::QuickStop { .. } => replay.quick_stop(),
                Event::Plan {
                    spec,
                    clock_hz,
                    ramp_cycles,
                    ..
                } => {
                    match plan_for(spec, *clock_hz)
                        .and_then(|plan| replay.set_plan(plan).map_err(|error| error.to_string()))
                    {
                        Ok(()) => replay.set_ramp_cycles(*ramp_cycles),
                        Err(reason) => {
                            problems.push(format!("plan at tick {tick} refused: {reason}"))
                        }
                    }
                }
                _ => {}
            }
            false
        });
        for problem in problems {
            self.problem(problem);
        }
    }

    /// A missed edge: the output played the segment again; what was planned from here until the
    /// next reported edge never began.
    fn replayed(&mut self, replayed: &SegmentEvent) {
        self.report.missed.push(*replayed);
        let late = match replayed.slack_ticks {
            Some(slack) => format!(
                "the next segment was preloaded {} ticks late",
                -i128::from(slack)
            ),
            None => "the next segment was not preloaded".to_string(),
        };
        self.problem(format!(
            "edge missed at tick {}: {late}, so the output played cycle {}'s {} again",
            replayed.actual_tick,
            replayed.cycle,
            replayed.kind.name()
        ));
        self.edges.push(Edge::reported(
            EdgeSource::Replayed,
            replayed,
            self.peak_accel_mps2,
            self.plan_index,
        ));
        self.missed_edge = true;
    }

    fn segment(&mut self, reported: &SegmentEvent) {
        self.report.edges += 1;
        let shift = i128::from(reported.actual_tick) - i128::from(reported.planned_tick);
        let offset = *self.timeline_offset.get_or_insert(shift);
        let deviation = (shift - offset).clamp(-i128::from(i64::MAX), i128::from(i64::MAX)) as i64;
        *self
            .report
            .deviation_histogram
            .entry(deviation)
            .or_default() += 1;
        if let Some(slack) = reported.slack_ticks {
            *self
                .report
                .slack_histogram
                .entry(slack_bucket(slack))
                .or_default() += 1;
            if self.report.min_slack.is_none_or(|(least, _)| slack < least) {
                self.report.min_slack = Some((slack, reported.planned_tick));
            }
        }
        if let Some(previous) = self.previous {
            let changed = previous.step != reported.step || previous.steps != reported.steps;
            let boundary = matches!(reported.kind, SegmentKind::Accelerate | SegmentKind::Idle);
            if changed && !boundary {
                self.report.glitches += 1;
                self.problem(format!(
                    "amplitude changed mid-cycle at tick {}",
                    reported.planned_tick
                ));
            }
        }
        self.previous = Some(*reported);
        if self.out_of_step {
            self.report.unexpected += 1;
            return;
        }
        if self.replay.is_none() {
            self.report.unexpected += 1;
            self.problem("segment before the initial plan".into());
            return;
        }
        let mut skipped = 0;
        loop {
            self.apply_requests();
            let Some(replay) = self.replay.as_mut() else {
                return;
            };
            if replay.next_tick() > reported.planned_tick {
                self.report.unexpected += 1;
                self.problem(format!("unexpected edge at tick {}", reported.planned_tick));
                return;
            }
            let expected = replay.next_segment();
            if expected.plan_applied {
                self.plan_index += 1;
            }
            if expected.start_tick < reported.planned_tick {
                if self.missed_edge {
                    self.edges.push(Edge {
                        source: EdgeSource::Unplayed,
                        actual_tick: expected.start_tick,
                        planned_tick: expected.start_tick,
                        ticks: expected.ticks,
                        accel_mps2: 0.0,
                        starts_cycle: expected.starts_cycle(),
                        full_amplitude: false,
                        plan_index: self.plan_index,
                    });
                } else {
                    self.report.missing += 1;
                    self.problem(format!("missing edge at tick {}", expected.start_tick));
                }
                skipped += 1;
                if skipped == MAX_SKIPPED_SEGMENTS {
                    self.report.unexpected += 1;
                    self.out_of_step = true;
                    // Listed even past MAX_PROBLEMS: the missing edges before it fill the list.
                    self.report.problems.push(format!(
                        "edge at tick {} lies over {MAX_SKIPPED_SEGMENTS} segments past the plan: \
                         the stream is out of step, later edges are not replayed",
                        reported.planned_tick
                    ));
                    return;
                }
                continue;
            }
            self.missed_edge = false;
            self.peak_accel_mps2 = expected.peak_accel_mps2;
            self.edges.push(Edge::reported(
                EdgeSource::Played,
                reported,
                expected.peak_accel_mps2,
                self.plan_index,
            ));
            if matches(&expected, reported) {
                self.report.matched += 1;
                if expected.kind == SegmentKind::Return {
                    self.report.motion_cycles += 1;
                }
            } else {
                self.report.unexpected += 1;
                self.problem(format!(
                    "edge at tick {} differs: reported {:?}, planned {:?} for {} ticks at {}/{}",
                    reported.planned_tick,
                    reported,
                    expected.kind,
                    expected.ticks,
                    expected.amplitude.step,
                    expected.amplitude.steps
                ));
            }
            return;
        }
    }

    /// The comparison, the edges as reported, and the clock they count. With `end_required` a
    /// stream without an `end` event fails (the firmware stopped early).
    pub fn finish(mut self, end_required: bool) -> (CheckReport, Vec<Edge>, u32) {
        self.report.end_required = end_required;
        if end_required && !self.report.ended {
            self.problem("the stream has no `end` event: the firmware stopped early".into());
        }
        (self.report, self.edges, self.clock_hz)
    }
}

fn matches(expected: &Segment, reported: &SegmentEvent) -> bool {
    expected.start_tick == reported.planned_tick
        && expected.ticks == reported.ticks
        && expected.kind == reported.kind
        && expected.level.sign() == reported.level
        && expected.amplitude.step == reported.step
        && expected.amplitude.steps == reported.steps
        && expected.cycle == reported.cycle
}

fn plan_for(spec: &WaveformSpec, clock_hz: u32) -> Result<TickPlan, String> {
    let waveform = Waveform::new(*spec, &Limits::NONE).map_err(|error| error.to_string())?;
    TickPlan::new(&waveform, TickClock::new(clock_hz)).map_err(|error| error.to_string())
}

/// A decoded log: its events and the lines that report a firmware error.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stream {
    pub events: Vec<Event>,
    /// Lines with `ERROR` or `panic` (defmt's error level, the panic handler's message).
    pub errors: Vec<String>,
}

/// Longest line read: decoded event lines are a few hundred bytes at most, so a longer one means
/// the input is not a decoded log.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Reads a decoded log (defmt-print's or probe-rs's output): UTF-8 lines of at most
/// [`MAX_LINE_BYTES`].
pub fn read_stream(mut reader: impl BufRead) -> Result<Stream, HilError> {
    let mut stream = Stream::default();
    let mut bytes = Vec::new();
    for number in 1.. {
        bytes.clear();
        let read = (&mut reader)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut bytes)
            .map_err(|error| HilError::Read(error.to_string()))?;
        if read == 0 {
            break;
        }
        let text = bytes.strip_suffix(b"\n").unwrap_or(&bytes);
        if text.len() > MAX_LINE_BYTES {
            return Err(HilError::Read(format!(
                "line {number} is longer than {MAX_LINE_BYTES} bytes"
            )));
        }
        let text = text.strip_suffix(b"\r").unwrap_or(text);
        let line = std::str::from_utf8(text)
            .map_err(|_| HilError::Read(format!("line {number} is not UTF-8 text")))?;
        match parse_line(line) {
            Ok(Some(event)) => stream.events.push(event),
            Ok(None) if line.contains("ERROR") || line.contains("panic") => {
                stream.errors.push(line.trim_end().to_string())
            }
            Ok(None) => {}
            Err(error) => {
                return Err(HilError::Parse {
                    line: number,
                    error,
                })
            }
        }
    }
    Ok(stream)
}

/// Why a stream could not be analysed; the message leaves naming the stream to the caller.
#[derive(Debug, Clone, PartialEq)]
pub enum HilError {
    /// The reader failed, or a line is not text or too long.
    Read(String),
    /// A line (counted from 1) carries the event marker but cannot be read.
    Parse { line: usize, error: ParseError },
}

impl fmt::Display for HilError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HilError::Read(reason) => f.write_str(reason),
            HilError::Parse { line, error } => write!(f, "line {line}: {error}"),
        }
    }
}

impl std::error::Error for HilError {}

/// Cycles averaged for the steady feed rate: the last ones at full amplitude of the final plan.
/// A change of plan decays by about `((a − μg)/(a + μg))²` per cycle (Eq. 12), so the window sits
/// at the end of the stretch.
pub const STEADY_WINDOW_CYCLES: usize = 16;

/// Which instant of each edge the simulation uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeTimes {
    /// When the level took effect, as the firmware measured it.
    Actual,
    /// The scheduler's planned tick.
    Planned,
}

/// The part simulated on the recorded edges.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartReport {
    /// Mean part velocity over the last [`STEADY_WINDOW_CYCLES`] full-amplitude cycles of the
    /// final plan (fewer if the run had fewer).
    pub feed_rate_mps: f64,
    /// The same relative to the plate's mean velocity over those cycles: the feed rate the
    /// waveform produces, whatever the plate's drift.
    pub feed_rate_relative_mps: f64,
    /// Cycles those means are over.
    pub steady_cycles: usize,
    /// Stick fraction over the same cycles.
    pub stick_fraction: f64,
    /// Distance the part moved over the whole run.
    pub part_travel_m: f64,
    /// Peak-to-peak plate travel over the run.
    pub plate_excursion_m: f64,
    /// Plate position at the end of the run relative to its start.
    pub plate_drift_m: f64,
    /// Seconds of firmware time simulated.
    pub duration_s: f64,
    /// Every cycle (and idle period) of the run.
    pub cycles: Vec<CyclePoint>,
    /// The plate at each halt: where the output went to zero (actual edges only).
    pub halts: Vec<HaltPoint>,
}

/// Where a halt left the plate: its state when the output went to zero, relative to its
/// position and rest at the start of the run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HaltPoint {
    pub tick: u64,
    pub time_s: f64,
    pub plate_position_m: f64,
    pub plate_velocity_mps: f64,
}

/// One cycle of a simulated run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CyclePoint {
    pub start_s: f64,
    pub duration_s: f64,
    /// Mean part velocity.
    pub part_velocity_mps: f64,
    /// Mean plate velocity: zero for a cycle that returns the plate to its start.
    pub plate_velocity_mps: f64,
}

/// Simulates the part on the edges of one timeline: each level holds from its edge to the next
/// edge (the last one for its planned length), at the actual or the planned instants.
pub fn simulate(edges: &[Edge], clock_hz: u32, contact: &Contact, times: EdgeTimes) -> PartReport {
    let clock_hz = f64::from(clock_hz.max(1));
    let edges: Vec<&Edge> = edges.iter().filter(|edge| edge.source.on(times)).collect();
    let tick = |edge: &&Edge| match times {
        EdgeTimes::Actual => edge.actual_tick,
        EdgeTimes::Planned => edge.planned_tick,
    };
    let segments: Vec<PlateSegment> = edges
        .iter()
        .enumerate()
        .map(|(index, edge)| {
            let start_tick = tick(edge);
            let end_tick = edges
                .get(index + 1)
                .map_or(start_tick.saturating_add(u64::from(edge.ticks)), tick);
            PlateSegment {
                duration_s: end_tick.saturating_sub(start_tick) as f64 / clock_hz,
                accel_mps2: edge.accel_mps2,
                starts_cycle: edge.starts_cycle,
            }
        })
        .collect();
    let options = RunOptions {
        fixed_cycles: Some(u64::MAX),
        record_cycles: true,
        ..RunOptions::converge(Criteria::periodic(0.0, 1.0))
    };
    let run = run_segments(segments.iter().copied(), contact, &options);
    let plate_m = plate_cycle_displacements_m(&segments);
    // Cycles (in order) that ran at full amplitude under the final plan.
    let final_plan = edges.last().map_or(0, |edge| edge.plan_index);
    let steady: Vec<bool> = edges
        .iter()
        .filter(|edge| edge.starts_cycle)
        .map(|edge| edge.full_amplitude && edge.plan_index == final_plan)
        .collect();
    let window: Vec<(&CycleStats, f64)> = run
        .cycle_stats
        .iter()
        .zip(plate_m.iter().copied())
        .zip(&steady)
        .filter(|(_, steady)| **steady)
        .map(|(cycle, _)| cycle)
        .collect();
    let window = &window[window.len().saturating_sub(STEADY_WINDOW_CYCLES)..];
    let window_s: f64 = window.iter().map(|(stats, _)| stats.duration_s).sum();
    let mean = |total: f64| {
        if window_s > 0.0 {
            total / window_s
        } else {
            0.0
        }
    };
    let part_m: f64 = window
        .iter()
        .map(|(stats, _)| stats.mean_velocity_mps * stats.duration_s)
        .sum();
    let plate_window_m: f64 = window.iter().map(|(_, plate_m)| plate_m).sum();
    let mut start_s = 0.0;
    let cycles = run
        .cycle_stats
        .iter()
        .zip(&plate_m)
        .map(|(stats, plate_m)| {
            let point = CyclePoint {
                start_s,
                duration_s: stats.duration_s,
                part_velocity_mps: stats.mean_velocity_mps,
                plate_velocity_mps: plate_m / stats.duration_s,
            };
            start_s += stats.duration_s;
            point
        })
        .collect();
    PartReport {
        feed_rate_mps: mean(part_m),
        feed_rate_relative_mps: mean(part_m - plate_window_m),
        steady_cycles: window.len(),
        stick_fraction: mean(
            window
                .iter()
                .map(|(stats, _)| stats.stick_fraction * stats.duration_s)
                .sum(),
        ),
        part_travel_m: run
            .cycle_stats
            .iter()
            .map(|stats| stats.mean_velocity_mps * stats.duration_s)
            .sum(),
        plate_excursion_m: run.plate_excursion_m,
        plate_drift_m: plate_m.iter().sum(),
        duration_s: segments.iter().map(|segment| segment.duration_s).sum(),
        cycles,
        halts: plate_at_halts(&edges, &segments, clock_hz),
    }
}

/// The plate's state where each `Zeroed` edge begins, integrating `segments` (one per edge)
/// from rest.
fn plate_at_halts(edges: &[&Edge], segments: &[PlateSegment], clock_hz: f64) -> Vec<HaltPoint> {
    let mut halts = Vec::new();
    let (mut position_m, mut velocity_mps) = (0.0, 0.0);
    for (edge, segment) in edges.iter().zip(segments) {
        if edge.source == EdgeSource::Zeroed {
            halts.push(HaltPoint {
                tick: edge.actual_tick,
                time_s: edge.actual_tick as f64 / clock_hz,
                plate_position_m: position_m,
                plate_velocity_mps: velocity_mps,
            });
        }
        let t = segment.duration_s;
        position_m += velocity_mps * t + segment.accel_mps2 * t * t / 2.0;
        velocity_mps += segment.accel_mps2 * t;
    }
    halts
}

/// The plate's displacement over each cycle of `segments`, from rest (constant acceleration per
/// segment); the velocity carried across a cycle boundary is what timing errors leave behind.
fn plate_cycle_displacements_m(segments: &[PlateSegment]) -> Vec<f64> {
    let mut cycles = Vec::new();
    let mut velocity_mps = 0.0;
    for segment in segments {
        if segment.starts_cycle || cycles.is_empty() {
            cycles.push(0.0);
        }
        let t = segment.duration_s;
        if let Some(displacement_m) = cycles.last_mut() {
            *displacement_m += velocity_mps * t + segment.accel_mps2 * t * t / 2.0;
        }
        velocity_mps += segment.accel_mps2 * t;
    }
    cycles
}
