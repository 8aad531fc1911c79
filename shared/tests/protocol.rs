//! The command protocol: every command and every error by table, the line assembler's framing,
//! reply formatting, validation of `set`, and properties over arbitrary input bytes.

use feeder_shared::number::{split_decimal, Fixed, Significant};
use feeder_shared::protocol::{self, MAX_LINE_BYTES, REPLY_CAPACITY};
use feeder_shared::recipe::{self, RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{
    Command, Drive, Error, Limits, LineAssembler, Machine, Param, Phase, Quantity, RecipeSlot,
    Reply, ReplyError, Setting, Settings, Status, TickClock, Waveform, WaveformSpec,
};
use proptest::prelude::*;

mod common;
use common::{machine, slot};
use std::fmt::Write as _;

/// Feeds `input` and collects what each completed line asks for.
fn feed(input: &[u8]) -> Vec<Result<Command, ReplyError>> {
    let mut assembler = LineAssembler::new();
    input
        .iter()
        .filter_map(|&byte| assembler.push(byte))
        .collect()
}

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
        ("set freq inf", 25),
        ("set freq -inf", 25),
        ("set duty NaN", 25),
        ("set freq 1e999", 25),
        ("set ramp infinity", 25),
        ("set freq 50 kHz", 26),
        ("set freq 50mm", 26),
        ("set stroke 2.5 m", 26),
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
fn error_codes_are_stable_and_explained() {
    let nan = f64::NAN;
    let table: Vec<(ReplyError, u16, &str)> = vec![
        (
            ReplyError::LineTooLong,
            10,
            "line longer than 64 bytes, ignored",
        ),
        (
            ReplyError::NotText,
            11,
            "line contains bytes that are not text, ignored",
        ),
        (
            ReplyError::UnknownCommand,
            20,
            "unknown command; send help for the list of commands",
        ),
        (
            ReplyError::MissingArgument {
                what: "the stroke in mm",
            },
            21,
            "missing the stroke in mm",
        ),
        (ReplyError::UnexpectedArgument, 22, "unexpected words"),
        (
            ReplyError::UnknownParameter,
            23,
            "unknown parameter; use freq, duty",
        ),
        (
            ReplyError::BadNumber { what: "x" },
            24,
            "not a number: expected x",
        ),
        (ReplyError::NotFinite, 25, "the number must be finite"),
        (
            ReplyError::WrongUnit {
                what: "the frequency in Hz",
            },
            26,
            "wrong unit: expected the",
        ),
        (
            ReplyError::NotWholeNumber { what: "x" },
            27,
            "not a whole number: expected x",
        ),
        (
            ReplyError::OutOfRange {
                what: "x",
                min: 0,
                max: 7,
            },
            28,
            "expected x from 0 to 7",
        ),
        (
            Error::NotFinite {
                quantity: Quantity::Duty,
            }
            .into(),
            40,
            "duty cycle must be a finite",
        ),
        (
            Error::NotPositive {
                quantity: Quantity::FrequencyHz,
                value: 0.0,
            }
            .into(),
            41,
            "greater",
        ),
        (
            Error::DutyTooLow { duty: 0.4 }.into(),
            42,
            "duty cycle 0.4 must be above 0.5",
        ),
        (
            Error::DutyTooHigh { duty: 1.0 }.into(),
            43,
            "duty cycle 1 must be below 1",
        ),
        (
            Error::FrequencyOutOfBand {
                frequency_hz: 500.0,
                min_hz: 20.0,
                max_hz: 200.0,
            }
            .into(),
            44,
            "frequency 500 Hz is outside the allowed band 20..=200 Hz; nothing changed",
        ),
        (
            Error::AccelAboveLimit {
                accel_mps2: 600.0,
                limit_mps2: 500.0,
            }
            .into(),
            45,
            "m/s2",
        ),
        (
            Error::StrokeAboveLimit {
                stroke_m: 0.01,
                limit_m: 0.005,
            }
            .into(),
            46,
            "stroke 0.01 m",
        ),
        (
            Error::InvalidLimit {
                quantity: Quantity::StrokeLimitM,
                value: nan,
            }
            .into(),
            47,
            "NaN",
        ),
        (
            Error::SegmentTooShort {
                segment: feeder_shared::SegmentKind::Plateau,
                exact_ticks: 0.25,
            }
            .into(),
            48,
            "plateau segment lasts 0.25 timer ticks",
        ),
        (
            Error::TicksOverflow {
                segment: feeder_shared::SegmentKind::Idle,
                exact_ticks: 2e4,
                max_ticks: 1000,
            }
            .into(),
            49,
            "at most 1000",
        ),
        (
            Error::ClockMismatch {
                running_hz: 1,
                requested_hz: 2,
            }
            .into(),
            50,
            "2 Hz clock",
        ),
        (
            Error::NoSlip {
                accel_mps2: 5.0,
                friction_accel_mps2: 9.8,
            }
            .into(),
            51,
            "mug = 9.8",
        ),
        (
            Error::OutsideViscousRange { force_n: 1.0 }.into(),
            52,
            "viscous",
        ),
        (
            Error::FeedRateAboveReach {
                target_mps: 1.0,
                max_mps: 0.1,
            }
            .into(),
            53,
            "most is 0.1",
        ),
        (
            Error::FeedRateBelowReach {
                target_mps: 0.001,
                min_mps: 0.01,
            }
            .into(),
            54,
            "least",
        ),
        (
            Error::SegmentBelowFloor {
                segment: feeder_shared::SegmentKind::Accelerate,
                ticks: 95,
                min_ticks: 120,
                clock_hz: 1_000_000,
            }
            .into(),
            55,
            "accelerate segment lasts 95 ticks of the 1000000 Hz clock (95 us), shorter than the 120 ticks (120 us)",
        ),
        (ReplyError::NotStopped, 60, "only allowed while stopped"),
        (ReplyError::FaultLatched, 61, "send reset"),
        (ReplyError::StorageFailed, 62, "could not be written"),
    ];
    let mut codes: Vec<u16> = table.iter().map(|(_, code, _)| *code).collect();
    codes.dedup();
    assert_eq!(codes.len(), table.len(), "codes are unique");
    for (error, expected_code, text) in &table {
        assert_eq!(error.code(), *expected_code, "{error:?}");
        let reply = Reply::error(error);
        let head = format!("ERR {expected_code} ");
        assert!(reply.as_str().starts_with(&head), "{reply}");
        assert!(reply.as_str().contains(text), "{reply} lacks {text:?}");
        assert!(!reply.is_ok());
        assert_printable_ascii(reply.as_str());
    }
}

fn assert_printable_ascii(text: &str) {
    assert!(
        text.bytes().all(|b| (b' '..=b'~').contains(&b)),
        "not printable ASCII: {text:?}"
    );
}

#[test]
fn lines_end_at_cr_lf_or_crlf() {
    let got = feed(b"start\rstop\nstatus\r\nhelp\n\rreset\r\r\n\n");
    assert_eq!(
        got,
        [
            Ok(Command::Start),
            Ok(Command::Stop),
            Ok(Command::Status),
            Ok(Command::Help),
            Ok(Command::Reset)
        ]
    );
    // Nothing until the terminator arrives.
    assert!(feed(b"start").is_empty());
}

#[test]
fn blank_lines_get_no_reply() {
    assert!(feed(b"\r\n\n\r   \t \r\n").is_empty());
    // Backspacing a whole line leaves it blank.
    assert!(feed(b"sta\x08\x08\x08\r").is_empty());
}

#[test]
fn backspace_and_delete_erase_characters() {
    assert_eq!(feed(b"stoq\x08p\r"), [Ok(Command::Stop)]);
    assert_eq!(feed(b"startx\x7f\n"), [Ok(Command::Start)]);
    // A multi-byte character goes in one erase.
    assert_eq!(
        feed("set accel 150 m/s²\x08\x08\x08\x082\n".as_bytes()),
        feed(b"set accel 150 2\n")
    );
    assert_eq!(feed("stop²\x08\n".as_bytes()), [Ok(Command::Stop)]);
    assert_eq!(feed(b"\x08\x08stop\n"), [Ok(Command::Stop)]);
}

#[test]
fn overlong_lines_give_one_error_when_they_end() {
    let long = "x".repeat(MAX_LINE_BYTES + 1);
    let input = format!("{long}{long}{long}\r\nstart\n");
    assert_eq!(
        feed(input.as_bytes()),
        [Err(ReplyError::LineTooLong), Ok(Command::Start)]
    );
    // Erasing cannot rescue a line that already overflowed.
    let input = format!("{long}\x08\x08\n");
    assert_eq!(feed(input.as_bytes()), [Err(ReplyError::LineTooLong)]);
}

#[test]
fn line_length_limit_is_exact_and_ignores_leading_blanks() {
    let padded = |length: usize| format!("status{}", " ".repeat(length - "status".len()));
    assert_eq!(
        feed(format!("{}\n", padded(MAX_LINE_BYTES)).as_bytes()),
        [Ok(Command::Status)]
    );
    assert_eq!(
        feed(format!("{}\n", padded(MAX_LINE_BYTES + 1)).as_bytes()),
        [Err(ReplyError::LineTooLong)]
    );
    let indented = format!("{}status\n", " ".repeat(3 * MAX_LINE_BYTES));
    assert_eq!(feed(indented.as_bytes()), [Ok(Command::Status)]);
}

#[test]
fn garbage_is_refused_as_not_text() {
    for input in [
        &b"st\xffart\n"[..],
        b"\x00\n",
        b"\x1b[A\n",
        b"start\x07\n",
        b"\xc3\n",
        b"\xe2\x82\n",
    ] {
        assert_eq!(feed(input), [Err(ReplyError::NotText)], "{input:?}");
    }
    // UTF-8 text that is no command is an unknown command, not garbage.
    assert_eq!(
        feed("démarrer\n".as_bytes()),
        [Err(ReplyError::UnknownCommand)]
    );
}

#[test]
fn clear_drops_a_partial_line() {
    let mut assembler = LineAssembler::new();
    for &byte in b"garbage" {
        assert_eq!(assembler.push(byte), None);
    }
    assembler.clear();
    let got: Vec<_> = b"stop\n"
        .iter()
        .filter_map(|&b| assembler.push(b))
        .collect();
    assert_eq!(got, [Ok(Command::Stop)]);
}

fn paper_stroke_m() -> f64 {
    0.0025
}

#[test]
fn defaults_are_the_papers_operating_point() {
    let applied = Settings::DEFAULT.validate(&machine()).unwrap();
    assert_eq!(applied.settings, Settings::default());
    let waveform = applied.plan.waveform;
    assert!((waveform.frequency_hz() - 50.0).abs() < 1e-9);
    assert!((waveform.duty - (2.0 - 2f64.sqrt())).abs() < 1e-15);
    assert_eq!(waveform.stroke_m, paper_stroke_m());
    assert_eq!(applied.plan.period_ticks, 20_000);
    // Eq. 15 while sliding: aT(2d − 1)/4.
    let expected = waveform.accel_mps2 * 0.02 * (2.0 * waveform.duty - 1.0) / 4.0;
    assert!((applied.feed_rate_mps - expected).abs() < 1e-12);
}

#[test]
fn set_changes_one_parameter_and_holds_the_others() {
    let machine = machine();
    let base = Settings::DEFAULT;

    let applied = base.apply(Setting::FrequencyHz(62.5), &machine).unwrap();
    assert_eq!(
        applied.settings,
        Settings {
            frequency_hz: 62.5,
            ..base
        }
    );
    assert_eq!(applied.plan.period_ticks, 16_000);
    assert_eq!(applied.plan.waveform.stroke_m, paper_stroke_m());

    let applied = base.apply(Setting::Duty(0.6), &machine).unwrap();
    assert_eq!(applied.settings, Settings { duty: 0.6, ..base });

    let applied = base.apply(Setting::StrokeMm(2.0), &machine).unwrap();
    assert_eq!(applied.settings.drive, Drive::Stroke { stroke_m: 0.002 });
    assert!((applied.plan.waveform.stroke_m - 0.002).abs() < 1e-15);

    let applied = base.apply(Setting::AccelMps2(120.0), &machine).unwrap();
    assert_eq!(applied.settings.drive, Drive::Accel { accel_mps2: 120.0 });
    assert_eq!(applied.plan.waveform.accel_mps2, 120.0);
    // With the acceleration held, a new frequency changes the stroke, not the acceleration.
    let held = applied
        .settings
        .apply(Setting::FrequencyHz(100.0), &machine)
        .unwrap();
    assert_eq!(held.plan.waveform.accel_mps2, 120.0);

    let applied = base.apply(Setting::RampCycles(25), &machine).unwrap();
    assert_eq!(
        applied.settings,
        Settings {
            ramp_cycles: 25,
            ..base
        }
    );
    assert_eq!(applied.plan, base.validate(&machine).unwrap().plan);
}

#[test]
fn set_feed_chooses_the_duty_for_the_target() {
    let machine = machine();
    for target_mmps in [20.0, 30.0, 45.0] {
        let applied = Settings::DEFAULT
            .apply(Setting::FeedMmps(target_mmps), &machine)
            .unwrap();
        let d = applied.settings.duty;
        // Independent Eq. 5 and Eq. 15 at the chosen duty with the stroke held.
        let (period_s, stroke_m) = (0.02, paper_stroke_m());
        let accel = stroke_m / (period_s * (1.0 - d) / 2.0).powi(2);
        let feed_mmps = accel * period_s * (2.0 * d - 1.0) / 4.0 * 1000.0;
        assert!(
            (feed_mmps - target_mmps).abs() < 1e-6 * target_mmps,
            "{target_mmps}: {feed_mmps}"
        );
        assert!((applied.feed_rate_mps * 1000.0 - target_mmps).abs() < 1e-6 * target_mmps);
        assert_eq!(applied.settings.frequency_hz, 50.0);
        assert_eq!(applied.settings.drive, Settings::DEFAULT.drive);
    }
}

#[test]
fn refused_settings_name_the_reason() {
    let machine = machine();
    let base = Settings::DEFAULT;
    let refuse = |setting| base.apply(setting, &machine).unwrap_err();
    assert!(matches!(
        refuse(Setting::FrequencyHz(0.0)),
        Error::NotPositive {
            quantity: Quantity::FrequencyHz,
            ..
        }
    ));
    assert!(matches!(
        refuse(Setting::FrequencyHz(500.0)),
        Error::FrequencyOutOfBand { .. }
    ));
    assert!(matches!(
        refuse(Setting::FrequencyHz(10.0)),
        Error::FrequencyOutOfBand { .. }
    ));
    assert!(matches!(
        refuse(Setting::Duty(0.5)),
        Error::DutyTooLow { .. }
    ));
    assert!(matches!(
        refuse(Setting::Duty(1.0)),
        Error::DutyTooHigh { .. }
    ));
    assert!(matches!(
        refuse(Setting::StrokeMm(6.0)),
        Error::StrokeAboveLimit { .. }
    ));
    assert!(matches!(
        refuse(Setting::StrokeMm(-1.0)),
        Error::NotPositive { .. }
    ));
    assert!(matches!(
        refuse(Setting::AccelMps2(600.0)),
        Error::AccelAboveLimit { .. }
    ));
    assert!(matches!(
        refuse(Setting::FeedMmps(0.0)),
        Error::NotPositive { .. }
    ));
    assert!(matches!(
        refuse(Setting::FeedMmps(5000.0)),
        Error::FeedRateAboveReach { .. }
    ));
    // Duty close to 1 at 200 Hz on a 1 MHz clock: the backward swing is a fraction of a tick.
    let fast = Settings {
        frequency_hz: 200.0,
        drive: Drive::Accel { accel_mps2: 100.0 },
        ..base
    };
    assert!(matches!(
        fast.apply(Setting::Duty(0.9999999), &machine),
        Err(Error::SegmentTooShort { .. })
    ));
    // A timer that counts at most 10,000 ticks at 1 MHz cannot idle a 20 ms period.
    let narrow = Machine {
        clock: TickClock::new(1_000_000).with_max_segment_ticks(10_000),
        ..machine
    };
    assert!(matches!(
        base.validate(&narrow),
        Err(Error::TicksOverflow { .. })
    ));
}

fn status(fault: Option<&str>) -> Status<&str> {
    let waveform = Waveform::new(
        WaveformSpec::from_frequency(50.0, 0.6, Drive::Stroke { stroke_m: 0.0025 }),
        &Limits::NONE,
    )
    .unwrap();
    Status {
        phase: Phase::Running,
        fault,
        waveform,
        ramp_cycles: 10,
        feed_rate_mps: 0.0731234,
        uptime_ms: 12_345,
        cycles: 617,
    }
}

#[test]
fn status_reports_state_parameters_fault_uptime_and_cycles() {
    // a = x / (T(1 − d)/2)² = 0.0025 / 0.004² = 156.25 m/s².
    let expected = "OK state=running freq_hz=50 duty=0.6 stroke_mm=2.5 accel_mps2=156.25 \
                    ramp_cycles=10 feed_mmps=73.123 uptime_s=12.345 cycles=617 fault=none";
    assert_eq!(Reply::status(&status(None)).as_str(), expected);
    let faulted = Reply::status(&status(Some("overcurrent on phase A")));
    assert!(
        faulted.as_str().starts_with("OK state=fault freq_hz=50 "),
        "{faulted}"
    );
    assert!(
        faulted.as_str().ends_with(" fault=overcurrent on phase A"),
        "{faulted}"
    );
    for (phase, name) in [
        (Phase::Stopped, "stopped"),
        (Phase::Starting, "starting"),
        (Phase::Stopping, "stopping"),
    ] {
        let reply = Reply::status(&Status {
            phase,
            ..status(None)
        });
        assert!(
            reply.as_str().starts_with(&format!("OK state={name} ")),
            "{reply}"
        );
    }
}

#[test]
fn get_reports_one_parameter() {
    let snapshot = status(None);
    let table = [
        (Param::Frequency, "OK freq_hz=50"),
        (Param::Duty, "OK duty=0.6"),
        (Param::Stroke, "OK stroke_mm=2.5"),
        (Param::Accel, "OK accel_mps2=156.25"),
        (Param::Feed, "OK feed_mmps=73.123"),
        (Param::Ramp, "OK ramp_cycles=10"),
    ];
    for (param, expected) in table {
        assert_eq!(Reply::get(param, &snapshot).as_str(), expected);
    }
}

#[test]
fn set_reply_lists_the_candidate() {
    let applied = Settings::DEFAULT
        .apply(Setting::Duty(0.6), &machine())
        .unwrap();
    let reply = Reply::applied(&applied);
    assert!(
        reply.as_str().starts_with(
            "OK freq_hz=50 duty=0.6 stroke_mm=2.5 accel_mps2=156.25 ramp_cycles=10 feed_mmps="
        ),
        "{reply}"
    );
}

#[test]
fn simple_replies() {
    assert_eq!(Reply::ok(format_args!("")).as_str(), "OK");
    assert_eq!(
        Reply::ok(format_args!("stopping at the next cycle")).as_str(),
        "OK stopping at the next cycle"
    );
    assert_eq!(Reply::recipe_saved(slot(4)).as_str(), "OK recipe 4 saved");
    let help = Reply::help();
    assert!(help.is_ok());
    for word in [
        "start",
        "stop",
        "status",
        "get",
        "set freq <Hz>",
        "set feed <mm/s>",
        "recipe list",
        "reset",
        "help",
    ] {
        assert!(help.as_str().contains(word), "{help} lacks {word}");
    }
    assert!(help.as_str().len() < REPLY_CAPACITY);
}

#[test]
fn replies_are_ascii_single_lines_and_truncate_instead_of_failing() {
    let reply = Reply::ok(format_args!("a\r\nb\tc μg ² − ≤ ≥ … · 漢"));
    assert_eq!(reply.as_str(), "OK a  b c mug 2 - <= >= ... * ?");
    let long = "y".repeat(2 * REPLY_CAPACITY);
    let reply = Reply::ok(format_args!("{long}"));
    assert_eq!(reply.as_str().len(), REPLY_CAPACITY);
    assert!(reply.as_str().starts_with("OK yyy"));
    let mut reply = Reply::ok(format_args!("x"));
    write!(reply, "{}", "²".repeat(2 * REPLY_CAPACITY)).unwrap();
    assert_eq!(reply.as_str().len(), REPLY_CAPACITY);
}

#[test]
fn recipe_replies() {
    let machine = machine();
    let mut flash = [[0xffu8; RECORD_LEN]; RECIPE_SLOTS];
    let stored = Settings {
        frequency_hz: 60.0,
        duty: 0.6,
        ..Settings::DEFAULT
    };
    flash[1] = recipe::encode(slot(1), &stored);
    let accel = Settings {
        drive: Drive::Accel { accel_mps2: 150.0 },
        ramp_cycles: 3,
        ..stored
    };
    flash[2] = recipe::encode(slot(2), &accel);
    flash[3] = recipe::encode(slot(3), &stored);
    flash[3][9] ^= 0x10;
    flash[4] = recipe::encode(slot(5), &stored);

    let loaded = recipe::load(&flash[1], slot(1), &machine).unwrap();
    let reply = Reply::recipe_loaded(slot(1), &loaded);
    assert!(
        reply
            .as_str()
            .starts_with("OK recipe 1 loaded freq_hz=60 duty=0.6 "),
        "{reply}"
    );

    let loaded = recipe::load(&flash[0], slot(0), &machine).unwrap();
    let reply = Reply::recipe_loaded(slot(0), &loaded);
    assert!(
        reply.as_str().starts_with(
            "OK recipe 0 not usable (no recipe saved in this slot), defaults loaded \
             freq_hz=50 duty=0.5858 "
        ),
        "{reply}"
    );

    let entries: [_; RECIPE_SLOTS] =
        std::array::from_fn(|index| recipe::decode(&flash[index], slot(index as u8)));
    assert_eq!(
        Reply::recipe_list(&entries).as_str(),
        "OK recipes 0=empty 1=60Hz/0.6/2.5mm/r10 2=60Hz/0.6/150m/s2/r3 3=corrupt 4=wrong-slot \
         5=empty 6=empty 7=empty"
    );
}

/// A minimal controller over the shared API, standing in for the firmware's.
struct Controller {
    machine: Machine,
    settings: Settings,
    applied: feeder_shared::Applied,
    running: bool,
    fault: Option<&'static str>,
    flash: [[u8; RECORD_LEN]; RECIPE_SLOTS],
}

impl Controller {
    fn new() -> Self {
        let machine = machine();
        Controller {
            machine,
            settings: Settings::DEFAULT,
            applied: Settings::DEFAULT.validate(&machine).unwrap(),
            running: false,
            fault: None,
            flash: [[0xff; RECORD_LEN]; RECIPE_SLOTS],
        }
    }

    fn execute(&mut self, request: Result<Command, ReplyError>) -> Reply {
        let command = match request {
            Ok(command) => command,
            Err(error) => return Reply::error(&error),
        };
        match command {
            Command::Start if self.fault.is_some() => Reply::error(&ReplyError::FaultLatched),
            Command::Start => {
                self.running = true;
                Reply::ok(format_args!("starting"))
            }
            Command::Stop => {
                self.running = false;
                Reply::ok(format_args!("stopping"))
            }
            Command::Status => Reply::status(&self.status()),
            Command::Get(param) => Reply::get(param, &self.status()),
            Command::Set(setting) => match self.settings.apply(setting, &self.machine) {
                Ok(applied) => {
                    self.settings = applied.settings;
                    self.applied = applied;
                    Reply::applied(&applied)
                }
                Err(error) => Reply::error(&error.into()),
            },
            Command::RecipeSave(_) if self.running => Reply::error(&ReplyError::NotStopped),
            Command::RecipeSave(slot) => {
                self.flash[slot.index()] = recipe::encode(slot, &self.settings);
                Reply::recipe_saved(slot)
            }
            Command::RecipeLoad(slot) => {
                let loaded = recipe::load(&self.flash[slot.index()], slot, &self.machine).unwrap();
                self.settings = loaded.applied.settings;
                self.applied = loaded.applied;
                Reply::recipe_loaded(slot, &loaded)
            }
            Command::RecipeList => {
                let entries: [_; RECIPE_SLOTS] = std::array::from_fn(|index| {
                    recipe::decode(&self.flash[index], RecipeSlot::new(index as u8).unwrap())
                });
                Reply::recipe_list(&entries)
            }
            Command::Reset => {
                self.fault = None;
                Reply::ok(format_args!("fault cleared"))
            }
            Command::Help => Reply::help(),
        }
    }

    fn status(&self) -> Status<&'static str> {
        Status {
            phase: if self.running {
                Phase::Running
            } else {
                Phase::Stopped
            },
            fault: self.fault,
            waveform: self.applied.plan.waveform,
            ramp_cycles: self.settings.ramp_cycles,
            feed_rate_mps: self.applied.feed_rate_mps,
            uptime_ms: 0,
            cycles: 0,
        }
    }

    fn session(&mut self, input: &[u8]) -> Vec<Reply> {
        let mut assembler = LineAssembler::new();
        input
            .iter()
            .filter_map(|&byte| assembler.push(byte))
            .map(|r| self.execute(r))
            .collect()
    }
}

