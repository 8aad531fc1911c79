//! `feeder-ctl calibrate`: a guided calibration of the drive, step by step on the board's own
//! closed loop, judged by `feeder_shared::calibration`:
//!
//! 1. **The board**: stopped, no fault latched, a closed loop to run; its DAC calibration.
//! 2. **The encoder's direction**, by hand, on a terminal: with the driver off the operator
//!    pushes the plate forward, and the position the telemetry shows must rise; a fall refuses
//!    the calibration and names the setting to flip. Headless, the drive's step stands in: the
//!    closed loop's settle refuses a backwards encoder (`loop_error=encoder-reversed`).
//! 3. **The drive**: a start, on which the closed loop settles, probes and identifies the drive
//!    (gains, zero offset, the current loop's lag), then a stop; every step ends with the plate
//!    stopped, and `stop` from any console stops it meanwhile.
//! 4. **The verdict**: each check against the envelope's limits, and the zero code that takes
//!    the offset off.
//! 5. **Saving**, with the operator's consent (`--save`, or a `y` on a terminal): `config set
//!    dac_zero`, `config save`, `restart`.
//!
//! Every step is printed as it runs; `--report FILE` writes them all, one `key=value` a line.

use std::fmt::Write as _;
use std::io::{self, BufRead, IsTerminal, Write};
use std::path::Path;
use std::thread;
use std::time::{Duration, Instant};

use feeder_shared::calibration::DriveVerdict;
use feeder_shared::closed_loop::{Identified, ENVELOPE};
use feeder_shared::DacCalibration;

use crate::console::{field, uptime_s, Console};

/// How often the drive's step asks for the board's status.
const POLL: Duration = Duration::from_millis(200);
/// The longest the drive's step waits for the identification, in the board's seconds.
const DRIVE_LIMIT_S: f64 = 60.0;
/// The least a push by hand must move the plate, m: two counts of a 1 µm encoder.
const HAND_PUSH_MIN_M: f64 = 2e-6;

/// How the calibration ended.
pub enum Outcome {
    /// Every check passed; saved where something was to save and the operator agreed.
    Accepted,
    /// A check failed or the board refused: the reason.
    Refused(String),
}

/// The calibration's record: every step's findings, for the report.
#[derive(Default)]
struct Report {
    lines: Vec<(String, String)>,
}

impl Report {
    fn note(&mut self, key: &str, value: impl std::fmt::Display) {
        self.lines.push((key.to_string(), value.to_string()));
    }

    fn text(&self) -> String {
        let mut text = String::from("# feeder calibration\n");
        for (key, value) in &self.lines {
            let _ = writeln!(text, "{key}={value}");
        }
        text
    }
}

/// Runs the calibration on `console`; saves with `save` (or the operator's consent on a
/// terminal); writes the report to `report` if given, also when it was refused.
pub fn run(console: &mut Console, save: bool, report_path: Option<&Path>) -> io::Result<Outcome> {
    let mut report = Report::default();
    let outcome = steps(console, save, &mut report);
    if let Some(path) = report_path {
        match &outcome {
            Ok(Outcome::Accepted) => report.note("outcome", "accepted"),
            Ok(Outcome::Refused(reason)) => report.note("outcome", format!("refused: {reason}")),
            Err(error) => report.note("outcome", format!("failed: {error}")),
        }
        std::fs::write(path, report.text())?;
        eprintln!(
            "feeder-ctl: calibration report written to {}",
            path.display()
        );
    }
    outcome
}

