//! The exact real-plate solver against the fixed-step RK4 reference, refined until it stops
//! changing.

mod plate_support;

use std::path::Path;

use host_sim::contact::Contact;
use host_sim::plate::reference::run_fixed_step;
use host_sim::plate::{self, PlateParams, PlateRun, PlateRunOptions};
use plate_support::cycles;
use proptest::prelude::*;

/// Lag, spring and every other non-ideality the reference models.
fn lagging_sprung_plate() -> PlateParams {
    PlateParams {
        mass_kg: 1.5,
        zero_offset_fraction: 0.005,
        gain_positive: 1.02,
        gain_negative: 0.98,
        current_bandwidth_hz: Some(1000.0),
        force_limit_n: Some(215.0),
        viscous_friction_nspm: 5.0,
        spring_npm: 2.0e4,
        spring_damping_nspm: 20.0,
        ..PlateParams::default()
    }
}

const OPTIONS: PlateRunOptions = PlateRunOptions {
    cycles: 4,
    average_cycles: 2,
};

/// The reference halved from `T/500` until two runs agree to `1e-11` (at most `T/32000`), printed
/// beside the exact run.
fn refined(
    params: &PlateParams,
    contact: &Contact,
    duty: f64,
    options: &PlateRunOptions,
    exact: &PlateRun,
) -> PlateRun {
    let mut steps_per_cycle = 500.0;
    let mut previous: Option<PlateRun> = None;
    loop {
        let dt_s = 0.02 / steps_per_cycle;
        let run = run_fixed_step(params, contact, cycles(duty), options, dt_s).unwrap();
        println!(
            "d = {duty}: T/dt = {steps_per_cycle}: reference {:.15e}, exact {:.15e} m/s, \
             difference {:.2e} relative; end stop {:?} / {:?}",
            run.feed_rate_mps,
            exact.feed_rate_mps,
            (run.feed_rate_mps - exact.feed_rate_mps).abs() / exact.feed_rate_mps.abs(),
            run.end_stop.map(|hit| hit.time_s),
            exact.end_stop.map(|hit| hit.time_s),
        );
        let settled = previous.is_some_and(|p| {
            (p.feed_rate_mps - run.feed_rate_mps).abs() <= 1e-11 * run.feed_rate_mps.abs()
        });
        if settled || steps_per_cycle >= 32_000.0 {
            return run;
        }
        previous = Some(run);
        steps_per_cycle *= 2.0;
    }
}

fn assert_agree(params: &PlateParams, duty: f64, mu: f64, mu_static: f64) {
    let contact = Contact::new(mu, mu_static, 9.81, 1e-4, 0.0).unwrap();
    let exact = plate::run(params, &contact, cycles(duty), &OPTIONS).unwrap();
    let reference = refined(params, &contact, duty, &OPTIONS, &exact);
    let error = (reference.feed_rate_mps - exact.feed_rate_mps).abs() / exact.feed_rate_mps.abs();
    assert!(error < 1e-9, "feed rate relative error {error:e}");
    let position_error = (reference.mean_position_m - exact.mean_position_m).abs();
    assert!(
        position_error < 1e-9 * exact.peak_excursion_m,
        "{reference:?} {exact:?}"
    );
}

#[test]
fn exact_solver_agrees_with_the_refined_reference_with_lag_and_spring() {
    for (duty, mu, mu_static) in [(0.586, 0.3, 0.3), (0.7, 0.3, 0.45)] {
        assert_agree(&lagging_sprung_plate(), duty, mu, mu_static);
    }
}

#[test]
fn exact_solver_agrees_with_the_refined_reference_with_slide_friction() {
    let params = PlateParams {
        coulomb_friction_n: 4.0,
        ..lagging_sprung_plate()
    };
    for (duty, mu, mu_static) in [(0.586, 0.3, 0.3), (0.7, 0.3, 0.45)] {
        assert_agree(&params, duty, mu, mu_static);
    }
}

#[test]
fn exact_solver_agrees_where_the_current_loop_cannot_be_split_off() {
    // The slide's damping rate (c + b)/M equals the current loop's 2π·f_c: the two modes
    // coincide, so no step is coarser than the fine one.
    let current_bandwidth_hz = 1000.0;
    let params = PlateParams {
        spring_npm: 0.0,
        spring_damping_nspm: 0.0,
        viscous_friction_nspm: 1.5 * 2.0 * std::f64::consts::PI * current_bandwidth_hz,
        force_limit_n: None,
        ..lagging_sprung_plate()
    };
    assert_agree(&params, 0.586, 0.3, 0.3);
}

#[test]
fn exact_solver_agrees_on_a_soft_spring_with_long_coarse_steps() {
    let params = PlateParams {
        spring_npm: 50.0,
        spring_damping_nspm: 0.5,
        ..lagging_sprung_plate()
    };
    for (duty, mu, mu_static) in [(0.586, 0.3, 0.3), (0.65, 0.2, 0.5)] {
        assert_agree(&params, duty, mu, mu_static);
    }
}