#[test]
fn a_session_answers_every_line_once() {
    let mut controller = Controller::new();
    let script = "set freq 60\r\nset duty 0.3\r\nstart\r\nrecipe save 1\r\nstop\r\n\
                  recipe save 1\r\n\x00\x01\x02\r\nset feed 30\r\nrecipe load 1\r\nget freq\r\n\
                  get duty\r\nrecipe load 2\r\n";
    let replies: Vec<String> = controller
        .session(script.as_bytes())
        .iter()
        .map(|r| r.to_string())
        .collect();
    let heads: Vec<&str> = replies
        .iter()
        .map(|r| r.split(' ').take(2).last().unwrap())
        .collect();
    assert_eq!(replies.len(), 12, "{replies:#?}");
    assert!(replies[0].starts_with("OK freq_hz=60 "));
    assert!(replies[1].starts_with("ERR 42 duty cycle 0.3 must be above 0.5"));
    assert_eq!(replies[2], "OK starting");
    assert!(replies[3].starts_with("ERR 60 "));
    assert_eq!(replies[5], "OK recipe 1 saved");
    assert!(replies[6].starts_with("ERR 11 "));
    assert!(replies[7].starts_with("OK freq_hz=60 duty=0.5"));
    assert!(
        replies[8].starts_with("OK recipe 1 loaded freq_hz=60 duty=0.5858 "),
        "{}",
        replies[8]
    );
    assert_eq!(replies[9], "OK freq_hz=60");
    assert_eq!(replies[10], "OK duty=0.5858");
    assert!(replies[11].starts_with("OK recipe 2 not usable (no recipe saved"));
    assert_eq!(heads[4], "stopping");
}

