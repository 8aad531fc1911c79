//! The settle: before the first cycle of a start, segments of a fraction of a period `h` at
//! level zero ([`SegmentKind::Settle`](crate::SegmentKind::Settle)), run in pairs, in which the
//! loop holds the plate through a bias alone and learns what a cycle's feedforward must hold
//! against before the first cycle runs: the drive's zero offset and the difference of its gains.
//!
//! **Dither.** At rest a slide's friction hides the offset. So the middle pairs shake the plate
//! at `±D` (a pair runs `b + (D' + D)/2`, then `b − D`, `D'` the pair before's), fast enough
//! that the plate moves back and forth within every pair: friction and viscous drag then cancel
//! over a pair as they do over a cycle, and what is left of the pair's mean acceleration is the
//! offset plus the gains' difference times the dither, `e = o + ε·D` with `ε = (g₊ − g₋)/2`.
//! The dither rises through several levels ([`DITHER_MPS2`]), which tell `o` from `ε` (a
//! least-squares line through every dithered measurement); each level's error is found at the
//! level below, where it moves the plate less. Through the second and the fourth level the plate
//! is held [`EXCURSION_M`] off its rest, so that a centring spring's pull `−κ·X` shows in the
//! same fit: the cycles' loop runs on that spring from the probe's first cycle.
//!
//! **Pairs.** In pair `j` (start `X_j`, length `H = 2h`) the dither's half-level entry makes the
//! plate's velocity at every pair start `−D'·h/2` above the slow part `w_j`, and moves it
//! `k_j = (D − D')·h²/4`; the slow part is a double integrator in the bias:
//! `X_{j+1} = X_j + w_j·H + (b_j + e_j)·H²/2 + k_j`, `w_{j+1} = w_j + (b_j + e_j)·H`. Three pair
//! starts measure `(e_j + e_{j−1})/2 = (X_{j+1} − 2X_j + X_{j−1} − k_j + k_{j−1})/H² −
//! (b_j + b_{j−1})/2`. The gains' difference scales a pair's swing by `ε·b` too, so that a bias
//! moved between the two pairs adds `ε·(b_j − b_{j−1})/4`: the dither's regressor carries it.
//!
//! **Direction.** Through the dither a pair's command falls by `(D' + D)/2 + D` from its first
//! half to its second, whatever the bias, and so does the plate's acceleration, fitted through
//! each half's encoder samples; an encoder that counts backwards reads the fall reversed. Pairs
//! that show it are counted (`Settle::check_direction`), so that a loop on such an encoder is
//! refused before its corrections push the plate away.
//!
//! **Loop.** A settle segment is one segment long, so the next one is made as it begins, before
//! the decision ([`Decision`](super::Decision)): at a pair's start the loop decides the next
//! pair, predicting the slow state at its start, and places both poles of the sampled double
//! integrator at [`POLE`]: `b = −ê − k₁·(X_p − x*) − k₂·w_p`, `k₁ = (1 − p)²/H²`,
//! `k₂ = (3 − 2p − p²)/(2H)`. The first pair was made before any decision and runs the
//! feedforward; the last pairs hold the plate, without dither, where the first cycle should
//! start.

use libm::fabs;

use super::cycle_loop::{LoopError, LoopLimits};

/// Both poles of the settle's loop, per pair.
pub const POLE: f64 = 0.4;

/// The least fall of the command across a dithered pair that reads the encoder's direction,
/// m/s² (`Settle::check_direction`).
pub const DIRECTION_MIN_MPS2: f64 = 30.0;

/// The share of that fall a pair must read, with the command or against it, to count.
pub const DIRECTION_SHARE: f64 = 0.5;

/// Backward pairs, with none forward, that refuse the encoder.
pub const DIRECTION_PAIRS: u16 = 2;

