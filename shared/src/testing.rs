//! Fixtures shared by this crate's tests and its fuzz targets (feature `testing`).

use crate::model::{Friction, STANDARD_GRAVITY_MPS2};
use crate::plan::TickClock;
use crate::settings::Machine;
use crate::waveform::Limits;

/// A permissive machine: 20–200 Hz, 500 m/s², 5 mm, μ = 1 under standard gravity, a 1 MHz clock,
/// open loop.
pub const fn machine() -> Machine {
    Machine {
        limits: Limits {
            min_frequency_hz: 20.0,
            max_frequency_hz: 200.0,
            max_accel_mps2: 500.0,
            max_stroke_m: 0.005,
        },
        friction: Friction {
            mu: 1.0,
            gravity_mps2: STANDARD_GRAVITY_MPS2,
        },
        clock: TickClock::new(1_000_000),
        loop_linear_mps2: None,
    }
}