/// Independent check of a reply line's shape.
fn well_formed(reply: &str) -> bool {
    let printable = reply.bytes().all(|b| (b' '..=b'~').contains(&b));
    let shape = reply == "OK"
        || reply.starts_with("OK ")
        || reply.strip_prefix("ERR ").is_some_and(|rest| {
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            !digits.is_empty() && rest[digits.len()..].starts_with(' ')
        });
    printable && shape && reply.len() <= REPLY_CAPACITY
}

/// Command words, numbers and units to build plausible lines from.
fn word() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "start", "STOP", "status", "get", "set", "recipe", "save", "load", "list", "reset",
            "help", "freq", "duty", "stroke", "accel", "feed", "ramp", "hz", "mm", "m/s2", "mm/s",
            "cycles", "inf", "nan", "-", "1e999", "0", "7", "8",
        ])
        .prop_map(str::to_string),
        any::<f64>().prop_map(|x| x.to_string()),
        (0.0f64..300.0).prop_map(|x| format!("{x:.3}")),
        "[ -~]{0,12}",
    ]
}

fn line_text() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        3 => prop::collection::vec(word(), 0..6).prop_map(|words| words.join(" ").into_bytes()),
        1 => prop::collection::vec(
            any::<u8>().prop_filter("no terminator", |b| !matches!(b, b'\r' | b'\n' | 0x08 | 0x7f)),
            0..90,
        ),
    ]
}