/// The dither levels, m/s², in turn: the upper ones above the envelope's stickiest slide
/// (15 N on 0.5 kg, 30 m/s²) with its largest offset, all within the output's linear range
/// with a bias on top.
pub const DITHER_MPS2: [f64; 4] = [25.0, 50.0, 75.0, 100.0];

/// Pairs of the settle: held where the plate rests, dithered at each level, then moved to
/// where the cycles start and held there.
const HOLD_PAIRS: u16 = 3;
const DITHER_PAIRS: u16 = 5;
const MOVE_PAIRS: u16 = 7;
/// The settle's pairs.
pub const PAIRS: u16 = HOLD_PAIRS + DITHER_MPS2.len() as u16 * DITHER_PAIRS + MOVE_PAIRS;

/// Least squares for `e = o + ε·D + (ḡ − 1)·b − c·w − F'·w/(D·h) − κ·X` through the dithered
/// measurements. What a pair's levels drive is `ḡ·b + o + ε·D` (`ḡ = (g₊ + g₋)/2`,
/// `ε = (g₊ − g₋)/2`), so the bias the loop moves is itself a regressor. Dither turns the slide's
/// Coulomb friction into a drag, the slow velocity `w` over the dither's velocity swing `D·h`,
/// and a viscous one adds `c·w`, so a plate the loop is still moving would read them as offset.
/// The mean gain and the drags are held near their plain values by a small ridge, so that a
/// plate held still reads its offset and gains' difference alone. A centring spring `κ = k/M`
/// pulls by `−κ·X` at the pairs' mean position `X`: the plate is held off its rest through two
/// of the dither levels ([`EXCURSION_M`]) so that the pull shows. What holds the plate at a
/// dither `D` is then `b = −(o + ε·D − κ·X)/ḡ`: the feedforward takes `o/ḡ` and `ε/ḡ`, the
/// cycles' loop the spring.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Fit {
    /// `AᵀA` and `Aᵀe` of the regressors `[1, D, b, w, w/(D·h), X]`.
    normal: [[f64; TERMS]; TERMS],
    right: [f64; TERMS],
    count: u16,
    /// The first and the last dither level measured.
    levels: Option<(f64, f64)>,
    /// The drive solved from the measurements so far ([`Fit::drive`]): solved once a
    /// measurement, as a settle segment's work is bounded by its length.
    solved: Option<(f64, f64, f64)>,
}

const TERMS: usize = 6;

/// The ridge on the mean gain's term (`b`, m/s²), the viscous drag's (`w`, m/s),
/// friction's (`w/(D·h)`) and the spring's (`X`, m): each about the sum of squares of a few
/// measurements of its regressor's typical spread, so that a term is fitted only once the
/// measurements move it further (2 m/s² of bias, 10 mm/s, a tenth of the swing, 0.1 mm off
/// the rest).
const RIDGE: [f64; 4] = [20.0, 1e-3, 0.1, 1e-8];

/// How far the plate is held off its rest through the second and the fourth dither level,
/// toward where the cycles start: far enough that a spring's pull shows above the sensor's
/// steps and the slide's friction, inside the start-up's bound of 1 mm.
pub const EXCURSION_M: f64 = 0.6e-3;

/// A spring softer than this (`k/M`, 1/s²: 8.7 Hz) is taken for none. Friction that the dither
/// leaves reads as up to about 2000 1/s² of spring on a bare slide over the excursion; a spring
/// this soft moves the plate by less than `(k/M)·T²/2 = 0.6` of its offset from centre over a
/// 50 Hz cycle, and the cycles' loop holds it as a disturbance until the probe finds it.
const SPRING_FLOOR_PER_S2: f64 = 3000.0;

impl Fit {
    /// A measurement `offset_mps2` at the dither `level_mps2`, its regressors
    /// `[1, D, b, w, w/(D·h), X]` in `row`.
    fn take(&mut self, level_mps2: f64, row: [f64; TERMS], offset_mps2: f64) {
        for i in 0..TERMS {
            for j in 0..TERMS {
                self.normal[i][j] += row[i] * row[j];
            }
            self.right[i] += row[i] * offset_mps2;
        }
        self.count += 1;
        let first = self.levels.map_or(level_mps2, |(first, _)| first);
        self.levels = Some((first, level_mps2));
        self.solved = self.solve();
    }

