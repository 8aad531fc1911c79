//! The firmware-in-the-loop checker on synthetic event streams: a faithful stream passes, and
//! each kind of fault (dropped edge, shifted edge, extra edge, mid-cycle amplitude change, early
//! end, missed edge) is found and counted.

use feeder_shared::event::{EdgeWork, Event, SegmentEvent};
use feeder_shared::{
    Drive, Limits, Scheduler, Segment, SegmentKind, TickClock, TickPlan, Waveform, WaveformSpec,
};
use host_sim::contact::Contact;
use host_sim::hil::{self, Checker};

const CLOCK_HZ: u32 = 1_000_000;

fn spec(duty: f64) -> WaveformSpec {
    WaveformSpec {
        period_s: 0.02,
        duty,
        drive: Drive::Stroke { stroke_m: 0.0025 },
    }
}

fn plan(duty: f64) -> TickPlan {
    let waveform = Waveform::new(spec(duty), &Limits::NONE).unwrap();
    TickPlan::new(&waveform, TickClock::new(CLOCK_HZ)).unwrap()
}

/// The `plan` line for `duty` taking effect at `tick`.
fn plan_line(tick: u64, duty: f64, ramp_cycles: u16) -> String {
    Event::Plan {
        tick,
        spec: spec(duty),
        clock_hz: CLOCK_HZ,
        ramp_cycles,
    }
    .to_string()
}

/// What a firmware with `latency_ticks` of output latency prints for: idle, start, 40 cycles,
/// a duty change, 40 cycles, stop, idle until stopped.
fn faithful_stream(latency_ticks: u64) -> Vec<String> {
    let ramp = 4;
    let mut scheduler = Scheduler::new(plan(0.586), ramp);
    let mut lines = vec![plan_line(0, 0.586, ramp)];
    let emit = |scheduler: &mut Scheduler, lines: &mut Vec<String>, segments: usize| {
        for _ in 0..segments {
            let s = scheduler.next_segment();
            let actual = if s.start_tick == 0 {
                0
            } else {
                s.start_tick + latency_ticks
            };
            let event = Event::Segment(SegmentEvent::played(&s, actual, None));
            lines.push(format!("INFO  noise {event}"));
        }
    };
    emit(&mut scheduler, &mut lines, 2);
    log_start(&mut scheduler, &mut lines);
    emit(&mut scheduler, &mut lines, 161);
    scheduler.set_plan(plan(0.6)).unwrap();
    scheduler.set_ramp_cycles(ramp);
    lines.push(plan_line(scheduler.next_tick(), 0.6, ramp));
    emit(&mut scheduler, &mut lines, 160);
    log_stop(&mut scheduler, &mut lines);
    emit(&mut scheduler, &mut lines, 20);
    lines.push(Event::End { tick: 0 }.to_string());
    lines
}

fn check(lines: &[String]) -> hil::CheckReport {
    check_with(lines, true).0
}

/// What the checker finds in `lines`: its report, the edges and their clock.
fn check_with(lines: &[String], end_required: bool) -> (hil::CheckReport, Vec<hil::Edge>, u32) {
    let stream = hil::read_stream(lines.join("\n").as_bytes()).unwrap();
    Checker::check_events(&stream.events, end_required)
}

/// Starts `scheduler` and prints the `start` line a firmware prints.
fn log_start(scheduler: &mut Scheduler, lines: &mut Vec<String>) {
    scheduler.start();
    let tick = scheduler.next_tick();
    lines.push(Event::Start { tick }.to_string());
}

/// Stops `scheduler` and prints the `stop` line a firmware prints.
fn log_stop(scheduler: &mut Scheduler, lines: &mut Vec<String>) {
    scheduler.stop();
    let tick = scheduler.next_tick();
    lines.push(Event::Stop { tick }.to_string());
}

fn is_seg(line: &str) -> bool {
    line.contains("EVT seg")
}

