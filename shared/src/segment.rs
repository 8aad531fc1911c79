//! The kinds of segment the output is made of: the four of a waveform cycle (Fig. 2a) and the
//! scheduler's idle period.
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
}

impl SegmentKind {
    /// Every kind, in the order of [`Self`]'s variants.
    pub const ALL: [SegmentKind; 5] = [
        SegmentKind::Accelerate,
        SegmentKind::Plateau,
        SegmentKind::Reverse,
        SegmentKind::Return,
        SegmentKind::Idle,
    ];

    /// The kind's name in the event stream and in refusals.
    pub const fn name(self) -> &'static str {
        match self {
            SegmentKind::Accelerate => "accelerate",
            SegmentKind::Plateau => "plateau",
            SegmentKind::Reverse => "reverse",
            SegmentKind::Return => "return",
            SegmentKind::Idle => "idle",
        }
    }
}