    /// `(o/ḡ, ε/ḡ, κ)`; with one dither level measured `((o + ε·D)/ḡ, 0, κ)`, what acts at
    /// that level; `None` before any.
    fn drive(&self) -> Option<(f64, f64, f64)> {
        self.solved
    }

    /// [`Fit::drive`] from the measurements.
    fn solve(&self) -> Option<(f64, f64, f64)> {
        if self.count == 0 {
            return None;
        }
        let one_level = self.levels.is_none_or(|(first, last)| first == last);
        let sprung = self.solve_without(one_level, None)?;
        if sprung.2 >= SPRING_FLOOR_PER_S2 {
            return Some(sprung);
        }
        // A spring taken for none is left out: what it took up of the offset and the gains'
        // difference goes back to them.
        self.solve_without(one_level, Some(TERMS - 1))
            .map(|(offset, slope, _)| (offset, slope, 0.0))
    }

    /// The fit without the slope where one level was measured, and without the term `left_out`.
    fn solve_without(&self, one_level: bool, left_out: Option<usize>) -> Option<(f64, f64, f64)> {
        let mut a = self.normal;
        let mut b = self.right;
        for (k, ridge) in RIDGE.iter().enumerate() {
            a[k + 2][k + 2] += ridge;
        }
        let terms = [one_level.then_some(1), left_out];
        for term in terms.into_iter().flatten() {
            for k in 0..TERMS {
                a[term][k] = 0.0;
                a[k][term] = 0.0;
            }
            a[term][term] = 1.0;
            b[term] = 0.0;
        }
        let x = solve(&mut a, &mut b)?;
        let gain = 1.0 + x[2];
        (gain > 0.5).then(|| (x[0] / gain, x[1] / gain, -x[5]))
    }
}

/// Solves `a·x = b` by elimination with partial pivoting; `None` if singular.
fn solve(a: &mut [[f64; TERMS]; TERMS], b: &mut [f64; TERMS]) -> Option<[f64; TERMS]> {
    for col in 0..TERMS {
        let pivot = (col..TERMS).max_by(|&i, &j| fabs(a[i][col]).total_cmp(&fabs(a[j][col])))?;
        if fabs(a[pivot][col]) < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..TERMS {
            let factor = a[row][col] / a[col][col];
            for k in col..TERMS {
                a[row][k] -= factor * a[col][k];
            }
            b[row] -= factor * b[col];
        }
    }
    let mut x = [0.0; TERMS];
    for row in (0..TERMS).rev() {
        let mut sum = b[row];
        for k in row + 1..TERMS {
            sum -= a[row][k] * x[k];
        }
        x[row] = sum / a[row][row];
    }
    Some(x)
}

/// The settle's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settle {
    limits: LoopLimits,
    /// The output's smallest step of a level (0: continuous): biases are rounded to it.
    level_step_mps2: f64,
    /// Boundaries seen.
    boundaries: u16,
    /// The biases of the next pair (decided at the running one's start), of the running one,
    /// of the one before and of the one before that.
    biases_mps2: [f64; 4],
    /// The starts of the running pair and of the one before.
    starts_m: [Option<f64>; 2],
    fit: Fit,
    /// Where the plate rested at the first start.
    rest_m: Option<f64>,
    /// From this pair on no dither and no move: the plate is held where it rested
    /// ([`Settle::hold`]).
    hold_from: Option<u16>,
    /// The measurements of the held pairs before the dither: the sum and the count.
    held_sum_mps2: f64,
    held: u16,
    /// The encoder's direction as the dither shows it: the acceleration fitted through the
    /// first half of the pair running, and the pairs that read forward and backward.
    first_half_mps2: Option<f64>,
    forward_pairs: u16,
    backward_pairs: u16,
}

