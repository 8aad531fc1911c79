//! The course's decision at a boundary ([`Decision`]) and the trims each cycle runs as the
//! output takes them ([`CycleTrims`]).

use crate::closed_loop::cycle_loop::Trims;
use crate::scheduler::Segment;
use crate::segment::SegmentKind;

/// The course's decision at a boundary.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decision {
    /// The cycle these trims are for: the one after the cycle begun.
    pub cycle: u64,
    pub trims: Trims,
    /// The plate is centred: release the scheduler's hold ([`Scheduler::release_hold`](crate::scheduler::Scheduler::release_hold)).
    pub release: bool,
    /// The probe is complete: identify the drive from [`Course::probe`](super::Course::probe).
    pub identify: bool,
}

impl Decision {
    /// `trims` for the cycle after the one `begun` starts, nothing else.
    pub(super) fn trims(begun: &Segment, trims: Trims) -> Self {
        Decision {
            cycle: begun.cycle + 1,
            trims,
            release: false,
            identify: false,
        }
    }
}

/// The trims each cycle runs, as the output takes them (the firmware's control loop and the
/// simulator both): a decision is taken at the segment after the boundary that made it, and a
/// cycle's trims are fixed when its first segment is made. That is the cycle's decided trims;
/// after an idle period, whose first segment was made before the decision, the feedforward. An
/// idle period runs the plan's zero level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleTrims {
    decided: Option<(u64, Trims)>,
    feedforward: Trims,
}

/// A running cycle that follows a running cycle has no trims decided for it: the closed loop
/// did not keep up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LateTrims {
    pub cycle: u64,
}

impl CycleTrims {
    /// Before any decision: the plan's levels.
    pub const NONE: CycleTrims = CycleTrims {
        decided: None,
        feedforward: Trims::NONE,
    };

    /// Takes the course's `decision` and its feedforward of the moment.
    pub fn take(&mut self, decision: &Decision, feedforward: Trims) {
        self.decided = Some((decision.cycle, decision.trims));
        self.feedforward = feedforward;
    }

    /// The trims of the cycle `first` begins, made while a cycle or idle period (`after_idle`)
    /// plays: `None` for an idle period.
    pub fn for_cycle(&self, first: &Segment, after_idle: bool) -> Result<Option<Trims>, LateTrims> {
        if first.kind == SegmentKind::Idle {
            return Ok(None);
        }
        match self.decided {
            Some((cycle, trims)) if cycle == first.cycle => Ok(Some(trims)),
            _ if after_idle => Ok(Some(self.feedforward)),
            _ => Err(LateTrims { cycle: first.cycle }),
        }
    }

    /// The feedforward last taken: what a cycle without its own trims runs.
    pub fn feedforward(&self) -> Trims {
        self.feedforward
    }
}
