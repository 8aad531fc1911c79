//! The parser: every command and every refused line by table, and whole numbers by property.

use feeder_shared::protocol;
use feeder_shared::{Command, Param, ReplyError, Setting};
use proptest::prelude::*;

use crate::common::slot;

fn code(line: &str) -> u16 {
    match protocol::parse(line) {
        Err(error) => error.code(),
        Ok(command) => panic!("{line:?} parsed as {command:?}"),
    }
}

#[test]
fn every_command_parses() {
    use Command::*;
    let table: &[(&str, Command)] = &[
        ("start", Start),
        ("stop", Stop),
        ("status", Status),
        ("reset", Reset),
        ("help", Help),
        ("?", Help),
        ("get freq", Get(Param::Frequency)),
        ("get duty", Get(Param::Duty)),
        ("get stroke", Get(Param::Stroke)),
        ("get accel", Get(Param::Accel)),
        ("get feed", Get(Param::Feed)),
        ("get ramp", Get(Param::Ramp)),
        ("set freq 50", Set(Setting::FrequencyHz(50.0))),
        ("set freq 62.5Hz", Set(Setting::FrequencyHz(62.5))),
        ("set freq 62.5 hz", Set(Setting::FrequencyHz(62.5))),
        ("set freq 1e2", Set(Setting::FrequencyHz(100.0))),
        ("set duty 0.6", Set(Setting::Duty(0.6))),
        ("set duty .6", Set(Setting::Duty(0.6))),
        ("set stroke 2.5", Set(Setting::StrokeMm(2.5))),
        ("set stroke 2.5mm", Set(Setting::StrokeMm(2.5))),
        ("set stroke 0.0025 m", Set(Setting::StrokeMm(2.5))),
        ("set stroke 0.0025M", Set(Setting::StrokeMm(2.5))),
        ("set stroke 2500um", Set(Setting::StrokeMm(2.5))),
        ("set stroke 2500 µm", Set(Setting::StrokeMm(2.5))),
        ("set accel 150", Set(Setting::AccelMps2(150.0))),
        ("set accel 150 m/s2", Set(Setting::AccelMps2(150.0))),
        ("set accel 150m/s^2", Set(Setting::AccelMps2(150.0))),
        ("set accel 150 m/s²", Set(Setting::AccelMps2(150.0))),
        ("set feed 30", Set(Setting::FeedMmps(30.0))),
        ("set feed 30 mm/s", Set(Setting::FeedMmps(30.0))),
        ("set feed -3", Set(Setting::FeedMmps(-3.0))),
        ("set ramp 0", Set(Setting::RampCycles(0))),
        ("set ramp 12 cycles", Set(Setting::RampCycles(12))),
        ("set ramp 1 cycle", Set(Setting::RampCycles(1))),
        ("set ramp 65535", Set(Setting::RampCycles(65535))),
        ("set ramp 4.0", Set(Setting::RampCycles(4))),
        ("recipe save 0", RecipeSave(slot(0))),
        ("recipe save 7", RecipeSave(slot(7))),
        ("recipe load 3", RecipeLoad(slot(3))),
        ("recipe list", RecipeList),
        // Case, blanks and tabs.
        ("START", Start),
        ("Set FREQ 50 HZ", Set(Setting::FrequencyHz(50.0))),
        ("  set\tduty   0.6  ", Set(Setting::Duty(0.6))),
        ("RECIPE Load 2", RecipeLoad(slot(2))),
        ("set stroke 2.5 MM", Set(Setting::StrokeMm(2.5))),
    ];
    for &(line, expected) in table {
        assert_eq!(protocol::parse(line), Ok(expected), "{line:?}");
    }
}

