//! The event stream's text: every event reads back as itself, lines of a real decoded log read
//! and write back byte for byte, numbers are written as defmt's decoder prints them, and a bad
//! line names what is wrong with it.

use feeder_shared::event::{parse_line, EdgeWork, Event, EventError, SegmentEvent};
use feeder_shared::{Drive, SegmentKind, WaveformSpec};
use proptest::prelude::*;

/// Lines of the emulated board's decoded log (the short scenario, a missed edge, a failed run).
const LOGGED_LINES: [&str; 13] = [
    "EVT plan tick=0 period_s=0.02 duty=0.586 stroke_m=0.0025 clock_hz=1000000 ramp=25",
    "EVT seg cycle=0 kind=idle planned=0 actual=0 ticks=20000 level=0 step=0 steps=25",
    "EVT seg cycle=1 kind=idle planned=20000 actual=20000 ticks=20000 level=0 step=0 steps=25 slack=19956",
    "EVT start tick=40000",
    "EVT plan tick=215860 period_s=0.02 duty=0.606 stroke_m=0.0025 clock_hz=1000000 ramp=4",
    "EVT seg cycle=2 kind=reverse planned=50007 actual=50007 ticks=5853 level=-1 step=1 steps=4 slack=8228",
    "EVT stop tick=416060",
    "EVT work edges=90 max_cycles=4295 total_cycles=151712 clock_hz=25000000",
    "EVT end tick=483389",
    "EVT replay cycle=9 kind=return planned=195860 actual=200000 ticks=4140 level=1 step=4 steps=4 slack=-51",
    "EVT zero actual=200057",
    "EVT enable state=off actual=200060",
    "EVT quickstop tick=1000000",
];

#[test]
fn logged_lines_read_and_write_back_byte_for_byte() {
    for line in LOGGED_LINES {
        let event = parse_line(line).unwrap().unwrap();
        assert_eq!(event.to_string(), line);
    }
}

#[test]
fn an_event_is_read_anywhere_after_its_marker() {
    assert_eq!(parse_line("INFO  plan: 50 Hz"), Ok(None));
    assert_eq!(
        parse_line("0.125 INFO  noise EVT halt tick=7"),
        Ok(Some(Event::Halt { tick: 7 }))
    );
    // Other words are ignored; of a key given twice the last value counts.
    assert_eq!(
        parse_line("EVT start note tick=1 by=operator tick=2"),
        Ok(Some(Event::Start { tick: 2 }))
    );
    assert_eq!(
        parse_line(
            "EVT plan tick=0 period_s=0.01 duty=0.6 accel_mps2=150 clock_hz=1000000 ramp=25"
        ),
        Ok(Some(Event::Plan {
            tick: 0,
            spec: WaveformSpec {
                period_s: 0.01,
                duty: 0.6,
                drive: Drive::Accel { accel_mps2: 150.0 },
            },
            clock_hz: 1_000_000,
            ramp_cycles: 25,
        }))
    );
}

/// A plan line whose stroke is `stroke_m`.
fn plan_with_stroke(stroke_m: f64) -> String {
    Event::Plan {
        tick: 0,
        spec: WaveformSpec {
            period_s: 0.02,
            duty: 0.586,
            drive: Drive::Stroke { stroke_m },
        },
        clock_hz: 1,
        ramp_cycles: 1,
    }
    .to_string()
}

