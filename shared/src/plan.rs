//! The waveform in integer timer ticks, computed once per parameter change.
//!
//! A cycle is four segments `s0` (`+a`), `s1` (`0`), `s2` (`−a`), `s3` (`+a`) of whole ticks that
//! add up to the period `N`. Two exact integer invariants keep the plate from walking away:
//!
//! * **Velocity.** `s2 = s0 + s3`: the `+a` and `−a` tick totals are equal, so the plate is back at
//!   rest at every cycle boundary, exactly, whatever the rounding.
//! * **Displacement.** Integrating the levels over whole ticks gives the net displacement of one
//!   cycle in units of `a·tick²` as the integer `X = s0·(s0 + s1) − s3²` (the tick version of
//!   Eq. 1: `t1·t2 = (B/2)²`). Rounding generally leaves `X ≠ 0`, which would walk the plate
//!   `X·a/f²` per cycle (about a micrometre per cycle at 1 MHz). The plan therefore keeps two cycle
//!   variants close to the exact edges, one with `X ≥ 0` and one with `X ≤ 0`, and the
//!   [`Scheduler`](crate::scheduler::Scheduler) picks one per cycle by the sign of the accumulated
//!   residual (first-order error feedback).
//!
//! **Drift bound.** If the accumulated residual `E` starts in `[X₋, X₊]` it stays there: with
//! `E ≤ 0` the `X₊` variant gives `E + X₊ ∈ [X₋, X₊]`, with `E > 0` the `X₋` variant gives
//! `E + X₋ ∈ (X₋, X₊]`. The plate's position at every cycle boundary therefore stays within
//! [`TickPlan::drift_bound_m`] `= max(X₊, −X₋)·a/f²` of its start, forever.

use crate::error::{positive, Error, Quantity};
use crate::segment::SegmentKind;
use crate::waveform::Waveform;
use libm::{fabs, round, sqrt};

/// The worst work between an edge and the next preload, in instructions, rounded up: 10,930
/// measured under QEMU (`-icount shift=4`, `cargo xtask run cycles=1000`, at 50 Hz and at 100 Hz
/// with `stroke_m=0.0006`), wake-up and the `EVT` trace included, on the edge that takes a start
/// request and a new plan.
pub const EDGE_WORK_INSTRUCTIONS: f64 = 11_000.0;

/// The shortest settle segment ([`TickPlan::settle_ticks`]): long enough for the closed loop's
/// decision below the edge path under QEMU, short enough that a drive's zero offset moves the
/// plate a few µm in one.
pub const SETTLE_MIN_S: f64 = 2.5e-3;

/// How many times the worst work per edge the shortest segment must last: segments shorter than
/// this are refused ([`Error::SegmentBelowFloor`]), so a validated waveform cannot miss an edge.
pub const EDGE_WORK_MARGIN: f64 = 3.0;

/// A timer that counts at `hz` and can time segments of at least `min_segment_ticks` and at most
/// `max_segment_ticks` ticks (for example `u16::MAX` for a 16-bit auto-reload register).
///
/// The floor is the output stage's: software must preload the next segment while the current one
/// plays, so a segment shorter than the worst case of that work (with margin) could be missed. A
/// plan whose every segment is at least the floor long can never miss an edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickClock {
    pub hz: u32,
    pub min_segment_ticks: u32,
    pub max_segment_ticks: u32,
}

impl TickClock {
    /// A clock limited only by the 32-bit tick counts of the plan (no segment may be empty).
    pub const fn new(hz: u32) -> Self {
        Self {
            hz,
            min_segment_ticks: 1,
            max_segment_ticks: u32::MAX,
        }
    }

    /// The same clock with the output stage's shortest segment, `min_segment_s` rounded up to
    /// whole ticks (at least one).
    pub fn with_min_segment_s(self, min_segment_s: f64) -> Self {
        let ticks = libm::ceil(min_segment_s * f64::from(self.hz));
        Self {
            min_segment_ticks: if ticks >= 1.0 && ticks < f64::from(u32::MAX) {
                ticks as u32
            } else if ticks >= 1.0 {
                u32::MAX
            } else {
                1
            },
            ..self
        }
    }

    /// The same clock with the shortest segment of an output stage whose core takes
    /// `instruction_s` per instruction: the worst work per edge ([`EDGE_WORK_INSTRUCTIONS`]) times
    /// [`EDGE_WORK_MARGIN`].
    pub fn with_edge_work_floor(self, instruction_s: f64) -> Self {
        self.with_min_segment_s(EDGE_WORK_MARGIN * EDGE_WORK_INSTRUCTIONS * instruction_s)
    }

    pub const fn with_max_segment_ticks(self, max_segment_ticks: u32) -> Self {
        Self {
            max_segment_ticks,
            ..self
        }
    }
}