fn steps(console: &mut Console, save: bool, report: &mut Report) -> io::Result<Outcome> {
    println!("step 1/5: the board");
    let status = console.command("status")?;
    report.note("status_before", &status);
    if !status.starts_with("OK state=stopped") {
        return Ok(Outcome::Refused(format!(
            "the feeder must be stopped with no fault latched: {status}"
        )));
    }
    let closed_loop = console.command("config get closed_loop")?;
    if closed_loop != "OK closed_loop=on" {
        return Ok(Outcome::Refused(format!(
            "the calibration runs on the closed loop, which this board does not run \
             (`config get closed_loop`: {closed_loop})"
        )));
    }
    let dac = DacCalibration {
        zero_code: config_number(console, "dac_zero")? as u16,
        counts_per_mps2: config_number(console, "dac_counts_per_mps2")?,
        linear_margin_counts: config_number(console, "dac_margin")? as u16,
        ..DacCalibration::DEFAULT
    };
    println!(
        "  stopped; DAC zero code {}, {} counts per m/s2",
        dac.zero_code, dac.counts_per_mps2
    );
    report.note("dac_zero", dac.zero_code);
    report.note("dac_counts_per_mps2", dac.counts_per_mps2);

    println!("step 2/5: the encoder's direction");
    if io::stdin().is_terminal() {
        if let Some(refused) = direction_by_hand(console, report)? {
            return Ok(Outcome::Refused(refused));
        }
    } else {
        println!("  headless: the closed loop's settle checks it on the drive's step");
        report.note("direction", "checked by the drive's step");
    }

    println!("step 3/5: the drive (start, settle, probe, identify, stop)");
    let drive = match identify(console, report)? {
        Ok(drive) => drive,
        Err(refused) => return Ok(Outcome::Refused(refused)),
    };

    println!("step 4/5: the verdict");
    let verdict = DriveVerdict::judge(&drive, &dac);
    let checks = [
        (
            "gains",
            verdict.gains_within,
            format!(
                "+a {:.5}, -a {:.5} (within {} to {})",
                drive.gain_positive, drive.gain_negative, ENVELOPE.gain_min, ENVELOPE.gain_max
            ),
        ),
        (
            "lag",
            verdict.lag_within,
            format!(
                "{:.3} ms (at most {:.3} ms)",
                drive.lag_s * 1e3,
                ENVELOPE.lag_max_s() * 1e3
            ),
        ),
        (
            "offset",
            verdict.offset_within,
            format!(
                "{:.3} m/s2, {:.1} counts (at most {:.2} m/s2)",
                drive.offset_mps2,
                verdict.offset_counts,
                ENVELOPE.offset_max_mps2()
            ),
        ),
    ];
    for (name, passed, text) in &checks {
        println!(
            "  {name:<7} {} {text}",
            if *passed { "ok  " } else { "FAIL" }
        );
        report.note(
            name,
            format!("{} {text}", if *passed { "ok" } else { "fail" }),
        );
    }
    if !verdict.accepted() {
        return Ok(Outcome::Refused(
            "the drive lies outside the envelope the closed loop holds (docs/closed-loop.md)"
                .into(),
        ));
    }

    println!("step 5/5: saving");
    let Some(zero_code) = verdict.proposed_zero_code else {
        println!("  the zero code is within half a count: nothing to change");
        report.note("proposed_dac_zero", "none");
        return Ok(Outcome::Accepted);
    };
    println!(
        "  proposed: dac_zero {} (from {}), taking the {:.1} counts of offset off",
        zero_code, dac.zero_code, verdict.offset_counts
    );
    report.note("proposed_dac_zero", zero_code);
    if !(save
        || consent(&format!(
            "save dac_zero={zero_code} on the board and restart it?"
        ))?)
    {
        println!("  not saved: `config set dac_zero {zero_code}`, `config save`, `restart` do it");
        report.note("saved", "no");
        return Ok(Outcome::Accepted);
    }
    for line in [
        format!("config set dac_zero {zero_code}"),
        "config save".into(),
        "restart".into(),
    ] {
        let reply = console.command(&line)?;
        println!("  > {line}\n  {reply}");
        if !reply.starts_with("OK") {
            return Ok(Outcome::Refused(format!(
                "the board refused {line}: {reply}"
            )));
        }
    }
    report.note("saved", "yes");
    Ok(Outcome::Accepted)
}

/// The direction by hand: the plate's position before and after the operator's push; the
/// refusal if it fell.
fn direction_by_hand(console: &mut Console, report: &mut Report) -> io::Result<Option<String>> {
    let before_m = latest_position(console)?;
    print!("  with the driver off, push the plate forward by hand, then press Enter ");
    io::stdout().flush()?;
    let mut line = String::new();
    io::stdin().lock().read_line(&mut line)?;
    let after_m = latest_position(console)?;
    let moved_m = match (before_m, after_m) {
        (Some(before), Some(after)) => after - before,
        _ => {
            println!("  no position in the telemetry: skipped");
            report.note("direction", "skipped: no position");
            return Ok(None);
        }
    };
    report.note("direction_moved_um", format!("{:.1}", moved_m * 1e6));
    if moved_m <= -HAND_PUSH_MIN_M {
        return Ok(Some(format!(
            "the encoder counts backwards: a push forward read as {:.1} um; flip it \
             (config set encoder_dir reversed, config save, restart)",
            moved_m * 1e6
        )));
    }
    if moved_m < HAND_PUSH_MIN_M {
        println!("  the plate did not move: skipped, the drive's step checks it");
        report.note("direction", "skipped: no push");
    } else {
        println!("  forward, {:.1} um: ok", moved_m * 1e6);
        report.note("direction", "forward");
    }
    Ok(None)
}

