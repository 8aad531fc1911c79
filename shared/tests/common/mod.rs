//! Helpers shared by the protocol, control, recipe and Modbus tests (each uses its own part).
#![allow(dead_code)]

use feeder_shared::{Friction, Limits, Machine, RecipeSlot, TickClock};

pub fn slot(number: u8) -> RecipeSlot {
    RecipeSlot::new(number).unwrap()
}

/// The machine these tests validate on: 50–100 Hz, 200 m/s², 5 mm, μ = 0.3, a 1 MHz clock.
pub fn machine() -> Machine {
    Machine {
        limits: Limits {
            min_frequency_hz: 50.0,
            max_frequency_hz: 100.0,
            max_accel_mps2: 200.0,
            max_stroke_m: 5.0e-3,
        },
        friction: Friction::new(0.3, 9.80665).unwrap(),
        clock: TickClock::new(1_000_000),
        loop_linear_mps2: None,
    }
}
