//! How the course runs: the probe's length and level, when the plate counts as centred, the
//! loop's limits.

use crate::closed_loop::cycle_loop::LoopLimits;

/// How the course runs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CourseConfig {
    /// Settle segments before the probe ([`Scheduler::settle_before_start`](crate::Scheduler::settle_before_start)).
    pub settle_segments: u16,
    /// Held cycles the probe keeps (1 to [`PROBE_CYCLES_MAX`](super::PROBE_CYCLES_MAX)).
    pub probe_cycles: u32,
    /// The held step as a fraction of the soft start's steps (at least one step).
    pub probe_fraction: f64,
    /// The position sensor's resolution: the probe must move the plate 20 of them.
    pub resolution_m: f64,
    /// The plate counts as centred within this of where a cycle should start …
    pub centred_m: f64,
    /// … for this many held cycles in a row.
    pub centred_cycles: u32,
    /// Centring that takes more held cycles than this fails.
    pub centring_cycles_max: u32,
    /// The held cycles after the probe give the identification this long for each fit it
    /// makes (the slowest board's time, with room to spare) …
    pub identify_fit_s: f64,
    /// … and this long besides ([`CourseConfig::identify_hold_s`]).
    pub identify_base_s: f64,
    pub loop_limits: LoopLimits,
    /// The output's smallest step of a level (a DAC count), 0 for a continuous one
    /// ([`CycleLoop::with_level_step`](crate::closed_loop::CycleLoop::with_level_step)).
    pub level_step_mps2: f64,
    /// The part's sliding deceleration `μg`, for the feed's compensation of the drive's lag
    /// ([`FeedRequest`](crate::closed_loop::FeedRequest)); 0: none.
    pub part_mps2: f64,
    /// How far the output's levels reach in the drive's linear range.
    pub linear_mps2: f64,
    /// How long after the course asks for a feed compensation it takes the answer
    /// ([`Course::feed_request`](crate::closed_loop::Course::feed_request)).
    pub feed_hold_s: f64,
    /// The held cycles' levels rise to this factor and fall back once the drive is
    /// identified ([`CycleLoop::excite`](crate::closed_loop::CycleLoop::excite)); the soft
    /// start is released after.
    pub excitation_peak: f64,
}

impl CourseConfig {
    /// The settle's pairs (60 segments, 150 ms at 50 Hz and at 100 Hz); 4 probe cycles at 30 %
    /// of the levels; the identification given 0.1125 s a fit and 0.25 s besides (a fit takes
    /// the firmware 79 ms under QEMU at 50 Hz, 60 ms at 100 Hz, where the probe has half the
    /// latches and the interrupts take twice the time: 1.26 s for `realistic.toml`'s 16 fits at
    /// 50 Hz); centred within 25 µm for 20 cycles (the loop's disturbance estimate
    /// settles on the identified drive meanwhile), in at most 250 cycles; the loop may add up to
    /// 50 m/s² (a quarter of the envelope's full scale: a spring or slide friction at its limit
    /// needs that much), trim the stroke by ±20 % and gives up 4 mm from centre; levels in steps
    /// of `level_step_mps2`; no feed compensation ([`CourseConfig::with_feed`]), taken 1 s
    /// after it is asked for where there is one (the firmware needs up to 0.7 s under QEMU);
    /// the held levels excited to 1.5 times the probe's and back (20 cycles).
    pub fn new(resolution_m: f64, level_step_mps2: f64) -> Self {
        CourseConfig {
            settle_segments: 2 * crate::closed_loop::settle::PAIRS,
            probe_cycles: 4,
            probe_fraction: 0.3,
            resolution_m,
            centred_m: 25e-6,
            centred_cycles: 20,
            centring_cycles_max: 250,
            identify_fit_s: 0.1125,
            identify_base_s: 0.25,
            loop_limits: LoopLimits {
                correction_max_mps2: 50.0,
                amplitude_max: 0.2,
                position_error_max_m: 4e-3,
            },
            level_step_mps2,
            part_mps2: 0.0,
            linear_mps2: 0.0,
            feed_hold_s: 1.0,
            excitation_peak: 1.5,
        }
    }

    /// How long the held cycles after the probe give an identification of `fits` fits: it is
    /// taken at the first boundary that long after the probe's end,
    /// however early it came, so that every runner holds the plate as long; one handed over
    /// later stops the course, and so does none by the hold of the most fits
    /// ([`FITS_MAX`](crate::closed_loop::identify::FITS_MAX)).
    pub fn identify_hold_s(&self, fits: u32) -> f64 {
        self.identify_base_s + f64::from(fits) * self.identify_fit_s
    }

    /// The course for a part of `part_mps2 = μg` on an output whose levels reach `linear_mps2`
    /// in the drive's linear range: the feed is compensated for the drive's lag.
    pub fn with_feed(self, part_mps2: f64, linear_mps2: f64) -> Self {
        CourseConfig {
            part_mps2,
            linear_mps2,
            ..self
        }
    }

    /// The held step of a soft start of `ramp_steps` steps.
    pub fn probe_step(&self, ramp_steps: u16) -> u16 {
        let step = libm::round(self.probe_fraction * f64::from(ramp_steps));
        (step as u16).clamp(1, ramp_steps.max(1))
    }
}
