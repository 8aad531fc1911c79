//! Eq. 1–5 against hand-derived values and independent kinematics, and the bad-input table.

use feeder_shared::{Drive, Error, Level, Limits, Quantity, Waveform, WaveformSpec};
use proptest::prelude::*;

fn paper_point() -> Waveform {
    let spec = WaveformSpec::from_frequency(50.0, 0.586, Drive::Stroke { stroke_m: 0.0025 });
    Waveform::new(spec, &Limits::NONE).unwrap()
}

fn close(actual: f64, expected: f64, rel: f64) -> bool {
    (actual - expected).abs() <= rel * expected.abs().max(f64::MIN_POSITIVE)
}

/// Integrates the exact segments piecewise (constant acceleration each) and returns the final
/// velocity, the final position and the largest position reached.
fn integrate(waveform: &Waveform) -> (f64, f64, f64) {
    let (mut velocity, mut position, mut peak) = (0.0_f64, 0.0_f64, 0.0_f64);
    for segment in waveform.segments() {
        let accel = f64::from(segment.level.sign()) * waveform.accel_mps2;
        let t = segment.duration_s;
        // The peak is where the velocity crosses zero inside a segment (at F, within −a).
        let zero_crossing_s = if accel != 0.0 {
            -velocity / accel
        } else {
            -1.0
        };
        if zero_crossing_s > 0.0 && zero_crossing_s < t {
            let s = zero_crossing_s;
            peak = peak.max(position + velocity * s + accel * s * s / 2.0);
        }
        position += velocity * t + accel * t * t / 2.0;
        velocity += accel * t;
        peak = peak.max(position);
    }
    (velocity, position, peak)
}

#[test]
fn paper_operating_point_matches_section_iv_a() {
    let waveform = paper_point();
    // Section IV.A's a ≈ 15,000 cm/s² is rounded: Eq. 5 with x_max = 0.25 cm at T = 0.02 s,
    // d = 0.586 gives a ≈ 14,586 cm/s².
    let expected_accel = 0.0025 / (0.02 * (1.0 - 0.586) / 2.0_f64).powi(2);
    assert!(close(waveform.accel_mps2, expected_accel, 1e-12));
    assert!((waveform.accel_mps2 - 145.86).abs() < 0.01);
    assert!(close(
        waveform.plateau_s,
        0.02 * (2.0 * 0.586 - 1.0_f64).sqrt(),
        1e-12
    ));
    assert!(close(waveform.t3_s, 0.01172 + 0.00828 / 2.0, 1e-12));
    assert_eq!(waveform.frequency_hz(), 50.0);
}

#[test]
fn segments_follow_fig_2a() {
    let levels: Vec<Level> = paper_point().segments().iter().map(|s| s.level).collect();
    assert_eq!(
        levels,
        [
            Level::Positive,
            Level::Zero,
            Level::Negative,
            Level::Positive
        ]
    );
}

