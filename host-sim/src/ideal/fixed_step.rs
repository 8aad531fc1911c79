//! A fixed-step reference integrator of the part on the ideal plate, for validation and
//! benchmarks.
//!
//! Each step of `dt` applies the plate's mean acceleration over the step (so the plate's velocity
//! is exact at every step point) and the part's Coulomb acceleration at the step's start. When the
//! relative velocity changes sign within a step, the part sticks for the rest of the step if
//! static friction can hold it. Its error is first order in `dt`.

use crate::contact::Contact;
use crate::segments::PlateSegment;

/// The outcome of a fixed-step run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedStepResult {
    /// Mean part velocity over the last cycle.
    pub feed_rate_mps: f64,
    /// Fraction of the last cycle's steps spent stuck.
    pub stick_fraction: f64,
    pub steps_per_cycle: u64,
}

/// Integrates `cycles` repetitions of `cycle` (one waveform period of segments) with
/// `steps_per_cycle` equal steps, from a part at rest on the plate at rest.
pub fn run_fixed_step(
    cycle: &[PlateSegment],
    contact: &Contact,
    steps_per_cycle: u64,
    cycles: u64,
) -> FixedStepResult {
    let period_s: f64 = cycle.iter().map(|segment| segment.duration_s).sum();
    let steps_per_cycle = steps_per_cycle.max(1);
    let dt = period_s / steps_per_cycle as f64;
    let mu_g = contact.kinetic_accel_mps2();
    let hold = contact.static_accel_mps2();
    let force = contact.force_accel_mps2();
    // Mean plate acceleration of every step of a cycle, computed once.
    let step_accel = mean_accel_per_step(cycle, dt, steps_per_cycle);

    let (mut plate, mut part) = (0.0_f64, 0.0_f64);
    let mut stuck = true;
    let mut displacement = 0.0;
    let mut stuck_steps = 0_u64;
    for _ in 0..cycles {
        displacement = 0.0;
        stuck_steps = 0;
        for &accel in &step_accel {
            let plate_next = plate + accel * dt;
            let need = accel - force;
            let part_next = if stuck && need.abs() <= hold {
                plate_next
            } else {
                let behind = if stuck { need > 0.0 } else { part < plate };
                let part_accel = if behind { mu_g + force } else { -mu_g + force };
                let trial = part + part_accel * dt;
                let crossed = (trial < plate_next) != behind;
                if crossed && need.abs() <= hold {
                    plate_next
                } else {
                    trial
                }
            };
            stuck = part_next == plate_next;
            stuck_steps += u64::from(stuck);
            displacement += 0.5 * (part + part_next) * dt;
            plate = plate_next;
            part = part_next;
        }
    }
    FixedStepResult {
        feed_rate_mps: displacement / period_s,
        stick_fraction: stuck_steps as f64 / steps_per_cycle as f64,
        steps_per_cycle,
    }
}

/// The mean of the piecewise-constant plate acceleration over each of `steps` steps of `dt`.
fn mean_accel_per_step(cycle: &[PlateSegment], dt: f64, steps: u64) -> Vec<f64> {
    let mut edges = Vec::with_capacity(cycle.len());
    let mut end_s = 0.0;
    for segment in cycle {
        end_s += segment.duration_s;
        edges.push((end_s, segment.accel_mps2));
    }
    let mut accel = Vec::with_capacity(steps as usize);
    let mut index = 0;
    for step in 0..steps {
        let (from, to) = (step as f64 * dt, (step + 1) as f64 * dt);
        let mut t = from;
        let mut impulse = 0.0;
        while t < to && index < edges.len() {
            let (edge_s, level) = edges[index];
            let until = edge_s.min(to);
            impulse += level * (until - t);
            t = until;
            if edge_s <= to {
                index += 1;
            }
        }
        accel.push(impulse / dt);
    }
    accel
}
