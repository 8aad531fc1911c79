//! The probe's record ([`Probe`]): the levels its held cycles were commanded and the positions
//! sampled through them, from which the drive is identified.

use crate::closed_loop::identify::{
    identify_counted, GainPrior, Identification, IdentifyLimits, Latch,
};

/// The spread the probe's fit gives the settle's reading of the gains' half difference: the
/// dither reads it within 0.2 % on every drive of the envelope (`shared/tests/settle.rs`),
/// mostly far closer. Weighed as a reading to 0.05 %, the plant family holds the most plants
/// (as many within 1 % at 0.1 %, 2 % fewer at 0.2 %) and `realistic.toml`'s soft start strays
/// least.
const SETTLED_GAIN_SPREAD: f64 = 5e-4;
use crate::closed_loop::shape::CommandSegment;

use super::measure::PositionSample;

/// The most positions a probe keeps (the identification takes at most 512).
pub const PROBE_POSITIONS_MAX: usize = 512;
/// The most probe cycles.
pub const PROBE_CYCLES_MAX: u32 = 8;
/// The most segments in the probe's cycles and its lead-in.
const PROBE_SEGMENTS_MAX: usize = 4 * (PROBE_CYCLES_MAX as usize + 1);

/// The probe's record: the levels its cycles were commanded and the positions sampled through
/// them, timed from the start of its lead-in (the cycle before, whose levels are kept but not
/// its positions).
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    start_tick: u64,
    /// Positions are kept from this tick on: the probe's first start.
    latch_tick: u64,
    clock_hz: u32,
    resolution_m: f64,
    /// The gains' half difference over their mean as the settle found it, if it did.
    gain_half_difference: Option<f64>,
    positions: [Latch; PROBE_POSITIONS_MAX],
    position_count: usize,
    segments: [CommandSegment; PROBE_SEGMENTS_MAX],
    segment_count: usize,
}

impl Probe {
    /// A probe with nothing kept, to be begun ([`Probe::begin`]) or copied into
    /// ([`Probe::copy_from`]).
    pub const fn new() -> Self {
        let latch = Latch {
            t_s: 0.0,
            position_m: 0.0,
        };
        let segment = CommandSegment {
            duration_s: 0.0,
            accel_mps2: 0.0,
        };
        Probe {
            start_tick: 0,
            latch_tick: 0,
            clock_hz: 0,
            resolution_m: 0.0,
            gain_half_difference: None,
            positions: [latch; PROBE_POSITIONS_MAX],
            position_count: 0,
            segments: [segment; PROBE_SEGMENTS_MAX],
            segment_count: 0,
        }
    }

    /// Begins the probe afresh, in place (the course keeps one: a new one on a boundary's
    /// stack would take its size, several kilobytes, from an interrupt's stack): its lead-in
    /// from `start_tick`, positions kept from `latch_tick` on, on a clock of `clock_hz` and a
    /// sensor of `resolution_m`, with the settle's `gain_half_difference`.
    pub(super) fn begin(
        &mut self,
        start_tick: u64,
        latch_tick: u64,
        clock_hz: u32,
        resolution_m: f64,
        gain_half_difference: Option<f64>,
    ) {
        self.start_tick = start_tick;
        self.latch_tick = latch_tick;
        self.clock_hz = clock_hz;
        self.resolution_m = resolution_m;
        self.gain_half_difference = gain_half_difference;
        self.position_count = 0;
        self.segment_count = 0;
    }

    /// Makes this probe `other`, in place: the part of it kept, no copy on the stack.
    pub fn copy_from(&mut self, other: &Probe) {
        self.start_tick = other.start_tick;
        self.latch_tick = other.latch_tick;
        self.clock_hz = other.clock_hz;
        self.resolution_m = other.resolution_m;
        self.gain_half_difference = other.gain_half_difference;
        self.position_count = other.position_count;
        self.positions[..other.position_count]
            .copy_from_slice(&other.positions[..other.position_count]);
        self.segment_count = other.segment_count;
        self.segments[..other.segment_count]
            .copy_from_slice(&other.segments[..other.segment_count]);
    }

    /// Keeps `sample` if it is from the probe's first start on, later than the last one kept
    /// (and there is room).
    pub(super) fn keep_position(&mut self, sample: PositionSample) {
        if sample.tick < self.latch_tick {
            return;
        }
        let Some(ticks) = sample.tick.checked_sub(self.start_tick) else {
            return;
        };
        let t_s = ticks as f64 / f64::from(self.clock_hz);
        let later = self.positions[..self.position_count]
            .last()
            .is_none_or(|kept| t_s > kept.t_s);
        if later && self.position_count < PROBE_POSITIONS_MAX {
            self.positions[self.position_count] = Latch {
                t_s,
                position_m: sample.position_m,
            };
            self.position_count += 1;
        }
    }

    pub(super) fn keep_segment(&mut self, segment: CommandSegment) {
        if self.segment_count < PROBE_SEGMENTS_MAX {
            self.segments[self.segment_count] = segment;
            self.segment_count += 1;
        }
    }

    /// The positions kept.
    pub fn positions(&self) -> &[Latch] {
        &self.positions[..self.position_count]
    }

    /// The levels commanded, trims included.
    pub fn segments(&self) -> &[CommandSegment] {
        &self.segments[..self.segment_count]
    }

    /// The drive identified from the probe, within [`IdentifyLimits::for_probe`], its gains'
    /// difference held to the settle's
    /// ([`identify_given`](crate::closed_loop::identify_given)), with the work it took.
    pub fn identify(&self) -> Identification {
        let limits = IdentifyLimits::for_probe(self.resolution_m);
        // A latch is off the fit by the sensor's quantisation at least.
        let gains = self.gain_half_difference.map(|half_difference| GainPrior {
            half_difference,
            spread: SETTLED_GAIN_SPREAD,
            latch_spread_m: self.resolution_m / libm::sqrt(12.0),
        });
        identify_counted(self.segments(), self.positions(), &limits, gains)
    }
}
