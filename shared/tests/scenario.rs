//! The scripted operator's `key=value` words: what each key accepts, that every other word is
//! refused with the word or value named, and which runs the emulated board refuses before they
//! start.

use feeder_shared::scenario::{
    parse_setting, qemu_clock, RefusalCause, RunWaveform, Scenario, ScenarioRefusal, SCENARIO_KEYS,
};
use feeder_shared::{Error, Quantity, ScenarioError, ScenarioSetting};
use proptest::prelude::*;

#[test]
fn each_key_reads_its_value() {
    assert_eq!(
        parse_setting("cycles=1000"),
        Ok(ScenarioSetting::Cycles(1000))
    );
    assert_eq!(
        parse_setting("freq_hz=100"),
        Ok(ScenarioSetting::FreqHz(100.0))
    );
    assert_eq!(
        parse_setting("duty=0.606"),
        Ok(ScenarioSetting::Duty(0.606))
    );
    assert_eq!(
        parse_setting("stroke_m=6e-4"),
        Ok(ScenarioSetting::StrokeM(6e-4))
    );
    assert_eq!(
        parse_setting("new_duty=-0.5"),
        Ok(ScenarioSetting::NewDuty(-0.5))
    );
    assert_eq!(parse_setting("ramp=0"), Ok(ScenarioSetting::Ramp(0)));
    assert_eq!(
        parse_setting("ramp=65535"),
        Ok(ScenarioSetting::Ramp(u16::MAX))
    );
    assert_eq!(parse_setting("panic_at=0"), Ok(ScenarioSetting::PanicAt(0)));
    assert_eq!(
        parse_setting("overflow_at=30"),
        Ok(ScenarioSetting::OverflowAt(30))
    );
    assert_eq!(parse_setting("mask_at=0"), Ok(ScenarioSetting::MaskAt(0)));
    assert_eq!(
        parse_setting("changes=200"),
        Ok(ScenarioSetting::Changes(200))
    );
    assert_eq!(
        parse_setting("seed=4294967295"),
        Ok(ScenarioSetting::Seed(u32::MAX))
    );
    assert_eq!(
        parse_setting("late_preload_at=30"),
        Ok(ScenarioSetting::LatePreloadAt(30))
    );
}

#[test]
fn counts_are_whole_numbers_in_range() {
    for word in ["overflow_at=-1", "mask_at=2.5", "mask_at="] {
        let error = parse_setting(word).unwrap_err();
        assert!(
            matches!(error, ScenarioError::NotACount { min: 0, .. }),
            "{word}: {error:?}"
        );
        assert!(error.to_string().starts_with(word), "{error}");
    }
    for word in [
        "cycles=0",
        "cycles=-5",
        "cycles=1.5",
        "cycles=4294967296",
        "cycles=",
    ] {
        let error = parse_setting(word).unwrap_err();
        assert!(
            matches!(
                error,
                ScenarioError::NotACount {
                    key: "cycles",
                    min: 1,
                    ..
                }
            ),
            "{word}"
        );
        assert!(error.to_string().starts_with(word), "{error}");
    }
    assert_eq!(
        parse_setting("ramp=65536").unwrap_err().to_string(),
        "ramp=65536: ramp must be a whole number from 0 to 65535"
    );
}

#[test]
fn physical_values_are_finite_decimals() {
    for word in ["freq_hz=inf", "duty=NaN", "freq_hz=", "duty=1e400"] {
        let error = parse_setting(word).unwrap_err();
        assert!(
            matches!(error, ScenarioError::NotFinite { .. }),
            "{word}: {error:?}"
        );
        assert!(
            error
                .to_string()
                .ends_with("must be a finite decimal number"),
            "{error}"
        );
    }
}

#[test]
fn malformed_words_and_unknown_keys_are_named() {
    assert_eq!(
        parse_setting("cycles"),
        Err(ScenarioError::NotKeyValue("cycles"))
    );
    assert_eq!(
        parse_setting("speed=3"),
        Err(ScenarioError::UnknownKey("speed"))
    );
    let unknown = parse_setting("speed=3").unwrap_err().to_string();
    assert!(unknown.contains("`speed`"), "{unknown}");
    for (key, _) in SCENARIO_KEYS {
        assert!(unknown.contains(key), "{unknown} lists {key}");
    }
}

proptest! {
    #[test]
    fn every_listed_key_takes_a_whole_number(n in 1u16..) {
        for (key, _) in SCENARIO_KEYS {
            let word = format!("{key}={n}");
            prop_assert!(parse_setting(&word).is_ok(), "{word}");
        }
    }

    #[test]
    fn any_word_is_read_or_refused_without_panic(word in "\\PC{0,24}") {
        if let Err(error) = parse_setting(&word) {
            prop_assert!(!error.to_string().is_empty());
        }
    }

    /// Up to 15 significant digits, as an operator types them, read as `str::parse` reads them.
    #[test]
    fn typed_values_read_as_core_reads_them(
        mantissa in -999_999_999_999_999i64..=999_999_999_999_999,
        exponent in -22i32..=22,
    ) {
        let value = format!("{mantissa}e{exponent}");
        let word = format!("stroke_m={value}");
        let expected: f64 = value.parse().unwrap();
        prop_assert_eq!(parse_setting(&word), Ok(ScenarioSetting::StrokeM(expected)));
    }
}

