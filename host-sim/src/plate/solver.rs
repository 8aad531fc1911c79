//! What both of the plate's solvers do: find the next event of a stretch of a commanded segment,
//! from an event or the segment's start, the general solver ([`super::motion`]) whatever the
//! slide, the free slide's ([`super::free`]) in scalar closed form where it has no Coulomb
//! friction.

use super::linear::State;
use super::model::{ContactEvent, Part, Slide};

/// The first event of a stretch with its time from the stretch's start, and the state then (at
/// the segment's end if no event comes first).
pub type StretchEnd = (Option<(ContactEvent, f64)>, State);

/// A solver of the plate and its part between events, one commanded segment at a time.
pub trait Solver: std::fmt::Debug + Send + Sync {
    /// Starts a segment of `duration_s` under the drive target `target_n`, which holds for
    /// `holds_s ≥ duration_s` (into the segments after it).
    fn begin(&mut self, target_n: f64, duration_s: f64, holds_s: f64);

    /// The first event from the state `z` at `offset_s` into the segment, with the slide and
    /// the part in contact `slide` and `part`; `peak_m` is raised to the plate's distance from
    /// the centre at its turning points before it.
    fn next_event(
        &mut self,
        slide: Slide,
        part: Part,
        z: &State,
        offset_s: f64,
        peak_m: &mut f64,
    ) -> StretchEnd;
}
