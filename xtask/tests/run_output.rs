//! What `cargo xtask run` writes where: its result alone on standard output (with `--json`, one
//! JSON document), everything else on standard error, and a refused scenario refused before
//! anything is built, with exit code 2.

use std::process::{Command, Output};

fn xtask(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .output()
        .expect("xtask runs")
}

#[test]
#[ignore = "builds the firmware and runs it under QEMU; `cargo xtask test` runs it"]
fn a_json_run_writes_one_json_document_on_standard_output() {
    let output = xtask(&["run", "cycles=20", "--", "--json"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let report: serde_json::Value =
        serde_json::from_slice(&output.stdout).unwrap_or_else(|error| {
            panic!(
                "standard output is not one JSON document ({error}):\n{}",
                String::from_utf8_lossy(&output.stdout)
            )
        });
    assert_eq!(report["passed"], true, "{report}");
    assert!(
        stderr.contains("Prediction at the paper's operating point"),
        "{stderr}"
    );
}

#[test]
fn a_scenario_the_board_cannot_play_is_refused_before_anything_is_built() {
    for (word, reason) in [
        ("duty=1.2", "duty cycle 1.2 must be below 1"),
        (
            "freq_hz=120",
            "frequency 120 Hz is outside the allowed band 50..=100 Hz",
        ),
    ] {
        let output = xtask(&["run", word]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{stderr}");
        assert!(output.stdout.is_empty());
        assert!(
            stderr.starts_with("xtask: scenario refused: the waveform at start"),
            "{stderr}"
        );
        assert!(stderr.contains(reason), "{stderr}");
        assert!(!stderr.contains("running"), "{stderr}");
    }
}

#[test]
fn a_missing_plant_file_is_refused_once_before_anything_is_built() {
    let output = xtask(&["run", "--plant", "nothere.toml"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("xtask: cannot read nothere.toml"),
        "{stderr}"
    );
}
