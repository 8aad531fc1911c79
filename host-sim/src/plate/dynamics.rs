//! What the general solver keeps of each regime it meets (regimes recur every cycle): the matrix `A`,
//! the functionals it watches with their Taylor rows, the current loop's mode, and a ladder of
//! step exponentials.
//!
//! The current loop's mode is split off exactly. With `r` the eigenvector of `A` for `−2π·f_c`
//! (`r_F = 1`, `r_1 = 0`) and `φ = F − F*`, `z(t) = z_s(t) + φ(t)·r` with `φ(t) = φ(0)·e^{−2π·f_c·t}`,
//! where the slow part `z_s` keeps `F = F*` and moves with the slide's slower modes only
//! (spring, damping). A functional `g = c·z` is then `g_s + (c·r)·φ`: a slow function plus a
//! monotone exponential of constant sign. The slow part is sampled on a coarse step
//! `h_0 ≤ 1/(8ρ_s)` (`ρ_s` the slide's fastest rate), the whole on a fine step
//! `h_J = h_0/2^J ≤ min(1/(8ρ), 1/‖A‖)`.

use super::linear::{self, Matrix, State, F, ONE, V};
use super::model::{ContactEvent, Part, PlateModel, Slide};

/// Rows `c·A^k` kept per functional: the value to 23 Taylor terms and its slope.
pub const TAYLOR_ROWS: usize = 24;

/// Functionals a regime watches at most: two for the slide, two for the part, two end stops
/// and the plate's turning points.
pub const MAX_FUNCTIONALS: usize = 7;

/// Levels of the step ladder at most: the coarse step is at most `2^MAX_LEVELS` fine steps.
const MAX_LEVELS: u32 = 8;

/// What a functional watches for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Watch {
    /// A zero ends the regime.
    Event(ContactEvent),
    /// The plate's velocity, whose zeros are its turning points (sign set where it is used).
    Turn,
}

/// A functional `g = c·z` of a regime.
#[derive(Debug, Clone)]
pub struct Functional {
    pub watch: Watch,
    /// `c·A^k`, `k = 0, …, TAYLOR_ROWS − 1`: `g^(k) = rows[k]·z`.
    pub rows: [[f64; linear::N]; TAYLOR_ROWS],
    /// `c·r`, the weight of the current loop's mode in `g`.
    pub fast: f64,
}

/// The current loop's mode in a regime: `φ = F − F*` decays at `rate_per_s`.
#[derive(Debug, Clone, Copy)]
pub struct Lag {
    pub rate_per_s: f64,
    pub target_n: f64,
}

impl Lag {
    /// `φ` at the state `z`.
    pub fn phi_n(&self, z: &State) -> f64 {
        z[F] - self.target_n
    }
}

type Key = (u8, u8, u64);

/// The dynamics of one regime: fixed slide and part contact, fixed drive target.
#[derive(Debug, Clone)]
pub struct Dynamics {
    key: Key,
    pub a: Matrix,
    pub functionals: Vec<Functional>,
    /// The split-off current-loop mode, if the regime has one.
    pub lag: Option<Lag>,
    /// `e^{A·h_j}` for `h_j = h_0/2^j`, `j = 0, …, J`.
    ladder: Vec<Matrix>,
    coarse_step_s: f64,
    /// `‖A‖`.
    norm: f64,
}

impl Dynamics {
    fn new(model: &PlateModel, slide: Slide, part: Part, target_n: f64) -> Self {
        let a = model.matrix(slide, part, target_n);
        let eigenvector = model
            .lag_per_s
            .and_then(|rate_per_s| lag_eigenvector(&a, rate_per_s));
        let functional = |watch: Watch, c: [f64; linear::N]| {
            let mut rows = [[0.0; linear::N]; TAYLOR_ROWS];
            rows[0] = c;
            for k in 1..TAYLOR_ROWS {
                rows[k] = linear::derivative(&rows[k - 1], &a);
            }
            let fast = eigenvector.map_or(0.0, |r| linear::dot(&c, &r));
            Functional { watch, rows, fast }
        };
        let mut functionals: Vec<Functional> = model
            .events(slide, part, &a)
            .into_iter()
            .map(|(event, c)| functional(Watch::Event(event), c))
            .collect();
        if slide != Slide::Stuck {
            let mut c = [0.0; linear::N];
            c[V] = 1.0;
            functionals.push(functional(Watch::Turn, c));
        }
        let fine_step_s = model.fine_step_s(&a);
        // Without the split every step must be fine.
        let slow_per_s = match (model.lag_per_s, eigenvector) {
            (Some(_), None) => f64::INFINITY,
            _ => model.slow_per_s,
        };
        let longest_s = fine_step_s * f64::from(1_u32 << MAX_LEVELS);
        let coarse_s = if slow_per_s > 0.0 {
            (0.125 / slow_per_s).min(longest_s)
        } else {
            longest_s
        };
        let levels = if coarse_s > fine_step_s {
            (coarse_s / fine_step_s).log2().ceil() as u32
        } else {
            0
        };
        let coarse_step_s = coarse_s.max(fine_step_s);
        let ladder = (0..=levels)
            .map(|j| linear::exp(&a, coarse_step_s / f64::from(1_u32 << j)))
            .collect();
        Dynamics {
            key: key(slide, part, target_n),
            a,
            functionals,
            lag: model.lag_per_s.zip(eigenvector).map(|(rate_per_s, _)| Lag {
                rate_per_s,
                target_n,
            }),
            ladder,
            coarse_step_s,
            norm: linear::norm(&a),
        }
    }