#[test]
fn bad_inputs_are_refused_with_the_expected_error() {
    let stroke = Drive::Stroke { stroke_m: 0.0025 };
    let board = Limits {
        min_frequency_hz: 50.0,
        max_frequency_hz: 100.0,
        max_accel_mps2: 300.0,
        max_stroke_m: 0.004,
    };
    let spec = |period_s, duty, drive| WaveformSpec {
        period_s,
        duty,
        drive,
    };
    let mut table: Vec<(WaveformSpec, Limits, Error)> = vec![
        (
            spec(f64::NAN, 0.6, stroke),
            Limits::NONE,
            Error::NotFinite {
                quantity: Quantity::PeriodS,
            },
        ),
        (
            spec(f64::INFINITY, 0.6, stroke),
            Limits::NONE,
            Error::NotFinite {
                quantity: Quantity::PeriodS,
            },
        ),
        (
            spec(0.0, 0.6, stroke),
            Limits::NONE,
            Error::NotPositive {
                quantity: Quantity::PeriodS,
                value: 0.0,
            },
        ),
        (
            spec(-0.02, 0.6, stroke),
            Limits::NONE,
            Error::NotPositive {
                quantity: Quantity::PeriodS,
                value: -0.02,
            },
        ),
        (
            spec(0.02, f64::NAN, stroke),
            Limits::NONE,
            Error::NotFinite {
                quantity: Quantity::Duty,
            },
        ),
        (
            spec(0.02, 0.6, Drive::Stroke { stroke_m: 0.0 }),
            Limits::NONE,
            Error::NotPositive {
                quantity: Quantity::StrokeM,
                value: 0.0,
            },
        ),
        (
            spec(
                0.02,
                0.6,
                Drive::Accel {
                    accel_mps2: f64::NEG_INFINITY,
                },
            ),
            Limits::NONE,
            Error::NotFinite {
                quantity: Quantity::AccelMps2,
            },
        ),
        (
            spec(0.02, 0.6, Drive::Accel { accel_mps2: -1.0 }),
            Limits::NONE,
            Error::NotPositive {
                quantity: Quantity::AccelMps2,
                value: -1.0,
            },
        ),
        (
            spec(0.04, 0.6, stroke),
            board,
            Error::FrequencyOutOfBand {
                frequency_hz: 25.0,
                min_hz: 50.0,
                max_hz: 100.0,
            },
        ),
        (
            spec(0.005, 0.6, stroke),
            board,
            Error::FrequencyOutOfBand {
                frequency_hz: 200.0,
                min_hz: 50.0,
                max_hz: 100.0,
            },
        ),
        (
            // The travel allows 0.004/(0.02·0.3/2)² = 444 m/s²: the motor's 300 m/s² is tighter.
            spec(0.02, 0.7, Drive::Accel { accel_mps2: 400.0 }),
            board,
            Error::AccelAboveLimit {
                accel_mps2: 400.0,
                limit_mps2: 300.0,
            },
        ),
        (
            // The travel allows 0.004/(0.02·0.4/2)² = 250 m/s², less than the motor's 300 m/s².
            spec(0.02, 0.6, Drive::Accel { accel_mps2: 400.0 }),
            board,
            Error::AccelAboveTravelLimit {
                accel_mps2: 400.0,
                limit_mps2: 250.0,
                stroke_limit_m: 0.004,
                frequency_hz: 50.0,
                duty: 0.6,
            },
        ),
        (
            // x = a(T(1−d)/2)² = 250·(0.02·0.45/2)² = 5.0625 mm > 4 mm: the travel allows
            // 0.004/(0.02·0.45/2)² = 197.53 m/s².
            spec(0.02, 0.55, Drive::Accel { accel_mps2: 250.0 }),
            board,
            Error::AccelAboveTravelLimit {
                accel_mps2: 250.0,
                limit_mps2: 0.004 / 0.0045f64.powi(2),
                stroke_limit_m: 0.004,
                frequency_hz: 50.0,
                duty: 0.55,
            },
        ),
        (
            // a = 4x/(T(1−d))² = 4·0.0025/(0.02·0.2)² = 625 m/s² > 300 m/s²: the motor allows
            // a stroke of 300·(0.02·0.2/2)² = 1.2 mm.
            spec(0.02, 0.8, stroke),
            board,
            Error::StrokeAboveAccelLimit {
                stroke_m: 0.0025,
                limit_m: 0.0012,
                accel_limit_mps2: 300.0,
                frequency_hz: 50.0,
                duty: 0.8,
            },
        ),
        (
            // 5 mm is above the 4 mm travel and the motor's 1.2 mm: the tighter limit is named.
            spec(0.02, 0.8, Drive::Stroke { stroke_m: 0.005 }),
            board,
            Error::StrokeAboveAccelLimit {
                stroke_m: 0.005,
                limit_m: 0.0012,
                accel_limit_mps2: 300.0,
                frequency_hz: 50.0,
                duty: 0.8,
            },
        ),
        (
            // The motor allows 300·(0.02·0.45/2)² = 6.075 mm: the 4 mm travel is tighter.
            spec(0.02, 0.55, Drive::Stroke { stroke_m: 0.005 }),
            board,
            Error::StrokeAboveLimit {
                stroke_m: 0.005,
                limit_m: 0.004,
            },
        ),
        (
            spec(0.02, 0.6, stroke),
            Limits {
                max_accel_mps2: f64::NAN,
                ..board
            },
            Error::InvalidLimit {
                quantity: Quantity::AccelLimitMps2,
                value: f64::NAN,
            },
        ),
        (
            spec(0.02, 0.6, stroke),
            Limits {
                min_frequency_hz: -1.0,
                ..board
            },
            Error::InvalidLimit {
                quantity: Quantity::MinFrequencyLimitHz,
                value: -1.0,
            },
        ),
    ];
    for duty in [0.5, 0.2, 1.0, 1.5] {
        let error = if duty < 1.0 {
            Error::DutyTooLow { duty }
        } else {
            Error::DutyTooHigh { duty }
        };
        table.push((spec(0.02, duty, stroke), Limits::NONE, error));
    }
    for (spec, limits, expected) in table {
        let error = Waveform::new(spec, &limits).unwrap_err();
        let matches = match (error, expected) {
            // NaN never equals itself: compare the variant and quantity only.
            (Error::InvalidLimit { quantity: a, .. }, Error::InvalidLimit { quantity: b, .. }) => {
                a == b
            }
            (
                Error::AccelAboveLimit {
                    accel_mps2: a,
                    limit_mps2: la,
                },
                Error::AccelAboveLimit {
                    accel_mps2: b,
                    limit_mps2: lb,
                },
            ) => close(a, b, 1e-12) && la == lb,
            (
                Error::StrokeAboveLimit {
                    stroke_m: a,
                    limit_m: la,
                },
                Error::StrokeAboveLimit {
                    stroke_m: b,
                    limit_m: lb,
                },
            ) => close(a, b, 1e-12) && la == lb,
            (
                Error::StrokeAboveAccelLimit {
                    stroke_m: a,
                    limit_m: la,
                    accel_limit_mps2: ma,
                    frequency_hz: fa,
                    duty: da,
                },
                Error::StrokeAboveAccelLimit {
                    stroke_m: b,
                    limit_m: lb,
                    accel_limit_mps2: mb,
                    frequency_hz: fb,
                    duty: db,
                },
            ) => a == b && close(la, lb, 1e-12) && ma == mb && close(fa, fb, 1e-12) && da == db,
            (
                Error::AccelAboveTravelLimit {
                    accel_mps2: a,
                    limit_mps2: la,
                    stroke_limit_m: ma,
                    frequency_hz: fa,
                    duty: da,
                },
                Error::AccelAboveTravelLimit {
                    accel_mps2: b,
                    limit_mps2: lb,
                    stroke_limit_m: mb,
                    frequency_hz: fb,
                    duty: db,
                },
            ) => a == b && close(la, lb, 1e-12) && ma == mb && close(fa, fb, 1e-12) && da == db,
            (actual, expected) => actual == expected,
        };
        assert!(matches, "{spec:?} gave {error:?}, expected {expected:?}");
        assert!(!format!("{error}").is_empty());
    }
}

