//! The firmware-in-the-loop checker on synthetic event streams: a faithful stream passes, and
//! each kind of fault (dropped edge, shifted edge, extra edge, mid-cycle amplitude change, early
//! end) is found and counted.

use feeder_shared::{
    Drive, Limits, Scheduler, SegmentKind, TickClock, TickPlan, Waveform, WaveformSpec,
};
use host_sim::hil::{self, Checker, Event, SegmentEvent};
use host_sim::plant::Contact;

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

/// What a firmware with `latency_ticks` of output latency prints for: idle, start, 40 cycles,
/// a duty change, 40 cycles, stop, idle until stopped.
fn faithful_stream(latency_ticks: u64) -> Vec<String> {
    let ramp = 4;
    let mut scheduler = Scheduler::new(plan(0.586), ramp);
    let mut lines = vec![format!(
        "EVT plan tick=0 period_s=0.02 duty=0.586 stroke_m=0.0025 clock_hz={CLOCK_HZ} ramp={ramp}"
    )];
    let emit = |scheduler: &mut Scheduler, lines: &mut Vec<String>, segments: usize| {
        for _ in 0..segments {
            let s = scheduler.next_segment();
            let actual = if s.start_tick == 0 {
                0
            } else {
                s.start_tick + latency_ticks
            };
            lines.push(format!(
                "INFO  noise EVT seg cycle={} kind={} planned={} actual={} ticks={} level={} step={} steps={}",
                s.cycle, s.kind.name(), s.start_tick, actual, s.ticks, s.level.sign(), s.amplitude.step, s.amplitude.steps
            ));
        }
    };
    emit(&mut scheduler, &mut lines, 2);
    scheduler.start();
    lines.push(format!("EVT start tick={}", scheduler.next_tick()));
    emit(&mut scheduler, &mut lines, 161);
    scheduler.set_plan(plan(0.6)).unwrap();
    scheduler.set_ramp_cycles(ramp);
    lines.push(format!(
        "EVT plan tick={} period_s=0.02 duty=0.6 stroke_m=0.0025 clock_hz={CLOCK_HZ} ramp={ramp}",
        scheduler.next_tick()
    ));
    emit(&mut scheduler, &mut lines, 160);
    scheduler.stop();
    lines.push(format!("EVT stop tick={}", scheduler.next_tick()));
    emit(&mut scheduler, &mut lines, 20);
    lines.push("EVT end tick=0".to_string());
    lines
}

fn check(lines: &[String]) -> hil::CheckReport {
    let stream = hil::read_stream(lines.join("\n").as_bytes()).unwrap();
    let mut checker = Checker::new();
    for event in &stream.events {
        checker.feed(event);
    }
    checker.finish(true).0
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
    assert_eq!(
        hil::parse_line("0.1 EVT seg cycle=2 kind=reverse planned=50007 actual=50014 ticks=5853 level=-1 step=1 steps=4").unwrap(),
        Some(Event::Segment(SegmentEvent {
            cycle: 2,
            kind: SegmentKind::Reverse,
            planned_tick: 50_007,
            actual_tick: 50_014,
            ticks: 5_853,
            level: -1,
            step: 1,
            steps: 4,
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
    let stream = hil::read_stream(lines.join("\n").as_bytes()).unwrap();
    let mut checker = Checker::new();
    for event in &stream.events {
        checker.feed(event);
    }
    assert!(checker.finish(false).0.passed());
}

#[test]
fn the_part_feeds_on_recorded_edges_and_the_plate_returns() {
    let lines = faithful_stream(7);
    let stream = hil::read_stream(lines.join("\n").as_bytes()).unwrap();
    let mut checker = Checker::new();
    for event in &stream.events {
        checker.feed(event);
    }
    let (_, edges, clock_hz) = checker.finish(true);
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
