//! The command line's answers to a new user's input: negative numbers after a space, and one
//! clear `error:` line with exit code 2 for everything it cannot run.

mod support;

use std::time::Duration;

use support::{golden_log, run, scratch_dir, Outcome, REFUSAL_TIME};

/// Time allowed to runs that do compute something.
const RUN_TIME: Duration = Duration::from_secs(30);

fn refusal(args: &[&str]) -> Outcome {
    run(args, REFUSAL_TIME * 5)
}

fn json(outcome: &Outcome) -> serde_json::Value {
    assert_eq!(outcome.code(), Some(0), "{outcome:#?}");
    serde_json::from_str(&outcome.stdout).expect("the output is JSON")
}

#[test]
fn negative_force_after_a_space_gives_a_negative_force_result() {
    let outcome = run(&["simulate", "--force-n", "-0.0001", "--json"], RUN_TIME);
    let report = json(&outcome);
    assert_eq!(report["force_n"], -0.0001);
    assert!(report["feed_rate_mps"].as_f64().is_some(), "{report}");
    assert_eq!(outcome.stderr, "");
}

#[test]
fn negative_exponent_forms_after_a_space_are_numbers() {
    let report = json(&run(
        &[
            "simulate",
            "--force-n",
            "-1.5e-5",
            "--exact-times",
            "--json",
        ],
        RUN_TIME,
    ));
    assert_eq!(report["force_n"], -1.5e-5);
    let fit = json(&run(
        &[
            "viscosity",
            "--force-min-n",
            "-1e-4",
            "--force-max-n",
            "1e-4",
            "--points",
            "5",
            "--exact-times",
            "--json",
        ],
        RUN_TIME,
    ));
    assert_eq!(fit["points"][0]["force_n"], -1e-4);
}

/// The numeric flags of the waveform of one operating point.
const WAVE_FLAGS: &[&str] = &["--freq-hz", "--duty", "--stroke-m", "--accel-mps2"];

/// The numeric flags of the contact with one part.
const CONTACT_FLAGS: &[&str] = &[
    "--mu",
    "--mu-static",
    "--gravity-mps2",
    "--mass-kg",
    "--force-n",
];

/// The numeric flags of `simulate` and `trace`, which run one operating point.
const POINT_FLAGS: &[&[&str]] = &[WAVE_FLAGS, CONTACT_FLAGS, &["--clock-hz", "--cycles"]];

/// Every numeric flag of every subcommand, after the subcommand and a size that keeps its run
/// short.
const NUMERIC_FLAGS: &[(&str, &[&str], &[&[&str]])] = &[
    ("simulate", &[], POINT_FLAGS),
    (
        "sweep",
        &["--duties", "2"],
        &[
            &["--freq-hz", "--accel-mps2", "--duties"],
            CONTACT_FLAGS,
            &["--clock-hz"],
        ],
    ),
    (
        "viscosity",
        &["--points", "3"],
        &[&[
            "--freq-hz",
            "--duty",
            "--accel-mps2",
            "--mu",
            "--mu-static",
            "--gravity-mps2",
            "--mass-kg",
            "--force-min-n",
            "--force-max-n",
            "--points",
            "--clock-hz",
        ]],
    ),
    (
        "saturation",
        &["--points", "2"],
        &[&[
            "--freq-hz",
            "--mu",
            "--accel-min-mps2",
            "--accel-max-mps2",
            "--points",
            "--gravity-mps2",
        ]],
    ),
    ("trace", &[], POINT_FLAGS),
    ("hil", &[], &[CONTACT_FLAGS]),
];

#[test]
fn every_numeric_flag_reads_a_negative_number_after_a_space() {
    for (command, size, flags) in NUMERIC_FLAGS {
        for flag in flags.iter().flat_map(|group| group.iter()) {
            for value in ["-0.0001", "-1e-5", "-inf"] {
                let mut args = vec![*command, flag, value];
                if !size.contains(flag) {
                    args.extend(*size);
                }
                let outcome = run(&args, RUN_TIME);
                let stderr = &outcome.stderr;
                assert!(
                    !stderr.contains("unexpected argument")
                        && !stderr.contains("value is required"),
                    "{args:?}: {stderr}"
                );
                assert!(
                    matches!(outcome.code(), Some(0 | 2)) && outcome.stderr_lines().len() <= 1,
                    "{outcome:#?}"
                );
            }
        }
    }
}