#[test]
fn parses_each_event_kind() {
    assert_eq!(hil::parse_line("INFO  plan: 50 Hz").unwrap(), None);
    assert_eq!(
        hil::parse_line("EVT start tick=40000").unwrap(),
        Some(Event::Start { tick: 40_000 })
    );
    let reverse = SegmentEvent {
        cycle: 2,
        kind: SegmentKind::Reverse,
        planned_tick: 50_007,
        actual_tick: 50_014,
        ticks: 5_853,
        level: -1,
        step: 1,
        steps: 4,
        slack_ticks: None,
    };
    assert_eq!(
        hil::parse_line("0.1 EVT seg cycle=2 kind=reverse planned=50007 actual=50014 ticks=5853 level=-1 step=1 steps=4").unwrap(),
        Some(Event::Segment(reverse))
    );
    let plateau = SegmentEvent {
        kind: SegmentKind::Plateau,
        planned_tick: 41_713,
        actual_tick: 41_713,
        ticks: 8_294,
        level: 0,
        slack_ticks: Some(1_635),
        ..reverse
    };
    assert_eq!(
        hil::parse_line("EVT seg cycle=2 kind=plateau planned=41713 actual=41713 ticks=8294 level=0 step=1 steps=4 slack=1635").unwrap(),
        Some(Event::Segment(plateau))
    );
    // The reverse segment played again, its preload 51 ticks late.
    let replayed = SegmentEvent {
        actual_tick: 55_860,
        slack_ticks: Some(-51),
        ..reverse
    };
    assert_eq!(
        hil::parse_line("EVT replay cycle=2 kind=reverse planned=50007 actual=55860 ticks=5853 level=-1 step=1 steps=4 slack=-51").unwrap(),
        Some(Event::Replay(replayed))
    );
    assert_eq!(
        hil::parse_line("EVT zero actual=200057").unwrap(),
        Some(Event::Zero {
            actual_tick: 200_057
        })
    );
    assert_eq!(
        hil::parse_line("EVT work edges=90 max_cycles=4236 total_cycles=151451 clock_hz=25000000")
            .unwrap(),
        Some(Event::Work(EdgeWork {
            edges: 90,
            max_cycles: 4_236,
            total_cycles: 151_451,
            clock_hz: 25_000_000,
        }))
    );
    assert_eq!(
        hil::parse_line(
            "EVT plan tick=0 period_s=0.01 duty=0.6 accel_mps2=150 clock_hz=1000000 ramp=25"
        )
        .unwrap(),
        Some(Event::Plan {
            tick: 0,
            spec: WaveformSpec {
                period_s: 0.01,
                duty: 0.6,
                drive: Drive::Accel { accel_mps2: 150.0 }
            },
            clock_hz: 1_000_000,
            ramp_cycles: 25,
        })
    );
    for bad in [
        "EVT warp tick=1",
        "EVT start",
        "EVT start tick=-3",
        "EVT seg cycle=1 kind=sideways planned=0 actual=0 ticks=1 level=0 step=0 steps=1",
        "EVT seg cycle=1 kind=idle planned=0 actual=0 ticks=1 level=2 step=0 steps=1",
        // A segment that began was preloaded before its start.
        "EVT seg cycle=1 kind=idle planned=0 actual=0 ticks=1 level=0 step=0 steps=1 slack=-3",
        "EVT zero tick=5",
        "EVT plan tick=0 period_s=0.02 duty=0.6 stroke_m=1 accel_mps2=1 clock_hz=1 ramp=1",
    ] {
        assert!(hil::parse_line(bad).is_err(), "{bad}");
    }
}

#[test]
fn a_faithful_stream_passes_with_its_latency_histogram() {
    let lines = faithful_stream(7);
    let report = check(&lines);
    assert!(report.passed(), "{:?}", report.problems);
    let edges = lines.iter().filter(|line| is_seg(line)).count() as u64;
    assert_eq!((report.edges, report.matched), (edges, edges));
    // The first idle period starts at tick 0 with no latency; every other edge is 7 ticks late.
    assert_eq!(report.deviation_histogram.get(&0), Some(&1));
    assert_eq!(report.deviation_histogram.get(&7), Some(&(edges - 1)));
    assert_eq!(report.max_deviation_ticks(), 7);
    // 161 segments after the start are 40 cycles and the first segment of the 41st, which
    // finishes under the old plan; 160 more finish it and run 39 cycles and begin the 40th; after
    // the stop that one finishes and 3 ramp-down cycles (steps 3, 2, 1 of 4) follow.
    assert_eq!(report.motion_cycles, 41 + 40 + 3);
}

