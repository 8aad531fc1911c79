//! A fixed-step reference of the real plate and its part, for validation only.
//!
//! Classical RK4 at step `dt` on `(x, v, F, u, p, q)` with the equations written out directly
//! (`F' = 2π·f_c·(F* − F)`, `M·v' = F − k·x − (c + b)·v`, `u' = −σ·μg + φ` sliding or `u' = v'`
//! stuck, `p' = u`, `q' = x`). Steps end at segment edges. When a step crosses a part event
//! (`w = u − v` changes sign, or a stuck part's `|v' − φ|` exceeds `μ_s·g`), the event's time
//! inside the step is bisected on RK4 steps of the shortened length, so the error stays
//! fourth order in `dt`. Slide Coulomb friction and end stops are not modelled here.

use crate::error::SimError;
use crate::plant::{Contact, PlateSegment};

use super::params::PlateParams;
use super::run::{PlateRun, PlateRunOptions};

type State = [f64; 6];

struct Rhs<'a> {
    params: &'a PlateParams,
    contact: &'a Contact,
    lag_per_s: Option<f64>,
    target_n: f64,
}

impl Rhs<'_> {
    fn plate_accel_mps2(&self, s: &State) -> f64 {
        let p = self.params;
        (s[2] - p.spring_npm * s[0] - (p.spring_damping_nspm + p.viscous_friction_nspm) * s[1])
            / p.mass_kg
    }

    /// `ds/dt` with the part stuck (`sigma = None`) or sliding on side `sigma`.
    fn derivative(&self, s: &State, sigma: Option<f64>) -> State {
        let a_plate = self.plate_accel_mps2(s);
        let force_rate = self
            .lag_per_s
            .map_or(0.0, |lag| lag * (self.target_n - s[2]));
        let part_accel = sigma.map_or(a_plate, |sigma| {
            -sigma * self.contact.kinetic_accel_mps2() + self.contact.force_accel_mps2()
        });
        [s[1], a_plate, force_rate, part_accel, s[3], s[0]]
    }

    fn rk4(&self, s: &State, sigma: Option<f64>, dt: f64) -> State {
        let add =
            |a: &State, k: &State, h: f64| -> State { std::array::from_fn(|i| a[i] + h * k[i]) };
        let k1 = self.derivative(s, sigma);
        let k2 = self.derivative(&add(s, &k1, 0.5 * dt), sigma);
        let k3 = self.derivative(&add(s, &k2, 0.5 * dt), sigma);
        let k4 = self.derivative(&add(s, &k3, dt), sigma);
        std::array::from_fn(|i| s[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
    }

    /// `> 0` while the part's contact state `sigma` holds.
    fn holds(&self, s: &State, sigma: Option<f64>) -> f64 {
        match sigma {
            Some(sigma) => sigma * (s[3] - s[1]),
            None => {
                let need = self.plate_accel_mps2(s) - self.contact.force_accel_mps2();
                self.contact.static_accel_mps2() - need.abs()
            }
        }
    }

    /// The contact state of a part at the plate's velocity.
    fn settle(&self, s: &mut State) -> Option<f64> {
        let need = self.plate_accel_mps2(s) - self.contact.force_accel_mps2();
        if need.abs() <= self.contact.static_accel_mps2() {
            s[3] = s[1];
            None
        } else {
            Some(-need.signum())
        }
    }
}

/// Runs `segments` like [`super::run`] with RK4 steps of at most `dt_s`.
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
    if params.coulomb_friction_n > 0.0 || params.end_stop_m.is_some() {
        return Err(SimError::Request(
            "the fixed-step reference models neither slide Coulomb friction nor end stops".into(),
        ));
    }
    if !(dt_s.is_finite() && dt_s > 0.0) || options.average_cycles == 0 {
        return Err(SimError::BadRange {
            what: "the reference needs a positive step and at least one averaged cycle",
        });
    }
    let lag_per_s = params
        .current_bandwidth_hz
        .map(|f_c| 2.0 * std::f64::consts::PI * f_c);
    let mut s: State = [0.0; 6];
    let mut sigma: Option<f64> = None;
    let mut time_s = 0.0;
    let mut peak_m = 0.0_f64;
    let mut marks = std::collections::VecDeque::new();
    let mut cycles = 0_u64;
    for segment in segments {
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
        if sigma.is_none() || s[3] == s[1] {
            sigma = rhs.settle(&mut s);
        }
        let steps = (segment.duration_s / dt_s).ceil().max(1.0) as u64;
        let h = segment.duration_s / steps as f64;
        for _ in 0..steps {
            let mut rest = h;
            while rest > 0.0 {
                let next = rhs.rk4(&s, sigma, rest);
                if rhs.holds(&next, sigma) > 0.0 || rhs.holds(&s, sigma) <= 0.0 {
                    s = next;
                    break;
                }
                let (mut lo, mut hi) = (0.0, rest);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if rhs.holds(&rhs.rk4(&s, sigma, mid), sigma) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                s = rhs.rk4(&s, sigma, hi);
                rest -= hi;
                sigma = match sigma {
                    Some(_) => {
                        s[3] = s[1];
                        rhs.settle(&mut s)
                    }
                    None => {
                        let need = rhs.plate_accel_mps2(&s) - contact.force_accel_mps2();
                        Some(-need.signum())
                    }
                };
            }
            if sigma.is_none() {
                s[3] = s[1];
            }
            peak_m = peak_m.max(s[0].abs());
        }
        time_s += segment.duration_s;
    }
    let (first, last) = (marks.front().copied(), marks.back().copied());
    let (feed_rate_mps, mean_position_m) = match (first, last) {
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
        end_stop: None,
    })
}
