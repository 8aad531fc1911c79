//! A seeded family of plants drawn across the closed loop's envelope
//! ([`feeder_shared::closed_loop::ENVELOPE`]) and just outside it, and their runs at a few
//! operating points, each judged by the one verdict.
//!
//! An inside plant draws every property independently: moving mass 0.5–5 kg, zero offset up to
//! ±2 % of the envelope's 200 m/s² full scale, each gain 0.90–1.10, a current loop of 150 Hz–2 kHz
//! (log-uniform), slide friction 0–15 N and 0–20 N·s/m, no spring on half of them and a flexure
//! of up to 50 kN/m (damping ratio 1–10 %) on the others, end stops at ±3–10 mm and an encoder of
//! 0.5–5 µm a count. The drive's force limit is 5 % above what a full-scale command asks of the
//! highest gain. An outside plant is an inside one with one property past its limit, the
//! [`Cause`]s in turn.

use feeder_shared::closed_loop::{Cause, ENVELOPE};
use feeder_shared::{Drive, Limits, TickClock, TickPlan, Waveform, WaveformSpec};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Uniform};
use serde::Serialize;

use crate::contact::Contact;
use crate::error::SimError;
use crate::operating_point::OperatingPoint;
use crate::plate::{PlantFile, PlateParams};
use crate::sensors::{EncoderConfig, SensorsConfig};

use super::{run_closed_loop, ClosedLoopOptions, Verdict};

/// The timer clock of every run's tick plan.
const CLOCK_HZ: u32 = 1_000_000;

/// One plant of the family.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    pub index: usize,
    pub plant: PlantFile,
    /// The property that lies outside the envelope; `None` for an inside plant.
    pub outside: Option<Cause>,
}

/// A point the family runs at.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FamilyPoint {
    pub freq_hz: f64,
    pub duty: f64,
    pub accel_mps2: f64,
}

/// The operating points: 50 Hz and 100 Hz, each at the envelope's two ends of duty short of a
/// hundredth, at a peak acceleration of 140 m/s² (a 2.4 mm stroke at 50 Hz and d = 0.53).
pub const POINTS: [FamilyPoint; 4] = [
    FamilyPoint {
        freq_hz: 50.0,
        duty: 0.53,
        accel_mps2: 140.0,
    },
    FamilyPoint {
        freq_hz: 50.0,
        duty: 0.61,
        accel_mps2: 140.0,
    },
    FamilyPoint {
        freq_hz: 100.0,
        duty: 0.53,
        accel_mps2: 140.0,
    },
    FamilyPoint {
        freq_hz: 100.0,
        duty: 0.61,
        accel_mps2: 140.0,
    },
];

fn uniform(rng: &mut ChaCha8Rng, low: f64, high: f64) -> f64 {
    Uniform::new_inclusive(low, high).map_or(low, |u| u.sample(rng))
}

fn log_uniform(rng: &mut ChaCha8Rng, low: f64, high: f64) -> f64 {
    uniform(rng, low.ln(), high.ln()).exp()
}

/// A random sign.
fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if uniform(rng, 0.0, 1.0) < 0.5 {
        -1.0
    } else {
        1.0
    }
}

/// An inside plant drawn from `rng`.
fn inside(rng: &mut ChaCha8Rng) -> PlantFile {
    let e = ENVELOPE;
    let mass_kg = uniform(rng, e.mass_min_kg, e.mass_max_kg);
    let spring_npm = if uniform(rng, 0.0, 1.0) < 0.5 {
        0.0
    } else {
        uniform(rng, 0.0, e.spring_max_npm)
    };
    let damping_ratio = uniform(rng, 0.01, 0.1);
    let plate = PlateParams {
        mass_kg,
        full_scale_accel_mps2: e.full_scale_mps2,
        zero_offset_fraction: uniform(rng, -e.zero_offset_fraction_max, e.zero_offset_fraction_max),
        gain_positive: uniform(rng, e.gain_min, e.gain_max),
        gain_negative: uniform(rng, e.gain_min, e.gain_max),
        current_bandwidth_hz: Some(log_uniform(rng, e.current_bandwidth_min_hz, 2000.0)),
        force_limit_n: None,
        coulomb_friction_n: uniform(rng, 0.0, e.coulomb_max_n),
        viscous_friction_nspm: uniform(rng, 0.0, e.viscous_max_nspm),
        spring_npm,
        spring_damping_nspm: 2.0 * damping_ratio * (spring_npm * mass_kg).sqrt(),
        end_stop_m: Some(uniform(rng, e.end_stop_min_m, 10e-3)),
    };
    let encoder = EncoderConfig {
        resolution_m: uniform(rng, 0.5e-6, e.resolution_max_m),
        index_m: Some(0.0),
        reversed: false,
    };
    with_force_limit(PlantFile {
        plate,
        sensors: SensorsConfig {
            encoder: Some(encoder),
            ..SensorsConfig::default()
        },
    })
}

