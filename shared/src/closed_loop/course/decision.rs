//! The course's decision at a boundary ([`Decision`]) and the trims each cycle runs as the
//! output takes them ([`CycleTrims`]).

use crate::closed_loop::cycle_loop::Trims;
use crate::scheduler::Segment;
use crate::segment::SegmentKind;

/// The course's decision at a boundary.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decision {
    /// The cycle these trims are for: the first made after the decision, the one after the
    /// cycle begun (after a settle segment, which is one segment long, the one after that).
    pub cycle: u64,
    pub trims: Trims,
    /// The plate is centred: release the scheduler's hold ([`Scheduler::release_hold`](crate::scheduler::Scheduler::release_hold)).
    pub release: bool,
    /// The probe is complete: identify the drive from [`Course::probe`](super::Course::probe).
    pub identify: bool,
}

impl Decision {
    /// `trims` for the first cycle made after the decision at the start of `begun`, nothing else.
    pub(super) fn trims(begun: &Segment, trims: Trims) -> Self {
        let ahead = if begun.kind == SegmentKind::Settle {
            2
        } else {
            1
        };
        Decision {
            cycle: begun.cycle + ahead,
            trims,
            release: false,
            identify: false,
        }
    }
}

/// The trims each cycle runs, as the output takes them (the firmware's control loop and the
/// simulator both): a decision is taken at the segment after the boundary that made it, and a
/// cycle's trims are fixed when its first segment is made. That is the cycle's decided trims;
/// after an idle period, whose first segment was made before the decision, the feedforward, and
/// so for the second settle segment after it, made as the first began. An idle period runs the
/// plan's zero level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleTrims {
    decided: Option<(u64, Trims)>,
    feedforward: Trims,
    /// Cycles made since the last idle period made (or since the first, at most 3).
    since_idle: u8,
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
        since_idle: 0,
    };

    /// Takes the course's `decision` and its feedforward of the moment.
    pub fn take(&mut self, decision: &Decision, feedforward: Trims) {
        self.decided = Some((decision.cycle, decision.trims));
        self.feedforward = feedforward;
    }

    /// The trims of the cycle `first` begins, made while a cycle or idle period (`after_idle`)
    /// plays: `None` for an idle period. Every cycle start made must come here, in order.
    pub fn for_cycle(
        &mut self,
        first: &Segment,
        after_idle: bool,
    ) -> Result<Option<Trims>, LateTrims> {
        if first.kind == SegmentKind::Idle {
            self.since_idle = 0;
            return Ok(None);
        }
        self.since_idle = self.since_idle.saturating_add(1).min(3);
        // The first two settle segments are made before any decision for them.
        let early_settle = first.kind == SegmentKind::Settle && self.since_idle <= 2;
        match self.decided {
            Some((cycle, trims)) if cycle == first.cycle => Ok(Some(trims)),
            _ if after_idle || early_settle => Ok(Some(self.feedforward)),
            _ => Err(LateTrims { cycle: first.cycle }),
        }
    }

    /// The feedforward last taken: what a cycle without its own trims runs.
    pub fn feedforward(&self) -> Trims {
        self.feedforward
    }
}
