//! Exact solution of the plate's linear ODE with constant input, `z' = A·z`, where the state
//! carries a constant 1 as its last component so that every input is a column of `A`.
//!
//! `z(t) = e^{A·t}·z(0)`, with the matrix exponential by scaling and squaring: `A·t/2^s` has
//! norm ≤ ½ (the norm taken over the state columns, which govern convergence; the input column
//! is carried along, `[B b; 0 0]ⁿ = [Bⁿ Bⁿ⁻¹b; 0 0]`), its Taylor series is summed to 18 terms
//! (remainder below ½¹⁸/18! ≈ 6·10⁻²², under the unit roundoff) and squared `s` times.

/// Length of the state vector `z`.
pub const N: usize = 7;
/// Index in `z` of the plate's position `x` (m).
pub const X: usize = 0;
/// Index in `z` of the plate's velocity `v` (m/s).
pub const V: usize = 1;
/// Index in `z` of the drive's force `F` (N).
pub const F: usize = 2;
/// Index in `z` of the part's velocity (m/s).
pub const U: usize = 3;
/// Index in `z` of the part's position (m).
pub const P: usize = 4;
/// Index in `z` of `∫x dt` (m·s), for the plate's mean position.
pub const Q: usize = 5;
/// Index in `z` of the constant 1 that carries the input column.
pub const ONE: usize = 6;

pub type State = [f64; N];
pub type Matrix = [[f64; N]; N];

const TAYLOR_TERMS: usize = 18;

pub fn zero() -> Matrix {
    [[0.0; N]; N]
}

fn identity() -> Matrix {
    let mut m = zero();
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    m
}

fn multiply(a: &Matrix, b: &Matrix) -> Matrix {
    let mut c = zero();
    for i in 0..N {
        for k in 0..N {
            let a_ik = a[i][k];
            if a_ik != 0.0 {
                for j in 0..N {
                    c[i][j] += a_ik * b[k][j];
                }
            }
        }
    }
    c
}

pub fn apply(m: &Matrix, z: &State) -> State {
    let mut out = [0.0; N];
    for (o, row) in out.iter_mut().zip(m) {
        *o = dot(row, z);
    }
    out
}

pub fn dot(c: &[f64; N], z: &State) -> f64 {
    c.iter().zip(z).map(|(a, b)| a * b).sum()
}

/// `c·A`, the functional whose value is the time derivative of `c·z`.
pub fn derivative(c: &[f64; N], a: &Matrix) -> [f64; N] {
    let mut out = [0.0; N];
    for (k, row) in a.iter().enumerate() {
        for j in 0..N {
            out[j] += c[k] * row[j];
        }
    }
    out
}

/// The norm that governs the series: the largest row sum over the state columns.
pub fn norm(a: &Matrix) -> f64 {
    a.iter()
        .map(|row| row[..ONE].iter().map(|x| x.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// `e^{A·t}·z` for `‖A‖·|t| ≤ 1` (`norm_a` is `‖A‖`) by Horner's scheme on the vector,
/// `z + tA(z + tA/2(z + …))`, to the first term `(‖A‖·|t|)ⁿ/n!` below 10⁻²¹ (22 terms at
/// `‖A‖·|t| = 1`, fewer on shorter steps): a seventh of the work of [`exp`] at most.
pub fn exp_apply_short(a: &Matrix, norm_a: f64, t: f64, z: &State) -> State {
    let x = norm_a * t.abs();
    let mut terms = 0;
    let mut bound = 1.0;
    while bound >= 1e-21 && terms < 22 {
        terms += 1;
        bound *= x / terms as f64;
    }
    let mut e = *z;
    for n in (1..=terms).rev() {
        let scale = t / n as f64;
        let step = apply(a, &e);
        for ((e_i, s_i), z_i) in e.iter_mut().zip(step).zip(z) {
            *e_i = z_i + scale * s_i;
        }
    }
    e
}

/// `e^{A·t}`.
pub fn exp(a: &Matrix, t: f64) -> Matrix {
    let norm = norm(a) * t.abs();
    let squarings = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let scale = t * 2f64.powi(-squarings);
    let mut x = zero();
    for (xr, ar) in x.iter_mut().zip(a) {
        for (xe, ae) in xr.iter_mut().zip(ar) {
            *xe = ae * scale;
        }
    }
    // Horner: I + X(I + X/2(I + X/3(…))).
    let mut e = identity();
    for n in (1..=TAYLOR_TERMS).rev() {
        let mut term = multiply(&x, &e);
        for (i, row) in term.iter_mut().enumerate() {
            for value in row.iter_mut() {
                *value /= n as f64;
            }
            row[i] += 1.0;
        }
        e = term;
    }
    for _ in 0..squarings {
        e = multiply(&e, &e);
    }
    e
}
