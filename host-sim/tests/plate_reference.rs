//! The exact real-plate solver against the fixed-step RK4 reference, refined until it stops
//! changing.

use feeder_shared::{Drive, Limits, Waveform, WaveformSpec};
use host_sim::plant::{Contact, PlateSegment};
use host_sim::plate::reference::run_fixed_step;
use host_sim::plate::{self, PlateParams, PlateRunOptions};
use host_sim::segments::exact_cycle;

fn cycles(duty: f64) -> impl Iterator<Item = PlateSegment> + Clone {
    let spec = WaveformSpec::from_frequency(50.0, duty, Drive::Accel { accel_mps2: 146.0 });
    let waveform = Waveform::new(spec, &Limits::NONE).unwrap();
    exact_cycle(&waveform).into_iter().cycle()
}

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

#[test]
fn exact_solver_agrees_with_the_refined_reference() {
    let params = lagging_sprung_plate();
    for (duty, mu, mu_static) in [(0.586, 0.3, 0.3), (0.7, 0.3, 0.45)] {
        let contact = Contact::new(mu, mu_static, 9.81, 1e-4, 0.0).unwrap();
        let exact = plate::run(&params, &contact, cycles(duty), &OPTIONS).unwrap();
        let mut steps_per_cycle = 500.0;
        let mut previous: Option<f64> = None;
        let reference = loop {
            let dt_s = 0.02 / steps_per_cycle;
            let run = run_fixed_step(&params, &contact, cycles(duty), &OPTIONS, dt_s).unwrap();
            let feed = run.feed_rate_mps;
            println!(
                "d = {duty}: T/dt = {steps_per_cycle}: reference {feed:.15e}, exact {:.15e}, \
                 difference {:.2e} relative",
                exact.feed_rate_mps,
                (feed - exact.feed_rate_mps).abs() / exact.feed_rate_mps.abs()
            );
            if previous.is_some_and(|p| (p - feed).abs() <= 1e-11 * feed.abs())
                || steps_per_cycle >= 64_000.0
            {
                break run;
            }
            previous = Some(feed);
            steps_per_cycle *= 2.0;
        };
        let error =
            (reference.feed_rate_mps - exact.feed_rate_mps).abs() / exact.feed_rate_mps.abs();
        assert!(error < 1e-9, "feed rate relative error {error:e}");
        let position_error = (reference.mean_position_m - exact.mean_position_m).abs();
        assert!(
            position_error < 1e-9 * exact.peak_excursion_m,
            "{reference:?} {exact:?}"
        );
    }
}

#[test]
fn the_reference_refuses_what_it_does_not_model() {
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let params = PlateParams {
        coulomb_friction_n: 1.0,
        ..PlateParams::default()
    };
    assert!(run_fixed_step(&params, &contact, cycles(0.6), &OPTIONS, 1e-5).is_err());
}