/// The plant with its force limit 5 % above a full-scale command on its higher gain.
fn with_force_limit(mut plant: PlantFile) -> PlantFile {
    let p = &plant.plate;
    let gain = p.gain_positive.max(p.gain_negative);
    let offset_mps2 = p.zero_offset_fraction.abs() * p.full_scale_accel_mps2;
    plant.plate.force_limit_n =
        Some(1.05 * p.mass_kg * (gain * p.full_scale_accel_mps2 + offset_mps2));
    plant
}

/// `plant` with its property of `cause` drawn past the envelope's limit.
fn outside(rng: &mut ChaCha8Rng, mut plant: PlantFile, cause: Cause) -> PlantFile {
    let e = ENVELOPE;
    let plate = &mut plant.plate;
    match cause {
        Cause::Spring => {
            plate.spring_npm = uniform(rng, 1.2, 3.0) * e.spring_max_npm;
            plate.spring_damping_nspm = 0.1 * (plate.spring_npm * plate.mass_kg).sqrt();
        }
        Cause::Friction => plate.coulomb_friction_n = uniform(rng, 1.2, 3.0) * e.coulomb_max_n,
        Cause::Offset => {
            plate.zero_offset_fraction =
                sign(rng) * uniform(rng, 1.25, 2.5) * e.zero_offset_fraction_max
        }
        Cause::Gain => {
            let excess = uniform(rng, 0.03, 0.15);
            let gain = if sign(rng) > 0.0 {
                e.gain_max + excess
            } else {
                e.gain_min - excess
            };
            if sign(rng) > 0.0 {
                plate.gain_positive = gain;
            } else {
                plate.gain_negative = gain;
            }
        }
        Cause::Lag => {
            plate.current_bandwidth_hz = Some(uniform(rng, 0.3, 0.8) * e.current_bandwidth_min_hz)
        }
        Cause::Sensor => {
            if let Some(encoder) = plant.sensors.encoder.as_mut() {
                encoder.resolution_m = uniform(rng, 1.4, 4.0) * e.resolution_max_m;
            }
        }
    }
    with_force_limit(plant)
}

/// `inside` plants and `outside` plants drawn from `seed`: member `i` depends on the seed and
/// `i` alone, so a family grows without changing its first members.
pub fn members(seed: u64, inside_count: usize, outside_count: usize) -> Vec<Member> {
    let draw = |index: usize| {
        let mut rng =
            ChaCha8Rng::seed_from_u64(seed ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let plant = inside(&mut rng);
        if index < inside_count {
            Member {
                index,
                plant,
                outside: None,
            }
        } else {
            let cause = Cause::ALL[(index - inside_count) % Cause::ALL.len()];
            Member {
                index,
                plant: outside(&mut rng, plant, cause),
                outside: Some(cause),
            }
        }
    };
    (0..inside_count + outside_count).map(draw).collect()
}

/// One member run at one point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FamilyRun {
    pub member: usize,
    #[serde(serialize_with = "cause_name")]
    pub outside: Option<Cause>,
    pub point: FamilyPoint,
    /// The run held every criterion and kept the start-up within its bound.
    pub passed: bool,
    /// The envelope property the loop named where it gave up, if any.
    #[serde(serialize_with = "cause_name")]
    pub refused_for: Option<Cause>,
    /// An outside plant refused before it moved 0.5 mm, with its cause named.
    pub refused_by_cause: bool,
    /// The course said, before the release, that the drive's range cannot give the ideal
    /// plate's feed, and which feed it gives instead (m/s).
    pub feed_limited_mps: Option<f64>,
    pub verdict: Verdict,
}

