//! Identification at start-up: the drive's ± gains and zero offset from plate positions read
//! during a few low-amplitude probe cycles.
//!
//! The drive's force follows its target through the current loop, a first-order lag `τ`, so
//! from the probe's start the plate moves as
//! `x(t) = x₀ + v₀·t + e·E(t) + g₊·P(t) + g₋·N(t) − (F_c/M)·C(t) − (b/M)·X(t)`:
//! `P`, `N` and `E` the double integrals of the lagged positive part of the command, its negative
//! part and of 1 (the zero offset `e` goes through the lag too, settled before the probe: the
//! drive is on at zero command first), `C` the double integral of the
//! sign of the plate's velocity (slide friction `F_c`) and `X` the integral of its displacement
//! (viscous friction `b`), both taken from the latched positions. For a given `τ` the seven
//! unknowns enter linearly and are fitted by least squares; `τ` is the one that leaves the least
//! residual (golden-section search), the fit at it the result.

use libm::{fabs, sqrt};

use super::envelope::{Cause, ENVELOPE};
use super::shape::{sign, CommandSegment};
use crate::number::Significant;

/// A plate position read at a time since the probe started.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Latch {
    pub t_s: f64,
    pub position_m: f64,
}

/// What a probe found.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Identified {
    /// Gain on a positive command (1 is ideal).
    pub gain_positive: f64,
    /// Gain on a negative command (1 is ideal).
    pub gain_negative: f64,
    /// Constant acceleration at zero command.
    pub offset_mps2: f64,
    /// The current loop's lag `τ`.
    pub lag_s: f64,
    /// Slide friction as a deceleration `F_c/M`.
    pub coulomb_mps2: f64,
    /// Viscous friction (and a spring's damping) as a rate `b/M`.
    pub viscous_per_s: f64,
    /// A centring spring's stiffness as `k/M`, the square of its natural angular frequency.
    pub spring_per_s2: f64,
    /// Root-mean-square difference between the fitted and the latched positions.
    pub residual_m: f64,
}

impl Identified {
    /// The drive as planned: gains 1, no offset, no lag, no friction.
    pub const NOMINAL: Identified = Identified {
        gain_positive: 1.0,
        gain_negative: 1.0,
        offset_mps2: 0.0,
        lag_s: 0.0,
        coulomb_mps2: 0.0,
        viscous_per_s: 0.0,
        spring_per_s2: 0.0,
        residual_m: 0.0,
    };
}

/// The ranges an identification must fall in for the feeder to run.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IdentifyLimits {
    /// Each gain within `[gain_min, gain_max]`.
    pub gain_min: f64,
    pub gain_max: f64,
    /// `|e|` at most this.
    pub offset_max_mps2: f64,
    /// The plate must move at least this far from its first position.
    pub min_excursion_m: f64,
    /// A centring spring's `k/M` at most this.
    pub spring_max_per_s2: f64,
}

impl IdentifyLimits {
    /// The envelope's gains and offset ([`super::Envelope::identified_gains`],
    /// [`super::Envelope::offset_max_mps2`]), a motion of at least 20 `resolution_m`, and a spring
    /// the cycle-rate loop holds at a period of `period_s` ([`spring_max_per_s2`]).
    pub fn for_probe(resolution_m: f64, period_s: f64) -> Self {
        let (gain_min, gain_max) = ENVELOPE.identified_gains();
        IdentifyLimits {
            gain_min,
            gain_max,
            offset_max_mps2: ENVELOPE.offset_max_mps2(),
            min_excursion_m: 20.0 * resolution_m,
            spring_max_per_s2: spring_max_per_s2(period_s),
        }
    }
}

/// The stiffest spring (`k/M`) the cycle-rate loop holds at a period of `period_s`: one whose
/// pull over a cycle, `(k/M)·T²/2` of the plate's offset from centre, is at most a tenth of it.
/// The loop's per-cycle model is a free mass; a stiffer mount turns the plate back within the
/// cycle, which that model does not describe.
pub fn spring_max_per_s2(period_s: f64) -> f64 {
    0.1 * 2.0 / (period_s * period_s)
}

