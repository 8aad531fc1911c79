//! The cycles ahead as the course plans them: the rest of the cycle begun and the shape of the
//! next one, from a copy of the scheduler.

use crate::closed_loop::cycle_loop::CycleLoop;
use crate::closed_loop::shape::{CommandSegment, CycleShape};
use crate::scheduler::{Scheduler, Segment};
use crate::segment::SegmentKind;

use super::error::CourseError;

/// The segments of the cycle `begun` starts, in seconds, with `scheduler` right after it
/// (advanced to the next boundary); an idle period or a settle segment is its one segment.
pub(super) fn rest_of_cycle(
    begun: &Segment,
    scheduler: &mut Scheduler,
) -> ([CommandSegment; 4], usize) {
    let plan = *scheduler.plan();
    let mut segments = [CommandSegment::of(begun, &plan); 4];
    let mut count = 1;
    if !matches!(begun.kind, SegmentKind::Idle | SegmentKind::Settle) {
        while !scheduler.at_boundary() && count < 4 {
            segments[count] = CommandSegment::of(&scheduler.next_segment(), &plan);
            count += 1;
        }
    }
    (segments, count)
}

/// The plan of the scheduler's next cycle as the loop aims at it, `ahead` cycles after the one
/// beginning at the next boundary ([`CycleLoop::plan_ahead`]).
pub(super) fn next_shape(
    cycle_loop: &CycleLoop,
    scheduler: &mut Scheduler,
    ahead: u32,
) -> Result<CycleShape, CourseError> {
    let first = scheduler.next_segment();
    next_shape_from(cycle_loop, first, scheduler, ahead)
}

/// The plan of the cycle `first` begins, with `scheduler` right after it.
pub(super) fn next_shape_from(
    cycle_loop: &CycleLoop,
    first: Segment,
    scheduler: &mut Scheduler,
    ahead: u32,
) -> Result<CycleShape, CourseError> {
    let (segments, count) = rest_of_cycle(&first, scheduler);
    if matches!(first.kind, SegmentKind::Idle | SegmentKind::Settle) {
        return Ok(CycleShape::idle(segments[0].duration_s));
    }
    cycle_loop
        .plan_ahead(&segments[..count], ahead)
        .ok_or(CourseError::Plan)
}
