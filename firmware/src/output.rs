//! The output stage as the application sees it: a timer that starts each segment in hardware,
//! with the next segment preloaded by software while the current one plays.

use core::future::poll_fn;
use core::sync::atomic::{AtomicU32, Ordering};
use core::task::Poll;

use embassy_sync::waitqueue::AtomicWaker;
use feeder_shared::{DriveError, Segment, TickClock};

/// A segment could not be prepared before its edge: the output timing is lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct EdgeMissed;

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
}

/// Edge count of the segment timer, shared between its interrupt and the output stage.
pub struct EdgeSignal {
    edges: AtomicU32,
    waker: AtomicWaker,
}

impl EdgeSignal {
    pub const fn new() -> Self {
        Self {
            edges: AtomicU32::new(0),
            waker: AtomicWaker::new(),
        }
    }

    /// Records one edge; called from the segment timer's interrupt.
    pub fn record(&self) {
        self.edges.fetch_add(1, Ordering::Release);
        self.waker.wake();
    }

    /// Edges recorded so far (wrapping).
    pub fn count(&self) -> u32 {
        self.edges.load(Ordering::Acquire)
    }

    /// Waits until the count differs from `seen` and returns how many edges have passed.
    pub async fn wait_past(&self, seen: u32) -> (u32, u32) {
        poll_fn(|cx| {
            self.waker.register(cx.waker());
            let now = self.count();
            if now == seen {
                Poll::Pending
            } else {
                Poll::Ready((now, now.wrapping_sub(seen)))
            }
        })
        .await
    }
}
