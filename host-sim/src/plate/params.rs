//! The plate's physical parameters: the top-level keys of a plant file.
//!
//! Every key is optional and defaults to the ideal plate, which follows the commanded acceleration
//! exactly: no offset, unit gains, an instantaneous current loop, no force limit, a frictionless
//! free slide and no end stops ([`PlateParams::is_ideal`]).

use serde::Deserialize;

use crate::error::SimError;

/// A linear-motor slide carrying the plate, and the drive that powers it.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlateParams {
    /// Moving mass `M` (plate, slide carriage and motor forcer).
    pub mass_kg: f64,
    /// Full-scale acceleration of the drive's command, the unit of the zero offset.
    pub full_scale_accel_mps2: f64,
    /// Zero offset `e₀` as a fraction of full scale: the drive pushes `M·e₀·a_fs` at zero command.
    pub zero_offset_fraction: f64,
    /// Gain applied to a positive command (`+a`); 1 is ideal.
    pub gain_positive: f64,
    /// Gain applied to a negative command (`−a`); 1 is ideal.
    pub gain_negative: f64,
    /// Current-loop bandwidth `f_c`: `F' = 2π·f_c·(F* − F)`. Absent: the force follows at once.
    pub current_bandwidth_hz: Option<f64>,
    /// Peak force of the drive, `|F*| ≤ F_max`. Absent: unlimited.
    pub force_limit_n: Option<f64>,
    /// Coulomb friction of the slide, `F_c·sign(v)`; the slide sticks while `|F − k·x| ≤ F_c`.
    pub coulomb_friction_n: f64,
    /// Viscous friction of the slide, `b·v`.
    pub viscous_friction_nspm: f64,
    /// Centring spring `k·x`.
    pub spring_npm: f64,
    /// Damping of the centring spring, `c·v`.
    pub spring_damping_nspm: f64,
    /// End stops at `±x_lim`. Absent: unlimited travel.
    pub end_stop_m: Option<f64>,
}

impl Default for PlateParams {
    fn default() -> Self {
        PlateParams {
            mass_kg: 1.0,
            full_scale_accel_mps2: 200.0,
            zero_offset_fraction: 0.0,
            gain_positive: 1.0,
            gain_negative: 1.0,
            current_bandwidth_hz: None,
            force_limit_n: None,
            coulomb_friction_n: 0.0,
            viscous_friction_nspm: 0.0,
            spring_npm: 0.0,
            spring_damping_nspm: 0.0,
            end_stop_m: None,
        }
    }
}

/// Ranges a key can be refused for.
const POSITIVE: &str = "finite and > 0";
const NON_NEGATIVE: &str = "finite and ≥ 0";
const FRACTION: &str = "between -1 and 1";

impl PlateParams {
    /// Refuses every value outside its physical range, naming the key.
    pub fn validate(&self) -> Result<(), SimError> {
        check("mass_kg", self.mass_kg, POSITIVE, |x| x > 0.0)?;
        check(
            "full_scale_accel_mps2",
            self.full_scale_accel_mps2,
            POSITIVE,
            |x| x > 0.0,
        )?;
        check(
            "zero_offset_fraction",
            self.zero_offset_fraction,
            FRACTION,
            |x| x.abs() <= 1.0,
        )?;
        check("gain_positive", self.gain_positive, POSITIVE, |x| x > 0.0)?;
        check("gain_negative", self.gain_negative, POSITIVE, |x| x > 0.0)?;
        if let Some(f_c) = self.current_bandwidth_hz {
            check("current_bandwidth_hz", f_c, POSITIVE, |x| x > 0.0)?;
        }
        if let Some(limit) = self.force_limit_n {
            check("force_limit_n", limit, POSITIVE, |x| x > 0.0)?;
        }
        for (key, value) in [
            ("coulomb_friction_n", self.coulomb_friction_n),
            ("viscous_friction_nspm", self.viscous_friction_nspm),
            ("spring_npm", self.spring_npm),
            ("spring_damping_nspm", self.spring_damping_nspm),
        ] {
            check(key, value, NON_NEGATIVE, |x| x >= 0.0)?;
        }
        if let Some(x_lim) = self.end_stop_m {
            check("end_stop_m", x_lim, POSITIVE, |x| x > 0.0)?;
        }
        Ok(())
    }

    /// True when the plate follows the command exactly, so the exact piecewise-linear simulator
    /// ([`crate::ideal`]) applies unchanged.
    pub fn is_ideal(&self) -> bool {
        self.zero_offset_fraction == 0.0
            && self.gain_positive == 1.0
            && self.gain_negative == 1.0
            && self.current_bandwidth_hz.is_none()
            && self.force_limit_n.is_none()
            && self.coulomb_friction_n == 0.0
            && self.viscous_friction_nspm == 0.0
            && self.spring_npm == 0.0
            && self.spring_damping_nspm == 0.0
            && self.end_stop_m.is_none()
    }

    /// Driver target force for a commanded acceleration, `F* = M·(g_± · a_cmd + e₀·a_fs)` clamped
    /// to `±F_max`.
    pub fn target_force_n(&self, command_mps2: f64) -> f64 {
        let gain = if command_mps2 >= 0.0 {
            self.gain_positive
        } else {
            self.gain_negative
        };
        let offset_mps2 = self.zero_offset_fraction * self.full_scale_accel_mps2;
        let force = self.mass_kg * (gain * command_mps2 + offset_mps2);
        match self.force_limit_n {
            Some(limit) => force.clamp(-limit, limit),
            None => force,
        }
    }
}

fn check(
    key: &'static str,
    value: f64,
    allowed: &'static str,
    ok: fn(f64) -> bool,
) -> Result<(), SimError> {
    if value.is_finite() && ok(value) {
        Ok(())
    } else {
        Err(SimError::PlantValue {
            key,
            value,
            allowed,
        })
    }
}
