//! The factor on a cycle's levels and on its planned motion: the feed's amplitude and an
//! excitation, each moving a step a cycle toward where it is going.

/// The feed's amplitude moves by at most this a cycle toward a new one.
const FEED_STEP: f64 = 0.005;
/// The excitation's factor on the levels moves by this a cycle ([`CycleLoop::excite`](super::CycleLoop::excite)).
pub(super) const EXCITE_STEP: f64 = 0.05;

/// The factor on the levels and on the planned motion: the feed's amplitude and an excitation,
/// each on its way to where it is going, a step a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Scale {
    /// The amplitude the feed needs on the identified plate ([`feed`](crate::closed_loop::feed)), and where it is
    /// going: it moves there by [`FEED_STEP`] a cycle.
    pub(super) feed: f64,
    pub(super) feed_target: f64,
    /// The excitation's factor, and the peak it rises to before it falls back to 1
    /// ([`CycleLoop::excite`](super::CycleLoop::excite)); it moves only once the slide is fed forward in full.
    pub(super) excitation: f64,
    pub(super) excitation_peak: Option<f64>,
}

impl Scale {
    pub(super) const ONE: Scale = Scale {
        feed: 1.0,
        feed_target: 1.0,
        excitation: 1.0,
        excitation_peak: None,
    };

    pub(super) fn factor(&self) -> f64 {
        self.feed * self.excitation
    }

    /// The scale a cycle on, the slide fed forward in full or not (`slide_full`).
    pub(super) fn stepped(self, slide_full: bool) -> Scale {
        let mut next = self;
        next.feed += (self.feed_target - self.feed).clamp(-FEED_STEP, FEED_STEP);
        if slide_full {
            // Within half a step of its end a move ends there: the steps' sums do not carry
            // rounding into an extra cycle.
            match self.excitation_peak {
                Some(peak) => {
                    next.excitation = self.excitation + EXCITE_STEP;
                    if next.excitation >= peak - EXCITE_STEP / 2.0 {
                        next.excitation = peak;
                        next.excitation_peak = None;
                    }
                }
                None => {
                    next.excitation = self.excitation - EXCITE_STEP;
                    if next.excitation <= 1.0 + EXCITE_STEP / 2.0 {
                        next.excitation = 1.0;
                    }
                }
            }
        }
        next
    }
}