#[test]
fn a_dropped_edge_is_missing() {
    let mut lines = faithful_stream(7);
    let dropped = lines
        .iter()
        .position(|line| line.contains("kind=plateau"))
        .unwrap();
    lines.remove(dropped);
    let report = check(&lines);
    assert_eq!(
        (report.missing, report.unexpected, report.glitches),
        (1, 0, 0)
    );
    assert!(!report.passed());
}

#[test]
fn a_shifted_or_extra_edge_is_unexpected() {
    let faithful = faithful_stream(7);
    let index = faithful
        .iter()
        .position(|line| line.contains("kind=reverse"))
        .unwrap();
    let mut shifted = faithful.clone();
    shifted[index] = shifted[index].replace(" ticks=", " ticks=1");
    assert_eq!(check(&shifted).unexpected, 1);

    let mut extra = faithful.clone();
    extra.insert(index + 1, faithful[index].clone());
    let report = check(&extra);
    assert_eq!((report.unexpected, report.missing), (1, 0));
}

#[test]
fn an_amplitude_change_mid_cycle_is_a_glitch() {
    let mut lines = faithful_stream(7);
    // A plateau during the soft start reports the next cycle's amplitude.
    let index = lines
        .iter()
        .position(|line| line.contains("kind=plateau") && line.contains("step=1 "))
        .unwrap();
    lines[index] = lines[index].replace("step=1 ", "step=2 ");
    let report = check(&lines);
    assert_eq!(report.glitches, 2, "into and out of the wrong amplitude");
    assert!(!report.passed());
}

#[test]
fn a_stream_without_its_end_fails_unless_open_ended() {
    let mut lines = faithful_stream(7);
    lines.pop();
    let report = check(&lines);
    assert!(!report.ended);
    assert!(!report.passed());
    assert!(check_with(&lines, false).0.passed());
}

#[test]
fn the_part_feeds_on_recorded_edges_and_the_plate_returns() {
    let lines = faithful_stream(7);
    let (_, edges, clock_hz) = check_with(&lines, true);
    let contact = Contact::kinetic(1.0, 1e-3).unwrap();
    let part = hil::simulate(&edges, clock_hz, &contact, hil::EdgeTimes::Actual);
    // Eq. 15 for the final plan, d = 0.6: a·T·(2d − 1)/4 with a = 4·x/(T(1 − d))².
    let accel_mps2 = 4.0 * 0.0025 / (0.02 * 0.4_f64).powi(2);
    let eq_15_mps = accel_mps2 * 0.02 * 0.2 / 4.0;
    // The final plan runs 40 whole cycles at full amplitude; the feed rate is over the last 16,
    // when the change of plan has decayed by 0.78²⁴ (Eq. 12's k1 per cycle).
    assert_eq!(part.steady_cycles, hil::STEADY_WINDOW_CYCLES);
    assert!(
        (part.feed_rate_mps - eq_15_mps).abs() < 1e-3 * eq_15_mps,
        "{} vs {eq_15_mps}",
        part.feed_rate_mps
    );
    // The plate's mean velocity over the window is only its bounded tick-plan residual.
    let window_s = hil::STEADY_WINDOW_CYCLES as f64 * 0.02;
    assert!(
        (part.feed_rate_relative_mps - part.feed_rate_mps).abs()
            <= 2.0 * plan(0.6).drift_bound_m / window_s
    );
    assert!(part.part_travel_m > 0.0);
    assert!(
        (part.plate_excursion_m - 0.0025).abs() < 1e-5,
        "{}",
        part.plate_excursion_m
    );
    assert!(part.plate_drift_m.abs() < 2.0 * plan(0.6).drift_bound_m + plan(0.586).drift_bound_m);
}

/// One `seg` line as the emulated board prints it.
fn seg_line(segment: &Segment, actual_tick: u64, slack_ticks: Option<u32>) -> String {
    let slack_ticks = slack_ticks.map(i64::from);
    Event::Segment(SegmentEvent::played(segment, actual_tick, slack_ticks)).to_string()
}

/// Preload slack of a segment preloaded 63 ticks after the edge before it.
const WORK_TICKS: u32 = 63;

