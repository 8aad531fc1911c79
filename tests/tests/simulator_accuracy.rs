//! The exact simulator against the paper's closed forms (with the errata of `shared/README.md`),
//! against the fixed-step reference integrator, and against physical invariants.
//!
//! Expected values are written out here from the equations, independently of the shared model
//! code, which is compared as a second opinion only.

use feeder_shared::model::{self, STANDARD_GRAVITY_MPS2};
use feeder_shared::{Drive, Error, Limits, Waveform, WaveformSpec};
use host_sim::figures;
use host_sim::ideal::fixed_step::run_fixed_step;
use host_sim::ideal::simulator::{CycleTable, RunOptions};
use host_sim::ideal::stick_slip::EventKind;
use host_sim::segments::exact_cycle;
use host_sim::{run_segments, Contact, OperatingPoint, SimError};

const G: f64 = STANDARD_GRAVITY_MPS2;
const PERIOD_S: f64 = 0.02;

fn exact_point(duty: f64, accel_mps2: f64, mu: f64) -> OperatingPoint {
    let spec = WaveformSpec {
        period_s: PERIOD_S,
        duty,
        drive: Drive::Accel { accel_mps2 },
    };
    OperatingPoint::new(spec, Contact::kinetic(mu, 1e-4).unwrap(), None).unwrap()
}

/// Eq. 15: `aT(2d − 1)/4`.
fn eq15(accel: f64, period: f64, duty: f64) -> f64 {
    accel * period * (2.0 * duty - 1.0) / 4.0
}

/// Eq. 16.
fn eq16(accel: f64, mu_g: f64) -> f64 {
    (5.0 * accel * accel + mu_g * (mu_g - 2.0 * accel)) / (8.0 * accel * accel)
}

/// Eq. 18.
fn eq18(accel: f64, period: f64, duty: f64, mu_g: f64) -> f64 {
    let ratio = (accel - mu_g) / (accel + mu_g);
    accel * period / 2.0 * ratio * ratio * (duty - (2.0 * duty - 1.0).sqrt())
}

fn relative(actual: f64, expected: f64) -> f64 {
    ((actual - expected) / expected).abs()
}