#[test]
fn counts_beyond_their_limits_are_refused_up_front() {
    refusal(&["viscosity", "--points", "100000000"]).assert_refused(&[
        "--points",
        "100000000",
        "10000",
    ]);
    refusal(&["saturation", "--points", "100000000"]).assert_refused(&["--points", "10000"]);
    refusal(&["sweep", "--duties", "100000000"]).assert_refused(&["--duties", "10000"]);
    refusal(&["simulate", "--cycles", "100000000"]).assert_refused(&["--cycles", "10000000"]);
    refusal(&["simulate", "--cycles", "18446744073709551616"]).assert_refused(&["--cycles"]);
    refusal(&["sweep", "--accel-mps2", "100,150,200", "--duties", "5000"]).assert_refused(&[
        "--accel-mps2",
        "--duties 5000",
        "15000",
        "10000",
    ]);
    refusal(&["saturation", "--mu", "1,0.5", "--points", "6000"]).assert_refused(&[
        "--mu",
        "--points 6000",
        "10000",
    ]);
}

#[test]
fn trace_beyond_its_limit_is_refused_before_anything_is_drawn() {
    let dir = scratch_dir("trace-limit");
    let plot = dir.join("x.png");
    let plot = plot.to_str().expect("UTF-8 path");
    refusal(&["trace", "--cycles", "100000000", "--plot", plot]).assert_refused(&[
        "--cycles",
        "100000000",
        "10000",
    ]);
    assert!(!dir.join("x.png").exists());
}

#[test]
fn counts_at_their_limits_run() {
    let report = json(&run(
        &[
            "simulate",
            "--cycles",
            "10000000",
            "--exact-times",
            "--json",
        ],
        RUN_TIME,
    ));
    assert_eq!(report["cycles"], 10_000_000);
    let trace = json(&run(&["trace", "--cycles", "10000", "--json"], RUN_TIME));
    assert!(trace.as_array().is_some_and(|events| events.len() > 10_000));
}

#[test]
fn zero_counts_are_refused_naming_the_flag() {
    for (command, flag) in [
        ("simulate", "--cycles"),
        ("trace", "--cycles"),
        ("sweep", "--duties"),
        ("viscosity", "--points"),
        ("saturation", "--points"),
    ] {
        refusal(&[command, flag, "0"]).assert_refused(&[flag, "'0'"]);
        refusal(&[command, flag, "-3"]).assert_refused(&[flag, "'-3'"]);
    }
}

#[test]
fn frequencies_without_a_period_are_refused_naming_the_frequency() {
    for command in ["simulate", "sweep", "viscosity", "saturation", "trace"] {
        for (typed, shown) in [
            ("inf", "got inf"),
            ("-inf", "got -inf"),
            ("nan", "got NaN"),
            ("0", "got 0"),
            ("-50", "got -50"),
        ] {
            refusal(&[command, "--freq-hz", typed])
                .assert_refused(&["frequency (Hz) must be finite and greater than zero", shown]);
        }
    }
}

#[test]
fn unreadable_hil_inputs_end_with_one_line() {
    let dir = scratch_dir("hil-inputs");
    let garbage = dir.join("garbage.bin");
    std::fs::write(&garbage, [0u8, 0xff, 0xfe, b'\n', 0x80, 0x81]).expect("write");
    let long = dir.join("long.log");
    std::fs::write(&long, vec![b'x'; 100_000]).expect("write");
    let broken = dir.join("broken.log");
    std::fs::write(&broken, "EVT seg cycle=1 kind=sideways planned=0\n").expect("write");
    let directory = dir.to_str().expect("UTF-8 path");
    let missing = dir.join("missing.log");
    for (path, words) in [
        (&garbage, &["garbage.bin", "line 1 is not UTF-8 text"][..]),
        (&long, &["long.log", "line 1 is longer than"][..]),
        (
            &broken,
            &["broken.log", "line 1", "unknown segment kind `sideways`"][..],
        ),
        (&missing, &["missing.log", "No such file"][..]),
    ] {
        let path = path.to_str().expect("UTF-8 path");
        refusal(&["hil", "--input", path]).assert_refused(words);
    }
    let outcome = refusal(&["hil", "--input", directory]);
    outcome.assert_refused(&["cannot read", "directory"]);
    assert_eq!(
        outcome.stderr.matches("cannot read").count(),
        1,
        "{outcome:#?}"
    );
}