#[test]
fn slack_is_summarised_by_its_minimum_and_power_of_two_buckets() {
    let mut scheduler = Scheduler::new(plan(0.586), 4);
    let mut lines = vec![plan_line(0, 0.586, 4)];
    let mut previous: Option<Segment> = None;
    let mut emit = |scheduler: &mut Scheduler, lines: &mut Vec<String>, segments: usize| {
        for _ in 0..segments {
            let segment = scheduler.next_segment();
            let slack = previous.map(|previous| previous.ticks - WORK_TICKS);
            lines.push(seg_line(&segment, segment.start_tick, slack));
            previous = Some(segment);
        }
    };
    emit(&mut scheduler, &mut lines, 2);
    log_start(&mut scheduler, &mut lines);
    emit(&mut scheduler, &mut lines, 40);
    let report = check_with(&lines, false).0;
    assert!(report.passed(), "{:?}", report.problems);
    // The shortest segment before a preload is an accelerate one (1712 or 1713 ticks).
    let (least, _) = report.min_slack.unwrap();
    assert_eq!(least, 1712 - i64::from(WORK_TICKS));
    assert_eq!(hil::slack_bucket(least), 1024);
    assert_eq!(report.slack_histogram.values().sum::<u64>(), 41);
    assert_eq!(
        report.slack_histogram.keys().copied().collect::<Vec<_>>(),
        [1024, 2048, 4096, 8192, 16384]
    );
    assert_eq!(
        (
            hil::slack_bucket(0),
            hil::slack_bucket(1),
            hil::slack_bucket(3)
        ),
        (0, 1, 2)
    );
}

/// Ticks past its deadline at which the late preload came, at which the output was zeroed, and
/// at which it restarted.
const LATE_TICKS: u64 = 51;
const ZERO_AFTER_TICKS: u64 = 57;
const RESTART_AFTER_TICKS: u64 = 60;

/// What the emulated board prints when the preload of cycle 10's first segment comes late: its
/// timer plays the segment playing (cycle 9's return) again, the firmware zeroes the output and
/// restarts it idle, then starts again and stops. Returns the lines and the missed deadline.
fn stream_with_a_missed_edge() -> (Vec<String>, u64) {
    let ramp = 4;
    let mut scheduler = Scheduler::new(plan(0.586), ramp);
    let mut lines = vec![plan_line(0, 0.586, ramp)];
    let mut shift = 0i64;
    let emit = |scheduler: &mut Scheduler, lines: &mut Vec<String>, shift: i64, segments| {
        for _ in 0..segments {
            let segment = scheduler.next_segment();
            let actual = segment.start_tick.checked_add_signed(shift).unwrap();
            lines.push(seg_line(&segment, actual, Some(1_000)));
        }
    };
    emit(&mut scheduler, &mut lines, shift, 2);
    log_start(&mut scheduler, &mut lines);
    let mut playing = scheduler.next_segment();
    let missed = loop {
        lines.push(seg_line(&playing, playing.start_tick, Some(1_000)));
        let next = scheduler.next_segment();
        if next.cycle == 10 {
            break next;
        }
        playing = next;
    };
    let deadline = missed.start_tick;
    let late_ticks = -i64::try_from(LATE_TICKS).unwrap();
    let replayed = SegmentEvent::played(&playing, deadline, Some(late_ticks));
    lines.push(Event::Replay(replayed).to_string());
    let zeroed_tick = deadline + ZERO_AFTER_TICKS;
    lines.push(
        Event::Zero {
            actual_tick: zeroed_tick,
        }
        .to_string(),
    );
    lines.push("ERROR fault: EdgeMissed (stop: Immediate)".into());
    lines.push(
        Event::Halt {
            tick: scheduler.next_tick(),
        }
        .to_string(),
    );
    scheduler.halt();
    let restart = scheduler.next_segment();
    shift = (deadline + RESTART_AFTER_TICKS) as i64 - restart.start_tick as i64;
    lines.push(seg_line(&restart, deadline + RESTART_AFTER_TICKS, None));
    emit(&mut scheduler, &mut lines, shift, 1);
    log_start(&mut scheduler, &mut lines);
    emit(&mut scheduler, &mut lines, shift, 80);
    log_stop(&mut scheduler, &mut lines);
    emit(&mut scheduler, &mut lines, shift, 20);
    lines.push(Event::End { tick: 0 }.to_string());
    (lines, deadline)
}

