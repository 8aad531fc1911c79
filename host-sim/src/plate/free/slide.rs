//! The free slide's constants: the current loop's mode split off, and the slow part's Taylor
//! series from three basis series, with the tables its sums use.

use crate::plate::linear::{F, V, X};
use crate::plate::model::{PlateModel, Slide};

/// Taylor coefficients summed for the slow part over a chunk of at most `1/ω`.
pub const TERMS: usize = 22;

/// The last Taylor term summed is below this, relative to the slow part's scale.
pub const TAIL: f64 = f64::EPSILON / 16.0;

pub type Poly = [f64; TERMS];

/// `n·(n − 1)·…·(n − d + 1)` for `d ≤ 3`, `n < TERMS`: the weight of `X_n` in the Taylor
/// coefficient of `τ^(n−d)` in `X^(d)`.
pub const FALLING: [[f64; TERMS]; 4] = {
    let mut out = [[0.0; TERMS]; 4];
    let mut n = 0;
    while n < TERMS {
        let mut d = 0;
        let mut weight = 1.0;
        while d < 4 {
            out[d][n] = weight;
            weight *= n as f64 - d as f64;
            d += 1;
        }
        n += 1;
    }
    out
};

/// `1/n` for `n < TERMS + 1` (`1/0` left at 0).
pub const INVERSE: [f64; TERMS + 1] = {
    let mut out = [0.0; TERMS + 1];
    let mut n = 1;
    while n <= TERMS {
        out[n] = 1.0 / n as f64;
        n += 1;
    }
    out
};

/// The plate on a free slide and its part: a [`PlateModel`] with what the scalar solution adds.
#[derive(Debug, Clone, Copy)]
pub struct FreeSlide {
    pub model: PlateModel,
    /// `ρ`, 0 without a current loop.
    pub lag_per_s: f64,
    /// `r_x`: the plate's position per newton of `φ` in the current loop's mode.
    pub mode_m_per_n: f64,
    /// Taylor coefficients of `X` from `X(0) = 1`, from `X′(0) = 1` and for `F* = 1`, the
    /// others 0: `X` is their sum weighted by its start and the target.
    pub basis: [Poly; 3],
    pub longest_chunk_s: f64,
    /// `reach_limits[n]`: the reach `ω·L` from which `n` terms are too few, `(tol·(n−1)!)^{1/(n−1)}`
    /// with `tol` = [`TAIL`] (`n ≥ 4`).
    pub reach_limits: [f64; TERMS],
}

impl FreeSlide {
    /// The free slide of `model`; `None` if the slide has Coulomb friction, or if the current
    /// loop's rate is one of the slide's own (the mode cannot be split off).
    pub fn new(model: &PlateModel) -> Option<FreeSlide> {
        if model.params.coulomb_friction_n != 0.0 {
            return None;
        }
        // The plate's equation, `X″ = a_x·X + a_v·X′ + a_F·F`, as the model has it.
        let row = model.plate_accel_row(Slide::Free);
        let (a_x, a_v, a_f) = (row[X], row[V], row[F]);
        let (lag_per_s, mode_m_per_n) = match model.lag_per_s {
            Some(rho) => {
                // `r_x·(ρ² + a_v·ρ − a_x) = a_F`: zero where `−ρ` is one of the slide's rates.
                let stiffness = rho * rho + a_v * rho - a_x;
                let scale = rho * rho + a_v.abs() * rho + a_x.abs();
                if stiffness.abs() <= 1e-9 * scale {
                    return None;
                }
                (rho, a_f / stiffness)
            }
            None => (0.0, 0.0),
        };
        let series = |x0: f64, v0: f64, force_n: f64| {
            let mut x = [0.0; TERMS];
            x[0] = x0;
            x[1] = v0;
            x[2] = 0.5 * (a_x * x0 + a_v * v0 + a_f * force_n);
            for n in 1..TERMS - 2 {
                x[n + 2] = (a_x * x[n] + a_v * (n + 1) as f64 * x[n + 1])
                    * INVERSE[n + 1]
                    * INVERSE[n + 2];
            }
            x
        };
        Some(FreeSlide {
            model: *model,
            basis: [
                series(1.0, 0.0, 0.0),
                series(0.0, 1.0, 0.0),
                series(0.0, 0.0, 1.0),
            ],
            lag_per_s,
            mode_m_per_n,
            longest_chunk_s: if model.slow_per_s > 0.0 {
                1.0 / model.slow_per_s
            } else {
                f64::INFINITY
            },
            reach_limits: core::array::from_fn(|n| {
                let below = n.max(2) as i32 - 1;
                let factorial: f64 = (1..=below).map(f64::from).product();
                (TAIL * factorial).powf(1.0 / f64::from(below))
            }),
        })
    }
}
