//! Level-to-output mapping: hand-derived codes and duties, symmetry and range checks.

use feeder_shared::drive::scale_counts;
use feeder_shared::{
    Amplitude, DacCalibration, Direction, DriveError, Level, PwmCalibration, PwmCommand,
};

const FULL: Amplitude = Amplitude { step: 1, steps: 1 };

fn amp(step: u16, steps: u16) -> Amplitude {
    Amplitude { step, steps }
}

#[test]
fn default_dac_codes_at_the_paper_operating_point() {
    // 150 m/s² (x_max = 2.5 mm at 50 Hz, d = 0.586) at 10 counts per m/s² is 1500 counts.
    let levels = DacCalibration::DEFAULT.levels(150.0).unwrap();
    assert_eq!(levels.zero_code(), 2048);
    assert_eq!(levels.amplitude_counts(), 1500);
    assert_eq!(levels.code(Level::Positive, FULL), 3548);
    assert_eq!(levels.code(Level::Zero, FULL), 2048);
    assert_eq!(levels.code(Level::Negative, FULL), 548);
}

#[test]
fn soft_start_steps_scale_the_amplitude_in_integers() {
    let levels = DacCalibration::DEFAULT.levels(150.0).unwrap();
    assert_eq!(levels.code(Level::Positive, amp(1, 3)), 2048 + 500);
    assert_eq!(levels.code(Level::Negative, amp(2, 3)), 2048 - 1000);
    assert_eq!(levels.code(Level::Positive, amp(0, 3)), 2048);
    assert_eq!(levels.code(Level::Zero, amp(2, 3)), 2048);
}

#[test]
fn fractions_round_half_up_and_stay_symmetric() {
    // 100.1 m/s² → 1001 counts; half of it is 500.5 → 501 on both sides.
    let levels = DacCalibration::DEFAULT.levels(100.1).unwrap();
    assert_eq!(levels.amplitude_counts(), 1001);
    assert_eq!(levels.code(Level::Positive, amp(1, 2)), 2048 + 501);
    assert_eq!(levels.code(Level::Negative, amp(1, 2)), 2048 - 501);
    // 1001 / 3 = 333.67 → 334.
    assert_eq!(levels.code(Level::Positive, amp(1, 3)), 2048 + 334);
}

#[test]
fn plus_and_minus_codes_are_symmetric_and_monotonic_for_every_step() {
    for accel_mps2 in [0.0, 0.04, 1.0, 37.3, 150.0, 204.7] {
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
fn dac_range_is_checked_on_the_narrower_side_of_zero() {
    // Headroom is min(2048, 4095 − 2048) = 2047 counts.
    let levels = DacCalibration::DEFAULT.levels(204.7).unwrap();
    assert_eq!(levels.code(Level::Positive, FULL), 4095);
    assert_eq!(levels.code(Level::Negative, FULL), 1);
    assert_eq!(
        DacCalibration::DEFAULT.levels(205.0),
        Err(DriveError::AmplitudeOutOfRange {
            accel_mps2: 205.0,
            amplitude_counts: 2050.0,
            headroom_counts: 2047
        })
    );
    let low_zero = DacCalibration {
        zero_code: 1000,
        ..DacCalibration::DEFAULT
    };
    let levels = low_zero.levels(100.0).unwrap();
    assert_eq!(levels.code(Level::Negative, FULL), 0);
    assert_eq!(levels.code(Level::Positive, FULL), 2000);
    assert!(low_zero.levels(100.1).is_err());
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
    let zero_above_max = DacCalibration {
        zero_code: 4096,
        ..DacCalibration::DEFAULT
    };
    assert_eq!(
        zero_above_max.levels(1.0),
        Err(DriveError::ZeroOutOfRange {
            zero_code: 4096,
            max_code: 4095
        })
    );
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
