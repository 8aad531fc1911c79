//! Plant files with sensors, and sensors reading the real plate's exact motion.

mod plate_support;

use std::path::Path;

use host_sim::contact::Contact;
use host_sim::plate::{PlantFile, PlateParams, Stepper};
use host_sim::segments::PlateSegment;
use host_sim::sensors::{Accelerometer, AccelerometerConfig, AdcConfig, Encoder, EncoderConfig};
use host_sim::sensors::{LightBarrier, LightBarrierConfig, PartMotion, PlateMotion};
use host_sim::SimError;
use plate_support::millisecond;

fn realistic() -> PlantFile {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/realistic.toml");
    PlantFile::from_path(&path).unwrap()
}

#[test]
fn the_realistic_plant_carries_an_encoder_an_accelerometer_and_a_light_barrier() {
    let plant = realistic();
    assert_eq!(plant.sensors.encoder.unwrap().resolution_m, 1e-6);
    assert_eq!(plant.sensors.accelerometer.unwrap().bandwidth_hz, 5000.0);
    assert_eq!(plant.sensors.light_barrier.unwrap().position_m, 0.05);
    assert_eq!(plant.sensors.lvdt, None);
    assert_eq!(
        PlateParams::from_path(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/realistic.toml")
        )
        .unwrap(),
        plant.plate
    );
}

#[test]
fn a_plant_without_sensors_has_none() {
    let plant = PlantFile::from_toml_str("test", "mass_kg = 2.0").unwrap();
    assert_eq!(plant.plate.mass_kg, 2.0);
    assert_eq!(plant.sensors, Default::default());
}

#[test]
fn sensor_keys_and_values_are_refused_by_name() {
    let unknown = "[sensors.encoder]\nresolution_m = 1e-6\nbogus = 1\n";
    match PlantFile::from_toml_str("test", unknown) {
        Err(SimError::PlantFile { reason, .. }) => assert!(reason.contains("bogus"), "{reason}"),
        other => panic!("{other:?}"),
    }
    let unknown_sensor = "[sensors.camera]\nfps = 30\n";
    match PlantFile::from_toml_str("test", unknown_sensor) {
        Err(SimError::PlantFile { reason, .. }) => assert!(reason.contains("camera"), "{reason}"),
        other => panic!("{other:?}"),
    }
    let negative = "[sensors.encoder]\nresolution_m = -1e-6\n";
    match PlantFile::from_toml_str("test", negative) {
        Err(error @ SimError::PlantFile { .. }) => {
            assert!(error.to_string().contains("resolution_m"), "{error}")
        }
        other => panic!("{other:?}"),
    }
    let not_a_table = "sensors = 3\n";
    assert!(matches!(
        PlantFile::from_toml_str("test", not_a_table),
        Err(SimError::PlantFile { .. })
    ));
    let plate_key = "mass_kg = 1.0\nbogus_kg = 2.0\n[sensors.encoder]\nresolution_m = 1e-6\n";
    match PlantFile::from_toml_str("test", plate_key) {
        Err(SimError::PlantFile { reason, .. }) => assert!(reason.contains("bogus_kg"), "{reason}"),
        other => panic!("{other:?}"),
    }
}

/// An offset `e` alone, zero command: the plate moves `e·t²/2`, and an encoder of resolution `r`
/// counts `floor(e·t²/(2r))` at every sample.
#[test]
fn an_encoder_counts_the_offset_drift_exactly() {
    let params = PlateParams {
        zero_offset_fraction: 0.005,
        ..PlateParams::default()
    };
    let e_mps2 = 0.005 * params.full_scale_accel_mps2;
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let mut stepper = Stepper::new(&params, &contact).unwrap().with_trajectory();
    for _ in 0..50 {
        stepper.segment(&millisecond(0.0)).unwrap();
    }
    let trajectory = stepper.trajectory();
    let resolution_m = 1e-7;
    let mut encoder = Encoder::new(EncoderConfig {
        resolution_m,
        index_m: None,
        reversed: false,
    })
    .unwrap();
    for k in 1..=100 {
        let t_s = k as f64 * 0.5e-3;
        let expected_m = 0.5 * e_mps2 * t_s * t_s;
        let x_m = PlateMotion::position_m(&trajectory, t_s);
        assert!(
            (x_m - expected_m).abs() <= 1e-13 * expected_m,
            "{x_m} {expected_m}"
        );
        let count = encoder.sample(&trajectory, t_s).unwrap().count;
        assert_eq!(count, (x_m / resolution_m).floor() as i64);
        assert!((count - (expected_m / resolution_m).floor() as i64).abs() <= 1);
    }
}