fn terminator() -> impl Strategy<Value = &'static [u8]> {
    prop::sample::select(vec![&b"\r"[..], b"\n", b"\r\n"])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Any bytes: no panic, never more replies than terminators, every reply well formed.
    #[test]
    fn arbitrary_bytes_never_break_the_session(
        input in prop::collection::vec(any::<u8>(), 0..600),
    ) {
        let mut controller = Controller::new();
        let replies = controller.session(&input);
        let terminators = input.iter().filter(|&&b| b == b'\r' || b == b'\n').count();
        prop_assert!(replies.len() <= terminators);
        for reply in &replies {
            prop_assert!(well_formed(reply.as_str()), "{:?}", reply.as_str());
        }
    }

    /// Every complete non-blank line gets exactly one reply, in order, of the expected kind.
    #[test]
    fn every_line_gets_exactly_one_reply(
        lines in prop::collection::vec((line_text(), terminator()), 0..12),
        tail in line_text(),
    ) {
        let mut input = Vec::new();
        let mut expected = Vec::new();
        for (text, end) in &lines {
            input.extend_from_slice(text);
            input.extend_from_slice(end);
            let blanks = text.iter().take_while(|b| matches!(b, b' ' | b'\t')).count();
            let content = &text[blanks..];
            if content.is_empty() {
                continue;
            }
            expected.push(if content.len() > MAX_LINE_BYTES {
                Some(10)
            } else {
                match std::str::from_utf8(content) {
                    Ok(s) if !s.chars().any(|c| c.is_control() && c != '\t') => None,
                    _ => Some(11),
                }
            });
        }
        // An unterminated tail gets no reply.
        input.extend_from_slice(&tail);
        let mut controller = Controller::new();
        let replies = controller.session(&input);
        prop_assert_eq!(replies.len(), expected.len());
        for (reply, expected_code) in replies.iter().zip(expected) {
            prop_assert!(well_formed(reply.as_str()), "{:?}", reply.as_str());
            if let Some(code) = expected_code {
                let head = format!("ERR {code} ");
                prop_assert!(reply.as_str().starts_with(&head), "{:?}", reply.as_str());
            }
        }
    }

    /// Any number core prints is read back within the parser's bound, and non-finite ones are
    /// refused; only values next to `f64::MAX` may overflow on the way.
    #[test]
    fn any_number_is_read_closely_or_refused(x in any::<f64>(), unit in prop::bool::ANY) {
        let line = if unit { format!("set freq {x} Hz") } else { format!("SET Freq {x}") };
        let parsed = protocol::parse(&line);
        if !x.is_finite() {
            prop_assert_eq!(parsed, Err(ReplyError::NotFinite));
        } else if let Ok(Command::Set(Setting::FrequencyHz(y))) = parsed {
            prop_assert!(close_to_parser_bound(y, x), "{} read as {}", x, y);
        } else {
            prop_assert_eq!(parsed, Err(ReplyError::NotFinite));
            prop_assert!(x.abs() > f64::MAX * (1.0 - WORST_RELATIVE_ERROR), "{}", x);
        }
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

    /// A refused setting leaves everything as it was; an accepted one is within the limits.
    #[test]
    fn set_is_validated_before_anything_changes(
        which in 0usize..5,
        value in -50.0f64..700.0,
    ) {
        let machine = machine();
        let base = Settings::DEFAULT;
        let setting = match which {
            0 => Setting::FrequencyHz(value),
            1 => Setting::Duty(value / 500.0),
            2 => Setting::StrokeMm(value / 50.0),
            3 => Setting::AccelMps2(value),
            _ => Setting::FeedMmps(value / 5.0),
        };
        if let Ok(applied) = base.apply(setting, &machine) {
            let w = applied.plan.waveform;
            let limits = machine.limits;
            let band = limits.min_frequency_hz..=limits.max_frequency_hz;
            prop_assert!(band.contains(&w.frequency_hz()));
            prop_assert!(w.duty > 0.5 && w.duty < 1.0);
            prop_assert!(w.accel_mps2 <= limits.max_accel_mps2);
            prop_assert!(w.stroke_m <= limits.max_stroke_m);
            let s = applied.settings;
            prop_assert_eq!(s.ramp_cycles, base.ramp_cycles);
            match setting {
                Setting::FrequencyHz(f) => prop_assert_eq!(s, Settings { frequency_hz: f, ..base }),
                Setting::Duty(d) => prop_assert_eq!(s, Settings { duty: d, ..base }),
                Setting::StrokeMm(mm) => {
                    let drive = Drive::Stroke { stroke_m: mm / 1000.0 };
                    prop_assert_eq!(s, Settings { drive, ..base });
                }
                Setting::AccelMps2(a) => {
                    let drive = Drive::Accel { accel_mps2: a };
                    prop_assert_eq!(s, Settings { drive, ..base });
                }
                _ => prop_assert_eq!(s, Settings { duty: s.duty, ..base }),
            }
        }
    }
}

