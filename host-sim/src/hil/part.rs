//! The part simulated on the recorded edges: the ideal plate driven by the levels the firmware
//! output, at their actual or planned instants, with the feed rate, the plate's drift and where
//! each halt left the plate.

use serde::Serialize;

use crate::contact::Contact;
use crate::error::SimError;
use crate::ideal::simulator::{run_segments, Criteria, CycleStats, RunOptions};
use crate::plate::{self, PlateParams, PlatePoint, PlateRun, PlateRunOptions};
use crate::segments::PlateSegment;

use super::edge::{Edge, EdgeSource, EdgeTimes};

/// Cycles averaged for the steady feed rate: the last ones at full amplitude of the final plan.
/// A change of plan decays by about `((a − μg)/(a + μg))²` per cycle (Eq. 12), so the window sits
/// at the end of the stretch.
pub const STEADY_WINDOW_CYCLES: usize = 16;

/// The part simulated on the recorded edges.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartReport {
    /// Mean part velocity over the last [`STEADY_WINDOW_CYCLES`] full-amplitude cycles of the
    /// final plan (fewer if the run had fewer).
    pub feed_rate_mps: f64,
    /// The same relative to the plate's mean velocity over those cycles: the feed rate the
    /// waveform produces, whatever the plate's drift.
    pub feed_rate_relative_mps: f64,
    /// Cycles those means are over.
    pub steady_cycles: usize,
    /// Stick fraction over the same cycles.
    pub stick_fraction: f64,
    /// Distance the part moved over the whole run.
    pub part_travel_m: f64,
    /// Peak-to-peak plate travel over the run.
    pub plate_excursion_m: f64,
    /// Plate position at the end of the run relative to its start.
    pub plate_drift_m: f64,
    /// Seconds of firmware time simulated.
    pub duration_s: f64,
    /// Every cycle (and idle period) of the run: a series for the CSV and the chart, not the
    /// summary.
    #[serde(skip)]
    pub cycles: Vec<CyclePoint>,
    /// The plate at each halt: where the output went to zero (actual edges only); the report
    /// lists them once, beside the part.
    #[serde(skip)]
    pub halts: Vec<HaltPoint>,
}

/// Where a halt left the plate: its state when the output went to zero, relative to its
/// position and rest at the start of the run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HaltPoint {
    pub tick: u64,
    pub time_s: f64,
    pub plate_position_m: f64,
    pub plate_velocity_mps: f64,
}

/// One cycle of a simulated run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CyclePoint {
    pub start_s: f64,
    pub duration_s: f64,
    /// Mean part velocity.
    pub part_velocity_mps: f64,
    /// Mean plate velocity: zero for a cycle that returns the plate to its start.
    pub plate_velocity_mps: f64,
}

/// Simulates the part on the edges of one timeline: each level holds from its edge to the next
/// edge (the last one for its planned length), at the actual or the planned instants.
pub fn simulate(edges: &[Edge], clock_hz: u32, contact: &Contact, times: EdgeTimes) -> PartReport {
    let clock_hz = f64::from(clock_hz.max(1));
    let edges: Vec<&Edge> = edges.iter().filter(|edge| edge.source.on(times)).collect();
    let segments = edge_segments(&edges, clock_hz, times);
    let options = RunOptions {
        fixed_cycles: Some(u64::MAX),
        record_cycles: true,
        ..RunOptions::converge(Criteria::periodic(0.0, 1.0))
    };
    let run = run_segments(segments.iter().copied(), contact, &options);
    let plate_m = plate_cycle_displacements_m(&segments);
    // Cycles (in order) that ran at full amplitude under the final plan.
    let final_plan = edges.last().map_or(0, |edge| edge.plan_index);
    let steady: Vec<bool> = edges
        .iter()
        .filter(|edge| edge.starts_cycle)
        .map(|edge| edge.full_amplitude && edge.plan_index == final_plan)
        .collect();
    let window: Vec<(&CycleStats, f64)> = run
        .cycle_stats
        .iter()
        .zip(plate_m.iter().copied())
        .zip(&steady)
        .filter(|(_, steady)| **steady)
        .map(|(cycle, _)| cycle)
        .collect();
    let window = &window[window.len().saturating_sub(STEADY_WINDOW_CYCLES)..];
    let window_s: f64 = window.iter().map(|(stats, _)| stats.duration_s).sum();
    let mean = |total: f64| {
        if window_s > 0.0 {
            total / window_s
        } else {
            0.0
        }
    };
    let part_m: f64 = window
        .iter()
        .map(|(stats, _)| stats.mean_velocity_mps * stats.duration_s)
        .sum();
    let plate_window_m: f64 = window.iter().map(|(_, plate_m)| plate_m).sum();
    let mut start_s = 0.0;
    let cycles = run
        .cycle_stats
        .iter()
        .zip(&plate_m)
        .map(|(stats, plate_m)| {
            let point = CyclePoint {
                start_s,
                duration_s: stats.duration_s,
                part_velocity_mps: stats.mean_velocity_mps,
                plate_velocity_mps: plate_m / stats.duration_s,
            };
            start_s += stats.duration_s;
            point
        })
        .collect();
    PartReport {
        feed_rate_mps: mean(part_m),
        feed_rate_relative_mps: mean(part_m - plate_window_m),
        steady_cycles: window.len(),
        stick_fraction: mean(
            window
                .iter()
                .map(|(stats, _)| stats.stick_fraction * stats.duration_s)
                .sum(),
        ),
        part_travel_m: run
            .cycle_stats
            .iter()
            .map(|stats| stats.mean_velocity_mps * stats.duration_s)
            .sum(),
        plate_excursion_m: run.plate_excursion_m,
        plate_drift_m: plate_m.iter().sum(),
        duration_s: segments.iter().map(|segment| segment.duration_s).sum(),
        cycles,
        halts: plate_at_halts(&edges, &segments, clock_hz),
    }
}

