//! The part and its contact with the plate: Coulomb friction (kinetic and static), gravity, its
//! mass and a constant external force. The same part rides the ideal plate and a real one.

use feeder_shared::model::STANDARD_GRAVITY_MPS2;
use feeder_shared::{Error, Friction, Quantity};

use crate::error::SimError;

/// The paper's part mass, 0.1 g.
pub const PAPER_PART_MASS_KG: f64 = 1e-4;

/// Coulomb contact between part and plate, and the constant external force on the part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Kinetic friction coefficient `μ`, used while the part slides.
    pub mu: f64,
    /// Static friction coefficient `μ_s ≥ μ`, which decides sticking and breakaway.
    pub mu_static: f64,
    pub gravity_mps2: f64,
    pub mass_kg: f64,
    /// Constant external force on the part along the feed direction.
    pub force_n: f64,
}

impl Contact {
    /// Validates every coefficient; `μ_s` below `μ` is refused because a part could then neither
    /// stick nor slip consistently.
    pub fn new(
        mu: f64,
        mu_static: f64,
        gravity_mps2: f64,
        mass_kg: f64,
        force_n: f64,
    ) -> Result<Self, SimError> {
        let friction = Friction::new(mu, gravity_mps2)?;
        let mu_static = Friction::new(mu_static, gravity_mps2)?.mu;
        if mu_static < friction.mu {
            return Err(SimError::StaticBelowKinetic { mu, mu_static });
        }
        if !mass_kg.is_finite() {
            return Err(Error::NotFinite {
                quantity: Quantity::MassKg,
            }
            .into());
        }
        if mass_kg <= 0.0 {
            return Err(Error::NotPositive {
                quantity: Quantity::MassKg,
                value: mass_kg,
            }
            .into());
        }
        if !force_n.is_finite() {
            return Err(Error::NotFinite {
                quantity: Quantity::ForceN,
            }
            .into());
        }
        Ok(Contact {
            mu,
            mu_static,
            gravity_mps2,
            mass_kg,
            force_n,
        })
    }

    /// Equal static and kinetic friction, standard gravity, no external force.
    pub fn kinetic(mu: f64, mass_kg: f64) -> Result<Self, SimError> {
        Self::new(mu, mu, STANDARD_GRAVITY_MPS2, mass_kg, 0.0)
    }

    /// The paper's part ([`PAPER_PART_MASS_KG`]) with equal static and kinetic friction and no
    /// external force, under `gravity_mps2`.
    pub fn paper_part(mu: f64, gravity_mps2: f64) -> Result<Self, SimError> {
        Self::new(mu, mu, gravity_mps2, PAPER_PART_MASS_KG, 0.0)
    }

    /// The kinetic friction as the shared crate's model sees it.
    pub fn friction(&self) -> Friction {
        Friction {
            mu: self.mu,
            gravity_mps2: self.gravity_mps2,
        }
    }

    /// `μg`.
    pub fn kinetic_accel_mps2(&self) -> f64 {
        self.mu * self.gravity_mps2
    }

    /// `μ_s·g`.
    pub fn static_accel_mps2(&self) -> f64 {
        self.mu_static * self.gravity_mps2
    }

    /// `φ = f_ext / m`.
    pub fn force_accel_mps2(&self) -> f64 {
        self.force_n / self.mass_kg
    }
}
