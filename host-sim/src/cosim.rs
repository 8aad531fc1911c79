//! The real plate as the plant of the firmware's lockstep link (the QEMU `cosim` image): every
//! level the firmware's output applies drives the plate from its tick on, and every sample
//! request is answered with the plate encoder's count at its tick. QEMU runs no instruction
//! while the plate computes, so the co-simulation is deterministic.

use feeder_emulator::plant::Plant;
use feeder_shared::DacCalibration;

use crate::error::SimError;
use crate::plant::{Contact, PlateSegment};
use crate::plate::{EndStop, PlantFile, Stepper};
use crate::sensors::EncoderConfig;

/// The plate at a sample request: a cycle start of the firmware's output.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PlateSample {
    /// The output's tick.
    pub tick: u64,
    pub time_s: f64,
    pub position_m: f64,
    /// The count answered.
    pub count: i32,
    /// `∫x dt` since the start, for mean positions between samples.
    pub position_integral_ms: f64,
}

/// A real plate behind the link.
#[derive(Debug)]
pub struct PlatePlant {
    stepper: Stepper,
    dac: DacCalibration,
    encoder: EncoderConfig,
    clock_hz: u32,
    /// The acceleration held and the tick from which it has been.
    held: Option<(u64, f64)>,
    samples: Vec<PlateSample>,
    error: Option<SimError>,
}

impl PlatePlant {
    /// The plate of `plant` carrying a part of `contact`, its drive fed through `dac` by an output
    /// timed in ticks of `clock_hz`; the plant file must list an encoder.
    pub fn new(
        plant: &PlantFile,
        contact: &Contact,
        dac: DacCalibration,
        clock_hz: u32,
    ) -> Result<Self, SimError> {
        let encoder = plant
            .sensors
            .encoder
            .ok_or(SimError::MissingSensor { sensor: "encoder" })?;
        Ok(PlatePlant {
            stepper: Stepper::new(&plant.plate, contact)?,
            dac,
            encoder,
            clock_hz,
            held: None,
            samples: Vec::new(),
            error: None,
        })
    }

    /// Runs the held level up to `tick`.
    fn advance(&mut self, tick: u64) {
        let Some((from, accel_mps2)) = self.held else {
            return;
        };
        if tick <= from || self.error.is_some() {
            return;
        }
        let segment = PlateSegment {
            duration_s: (tick - from) as f64 / f64::from(self.clock_hz),
            accel_mps2,
            starts_cycle: false,
        };
        if let Err(error) = self.stepper.segment(&segment) {
            self.error = Some(error);
        }
        self.held = Some((tick, accel_mps2));
    }

    /// Every sample answered, in order.
    pub fn samples(&self) -> &[PlateSample] {
        &self.samples
    }

    /// Where and when the plate hit an end stop, if it did.
    pub fn end_stop(&self) -> Option<EndStop> {
        self.stepper.end_stop()
    }

    /// Largest `|x|` so far.
    pub fn peak_excursion_m(&self) -> f64 {
        self.stepper.peak_excursion_m()
    }

    /// A plate the solver could not continue (it then stands still), if any.
    pub fn error(&self) -> Option<&SimError> {
        self.error.as_ref()
    }
}

impl Plant for PlatePlant {
    fn level(&mut self, tick: u64, code: i32) {
        self.advance(tick);
        self.held = Some((tick, self.dac.accel_mps2(code)));
    }

    fn sample(&mut self, tick: u64) -> i32 {
        self.advance(tick);
        let position_m = self.stepper.plate_position_m();
        let count = self.encoder.count(position_m).map_or(0, |c| {
            c.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
        });
        self.samples.push(PlateSample {
            tick,
            time_s: self.stepper.time_s(),
            position_m,
            count,
            position_integral_ms: self.stepper.position_integral_ms(),
        });
        count
    }
}