#[test]
fn the_realistic_plant_hits_its_end_stop_when_the_reference_does() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/realistic.toml");
    let params = PlateParams::from_path(&path).unwrap();
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let options = PlateRunOptions {
        cycles: 100,
        average_cycles: 1,
    };
    let exact = plate::run(&params, &contact, cycles(0.586), &options).unwrap();
    let reference = refined(&params, &contact, 0.586, &options, &exact);
    let (hit, reference_hit) = (exact.end_stop.unwrap(), reference.end_stop.unwrap());
    assert!(
        (hit.time_s - reference_hit.time_s).abs() <= 1e-12,
        "{hit:?} {reference_hit:?}"
    );
    assert_eq!(hit.position_m, reference_hit.position_m);
    assert!((hit.velocity_mps - reference_hit.velocity_mps).abs() <= 1e-9 * hit.velocity_mps.abs());
}

#[test]
fn the_reference_refuses_a_step_that_is_not_positive() {
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    for dt_s in [0.0, -1e-5, f64::NAN] {
        assert!(run_fixed_step(
            &PlateParams::default(),
            &contact,
            cycles(0.6),
            &OPTIONS,
            dt_s
        )
        .is_err());
    }
}

#[test]
fn a_stream_that_ends_closes_its_last_cycle_in_both() {
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let params = lagging_sprung_plate();
    let options = PlateRunOptions {
        cycles: 10,
        average_cycles: 1,
    };
    let exact = plate::run(&params, &contact, cycles(0.6).take(12), &options).unwrap();
    let reference = run_fixed_step(
        &params,
        &contact,
        cycles(0.6).take(12),
        &options,
        0.02 / 8000.0,
    )
    .unwrap();
    assert_eq!((exact.cycles, reference.cycles), (3, 3));
    let error = (exact.feed_rate_mps - reference.feed_rate_mps).abs() / exact.feed_rate_mps;
    assert!(error < 1e-9, "{exact:?} {reference:?}");
}

/// Any plate with every non-ideality, end stops included.
fn any_plate() -> impl Strategy<Value = PlateParams> {
    (
        (
            0.5..3.0_f64,
            -0.01..0.01_f64,
            0.95..1.05_f64,
            0.95..1.05_f64,
        ),
        (
            prop::option::of(300.0..5000.0_f64),
            prop::option::of(150.0..600.0_f64),
        ),
        (0.0..5.0_f64, 0.0..20.0_f64, 0.0..5e4_f64, 0.0..50.0_f64),
        prop::option::of(0.002..0.02_f64),
    )
        .prop_map(
            |((mass_kg, offset, plus, minus), (bandwidth, limit), slide, stop)| PlateParams {
                mass_kg,
                zero_offset_fraction: offset,
                gain_positive: plus,
                gain_negative: minus,
                current_bandwidth_hz: bandwidth,
                force_limit_n: limit,
                coulomb_friction_n: slide.0,
                viscous_friction_nspm: slide.1,
                spring_npm: slide.2,
                spring_damping_nspm: slide.3,
                end_stop_m: stop,
                ..PlateParams::default()
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// At `T/8000` the reference is within 1e-7 of the velocity scale `a·T/4`; its peak, sampled
    /// at its steps, is at most the exact peak (up to its own error) and close below it.
    #[test]
    fn any_plate_agrees_with_the_reference(
        params in any_plate(),
        duty in 0.52..0.95_f64,
        mu in 0.05..1.0_f64,
        extra in 0.0..0.3_f64,
    ) {
        let contact = Contact::new(mu, mu + extra, 9.81, 1e-4, 0.0).unwrap();
        let options = PlateRunOptions { cycles: 3, average_cycles: 1 };
        let exact = plate::run(&params, &contact, cycles(duty), &options).unwrap();
        let reference =
            run_fixed_step(&params, &contact, cycles(duty), &options, 0.02 / 8000.0).unwrap();
        let scale_mps = 146.0 * 0.02 / 4.0;
        prop_assert!(
            (exact.feed_rate_mps - reference.feed_rate_mps).abs() <= 1e-7 * scale_mps,
            "{:?}\n{:?}", exact, reference
        );
        prop_assert_eq!(exact.cycles, reference.cycles);
        prop_assert_eq!(exact.end_stop.is_some(), reference.end_stop.is_some());
        let (peak, reference_peak) = (exact.peak_excursion_m, reference.peak_excursion_m);
        prop_assert!(reference_peak <= peak * (1.0 + 1e-8) + 1e-15, "{} {}", peak, reference_peak);
        prop_assert!(peak - reference_peak <= 1e-4 * peak, "{} {}", peak, reference_peak);
    }
}