/// A plate with a 1 kHz current loop under a step command: its acceleration is
/// `a·(1 − e^{−2π·f_c·t})`. A noiseless accelerometer far faster than the samples reads, at
/// each sample, the acceleration it held from the previous one, to its ADC step.
#[test]
fn an_accelerometer_reads_the_current_loops_rise() {
    let params = PlateParams {
        current_bandwidth_hz: Some(1000.0),
        ..PlateParams::default()
    };
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let mut stepper = Stepper::new(&params, &contact).unwrap().with_trajectory();
    for _ in 0..5 {
        stepper.segment(&millisecond(100.0)).unwrap();
    }
    let trajectory = stepper.trajectory();
    let adc = AdcConfig {
        bits: 16,
        min_v: -10.0,
        max_v: 10.0,
    };
    let sensitivity = 0.0306;
    let mut accelerometer = Accelerometer::new(AccelerometerConfig {
        bandwidth_hz: 1e9,
        noise_mps2: 0.0,
        seed: 0,
        sensitivity_v_per_mps2: sensitivity,
        adc,
    })
    .unwrap();
    let lsb_mps2 = adc.lsb_v() / sensitivity;
    let rate_per_s = 2.0 * std::f64::consts::PI * 1000.0;
    let rise = |t_s: f64| 100.0 * (1.0 - (-rate_per_s * t_s).exp());
    accelerometer.sample(&trajectory, 0.0).unwrap();
    for k in 1..=50 {
        let t_s = k as f64 * 1e-4;
        let exact = PlateMotion::accel_mps2(&trajectory, t_s);
        assert!((exact - rise(t_s)).abs() < 1e-9, "{t_s}: {exact}");
        let read = accelerometer.sample(&trajectory, t_s).unwrap().accel_mps2;
        let held = rise(t_s - 1e-4);
        assert!((read - held).abs() <= lsb_mps2, "{t_s}: {read} {held}");
    }
}

/// On the ideal plate (no offset, no lag) with a constant command the part slides behind the
/// plate at `μ·g`: its front reaches a barrier at `s` when `μ·g·t²/2 = s`.
#[test]
fn a_light_barrier_sees_the_part_arrive_at_the_analytic_time() {
    let params = PlateParams {
        current_bandwidth_hz: Some(1e6),
        ..PlateParams::default()
    };
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let mut stepper = Stepper::new(&params, &contact).unwrap().with_trajectory();
    for _ in 0..100 {
        stepper.segment(&millisecond(20.0)).unwrap();
    }
    let trajectory = stepper.trajectory();
    let position_m = 1e-3;
    let barrier = LightBarrier::new(LightBarrierConfig {
        position_m,
        min_gap_s: 0.0,
    })
    .unwrap();
    let times: Vec<f64> = (0..=100).map(|k| k as f64 * 1e-3).collect();
    let edges = barrier.rising_edges(&trajectory, &times).unwrap();
    assert_eq!(edges.len(), 1);
    let mu_g = contact.kinetic_accel_mps2();
    // The force reaches its target within a few µs; the part's front lags it by under 1e-9 s.
    let expected_s = (2.0 * position_m / mu_g).sqrt();
    assert!(
        (edges[0] - expected_s).abs() < 1e-5,
        "{} {expected_s}",
        edges[0]
    );
    assert!(PartMotion::position_m(&trajectory, expected_s + 1e-4) > position_m);
}

#[test]
fn the_trajectory_passes_through_the_stepper_at_every_segment_end() {
    let plant = realistic();
    let params = PlateParams {
        end_stop_m: None,
        ..plant.plate
    };
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let mut stepper = Stepper::new(&params, &contact).unwrap().with_trajectory();
    let mut ends = Vec::new();
    for (k, accel) in [146.0, 0.0, -146.0, 146.0]
        .iter()
        .cycle()
        .take(40)
        .enumerate()
    {
        stepper
            .segment(&PlateSegment {
                duration_s: 1e-3 * (1 + k % 4) as f64,
                accel_mps2: *accel,
                starts_cycle: k % 4 == 0,
            })
            .unwrap();
        ends.push((
            stepper.time_s(),
            stepper.plate_position_m(),
            stepper.part_position_m(),
        ));
    }
    let trajectory = stepper.trajectory();
    for (t_s, x_m, p_m) in ends {
        let tolerance = 1e-12 * stepper.peak_excursion_m();
        assert!((PlateMotion::position_m(&trajectory, t_s) - x_m).abs() <= tolerance);
        assert!(
            (PartMotion::position_m(&trajectory, t_s) - p_m).abs() <= 1e-12 * p_m.abs().max(1e-9)
        );
    }
}
