//! The settle on a frictionless plate integrated exactly here, its drive `x'' = g±·u + o` (the
//! gain by the command's sign), read through an encoder of 1 µm at each segment's start, each
//! decision applied two segments on as the firmware applies it; and on a flexure mount,
//! `x'' = g±·u + o − κ·x`, by fine Runge–Kutta steps.

use feeder_shared::closed_loop::settle::{EXCURSION_M, PAIRS, POLE};
use feeder_shared::closed_loop::{LoopError, LoopLimits, Settle};
use feeder_shared::testing::sprung_motion;
use proptest::prelude::*;

const SEGMENT_S: f64 = 2.5e-3;
const RESOLUTION_M: f64 = 1e-6;
const LIMITS: LoopLimits = LoopLimits {
    correction_max_mps2: 50.0,
    amplitude_max: 0.2,
    position_error_max_m: 4e-3,
};

/// Runs a whole settle on the drive `[g₊, g₋, o]`, holding the plate at `target_m` for its last
/// pairs: the settle, and the largest `|x|` reached.
fn settle(drive: [f64; 3], target_m: f64) -> Result<(Settle, f64), LoopError> {
    sprung_settle(drive, 0.0, target_m)
}

/// [`settle`] on a plate whose mount pulls it back by `spring_per_s2·x`.
fn sprung_settle(
    drive: [f64; 3],
    spring_per_s2: f64,
    target_m: f64,
) -> Result<(Settle, f64), LoopError> {
    read_settle(drive, spring_per_s2, target_m, 1.0)
}

/// [`sprung_settle`] read through an encoder that counts forward (`sign` 1) or backward (−1):
/// each segment's position at its start and the drive's acceleration through the segment
/// that just ended, as the course fits it from the samples.
fn read_settle(
    drive: [f64; 3],
    spring_per_s2: f64,
    target_m: f64,
    sign: f64,
) -> Result<(Settle, f64), LoopError> {
    let [plus, minus, offset] = drive;
    let mut settle = Settle::new(LIMITS, 0.0, 0.0);
    let (mut x, mut v, mut largest) = (0.0f64, 0.0f64, 0.0f64);
    // The levels of the segment running and of the next, made before any decision.
    let mut levels = std::collections::VecDeque::from([0.0, 0.0]);
    let mut ended_mps2 = None;
    for _ in 0..2 * PAIRS {
        let read = sign * ((x / RESOLUTION_M).floor() * RESOLUTION_M + RESOLUTION_M / 2.0);
        let level = settle.update(read, ended_mps2, SEGMENT_S, target_m)?;
        levels.push_back(level);
        let u = levels.pop_front().unwrap();
        let a = u * if u > 0.0 { plus } else { minus } + offset;
        ended_mps2 = Some(sign * a);
        if spring_per_s2 > 0.0 {
            for _ in 0..50 {
                (x, v) = sprung_motion((x, v), a, spring_per_s2, 0.0, SEGMENT_S / 50.0, 10);
                largest = largest.max(x.abs());
            }
            continue;
        }
        let turn_s = -v / a;
        if a != 0.0 && turn_s > 0.0 && turn_s < SEGMENT_S {
            largest = largest.max((x + v * turn_s + a * turn_s * turn_s / 2.0).abs());
        }
        x += v * SEGMENT_S + a * SEGMENT_S * SEGMENT_S / 2.0;
        v += a * SEGMENT_S;
        largest = largest.max(x.abs());
    }
    Ok((settle, largest))
}