#[test]
fn a_hil_stream_without_segments_says_so() {
    let dir = scratch_dir("hil-empty");
    let empty = dir.join("empty.log");
    std::fs::write(&empty, "").expect("write");
    let chatter = dir.join("chatter.log");
    std::fs::write(&chatter, "INFO  booting\nINFO  stopped\n").expect("write");
    let panicked = dir.join("panicked.log");
    std::fs::write(
        &panicked,
        "INFO  booting\nERROR panicked at src/main.rs:1:1\n",
    )
    .expect("write");
    for path in [&empty, &chatter] {
        let path = path.to_str().expect("UTF-8 path");
        for open_ended in [false, true] {
            let mut args = vec!["hil", "--input", path];
            if open_ended {
                args.push("--open-ended");
            }
            let outcome = refusal(&args);
            outcome.assert_refused(&["holds no segments", "decoded event log"]);
            assert!(!outcome.stderr.contains("problem(s)"), "{outcome:#?}");
        }
    }
    let panicked = panicked.to_str().expect("UTF-8 path");
    refusal(&["hil", "--input", panicked])
        .assert_refused(&["holds no segments", "the firmware reported: ERROR panicked"]);
    refusal(&["hil"]).assert_refused(&["standard input holds no segments"]);
}

#[test]
fn a_passing_hil_log_still_passes() {
    let log = golden_log();
    let outcome = run(
        &[
            "hil",
            "--input",
            log.to_str().expect("UTF-8 path"),
            "--json",
        ],
        RUN_TIME,
    );
    assert_eq!(json(&outcome)["passed"], true);
}

/// The plant file most commands' plate runs take.
fn realistic_plant() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/plants/realistic.toml").to_string()
}

#[test]
fn unwritable_outputs_are_refused_before_anything_runs() {
    let dir = scratch_dir("outputs");
    let directory = dir.to_str().expect("UTF-8 path").to_string();
    let log = golden_log();
    let log = log.to_str().expect("UTF-8 path");
    let plant = realistic_plant();
    let missing_dir = dir.join("no/such/dir");
    let missing_dir = missing_dir.to_str().expect("UTF-8 path");
    let plot_in_missing = format!("{missing_dir}/x.svg");
    let csv_in_missing = format!("{missing_dir}/x.csv");
    let plot_is_dir = format!("{directory}/sub.svg");
    std::fs::create_dir_all(&plot_is_dir).expect("directory named like a plot");
    let wrong_format = format!("{directory}/x.jpg");
    for command in [
        &["simulate", "--exact-times"][..],
        &["trace"][..],
        &["sweep", "--duties", "2", "--exact-times"][..],
        &["viscosity", "--points", "3", "--exact-times"][..],
        &["saturation", "--points", "2", "--mu", "1"][..],
        &["hil", "--input", log][..],
        &["hil", "--input", log, "--plant", &plant][..],
        &["drift"][..],
        &["closed-loop", "--plant", &plant][..],
        &["family", "--inside", "1", "--outside", "0"][..],
        &["cosim", "--elf", log, "--plant", &plant][..],
    ] {
        for (flag, path, words) in [
            (
                "--csv",
                &csv_in_missing,
                &["cannot write", "does not exist"][..],
            ),
            (
                "--plot",
                &plot_in_missing,
                &["cannot write", "does not exist"][..],
            ),
            ("--plot", &plot_is_dir, &["cannot write", "directory"][..]),
            ("--plot", &wrong_format, &["x.jpg", ".svg or .png"][..]),
            ("--csv", &directory, &["cannot write", "directory"][..]),
        ] {
            let mut args = command.to_vec();
            args.extend([flag, path.as_str()]);
            run(&args, RUN_TIME).assert_refused(words);
        }
    }
    let log_in_missing = format!("{missing_dir}/cosim.log");
    run(
        &[
            "cosim",
            "--elf",
            log,
            "--plant",
            &plant,
            "--log",
            &log_in_missing,
        ],
        RUN_TIME,
    )
    .assert_refused(&["cosim.log", "does not exist"]);
}

