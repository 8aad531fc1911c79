//! The paper's part (Section III) on a plate's periodic motion: a point mass under Coulomb
//! friction `μg`, sliding at `±μg` toward the plate's velocity or stuck to the plate while the
//! plate's acceleration is at most `μg`. Its periodic motion is found by Newton's steps on its
//! velocity at the cycle's start, kept in a bracket (one cycle's map is monotone), each meeting
//! with the plate placed inside its step.

use libm::fabs;

use super::plate::PlateCycle;
use crate::closed_loop::shape::sign;

/// The periodic motion's search stops at this velocity error.
const VELOCITY_TOLERANCE_MPS: f64 = 1e-6;
const SEARCH_STEPS_MAX: usize = 60;

impl PlateCycle<'_> {
    /// The part's velocity at the cycle's end and its displacement through the cycle, from
    /// `part_v` at its start.
    /// And the derivative of the velocity at the end by the one at the start: the part keeps a
    /// change of its velocity while it slides, scaled at each meeting with the plate by the
    /// ratio of how fast the two velocities part after it to how fast they closed before; a
    /// part that sticks forgets it.
    fn part_cycle(&self, part_mps2: f64, mut part_v: f64) -> (f64, f64, f64) {
        let mut moved_m = 0.0;
        let mut plate_v = self.start_velocity_mps();
        let mut stuck = false;
        let mut slope = 1.0;
        self.for_each_step(|h, next_plate_v, accel, _| {
            if stuck && fabs(accel) <= part_mps2 {
                moved_m += (part_v + next_plate_v) / 2.0 * h;
                part_v = next_plate_v;
                plate_v = next_plate_v;
                return;
            }
            stuck = false;
            let ahead = plate_v - part_v;
            let direction = if ahead != 0.0 {
                sign(ahead)
            } else {
                sign(accel)
            };
            let next_v = part_v + direction * part_mps2 * h;
            let next_ahead = next_plate_v - next_v;
            if next_ahead * direction > 0.0 || direction == 0.0 {
                moved_m += (part_v + next_v) / 2.0 * h;
                part_v = next_v;
            } else {
                // The part meets the plate inside the step: it sticks there or slides on the
                // other way.
                let fraction = ahead / (ahead - next_ahead);
                let met_v = part_v + direction * part_mps2 * fraction * h;
                let rest_s = (1.0 - fraction) * h;
                moved_m += (part_v + met_v) / 2.0 * fraction * h;
                part_v = if fabs(accel) <= part_mps2 {
                    stuck = true;
                    slope = 0.0;
                    next_plate_v
                } else {
                    slope *= (accel + direction * part_mps2) / (accel - direction * part_mps2);
                    met_v - direction * part_mps2 * rest_s
                };
                moved_m += (met_v + part_v) / 2.0 * rest_s;
            }
            plate_v = next_plate_v;
        });
        (part_v, moved_m, slope)
    }

    /// The part's mean velocity in its periodic motion on this plate.
    pub(super) fn feed_rate_mps(&self, part_mps2: f64) -> f64 {
        // One cycle's map `F` is monotone and maps the plate's velocity range into itself:
        // `F(v) − v` is at least 0 at `low` and at most 0 at `high`. Between the part's changes
        // of course `F` is linear, so Newton's steps (with the slope from the pass itself)
        // land on the fixed point in a few passes; a step that leaves the bracket bisects it.
        let (mut low, mut high) = self.velocity_range();
        let mut v = (low + high) / 2.0;
        let mut moved_m = 0.0;
        for _ in 0..SEARCH_STEPS_MAX {
            let (end_v, moved, slope) = self.part_cycle(part_mps2, v);
            moved_m = moved;
            let gap = end_v - v;
            if gap >= 0.0 {
                low = v;
            }
            if gap <= 0.0 {
                high = v;
            }
            if fabs(gap) <= VELOCITY_TOLERANCE_MPS || high - low <= VELOCITY_TOLERANCE_MPS {
                break;
            }
            let newton = v - gap / (slope - 1.0);
            v = if slope < 1.0 && low < newton && newton < high {
                newton
            } else {
                (low + high) / 2.0
            };
        }
        moved_m / self.period_s()
    }
}
