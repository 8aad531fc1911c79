//! What the commands write for a real plate (`--plant`): the CSV and the chart show that plate,
//! not the ideal one.

mod support;

use std::time::Duration;

use support::{run, scratch_dir};

const RUN_TIME: Duration = Duration::from_secs(60);

fn plant(name: &str) -> String {
    format!("{}/plants/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `sweep --plant` reports each point's end stop in the JSON and the CSV: a time where the
/// plate hit one, null (an empty field) where it ran every cycle.
#[test]
fn sweep_on_a_real_plate_reports_each_point_s_end_stop() {
    let dir = scratch_dir("sweep-plant");
    let lagging = dir.join("lagging.toml");
    std::fs::write(&lagging, "mass_kg = 1.5\ncurrent_bandwidth_hz = 1000.0\n").expect("plant");
    let csv = dir.join("sweep.csv");
    let sweep = |plant: &str, csv: Option<&str>| {
        let mut args = vec![
            "sweep",
            "--plant",
            plant,
            "--accel-mps2",
            "150",
            "--duties",
            "2",
            "--cycles",
            "30",
            "--json",
        ];
        if let Some(csv) = csv {
            args.extend(["--csv", csv]);
        }
        let outcome = run(&args, RUN_TIME);
        assert_eq!(outcome.code(), Some(0), "{outcome:#?}");
        serde_json::from_str::<serde_json::Value>(&outcome.stdout).expect("JSON")
    };
    let stopped = sweep(&plant("realistic.toml"), None);
    for point in stopped.as_array().expect("points") {
        assert!(point["end_stop_after_s"].as_f64().is_some(), "{point}");
        assert!(point["cycles"].as_u64().expect("cycles") < 30, "{point}");
    }
    let centred = sweep(
        lagging.to_str().expect("UTF-8 path"),
        csv.to_str().map(Some).expect("UTF-8 path"),
    );
    for point in centred.as_array().expect("points") {
        assert!(point["end_stop_after_s"].is_null(), "{point}");
        assert_eq!(point["cycles"], 30);
        let mean_m = point["mean_position_m"].as_f64().expect("a mean position");
        assert!(mean_m > 0.0 && mean_m < 0.0025, "{point}");
    }
    let text = std::fs::read_to_string(&csv).expect("the CSV");
    let header: Vec<&str> = text.lines().next().expect("a header").split(',').collect();
    let column = header
        .iter()
        .position(|name| *name == "end_stop_after_s")
        .expect("an end-stop column");
    for row in text.lines().skip(1) {
        assert_eq!(row.split(',').nth(column), Some(""), "{row}");
    }
}
