//! Plant files: the shipped ones load; syntax errors, unknown keys, values of the wrong type and
//! out-of-range values are refused with the key (and its table) and the line and column named.

use std::path::Path;

use host_sim::error::PlantPlace;
use host_sim::plate::{PlantFile, PlateParams};
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

/// The place a plant file's text is refused at, and the reason.
fn refusal(text: &str) -> (PlantPlace, String) {
    match PlantFile::from_toml_str("plant.toml", text) {
        Err(SimError::PlantFile {
            place: Some(place),
            reason,
            ..
        }) => (place, reason),
        other => panic!("{text}: {other:?}"),
    }
}

fn at(line: usize, column: usize, key: &str) -> PlantPlace {
    PlantPlace {
        line,
        column,
        key: Some(key.to_owned()),
    }
}

#[test]
fn every_refusal_names_the_key_with_its_table_and_the_line_and_column() {
    let sensors = "mass_kg = 1.5\n\n[sensors.encoder]\n";
    let accelerometer = "[sensors.accelerometer]\nsensitivity_v_per_mps2 = 0.03\n\
                         bandwidth_hz = 1e3\nnoise_mps2 = 0.1\nseed = 1\n";
    for (text, place, reason) in [
        (
            "# the plate\nmass_kg = \"1.5\"\n".to_owned(),
            at(2, 11, "mass_kg"),
            "invalid type: string \"1.5\", expected f64",
        ),
        (
            "mass_kg = 1.5.3\n".to_owned(),
            at(1, 14, "mass_kg"),
            "invalid float",
        ),
        (
            "mass_kg = 1.0\ngain_positive = -1.0\n".to_owned(),
            at(2, 17, "gain_positive"),
            "must be finite and > 0, got -1",
        ),
        (
            "mass_kg = 1.0\n  mas_kg = 2.0\n".to_owned(),
            at(2, 3, "mas_kg"),
            "unknown field `mas_kg`",
        ),
        (
            format!("{sensors}resolution_m = \"fine\"\n"),
            at(4, 16, "[sensors.encoder] resolution_m"),
            "invalid type: string \"fine\", expected f64",
        ),
        (
            format!("{sensors}resolution_m = 1e-6\nbogus = 1\n"),
            at(5, 1, "[sensors.encoder] bogus"),
            "unknown field `bogus`",
        ),
        (
            format!("{sensors}resolution_m = -1e-6\n"),
            at(4, 16, "[sensors.encoder] resolution_m"),
            "must be finite and greater than zero, got -1e-6",
        ),
        (
            format!("{sensors}index_m = 0.0\n"),
            at(3, 1, "[sensors.encoder]"),
            "missing field `resolution_m`",
        ),
        (
            format!("{accelerometer}adc = {{ bits = 40, min_v = -5.0, max_v = 5.0 }}\n"),
            at(6, 16, "[sensors.accelerometer] adc.bits"),
            "must be from 1 to 32, got 40",
        ),
        (
            "[sensors.camera]\nfps = 30\n".to_owned(),
            at(1, 10, "[sensors.camera]"),
            "unknown field `camera`",
        ),
        (
            "mass_kg = 1.0\nmass_kg = 2.0\n".to_owned(),
            at(2, 1, "mass_kg"),
            "duplicate key",
        ),
        (
            format!("{sensors}resolution_m = 1e-6\nresolution_m = 2e-6\n"),
            at(5, 1, "[sensors.encoder] resolution_m"),
            "duplicate key",
        ),
        (
            "sensors = 3\n".to_owned(),
            at(1, 11, "sensors"),
            "invalid type: integer `3`",
        ),
    ] {
        let (refused_at, refused_for) = refusal(&text);
        assert_eq!(refused_at, place, "{text}");
        assert!(refused_for.contains(reason), "{text}: {refused_for}");
    }
}

#[test]
fn a_syntax_error_between_keys_names_its_line_and_column() {
    let (place, reason) = refusal("mass_kg = 1.0\n[sensors.encoder\n");
    assert!(
        matches!(
            place,
            PlantPlace {
                line: 2,
                column: 17,
                ..
            }
        ),
        "{place:?}"
    );
    assert!(reason.contains("unclosed table"), "{reason}");
    let (place, _) = refusal("mass_kg = 1.0\n= 2\n");
    assert_eq!(
        place,
        PlantPlace {
            line: 2,
            column: 1,
            key: None
        }
    );
}

#[test]
fn the_whole_message_reads_file_line_column_key_and_reason() {
    let error = PlantFile::from_toml_str("plant.toml", "mass_kg = \"1.5\"\n").unwrap_err();
    assert_eq!(
        error.to_string(),
        "cannot load the plant from plant.toml, line 1, column 11, key `mass_kg`: invalid type: \
         string \"1.5\", expected f64"
    );
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
            matches!(
                &error,
                SimError::PlantFile { place: Some(PlantPlace { line: 1, key: Some(k), .. }), .. }
                    if k == key
            ),
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

/// A shipped plant file states its facts itself: it cites no document the repository does not
/// hold, and no numbered erratum of a list the repository does not hold.
#[test]
fn the_shipped_plant_files_cite_nothing_outside_the_repository() {
    let repository = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let plants = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants");
    for entry in std::fs::read_dir(&plants).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(!text.contains("errata"), "{} cites errata", path.display());
        for word in text.split(|c: char| c.is_whitespace() || "(),;:`'\"".contains(c)) {
            if word.ends_with(".md") {
                assert!(
                    repository.join(word).exists() || plants.join(word).exists(),
                    "{} cites {word}, which the repository does not hold",
                    path.display()
                );
            }
        }
    }
}
