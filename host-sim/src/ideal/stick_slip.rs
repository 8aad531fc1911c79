//! The part's stick–slip on the ideal plate: a point-mass part under Coulomb friction on a plate
//! of piecewise-constant acceleration (paper, Section III, with the stick–slip corrections among
//! the errata of `shared/README.md`).
//!
//! The state is the part's velocity relative to the plate, `w = v_part − v_plate`. Within one
//! segment of constant plate acceleration `a_p` the part's acceleration is constant too:
//! `+μg + φ` while it is slower than the plate, `−μg + φ` while it is faster (`φ = f_ext/m`), and
//! `a_p` while it sticks. So `w` is linear in time between events and every event is solved in
//! closed form:
//!
//! * **Meeting** (`w` reaches 0): the part sticks if static friction can hold it,
//!   `|a_p − φ| ≤ μ_s·g`, and otherwise slips through to the other side (slip reversal).
//! * **Breakaway**: a stuck part starts to slip as soon as a segment asks more than `μ_s·g` of
//!   friction; it then slides at the kinetic rate, behind the plate if `a_p − φ > μ_s·g`, ahead of
//!   it if `a_p − φ < −μ_s·g`.
//!
//! A stuck part is represented exactly by `w = 0`.

use crate::contact::Contact;

/// The part's relative accelerations during a segment of plate acceleration `a_p`, and their
/// reciprocals, so that stepping never divides.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rates {
    /// `dw/dt = μg + φ − a_p` while the part is behind the plate (`w < 0`).
    pub behind_mps2: f64,
    pub inv_behind_s2pm: f64,
    /// `dw/dt = −μg + φ − a_p` while the part is ahead of the plate (`w > 0`).
    pub ahead_mps2: f64,
    pub inv_ahead_s2pm: f64,
    /// `dw/dt` of a stuck part: 0 if static friction holds it, else the kinetic rate of the side
    /// it breaks away to.
    pub release_mps2: f64,
}

impl Rates {
    pub fn new(contact: &Contact, accel_mps2: f64) -> Self {
        let mu_g = contact.kinetic_accel_mps2();
        let need = accel_mps2 - contact.force_accel_mps2();
        let behind = mu_g - need;
        let ahead = -mu_g - need;
        let hold = contact.static_accel_mps2();
        let release = if need > hold {
            behind
        } else if need < -hold {
            ahead
        } else {
            0.0
        };
        Rates {
            behind_mps2: behind,
            inv_behind_s2pm: 1.0 / behind,
            ahead_mps2: ahead,
            inv_ahead_s2pm: 1.0 / ahead,
            release_mps2: release,
        }
    }
}

/// What happened inside a segment, for traces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A segment (a switch of the plate's acceleration) begins.
    Edge,
    /// The part reaches the plate's velocity and sticks.
    Stick,
    /// The part reaches the plate's velocity and slips through to the other side.
    Reversal,
    /// A stuck part starts to slip.
    Breakaway,
}

/// Receives the events of [`advance`], at `offset_s` into the segment with relative velocity
/// `w_mps`. The no-op implementation on `()` compiles away.
pub trait Observer {
    const ACTIVE: bool;
    fn event(&mut self, kind: EventKind, offset_s: f64, w_mps: f64);
}

impl Observer for () {
    const ACTIVE: bool = false;
    #[inline(always)]
    fn event(&mut self, _: EventKind, _: f64, _: f64) {}
}

/// Integrals of one segment: `∫w dt` and the time spent stuck.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Step {
    pub rel_displacement_m: f64,
    pub stick_s: f64,
}

/// A segment as [`advance`] consumes it: its duration, its [`Rates`], and the change of a sliding
/// part's relative velocity over the whole segment on either side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    pub duration_s: f64,
    pub rates: Rates,
    /// `behind_mps2 · duration_s`.
    pub behind_change_mps: f64,
    /// `ahead_mps2 · duration_s`.
    pub ahead_change_mps: f64,
}

impl Span {
    #[inline(always)]
    pub fn new(duration_s: f64, rates: Rates) -> Self {
        Span {
            duration_s,
            rates,
            behind_change_mps: rates.behind_mps2 * duration_s,
            ahead_change_mps: rates.ahead_mps2 * duration_s,
        }
    }
}

/// Advances the relative velocity `w` through `span`, solving the meeting time in closed form,
/// and returns the segment's integrals.
///
/// Each side of the plate has its own branch: the side a part slides on is well predicted, and a
/// branch keeps it off the dependency chain through `w` that a selected operand would lengthen.
#[inline(always)]
pub fn advance<O: Observer>(w: &mut f64, span: &Span, observer: &mut O) -> Step {
    let w0 = *w;
    if w0 == 0.0 {
        release(w, 0.0, span.duration_s, &span.rates, observer)
    } else if w0 < 0.0 {
        slide(
            w,
            w0,
            span.behind_change_mps,
            span.rates.inv_behind_s2pm,
            span,
            observer,
        )
    } else {
        slide(
            w,
            w0,
            span.ahead_change_mps,
            span.rates.inv_ahead_s2pm,
            span,
            observer,
        )
    }
}

/// A part sliding at `w0 ≠ 0` through `span` on the side whose velocity change over the whole
/// segment is `change` and whose reciprocal rate is `inv_rate`.
#[inline(always)]
fn slide<O: Observer>(
    w: &mut f64,
    w0: f64,
    change: f64,
    inv_rate: f64,
    span: &Span,
    observer: &mut O,
) -> Step {
    let duration_s = span.duration_s;
    let w1 = w0 + change;
    if w1 * w0 > 0.0 {
        *w = w1;
        return Step {
            rel_displacement_m: 0.5 * (w0 + w1) * duration_s,
            stick_s: 0.0,
        };
    }
    // The side's rate is not 0 here (else `w1 = w0`), so the quotient is never NaN and a plain
    // comparison serves as the minimum.
    let to_meet_s = -w0 * inv_rate;
    let meet_s = if to_meet_s < duration_s {
        to_meet_s
    } else {
        duration_s
    };
    let before = 0.5 * w0 * meet_s;
    let mut step = release(w, meet_s, duration_s - meet_s, &span.rates, observer);
    step.rel_displacement_m += before;
    step
}

/// A part at the plate's velocity `offset_s` into the segment, for the remaining `rest_s`: it
/// sticks if static friction holds, otherwise it slides away at the kinetic rate.
#[inline(always)]
fn release<O: Observer>(
    w: &mut f64,
    offset_s: f64,
    rest_s: f64,
    rates: &Rates,
    observer: &mut O,
) -> Step {
    let rate = rates.release_mps2;
    *w = rate * rest_s;
    if O::ACTIVE {
        let kind = match (offset_s > 0.0, rate == 0.0) {
            (true, true) => Some(EventKind::Stick),
            (true, false) => Some(EventKind::Reversal),
            (false, false) => Some(EventKind::Breakaway),
            (false, true) => None,
        };
        if let Some(kind) = kind {
            observer.event(kind, offset_s, 0.0);
        }
    }
    Step {
        rel_displacement_m: 0.5 * rate * rest_s * rest_s,
        stick_s: if rate == 0.0 { rest_s } else { 0.0 },
    }
}
