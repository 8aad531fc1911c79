//! Why a line is refused: every refusal's stable code and its explanation.

use feeder_shared::{Error, Quantity, RecipeSlot, RecordError, Reply, ReplyError};

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
        (
            Error::AccelAboveLoopRoom {
                accel_mps2: 180.0,
                limit_mps2: 171.675,
                linear_mps2: 224.75,
            }
            .into(),
            56,
            "peak acceleration 180 m/s2 is more than the closed loop can hold: the output's linear range reaches 224.75 m/s2",
        ),
        (
            Error::StrokeAboveAccelLimit {
                stroke_m: 0.006,
                limit_m: 0.0034,
                accel_limit_mps2: 200.0,
                frequency_hz: 50.0,
                duty: 0.586,
            }
            .into(),
            57,
            "stroke 0.006 m exceeds the 0.0034 m that the motor limit of 200 m/s2 allows at 50 Hz \
             and duty cycle 0.586; nothing changed",
        ),
        (
            Error::AccelAboveTravelLimit {
                accel_mps2: 250.0,
                limit_mps2: 197.5,
                stroke_limit_m: 0.004,
                frequency_hz: 50.0,
                duty: 0.55,
            }
            .into(),
            58,
            "peak acceleration 250 m/s2 exceeds the 197.5 m/s2 that the plate travel limit of \
             0.004 m allows at 50 Hz and duty cycle 0.55; nothing changed",
        ),
        (ReplyError::NotStopped, 60, "only allowed while stopped"),
        (ReplyError::FaultLatched, 61, "send reset"),
        (ReplyError::StorageFailed, 62, "could not be written"),
        (
            ReplyError::RecipeUnusable {
                slot: RecipeSlot::new(3).unwrap(),
                issue: RecordError::Empty,
            },
            63,
            "recipe 3 not loaded: no recipe saved in this slot; nothing changed",
        ),
        (
            ReplyError::RecipeUnusable {
                slot: RecipeSlot::new(2).unwrap(),
                issue: RecordError::WrongSlot {
                    found: 5,
                    expected: RecipeSlot::new(2).unwrap(),
                },
            },
            64,
            "recipe 2 not loaded: record belongs to slot 5, not slot 2; nothing changed",
        ),
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
