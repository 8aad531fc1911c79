//! Where the course is ([`Stage`]) and what the closed loop reports of it ([`LoopReport`]).

use crate::closed_loop::feed::FeedCompensation;
use crate::closed_loop::identify::Identified;

use super::error::CourseError;

/// Where the course is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Waiting for a start.
    Waiting,
    /// Holding the plate through the settle segments before the first cycle, then through the
    /// soft start's rise to the probe's held step.
    Settling,
    /// Keeping the positions of the probe's cycles.
    Probing,
    /// The probe complete, held until the identification handed over
    /// ([`Course::set_identified`](super::Course::set_identified)) is taken.
    Identifying,
    /// Held cycles, trimmed on the identified drive, until the plate is centred.
    Centring,
    /// The soft start released; every cycle trimmed.
    Feeding,
    /// The course stopped with an error; only a new course helps.
    Failed,
}

impl Stage {
    /// Every stage, in the course's order.
    pub const ALL: [Stage; 7] = [
        Stage::Waiting,
        Stage::Settling,
        Stage::Probing,
        Stage::Identifying,
        Stage::Centring,
        Stage::Feeding,
        Stage::Failed,
    ];

    /// The stage's name in replies and logs.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Waiting => "waiting",
            Stage::Settling => "settling",
            Stage::Probing => "probing",
            Stage::Identifying => "identifying",
            Stage::Centring => "centring",
            Stage::Feeding => "feeding",
            Stage::Failed => "failed",
        }
    }
}

/// What the closed loop reports (the console's `status`): where the course is and, once
/// identified, the drive.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopReport {
    pub stage: Stage,
    pub drive: Option<Identified>,
    /// The feed's compensation of the drive's lag for the plan running, once found.
    pub feed: Option<FeedCompensation>,
    /// Why the course stopped, once it has.
    pub failure: Option<CourseError>,
}
