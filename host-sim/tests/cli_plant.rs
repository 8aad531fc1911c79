//! What the commands write for a real plate (`--plant`): the CSV and the chart show that plate,
//! not the ideal one.

mod support;

use std::time::Duration;

use support::{golden_log, run, scratch_dir};

const RUN_TIME: Duration = Duration::from_secs(60);

fn plant(name: &str) -> String {
    format!("{}/plants/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `hil --plant` with a plate that is not ideal writes the trace of that plate on the actual
/// edges, ending where the JSON says it hit its end stop; the end stop fails the run.
#[test]
fn hil_on_a_real_plate_writes_the_real_plate_s_trace() {
    let dir = scratch_dir("hil-plant");
    let csv = dir.join("trace.csv");
    let svg = dir.join("trace.svg");
    let log = golden_log();
    let outcome = run(
        &[
            "hil",
            "--input",
            log.to_str().expect("UTF-8 path"),
            "--plant",
            &plant("realistic.toml"),
            "--csv",
            csv.to_str().expect("UTF-8 path"),
            "--plot",
            svg.to_str().expect("UTF-8 path"),
            "--json",
        ],
        RUN_TIME,
    );
    assert_eq!(outcome.code(), Some(1), "{outcome:#?}");
    let report: serde_json::Value = serde_json::from_str(&outcome.stdout).expect("JSON");
    let end_stop_s = report["end_stop_after_s"].as_f64().expect("an end stop");
    assert_eq!(report["passed"], false);
    assert_eq!(
        report["failures"][0],
        "end stop at +5.0 mm after 0.1108 s, at +0.230 m/s on the actual edges"
    );
    assert_eq!(
        report["verdict_line"],
        "firmware in the loop: FAILED (end stop at +5.0 mm after 0.1108 s, at +0.230 m/s on the \
         actual edges)"
    );
    let text = std::fs::read_to_string(&csv).expect("the CSV");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("time_s,plate_position_m,plate_velocity_mps,part_velocity_mps,command_mps2")
    );
    let last: Vec<f64> = lines
        .last()
        .expect("rows")
        .split(',')
        .map(|field| field.parse().expect("a number"))
        .collect();
    assert!(
        (last[0] - end_stop_s).abs() < 1e-12,
        "{last:?}, end stop at {end_stop_s} s"
    );
    assert!((last[1] - 0.005).abs() < 1e-12, "{last:?}");
    let chart = std::fs::read_to_string(&svg).expect("the chart");
    assert!(chart.contains("plate position"));
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

/// A run the loop gives up on is an outcome too: exit code 2, and the JSON, the CSV and the
/// chart are written with the reason, the start-up's peak and the cycles that ran. The plate is
/// `realistic.toml` on a flexure of 37 kN/m (24.8 Hz: it turns the plate about half around in
/// a cycle at 50 Hz), which the cycle-rate loop cannot centre.
#[test]
fn closed_loop_writes_its_report_when_the_loop_gives_up() {
    let dir = scratch_dir("closed-loop-gives-up");
    let realistic = std::fs::read_to_string(plant("realistic.toml")).unwrap();
    let pushed = realistic
        .replace("spring_npm = 0.0", "spring_npm = 37000.0")
        .replace("spring_damping_nspm = 0.0", "spring_damping_nspm = 20.0");
    let plant_path = dir.join("pushed.toml");
    std::fs::write(&plant_path, pushed).unwrap();
    let (csv, chart) = (dir.join("run.csv"), dir.join("run.svg"));
    let outcome = run(
        &[
            "closed-loop",
            "--plant",
            plant_path.to_str().unwrap(),
            "--cycles",
            "100",
            "--json",
            "--csv",
            csv.to_str().unwrap(),
            "--plot",
            chart.to_str().unwrap(),
        ],
        RUN_TIME,
    );
    assert_eq!(outcome.code(), Some(2), "{outcome:#?}");
    let report: serde_json::Value = serde_json::from_str(&outcome.stdout).expect("JSON");
    let reason = report["gave_up"].as_str().expect("a reason");
    assert!(
        reason.contains("the closed loop stopped at t ="),
        "{reason}"
    );
    assert_eq!(report["passed"], false);
    // The probe and the hold swing the plate (0.59 mm) short of its ±5 mm end stops.
    let peak_m = report["startup_peak_m"].as_f64().unwrap();
    assert!(peak_m > 0.2e-3 && peak_m < 5e-3, "{peak_m}");
    let rows = std::fs::read_to_string(&csv).unwrap();
    assert!(rows.lines().count() > 2, "{rows}");
    assert!(std::fs::read_to_string(&chart).unwrap().contains("<svg"));
}
