//! Helpers shared by the protocol and recipe tests.

use feeder_shared::{Friction, Limits, Machine, RecipeSlot, TickClock};

/// A permissive machine: 20–200 Hz, 500 m/s², 5 mm, μ = 1, a 1 MHz clock.
pub fn machine() -> Machine {
    Machine {
        limits: Limits {
            min_frequency_hz: 20.0,
            max_frequency_hz: 200.0,
            max_accel_mps2: 500.0,
            max_stroke_m: 0.005,
        },
        friction: Friction::new(1.0, 9.80665).unwrap(),
        clock: TickClock::new(1_000_000),
    }
}

pub fn slot(number: u8) -> RecipeSlot {
    RecipeSlot::new(number).unwrap()
}