/// The plate's position as the newest telemetry record has it.
fn latest_position(console: &mut Console) -> io::Result<Option<f64>> {
    console.command("telemetry on")?;
    console.listen(Duration::from_millis(300))?;
    console.command("telemetry off")?;
    Ok(console
        .take_telemetry()
        .iter()
        .rev()
        .find_map(|record| record.mean_m))
}

/// Starts the feeder, waits for the identified drive, stops it: the drive, or why not.
fn identify(console: &mut Console, report: &mut Report) -> io::Result<Result<Identified, String>> {
    let started = console.command("start")?;
    if !started.starts_with("OK") {
        return Ok(Err(format!("the board refused start: {started}")));
    }
    let start_s = uptime_s(&console.command("status")?).unwrap_or(0.0);
    let found = loop {
        thread::sleep(POLL);
        let status = console.command("status")?;
        let stage = field(&status, "loop").unwrap_or("-").to_string();
        let failed = stage == "failed" || status.starts_with("OK state=fault");
        if failed || field(&status, "gain_pos").is_some() {
            break (status, failed);
        }
        if uptime_s(&status).is_some_and(|now| now - start_s > DRIVE_LIMIT_S) {
            break (status, true);
        }
    };
    let (status, failed) = found;
    report.note("status_identified", &status);
    stop(console)?;
    if failed {
        let error = field(&status, "loop_error").unwrap_or("none");
        report.note("loop_error", error);
        let reason = match error {
            "encoder-reversed" => "the encoder counts backwards (the closed loop's settle saw \
                 the plate accelerate against its command): flip it (config set encoder_dir \
                 reversed, config save, restart) and calibrate again"
                .to_string(),
            "loop-limit" if field(&status, "gain_pos").is_none() => format!(
                "the closed loop lost the plate before it identified the drive ({error}): an \
                 encoder that counts backwards does that; flip it (config set encoder_dir \
                 reversed, config save, restart) and calibrate again, or check the driver's \
                 zero: {status}"
            ),
            _ => format!("the closed loop stopped ({error}); the board's log says why: {status}"),
        };
        return Ok(Err(reason));
    }
    let number = |key| field(&status, key).and_then(|value| value.parse::<f64>().ok());
    match (
        number("gain_pos"),
        number("gain_neg"),
        number("offset_mps2"),
        number("lag_ms"),
    ) {
        (Some(gain_positive), Some(gain_negative), Some(offset_mps2), Some(lag_ms)) => {
            println!(
                "  identified: gains {gain_positive} / {gain_negative}, offset {offset_mps2} \
                 m/s2, lag {lag_ms} ms"
            );
            Ok(Ok(Identified {
                gain_positive,
                gain_negative,
                offset_mps2,
                lag_s: lag_ms * 1e-3,
                ..Identified::NOMINAL
            }))
        }
        _ => Ok(Err(format!("no identified drive in {status}"))),
    }
}

/// Stops the feeder and waits until it is stopped (or faulted, which stopped it).
fn stop(console: &mut Console) -> io::Result<()> {
    console.command("stop")?;
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        let status = console.command("status")?;
        if status.starts_with("OK state=stopped") || status.starts_with("OK state=fault") {
            return Ok(());
        }
        thread::sleep(POLL);
    }
    Err(io::Error::new(
        io::ErrorKind::TimedOut,
        "the feeder did not stop",
    ))
}

/// A configuration key's number.
fn config_number(console: &mut Console, key: &str) -> io::Result<f64> {
    let reply = console.command(&format!("config get {key}"))?;
    field(&reply, key)
        .and_then(|value| value.parse().ok())
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidData, format!("no {key} in {reply:?}")))
}

/// The operator's yes on a terminal; no elsewhere.
fn consent(question: &str) -> io::Result<bool> {
    if !io::stdin().is_terminal() {
        return Ok(false);
    }
    print!("  {question} [y/N] ");
    io::stdout().flush()?;
    let mut answer = String::new();
    io::stdin().lock().read_line(&mut answer)?;
    Ok(matches!(answer.trim(), "y" | "Y" | "yes"))
}
