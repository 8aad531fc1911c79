//! The operator's settings: the defaults, `set` of each parameter, and every refusal, validated
//! before anything changes.

use feeder_shared::testing::machine;
use feeder_shared::{Drive, Error, Machine, Quantity, Setting, Settings, TickClock};
use proptest::prelude::*;

fn paper_stroke_m() -> f64 {
    0.0025
}

#[test]
fn defaults_are_the_papers_operating_point() {
    let applied = Settings::DEFAULT.validate(&machine()).unwrap();
    assert_eq!(applied.settings, Settings::default());
    let waveform = applied.plan.waveform;
    assert!((waveform.frequency_hz() - 50.0).abs() < 1e-9);
    // The optimum d = 2 − √2 to the paper's three decimals.
    assert_eq!(waveform.duty, 0.586);
    assert!((waveform.duty - (2.0 - 2f64.sqrt())).abs() < 5e-4);
    assert_eq!(waveform.stroke_m, paper_stroke_m());
    assert_eq!(applied.settings.ramp_cycles, 25);
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
    // The 5 mm travel allows 0.005/(0.02·(1 − 0.586)/2)² = 291.7 m/s², below the motor's 500.
    let Error::AccelAboveTravelLimit {
        accel_mps2,
        limit_mps2,
        ..
    } = refuse(Setting::AccelMps2(400.0))
    else {
        panic!("{:?}", refuse(Setting::AccelMps2(400.0)));
    };
    assert_eq!(accel_mps2, 400.0);
    assert!((limit_mps2 - 0.005 / (0.02f64 * 0.414 / 2.0).powi(2)).abs() < 1e-9);
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

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
