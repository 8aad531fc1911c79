//! A fixed-step reference of the real plate and its part, for validation only.
//!
//! Classical RK4 at step `dt` on `(x, v, F, u, p, q)` with the equations written out directly
//! (`F' = 2π·f_c·(F* − F)`, `M·v' = F − k·x − (c + b)·v − F_c·sign(v)` or `v' = x' = 0` while the
//! slide sticks, `u' = −σ·μg + φ` sliding or `u' = v'` stuck, `p' = u`, `q' = x`). Steps end at
//! segment edges. When a step crosses an event (the slide stops or breaks away, `w = u − v`
//! changes sign, a stuck part's `|v' − φ|` exceeds `μ_s·g`, `|x|` reaches an end stop), the
//! event's time inside the step is bisected on RK4 steps of the shortened length, so the error
//! stays fourth order in `dt`.

use crate::contact::Contact;
use crate::error::SimError;
use crate::segments::PlateSegment;

use super::params::PlateParams;
use super::run::{PlateRun, PlateRunOptions};
use super::stepper::EndStop;

type State = [f64; 6];

/// The slide: `None` stuck, `Some(s)` moving with `F_c·s` against it (`s = 0` without Coulomb
/// friction).
type Slide = Option<f64>;

struct Rhs<'a> {
    params: &'a PlateParams,
    contact: &'a Contact,
    lag_per_s: Option<f64>,
    target_n: f64,
}

