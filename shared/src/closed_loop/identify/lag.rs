//! The drive's current loop as a first-order lag: the lagged command's regressors at each
//! latch, carried exactly across each segment.

use super::latched::Latch;
use crate::closed_loop::shape::CommandSegment;

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
/// (their rates), passed to `each` in order.
pub(super) fn lagged_rows(
    probe: &[CommandSegment],
    latches: &[Latch],
    lag_s: f64,
    mut each: impl FnMut(usize, [f64; 3], [f64; 3]),
) {
    let mut index = 0;
    let mut start_s = 0.0;
    // The drive is on, at zero command, before the probe: the current loop has long settled on
    // the offset, while the command's parts start from zero.
    let risen = Lagged {
        y: 1.0,
        ..Lagged::default()
    };
    let mut at_start = [Lagged::default(), Lagged::default(), risen];
    let inputs = |u: f64| [u.max(0.0), u.min(0.0), 1.0];
    for (i, latch) in latches.iter().enumerate() {
        while index + 1 < probe.len() && latch.t_s > start_s + probe[index].duration_s {
            let segment = probe[index];
            let u = inputs(segment.accel_mps2);
            let step = LagStep::new(segment.duration_s, lag_s);
            for (l, c) in at_start.iter_mut().zip(u) {
                *l = l.advance(c, &step);
            }
            start_s += segment.duration_s;
            index += 1;
        }
        let u = inputs(probe[index].accel_mps2);
        let step = LagStep::new(latch.t_s - start_s, lag_s);
        let [p, n, e] = [0, 1, 2].map(|k| at_start[k].advance(u[k], &step));
        each(i, [p.twice, n.twice, e.twice], [p.once, n.once, e.once]);
    }
}