/// A file that passes the check but cannot take the data (`/dev/full`): the finished report is
/// printed all the same, then the error, with exit code 2.
#[test]
fn a_finished_report_survives_an_output_that_fails() {
    let dir = scratch_dir("full");
    let full_chart = dir.join("full.svg");
    std::os::unix::fs::symlink("/dev/full", &full_chart).expect("a chart path on /dev/full");
    let full_chart = full_chart.to_str().expect("UTF-8 path");
    let plant = realistic_plant();
    for (args, report) in [
        (
            &[
                "closed-loop",
                "--plant",
                &plant,
                "--cycles",
                "60",
                "--csv",
                "/dev/full",
            ][..],
            "closed loop: ",
        ),
        (
            &[
                "closed-loop",
                "--plant",
                &plant,
                "--cycles",
                "60",
                "--plot",
                full_chart,
            ][..],
            "closed loop: ",
        ),
        (&["simulate", "--csv", "/dev/full"][..], "feed rate"),
        (
            &["simulate", "--csv", "/dev/full", "--json"][..],
            "\"feed_rate_mps\"",
        ),
    ] {
        let outcome = run(args, RUN_TIME);
        assert_eq!(outcome.code(), Some(2), "{outcome:#?}");
        assert!(outcome.stdout.contains(report), "{outcome:#?}");
        let lines = outcome.stderr_lines();
        assert_eq!(lines.len(), 1, "{outcome:#?}");
        assert!(lines[0].starts_with("error: cannot write "), "{outcome:#?}");
    }
}

#[test]
fn waveforms_beyond_the_machine_are_refused_unless_lifted() {
    let plant = realistic_plant();
    let beyond = "beyond the machine's drive limits, which the firmware refuses";
    // A bare number is metres: 2.5 is a 2.5 m stroke, not the console's 2.5 mm.
    refusal(&["simulate", "--stroke-m", "2.5"]).assert_refused(&[
        "stroke 2.5 m",
        beyond,
        "--no-drive-limits",
    ]);
    refusal(&["simulate", "--duty", "0.7"]).assert_refused(&["200 m/s²", beyond]);
    refusal(&["simulate", "--freq-hz", "40"]).assert_refused(&["40 Hz", beyond]);
    refusal(&["drift", "--duty", "0.7"]).assert_refused(&["200 m/s²", beyond]);
    let closed = refusal(&["closed-loop", "--plant", &plant, "--freq-hz", "100"]);
    closed.assert_refused(&["200 m/s²", beyond]);
    assert!(!closed.stderr.contains("--no-drive-limits"), "{closed:#?}");
    let closed = refusal(&[
        "closed-loop",
        "--plant",
        &plant,
        "--change-duty-at",
        "10",
        "--to-duty",
        "0.7",
    ]);
    closed.assert_refused(&["duty cycle 0.7", beyond]);
    let lifted = json(&run(
        &[
            "simulate",
            "--duty",
            "0.7",
            "--no-drive-limits",
            "--cycles",
            "3",
            "--json",
        ],
        RUN_TIME,
    ));
    assert!(lifted["accel_mps2"].as_f64() > Some(277.0), "{lifted}");
    let reason = lifted["beyond_drive_limits"].as_str().expect("the reason");
    assert!(reason.contains("200 m/s²"), "{reason}");
    let within = json(&run(&["simulate", "--cycles", "3", "--json"], RUN_TIME));
    assert_eq!(within["beyond_drive_limits"], serde_json::Value::Null);
    // The paper's figures go beyond the machine: Fig. 8 at d = 0.7 and 2.5 mm.
    let figure = run(&["trace", "--duty", "0.7", "--cycles", "1"], RUN_TIME);
    assert_eq!(figure.code(), Some(0), "{figure:#?}");
}

#[test]
fn a_stroke_typed_with_its_unit_reads_right() {
    for stroke in ["2.5mm", "0.0025m", "2500um", "2500µm", "2500μm", "0.0025"] {
        let report = json(&run(
            &["simulate", "--stroke-m", stroke, "--cycles", "1", "--json"],
            RUN_TIME,
        ));
        assert_eq!(report["stroke_m"], 0.0025, "{stroke}");
    }
    refusal(&["simulate", "--stroke-m", "2.5in"]).assert_refused(&[
        "'2.5in'",
        "--stroke-m",
        "m, mm, um or µm",
    ]);
}

#[test]
fn usage_errors_are_one_line() {
    refusal(&["simulate", "--frq-hz", "60"]).assert_refused(&["'--frq-hz'", "'--freq-hz'"]);
    refusal(&["simulate", "--stroke-m", "0.002", "--accel-mps2", "100"])
        .assert_refused(&["--stroke-m", "--accel-mps2"]);
    refusal(&["simulate", "--duty", "half"]).assert_refused(&["'half'", "--duty"]);
    refusal(&["simulate", "--mu"]).assert_refused(&["--mu"]);
    refusal(&["simulate", "--duty", "0.6\n0.7"]).assert_refused(&["--duty"]);
    refusal(&["feed"]).assert_refused(&["'feed'"]);
}