/// The four segment lengths of one cycle, in ticks, and the cycle's net displacement residual.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleTicks {
    /// `s0`, `+a`.
    pub accelerate_ticks: u32,
    /// `s1`, `0`.
    pub plateau_ticks: u32,
    /// `s2 = s0 + s3`, `−a`.
    pub reverse_ticks: u32,
    /// `s3`, `+a`.
    pub return_ticks: u32,
    /// Net displacement `X` of this cycle in units of `a·tick²` (exact).
    pub residual: i64,
}

impl CycleTicks {
    /// Length of the `index`-th segment of the cycle (0 = accelerate … 3 = return).
    pub const fn segment_ticks(&self, index: usize) -> u32 {
        match index {
            0 => self.accelerate_ticks,
            1 => self.plateau_ticks,
            2 => self.reverse_ticks,
            _ => self.return_ticks,
        }
    }

    /// The switching instants `t1`, `t2`, `t3` in ticks from the cycle start.
    pub const fn edge_ticks(&self) -> [u32; 3] {
        let t1 = self.accelerate_ticks;
        let t2 = t1 + self.plateau_ticks;
        [t1, t2, t2 + self.reverse_ticks]
    }
}

/// A waveform turned into whole ticks of one timer clock.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickPlan {
    /// The waveform the plan was made from.
    pub waveform: Waveform,
    pub clock_hz: u32,
    /// `N = round(T·f)`. The realised frequency is `f/N` ([`Self::realized_frequency_hz`]).
    pub period_ticks: u32,
    /// `[X ≥ 0 variant, X ≤ 0 variant]`; both are the same cycle when it has `X = 0`.
    pub variants: [CycleTicks; 2],
    /// Largest distance of any edge of either variant from the exact edge of the waveform at the
    /// realised period, in ticks.
    pub worst_edge_offset_ticks: f64,
    /// Bound on the plate's position error at any cycle boundary, for as long as the plan runs.
    pub drift_bound_m: f64,
}

/// Half-width of the neighbourhood of the rounded edges searched for the two variants.
const SEARCH_TICKS: i64 = 3;
/// Variants whose edges stray further than this from the exact ones are used only if no closer
/// one has the needed residual sign.
const PREFERRED_EDGE_OFFSET_TICKS: f64 = 1.5;

impl TickPlan {
    /// Plans `waveform` on `clock`, refusing segments that round to nothing or overflow the timer.
    pub fn new(waveform: &Waveform, clock: TickClock) -> Result<Self, Error> {
        positive(Quantity::ClockHz, f64::from(clock.hz))?;
        let clock_hz = f64::from(clock.hz);
        let max_ticks = clock.max_segment_ticks;
        let exact_period = waveform.period_s * clock_hz;
        // While stopped, the scheduler idles one period at a time; every other segment is shorter.
        if exact_period > f64::from(max_ticks) {
            return Err(Error::TicksOverflow {
                segment: SegmentKind::Idle,
                exact_ticks: exact_period,
                max_ticks,
            });
        }
        let period_ticks = round(exact_period) as u32;
        let n = f64::from(period_ticks);
        let d = waveform.duty;
        let root = sqrt(2.0 * d - 1.0);
        // t1 = N(d − √(2d − 1))/2 = N(1 − d)²/(2(d + √(2d − 1))), free of cancellation.
        let t1 = n * (1.0 - d) * (1.0 - d) / (2.0 * (d + root));
        let exact = ExactTicks {
            t1,
            t2: n * d - t1,
            t3: n * (1.0 + d) / 2.0,
        };
        let lengths = [
            (SegmentKind::Accelerate, exact.t1),
            (SegmentKind::Plateau, exact.t2 - exact.t1),
            (SegmentKind::Reverse, exact.t3 - exact.t2),
            (SegmentKind::Return, n - exact.t3),
        ];
        for (segment, exact_ticks) in lengths {
            if exact_ticks < 0.5 {
                return Err(Error::SegmentTooShort {
                    segment,
                    exact_ticks,
                });
            }
        }

        let mut best_non_negative: Option<Candidate> = None;
        let mut best_non_positive: Option<Candidate> = None;
        let centre_accelerate = round(exact.t1) as i64;
        let centre_return = round(n - exact.t3) as i64;
        for accelerate_offset in -SEARCH_TICKS..=SEARCH_TICKS {
            for return_offset in -SEARCH_TICKS..=SEARCH_TICKS {
                let Some(candidate) = Candidate::new(
                    i64::from(period_ticks),
                    centre_accelerate + accelerate_offset,
                    centre_return + return_offset,
                    &exact,
                ) else {
                    continue;
                };
                if candidate.cycle.residual >= 0 {
                    Candidate::keep_better(&mut best_non_negative, candidate);
                }
                if candidate.cycle.residual <= 0 {
                    Candidate::keep_better(&mut best_non_positive, candidate);
                }
            }
        }
        let (Some(up), Some(down)) = (best_non_negative, best_non_positive) else {
            let (segment, exact_ticks) = lengths.into_iter().fold(
                (SegmentKind::Accelerate, f64::INFINITY),
                |shortest, (kind, ticks)| {
                    if ticks < shortest.1 {
                        (kind, ticks)
                    } else {
                        shortest
                    }
                },
            );
            return Err(Error::SegmentTooShort {
                segment,
                exact_ticks,
            });
        };
        for variant in [&up.cycle, &down.cycle] {
            for (index, (segment, _)) in lengths.iter().enumerate() {
                let ticks = variant.segment_ticks(index);
                if ticks < clock.min_segment_ticks {
                    return Err(Error::SegmentBelowFloor {
                        segment: *segment,
                        ticks,
                        min_ticks: clock.min_segment_ticks,
                        clock_hz: clock.hz,
                    });
                }
            }
        }
        let worst_residual = up.cycle.residual.max(-down.cycle.residual);
        Ok(TickPlan {
            waveform: *waveform,
            clock_hz: clock.hz,
            period_ticks,
            variants: [up.cycle, down.cycle],
            worst_edge_offset_ticks: up.edge_offset_ticks.max(down.edge_offset_ticks),
            drift_bound_m: worst_residual as f64 * Self::residual_unit_m_for(waveform, clock.hz),
        })
    }