impl Rhs<'_> {
    /// `F − k·x`, the force a stuck slide holds.
    fn net_n(&self, s: &State) -> f64 {
        s[2] - self.params.spring_npm * s[0]
    }

    fn plate_accel_mps2(&self, s: &State, slide: Slide) -> f64 {
        let p = self.params;
        slide.map_or(0.0, |sign| {
            (self.net_n(s)
                - (p.spring_damping_nspm + p.viscous_friction_nspm) * s[1]
                - p.coulomb_friction_n * sign)
                / p.mass_kg
        })
    }

    /// `ds/dt` with the part stuck (`sigma = None`) or sliding on side `sigma`.
    fn derivative(&self, s: &State, slide: Slide, sigma: Option<f64>) -> State {
        let a_plate = self.plate_accel_mps2(s, slide);
        let force_rate = self
            .lag_per_s
            .map_or(0.0, |lag| lag * (self.target_n - s[2]));
        let part_accel = sigma.map_or(a_plate, |sigma| {
            -sigma * self.contact.kinetic_accel_mps2() + self.contact.force_accel_mps2()
        });
        let velocity = if slide.is_some() { s[1] } else { 0.0 };
        [velocity, a_plate, force_rate, part_accel, s[3], s[0]]
    }

    fn rk4(&self, s: &State, (slide, sigma): Modes, dt: f64) -> State {
        let add =
            |a: &State, k: &State, h: f64| -> State { std::array::from_fn(|i| a[i] + h * k[i]) };
        let k1 = self.derivative(s, slide, sigma);
        let k2 = self.derivative(&add(s, &k1, 0.5 * dt), slide, sigma);
        let k3 = self.derivative(&add(s, &k2, 0.5 * dt), slide, sigma);
        let k4 = self.derivative(&add(s, &k3, dt), slide, sigma);
        std::array::from_fn(|i| s[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
    }

    /// `> 0` while the slide's state holds, then while the part's does, then inside the stops.
    fn holds(&self, s: &State, (slide, sigma): Modes) -> [f64; 3] {
        let slide_holds = match slide {
            Some(sign) if self.params.coulomb_friction_n > 0.0 => sign * s[1],
            Some(_) => f64::INFINITY,
            None => self.params.coulomb_friction_n - self.net_n(s).abs(),
        };
        let part_holds = match sigma {
            Some(sigma) => sigma * (s[3] - s[1]),
            None => {
                let need = self.plate_accel_mps2(s, slide) - self.contact.force_accel_mps2();
                self.contact.static_accel_mps2() - need.abs()
            }
        };
        let stop_holds = self
            .params
            .end_stop_m
            .map_or(f64::INFINITY, |x| x - s[0].abs());
        [slide_holds, part_holds, stop_holds]
    }

    /// The slide's state once it stops or while it is stuck.
    fn settle_slide(&self, s: &mut State) -> Slide {
        let net = self.net_n(s);
        if net.abs() <= self.params.coulomb_friction_n {
            s[1] = 0.0;
            None
        } else {
            Some(net.signum())
        }
    }

    /// The contact state of a part at the plate's velocity.
    fn settle_part(&self, s: &mut State, slide: Slide) -> Option<f64> {
        let need = self.plate_accel_mps2(s, slide) - self.contact.force_accel_mps2();
        if need.abs() <= self.contact.static_accel_mps2() {
            s[3] = s[1];
            None
        } else {
            Some(-need.signum())
        }
    }
}

/// Slide and part states.
type Modes = (Slide, Option<f64>);

/// `true` when an event function has crossed: it is negative, or it reached zero from above.
fn hit(before: f64, after: f64) -> bool {
    after < 0.0 || (after <= 0.0 && before > 0.0)
}

/// At most this many events within one step before the run is refused as chatter.
const MAX_EVENTS_PER_STEP: usize = 1000;

/// Runs `segments` like [`super::run()`] with RK4 steps of at most `dt_s`.
pub fn run_fixed_step<I>(
    params: &PlateParams,
    contact: &Contact,
    segments: I,
    options: &PlateRunOptions,
    dt_s: f64,
) -> Result<PlateRun, SimError>
where
    I: IntoIterator<Item = PlateSegment>,
{
    params.validate()?;
    if !(dt_s.is_finite() && dt_s > 0.0) || options.average_cycles == 0 {
        return Err(SimError::BadRange {
            what: "the reference needs a positive step and at least one averaged cycle",
        });
    }
    let lag_per_s = params
        .current_bandwidth_hz
        .map(|f_c| 2.0 * std::f64::consts::PI * f_c);
    let mut s: State = [0.0; 6];
    let mut modes: Modes = (
        if params.coulomb_friction_n > 0.0 {
            None
        } else {
            Some(0.0)
        },
        None,
    );
    let mut time_s = 0.0;
    let mut peak_m = 0.0_f64;
    let mut marks = std::collections::VecDeque::new();
    let mut cycles = 0_u64;
    let mut end_stop = None;
    'segments: for segment in segments {
        if segment.starts_cycle {
            if !marks.is_empty() {
                cycles += 1;
            }
            marks.push_back((time_s, s[4], s[5]));
            if marks.len() as u64 > options.average_cycles + 1 {
                marks.pop_front();
            }
            if cycles == options.cycles {
                break;
            }
        }
        let rhs = Rhs {
            params,
            contact,
            lag_per_s,
            target_n: params.target_force_n(segment.accel_mps2),
        };
        if lag_per_s.is_none() {
            s[2] = rhs.target_n;
        }
        if modes.0.is_none() {
            modes.0 = rhs.settle_slide(&mut s);
        }
        if modes.1.is_none() {
            modes.1 = rhs.settle_part(&mut s, modes.0);
        }
        let steps = (segment.duration_s / dt_s).ceil().max(1.0) as u64;
        let h = segment.duration_s / steps as f64;
        for step in 0..steps {
            let mut rest = h;
            let mut events = 0;
            while rest > 0.0 {
                let before = rhs.holds(&s, modes);
                let crossed = |state: &State| {
                    let after = rhs.holds(state, modes);
                    (0..3).find(|&i| hit(before[i], after[i]))
                };
                let next = rhs.rk4(&s, modes, rest);
                if crossed(&next).is_none() {
                    s = next;
                    break;
                }
                let (mut lo, mut hi) = (0.0, rest);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if crossed(&rhs.rk4(&s, modes, mid)).is_none() {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let start = s;
                s = rhs.rk4(&start, modes, hi);
                rest -= hi;
                match crossed(&s) {
                    Some(0) => {
                        if modes.0.is_some() {
                            s[1] = 0.0;
                            if modes.1.is_none() {
                                s[3] = 0.0;
                            }
                            modes.0 = rhs.settle_slide(&mut s);
                        } else {
                            modes.0 = Some(rhs.net_n(&s).signum());
                        }
                        if modes.1.is_none() {
                            modes.1 = rhs.settle_part(&mut s, modes.0);
                        }
                    }
                    Some(1) => {
                        modes.1 = match modes.1 {
                            Some(_) => {
                                s[3] = s[1];
                                rhs.settle_part(&mut s, modes.0)
                            }
                            None => {
                                let need =
                                    rhs.plate_accel_mps2(&s, modes.0) - contact.force_accel_mps2();
                                Some(-need.signum())
                            }
                        };
                    }
                    _ => {
                        let x_lim = params.end_stop_m.unwrap_or(f64::INFINITY);
                        end_stop = Some(EndStop {
                            time_s: time_s + step as f64 * h + (h - rest),
                            position_m: x_lim.copysign(s[0]),
                            velocity_mps: s[1],
                        });
                        peak_m = peak_m.max(x_lim);
                        break 'segments;
                    }
                }
                events += 1;
                if events == MAX_EVENTS_PER_STEP {
                    return Err(SimError::Chatter {
                        time_s: time_s + step as f64 * h + (h - rest),
                    });
                }
            }
            if modes.1.is_none() {
                s[3] = s[1];
            }
            peak_m = peak_m.max(s[0].abs());
        }
        time_s += segment.duration_s;
    }
    if end_stop.is_none() && !marks.is_empty() && cycles < options.cycles {
        cycles += 1;
        marks.push_back((time_s, s[4], s[5]));
        if marks.len() as u64 > options.average_cycles + 1 {
            marks.pop_front();
        }
    }
    let (feed_rate_mps, mean_position_m) = match (marks.front(), marks.back()) {
        (Some(a), Some(b)) if marks.len() >= 2 => {
            ((b.1 - a.1) / (b.0 - a.0), (b.2 - a.2) / (b.0 - a.0))
        }
        _ => (0.0, 0.0),
    };
    Ok(PlateRun {
        feed_rate_mps,
        mean_position_m,
        peak_excursion_m: peak_m,
        cycles,
        end_stop,
    })
}
