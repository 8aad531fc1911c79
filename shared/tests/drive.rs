//! Level-to-output mapping: hand-derived codes and duties, symmetry, range and linearity checks.

use feeder_shared::drive::{scale_counts, MACHINE_LIMITS};
use feeder_shared::{
    Amplitude, DacCalibration, Direction, DriveError, Level, PwmCalibration, PwmCommand,
};

const FULL: Amplitude = Amplitude { step: 1, steps: 1 };

fn amp(step: u16, steps: u16) -> Amplitude {
    Amplitude { step, steps }
}

/// The machine's acceleration limit; `shared` asserts at compile time that the default DAC
/// calibration reaches it in the linear range.
const MACHINE_MAX_ACCEL_MPS2: f64 = MACHINE_LIMITS.max_accel_mps2;

#[test]
fn default_dac_codes_at_the_paper_operating_point() {
    // 150 m/s² (x_max = 2.5 mm at 50 Hz, d = 0.586) at 8 counts per m/s² is 1200 counts.
    let levels = DacCalibration::DEFAULT.levels(150.0).unwrap();
    assert_eq!(levels.zero_code(), 2048);
    assert_eq!(levels.amplitude_counts(), 1200);
    assert_eq!(levels.code(Level::Positive, FULL), 3248);
    assert_eq!(levels.code(Level::Zero, FULL), 2048);
    assert_eq!(levels.code(Level::Negative, FULL), 848);
}

#[test]
fn a_dac_code_reads_back_as_its_acceleration() {
    let dac = DacCalibration::DEFAULT;
    let levels = dac.levels(150.0).unwrap();
    for (level, accel_mps2) in [
        (Level::Positive, 150.0),
        (Level::Zero, 0.0),
        (Level::Negative, -150.0),
    ] {
        assert_eq!(
            dac.accel_mps2(i32::from(levels.code(level, FULL))),
            accel_mps2
        );
    }
    // A quarter step of a soft start: 300 counts, 37.5 m/s².
    assert_eq!(
        dac.accel_mps2(i32::from(levels.code(Level::Positive, amp(1, 4)))),
        37.5
    );
}

#[test]
fn soft_start_steps_scale_the_amplitude_in_integers() {
    let levels = DacCalibration::DEFAULT.levels(150.0).unwrap();
    assert_eq!(levels.code(Level::Positive, amp(1, 3)), 2048 + 400);
    assert_eq!(levels.code(Level::Negative, amp(2, 3)), 2048 - 800);
    assert_eq!(levels.code(Level::Positive, amp(0, 3)), 2048);
    assert_eq!(levels.code(Level::Zero, amp(2, 3)), 2048);
}

#[test]
fn fractions_round_half_up_and_stay_symmetric() {
    // 125.125 m/s² → 1001 counts; half of it is 500.5 → 501 on both sides.
    let levels = DacCalibration::DEFAULT.levels(125.125).unwrap();
    assert_eq!(levels.amplitude_counts(), 1001);
    assert_eq!(levels.code(Level::Positive, amp(1, 2)), 2048 + 501);
    assert_eq!(levels.code(Level::Negative, amp(1, 2)), 2048 - 501);
    // 1001 / 3 = 333.67 → 334.
    assert_eq!(levels.code(Level::Positive, amp(1, 3)), 2048 + 334);
}

#[test]
fn plus_and_minus_codes_are_symmetric_and_monotonic_for_every_step() {
    for accel_mps2 in [0.0, 0.04, 1.0, 37.3, 150.0, 224.75] {
        let levels = DacCalibration::DEFAULT.levels(accel_mps2).unwrap();
        for steps in 1..=40u16 {
            let mut last_offset = 0;
            for step in 0..=steps {
                let a = amp(step, steps);
                let plus = levels.code(Level::Positive, a);
                let minus = levels.code(Level::Negative, a);
                assert_eq!(u32::from(plus) + u32::from(minus), 2 * 2048);
                let offset = plus - 2048;
                assert!(offset >= last_offset && offset <= levels.amplitude_counts());
                last_offset = offset;
            }
            assert_eq!(last_offset, levels.amplitude_counts());
        }
    }
}

