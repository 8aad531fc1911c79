//! The positions latched during the probe ([`Latch`]) and the regressors the latched motion
//! gives: slide friction, viscous friction and a centring spring.

use crate::closed_loop::shape::sign;

/// A plate position read at a time since the probe started.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Latch {
    pub t_s: f64,
    pub position_m: f64,
}

/// The regressors at each latch from the latched motion: `C`, the double integral of the sign
/// of the velocity (Coulomb friction), `X`, the integral of the displacement from the first
/// latch (viscous friction and the spring's damping), and `S`, the double integral of the
/// position (a centring spring), each by trapezoids on the latches, with their rates. The
/// velocity at each latch is `velocity(i)`; where it changes sign between two latches, it does
/// so where its linear interpolation does.
pub(super) fn motion_rows(
    latches: &[Latch],
    velocity: impl Fn(usize) -> f64,
    mut each: impl FnMut(usize, [f64; 3], [f64; 3]),
) {
    let n = latches.len();
    let (mut c1, mut c, mut x) = (0.0, 0.0, 0.0);
    let (mut s1, mut spring) = (0.0, 0.0);
    let integrate = |sign: f64, s: f64, c1: &mut f64, c: &mut f64| {
        *c += *c1 * s + sign * s * s / 2.0;
        *c1 += sign * s;
    };
    let first_m = latches[0].position_m;
    each(0, [0.0; 3], [0.0; 3]);
    for i in 0..n - 1 {
        let (a, b) = (latches[i], latches[i + 1]);
        let s = b.t_s - a.t_s;
        let (va, vb) = (velocity(i), velocity(i + 1));
        if sign(va) * sign(vb) < 0.0 {
            let first = s * va / (va - vb);
            integrate(sign(va), first, &mut c1, &mut c);
            integrate(sign(vb), s - first, &mut c1, &mut c);
        } else {
            integrate(sign(va + vb), s, &mut c1, &mut c);
        }
        x += s * ((a.position_m - first_m) + (b.position_m - first_m)) / 2.0;
        spring += s1 * s + s * s * (2.0 * a.position_m + b.position_m) / 6.0;
        s1 += s * (a.position_m + b.position_m) / 2.0;
        each(i + 1, [c, x, spring], [c1, b.position_m - first_m, s1]);
    }
}

/// The velocity at latch `i` from the central difference of its neighbours.
pub(super) fn latched_velocity(latches: &[Latch], i: usize) -> f64 {
    let (a, b) = (
        latches[i.saturating_sub(1)],
        latches[(i + 1).min(latches.len() - 1)],
    );
    (b.position_m - a.position_m) / (b.t_s - a.t_s)
}
