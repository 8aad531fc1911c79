//! The operator's settings and their validation on a machine.
//!
//! A change never touches the running machine directly: [`Settings::apply`] turns a [`Setting`]
//! into a fully validated candidate ([`Applied`]: settings, tick plan, predicted feed rate) or a
//! typed [`Error`], so a refused change leaves everything as it was.

use crate::closed_loop::ENVELOPE;
use crate::error::{positive, Error, Quantity};
use crate::model::{self, Friction};
use crate::plan::{TickClock, TickPlan};
use crate::waveform::{Drive, Limits, Waveform, WaveformSpec};

/// The machine a setting is validated for: its limits, the part's friction (for the feed-rate
/// model), the waveform timer and, where the closed loop runs, the output's linear range.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Machine {
    pub limits: Limits,
    pub friction: Friction,
    pub clock: TickClock,
    /// Where the closed loop runs the waveform: the peak acceleration the output's linear range
    /// reaches, m/s². Every waveform must then leave the loop its room
    /// ([`crate::closed_loop::Envelope::check_loop_accel`]); `None` for an open-loop machine.
    pub loop_linear_mps2: Option<f64>,
}

impl Machine {
    /// Steady-state feed rate the model predicts for `waveform` on this machine.
    pub fn feed_rate_mps(&self, waveform: &Waveform) -> f64 {
        model::steady_state(waveform, &self.friction).feed_rate_mps
    }
}

/// A requested parameter change, in the units of the protocol.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Setting {
    FrequencyHz(f64),
    Duty(f64),
    /// Holds the stroke from now on; the peak acceleration follows from Eq. 5.
    StrokeMm(f64),
    /// Holds the peak acceleration from now on; the stroke follows from Eq. 5.
    AccelMps2(f64),
    /// Chooses the duty with the inverse model, holding frequency and stroke or acceleration.
    FeedMmps(f64),
    RampCycles(u16),
}

/// The operator's parameters: what `set` changes and a recipe stores.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Settings {
    pub frequency_hz: f64,
    pub duty: f64,
    pub drive: Drive,
    pub ramp_cycles: u16,
}

impl Settings {
    /// The defaults, the one definition the firmware powers up with: the paper's operating point,
    /// 50 Hz, `d = 0.586` (the optimum `2 − √2`, [`model::DUTY_OPT`], to the paper's three
    /// decimals) and a 2.5 mm stroke, which Eq. 5 turns into `a_max ≈ 146 m/s²`; soft start and
    /// stop over 25 cycles (0.5 s at 50 Hz).
    pub const DEFAULT: Settings = Settings {
        frequency_hz: 50.0,
        duty: 0.586,
        drive: Drive::Stroke { stroke_m: 2.5e-3 },
        ramp_cycles: 25,
    };

    /// The waveform these settings ask for (not yet validated).
    pub const fn spec(&self) -> WaveformSpec {
        WaveformSpec::from_frequency(self.frequency_hz, self.duty, self.drive)
    }

    /// Validates these settings on `machine`: waveform within the limits (and the closed loop's
    /// room, where it runs) and a representable tick plan.
    pub fn validate(&self, machine: &Machine) -> Result<Applied, Error> {
        positive(Quantity::FrequencyHz, self.frequency_hz)?;
        let (waveform, plan) = plan_waveform(
            self.spec(),
            &machine.limits,
            machine.loop_linear_mps2,
            machine.clock,
        )?;
        Ok(Applied {
            settings: *self,
            plan,
            feed_rate_mps: machine.feed_rate_mps(&waveform),
        })
    }

    /// The settings after `setting`, fully validated; `self` is left as it is either way.
    pub fn apply(&self, setting: Setting, machine: &Machine) -> Result<Applied, Error> {
        let mut next = *self;
        match setting {
            Setting::FrequencyHz(frequency_hz) => next.frequency_hz = frequency_hz,
            Setting::Duty(duty) => next.duty = duty,
            Setting::StrokeMm(stroke_mm) => {
                next.drive = Drive::Stroke {
                    stroke_m: stroke_mm / 1000.0,
                }
            }
            Setting::AccelMps2(accel_mps2) => next.drive = Drive::Accel { accel_mps2 },
            Setting::RampCycles(ramp_cycles) => next.ramp_cycles = ramp_cycles,
            Setting::FeedMmps(feed_mmps) => {
                let period_s = 1.0 / positive(Quantity::FrequencyHz, self.frequency_hz)?;
                let waveform = model::duty_for_feed_rate(
                    period_s,
                    feed_mmps / 1000.0,
                    self.drive,
                    &machine.friction,
                    &machine.limits,
                )?;
                next.duty = waveform.duty;
            }
        }
        next.validate(machine)
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings::DEFAULT
    }
}

/// Validated settings, ready for the scheduler (`set_plan`, `set_ramp_cycles`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Applied {
    pub settings: Settings,
    pub plan: TickPlan,
    /// Steady-state feed rate the model predicts for the plan's waveform.
    pub feed_rate_mps: f64,
}

/// The one check a waveform passes before it plays, wherever it comes from (console, recipe,
/// script, the host): within `limits` (Eq. 1–5), the closed loop's room where it runs
/// (`loop_linear_mps2`, the output's linear range; `None` in open loop), and a representable tick
/// plan on `clock`.
pub fn plan_waveform(
    spec: WaveformSpec,
    limits: &Limits,
    loop_linear_mps2: Option<f64>,
    clock: TickClock,
) -> Result<(Waveform, TickPlan), Error> {
    let waveform = Waveform::new(spec, limits)?;
    if let Some(linear_mps2) = loop_linear_mps2 {
        ENVELOPE.check_loop_accel(waveform.accel_mps2, linear_mps2)?;
    }
    let plan = TickPlan::new(&waveform, clock)?;
    Ok((waveform, plan))
}
