//! An operating point of the feeder (waveform, contact, timing), its run on the ideal plate or a
//! real one, and its analytic predictions.

use feeder_shared::model::{self, Regime};
use feeder_shared::{Limits, TickClock, TickPlan, Waveform, WaveformSpec};

use crate::contact::Contact;
use crate::error::SimError;
use crate::ideal::simulator::{
    run_segments, run_table, Criteria, CycleTable, RunOptions, RunResult,
};
use crate::plate::{self, PlateParams, PlateRun, PlateRunOptions};
use crate::segments::{exact_cycle, scheduler_segments, PlateSegment};

/// Where the segment edges come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Timing {
    /// The waveform's exact real-valued edges (Eq. 1–5).
    Exact,
    /// The shared scheduler's tick plan on a timer of this clock.
    Ticks(TickPlan),
}

/// Default relative tolerance of steady-state detection for exact edges.
pub const EXACT_REL_TOL: f64 = 1e-12;
/// Cycles per block for tick-plan runs: the plan alternates two cycle variants to cancel drift,
/// so single cycles differ slightly and only block means settle.
pub const TICK_BLOCK_CYCLES: u32 = 64;
/// Default relative tolerance of steady-state detection on a tick plan.
pub const TICK_REL_TOL: f64 = 1e-6;
/// Block-to-block variation of a tick plan's feed rate that is quantization, not transient: edges
/// rounded to one tick in 10⁴–10⁵ move a 64-cycle mean by about 10⁻⁵.
pub const TICK_REL_NOISE: f64 = 1e-4;

/// Below this share of the velocity scale `a_max·T/4` a tick plan's noise allowance no longer
/// shrinks with the feed rate: saturated parts feeding at a few percent of the scale still see
/// quantization noise of the scale's order.
pub const TICK_NOISE_FLOOR: f64 = 0.1;

/// Everything needed to simulate one operating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    pub waveform: Waveform,
    pub contact: Contact,
    pub timing: Timing,
}

impl OperatingPoint {
    /// Validates the waveform (no machine limits) and, for `clock_hz`, plans it in ticks.
    pub fn new(
        spec: WaveformSpec,
        contact: Contact,
        clock_hz: Option<u32>,
    ) -> Result<Self, SimError> {
        let waveform = Waveform::new(spec, &Limits::NONE)?;
        let timing = match clock_hz {
            None => Timing::Exact,
            Some(hz) => Timing::Ticks(TickPlan::new(&waveform, TickClock::new(hz))?),
        };
        Ok(OperatingPoint {
            waveform,
            contact,
            timing,
        })
    }

    /// Velocity scale `a_max·T/4` of Eq. 15.
    pub fn velocity_scale_mps(&self) -> f64 {
        self.waveform.accel_mps2 * self.waveform.period_s / 4.0
    }

    /// Steady-state detection suited to the timing.
    pub fn default_criteria(&self) -> Criteria {
        let scale = self.velocity_scale_mps();
        match self.timing {
            Timing::Exact => Criteria::periodic(EXACT_REL_TOL, scale),
            Timing::Ticks(_) => Criteria {
                rel_tol: TICK_REL_TOL,
                abs_tol_mps: TICK_REL_TOL * 1e-3 * scale,
                rel_noise: TICK_REL_NOISE,
                noise_floor_mps: TICK_NOISE_FLOOR * scale,
                block_cycles: TICK_BLOCK_CYCLES,
                max_cycles: 1_000_000,
            },
        }
    }

    /// Runs the ideal plate from a part at rest on the plate at rest.
    pub fn run(&self, options: &RunOptions) -> RunResult {
        match self.timing {
            Timing::Exact => run_table(&CycleTable::exact(&self.waveform, &self.contact), options),
            Timing::Ticks(plan) => run_segments(scheduler_segments(plan), &self.contact, options),
        }
    }

    /// The commanded segments from the start, endless: the exact cycle over and over, or the
    /// scheduler's tick plan.
    pub fn segments(&self) -> Box<dyn Iterator<Item = PlateSegment>> {
        match self.timing {
            Timing::Exact => Box::new(exact_cycle(&self.waveform).into_iter().cycle()),
            Timing::Ticks(plan) => Box::new(scheduler_segments(plan)),
        }
    }

    /// Open loop on a real plate: the command exactly as planned, with no correction, drives
    /// `plate` (a part at rest on the plate at rest at the centre).
    pub fn run_plate(
        &self,
        plate: &PlateParams,
        options: &PlateRunOptions,
    ) -> Result<PlateRun, SimError> {
        plate::run(plate, &self.contact, self.segments(), options)
    }

    /// Runs to steady state with [`Self::default_criteria`].
    pub fn steady(&self) -> RunResult {
        self.run(&RunOptions::converge(self.default_criteria()))
    }

    /// The shared analytic model's prediction for this point.
    pub fn model(&self) -> Prediction {
        let friction = self.contact.friction();
        let state = model::steady_state(&self.waveform, &friction);
        let feed_rate_mps = if self.contact.force_n == 0.0 {
            Some(state.feed_rate_mps)
        } else {
            model::feed_rate_under_force_mps(
                &self.waveform,
                &friction,
                self.contact.mass_kg,
                self.contact.force_n,
            )
            .ok()
        };
        Prediction {
            feed_rate_mps,
            quasi_static_feed_rate_mps: model::feed_rate_quasi_static_mps(&self.waveform),
            regime: state.regime,
            stick_fraction: state.stick_fraction,
            duty_sat_nqs: model::duty_sat_non_quasi_static(self.waveform.accel_mps2, &friction),
        }
    }
}

/// What the shared analytic model predicts (static friction taken equal to kinetic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Eq. 15 or Eq. 18 without force; `v_eq + f/K` (Eq. 10) with one, `None` where that linear
    /// law does not hold.
    pub feed_rate_mps: Option<f64>,
    /// Eq. 9 with its quasi-static saturated branch.
    pub quasi_static_feed_rate_mps: f64,
    pub regime: Regime,
    pub stick_fraction: f64,
    /// Eq. 16.
    pub duty_sat_nqs: f64,
}