const REFERENCE: &str = include_str!("../PROTOCOL.md");

#[test]
fn the_reference_example_is_what_status_prints() {
    let applied = Settings::DEFAULT.validate(&machine()).unwrap();
    let reply = Reply::status(&Status::<&str> {
        phase: Phase::Running,
        fault: None,
        waveform: applied.plan.waveform,
        ramp_cycles: applied.settings.ramp_cycles,
        feed_rate_mps: applied.feed_rate_mps,
        uptime_ms: 12_345,
        cycles: 617,
    });
    let example = format!("    {reply}\n");
    assert!(
        REFERENCE.contains(&example),
        "PROTOCOL.md lacks {example:?}"
    );
}

#[test]
fn the_reference_documents_every_error_code() {
    let documented: Vec<u16> = REFERENCE
        .lines()
        .filter_map(|line| {
            line.strip_prefix('|')?
                .split('|')
                .next()?
                .trim()
                .parse()
                .ok()
        })
        .collect();
    let mut expected: Vec<u16> = vec![10, 11];
    expected.extend(20..=28);
    expected.extend(40..=55);
    expected.extend(60..=62);
    assert_eq!(documented, expected);
}

/// The parser's documented worst case, one rounding for the digits and one per `10^22` step (17
/// in all), plus core's own rounding.
const WORST_RELATIVE_ERROR: f64 = 18.0 * f64::EPSILON / 2.0;

