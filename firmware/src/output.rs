//! The output stage as the application sees it: a timer that starts each segment in hardware,
//! with the next segment preloaded by software while the current one plays.

use feeder_shared::{DriveError, Segment, TickClock};

/// A segment could not be prepared before its edge: the output timing is lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct EdgeMissed;

/// How a segment began on the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentStart {
    /// The tick at which it took effect.
    pub tick: u64,
    /// Its deadline (its start) minus the moment software preloaded it, in ticks; `None` for a
    /// segment applied at once by [`SegmentOutput::restart`] or where the stage cannot read it.
    pub slack_ticks: Option<u32>,
}

/// A hardware-timed output of segments.
///
/// The stage holds two segments: the one playing and the one preloaded. At the end of the
/// playing segment the timer starts the preloaded one without software; the application then
/// preloads the next. Segment lengths are in ticks of [`SegmentOutput::clock`].
pub trait SegmentOutput {
    /// The clock that times the segments; the scheduler plans in its ticks.
    fn clock(&self) -> TickClock;

    /// Recomputes the output levels for plans with this peak acceleration. Segments already
    /// playing or preloaded keep their values. On error the stage outputs zero until a valid
    /// acceleration is set.
    fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError>;

    /// Applies `segment` at once and restarts the timer with its length; nothing is preloaded.
    fn restart(&mut self, segment: &Segment);

    /// Preloads `segment` to begin when the playing one ends. Fails if an edge has passed since
    /// [`SegmentOutput::wait_edge`] returned, or if the segment is too short to be timed.
    fn preload(&mut self, segment: &Segment) -> Result<(), EdgeMissed>;

    /// Waits until the preloaded segment has begun. Fails if more than one edge has passed.
    async fn wait_edge(&mut self) -> Result<(), EdgeMissed>;

    /// Outputs zero at once and stops the timer.
    fn halt(&mut self);

    /// How `segment`, the one just begun, started. The timer starts every segment on its
    /// planned tick: the tick is that start, on the stage's own timeline (which a restart after
    /// a halt may shift against the plan).
    fn started(&self, segment: &Segment) -> SegmentStart;
}
