//! The fitted motion's velocity at each latch, from which the refit takes the friction's signs
//! again instead of from the latches' differences.

use super::fit::{MAX_LATCHES, UNKNOWNS};
use super::lag::lagged_rows;
use super::latched::{latched_velocity, motion_rows, Latch};
use crate::closed_loop::shape::CommandSegment;

/// The velocity of the motion `theta` describes (at a lag of `lag_s`) at each latch.
pub(super) fn fitted_velocity(
    probe: &[CommandSegment],
    latches: &[Latch],
    theta: &[f64; UNKNOWNS],
    lag_s: f64,
) -> [f64; MAX_LATCHES] {
    let [_, v0, e, gain_positive, gain_negative, friction, viscous, spring] = *theta;
    let mut velocity = [v0; MAX_LATCHES];
    lagged_rows(probe, latches, lag_s, |i, _, [p, n, e1]| {
        velocity[i] += gain_positive * p + gain_negative * n + e * e1;
    });
    motion_rows(
        latches,
        |i| latched_velocity(latches, i),
        |i, _, [c, x, s]| velocity[i] += friction * c + viscous * x + spring * s,
    );
    velocity
}