#[test]
fn dac_codes_stay_in_the_linear_range_on_the_narrower_side_of_zero() {
    // The buffered output is linear from 0.2 V to 3.1 V: codes 249 to 3846. Around 2048 that is
    // min(2048 − 249, 3846 − 2048) = 1798 counts, 224.75 m/s² at 8 counts per m/s².
    let default = DacCalibration::DEFAULT;
    assert_eq!(default.linear_codes(), (249, 3846));
    assert_eq!(default.linear_limit_mps2(), 224.75);
    let levels = default.levels(224.75).unwrap();
    assert_eq!(levels.code(Level::Positive, FULL), 3846);
    assert_eq!(levels.code(Level::Negative, FULL), 250);
    assert_eq!(
        default.levels(224.9),
        Err(DriveError::BeyondLinearRange {
            accel_mps2: 224.9,
            linear_limit_mps2: 224.75,
            min_code: 249,
            max_code: 3846
        })
    );
    // Zero at 1000: 751 counts below it, 93.875 m/s².
    let low_zero = DacCalibration {
        zero_code: 1000,
        ..DacCalibration::DEFAULT
    };
    let levels = low_zero.levels(93.875).unwrap();
    assert_eq!(levels.code(Level::Negative, FULL), 249);
    assert_eq!(levels.code(Level::Positive, FULL), 1751);
    assert!(matches!(
        low_zero.levels(94.0),
        Err(DriveError::BeyondLinearRange {
            linear_limit_mps2: 93.875,
            ..
        })
    ));
}

#[test]
fn ten_counts_per_mps2_would_clip_above_180_mps2() {
    // ±2000 counts at 200 m/s² reach beyond the linear range from 179.8 m/s² on.
    let ten = DacCalibration {
        counts_per_mps2: 10.0,
        ..DacCalibration::DEFAULT
    };
    assert_eq!(ten.linear_limit_mps2(), 179.8);
    assert!(ten.levels(179.8).is_ok());
    let err = ten.levels(185.0).unwrap_err();
    assert_eq!(
        err,
        DriveError::BeyondLinearRange {
            accel_mps2: 185.0,
            linear_limit_mps2: 179.8,
            min_code: 249,
            max_code: 3846
        }
    );
    let message = err.to_string();
    assert!(message.contains("185 m/s²") && message.contains("179.8 m/s²"));
    assert!(ten.levels(MACHINE_MAX_ACCEL_MPS2).is_err());
}

#[test]
fn the_default_machine_never_asks_the_dac_for_a_clipped_level() {
    let default = DacCalibration::DEFAULT;
    assert!(default.linear_limit_mps2() >= MACHINE_MAX_ACCEL_MPS2);
    let levels = default.levels(MACHINE_MAX_ACCEL_MPS2).unwrap();
    let (min_code, max_code) = default.linear_codes();
    for level in [Level::Positive, Level::Zero, Level::Negative] {
        let code = levels.code(level, FULL);
        assert!((min_code..=max_code).contains(&code), "{code}");
    }
}

#[test]
fn bad_dac_calibrations_and_accelerations_are_refused() {
    let bad_scale = DacCalibration {
        counts_per_mps2: 0.0,
        ..DacCalibration::DEFAULT
    };
    assert_eq!(
        bad_scale.levels(1.0),
        Err(DriveError::InvalidScale { value: 0.0 })
    );
    let nan_scale = DacCalibration {
        counts_per_mps2: f64::NAN,
        ..DacCalibration::DEFAULT
    };
    assert!(matches!(
        nan_scale.levels(1.0),
        Err(DriveError::InvalidScale { .. })
    ));
    assert_eq!(
        DacCalibration::DEFAULT.levels(-1.0),
        Err(DriveError::InvalidAccel { accel_mps2: -1.0 })
    );
    assert!(matches!(
        DacCalibration::DEFAULT.levels(f64::INFINITY),
        Err(DriveError::InvalidAccel { .. })
    ));
    for zero_code in [4096, 100, 3900] {
        let zero_outside = DacCalibration {
            zero_code,
            ..DacCalibration::DEFAULT
        };
        assert_eq!(
            zero_outside.levels(1.0),
            Err(DriveError::ZeroOutOfRange {
                zero_code,
                min_code: 249,
                max_code: 3846
            })
        );
        assert_eq!(zero_outside.linear_limit_mps2(), 0.0);
    }
    // A margin wider than half the range leaves no linear code at all.
    let no_linear_codes = DacCalibration {
        linear_margin_counts: 2100,
        ..DacCalibration::DEFAULT
    };
    assert!(matches!(
        no_linear_codes.levels(0.0),
        Err(DriveError::ZeroOutOfRange { .. })
    ));
}

