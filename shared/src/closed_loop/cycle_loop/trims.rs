//! A cycle's levels relative to the plan's ([`Trims`]) and its stroke as latched ([`Stroke`]).

use crate::closed_loop::shape::CycleShape;
use crate::scheduler::CYCLE;

/// The levels of one cycle relative to the plan's.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Trims {
    /// Factor on the `+a` level.
    pub positive: f64,
    /// Factor on the `−a` level.
    pub negative: f64,
    /// Acceleration added to every level.
    pub bias_mps2: f64,
    /// Acceleration added to the segment in each place of the cycle
    /// ([`SegmentKind::place`](crate::SegmentKind::place)): the slide's forces fed forward, and
    /// what rounding each level to the output's step adds.
    pub segments_mps2: [f64; 4],
}

impl Trims {
    /// The plan's levels unchanged.
    pub const NONE: Trims = Trims {
        positive: 1.0,
        negative: 1.0,
        bias_mps2: 0.0,
        segments_mps2: [0.0; 4],
    };

    /// The commanded levels of a cycle whose `±a` levels are planned at `peak_mps2`, each
    /// segment in its place ([`CYCLE`]).
    pub fn cycle_levels(&self, peak_mps2: f64) -> [f64; 4] {
        core::array::from_fn(|place| {
            self.level(place, f64::from(CYCLE[place].1.sign()) * peak_mps2)
        })
    }

    /// The commanded acceleration for a planned one, in the segment at `place` of its cycle.
    pub fn level(&self, place: usize, planned_mps2: f64) -> f64 {
        let scale = if planned_mps2 > 0.0 {
            self.positive
        } else {
            self.negative
        };
        planned_mps2 * scale
            + self.bias_mps2
            + self.segments_mps2.get(place).copied().unwrap_or(0.0)
    }
}

/// A cycle's stroke: latched from its start tick to its turning tick, and planned.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stroke {
    pub measured_m: f64,
    pub planned_m: f64,
}

impl Stroke {
    /// The stroke of a cycle of plan `shape` from the positions latched at its start, at its
    /// turning tick and at the next cycle's start: the turning position less the straight line
    /// between the two starts, so that a plate drifting at constant velocity reads the stroke
    /// it would have at rest.
    pub fn latched(start_m: f64, turn_m: f64, next_start_m: f64, shape: &CycleShape) -> Stroke {
        let drift_m = (next_start_m - start_m) * shape.turn_s / shape.period_s;
        Stroke {
            measured_m: turn_m - start_m - drift_m,
            planned_m: shape.latched_stroke_m,
        }
    }
}