impl FamilyRun {
    /// The criteria the run missed, by name, each once: those of its verdict's failures and
    /// the start-up's bound.
    pub fn missed(&self) -> Vec<&'static str> {
        let verdict = &self.verdict;
        let mut missed = verdict.criteria_missed();
        if verdict.startup_peak_m > verdict.startup_limit_m {
            missed.push("start-up peak");
        }
        missed.sort_unstable();
        missed
    }

    /// The run in one line, its figures rounded: for a summary a person reads or a golden file
    /// compares.
    pub fn line(&self) -> String {
        let verdict = &self.verdict;
        let outside = self.outside.map_or("inside".into(), |cause| {
            format!("outside: {}", cause.name())
        });
        let figure = |value: Option<f64>, scale: f64, unit: &str| {
            value.map_or("—".into(), |v| format!("{:.1} {unit}", v * scale))
        };
        format!(
            "member {} ({outside}) at {} Hz, d = {}: {}{}; start-up {}; worst mean {}; feed {}; \
             missed: {}",
            self.member,
            self.point.freq_hz,
            self.point.duty,
            if self.passed {
                "passed"
            } else if self.refused_by_cause {
                "refused by cause"
            } else {
                "failed"
            },
            self.refused_for.map_or(String::new(), |cause| format!(
                ", refused for its {}",
                cause.name()
            )),
            figure(Some(verdict.startup_peak_m), 1e6, "µm"),
            figure(verdict.worst_mean_position_m, 1e6, "µm"),
            figure(verdict.feed_rate_difference, 1e2, "%"),
            if self.missed().is_empty() {
                "nothing".into()
            } else {
                self.missed().join(", ")
            },
        )
    }
}

/// A cause by its name.
fn cause_name<S: serde::Serializer>(cause: &Option<Cause>, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_some(&cause.map(Cause::name))
}

/// How far an outside plant may move before it is refused.
pub const REFUSAL_TRAVEL_M: f64 = 0.5e-3;

/// The cycles a member runs after its course: the soft start and two feed-rate windows.
pub const CYCLES: u64 = 125;

/// Runs `member` at `point`: the course, then [`CYCLES`] cycles.
pub fn run_member(member: &Member, point: FamilyPoint) -> Result<FamilyRun, SimError> {
    let spec = WaveformSpec::from_frequency(
        point.freq_hz,
        point.duty,
        Drive::Accel {
            accel_mps2: point.accel_mps2,
        },
    );
    let waveform = Waveform::new(spec, &Limits::NONE)?;
    let plan = TickPlan::new(&waveform, TickClock::new(CLOCK_HZ))?;
    let contact = Contact::kinetic(1.0, 1e-4)?;
    let options = ClosedLoopOptions::new(CYCLES);
    let run = run_closed_loop(&member.plant, &contact, plan, &options)?;
    let ideal = OperatingPoint::new(spec, contact, Some(CLOCK_HZ))?;
    let verdict = run.verdict(
        &member.plant.plate,
        &options,
        ideal.steady().feed_rate_mps,
        ideal.velocity_scale_mps(),
    );
    let refused_for = run.gave_up.as_ref().and_then(SimError::cause);
    let refused_by_cause = member.outside.is_some()
        && member.outside == refused_for
        && verdict.peak_excursion_m <= REFUSAL_TRAVEL_M;
    let passed = verdict.passed && verdict.startup_peak_m <= verdict.startup_limit_m;
    Ok(FamilyRun {
        member: member.index,
        outside: member.outside,
        point,
        passed,
        refused_for,
        refused_by_cause,
        feed_limited_mps: run
            .feed
            .filter(|found| found.limited)
            .map(|found| found.feed_mps),
        verdict,
    })
}