#[test]
fn pwm_duty_and_direction_at_20_khz_from_170_mhz() {
    // One period is 8500 counts; 150 of 250 m/s² is 60 % duty = 5100 counts.
    let levels = PwmCalibration::DEFAULT.levels(150.0, 8500).unwrap();
    assert_eq!(levels.peak_duty_counts(), 5100);
    assert_eq!(levels.period_counts(), 8500);
    let forward = PwmCommand {
        duty_counts: 5100,
        direction: Direction::Forward,
    };
    let reverse = PwmCommand {
        duty_counts: 5100,
        direction: Direction::Reverse,
    };
    assert_eq!(levels.command(Level::Positive, FULL), forward);
    assert_eq!(levels.command(Level::Negative, FULL), reverse);
    assert_eq!(
        levels.command(Level::Zero, FULL),
        PwmCommand {
            duty_counts: 0,
            direction: Direction::Forward
        }
    );
    assert_eq!(levels.command(Level::Negative, amp(1, 4)).duty_counts, 1275);
}

#[test]
fn pwm_range_is_one_full_period() {
    assert_eq!(
        PwmCalibration::DEFAULT
            .levels(250.0, 8500)
            .unwrap()
            .peak_duty_counts(),
        8500
    );
    assert!(matches!(
        PwmCalibration::DEFAULT.levels(251.0, 8500),
        Err(DriveError::AmplitudeOutOfRange {
            headroom_counts: 8500,
            ..
        })
    ));
    assert_eq!(
        PwmCalibration::DEFAULT.levels(1.0, 0),
        Err(DriveError::EmptyPwmPeriod)
    );
    let bad = PwmCalibration {
        full_duty_accel_mps2: -5.0,
    };
    assert_eq!(
        bad.levels(1.0, 8500),
        Err(DriveError::InvalidScale { value: -5.0 })
    );
}

#[test]
fn scale_counts_edge_cases() {
    assert_eq!(scale_counts(1000, amp(0, 0)), 0);
    assert_eq!(scale_counts(1000, amp(5, 4)), 1000);
    assert_eq!(scale_counts(u16::MAX, amp(u16::MAX, u16::MAX)), u16::MAX);
    assert_eq!(scale_counts(u16::MAX, amp(1, u16::MAX)), 1);
    assert_eq!(scale_counts(3, amp(1, 2)), 2);
}

/// A trimmed level's code is the plan's code for the same acceleration, of either sign; a level
/// beyond the linear range or not a number is refused as a plan's would be.
#[test]
fn a_single_level_converts_as_a_plans_level_does() {
    let dac = DacCalibration::DEFAULT;
    for accel_mps2 in [0.0, 0.0625, 1.0, 37.3, 150.0, 224.75] {
        let levels = dac.levels(accel_mps2).unwrap();
        assert_eq!(dac.code(accel_mps2), Ok(levels.code(Level::Positive, FULL)));
        assert_eq!(
            dac.code(-accel_mps2),
            Ok(levels.code(Level::Negative, FULL))
        );
    }
    assert_eq!(dac.code(0.0), Ok(2048));
    assert_eq!(dac.code(-1.0), Ok(2040));
    assert!(matches!(
        dac.code(-230.0),
        Err(DriveError::BeyondLinearRange { .. })
    ));
    assert!(matches!(
        dac.code(f64::NAN),
        Err(DriveError::InvalidAccel { .. })
    ));
    let pwm = PwmCalibration::DEFAULT;
    let command = pwm.command(-125.0, 1000).unwrap();
    assert_eq!(
        (command.duty_counts, command.direction),
        (500, Direction::Reverse)
    );
    assert_eq!(
        pwm.command(12.5, 1000).unwrap().direction,
        Direction::Forward
    );
    assert!(pwm.command(300.0, 1000).is_err());
}
