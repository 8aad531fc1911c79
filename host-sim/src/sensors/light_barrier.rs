//! Part-passing light barrier at a point of the track: blocked while a part's front is at or past
//! it, clear while the front is before it.
//!
//! The part's position is scanned at the given sample times; where the state differs between two
//! samples, the edge time is found by bisection to adjacent floats (the first float at which the
//! new state holds). Two crossings between the same two samples cancel and go unseen: the sample
//! times must resolve the part's motion. A part known only at samples is a [`SampledPart`],
//! linear between them; scanned at its own sample times, its edges are exact.

use serde::Deserialize;

use super::{check_motion, check_time, check_value, PartMotion};
use crate::error::SimError;

const SENSOR: &str = "light_barrier";

/// Where the barrier is and how long a clearance must last to count.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightBarrierConfig {
    /// Position of the beam along the track in m.
    pub position_m: f64,
    /// A clearance shorter than this, in s, is ignored: the blocked spans on either side of it
    /// merge (0 to report every edge).
    #[serde(default)]
    pub min_gap_s: f64,
}

impl LightBarrierConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        check_value(SENSOR, "position_m", self.position_m, false)?;
        if !(self.min_gap_s.is_finite() && self.min_gap_s >= 0.0) {
            return Err(SimError::SensorValue {
                sensor: SENSOR,
                key: "min_gap_s",
                value: self.min_gap_s,
                allowed: "finite and not negative",
            });
        }
        Ok(())
    }
}

/// A change of the barrier's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarrierEdge {
    /// The first time, in s, at which the new state holds.
    pub t_s: f64,
    /// Blocked from here on (the part's front reached the beam); otherwise clear (it went back).
    pub rising: bool,
}

/// A light barrier.
#[derive(Debug, Clone)]
pub struct LightBarrier {
    config: LightBarrierConfig,
}

impl LightBarrier {
    pub fn new(config: LightBarrierConfig) -> Result<Self, SimError> {
        config.validate()?;
        Ok(LightBarrier { config })
    }

    /// The barrier's edges while `part` moves, scanned at the increasing `sample_times_s`; the
    /// state at the first sample is the starting state and makes no edge.
    pub fn edges(
        &self,
        part: &impl PartMotion,
        sample_times_s: &[f64],
    ) -> Result<Vec<BarrierEdge>, SimError> {
        let mut raw = Vec::new();
        let mut previous: Option<(f64, bool)> = None;
        for &t_s in sample_times_s {
            check_time(SENSOR, t_s, previous.map(|(t, _)| t))?;
            let blocked = self.blocked(part, t_s)?;
            if let Some((before_s, was_blocked)) = previous {
                if blocked != was_blocked {
                    raw.push(BarrierEdge {
                        t_s: self.bisect(part, before_s, t_s, blocked)?,
                        rising: blocked,
                    });
                }
            }
            previous = Some((t_s, blocked));
        }
        Ok(self.debounce(raw))
    }

    /// The times the part's front reached the beam (the rising edges).
    pub fn rising_edges(
        &self,
        part: &impl PartMotion,
        sample_times_s: &[f64],
    ) -> Result<Vec<f64>, SimError> {
        let edges = self.edges(part, sample_times_s)?;
        Ok(edges.iter().filter(|e| e.rising).map(|e| e.t_s).collect())
    }

    fn blocked(&self, part: &impl PartMotion, t_s: f64) -> Result<bool, SimError> {
        Ok(check_motion(SENSOR, t_s, part.position_m(t_s))? >= self.config.position_m)
    }

    /// The first float in (lo, hi] at which the state is `blocked_at_hi`, given the other state
    /// at `lo`.
    fn bisect(
        &self,
        part: &impl PartMotion,
        mut lo_s: f64,
        mut hi_s: f64,
        blocked_at_hi: bool,
    ) -> Result<f64, SimError> {
        loop {
            let mid_s = lo_s + (hi_s - lo_s) / 2.0;
            if mid_s <= lo_s || mid_s >= hi_s {
                return Ok(hi_s);
            }
            if self.blocked(part, mid_s)? == blocked_at_hi {
                hi_s = mid_s;
            } else {
                lo_s = mid_s;
            }
        }
    }

    /// Drops every clearance shorter than `min_gap_s` (its falling edge and the rising edge that
    /// ends it).
    fn debounce(&self, raw: Vec<BarrierEdge>) -> Vec<BarrierEdge> {
        let mut edges: Vec<BarrierEdge> = Vec::with_capacity(raw.len());
        for edge in raw {
            match edges.last() {
                Some(last)
                    if edge.rising
                        && !last.rising
                        && edge.t_s - last.t_s < self.config.min_gap_s =>
                {
                    edges.pop();
                }
                _ => edges.push(edge),
            }
        }
        edges
    }
}

/// A part trajectory known at sample times, linear between them and held beyond the ends.
#[derive(Debug, Clone, PartialEq)]
pub struct SampledPart {
    times_s: Vec<f64>,
    positions_m: Vec<f64>,
}

impl SampledPart {
    /// At least one sample, as many positions as times, all finite, times increasing.
    pub fn new(times_s: Vec<f64>, positions_m: Vec<f64>) -> Result<Self, SimError> {
        if times_s.is_empty() || times_s.len() != positions_m.len() {
            return Err(SimError::BadRange {
                what: "a sampled part needs at least one sample and as many positions as times",
            });
        }
        let mut previous = None;
        for (&t_s, &x_m) in times_s.iter().zip(&positions_m) {
            check_time(SENSOR, t_s, previous)?;
            check_motion(SENSOR, t_s, x_m)?;
            previous = Some(t_s);
        }
        Ok(SampledPart {
            times_s,
            positions_m,
        })
    }

    /// The sample times, to scan the part at with [`LightBarrier::edges`].
    pub fn times_s(&self) -> &[f64] {
        &self.times_s
    }
}

impl PartMotion for SampledPart {
    fn position_m(&self, t_s: f64) -> f64 {
        let after = self.times_s.partition_point(|&sample_s| sample_s <= t_s);
        if after == 0 {
            return self.positions_m[0];
        }
        if after == self.times_s.len() {
            return self.positions_m[after - 1];
        }
        let (t0_s, t1_s) = (self.times_s[after - 1], self.times_s[after]);
        let (x0_m, x1_m) = (self.positions_m[after - 1], self.positions_m[after]);
        x0_m + (x1_m - x0_m) * ((t_s - t0_s) / (t1_s - t0_s))
    }
}