/// Why an identification was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum IdentifyError {
    /// Fewer latches than the fit has unknowns, or a latch outside the probe or out of order.
    Latches,
    /// The command has no positive or no negative part: its gain cannot be told.
    Probe,
    /// The plate did not move: motor disconnected, driver disabled or a sensor that is stuck.
    NoMotion { excursion_m: f64 },
    /// The latches do not tell the unknowns apart.
    Singular,
    /// A gain outside its range; a negative one means the motor or the sensor is wired backwards.
    Gain { positive: bool, gain: f64 },
    /// The zero offset is beyond its limit.
    Offset { offset_mps2: f64, limit_mps2: f64 },
    /// A centring spring stiffer than the loop holds.
    Spring {
        spring_per_s2: f64,
        limit_per_s2: f64,
    },
}

impl IdentifyError {
    /// The envelope's property it names, if any.
    pub fn cause(&self) -> Option<Cause> {
        match self {
            IdentifyError::Gain { .. } => Some(Cause::Gain),
            IdentifyError::Offset { .. } => Some(Cause::Offset),
            IdentifyError::Spring { .. } => Some(Cause::Spring),
            _ => None,
        }
    }
}

impl core::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            IdentifyError::Latches => f.write_str(
                "identification needs 14 to 512 positions, in time order, inside the probe",
            ),
            IdentifyError::Probe => {
                f.write_str("the probe must command both a positive and a negative acceleration")
            }
            IdentifyError::NoMotion { excursion_m } => write!(
                f,
                "the plate moved {excursion_m} m during the probe: check the motor, the driver \
                 enable and the position sensor"
            ),
            IdentifyError::Singular => {
                f.write_str("the probe's positions do not determine the drive's gains")
            }
            IdentifyError::Gain { positive, gain } => {
                let direction = if positive { "positive" } else { "negative" };
                if gain < 0.0 {
                    write!(
                        f,
                        "the drive's {direction} gain is {gain}: the motor or the position sensor \
                         is wired backwards"
                    )
                } else {
                    let (min, max) = ENVELOPE.identified_gains();
                    write!(
                        f,
                        "the drive's {direction} gain is {gain}, outside {min}–{max}: {}",
                        Cause::Gain.remedy()
                    )
                }
            }
            IdentifyError::Offset {
                offset_mps2,
                limit_mps2,
            } => write!(
                f,
                "the drive's zero offset is {offset_mps2} m/s², beyond ±{limit_mps2} m/s²: {}",
                Cause::Offset.remedy()
            ),
            IdentifyError::Spring {
                spring_per_s2,
                limit_per_s2,
            } => write!(
                f,
                "the plate's mount is a spring of k/M = {} 1/s² (natural frequency {} Hz), \
                 stiffer than the {} 1/s² the loop holds at this frequency: {}",
                Significant(spring_per_s2),
                Significant(sqrt(spring_per_s2.max(0.0)) / (2.0 * core::f64::consts::PI)),
                Significant(limit_per_s2),
                Cause::Spring.remedy()
            ),
        }
    }
}

/// Unknowns of the fit: `x₀, v₀, e, g₊, g₋, F_c/M, b/M, k/M`.
const UNKNOWNS: usize = 8;

/// Longest current-loop lag searched.
const LAG_MAX_S: f64 = 5e-3;