/// `read` is within the parser's worst-case error of `exact` (plus half the least subnormal).
fn close_to_parser_bound(read: f64, exact: f64) -> bool {
    (read - exact).abs() <= exact.abs() * WORST_RELATIVE_ERROR + f64::from_bits(1)
}

/// The longest prefix of `text` that core reads as a number, and the rest: the reference for
/// `split_decimal`.
fn longest_parsed_prefix(text: &str) -> Option<(f64, &str)> {
    (1..=text.len())
        .rev()
        .filter(|&end| text.is_char_boundary(end))
        .find_map(|end| Some((text[..end].parse::<f64>().ok()?, &text[end..])))
}

#[test]
fn decimal_prefixes_by_table() {
    let table: &[(&str, Option<(f64, &str)>)] = &[
        ("0", Some((0.0, ""))),
        ("50", Some((50.0, ""))),
        ("+50", Some((50.0, ""))),
        ("-3", Some((-3.0, ""))),
        ("62.5Hz", Some((62.5, "Hz"))),
        (".6", Some((0.6, ""))),
        ("5.", Some((5.0, ""))),
        ("1.e3x", Some((1000.0, "x"))),
        ("1e2", Some((100.0, ""))),
        ("2.5E-3mm", Some((0.0025, "mm"))),
        ("1e+2", Some((100.0, ""))),
        ("5e", Some((5.0, "e"))),
        ("5e+", Some((5.0, "e+"))),
        ("5e-x", Some((5.0, "e-x"))),
        ("1.2.3", Some((1.2, ".3"))),
        ("0x10", Some((0.0, "x10"))),
        ("1_000", Some((1.0, "_000"))),
        ("150m/s²", Some((150.0, "m/s²"))),
        ("007", Some((7.0, ""))),
        ("0.000001", Some((1e-6, ""))),
        (
            "123456789012345678901234567890",
            Some((1.2345678901234568e29, "")),
        ),
        ("0.30000000000000004", Some((0.30000000000000004, ""))),
        ("9007199254740993", Some((9007199254740992.0, ""))),
        ("1e308", Some((1e308, ""))),
        ("1e-320", Some((1e-320, ""))),
        ("1e309", Some((f64::INFINITY, ""))),
        ("-1e999999999999", Some((f64::NEG_INFINITY, ""))),
        ("1e-400", Some((0.0, ""))),
        ("0e999999", Some((0.0, ""))),
        ("inf", Some((f64::INFINITY, ""))),
        ("-Infinity", Some((f64::NEG_INFINITY, ""))),
        ("+INFhz", Some((f64::INFINITY, "hz"))),
        ("infinit", Some((f64::INFINITY, "init"))),
        ("", None),
        ("-", None),
        (".", None),
        ("+.e1", None),
        ("e5", None),
        ("hz", None),
        ("in", None),
        ("²", None),
    ];
    for &(text, expected) in table {
        assert_eq!(
            longest_parsed_prefix(text),
            expected,
            "core reads {text:?} otherwise"
        );
        let read = split_decimal(text);
        assert_eq!(
            read.map(|(_, rest)| rest),
            expected.map(|(_, rest)| rest),
            "{text:?}"
        );
        if let (Some((read, _)), Some((expected, _))) = (read, expected) {
            let close = read == expected || close_to_parser_bound(read, expected);
            assert!(close, "{text:?} read as {read:e}");
        }
    }
    for text in ["nan", "-NaN", "+nanometre"] {
        let (value, rest) = split_decimal(text).unwrap();
        assert!(value.is_nan(), "{text:?}");
        assert_eq!(rest, &text[text.len() - rest.len()..]);
        assert_eq!(text.len() - rest.len(), text.find(['n', 'N']).unwrap() + 3);
    }
    assert!(split_decimal("-0").unwrap().0.is_sign_negative());
}

