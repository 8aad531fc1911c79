//! Random operator changes for the scripted run (`changes=K seed=S`): what a careless operator
//! or a PLC does to a running feeder, reproducible from the seed. Each change lands at a random
//! moment of a cycle and is one of: a setting (duty, frequency or stroke) drawn across the
//! machine's range and a little past it, planned here like a console command (a refused one is
//! logged and changes nothing); two settings back to back, of which the newer must win; or a
//! stop followed by a start up to a ramp later, so that the start may land mid-ramp.

use defmt::info;
use embassy_time::Timer;
use feeder_shared::{Drive, SupervisorEvent, TickClock, WaveformSpec};

use super::{cycle, offer, request};
use crate::configured;
use crate::mailbox::ReadyPlan;

/// Drawn values reach this fraction past each end of the machine's range.
const PAST_RANGE: f64 = 0.1;

/// xorshift32: small, fast and reproducible; the changes need no better randomness.
pub struct Random(u32);

impl Random {
    /// A generator from `seed` (zero, which xorshift cannot leave, is taken as one).
    pub fn new(seed: u32) -> Self {
        Random(seed.max(1))
    }

    fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }

    /// Uniform in `[low, high)`.
    fn between(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * f64::from(self.next()) / 4_294_967_296.0
    }

    /// Uniform in `[0, n)`; `n` ≥ 1.
    fn below(&mut self, n: u32) -> u32 {
        self.next() % n.max(1)
    }

    /// Uniform across `[low, high]` widened by [`PAST_RANGE`] of its span at each end.
    fn around(&mut self, low: f64, high: f64) -> f64 {
        let past = PAST_RANGE * (high - low);
        self.between(low - past, high + past)
    }
}

/// The random operator: its generator and the settings it last had accepted.
pub struct RandomChanges {
    random: Random,
    clock: TickClock,
    spec: WaveformSpec,
    ramp_cycles: u16,
}

impl RandomChanges {
    pub fn new(seed: u32, clock: TickClock, spec: WaveformSpec, ramp_cycles: u16) -> Self {
        Self {
            random: Random::new(seed),
            clock,
            spec,
            ramp_cycles,
        }
    }

    /// Cycle `index` of `count` changes spread evenly over `[first, last)`.
    pub fn cycle_of(index: u32, count: u32, first: u32, last: u32) -> u32 {
        let span = u64::from(last.saturating_sub(first));
        first + (span * u64::from(index + 1) / u64::from(count + 1)) as u32
    }

    /// Makes one change, from a random moment within the current cycle.
    pub async fn change(&mut self) {
        let period_us = (self.spec.period_s * 1e6) as u32;
        Timer::after_micros(u64::from(self.random.below(period_us))).await;
        match self.random.below(8) {
            0..=4 => self.set(),
            5 => {
                self.set();
                self.set();
            }
            _ => {
                info!("scenario: random stop and start");
                request(SupervisorEvent::StopRequested);
                let cycles = self.random.below(u32::from(self.ramp_cycles) + 1);
                let from = cycle();
                while cycle().wrapping_sub(from) < cycles {
                    Timer::after_millis(1).await;
                }
                request(SupervisorEvent::StartRequested);
            }
        }
    }

    /// Draws one setting and offers its plan to the control loop if the machine accepts it.
    fn set(&mut self) {
        let limits = configured::get().limits;
        let mut spec = self.spec;
        match self.random.below(3) {
            0 => spec.duty = self.random.around(0.5, 1.0),
            1 => {
                let frequency_hz = self
                    .random
                    .around(limits.min_frequency_hz, limits.max_frequency_hz);
                spec.period_s = 1.0 / frequency_hz;
            }
            _ => {
                let stroke_m = self.random.around(0.0, limits.max_stroke_m);
                spec.drive = Drive::Stroke { stroke_m };
            }
        }
        match ReadyPlan::new(self.clock, &spec, self.ramp_cycles) {
            Ok(ready) => {
                offer(ready);
                self.spec = spec;
            }
            Err(error) => info!("scenario: change refused: {}", error),
        }
    }
}