    /// The frequency actually produced, `f / N`.
    pub fn realized_frequency_hz(&self) -> f64 {
        f64::from(self.clock_hz) / f64::from(self.period_ticks)
    }

    /// Metres of plate displacement per unit of [`CycleTicks::residual`] at full amplitude,
    /// `a / f²`.
    pub fn residual_unit_m(&self) -> f64 {
        Self::residual_unit_m_for(&self.waveform, self.clock_hz)
    }

    fn residual_unit_m_for(waveform: &Waveform, clock_hz: u32) -> f64 {
        let clock_hz = f64::from(clock_hz);
        waveform.accel_mps2 / (clock_hz * clock_hz)
    }

    /// Worst edge offset in seconds.
    pub fn worst_edge_offset_s(&self) -> f64 {
        self.worst_edge_offset_ticks / f64::from(self.clock_hz)
    }

    /// A settle segment's ticks: the period divided by the largest whole number that leaves at
    /// least [`SETTLE_MIN_S`]: 2.5 ms at 50 Hz and at 100 Hz, a whole period where the period is
    /// shorter.
    pub fn settle_ticks(&self) -> u32 {
        let min_ticks = (SETTLE_MIN_S * f64::from(self.clock_hz)) as u32;
        let parts = (self.period_ticks / min_ticks.max(1)).max(1);
        self.period_ticks / parts
    }

    /// Converts a tick count of this plan's clock to seconds.
    pub fn ticks_to_s(&self, ticks: u64) -> f64 {
        ticks as f64 / f64::from(self.clock_hz)
    }
}

/// Exact (real-valued) edges of the waveform at the realised period, in ticks.
struct ExactTicks {
    t1: f64,
    t2: f64,
    t3: f64,
}

#[derive(Clone, Copy)]
struct Candidate {
    cycle: CycleTicks,
    edge_offset_ticks: f64,
}

impl Candidate {
    /// The cycle with `s0 = accelerate` and `s3 = return_`, if every segment is at least one tick.
    fn new(period: i64, accelerate: i64, return_: i64, exact: &ExactTicks) -> Option<Self> {
        let plateau = period - 2 * accelerate - 2 * return_;
        let reverse = accelerate + return_;
        if accelerate < 1 || plateau < 1 || return_ < 1 {
            return None;
        }
        let residual = i128::from(accelerate) * i128::from(accelerate + plateau)
            - i128::from(return_) * i128::from(return_);
        let residual = i64::try_from(residual).ok()?;
        let edge_offset_ticks = fabs(accelerate as f64 - exact.t1)
            .max(fabs((accelerate + plateau) as f64 - exact.t2))
            .max(fabs((period - return_) as f64 - exact.t3));
        Some(Candidate {
            cycle: CycleTicks {
                accelerate_ticks: accelerate as u32,
                plateau_ticks: plateau as u32,
                reverse_ticks: reverse as u32,
                return_ticks: return_ as u32,
                residual,
            },
            edge_offset_ticks,
        })
    }

    /// Ranks by: edges within the preferred offset, then smallest |residual|, then edge offset.
    fn keep_better(best: &mut Option<Candidate>, candidate: Candidate) {
        let rank = |c: &Candidate| {
            (
                c.edge_offset_ticks > PREFERRED_EDGE_OFFSET_TICKS,
                c.cycle.residual.unsigned_abs(),
            )
        };
        let better = match best {
            None => true,
            Some(current) => {
                let (new_rank, old_rank) = (rank(&candidate), rank(current));
                new_rank < old_rank
                    || (new_rank == old_rank
                        && candidate.edge_offset_ticks < current.edge_offset_ticks)
            }
        };
        if better {
            *best = Some(candidate);
        }
    }
}
