//! The drive's current loop as a first-order lag: the lagged command's regressors at each
//! latch, carried exactly across each segment.

use libm::fabs;

use super::latched::Latch;
use crate::closed_loop::shape::CommandSegment;

/// Intervals between latches (quotients of ticks) that differ by less than this share are one:
/// the step taken for the one stands for the other, a time error far below a tick.
const SAME_INTERVAL: f64 = 1e-12;

/// A first-order lag of `τ` on a piecewise-constant signal, its output `y` and the first and
/// second integrals of `y`, carried exactly across each piece.
#[derive(Clone, Copy, Default)]
struct Lagged {
    y: f64,
    once: f64,
    twice: f64,
}

/// What a first-order lag of `τ` does over `s`: the decay of the distance to the input, and
/// the first and second integrals of the approach. One exponential for every lagged signal
/// over the same stretch.
#[derive(Clone, Copy)]
struct LagStep {
    s: f64,
    decay: f64,
    rise: f64,
    rise_twice: f64,
}

impl LagStep {
    fn new(s: f64, lag_s: f64) -> Self {
        let (decay, rise, rise_twice) = if lag_s > 0.0 {
            let e = libm::exp(-s / lag_s);
            (e, lag_s * (1.0 - e), lag_s * (s - lag_s * (1.0 - e)))
        } else {
            (0.0, 0.0, 0.0)
        };
        LagStep {
            s,
            decay,
            rise,
            rise_twice,
        }
    }
}

impl Lagged {
    /// After `step` of input `c`.
    fn advance(self, c: f64, step: &LagStep) -> Lagged {
        let d = self.y - c;
        let s = step.s;
        Lagged {
            y: c + d * step.decay,
            once: self.once + c * s + d * step.rise,
            twice: self.twice + self.once * s + c * s * s / 2.0 + d * step.rise_twice,
        }
    }
}

/// The lagged regressors `P, N, E` at each latch, for one `τ`, and their first integrals
/// (their rates), passed to `each` in order. The lag is carried from latch to latch, across
/// every segment's end between them: latches a fixed interval apart inside a segment share one
/// step, so the exponential is taken at segment ends and where the interval changes only.
pub(super) fn lagged_rows(
    probe: &[CommandSegment],
    latches: &[Latch],
    lag_s: f64,
    mut each: impl FnMut(usize, [f64; 3], [f64; 3]),
) {
    let mut index = 0;
    let mut end_s = probe.first().map_or(0.0, |s| s.duration_s);
    let mut at_s = 0.0;
    // The drive is on, at zero command, before the probe: the current loop has long settled on
    // the offset, while the command's parts start from zero.
    let risen = Lagged {
        y: 1.0,
        ..Lagged::default()
    };
    let mut lagged = [Lagged::default(), Lagged::default(), risen];
    let inputs = |u: f64| [u.max(0.0), u.min(0.0), 1.0];
    let advance = |lagged: &mut [Lagged; 3], index: usize, step: &LagStep| {
        let u = inputs(probe[index].accel_mps2);
        for (l, c) in lagged.iter_mut().zip(u) {
            *l = l.advance(c, step);
        }
    };
    let mut interval: Option<LagStep> = None;
    for (i, latch) in latches.iter().enumerate() {
        while index + 1 < probe.len() && latch.t_s > end_s {
            advance(&mut lagged, index, &LagStep::new(end_s - at_s, lag_s));
            at_s = end_s;
            index += 1;
            end_s += probe[index].duration_s;
        }
        let s = latch.t_s - at_s;
        let step = match interval {
            Some(step) if fabs(step.s - s) <= SAME_INTERVAL * s => step,
            _ => LagStep::new(s, lag_s),
        };
        interval = Some(step);
        advance(&mut lagged, index, &step);
        at_s = latch.t_s;
        let [p, n, e] = lagged;
        each(i, [p.twice, n.twice, e.twice], [p.once, n.once, e.once]);
    }
}