#[test]
fn every_parse_error_has_its_code() {
    let table: &[(&str, u16)] = &[
        ("", 20),
        ("go", 20),
        ("starts", 20),
        ("recipe erase 1", 20),
        ("get", 21),
        ("set", 21),
        ("set freq", 21),
        ("set ramp", 21),
        ("recipe", 21),
        ("recipe save", 21),
        ("start now", 22),
        ("status all", 22),
        ("get freq hz", 22),
        ("set freq 50 Hz please", 22),
        ("recipe list 1", 22),
        ("get speed", 23),
        ("set speed 3", 23),
        ("set freq fifty", 24),
        ("set freq hz", 24),
        ("recipe load x", 24),
        ("set duty 0,6", 24),
        ("set duty ,6", 24),
        ("set freq 62,5hz", 24),
        ("recipe load 1,0", 24),
        ("set freq 50,", 26),
        ("set freq inf", 25),
        ("set freq -inf", 25),
        ("set duty NaN", 25),
        ("set freq 1e999", 25),
        ("set ramp infinity", 25),
        ("set freq 50 kHz", 26),
        ("set freq 50mm", 26),
        ("set stroke 2.5 cm", 26),
        ("set stroke 2.5 m/s2", 26),
        ("set stroke 2.5 in", 26),
        ("set duty 0.6 %", 26),
        ("set feed 30 m/s", 26),
        ("set accel 150 g", 26),
        ("set ramp 3 s", 26),
        ("recipe save 1x", 26),
        ("set freq 5e", 26),
        ("set ramp 2.5", 27),
        ("recipe load 1.5", 27),
        ("set ramp -1", 28),
        ("set ramp 65536", 28),
        ("recipe save 8", 28),
        ("recipe load -1", 28),
    ];
    for &(line, expected) in table {
        assert_eq!(code(line), expected, "{line:?}");
    }
}

#[test]
fn a_decimal_comma_is_named() {
    for (line, what) in [
        ("set duty 0,6", "the duty cycle as a plain fraction"),
        ("set stroke 2,5 mm", "the stroke in mm (or m, µm)"),
        ("set accel ,5", "the peak acceleration in m/s2"),
    ] {
        assert_eq!(
            protocol::parse(line),
            Err(ReplyError::DecimalComma { what }),
            "{line:?}"
        );
    }
    let reply = protocol::Reply::error(&ReplyError::DecimalComma {
        what: "the duty cycle as a plain fraction",
    });
    assert_eq!(
        reply.as_str(),
        "ERR 24 not a number: use a decimal point, not a comma; expected the duty cycle as a plain \
         fraction"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Any parameter's value with a decimal comma is refused as a decimal comma, never read or
    /// taken for a unit; the same value with a decimal point is read.
    #[test]
    fn decimal_commas_are_refused_as_such(
        whole in 0u32..1000,
        fraction in 0u32..1000,
        unit in prop::sample::select(vec!["", " ", "hz", "mm", " Hz"]),
        param in prop::sample::select(vec!["freq", "duty", "stroke", "accel", "feed", "ramp"]),
    ) {
        let line = format!("set {param} {whole},{fraction}{unit}");
        let refused = protocol::parse(&line);
        prop_assert!(
            matches!(refused, Err(ReplyError::DecimalComma { .. })),
            "{:?}: {:?}", line, refused
        );
        prop_assert_eq!(refused.map_err(|e| e.code()), Err(24));
        let pointed = protocol::parse(&format!("set {param} {whole}.{fraction}"));
        prop_assert!(
            !matches!(pointed, Err(ReplyError::DecimalComma { .. } | ReplyError::BadNumber { .. })),
            "{:?}", pointed
        );
    }

    /// Whole numbers: ramp lengths in range are read, others refused with the right code.
    #[test]
    fn ramp_lengths_are_checked(n in -100_000i64..200_000) {
        let parsed = protocol::parse(&format!("set ramp {n}"));
        match u16::try_from(n) {
            Ok(cycles) => prop_assert_eq!(parsed, Ok(Command::Set(Setting::RampCycles(cycles)))),
            Err(_) => prop_assert_eq!(parsed.map_err(|e| e.code()), Err(28)),
        }
    }

    /// A stroke typed in any length unit is the same number of millimetres, exactly: the unit's
    /// power of ten moves the decimal point, it is not a multiplication that rounds.
    #[test]
    fn a_stroke_reads_the_same_in_every_length_unit(micrometres in 1u32..100_000) {
        let mm = |line: String| match protocol::parse(&line) {
            Ok(Command::Set(Setting::StrokeMm(mm))) => mm,
            other => panic!("{line:?}: {other:?}"),
        };
        let expected: f64 = format!("{}.{:03}", micrometres / 1000, micrometres % 1000).parse().unwrap();
        prop_assert_eq!(mm(format!("set stroke {micrometres}um")), expected);
        prop_assert_eq!(mm(format!("set stroke {micrometres}e-3 mm")), expected);
        prop_assert_eq!(mm(format!("set stroke {micrometres}e-6 m")), expected);
    }
}