/// One segment per edge of `edges` (already filtered for `times`): each level holds from its
/// edge to the next one (the last for its planned length).
fn edge_segments(edges: &[&Edge], clock_hz: f64, times: EdgeTimes) -> Vec<PlateSegment> {
    let tick = |edge: &&Edge| match times {
        EdgeTimes::Actual => edge.actual_tick,
        EdgeTimes::Planned => edge.planned_tick,
    };
    edges
        .iter()
        .enumerate()
        .map(|(index, edge)| {
            let start_tick = tick(edge);
            let end_tick = edges
                .get(index + 1)
                .map_or(start_tick.saturating_add(u64::from(edge.ticks)), tick);
            PlateSegment {
                duration_s: end_tick.saturating_sub(start_tick) as f64 / clock_hz,
                accel_mps2: edge.accel_mps2,
                starts_cycle: edge.starts_cycle,
            }
        })
        .collect()
}

/// Runs the real plate `params` and its part on the edges of one timeline, from rest, averaging
/// over the last [`STEADY_WINDOW_CYCLES`] cycles (all if fewer), until the edges end or the
/// plate hits an end stop.
pub fn simulate_plate(
    edges: &[Edge],
    clock_hz: u32,
    contact: &Contact,
    times: EdgeTimes,
    params: &PlateParams,
) -> Result<PlateRun, SimError> {
    let (segments, options) = plate_segments(edges, clock_hz, times);
    plate::run(params, contact, segments, &options)
}

/// [`simulate_plate`], also recording the plate and the part through the run as
/// [`plate::trace`] does.
pub fn trace_plate(
    edges: &[Edge],
    clock_hz: u32,
    contact: &Contact,
    times: EdgeTimes,
    params: &PlateParams,
) -> Result<(PlateRun, Vec<PlatePoint>), SimError> {
    let (segments, options) = plate_segments(edges, clock_hz, times);
    plate::trace(params, contact, segments, &options)
}

/// The segments of one timeline's edges and a real plate's run over all of them.
fn plate_segments(
    edges: &[Edge],
    clock_hz: u32,
    times: EdgeTimes,
) -> (Vec<PlateSegment>, PlateRunOptions) {
    let clock_hz = f64::from(clock_hz.max(1));
    let edges: Vec<&Edge> = edges.iter().filter(|edge| edge.source.on(times)).collect();
    let segments = edge_segments(&edges, clock_hz, times);
    let cycles = (segments
        .iter()
        .filter(|segment| segment.starts_cycle)
        .count() as u64)
        .max(1);
    let options = PlateRunOptions {
        cycles,
        average_cycles: cycles.min(STEADY_WINDOW_CYCLES as u64),
    };
    (segments, options)
}

/// The plate's state where each `Zeroed` edge begins, integrating `segments` (one per edge)
/// from rest.
fn plate_at_halts(edges: &[&Edge], segments: &[PlateSegment], clock_hz: f64) -> Vec<HaltPoint> {
    let mut halts = Vec::new();
    let (mut position_m, mut velocity_mps) = (0.0, 0.0);
    for (edge, segment) in edges.iter().zip(segments) {
        if edge.source == EdgeSource::Zeroed {
            halts.push(HaltPoint {
                tick: edge.actual_tick,
                time_s: edge.actual_tick as f64 / clock_hz,
                plate_position_m: position_m,
                plate_velocity_mps: velocity_mps,
            });
        }
        let t = segment.duration_s;
        position_m += velocity_mps * t + segment.accel_mps2 * t * t / 2.0;
        velocity_mps += segment.accel_mps2 * t;
    }
    halts
}

/// The plate's displacement over each cycle of `segments`, from rest (constant acceleration per
/// segment); the velocity carried across a cycle boundary is what timing errors leave behind.
fn plate_cycle_displacements_m(segments: &[PlateSegment]) -> Vec<f64> {
    let mut cycles = Vec::new();
    let mut velocity_mps = 0.0;
    for segment in segments {
        if segment.starts_cycle || cycles.is_empty() {
            cycles.push(0.0);
        }
        let t = segment.duration_s;
        if let Some(displacement_m) = cycles.last_mut() {
            *displacement_m += velocity_mps * t + segment.accel_mps2 * t * t / 2.0;
        }
        velocity_mps += segment.accel_mps2 * t;
    }
    cycles
}
