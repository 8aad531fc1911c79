//! The recorded motion of a real plate and its part, exact at any instant: each piece between
//! events is `z(t) = e^{A·(t − t₀)}·z(t₀)`. Sensors read the plate through it.

use crate::sensors::{PartMotion, PlateMotion};

use super::linear::{self, Matrix, State, P, V, X};

/// One regime's stretch of motion.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    pub start_s: f64,
    pub end_s: f64,
    /// `A` of the regime.
    pub a: Matrix,
    /// The state at `start_s`.
    pub z: State,
}

/// The motion of a run, piece by piece in time order. Before the first piece it is the start,
/// after the last one the end (held).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trajectory {
    pieces: Vec<Piece>,
}

impl Trajectory {
    pub fn new(pieces: Vec<Piece>) -> Self {
        Trajectory { pieces }
    }

    /// The state and `A` at `t_s` (`None` for an empty trajectory).
    fn state(&self, t_s: f64) -> Option<(State, &Matrix)> {
        let index = self
            .pieces
            .partition_point(|piece| piece.end_s < t_s)
            .min(self.pieces.len().checked_sub(1)?);
        let piece = &self.pieces[index];
        let dt_s = (t_s.min(piece.end_s) - piece.start_s).max(0.0);
        Some((
            linear::apply(&linear::exp(&piece.a, dt_s), &piece.z),
            &piece.a,
        ))
    }
}

impl PlateMotion for Trajectory {
    fn position_m(&self, t_s: f64) -> f64 {
        self.state(t_s).map_or(0.0, |(z, _)| z[X])
    }

    fn velocity_mps(&self, t_s: f64) -> f64 {
        self.state(t_s).map_or(0.0, |(z, _)| z[V])
    }

    fn accel_mps2(&self, t_s: f64) -> f64 {
        self.state(t_s).map_or(0.0, |(z, a)| linear::dot(&a[V], &z))
    }
}

/// The part's displacement along the track since the start.
impl PartMotion for Trajectory {
    fn position_m(&self, t_s: f64) -> f64 {
        self.state(t_s).map_or(0.0, |(z, _)| z[P])
    }
}