    /// `J`, the finest level.
    pub fn levels(&self) -> u32 {
        self.ladder.len() as u32 - 1
    }

    /// `h_j`.
    pub fn step_s(&self, level: u32) -> f64 {
        self.coarse_step_s / f64::from(1_u32 << level)
    }

    /// `e^{A·t}·z` for `0 ≤ t ≤ h_0`: a ladder step for each binary digit of `t/h_J`, and the
    /// series for the rest.
    pub fn advance(&self, t_s: f64, z: &State) -> State {
        let levels = self.levels();
        let fine_s = self.step_s(levels);
        let steps = (t_s / fine_s).floor().min(f64::from(1_u32 << levels)) as u32;
        let mut out = *z;
        for level in 0..=levels {
            if steps & (1 << (levels - level)) != 0 {
                out = self.step(level, &out);
            }
        }
        self.advance_short(t_s - f64::from(steps) * fine_s, &out)
    }

    /// `e^{A·t}·z` for `0 ≤ t ≤ h_J` by the series.
    pub fn advance_short(&self, t_s: f64, z: &State) -> State {
        linear::exp_apply_short(&self.a, self.norm, t_s, z)
    }

    /// `e^{A·h_j}·z`.
    pub fn step(&self, level: u32, z: &State) -> State {
        linear::apply(&self.ladder[level as usize], z)
    }
}

fn key(slide: Slide, part: Part, target_n: f64) -> Key {
    let slide = match slide {
        Slide::Free => 0,
        Slide::Moving(s) if s > 0.0 => 1,
        Slide::Moving(_) => 2,
        Slide::Stuck => 3,
    };
    let part = match part {
        Part::Sliding(s) if s > 0.0 => 0,
        Part::Sliding(_) => 1,
        Part::Stuck => 2,
    };
    (slide, part, target_n.to_bits())
}

/// `r` with `A·r = −rate·r`, `r_F = 1` and `r_1 = 0`, if no other mode of `A` decays at the
/// same rate: `(A + rate·I)` restricted to the other states, solved by Gaussian elimination
/// with partial pivoting.
fn lag_eigenvector(a: &Matrix, rate_per_s: f64) -> Option<State> {
    let others: Vec<usize> = (0..linear::N).filter(|&i| i != F && i != ONE).collect();
    let n = others.len();
    let mut m: Vec<Vec<f64>> = others
        .iter()
        .map(|&i| {
            let mut row: Vec<f64> = others
                .iter()
                .map(|&j| a[i][j] + if i == j { rate_per_s } else { 0.0 })
                .collect();
            row.push(-a[i][F]);
            row
        })
        .collect();
    let scale = linear::norm(a).max(rate_per_s);
    for col in 0..n {
        let pivot = (col..n).max_by(|&p, &q| m[p][col].abs().total_cmp(&m[q][col].abs()))?;
        if m[pivot][col].abs() <= 1e-9 * scale {
            return None;
        }
        m.swap(col, pivot);
        let (upper, lower) = m.split_at_mut(col + 1);
        let pivot_row = &upper[col];
        for row in lower {
            let factor = row[col] / pivot_row[col];
            for (x, p) in row[col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= factor * p;
            }
        }
    }
    let mut r = [0.0; linear::N];
    r[F] = 1.0;
    for col in (0..n).rev() {
        let known: f64 = (col + 1..n).map(|k| m[col][k] * r[others[k]]).sum();
        r[others[col]] = (m[col][n] - known) / m[col][col];
    }
    Some(r)
}

/// The dynamics of the regimes met so far.
#[derive(Debug, Default)]
pub struct DynamicsCache {
    entries: Vec<Dynamics>,
}

impl DynamicsCache {
    const CAPACITY: usize = 64;

    /// The dynamics of `slide`, `part` and `target_n`, built on first use.
    pub fn get(
        &mut self,
        model: &PlateModel,
        slide: Slide,
        part: Part,
        target_n: f64,
    ) -> &Dynamics {
        let wanted = key(slide, part, target_n);
        let index = match self.entries.iter().position(|r| r.key == wanted) {
            Some(index) => index,
            None => {
                if self.entries.len() == Self::CAPACITY {
                    self.entries.clear();
                }
                self.entries
                    .push(Dynamics::new(model, slide, part, target_n));
                self.entries.len() - 1
            }
        };
        &self.entries[index]
    }
}