proptest! {
    /// On any drive of the envelope (gains 0.90–1.10, offset up to ±4 m/s²) the settle finds
    /// the offset and the gains' half difference as the cycles need them, over their mean gain
    /// (`o/ḡ` and `ε/ḡ`), takes the bare slide for one without a spring, and holds the plate
    /// within 0.2 mm of where it holds it (its rest, and the excursion's 0.6 mm off it; the
    /// dither's own swing is 0.23 mm).
    #[test]
    fn a_drive_of_the_envelope_is_found_and_the_plate_held(
        plus in 0.9f64..1.1,
        minus in 0.9f64..1.1,
        offset in -4.0f64..4.0,
    ) {
        let (settle, largest_m) = settle([plus, minus, offset], 0.0).unwrap();
        let mean = (plus + minus) / 2.0;
        let (found_offset, found_half_difference) = settle.drive();
        prop_assert!((found_offset - offset / mean).abs() < 0.15, "offset {found_offset}");
        prop_assert!(
            (found_half_difference - (plus - minus) / 2.0 / mean).abs() < 2e-3,
            "ε {found_half_difference}"
        );
        prop_assert_eq!(settle.spring_per_s2(), 0.0);
        prop_assert!(largest_m < EXCURSION_M + 0.2e-3, "{largest_m} m");
    }

    /// On a flexure mount of 11–18 Hz the settle finds the spring's `κ = k/M` within the range
    /// the cycles' loop holds it on (30 % low to 10 % high; `shared/tests/closed_loop.rs`), its
    /// offset at the centre within 1.5 m/s², and keeps the plate within 0.2 mm of where it holds
    /// it. Stiffer mounts it reads up to 45 % low, and a loop so told may not hold them.
    #[test]
    fn a_flexure_mounts_spring_is_found(
        spring in 5e3f64..1.3e4,
        plus in 0.9f64..1.1,
        minus in 0.9f64..1.1,
        offset in -4.0f64..4.0,
    ) {
        let (settle, largest_m) = sprung_settle([plus, minus, offset], spring, 0.0).unwrap();
        let found = settle.spring_per_s2();
        prop_assert!(found > 0.7 * spring && found < 1.1 * spring, "k/M {found} of {spring}");
        let (found_offset, _) = settle.drive();
        let mean = (plus + minus) / 2.0;
        prop_assert!((found_offset - offset / mean).abs() < 1.5, "offset {found_offset}");
        prop_assert!(largest_m < EXCURSION_M + 0.2e-3, "{largest_m} m");
    }
}

/// The settle's last pairs bring the plate to the target it is given, at rest.
#[test]
fn the_last_pairs_bring_the_plate_to_its_target() {
    let mut settle = Settle::new(LIMITS, 0.0, 0.0);
    let target_m = -300e-6;
    let (mut x, mut v) = (0.0f64, 0.0f64);
    let mut levels = std::collections::VecDeque::from([0.0, 0.0]);
    for _ in 0..2 * PAIRS {
        let level = settle.update(x, None, SEGMENT_S, target_m).unwrap();
        levels.push_back(level);
        let a = levels.pop_front().unwrap() + 1.0;
        x += v * SEGMENT_S + a * SEGMENT_S * SEGMENT_S / 2.0;
        v += a * SEGMENT_S;
    }
    assert!((x - target_m).abs() < 30e-6, "{x} m");
    assert!(v.abs() < 5e-3, "{v} m/s");
    assert!(POLE > 0.0 && POLE < 1.0);
}

/// A plate beyond the loop's reach stops the settle by name: a position past the limit, or a
/// position that is not a number.
#[test]
fn a_plate_out_of_reach_stops_the_settle() {
    let mut settle = Settle::new(LIMITS, 0.0, 0.0);
    assert!(settle.update(0.0, None, SEGMENT_S, 0.0).is_ok());
    assert_eq!(
        settle.update(5e-3, None, SEGMENT_S, 0.0),
        Err(LoopError::Position { error_m: 5e-3 })
    );
    assert_eq!(
        settle.update(f64::NAN, None, SEGMENT_S, 0.0),
        Err(LoopError::Sensor)
    );
}

/// Read through an encoder that counts backwards, the dither's pairs show the plate
/// accelerating against the command: the settle stops by name, before its loop's correction
/// outgrows its limit (which would stop it as a plate out of reach).
#[test]
fn a_backwards_encoder_is_refused_in_the_first_dither_level() {
    let refused = read_settle([1.0, 1.0, 0.0], 0.0, 0.0, -1.0).map(|_| ());
    let Err(LoopError::Backwards {
        measured_mps2,
        commanded_mps2,
    }) = refused
    else {
        panic!("{refused:?}");
    };
    assert!(
        measured_mps2 < -0.5 * commanded_mps2,
        "{measured_mps2} {commanded_mps2}"
    );
}
