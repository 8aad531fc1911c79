//! The real plate's exact solver: the ideal limit against the piecewise-linear simulator,
//! hand-derived motions, and the plant files.

mod plate_support;

use host_sim::contact::Contact;
use host_sim::ideal::simulator::{run_segments, Criteria, RunOptions};
use host_sim::plate::{self, PlateParams, PlateRunOptions, Stepper};
use host_sim::segments::PlateSegment;
use plate_support::{cycles, millisecond, options};

/// A constant command of `accel_mps2` in segments of 1 ms, each starting a cycle.
fn constant(accel_mps2: f64) -> impl Iterator<Item = PlateSegment> {
    std::iter::repeat(millisecond(accel_mps2))
}

#[test]
fn ideal_plate_matches_the_piecewise_linear_simulator() {
    for (duty, mu, mu_static) in [(0.586, 0.3, 0.3), (0.7, 0.3, 0.3), (0.6, 0.25, 0.4)] {
        let contact = Contact::new(mu, mu_static, 9.81, 1e-4, 0.0).unwrap();
        let mut sim_options = RunOptions::converge(Criteria::periodic(1e-12, 1.0));
        sim_options.fixed_cycles = Some(12);
        let ideal = run_segments(cycles(duty), &contact, &sim_options);
        let real = plate::run(
            &PlateParams::default(),
            &contact,
            cycles(duty),
            &options(12),
        )
        .unwrap();
        let error = (real.feed_rate_mps - ideal.feed_rate_mps).abs() / ideal.feed_rate_mps.abs();
        println!(
            "d = {duty}: ideal {} real {} relative error {error:.2e}",
            ideal.feed_rate_mps, real.feed_rate_mps
        );
        assert!(error < 1e-12, "relative error {error:e}");
        assert_eq!(real.cycles, 12);
        assert!(real.end_stop.is_none());
    }
}

#[test]
fn a_constant_offset_moves_the_plate_by_half_e_t_squared() {
    let params = PlateParams {
        zero_offset_fraction: 0.01,
        full_scale_accel_mps2: 15.0,
        ..PlateParams::default()
    };
    let e: f64 = 0.15;
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let run = plate::run(&params, &contact, constant(0.0), &options(100)).unwrap();
    // Mean of e·t²/2 over the last 1 ms cycle, [0.099, 0.1] s.
    let (t0, t1) = (0.099_f64, 0.1_f64);
    let mean = e * (t1.powi(3) - t0.powi(3)) / 6.0 / (t1 - t0);
    assert!(
        (run.mean_position_m - mean).abs() <= 1e-13 * mean,
        "{run:?}"
    );
    assert!((run.peak_excursion_m - e * t1 * t1 / 2.0).abs() <= 1e-14);
    // The part sticks (0.15 m/s² ≪ μ_s·g) and moves with the plate: mean velocity e·(t0+t1)/2.
    let feed = e * (t0 + t1) / 2.0;
    assert!((run.feed_rate_mps - feed).abs() <= 1e-12 * feed, "{run:?}");
}

#[test]
fn the_end_stop_is_hit_at_the_analytic_time() {
    let params = PlateParams {
        zero_offset_fraction: 0.01,
        full_scale_accel_mps2: 15.0,
        end_stop_m: Some(0.005),
        ..PlateParams::default()
    };
    let e: f64 = 0.15;
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let run = plate::run(&params, &contact, constant(0.0), &options(1000)).unwrap();
    let hit = run.end_stop.expect("the plate drifts into its end stop");
    let time_s = (2.0 * 0.005 / e).sqrt();
    assert!((hit.time_s - time_s).abs() <= 1e-13, "{hit:?} vs {time_s}");
    assert!((hit.velocity_mps - e * time_s).abs() <= 1e-12, "{hit:?}");
    assert_eq!(hit.position_m, 0.005);
    assert_eq!(run.cycles, (time_s / 1e-3).floor() as u64);
}

#[test]
fn a_spring_alone_gives_the_closed_form_oscillation() {
    // A step force F₀ on M and k from rest: x = (F₀/k)(1 − cos ωt), peak 2F₀/k at t = π/ω.
    let params = PlateParams {
        mass_kg: 2.0,
        spring_npm: 8.0e4,
        ..PlateParams::default()
    };
    let accel = 10.0;
    let omega = (8.0e4_f64 / 2.0).sqrt();
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let steps = 40;
    let run = plate::run(&params, &contact, constant(accel), &options(steps)).unwrap();
    let static_m = 2.0 * accel / 8.0e4;
    let t = steps as f64 * 1e-3;
    assert!(t > std::f64::consts::PI / omega);
    assert!(
        (run.peak_excursion_m - 2.0 * static_m).abs() <= 1e-15,
        "{run:?}"
    );
    // Mean of x over the last millisecond.
    let integral = |t: f64| static_m * (t - (omega * t).sin() / omega);
    let mean = (integral(t) - integral(t - 1e-3)) / 1e-3;
    assert!(
        (run.mean_position_m - mean).abs() <= 1e-15,
        "{} vs {mean}",
        run.mean_position_m
    );
}