impl Settle {
    /// A settle that has seen no start, its first pair run at `first_bias_mps2` (made before
    /// any decision).
    pub fn new(limits: LoopLimits, level_step_mps2: f64, first_bias_mps2: f64) -> Self {
        Settle {
            limits,
            level_step_mps2: if level_step_mps2.is_finite() && level_step_mps2 > 0.0 {
                level_step_mps2
            } else {
                0.0
            },
            boundaries: 0,
            biases_mps2: [first_bias_mps2; 4],
            starts_m: [None; 2],
            fit: Fit::default(),
            rest_m: None,
            hold_from: None,
            held_sum_mps2: 0.0,
            held: 0,
            first_half_mps2: None,
            forward_pairs: 0,
            backward_pairs: 0,
        }
    }

    /// The zero offset `ô` and the gains' half difference `ε̂ = (ĝ₊ − ĝ₋)/2` found so far:
    /// from the dither once it has measured both levels, before that the held pairs' mean.
    pub fn drive(&self) -> (f64, f64) {
        match self.fit.drive() {
            Some((offset, slope, _)) => (offset, slope),
            None if self.held > 0 => (self.held_sum_mps2 / f64::from(self.held), 0.0),
            None => (0.0, 0.0),
        }
    }

    /// The gains' half difference over their mean, `ε/ḡ`, where the dither has measured it (at
    /// two levels or more).
    pub fn gain_half_difference(&self) -> Option<f64> {
        let measured = self.fit.levels.is_some_and(|(first, last)| first != last);
        self.fit
            .drive()
            .filter(|_| measured)
            .map(|(_, slope, _)| slope)
    }

    /// A centring spring's `κ = k/M` found so far (0 where none shows): its pull on the plate
    /// at `X` is `−κ·X`, and [`Settle::drive`]'s offset is the one at `X = 0`.
    pub fn spring_per_s2(&self) -> f64 {
        self.fit.drive().map_or(0.0, |(_, _, spring)| spring)
    }

    /// What the held pairs before the dither measured acting on the plate, once they have: the
    /// offset less the slide's friction where the plate moved (never more than the offset).
    pub fn held_mps2(&self) -> Option<f64> {
        (self.held > 0).then(|| self.held_sum_mps2 / f64::from(self.held))
    }

    /// Ends the dither with the first pair not yet decided, and holds the plate where it
    /// rested from then on, instead of moving it: for a settle whose drive is refused, so that
    /// the plate is at rest when the refusal stops the feeder.
    pub fn hold(&mut self) {
        let decided = self.boundaries.saturating_sub(1) / 2 + 1;
        self.hold_from.get_or_insert(decided + 1);
    }

    /// The dither of pair `pair`.
    fn dither_mps2(&self, pair: u16) -> f64 {
        if self.hold_from.is_some_and(|from| pair >= from) {
            return 0.0;
        }
        pair.checked_sub(HOLD_PAIRS)
            .and_then(|k| DITHER_MPS2.get(usize::from(k / DITHER_PAIRS)))
            .copied()
            .unwrap_or(0.0)
    }

    /// Where the plate is held through pair `pair`: where it rested, [`EXCURSION_M`] off it
    /// toward `target_m` through the second and the fourth dither level, at `target_m` through
    /// the last pairs; where it rested from [`Settle::hold`] on.
    fn held_at_m(&self, pair: u16, rest_m: f64, target_m: f64) -> f64 {
        if self.hold_from.is_some() {
            return rest_m;
        }
        if pair >= PAIRS - MOVE_PAIRS {
            return target_m;
        }
        let level = pair
            .checked_sub(HOLD_PAIRS)
            .map(|k| k / DITHER_PAIRS)
            .filter(|level| level % 2 == 1);
        match level {
            Some(_) if target_m < rest_m => rest_m - EXCURSION_M,
            Some(_) => rest_m + EXCURSION_M,
            None => rest_m,
        }
    }

