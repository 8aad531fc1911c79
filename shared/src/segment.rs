//! The kinds of segment the output is made of: the four of a waveform cycle (Fig. 2a), the
//! scheduler's idle period and the closed loop's settle segments.
//!
//! A module of its own, below both: [`crate::error`] names a segment in its refusals, and
//! [`crate::waveform`], [`crate::plan`] and [`crate::scheduler`] build segments.

/// A segment of the three-level acceleration waveform, in the order it is output within a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SegmentKind {
    /// `+a` on `[0, t1)`: the plate speeds up forward.
    Accelerate,
    /// `0` on `[t1, t2)`: the plateau `P` at `v_max`.
    Plateau,
    /// `−a` on `[t2, t3)`: the plate brakes and swings backward.
    Reverse,
    /// `+a` on `[t3, T)`: the plate returns to rest at the cycle boundary.
    Return,
    /// `0` for a whole period while the scheduler is stopped.
    Idle,
    /// A fraction of a period at level `0` before the first cycle of a start, each its own
    /// cycle: the closed loop holds the plate at rest through its bias
    /// ([`Scheduler::settle_before_start`](crate::Scheduler::settle_before_start)).
    Settle,
}

impl SegmentKind {
    /// Every kind, in the order of [`Self`]'s variants.
    pub const ALL: [SegmentKind; 6] = [
        SegmentKind::Accelerate,
        SegmentKind::Plateau,
        SegmentKind::Reverse,
        SegmentKind::Return,
        SegmentKind::Idle,
        SegmentKind::Settle,
    ];

    /// True for the first segment of a cycle, an idle period or a settle segment: where the
    /// cycle count moves on and the closed loop decides.
    pub const fn starts_cycle(self) -> bool {
        matches!(
            self,
            SegmentKind::Accelerate | SegmentKind::Idle | SegmentKind::Settle
        )
    }

    /// Whether the driver is enabled while a segment of this kind plays (and the supervisor
    /// lets it): for all but an idle period, so that a drive's zero offset cannot walk a plate
    /// at rest.
    pub const fn drives(self) -> bool {
        !matches!(self, SegmentKind::Idle)
    }

    /// The segment's place in its cycle: 0 for the first (and the only one of an idle period
    /// or a settle segment), then 1, 2, 3 through the paper's cycle
    /// ([`CYCLE`](crate::scheduler::CYCLE)).
    pub const fn place(self) -> usize {
        match self {
            SegmentKind::Accelerate | SegmentKind::Idle | SegmentKind::Settle => 0,
            SegmentKind::Plateau => 1,
            SegmentKind::Reverse => 2,
            SegmentKind::Return => 3,
        }
    }

    /// The kind's name in the event stream and in refusals.
    pub const fn name(self) -> &'static str {
        match self {
            SegmentKind::Accelerate => "accelerate",
            SegmentKind::Plateau => "plateau",
            SegmentKind::Reverse => "reverse",
            SegmentKind::Return => "return",
            SegmentKind::Idle => "idle",
            SegmentKind::Settle => "settle",
        }
    }
}