#[test]
fn numbers_are_written_as_the_decoder_prints_them() {
    for (value, text) in [
        (0.02, "0.02"),
        (50.0, "50.0"),
        (145.86104693225042, "145.86104693225042"),
        (8.611636210880064e-7, "8.611636210880064e-7"),
        (1e-7, "1e-7"),
        (9.99e-6, "9.99e-6"),
        (1e-5, "0.00001"),
        (5e-5, "0.00005"),
        (1e15, "1000000000000000.0"),
        (9007199254740992.0, "9007199254740992.0"),
        (1e16, "1e16"),
        (1.5e16, "1.5e16"),
        (1e300, "1e300"),
        (f64::MAX, "1.7976931348623157e308"),
        (2.2250738585072014e-308, "2.2250738585072014e-308"),
        (5e-324, "5e-324"),
        (0.0, "0.0"),
        (-0.0, "-0.0"),
        (-0.586, "-0.586"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
        // Exactly halfway between two shortest candidates: the even one.
        (1969900000000000.0 + 0.25, "1969900000000000.2"),
        (271821092707313.0 + 0.625, "271821092707313.62"),
    ] {
        let line = plan_with_stroke(value);
        assert!(
            line.contains(&format!(" stroke_m={text} ")),
            "{value:e}: {line}"
        );
    }
}

#[test]
fn a_bad_line_names_what_is_wrong() {
    let segment = "cycle=1 kind=idle planned=0 actual=0 ticks=1 step=0 steps=1";
    for (line, error) in [
        ("EVT ", EventError::NoName),
        ("EVT warp tick=1", EventError::UnknownEvent("warp")),
        ("EVT start", EventError::Missing("tick")),
        ("EVT start tick=-3", EventError::NotWhole("tick")),
        ("EVT zero tick=5", EventError::Missing("actual")),
        (
            "EVT plan tick=0 period_s=0.02 duty=0.6 stroke_m=1 accel_mps2=1 clock_hz=1 ramp=1",
            EventError::Drive,
        ),
        (
            "EVT plan tick=0 period_s=fast duty=0.6 stroke_m=1 clock_hz=1 ramp=1",
            EventError::NotNumber("period_s"),
        ),
        (
            "EVT plan tick=0 period_s=0.02 duty=0.6 stroke_m=1 clock_hz=1 ramp=65536",
            EventError::OutOfRange("ramp"),
        ),
        (
            "EVT seg cycle=1 kind=sideways planned=0 actual=0 ticks=1 level=0 step=0 steps=1",
            EventError::UnknownKind("sideways"),
        ),
        (&format!("EVT seg {segment} level=2"), EventError::Level),
        (
            &format!("EVT seg {segment} level=0 slack=-3"),
            EventError::NotWhole("slack"),
        ),
        (
            &format!("EVT replay {segment} level=0 slack=late"),
            EventError::NotInteger("slack"),
        ),
        (
            "EVT seg cycle=1 kind=idle planned=0 actual=0 ticks=4294967296 level=0 step=0 steps=1",
            EventError::OutOfRange("ticks"),
        ),
        ("EVT enable state=maybe actual=1", EventError::State),
        (
            "EVT work edges=4294967296 max_cycles=1 total_cycles=1 clock_hz=1",
            EventError::OutOfRange("edges"),
        ),
    ] {
        assert_eq!(parse_line(line), Err(error), "{line}");
    }
}

#[test]
fn errors_read_as_words() {
    for (error, text) in [
        (EventError::NoName, "no event name"),
        (EventError::UnknownEvent("warp"), "unknown event `warp`"),
        (EventError::Missing("tick"), "no `tick`"),
        (EventError::NotWhole("tick"), "`tick` is not a whole number"),
        (EventError::NotNumber("duty"), "`duty` is not a number"),
        (EventError::NotInteger("slack"), "`slack` is not an integer"),
        (EventError::OutOfRange("ramp"), "`ramp` is out of range"),
        (
            EventError::Drive,
            "needs exactly one of `stroke_m`, `accel_mps2`",
        ),
        (
            EventError::UnknownKind("sideways"),
            "unknown segment kind `sideways`",
        ),
        (EventError::Level, "`level` must be -1, 0 or 1"),
        (EventError::State, "`state` must be on or off"),
    ] {
        assert_eq!(error.to_string(), text);
    }
}

/// Any `f64` but NaN, which never equals itself, with the extremes weighted in.
fn real() -> impl Strategy<Value = f64> {
    use proptest::num::f64 as float;
    prop_oneof![
        4 => float::POSITIVE
            | float::NEGATIVE
            | float::NORMAL
            | float::SUBNORMAL
            | float::ZERO
            | float::INFINITE,
        1 => prop::sample::select(vec![
            0.0,
            -0.0,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            5e-324,
            1e-5,
            1e16,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ]),
    ]
}

fn whole<T: Arbitrary + Copy + 'static>(extremes: &[T]) -> impl Strategy<Value = T> {
    prop_oneof![
        3 => any::<T>(),
        1 => prop::sample::select(extremes.to_vec()),
    ]
}