#[test]
fn sliding_feed_rate_matches_eq15() {
    let mut checked = 0;
    for (accel, mu) in [
        (100.0, 1.0),
        (146.0, 1.0),
        (200.0, 0.5),
        (30.0, 1.0),
        (500.0, 0.25),
    ] {
        let d_sat = eq16(accel, mu * G);
        for fraction in [0.05, 0.3, 0.6, 0.95] {
            let duty = 0.5 + fraction * (d_sat - 0.5);
            let run = exact_point(duty, accel, mu).steady();
            assert!(run.converged, "a = {accel}, d = {duty}");
            assert_eq!(run.stick_fraction, 0.0, "a = {accel}, d = {duty}");
            let expected = eq15(accel, PERIOD_S, duty);
            let error = relative(run.feed_rate_mps, expected);
            assert!(
                error <= 1e-9,
                "a = {accel}, d = {duty}: relative error {error:e}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 20);
}

#[test]
fn saturated_feed_rate_matches_eq18_and_stick_time() {
    for (accel, mu) in [(100.0, 1.0), (146.0, 1.0), (200.0, 0.5), (30.0, 1.0)] {
        let mu_g = mu * G;
        let d_sat = eq16(accel, mu_g);
        for fraction in [0.02, 0.3, 0.7, 0.98] {
            let duty = d_sat + fraction * (1.0 - d_sat);
            let point = exact_point(duty, accel, mu);
            let options = RunOptions {
                record_cycles: true,
                ..RunOptions::converge(point.default_criteria())
            };
            let run = point.run(&options);
            assert!(run.converged);
            let error = relative(run.feed_rate_mps, eq18(accel, PERIOD_S, duty, mu_g));
            assert!(
                error <= 1e-9,
                "a = {accel}, d = {duty}: relative error {error:e}"
            );
            // Errata 6: beyond d_sat,nqs the part sticks every cycle, so once it has stuck every
            // cycle repeats the last one exactly.
            let means: Vec<f64> = run
                .cycle_stats
                .iter()
                .map(|c| c.mean_velocity_mps)
                .collect();
            assert!(
                means.len() <= 50,
                "a = {accel}, d = {duty}: {} cycles",
                means.len()
            );
            assert_eq!(means[means.len() - 1], means[means.len() - 2]);
            let stick = point.model().stick_fraction;
            assert!(
                (run.stick_fraction - stick).abs() <= 1e-9,
                "{} vs {stick}",
                run.stick_fraction
            );
            assert!(run.stick_fraction > 0.0);
        }
    }
}

#[test]
fn paper_operating_point_feeds_at_eq15_with_stroke_eq5() {
    let spec = WaveformSpec::from_frequency(50.0, 0.586, Drive::Stroke { stroke_m: 0.0025 });
    let point = OperatingPoint::new(spec, Contact::kinetic(1.0, 1e-4).unwrap(), None).unwrap();
    let run = point.steady();
    // Eq. 5 inverted: a = x_max / (T(1 − d)/2)².
    let half_backward = PERIOD_S * (1.0 - 0.586) / 2.0;
    let accel = 0.0025 / (half_backward * half_backward);
    assert!(relative(run.feed_rate_mps, eq15(accel, PERIOD_S, 0.586)) <= 1e-9);
    assert!(relative(run.plate_excursion_m, 0.0025) <= 1e-12);
    assert_eq!(run.stick_fraction, 0.0);
}

#[test]
fn viscosity_fit_matches_eq10() {
    // Section IV.C in SI: T = 0.01 s, a = 100 m/s², μ = 0.5, m = 0.1 g, d from errata 8,
    // f = −15..15 dyn in 1 dyn steps.
    let (mu, mass, accel, period, duty) = (0.5, 1e-4, 100.0, 0.01, 0.5484);
    let forces: Vec<f64> = (-15..=15).map(|dyn_| f64::from(dyn_) * 1e-5).collect();
    let spec = WaveformSpec {
        period_s: period,
        duty,
        drive: Drive::Accel { accel_mps2: accel },
    };
    let contact = Contact::kinetic(mu, mass).unwrap();
    let fit = figures::viscosity(spec, &contact, &forces, None).unwrap();
    let expected_k = 4.0 * mu * mass * G / (accel * period);
    assert!(
        relative(fit.k_ns_per_m, expected_k) <= 1e-6,
        "K = {} vs {expected_k}",
        fit.k_ns_per_m
    );
    assert!(relative(fit.model_k_ns_per_m, expected_k) <= 1e-12);
    // Intercept −K·v_eq (Eq. 10 with the corrected sign).
    let intercept = -expected_k * eq15(accel, period, duty);
    assert!(relative(fit.intercept_n, intercept) <= 1e-6);
    assert_eq!(fit.points.len(), 31);
    assert!(fit
        .points
        .iter()
        .all(|point| !point.sticks && point.converged));
}

#[test]
fn large_forces_make_the_part_stick_and_leave_the_linear_law() {
    let spec = WaveformSpec {
        period_s: 0.01,
        duty: 0.5484,
        drive: Drive::Accel { accel_mps2: 100.0 },
    };
    let contact = Contact::kinetic(0.5, 1e-4).unwrap();
    // 4.5 mN pushes the part at 45 m/s², close to μg = 4.9 m/s².
    let fit = figures::viscosity(spec, &contact, &[-1e-4, 0.0, 1e-4, 4.5e-4], None).unwrap();
    let strong = fit.points.last().unwrap();
    assert!(strong.sticks);
    assert!(strong.model_velocity_mps.is_none());
    assert!(fit.points[..3].iter().all(|point| !point.sticks));
}

#[test]
fn fixed_step_agreement_tightens_as_the_step_shrinks() {
    for (duty, accel) in [(0.586, 146.0), (0.7, 146.0)] {
        let point = exact_point(duty, accel, 1.0);
        let exact = point.steady().feed_rate_mps;
        let segments = exact_cycle(&point.waveform);
        let errors: Vec<f64> = [200, 2_000, 20_000]
            .iter()
            .map(|&steps| {
                let run = run_fixed_step(&segments, &point.contact, steps, 150);
                relative(run.feed_rate_mps, exact)
            })
            .collect();
        assert!(
            errors[0] > errors[1] && errors[1] > errors[2],
            "d = {duty}: {errors:?}"
        );
        // First order: ten times smaller steps give at least three times smaller errors.
        assert!(
            errors[1] < errors[0] / 3.0 && errors[2] < errors[1] / 3.0,
            "{errors:?}"
        );
        assert!(errors[2] < 1e-3, "{errors:?}");
    }
}

#[test]
fn symmetric_limit_feeds_nothing() {
    // Eq. 15 is linear in d − 1/2: the feed vanishes in proportion as d → 0.5.
    for epsilon in [1e-3, 1e-5, 1e-7] {
        let run = exact_point(0.5 + epsilon, 146.0, 1.0).steady();
        let per_epsilon = run.feed_rate_mps / epsilon;
        assert!(
            relative(per_epsilon, 146.0 * PERIOD_S / 2.0) <= 1e-6,
            "ε = {epsilon:e}"
        );
    }
    let spec = WaveformSpec {
        period_s: PERIOD_S,
        duty: 0.5,
        drive: Drive::Accel { accel_mps2: 146.0 },
    };
    let refused = OperatingPoint::new(spec, Contact::kinetic(1.0, 1e-4).unwrap(), None);
    assert_eq!(
        refused.unwrap_err(),
        SimError::Shared(Error::DutyTooLow { duty: 0.5 })
    );
}

#[test]
fn plate_weaker_than_friction_carries_the_part_without_feed() {
    for accel in [0.5 * G, 0.999 * G, G] {
        for duty in [0.55, 0.586, 0.8] {
            let run = exact_point(duty, accel, 1.0).steady();
            // The part rides the plate, which returns to its start every cycle (to rounding).
            let scale = accel * PERIOD_S;
            assert!(
                run.feed_rate_mps.abs() <= 1e-14 * scale,
                "a = {accel}, d = {duty}"
            );
            assert_eq!(run.stick_fraction, 1.0);
            assert!(run.converged);
        }
    }
}

#[test]
fn static_friction_above_peak_accel_holds_the_part() {
    // a = 146 m/s² > μg but < μ_s·g with μ_s = 20: the part never breaks away.
    let waveform = exact_point(0.586, 146.0, 1.0).waveform;
    let contact = Contact::new(1.0, 20.0, G, 1e-4, 0.0).unwrap();
    let run = host_sim::run_table(
        &CycleTable::exact(&waveform, &contact),
        &RunOptions::converge(host_sim::Criteria::periodic(1e-12, 1.0)),
    );
    assert!(run.feed_rate_mps.abs() <= 1e-14 * 146.0 * PERIOD_S);
    assert_eq!(run.stick_fraction, 1.0);
    assert!(matches!(
        Contact::new(1.0, 0.5, G, 1e-4, 0.0),
        Err(SimError::StaticBelowKinetic { .. })
    ));
}

#[test]
fn higher_static_friction_never_speeds_the_part_past_eq15_when_sliding() {
    // While the part slides all cycle, static friction plays no part: the feed stays Eq. 15.
    let waveform = exact_point(0.56, 146.0, 1.0).waveform;
    let contact = Contact::new(1.0, 1.2, G, 1e-4, 0.0).unwrap();
    let run = host_sim::run_table(
        &CycleTable::exact(&waveform, &contact),
        &RunOptions::converge(host_sim::Criteria::periodic(1e-12, 1.0)),
    );
    assert!(relative(run.feed_rate_mps, eq15(146.0, PERIOD_S, 0.56)) <= 1e-9);
}

#[test]
fn tick_plan_approaches_exact_times_as_the_clock_speeds_up() {
    let contact = Contact::kinetic(1.0, 1e-4).unwrap();
    let spec = WaveformSpec::from_frequency(50.0, 0.7, Drive::Stroke { stroke_m: 0.0025 });
    let exact = OperatingPoint::new(spec, contact, None)
        .unwrap()
        .steady()
        .feed_rate_mps;
    let errors: Vec<f64> = [100_000, 1_000_000, 10_000_000]
        .iter()
        .map(|&clock| {
            let run = OperatingPoint::new(spec, contact, Some(clock))
                .unwrap()
                .steady();
            assert!(run.converged, "clock {clock}");
            relative(run.feed_rate_mps, exact)
        })
        .collect();
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    assert!(errors[2] < 1e-6, "{errors:?}");
}

#[test]
fn streamed_segments_match_the_cycle_table() {
    let point = exact_point(0.6, 146.0, 1.0);
    let cycle = exact_cycle(&point.waveform);
    let options = RunOptions {
        fixed_cycles: Some(300),
        ..RunOptions::converge(point.default_criteria())
    };
    let table = host_sim::run_table(
        &CycleTable::exact(&point.waveform, &point.contact),
        &options,
    );
    let streamed = run_segments(cycle.iter().copied().cycle(), &point.contact, &options);
    assert_eq!(table.cycles, 300);
    assert_eq!(streamed.cycles, 300);
    assert!(relative(streamed.feed_rate_mps, table.feed_rate_mps) <= 1e-12);
    // Streaming integrates the plate across cycles, so the rounding of the real-valued segment
    // durations accumulates over the 300 cycles (about 1e-13 m per cycle here).
    assert!(
        relative(streamed.plate_excursion_m, table.plate_excursion_m) <= 1e-9,
        "{} vs {}",
        streamed.plate_excursion_m,
        table.plate_excursion_m
    );
}

#[test]
fn trace_is_continuous_and_sticks_at_plate_velocity() {
    let point = exact_point(0.7, 146.0, 1.0);
    let options = RunOptions {
        fixed_cycles: Some(5),
        trace: true,
        ..RunOptions::converge(point.default_criteria())
    };
    let run = point.run(&options);
    let trace = &run.trace;
    assert!(trace
        .windows(2)
        .all(|pair| pair[1].time_s >= pair[0].time_s));
    let period = point.waveform.period_s;
    assert!((trace.last().unwrap().time_s - 5.0 * period).abs() < 1e-15);
    let mu_g = G;
    let mut sticks = 0;
    for pair in trace.windows(2) {
        let (from, to) = (pair[0], pair[1]);
        let slope = (to.part_velocity_mps - from.part_velocity_mps) / (to.time_s - from.time_s);
        let relative_velocity = from.part_velocity_mps - from.plate_velocity_mps;
        if to.time_s - from.time_s > 1e-9 && relative_velocity.abs() > 1e-12 {
            // Sliding: the part accelerates at exactly ±μg.
            assert!((slope.abs() - mu_g).abs() < 1e-6 * mu_g, "slope {slope}");
        }
        if from.event == EventKind::Stick {
            sticks += 1;
            assert_eq!(from.part_velocity_mps, from.plate_velocity_mps);
        }
    }
    assert_eq!(sticks, 5);
}

#[test]
fn external_force_shifts_the_feed_by_f_over_k() {
    let (mu, mass, accel, period, duty) = (0.5, 1e-4, 100.0, 0.01, 0.5484);
    let spec = WaveformSpec {
        period_s: period,
        duty,
        drive: Drive::Accel { accel_mps2: accel },
    };
    let k = 4.0 * mu * mass * G / (accel * period);
    for force in [-1e-4, 5e-5, 1.2e-4] {
        let contact = Contact::new(mu, mu, G, mass, force).unwrap();
        let run = OperatingPoint::new(spec, contact, None).unwrap().steady();
        let expected = eq15(accel, period, duty) + force / k;
        assert!(relative(run.feed_rate_mps, expected) <= 1e-9, "f = {force}");
    }
}

#[test]
fn shared_model_agrees_with_the_closed_forms_used_here() {
    let friction = feeder_shared::Friction::new(1.0, G).unwrap();
    for duty in [0.55, 0.6, 0.7, 0.9] {
        let spec = WaveformSpec {
            period_s: PERIOD_S,
            duty,
            drive: Drive::Accel { accel_mps2: 146.0 },
        };
        let waveform = Waveform::new(spec, &Limits::NONE).unwrap();
        let state = model::steady_state(&waveform, &friction);
        let expected = if duty <= eq16(146.0, G) {
            eq15(146.0, PERIOD_S, duty)
        } else {
            eq18(146.0, PERIOD_S, duty, G)
        };
        assert!(relative(state.feed_rate_mps, expected) <= 1e-12);
    }
}