/// Golden-section steps: the lag to `LAG_MAX_S·0.618²⁴ ≈ 5·10⁻⁸ s`, a three-thousandth of a
/// 1 kHz current loop's time constant (0.16 ms).
const LAG_STEPS: usize = 24;

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
fn lagged_rows(
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

/// The regressors at each latch from the latched motion: `C`, the double integral of the sign
/// of the velocity (Coulomb friction), `X`, the integral of the displacement from the first
/// latch (viscous friction and the spring's damping), and `S`, the double integral of the
/// position (a centring spring), each by trapezoids on the latches, with their rates. The
/// velocity at each latch is `velocity(i)`; where it changes sign between two latches, it does
/// so where its linear interpolation does.
fn motion_rows(
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
fn latched_velocity(latches: &[Latch], i: usize) -> f64 {
    let (a, b) = (
        latches[i.saturating_sub(1)],
        latches[(i + 1).min(latches.len() - 1)],
    );
    (b.position_m - a.position_m) / (b.t_s - a.t_s)
}

/// Which drive the fit describes.
#[derive(Clone, Copy, PartialEq)]
enum Model {
    /// A bare slide: every unknown but the spring (`k/M = 0`).
    Slide,
    /// A slide on a centring spring.
    Sprung,
}

impl Model {
    /// The unknowns it fits, the first of [`UNKNOWNS`].
    fn columns(self) -> usize {
        match self {
            Model::Slide => UNKNOWNS - 1,
            Model::Sprung => UNKNOWNS,
        }
    }
}

/// A spring softer than this (`k/M`, 1/s²: 1.6 Hz) is taken for none: over a probe of a few
/// cycles it moves the plate less than the fit's other unknowns can tell apart, and the loop
/// holds it as the disturbance it is.
const SPRING_MIN_PER_S2: f64 = 100.0;

/// The least-squares fit of `model` for one lag, with its residual sum of squares; `motion`
/// holds the friction and spring regressors of the latches, which do not depend on the lag.
fn fit(
    probe: &[CommandSegment],
    latches: &[Latch],
    motion: &[[f64; 3]; MAX_LATCHES],
    lag_s: f64,
    model: Model,
) -> Option<([f64; UNKNOWNS], f64)> {
    let columns = model.columns();
    let mut lagged = [[0.0; 3]; MAX_LATCHES];
    lagged_rows(probe, latches, lag_s, |i, r, _| lagged[i] = r);
    let row = |i: usize| -> [f64; UNKNOWNS] {
        let [p, n, e] = lagged[i];
        let [c, x, spring] = motion[i];
        [1.0, latches[i].t_s, e, p, n, c, x, spring]
    };
    // Columns scaled to a largest value of 1.
    let mut scale = [0.0_f64; UNKNOWNS];
    for i in 0..latches.len() {
        for (s, r) in scale.iter_mut().zip(row(i)) {
            *s = s.max(fabs(r));
        }
    }
    for s in scale.iter_mut() {
        if *s == 0.0 {
            *s = 1.0;
        }
    }
    let mut normal = [[0.0; UNKNOWNS]; UNKNOWNS];
    let mut right = [0.0; UNKNOWNS];
    for (i, latch) in latches.iter().enumerate() {
        let mut r = row(i);
        for (r, s) in r.iter_mut().zip(scale) {
            *r /= s;
        }
        r[columns..].fill(0.0);
        for a in 0..columns {
            right[a] += r[a] * latch.position_m;
            for b in a..columns {
                normal[a][b] += r[a] * r[b];
            }
        }
    }
    let upper = normal;
    for (a, row) in normal.iter_mut().enumerate() {
        for (b, entry) in row.iter_mut().enumerate().take(a) {
            *entry = upper[b][a];
        }
    }
    let mut theta = cholesky_solve(normal, right, columns)?;
    for (t, s) in theta.iter_mut().zip(scale) {
        *t /= s;
    }
    let squares = latches
        .iter()
        .enumerate()
        .map(|(i, latch)| {
            let fitted: f64 = row(i).iter().zip(theta).map(|(r, t)| r * t).sum();
            (fitted - latch.position_m) * (fitted - latch.position_m)
        })
        .sum();
    Some((theta, squares))
}

/// The lag whose fit of `model` leaves the least residual (a golden-section search over
/// `[0, LAG_MAX_S]`, and 0 itself), with that fit.
fn best_lag(
    probe: &[CommandSegment],
    latches: &[Latch],
    motion: &[[f64; 3]; MAX_LATCHES],
    model: Model,
) -> Result<(f64, ([f64; UNKNOWNS], f64)), IdentifyError> {
    let residual =
        |lag_s: f64| fit(probe, latches, motion, lag_s, model).map_or(f64::INFINITY, |(_, r)| r);
    let golden = 0.5 * (sqrt(5.0) - 1.0);
    let (mut lo, mut hi) = (0.0, LAG_MAX_S);
    let (mut a, mut b) = (hi - golden * (hi - lo), lo + golden * (hi - lo));
    let (mut fa, mut fb) = (residual(a), residual(b));
    for _ in 0..LAG_STEPS {
        if fa <= fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - golden * (hi - lo);
            fa = residual(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + golden * (hi - lo);
            fb = residual(b);
        }
    }
    // The search closes in on its interval's end without reaching it: a drive without a lag
    // (an ideal one, or a current loop far faster than the latches) is tried at 0 itself.
    let (lag_s, inside) = if fa <= fb { (a, fa) } else { (b, fb) };
    let lag_s = if residual(0.0) <= inside { 0.0 } else { lag_s };
    let fitted = fit(probe, latches, motion, lag_s, model).ok_or(IdentifyError::Singular)?;
    Ok((lag_s, fitted))
}

/// The velocity of the motion `theta` describes (at a lag of `lag_s`) at each latch.
fn fitted_velocity(
    probe: &[CommandSegment],
    latches: &[Latch],
    theta: &[f64; UNKNOWNS],
    lag_s: f64,
) -> [f64; MAX_LATCHES] {
    let [_, v0, e, gain_positive, gain_negative, friction, viscous, spring] = *theta;
    let mut velocity = [v0; MAX_LATCHES];
    lagged_rows(probe, latches, lag_s, |i, _, [p, n, e1]| {
        velocity[i] += gain_positive * p + gain_negative * n + e * e1;
    });
    motion_rows(
        latches,
        |i| latched_velocity(latches, i),
        |i, _, [c, x, s]| velocity[i] += friction * c + viscous * x + spring * s,
    );
    velocity
}

/// Latches a fit takes at most.
pub const MAX_LATCHES: usize = 512;

/// Fits the probe's model to `latches` (at most [`MAX_LATCHES`], the first at the probe's start)
/// and checks it against `limits`.
pub fn identify(
    probe: &[CommandSegment],
    latches: &[Latch],
    limits: &IdentifyLimits,
) -> Result<Identified, IdentifyError> {
    let valid_probe = probe
        .iter()
        .all(|s| s.duration_s.is_finite() && s.duration_s >= 0.0 && s.accel_mps2.is_finite());
    if !valid_probe
        || !probe.iter().any(|s| s.accel_mps2 > 0.0)
        || !probe.iter().any(|s| s.accel_mps2 < 0.0)
    {
        return Err(IdentifyError::Probe);
    }
    let length_s: f64 = probe.iter().map(|s| s.duration_s).sum();
    let ordered = latches.windows(2).all(|w| w[0].t_s < w[1].t_s);
    // The probe's length is a sum of segment lengths, a latch's time a quotient of ticks: they
    // may differ in the last bits.
    let end_s = length_s * (1.0 + 4.0 * f64::EPSILON);
    let inside = latches
        .iter()
        .all(|l| l.t_s >= 0.0 && l.t_s <= end_s && l.position_m.is_finite());
    if latches.len() < 2 * UNKNOWNS || latches.len() > MAX_LATCHES || !ordered || !inside {
        return Err(IdentifyError::Latches);
    }
    let first_m = latches[0].position_m;
    let excursion_m = latches
        .iter()
        .map(|l| fabs(l.position_m - first_m))
        .fold(0.0, f64::max);
    if excursion_m.is_nan() || excursion_m < limits.min_excursion_m {
        return Err(IdentifyError::NoMotion { excursion_m });
    }
    let mut motion = [[0.0; 3]; MAX_LATCHES];
    motion_rows(
        latches,
        |i| latched_velocity(latches, i),
        |i, r, _| motion[i] = r,
    );
    // The lag of a bare slide first; a spring found at that lag is searched for again with it.
    let (mut lag_s, mut fitted) = best_lag(probe, latches, &motion, Model::Slide)?;
    let (sprung, _) =
        fit(probe, latches, &motion, lag_s, Model::Sprung).ok_or(IdentifyError::Singular)?;
    let model = if -sprung[UNKNOWNS - 1] >= SPRING_MIN_PER_S2 {
        (lag_s, fitted) = best_lag(probe, latches, &motion, Model::Sprung)?;
        Model::Sprung
    } else {
        Model::Slide
    };
    // Differences of quantised latches read a slow plate as standing, or as turning, where it
    // does not: the friction's signs are taken again from the fitted motion's velocity, and
    // that fit is kept where it explains the latches better.
    let velocity = fitted_velocity(probe, latches, &fitted.0, lag_s);
    motion_rows(latches, |i| velocity[i], |i, r, _| motion[i] = r);
    if let Some(refit) = fit(probe, latches, &motion, lag_s, model) {
        if refit.1 < fitted.1 {
            fitted = refit;
        }
    }
    let (theta, squares) = fitted;
    let [_, _, offset_mps2, gain_positive, gain_negative, friction, viscous, spring] = theta;
    let identified = Identified {
        gain_positive,
        gain_negative,
        offset_mps2,
        lag_s,
        coulomb_mps2: -friction,
        viscous_per_s: -viscous,
        spring_per_s2: 0.0 - spring,
        residual_m: sqrt(squares / latches.len() as f64),
    };
    for (positive, gain) in [(true, gain_positive), (false, gain_negative)] {
        if !(limits.gain_min..=limits.gain_max).contains(&gain) {
            return Err(IdentifyError::Gain { positive, gain });
        }
    }
    if offset_mps2.is_nan() || fabs(offset_mps2) > limits.offset_max_mps2 {
        return Err(IdentifyError::Offset {
            offset_mps2,
            limit_mps2: limits.offset_max_mps2,
        });
    }
    if identified.spring_per_s2.is_nan() || identified.spring_per_s2 > limits.spring_max_per_s2 {
        return Err(IdentifyError::Spring {
            spring_per_s2: identified.spring_per_s2,
            limit_per_s2: limits.spring_max_per_s2,
        });
    }
    Ok(identified)
}

/// Solves the symmetric positive definite `a·x = b` in its first `n` unknowns (the rest stay
/// 0); `None` if a pivot is not clearly positive (or not a number).
fn cholesky_solve(
    mut a: [[f64; UNKNOWNS]; UNKNOWNS],
    mut b: [f64; UNKNOWNS],
    n: usize,
) -> Option<[f64; UNKNOWNS]> {
    let largest = (0..n).map(|i| a[i][i]).fold(0.0, f64::max);
    let dot = |x: &[f64], y: &[f64]| -> f64 { x.iter().zip(y).map(|(p, q)| p * q).sum() };
    for j in 0..n {
        let d = a[j][j] - dot(&a[j][..j], &a[j][..j]);
        if d.is_nan() || d <= 1e-13 * largest {
            return None;
        }
        let d = sqrt(d);
        a[j][j] = d;
        for i in j + 1..n {
            a[i][j] = (a[i][j] - dot(&a[i][..j], &a[j][..j])) / d;
        }
    }
    for i in 0..n {
        b[i] = (b[i] - dot(&a[i][..i], &b[..i])) / a[i][i];
    }
    for i in (0..n).rev() {
        let later: f64 = (i + 1..n).map(|k| a[k][i] * b[k]).sum();
        b[i] = (b[i] - later) / a[i][i];
    }
    b[n..].fill(0.0);
    Some(b)
}
