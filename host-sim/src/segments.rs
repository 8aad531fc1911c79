//! The plate's commanded segments ([`PlateSegment`]), taken only from the shared crate: one cycle
//! of the waveform's exact real-valued times (Eq. 1–5), or the scheduler's integer-tick plan
//! divided by its clock. Both the ideal plate and a real one run on them.

use feeder_shared::{Scheduler, Segment, SegmentKind, TickPlan, Waveform};

/// A stretch of constant commanded plate acceleration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateSegment {
    pub duration_s: f64,
    pub accel_mps2: f64,
    /// True for the first segment of a waveform cycle (or of an idle period); per-cycle
    /// statistics are closed here.
    pub starts_cycle: bool,
}

impl PlateSegment {
    /// A finite duration `≥ 0` and a finite acceleration.
    pub fn is_valid(&self) -> bool {
        self.duration_s >= 0.0 && self.duration_s.is_finite() && self.accel_mps2.is_finite()
    }
}

/// One cycle of the waveform's exact real-valued segments (`Waveform::segments`, Eq. 1–5).
pub fn exact_cycle(waveform: &Waveform) -> [PlateSegment; 4] {
    waveform.segments().map(|segment| PlateSegment {
        duration_s: segment.duration_s,
        accel_mps2: f64::from(segment.level.sign()) * waveform.accel_mps2,
        starts_cycle: segment.kind == SegmentKind::Accelerate,
    })
}

/// A scheduler's `segment` of `plan` in seconds (ticks ÷ clock).
pub fn in_seconds(plan: &TickPlan, segment: &Segment) -> PlateSegment {
    PlateSegment {
        duration_s: plan.ticks_to_s(u64::from(segment.ticks)),
        accel_mps2: segment.accel_mps2(),
        starts_cycle: segment.starts_cycle(),
    }
}

/// The shared scheduler's segments for `plan`, started at once at full amplitude, in seconds.
/// Endless.
pub fn scheduler_segments(plan: TickPlan) -> impl Iterator<Item = PlateSegment> {
    let mut scheduler = Scheduler::new(plan, 1);
    scheduler.start();
    std::iter::repeat_with(move || in_seconds(&plan, &scheduler.next_segment()))
}