fn tick() -> impl Strategy<Value = u64> {
    whole(&[0, 1, u64::MAX])
}

fn kind() -> impl Strategy<Value = SegmentKind> {
    prop::sample::select(SegmentKind::ALL.to_vec())
}

/// A segment event whose slack `slack_ticks` draws.
fn segment(slack_ticks: impl Strategy<Value = Option<i64>>) -> impl Strategy<Value = SegmentEvent> {
    (
        (tick(), kind(), tick(), tick()),
        (
            whole(&[0, u32::MAX]),
            -1i8..=1,
            whole(&[0, u16::MAX]),
            whole(&[0, u16::MAX]),
        ),
        slack_ticks,
    )
        .prop_map(
            |(
                (cycle, kind, planned_tick, actual_tick),
                (ticks, level, step, steps),
                slack_ticks,
            )| {
                SegmentEvent {
                    cycle,
                    kind,
                    planned_tick,
                    actual_tick,
                    ticks,
                    level,
                    step,
                    steps,
                    slack_ticks,
                }
            },
        )
}

fn event() -> impl Strategy<Value = Event> {
    let drive = prop_oneof![
        real().prop_map(|stroke_m| Drive::Stroke { stroke_m }),
        real().prop_map(|accel_mps2| Drive::Accel { accel_mps2 }),
    ];
    let plan = (
        tick(),
        real(),
        real(),
        drive,
        whole(&[0, u32::MAX]),
        whole(&[0, u16::MAX]),
    )
        .prop_map(
            |(tick, period_s, duty, drive, clock_hz, ramp_cycles)| Event::Plan {
                tick,
                spec: WaveformSpec {
                    period_s,
                    duty,
                    drive,
                },
                clock_hz,
                ramp_cycles,
            },
        );
    // A segment that began was preloaded in time; a replay's preload may have been late.
    let began_slack = prop::option::of(whole(&[0, u32::MAX]).prop_map(i64::from));
    let replay_slack = prop::option::of(whole(&[i64::MIN, -1, 0, i64::MAX]));
    let work = (
        whole(&[0, u32::MAX]),
        whole(&[0, u32::MAX]),
        tick(),
        whole(&[0, u32::MAX]),
    )
        .prop_map(|(edges, max_cycles, total_cycles, clock_hz)| EdgeWork {
            edges,
            max_cycles,
            total_cycles,
            clock_hz,
        });
    prop_oneof![
        plan,
        tick().prop_map(|tick| Event::Start { tick }),
        tick().prop_map(|tick| Event::Stop { tick }),
        tick().prop_map(|tick| Event::Halt { tick }),
        tick().prop_map(|tick| Event::QuickStop { tick }),
        segment(began_slack).prop_map(Event::Segment),
        segment(replay_slack).prop_map(Event::Replay),
        tick().prop_map(|actual_tick| Event::Zero { actual_tick }),
        (tick(), any::<bool>()).prop_map(|(actual_tick, enabled)| Event::Enable {
            actual_tick,
            enabled
        }),
        work.prop_map(Event::Work),
        tick().prop_map(|tick| Event::End { tick }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4096))]

    #[test]
    fn every_event_reads_back_as_itself(event in event()) {
        let line = event.to_string();
        prop_assert!(line.starts_with("EVT "), "{line}");
        prop_assert!(line.starts_with(&format!("EVT {} ", event.name())), "{line}");
        prop_assert_eq!(parse_line(&line), Ok(Some(event)), "{}", line);
    }
}