#[test]
fn fixed_by_table() {
    let table: &[(f64, u32, &str)] = &[
        (50.0, 3, "50"),
        (0.6, 4, "0.6"),
        (2.0 - 2f64.sqrt(), 4, "0.5858"),
        (156.25, 2, "156.25"),
        (73.1234, 3, "73.123"),
        (29.99999997, 3, "30"),
        (0.005, 3, "0.005"),
        (1500.0, 0, "1500"),
        (-3.25, 1, "-3.2"),
        (-0.00001, 3, "0"),
        (-0.0, 2, "0"),
        (0.0, 0, "0"),
        // Ties go to even on the exact binary value: 0.125 is exact, 0.35 lies just below.
        (0.125, 2, "0.12"),
        (0.375, 2, "0.38"),
        (2.5, 0, "2"),
        (0.35, 1, "0.3"),
        (1e20, 2, "1e20"),
        (f64::NAN, 2, "NaN"),
        (f64::NEG_INFINITY, 2, "-inf"),
    ];
    for &(value, decimals, expected) in table {
        let text = Fixed { value, decimals }.to_string();
        assert_eq!(text, expected, "{value} to {decimals} decimals");
    }
}

#[test]
fn significant_by_table() {
    let table: &[(f64, &str)] = &[
        (0.0, "0"),
        (-0.0, "0"),
        (0.4, "0.4"),
        (1.0, "1"),
        (500.0, "500"),
        (-2.5, "-2.5"),
        (0.1 + 0.2, "0.3"),
        (1.0 / 3.0, "0.333333333333333"),
        (2.0 / 3.0, "0.666666666666667"),
        (0.99999999, "0.99999999"),
        (0.00001, "0.00001"),
        (0.000001, "1e-6"),
        (1.5e-7, "1.5e-7"),
        (123456789012345.0, "123456789012345"),
        (999999999999999.9, "1e15"),
        (1e15, "1e15"),
        (6.02214076e23, "6.02214076e23"),
        (f64::MAX, "1.79769313486232e308"),
        (f64::MIN_POSITIVE, "2.2250738585072e-308"),
        (f64::from_bits(1), "4.94065645841247e-324"),
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
    ];
    for &(value, expected) in table {
        assert_eq!(Significant(value).to_string(), expected, "{value:e}");
    }
}