#[test]
fn a_missed_edge_is_reported_with_where_the_halt_left_the_plate() {
    let (lines, deadline) = stream_with_a_missed_edge();
    let stream = hil::read_stream(lines.join("\n").as_bytes()).unwrap();
    assert_eq!(stream.errors.len(), 1);
    let (report, edges, clock_hz) = Checker::check_events(&stream.events, true);
    // Every segment that began is as planned; the one never begun is not missing but missed.
    assert_eq!(report.missed.len(), 1);
    assert_eq!(report.missed[0].actual_tick, deadline);
    assert_eq!(
        (report.missing, report.unexpected, report.glitches),
        (0, 0, 0)
    );
    assert_eq!(report.matched, report.edges);
    assert!(!report.passed());
    assert!(
        report.problems[0].starts_with(&format!(
            "edge missed at tick {deadline}: the next segment was preloaded {LATE_TICKS} ticks late"
        )),
        "{:?}",
        report.problems
    );
    // The restart shifts the plan against the output's timeline; every edge is on its tick.
    assert_eq!(report.deviation_histogram.keys().collect::<Vec<_>>(), [&0]);

    // The replayed return (+a_max) held from the deadline until the output went to zero: the
    // plate, at rest at the end of cycle 9 within the plan's residual, moves at a_max·57 µs.
    let contact = Contact::kinetic(1.0, 1e-3).unwrap();
    let actual = hil::simulate(&edges, clock_hz, &contact, hil::EdgeTimes::Actual);
    assert_eq!(actual.halts.len(), 1);
    let halt = actual.halts[0];
    assert_eq!(halt.tick, deadline + ZERO_AFTER_TICKS);
    let accel_mps2 = plan(0.586).waveform.accel_mps2;
    let expected_mps = accel_mps2 * ZERO_AFTER_TICKS as f64 / f64::from(CLOCK_HZ);
    assert!(
        (halt.plate_velocity_mps - expected_mps).abs() < 1e-9,
        "{} vs {expected_mps} m/s",
        halt.plate_velocity_mps
    );
    assert!(
        halt.plate_position_m.abs() < 1e-6,
        "{} m",
        halt.plate_position_m
    );
    // On the planned ticks the output is zero from the missed edge on, as an on-time halt would
    // have made it: the plate stays within the plan's drift bound.
    let planned = hil::simulate(&edges, clock_hz, &contact, hil::EdgeTimes::Planned);
    assert!(planned.halts.is_empty());
    assert!(
        planned.plate_drift_m.abs() < 2.0 * plan(0.586).drift_bound_m,
        "{} m",
        planned.plate_drift_m
    );
}

/// Each field the checker compares with the plan fails a run when it is wrong: a level of the
/// wrong sign, a wrong cycle index, a wrong kind, length or start in one segment, a wrong step
/// or step count (in every segment, so that no amplitude changes mid-cycle and only the
/// comparison with the plan can see it).
#[test]
fn every_compared_field_of_a_segment_is_checked() {
    let faithful = faithful_stream(7);
    let reverse = faithful
        .iter()
        .position(|line| line.contains("kind=reverse") && line.contains(" step=4 "))
        .unwrap();
    let one = |from: &str, to: &str| {
        let mut lines = faithful.clone();
        assert!(lines[reverse].contains(from), "{}", lines[reverse]);
        lines[reverse] = lines[reverse].replace(from, to);
        lines
    };
    let every = |from: &str, to: &str| {
        faithful
            .iter()
            .map(|line| match is_seg(line) {
                true => line.replace(from, to),
                false => line.clone(),
            })
            .collect::<Vec<_>>()
    };
    let cases = [
        ("the level's sign", one("level=-1", "level=1")),
        ("the cycle index", one(" cycle=", " cycle=9")),
        ("the kind", one("kind=reverse", "kind=plateau")),
        ("the length", one(" ticks=", " ticks=1")),
        ("the step", every(" step=", " step=1")),
        ("the step count", every("steps=4", "steps=5")),
    ];
    assert!(check(&faithful).passed());
    for (field, lines) in cases {
        let report = check(&lines);
        assert!(
            !report.passed() && report.unexpected > 0,
            "{field}: {report:?}"
        );
    }
}
