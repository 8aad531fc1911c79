//! Slide friction, the shipped realistic plant, and random plates: hand-derived motions of a
//! stick–slip slide, and runs that always end in a result.

mod plate_support;

use std::path::Path;

use host_sim::contact::Contact;
use host_sim::ideal::simulator::{run_segments, Criteria, RunOptions};
use host_sim::plate::{self, PlateParams};
use plate_support::{cycles, millisecond, options};
use proptest::prelude::*;

fn coulomb(friction_n: f64) -> PlateParams {
    PlateParams {
        coulomb_friction_n: friction_n,
        ..PlateParams::default()
    }
}

#[test]
fn a_force_below_the_slide_friction_leaves_the_plate_stuck() {
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let segments = std::iter::repeat(millisecond(1.5));
    let run = plate::run(&coulomb(2.0), &contact, segments, &options(50)).unwrap();
    assert_eq!(run.peak_excursion_m, 0.0);
    assert_eq!(run.mean_position_m, 0.0);
    assert_eq!(run.feed_rate_mps, 0.0);
}

#[test]
fn a_force_above_the_slide_friction_accelerates_by_the_difference() {
    // M = 1 kg, F = 5 N, F_c = 2 N: x = 3·t²/2.
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let segments = std::iter::repeat(millisecond(5.0));
    let run = plate::run(&coulomb(2.0), &contact, segments, &options(50)).unwrap();
    let peak = 3.0 * 0.05_f64.powi(2) / 2.0;
    assert!((run.peak_excursion_m - peak).abs() <= 1e-15, "{run:?}");
}

#[test]
fn a_coasting_slide_stops_where_friction_has_taken_its_energy() {
    // 10 m/s² for 10 ms against 2 N of friction on 1 kg (net 8 m/s²), then no command: the slide
    // decelerates at 2 m/s² and sticks at x₁ + v₁²/(2·2).
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let segments =
        std::iter::repeat_n(millisecond(10.0), 10).chain(std::iter::repeat(millisecond(0.0)));
    let run = plate::run(&coulomb(2.0), &contact, segments, &options(200)).unwrap();
    let (v1, x1) = (8.0 * 0.01, 8.0 * 0.01_f64.powi(2) / 2.0);
    let rest_m = x1 + v1 * v1 / 4.0;
    assert!((run.peak_excursion_m - rest_m).abs() <= 1e-15, "{run:?}");
    assert!((run.mean_position_m - rest_m).abs() <= 1e-15, "{run:?}");
}

#[test]
fn the_realistic_plant_drifts_into_its_end_stop() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/realistic.toml");
    let params = PlateParams::from_path(&path).unwrap();
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let run = plate::run(&params, &contact, cycles(0.586), &options(1000)).unwrap();
    let hit = run
        .end_stop
        .expect("without a position loop the plate drifts");
    println!("realistic plate: {run:?}");
    assert_eq!(hit.position_m.abs(), 0.005);
    assert!(hit.time_s > 0.0 && hit.time_s < 0.5, "{hit:?}");
    assert_eq!(run.peak_excursion_m, 0.005);
}

/// A plate with every non-ideality, centred by its spring.
fn random_plate() -> impl Strategy<Value = PlateParams> {
    (
        0.5..3.0_f64,
        -0.01..0.01_f64,
        (0.95..1.05_f64, 0.95..1.05_f64),
        prop::option::of(300.0..5000.0_f64),
        prop::option::of(150.0..600.0_f64),
        (0.0..5.0_f64, 0.0..20.0_f64),
        (0.0..5e4_f64, 0.0..50.0_f64),
        prop::option::of(0.002..0.02_f64),
    )
        .prop_map(
            |(
                mass_kg,
                offset,
                (gain_positive, gain_negative),
                bandwidth,
                limit,
                slide,
                spring,
                stop,
            )| {
                PlateParams {
                    mass_kg,
                    zero_offset_fraction: offset,
                    gain_positive,
                    gain_negative,
                    current_bandwidth_hz: bandwidth,
                    force_limit_n: limit,
                    coulomb_friction_n: slide.0,
                    viscous_friction_nspm: slide.1,
                    spring_npm: spring.0,
                    spring_damping_nspm: spring.1,
                    end_stop_m: stop,
                    ..PlateParams::default()
                }
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn the_ideal_plate_matches_the_piecewise_linear_simulator(
        duty in 0.52..0.95_f64,
        mu in 0.05..1.0_f64,
        extra in 0.0..0.5_f64,
    ) {
        let contact = Contact::new(mu, mu + extra, 9.81, 1e-4, 0.0).unwrap();
        let mut sim_options = RunOptions::converge(Criteria::periodic(1e-12, 1.0));
        sim_options.fixed_cycles = Some(6);
        let ideal = run_segments(cycles(duty), &contact, &sim_options);
        let real = plate::run(&PlateParams::default(), &contact, cycles(duty), &options(6)).unwrap();
        let scale = 146.0 * 0.02 / 4.0;
        prop_assert!((real.feed_rate_mps - ideal.feed_rate_mps).abs() <= 1e-12 * scale,
            "{} vs {}", real.feed_rate_mps, ideal.feed_rate_mps);
    }

    #[test]
    fn any_valid_plate_runs_to_a_result_within_its_stops(
        params in random_plate(),
        duty in 0.52..0.95_f64,
        mu in 0.05..1.0_f64,
    ) {
        let contact = Contact::kinetic(mu, 1e-4).unwrap();
        let run = plate::run(&params, &contact, cycles(duty), &options(5)).unwrap();
        prop_assert!(run.feed_rate_mps.is_finite() && run.mean_position_m.is_finite());
        if let Some(x_lim) = params.end_stop_m {
            prop_assert!(run.peak_excursion_m <= x_lim * (1.0 + 1e-12), "{:?}", run);
        }
        if run.end_stop.is_none() {
            prop_assert_eq!(run.cycles, 5);
        }
    }
}
