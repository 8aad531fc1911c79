//! Plant files: the shipped ones load, unknown keys and out-of-range values are refused with
//! the key named.

use std::path::Path;

use host_sim::plate::PlateParams;
use host_sim::SimError;
use proptest::prelude::*;

fn plant(name: &str) -> Result<PlateParams, SimError> {
    PlateParams::from_path(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("plants")
            .join(name),
    )
}

#[test]
fn the_ideal_plant_file_is_the_default_plate() {
    let params = plant("ideal.toml").unwrap();
    assert_eq!(params, PlateParams::default());
    assert!(params.is_ideal());
    assert_eq!(
        PlateParams::from_toml_str("").unwrap(),
        PlateParams::default()
    );
}

#[test]
fn the_realistic_plant_file_loads_with_every_non_ideality() {
    let params = plant("realistic.toml").unwrap();
    assert!(!params.is_ideal());
    assert!(params.zero_offset_fraction >= 0.005);
    assert!((params.gain_positive - params.gain_negative).abs() >= 0.04 - 1e-12);
    assert_eq!(params.current_bandwidth_hz, Some(1000.0));
    assert!(params.force_limit_n.is_some());
    assert!(params.coulomb_friction_n > 0.0);
    assert_eq!(params.end_stop_m, Some(0.005));
}

#[test]
fn an_unknown_key_is_refused_by_name() {
    let error = PlateParams::from_toml_str("mass_kg = 1.0\nmas_kg = 2.0\n").unwrap_err();
    assert!(matches!(error, SimError::PlantFile { .. }));
    assert!(error.to_string().contains("mas_kg"), "{error}");
}

#[test]
fn a_missing_file_is_an_input_error() {
    assert!(matches!(plant("absent.toml"), Err(SimError::Input { .. })));
}

#[test]
fn out_of_range_values_are_refused_by_name() {
    for (text, key) in [
        ("mass_kg = -1.0", "mass_kg"),
        ("mass_kg = nan", "mass_kg"),
        ("gain_positive = 0.0", "gain_positive"),
        ("gain_negative = -0.5", "gain_negative"),
        ("zero_offset_fraction = 1.5", "zero_offset_fraction"),
        ("current_bandwidth_hz = 0.0", "current_bandwidth_hz"),
        ("force_limit_n = inf", "force_limit_n"),
        ("coulomb_friction_n = -2.0", "coulomb_friction_n"),
        ("viscous_friction_nspm = -1.0", "viscous_friction_nspm"),
        ("spring_npm = -1.0", "spring_npm"),
        ("spring_damping_nspm = nan", "spring_damping_nspm"),
        ("end_stop_m = 0.0", "end_stop_m"),
        ("full_scale_accel_mps2 = 0.0", "full_scale_accel_mps2"),
    ] {
        let error = PlateParams::from_toml_str(text).unwrap_err();
        assert!(
            matches!(error, SimError::PlantValue { key: k, .. } if k == key),
            "{text}: {error:?}"
        );
        assert!(error.to_string().contains(key), "{error}");
    }
}

proptest! {
    #[test]
    fn any_positive_mass_and_gains_are_accepted_and_round_trip(
        mass_kg in 1e-3..1e3_f64,
        gain_positive in 0.5..1.5_f64,
        gain_negative in 0.5..1.5_f64,
    ) {
        let text = format!(
            "mass_kg = {mass_kg:?}\ngain_positive = {gain_positive:?}\ngain_negative = {gain_negative:?}\n"
        );
        let params = PlateParams::from_toml_str(&text).unwrap();
        prop_assert_eq!(params.mass_kg, mass_kg);
        prop_assert_eq!(params.gain_positive, gain_positive);
        prop_assert_eq!(params.gain_negative, gain_negative);
    }

    #[test]
    fn any_negative_value_of_a_non_negative_key_is_refused(value in -1e6..-1e-9_f64) {
        for key in ["coulomb_friction_n", "viscous_friction_nspm", "spring_npm", "spring_damping_nspm"] {
            let error = PlateParams::from_toml_str(&format!("{key} = {value:?}")).unwrap_err();
            prop_assert!(error.to_string().contains(key), "{}", error);
        }
    }
}

#[test]
fn every_single_non_ideality_makes_the_plate_non_ideal() {
    for text in [
        "zero_offset_fraction = 0.001",
        "gain_positive = 1.01",
        "gain_negative = 0.99",
        "current_bandwidth_hz = 1000.0",
        "force_limit_n = 300.0",
        "coulomb_friction_n = 1.0",
        "viscous_friction_nspm = 1.0",
        "spring_npm = 1.0",
        "spring_damping_nspm = 1.0",
        "end_stop_m = 0.005",
    ] {
        assert!(
            !PlateParams::from_toml_str(text).unwrap().is_ideal(),
            "{text}"
        );
    }
    // Mass and full scale do not change what an ideal plate does.
    let scaled = PlateParams::from_toml_str("mass_kg = 3.0\nfull_scale_accel_mps2 = 50.0").unwrap();
    assert!(scaled.is_ideal());
}