#[test]
fn explanations_print_values_without_core_float_formatting() {
    let table: &[(Error, &str)] = &[
        (
            Error::DutyTooHigh { duty: 0.99999999 },
            "duty cycle 0.99999999 must be below 1",
        ),
        (
            Error::FeedRateAboveReach {
                target_mps: 0.2,
                max_mps: 0.1 * 2f64.sqrt(),
            },
            "feed rate 0.2 m/s cannot be reached within the limits while the part slides; the \
             most is 0.14142135623731 m/s",
        ),
        (
            Error::TicksOverflow {
                segment: feeder_shared::SegmentKind::Idle,
                exact_ticks: 1.25e16,
                max_ticks: u32::MAX,
            },
            "the idle segment needs 1.25e16 timer ticks but the timer counts at most 4294967295",
        ),
        (
            Error::NotPositive {
                quantity: Quantity::StrokeM,
                value: -1e-7,
            },
            "stroke x_max (m) must be greater than zero, got -1e-7",
        ),
    ];
    for (error, expected) in table {
        let text = error.to_string();
        assert!(text.starts_with(expected), "{text}");
    }
}

/// A decimal `[-]digits[.digits][e±exponent]` built from its parts.
fn decimal_text(negative: bool, digits: &str, point: usize, exponent: Option<i32>) -> String {
    let (integer, fraction) = digits.split_at(point.min(digits.len()));
    let mut text = String::from(if negative { "-" } else { "" });
    text.push_str(integer);
    if !fraction.is_empty() {
        write!(text, ".{fraction}").unwrap();
    }
    if let Some(exponent) = exponent {
        write!(text, "e{exponent}").unwrap();
    }
    text
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// What an operator types (up to 15 significant digits, decimal exponent within ±22) reads
    /// as exactly the `f64` core reads.
    #[test]
    fn operator_numbers_read_exactly(
        negative in prop::bool::ANY,
        digits in "[0-9]{1,15}",
        point in 0usize..16,
        exponent in prop::option::of(-7i32..=7),
    ) {
        let text = decimal_text(negative, &digits, point, exponent);
        let expected: f64 = text.parse().unwrap();
        prop_assert_eq!(split_decimal(&text), Some((expected, "")), "{}", text);
    }

    /// Up to 25 digits and any exponent keep to the documented bound; up to 19 digits with a
    /// decimal exponent within ±22 to two roundings, 2^-52 relative (plus core's rounding).
    #[test]
    fn any_decimal_reads_within_the_bound(
        negative in prop::bool::ANY,
        digits in "[0-9]{1,25}",
        point in 0usize..26,
        exponent in -330i32..=330,
    ) {
        let text = decimal_text(negative, &digits, point, Some(exponent));
        let expected: f64 = text.parse().unwrap();
        let Some((read, "")) = split_decimal(&text) else {
            return Err(TestCaseError::fail(format!("{text} not read")));
        };
        if expected.is_infinite() {
            prop_assert_eq!(read, expected, "{}", text);
        } else if read.is_infinite() {
            prop_assert!(expected.abs() > f64::MAX * (1.0 - WORST_RELATIVE_ERROR), "{}", text);
        } else {
            prop_assert!(close_to_parser_bound(read, expected), "{} read as {:e}", text, read);
            let fraction_digits = digits.len().saturating_sub(point) as i32;
            if digits.len() <= 19 && (exponent - fraction_digits).abs() <= 22 {
                let two_roundings = expected.abs() * 1.5 * f64::EPSILON;
                prop_assert!((read - expected).abs() <= two_roundings, "{}", text);
            }
        }
    }

    /// The prefix taken is the longest one core reads, and its value agrees with core's.
    #[test]
    fn prefixes_are_the_longest_core_reads(text in "[-+0-9.eEinfatyINFAThz ²]{0,12}") {
        match (split_decimal(&text), longest_parsed_prefix(&text)) {
            (None, None) => {}
            (Some((read, rest)), Some((expected, expected_rest))) => {
                prop_assert_eq!(rest, expected_rest, "{:?}", text);
                prop_assert!(
                    read.to_bits() == expected.to_bits()
                        || (read.is_nan() && expected.is_nan())
                        || close_to_parser_bound(read, expected),
                    "{:?} read as {}, core reads {}", text, read, expected
                );
            }
            (got, expected) => prop_assert!(false, "{:?}: {:?}, core {:?}", text, got, expected),
        }
    }

    /// Fixed places round like core's `{:.*}` (trailing zeros and the sign of zero dropped),
    /// including values right at a tie.
    #[test]
    fn fixed_matches_core_rounding(
        value in prop_oneof![
            -1e6f64..1e6,
            (-1_000_000i64..1_000_000, 1u32..=5)
                .prop_map(|(n, places)| (n as f64 + 0.5) / 10f64.powi(places as i32)),
        ],
        decimals in 0u32..=4,
    ) {
        let core = format!("{value:.*}", decimals as usize);
        let trimmed = if core.contains('.') {
            core.trim_end_matches('0').trim_end_matches('.')
        } else {
            &core
        };
        let expected = if trimmed == "-0" { "0" } else { trimmed };
        prop_assert_eq!(Fixed { value, decimals }.to_string(), expected);
    }

    /// Fifteen significant digits: any normal value reads back within half a unit of the last
    /// digit (5·10^-15 relative) and the scaling error, and a decimal with at most 15 digits
    /// prints as core prints it.
    #[test]
    fn significant_digits_read_back(
        value in any::<f64>().prop_filter("finite", |x| x.is_normal()),
        digits in "[1-9][0-9]{0,14}",
        exponent in -19i32..=0,
    ) {
        let text = Significant(value).to_string();
        let read: f64 = text.parse().unwrap();
        prop_assert!((read - value).abs() <= value.abs() * (5e-15 + WORST_RELATIVE_ERROR), "{:e} printed {}", value, text);
        let decimal: f64 = format!("{digits}e{exponent}").parse().unwrap();
        if (1e-5..1e15).contains(&decimal) {
            prop_assert_eq!(Significant(decimal).to_string(), decimal.to_string());
        }
    }
}
