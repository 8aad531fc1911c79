//! The replay: the firmware's requests applied to the shared scheduler at the ticks they were
//! made, and every reported edge compared with the segment it produces.

use feeder_shared::event::{Event, SegmentEvent};
use feeder_shared::{
    Limits, Scheduler, Segment, SegmentKind, TickClock, TickPlan, Waveform, WaveformSpec,
};

use super::edge::{Edge, EdgeSource};
use super::report::{slack_bucket, CheckReport, EdgeWork};

/// Problems listed in full; further ones are only counted.
const MAX_PROBLEMS: usize = 20;

/// Planned segments the replay passes over to reach one reported edge before the stream counts
/// as out of step and the replay stops: a garbled tick far ahead would otherwise replay for ages.
const MAX_SKIPPED_SEGMENTS: u64 = 100_000;

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

    /// Replays every event of a whole stream and finishes, as [`Checker::finish`] does.
    pub fn check_events(events: &[Event], end_required: bool) -> (CheckReport, Vec<Edge>, u32) {
        let mut checker = Self::new();
        for event in events {
            checker.feed(event);
        }
        checker.finish(end_required)
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
            Event::Work(work) => self.report.edge_work = Some(EdgeWork::from(*work)),
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
            request => self.pending.push(*request),
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
            let boundary = reported.starts_cycle();
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