    /// The position the dither adds over pair `pair`: `(D − D')·h²/4`.
    fn kick_m(&self, pair: u16, h: f64) -> f64 {
        let before = pair.checked_sub(1).map_or(0.0, |j| self.dither_mps2(j));
        (self.dither_mps2(pair) - before) * h * h / 4.0
    }

    /// At the start of a settle segment of `segment_s`: `start_m` the position latched there,
    /// `ended_mps2` the acceleration fitted through the segment that just ended (where its
    /// positions gave one), `target_m` where the first cycle should start (the plate is held
    /// where it rests until the last pairs). Returns the level of the segment after the next
    /// (bias and dither).
    pub fn update(
        &mut self,
        start_m: f64,
        ended_mps2: Option<f64>,
        segment_s: f64,
        target_m: f64,
    ) -> Result<f64, LoopError> {
        if !start_m.is_finite() {
            return Err(LoopError::Sensor);
        }
        let rest_m = *self.rest_m.get_or_insert(start_m);
        let error_m = start_m - self.held_at_m(self.boundaries / 2, rest_m, target_m);
        if fabs(error_m) > self.limits.position_error_max_m {
            return Err(LoopError::Position { error_m });
        }
        let boundary = self.boundaries;
        self.boundaries = self.boundaries.saturating_add(1);
        self.check_direction(boundary, ended_mps2)?;
        let pair = boundary / 2;
        if boundary % 2 == 1 {
            // Mid-pair: the next pair's second half, decided at this pair's start.
            return Ok(self.biases_mps2[0] - self.dither_mps2(pair + 1));
        }
        if pair > 0 {
            let [next, now, before, _] = self.biases_mps2;
            self.biases_mps2 = [next, next, now, before];
        }
        let [_, now, before, earlier] = self.biases_mps2;
        let h = segment_s;
        let span = 2.0 * h;
        // The dither and the kick of the pair running (0) and of the ones before it (1, 2, 3).
        let dithers =
            [0, 1, 2, 3].map(|back| pair.checked_sub(back).map_or(0.0, |j| self.dither_mps2(j)));
        let kicks = [0, 1, 2].map(|back| pair.checked_sub(back).map_or(0.0, |j| self.kick_m(j, h)));
        let dither = |back: usize| dithers[back];
        let kick = |back: usize| kicks[back];
        match self.starts_m {
            [Some(x1), Some(x2)] => {
                let measured = (start_m - 2.0 * x1 + x2 - kick(1) + kick(2)) / (span * span)
                    - (before + earlier) / 2.0;
                // Steady dither through both pairs (no level change at their starts, where the
                // drive's mean gain would scale the dither's kick), or held before it.
                if dither(1) > 0.0 && dither(1) == dither(2) && dither(2) == dither(3) {
                    let slow_mps = (start_m - x2 - kick(1) - kick(2)) / (2.0 * span);
                    // The gains' difference also scales the pair's swing by `ε·b`: a bias that
                    // moved between the pairs kicks the plate by `ε·Δb·h²`.
                    let row = [
                        1.0,
                        dither(1) + (before - earlier) / 4.0,
                        (before + earlier) / 2.0,
                        slow_mps,
                        slow_mps / (dither(1) * h),
                        (x2 + 2.0 * x1 + start_m) / 4.0,
                    ];
                    self.fit.take(dither(1), row, measured);
                } else if pair <= HOLD_PAIRS {
                    self.take_held(measured);
                }
            }
            // The first pair started from rest.
            [Some(x1), None] => self.take_held(2.0 * (start_m - x1) / (span * span) - before),
            _ => {}
        }
        let (offset, slope) = self.drive();
        let spring = self.spring_per_s2();
        // Where the running pair (0) and the one before (1) are, as the spring pulls them.
        let positions_m = [
            start_m,
            self.starts_m[0].map_or(start_m, |x1| (x1 + start_m) / 2.0),
        ];
        let acting = |back: usize| offset + slope * dither(back) - spring * positions_m[back];
        let slow_v = match self.starts_m[0] {
            Some(x1) => (start_m - x1 - kick(1)) / span + (before + acting(1)) * span / 2.0,
            None => 0.0,
        };
        // The loop holds the slow part of the position, the dither's kicks so far taken out
        // (they sum to `D·h²/4` and to nothing once the dither has ended), so that it never
        // fights a kick.
        let predicted_x = error_m + slow_v * span + (now + acting(0)) * span * span / 2.0 + kick(0)
            - dither(0) * h * h / 4.0;
        let predicted_v = slow_v + (now + acting(0)) * span;
        let k1 = (1.0 - POLE) * (1.0 - POLE) / (span * span);
        let k2 = (3.0 - 2.0 * POLE - POLE * POLE) / (2.0 * span);
        let correction_mps2 = -k1 * predicted_x - k2 * predicted_v;
        if fabs(correction_mps2) > self.limits.correction_max_mps2 {
            return Err(LoopError::Correction { correction_mps2 });
        }
        let next_dither = self.dither_mps2(pair + 1);
        let next = self.rounded(-(offset + slope * next_dither) + correction_mps2);
        self.biases_mps2[0] = next;
        self.starts_m = [Some(start_m), self.starts_m[0]];
        Ok(next + (dither(0) + next_dither) / 2.0)
    }