#[test]
fn bad_segments_and_windows_are_refused() {
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let params = PlateParams::default();
    for (duration_s, accel_mps2) in [(f64::NAN, 1.0), (-1e-3, 1.0), (1e-3, f64::INFINITY)] {
        let segment = PlateSegment {
            duration_s,
            accel_mps2,
            starts_cycle: true,
        };
        let result = plate::run(&params, &contact, std::iter::repeat(segment), &options(3));
        assert!(result.is_err(), "{duration_s} {accel_mps2}");
    }
    let window = PlateRunOptions {
        cycles: 2,
        average_cycles: 3,
    };
    assert!(plate::run(&params, &contact, constant(1.0), &window).is_err());
}

#[test]
fn a_trace_follows_the_run_it_records() {
    let params = PlateParams::from_path("plants/realistic.toml".as_ref()).unwrap();
    let contact = Contact::new(1.0, 1.0, 9.81, 1e-4, 0.0).unwrap();
    let run = plate::run(&params, &contact, cycles(0.586), &options(3)).unwrap();
    let (traced, points) = plate::trace(&params, &contact, cycles(0.586), &options(3)).unwrap();
    assert_eq!(traced, run);
    assert!(points.len() >= 3 * 6 * plate::TRACE_SAMPLES_PER_SEGMENT / 2);
    assert!(points.windows(2).all(|w| w[0].time_s <= w[1].time_s));
    let peak_m = points
        .iter()
        .map(|p| p.plate_position_m.abs())
        .fold(0.0, f64::max);
    assert!(peak_m <= run.peak_excursion_m * (1.0 + 1e-12));
    if let (Some(stop), Some(last)) = (run.end_stop, points.last()) {
        assert_eq!(last.time_s, stop.time_s);
    }
}

/// One of a stepper's readings.
type Reading = fn(&Stepper) -> f64;

/// Knowing the next segment lets the solver go on across the boundaries the command holds over
/// (the return and the next cycle's acceleration): the plate and the part end where a stepper
/// told nothing puts them, with a current loop and a spring, and at an end stop.
#[test]
fn knowing_the_next_segment_changes_nothing() {
    let lag_spring = PlateParams {
        mass_kg: 1.5,
        current_bandwidth_hz: Some(1000.0),
        spring_npm: 2e4,
        spring_damping_nspm: 20.0,
        ..PlateParams::default()
    };
    let realistic = PlateParams::from_path("plants/realistic.toml".as_ref()).unwrap();
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let segments: Vec<PlateSegment> = cycles(0.586).take(4 * 100).collect();
    for params in [lag_spring, realistic] {
        let mut blind = Stepper::new(&params, &contact).unwrap();
        let mut ahead = Stepper::new(&params, &contact).unwrap();
        for (k, segment) in segments.iter().enumerate() {
            blind.segment(segment).unwrap();
            ahead.segment_before(segment, segments.get(k + 1)).unwrap();
        }
        let quantities: [(&str, Reading, f64); 6] = [
            ("time", Stepper::time_s, 1.0),
            ("plate position", Stepper::plate_position_m, 1e-3),
            ("plate velocity", Stepper::plate_velocity_mps, 1.0),
            ("part position", Stepper::part_position_m, 1e-3),
            ("∫x dt", Stepper::position_integral_ms, 1e-6),
            ("peak excursion", Stepper::peak_excursion_m, 1e-3),
        ];
        for (what, of, scale) in quantities {
            let (a, b) = (of(&ahead), of(&blind));
            assert!(
                (a - b).abs() <= 1e-12 * scale.max(b.abs()),
                "{what}: {a:e} vs {b:e}"
            );
        }
        assert_eq!(ahead.end_stop().is_some(), blind.end_stop().is_some());
        if let (Some(a), Some(b)) = (ahead.end_stop(), blind.end_stop()) {
            assert!((a.time_s - b.time_s).abs() <= 1e-12, "{a:?} vs {b:?}");
        }
    }
}
