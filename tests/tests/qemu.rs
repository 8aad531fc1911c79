//! The firmware in the loop under QEMU: the real firmware image (feature `board-qemu`) runs
//! scripted scenarios; its event stream is checked edge by edge against the shared scheduler and
//! drives the simulated part.
//!
//! These tests need the QEMU firmware's ELF in `FEEDER_QEMU_ELF`, `qemu-system-arm` and
//! `defmt-print`; `cargo xtask test` provides all three and runs them with `--ignored`.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use feeder_shared::{Limits, TickClock, TickPlan, Waveform, WaveformSpec};
use host_sim::hil::{self, Checker, EdgeTimes, Event};
use host_sim::plant::Contact;
use host_sim::scenario::OperatingPoint;

/// A scenario may take this long before it is killed and failed.
const TIMEOUT: Duration = Duration::from_secs(120);

fn elf() -> PathBuf {
    std::env::var_os("FEEDER_QEMU_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_QEMU_ELF must name the QEMU firmware (cargo xtask test sets it)")
}

/// Runs the QEMU firmware with the scenario arguments; returns its exit status and decoded log.
fn run_scenario(arguments: &[&str]) -> (ExitStatus, String) {
    let elf = elf();
    let mut semihosting = String::from("enable=on,target=native");
    for argument in arguments {
        semihosting.push_str(",arg=");
        semihosting.push_str(argument);
    }
    let mut emulator = Command::new("qemu-system-arm")
        .args([
            "-machine",
            "mps2-an386",
            "-cpu",
            "cortex-m4",
            "-display",
            "none",
        ])
        .args(["-monitor", "none", "-serial", "none", "-icount", "shift=4"])
        .args(["-semihosting-config", &semihosting, "-kernel"])
        .arg(&elf)
        .stdout(Stdio::piped())
        .spawn()
        .expect("qemu-system-arm must be installed");
    let raw = emulator.stdout.take().expect("piped");
    let mut decoder = Command::new("defmt-print")
        .arg("-e")
        .arg(&elf)
        .stdin(raw)
        .stdout(Stdio::piped())
        .spawn()
        .expect("defmt-print must be installed");
    let mut decoded = decoder.stdout.take().expect("piped");
    let reader = std::thread::spawn(move || {
        let mut log = String::new();
        decoded.read_to_string(&mut log).map(|_| log)
    });
    let started = Instant::now();
    let status = loop {
        if let Some(status) = emulator.try_wait().expect("QEMU can be waited for") {
            break status;
        }
        if started.elapsed() > TIMEOUT {
            let _ = emulator.kill();
            panic!("the scenario {arguments:?} ran longer than {TIMEOUT:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let log = reader
        .join()
        .expect("reader thread")
        .expect("decoded log is text");
    let _ = decoder.wait();
    (status, log)
}

fn golden_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("golden")
        .join("qemu-short-scenario.log")
}

#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn short_scenario_log_matches_the_golden_file_byte_for_byte() {
    let (status, log) = run_scenario(&["cycles=20", "ramp=4"]);
    assert!(status.success(), "the firmware failed:\n{log}");
    let path = golden_path();
    if std::env::var_os("FEEDER_BLESS").is_some() {
        std::fs::write(&path, &log).expect("golden file is writable");
        return;
    }
    let golden = std::fs::read_to_string(&path).expect("golden file exists");
    if golden != log {
        let line = golden
            .lines()
            .zip(log.lines())
            .position(|(expected, actual)| expected != actual)
            .unwrap_or_else(|| golden.lines().count().min(log.lines().count()));
        panic!(
            "the event log differs from {} at line {}:\n  expected: {:?}\n  actual:   {:?}\n\
             (if the change is intended, rerun with FEEDER_BLESS=1)",
            path.display(),
            line + 1,
            golden.lines().nth(line),
            log.lines().nth(line)
        );
    }
}

/// Runs 1000 cycles at `frequency_hz` with a soft start, a duty change and a soft stop, and
/// checks the run edge by edge and the part it carries.
fn thousand_cycles(frequency_hz: &str, stroke_m: &str) {
    let (status, log) = run_scenario(&[
        "cycles=1000",
        &format!("freq_hz={frequency_hz}"),
        &format!("stroke_m={stroke_m}"),
        "ramp=25",
    ]);
    assert!(status.success(), "the firmware failed:\n{}", tail(&log));
    let stream = hil::read_stream(log.as_bytes()).expect("the event stream is readable");
    assert!(
        stream.errors.is_empty(),
        "firmware errors: {:?}",
        stream.errors
    );

    let mut checker = Checker::new();
    for event in &stream.events {
        checker.feed(event);
    }
    let (report, edges, clock_hz) = checker.finish(true);
    assert!(report.passed(), "edge check failed: {:?}", report.problems);
    assert_eq!(
        report.matched, report.edges,
        "every edge equals the shared plan"
    );
    assert!(
        report.motion_cycles >= 1000,
        "{} motion cycles",
        report.motion_cycles
    );
    assert!(
        report.max_deviation_ticks() < 100,
        "software latency {} ticks",
        report.max_deviation_ticks()
    );

    // The scenario's plans: the initial one, its own start plan and the live duty change.
    let specs: Vec<WaveformSpec> = stream
        .events
        .iter()
        .filter_map(|event| match event {
            Event::Plan { spec, .. } => Some(*spec),
            _ => None,
        })
        .collect();
    let final_spec = *specs.last().expect("plans are reported");
    assert_eq!(
        final_spec.period_s,
        1.0 / frequency_hz.parse::<f64>().unwrap()
    );
    assert!(
        specs.windows(2).any(|pair| pair[0].duty != pair[1].duty),
        "the duty changed live"
    );

    // On the planned ticks the plate returns to within the plans' drift bounds, and the part
    // feeds as host-sim predicts for the same plan.
    let contact = Contact::kinetic(1.0, 1e-3).unwrap();
    let planned = hil::simulate(&edges, clock_hz, &contact, EdgeTimes::Planned);
    let predicted = OperatingPoint::new(final_spec, contact, Some(clock_hz))
        .unwrap()
        .steady();
    let close = |feed_rate_mps: f64| {
        (feed_rate_mps - predicted.feed_rate_mps).abs() < 1e-3 * predicted.feed_rate_mps
    };
    assert!(
        close(planned.feed_rate_mps),
        "{} vs {} m/s",
        planned.feed_rate_mps,
        predicted.feed_rate_mps
    );
    let bound_m: f64 = specs
        .iter()
        .map(|spec| {
            let waveform = Waveform::new(*spec, &Limits::NONE).unwrap();
            TickPlan::new(&waveform, TickClock::new(clock_hz))
                .unwrap()
                .drift_bound_m
        })
        .sum();
    assert!(
        planned.plate_drift_m.abs() <= bound_m,
        "plate drift {} m > {} m",
        planned.plate_drift_m,
        bound_m
    );
    // On the actual (software-timed) edges the feed rate relative to the plate is the same; late
    // edges only leave the plate a drift velocity, which the report shows.
    let actual = hil::simulate(&edges, clock_hz, &contact, EdgeTimes::Actual);
    assert!(
        close(actual.feed_rate_relative_mps),
        "{} vs {} m/s",
        actual.feed_rate_relative_mps,
        predicted.feed_rate_mps
    );
}

fn tail(log: &str) -> String {
    let lines: Vec<&str> = log.lines().collect();
    lines[lines.len().saturating_sub(20)..].join("\n")
}

#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn thousand_cycles_at_50_hz_follow_the_shared_plan() {
    thousand_cycles("50", "0.0025");
}

#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn thousand_cycles_at_100_hz_follow_the_shared_plan() {
    // a_max = 4·x/(T(1 − d))² stays below the firmware's 200 m/s² limit at 100 Hz.
    thousand_cycles("100", "0.0006");
}

#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn a_firmware_panic_fails_the_run_and_shows_its_message() {
    let (status, log) = run_scenario(&["cycles=100", "panic_at=30"]);
    assert!(
        !status.success(),
        "a panic must end the emulation with a failure code"
    );
    assert!(
        log.contains("panic requested at cycle 30"),
        "the panic message is shown:\n{}",
        tail(&log)
    );
}