    /// The encoder's direction, read passively through the dither: a dithered pair's first half
    /// commands `(D' + D)/2` more than its bias and its second `D` less, so its fitted
    /// acceleration falls by `c = (D' + D)/2 + D` from the first half to the second (bias,
    /// offset and a spring's pull the same in both). A pair that reads the fall against its
    /// command by more than [`DIRECTION_SHARE`] of it is counted backward, one that reads it with
    /// the command forward; pairs of `c` below [`DIRECTION_MIN_MPS2`] (the slide's friction and
    /// the drive's lag can hide them) are not counted. [`DIRECTION_PAIRS`] backward and none
    /// forward: the encoder counts backwards, before the loop runs the plate away on it.
    fn check_direction(&mut self, boundary: u16, ended_mps2: Option<f64>) -> Result<(), LoopError> {
        if boundary % 2 == 1 {
            self.first_half_mps2 = ended_mps2;
            return Ok(());
        }
        let (Some(pair), Some(first), Some(second)) = (
            (boundary / 2).checked_sub(1),
            self.first_half_mps2.take(),
            ended_mps2,
        ) else {
            return Ok(());
        };
        let before = pair.checked_sub(1).map_or(0.0, |j| self.dither_mps2(j));
        let commanded_mps2 = (before + self.dither_mps2(pair)) / 2.0 + self.dither_mps2(pair);
        if commanded_mps2 < DIRECTION_MIN_MPS2 {
            return Ok(());
        }
        let measured_mps2 = first - second;
        if measured_mps2 < -DIRECTION_SHARE * commanded_mps2 {
            self.backward_pairs += 1;
        } else if measured_mps2 > DIRECTION_SHARE * commanded_mps2 {
            self.forward_pairs += 1;
        }
        if self.backward_pairs >= DIRECTION_PAIRS && self.forward_pairs == 0 {
            return Err(LoopError::Backwards {
                measured_mps2,
                commanded_mps2,
            });
        }
        Ok(())
    }

    fn take_held(&mut self, measured_mps2: f64) {
        self.held_sum_mps2 += measured_mps2;
        self.held += 1;
    }

    fn rounded(&self, bias_mps2: f64) -> f64 {
        if self.level_step_mps2 > 0.0 {
            libm::round(bias_mps2 / self.level_step_mps2) * self.level_step_mps2
        } else {
            bias_mps2
        }
    }
}
