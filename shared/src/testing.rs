//! Fixtures shared by this crate's tests and its fuzz targets (feature `testing`).

use crate::configuration::record as config_record;
use crate::control::{ConfigurationStore, RecipeStore};
use crate::model::{Friction, STANDARD_GRAVITY_MPS2};
use crate::plan::TickClock;
use crate::recipe::{RecipeSlot, RECIPE_SLOTS, RECORD_LEN};
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

/// `(x, v)` of a plate under a constant acceleration `accel_mps2`, pulled back by
/// `spring_per_s2·x` and damped by `viscous_per_s·v`, after `duration_s`, by `steps` classic
/// Runge–Kutta steps: an integration independent of the closed loop's cycle map.
pub fn sprung_motion(
    (mut x, mut v): (f64, f64),
    accel_mps2: f64,
    spring_per_s2: f64,
    viscous_per_s: f64,
    duration_s: f64,
    steps: usize,
) -> (f64, f64) {
    let h = duration_s / steps as f64;
    let f = |x: f64, v: f64| (v, accel_mps2 - spring_per_s2 * x - viscous_per_s * v);
    for _ in 0..steps {
        let (k1x, k1v) = f(x, v);
        let (k2x, k2v) = f(x + h / 2.0 * k1x, v + h / 2.0 * k1v);
        let (k3x, k3v) = f(x + h / 2.0 * k2x, v + h / 2.0 * k2v);
        let (k4x, k4v) = f(x + h * k3x, v + h * k3v);
        x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }
    (x, v)
}

/// Recipe and configuration records in RAM, a board's flash without the flash.
#[derive(Debug, Clone, PartialEq)]
pub struct MemoryStore {
    pub records: [[u8; RECORD_LEN]; RECIPE_SLOTS],
    pub configuration: [u8; config_record::RECORD_LEN],
}

impl MemoryStore {
    /// Nothing stored: every byte erased (`0xFF`).
    pub const fn erased() -> Self {
        MemoryStore {
            records: [[0xff; RECORD_LEN]; RECIPE_SLOTS],
            configuration: [0xff; config_record::RECORD_LEN],
        }
    }
}

impl RecipeStore for MemoryStore {
    type Error = ();

    fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN] {
        self.records[slot.index()]
    }

    fn write(&mut self, slot: RecipeSlot, record: &[u8; RECORD_LEN]) -> Result<(), ()> {
        self.records[slot.index()] = *record;
        Ok(())
    }
}

impl ConfigurationStore for MemoryStore {
    type WriteError = ();

    fn read_configuration(&mut self) -> [u8; config_record::RECORD_LEN] {
        self.configuration
    }

    fn write_configuration(&mut self, record: &[u8; config_record::RECORD_LEN]) -> Result<(), ()> {
        self.configuration = *record;
        Ok(())
    }
}