#[test]
fn the_stroke_takes_a_unit() {
    for word in [
        "stroke_m=2.5mm",
        "stroke_m=0.0025",
        "stroke_m=2500um",
        "stroke_m=2500µm",
    ] {
        assert_eq!(
            parse_setting(word),
            Ok(ScenarioSetting::StrokeM(0.0025)),
            "{word}"
        );
    }
    assert_eq!(
        parse_setting("stroke_m=2.5in").unwrap_err().to_string(),
        "stroke_m=2.5in: stroke_m must be a finite length in m or with its unit: the unit of a \
         length must be m, mm, um or µm"
    );
}

fn check(words: &[&'static str]) -> Result<(), ScenarioRefusal> {
    Scenario::parse(words.iter().copied())
        .expect("well-formed words")
        .check(qemu_clock(), None)
}

#[test]
fn the_default_run_and_the_documented_examples_pass() {
    assert_eq!(check(&[]), Ok(()));
    assert_eq!(
        check(&["cycles=1000", "freq_hz=100", "stroke_m=0.0006"]),
        Ok(())
    );
}

#[test]
fn a_duty_of_one_or_more_is_refused_by_the_waveform() {
    let refusal = check(&["duty=1.2"]).expect_err("refused");
    assert_eq!(
        refusal,
        ScenarioRefusal {
            which: RunWaveform::Start,
            duty: 1.2,
            cause: RefusalCause::Waveform(Error::DutyTooHigh { duty: 1.2 })
        }
    );
}

#[test]
fn a_frequency_outside_the_machines_band_is_refused() {
    let refusal = check(&["freq_hz=120"]).expect_err("refused");
    assert!(
        matches!(
            refusal,
            ScenarioRefusal {
                cause: RefusalCause::Waveform(Error::FrequencyOutOfBand { .. }),
                ..
            }
        ),
        "{refusal:?}"
    );
    let refusal = check(&["freq_hz=0"]).expect_err("refused");
    assert!(
        matches!(
            refusal,
            ScenarioRefusal {
                cause: RefusalCause::Waveform(Error::NotPositive {
                    quantity: Quantity::FrequencyHz,
                    ..
                }),
                ..
            }
        ),
        "{refusal:?}"
    );
}

#[test]
fn the_live_change_is_checked_with_its_default_duty() {
    // d = 0.64 keeps the default 2.5 mm stroke within 200 m/s²; 0.66 allows 2.312 mm.
    assert_eq!(check(&["duty=0.64", "new_duty=0.6"]), Ok(()));
    let refusal = check(&["duty=0.64"]).expect_err("refused");
    assert!(
        matches!(
            refusal,
            ScenarioRefusal {
                which: RunWaveform::LiveChange,
                cause: RefusalCause::Waveform(Error::StrokeAboveAccelLimit { .. }),
                ..
            }
        ),
        "{refusal:?}"
    );
    assert!(matches!(
        check(&["new_duty=0.5"]),
        Err(ScenarioRefusal {
            which: RunWaveform::LiveChange,
            cause: RefusalCause::Waveform(Error::DutyTooLow { .. }),
            ..
        })
    ));
}

#[test]
fn strokes_beyond_the_limits_and_segments_below_the_boards_floor_are_refused() {
    assert!(matches!(
        check(&["stroke_m=0.009"]),
        Err(ScenarioRefusal {
            cause: RefusalCause::Waveform(
                Error::StrokeAboveLimit { .. } | Error::StrokeAboveAccelLimit { .. }
            ),
            ..
        })
    ));
    // At 50 Hz and d = 0.9 the forward acceleration lasts 56 µs, below QEMU's 528 µs floor.
    assert!(matches!(
        check(&["duty=0.9", "new_duty=0.9", "stroke_m=0.0001"]),
        Err(ScenarioRefusal {
            cause: RefusalCause::Waveform(Error::SegmentBelowFloor { min_ticks: 528, .. }),
            ..
        })
    ));
}

#[test]
fn a_refusal_says_which_waveform_and_why_in_words() {
    let text = check(&["duty=1.2"]).expect_err("refused").to_string();
    assert_eq!(
        text,
        "the waveform at start (freq_hz, duty, stroke_m): duty cycle 1.2 must be below 1: at 1 \
         there is no time left for the backward swing"
    );
    let text = check(&["duty=0.64"]).expect_err("refused").to_string();
    assert!(
        text.starts_with(
            "the live change's waveform (new_duty = 0.66): stroke 0.0025 m exceeds the 0.002312 m"
        ),
        "{text}"
    );
}

#[test]
fn where_the_closed_loop_runs_its_room_in_the_dacs_range_is_checked_too() {
    let scenario = Scenario::parse(["duty=0.64", "new_duty=0.6"]).expect("well-formed words");
    assert_eq!(scenario.check(qemu_clock(), None), Ok(()));
    let linear_mps2 = feeder_shared::DacCalibration::DEFAULT.linear_limit_mps2();
    assert!(matches!(
        scenario.check(qemu_clock(), Some(linear_mps2)),
        Err(ScenarioRefusal {
            which: RunWaveform::Start,
            cause: RefusalCause::Waveform(Error::AccelAboveLoopRoom { .. }),
            ..
        })
    ));
}