#[test]
fn limits_at_their_edges_are_accepted() {
    let limits = Limits {
        min_frequency_hz: 50.0,
        max_frequency_hz: 100.0,
        ..Limits::NONE
    };
    for frequency_hz in [50.0, 100.0] {
        let spec =
            WaveformSpec::from_frequency(frequency_hz, 0.6, Drive::Accel { accel_mps2: 100.0 });
        assert!(Waveform::new(spec, &limits).is_ok());
    }
}

proptest! {
    #[test]
    fn derived_quantities_satisfy_eq_1_to_5(
        period_s in 0.002f64..0.2,
        duty in 0.5001f64..0.9999,
        stroke_m in 1e-5f64..0.02,
    ) {
        let waveform = Waveform::new(
            WaveformSpec { period_s, duty, drive: Drive::Stroke { stroke_m } },
            &Limits::NONE,
        ).unwrap();
        let w = &waveform;
        // Eq. 1: P² = F² − B².
        prop_assert!(close(w.plateau_s.powi(2), w.forward_s.powi(2) - w.backward_s.powi(2), 1e-9)
            || (w.plateau_s.powi(2) - (w.forward_s.powi(2) - w.backward_s.powi(2))).abs() < 1e-15);
        prop_assert!(0.0 < w.t1_s && w.t1_s < w.t2_s && w.t2_s < w.t3_s && w.t3_s < w.period_s);
        prop_assert!(close(w.t1_s + w.t2_s, w.forward_s, 1e-12));
        // Equal areas: ((F + P)/2)·v_max = B·|v_min|/2 (the forward trapezoid's area is
        // ((F + P)/2)·v_max; the paper prints half of it, though Eq. 1 uses the right one).
        prop_assert!(close((w.forward_s + w.plateau_s) / 2.0 * w.v_max_mps, w.backward_s * -w.v_min_mps / 2.0, 1e-9));
        // Independent kinematics: back at rest and at the start; the peak is x_max (Eq. 3, 5).
        let (velocity, position, peak) = integrate(w);
        prop_assert!(velocity.abs() <= 1e-9 * w.v_max_mps.abs().max(-w.v_min_mps));
        prop_assert!(position.abs() <= 1e-9 * w.stroke_m);
        prop_assert!(close(peak, w.stroke_m, 1e-9));
        // Eq. 5 inverts Eq. 5.
        let back = Waveform::new(
            WaveformSpec { period_s, duty, drive: Drive::Accel { accel_mps2: w.accel_mps2 } },
            &Limits::NONE,
        ).unwrap();
        prop_assert!(close(back.stroke_m, stroke_m, 1e-12));
        prop_assert!(close(w.accel_per_stroke_per_s2(), 4.0 / (period_s * (1.0 - duty)).powi(2), 1e-12));
    }

    /// A held stroke or acceleration is refused exactly when it exceeds the tighter of its two
    /// limits at this period and duty (the travel, and the motor limit through Eq. 5), and the
    /// refusal names the held quantity and that limit.
    #[test]
    fn refusals_name_the_held_quantity_and_its_tighter_limit(
        period_s in 0.01f64..0.02,
        duty in 0.51f64..0.95,
        value in 0.0f64..2.0,
        by_stroke in any::<bool>(),
        max_accel_mps2 in 50.0f64..500.0,
        max_stroke_m in 0.001f64..0.01,
    ) {
        let limits = Limits { min_frequency_hz: 50.0, max_frequency_hz: 100.0, max_accel_mps2, max_stroke_m };
        let per_accel_s2 = (period_s * (1.0 - duty) / 2.0).powi(2);
        let (drive, held, limit) = if by_stroke {
            let stroke_m = value * 1e-2;
            (Drive::Stroke { stroke_m }, stroke_m, max_stroke_m.min(max_accel_mps2 * per_accel_s2))
        } else {
            let accel_mps2 = value * 500.0;
            (Drive::Accel { accel_mps2 }, accel_mps2, max_accel_mps2.min(max_stroke_m / per_accel_s2))
        };
        prop_assume!(held > 0.0 && !close(held, limit, 1e-9));
        let result = Waveform::new(WaveformSpec { period_s, duty, drive }, &limits);
        let named = match result {
            Ok(_) => {
                prop_assert!(held < limit, "{} accepted above {}", held, limit);
                return Ok(());
            }
            Err(Error::StrokeAboveLimit { stroke_m, limit_m }) if by_stroke => (stroke_m, limit_m),
            Err(Error::StrokeAboveAccelLimit { stroke_m, limit_m, .. }) if by_stroke => (stroke_m, limit_m),
            Err(Error::AccelAboveLimit { accel_mps2, limit_mps2 }) if !by_stroke => (accel_mps2, limit_mps2),
            Err(Error::AccelAboveTravelLimit { accel_mps2, limit_mps2, .. }) if !by_stroke => (accel_mps2, limit_mps2),
            Err(other) => return Err(TestCaseError::fail(format!("{other:?} for {drive:?}"))),
        };
        prop_assert!(held > limit);
        prop_assert_eq!(named.0, held);
        prop_assert!(close(named.1, limit, 1e-12), "{:?} names {}, not {}", result, named.1, limit);
    }

    #[test]
    fn any_input_is_accepted_or_refused_without_panic(
        period_s in proptest::num::f64::ANY,
        duty in proptest::num::f64::ANY,
        value in proptest::num::f64::ANY,
        by_stroke in any::<bool>(),
    ) {
        let drive = if by_stroke { Drive::Stroke { stroke_m: value } } else { Drive::Accel { accel_mps2: value } };
        if let Ok(w) = Waveform::new(WaveformSpec { period_s, duty, drive }, &Limits::NONE) {
            prop_assert!(w.accel_mps2.is_finite() && w.accel_mps2 > 0.0);
            prop_assert!(w.stroke_m.is_finite() && w.stroke_m > 0.0);
            prop_assert!(duty > 0.5 && duty < 1.0);
        }
    }
}
