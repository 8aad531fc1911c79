//! `feeder-ctl calibrate`: a guided calibration of the drive, step by step on the board's own
//! closed loop, judged by `feeder_shared::calibration`:
//!
//! 1. **The board**: stopped, no fault latched, a closed loop to run; its DAC calibration, its
//!    limits and the settings it runs.
//! 2. **The encoder's direction**, by hand, on a terminal: with the driver off the operator
//!    pushes the plate forward, and the position the telemetry shows must rise; a fall refuses
//!    the calibration and names the setting to flip. Headless, the drive's step stands in: the
//!    closed loop's settle refuses a backwards encoder (`loop_error=encoder-reversed`).
//! 3. **The drive**: a start at a low amplitude ([`CALIBRATION_STROKE_M`]), on which the closed
//!    loop settles, probes and identifies the drive (gains, zero offset, the current loop's lag),
//!    then a stop and the stroke set back; the telemetry meanwhile gives the start's swing,
//!    which must stay clear of the stops. `stop` from any console, or Ctrl-C here, stops it.
//! 4. **The driver's zero**: what the plate does with the command at zero (the offset, its drift
//!    over a period), and the zero code that takes it off.
//! 5. **Gains and lag** against the envelope's limits.
//! 6. **The usable stroke**: the largest stroke the identified drive and the plate's travel give
//!    at the band's ends, and whether the settings' stroke is within it.
//! 7. **Saving**, with the operator's consent (`--save`, or a `y` on a terminal): `config set
//!    dac_zero`, `config save`, `restart`.
//!
//! Every step is printed as it runs; `--report FILE` writes them all, one `key=value` a line.

use std::fmt::Write as _;
use std::io::{self, BufRead, IsTerminal, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Once;
use std::thread;
use std::time::{Duration, Instant};

use feeder_shared::calibration::{swing_within, DriveVerdict, UsableStroke, CALIBRATION_STROKE_M};
use feeder_shared::closed_loop::{Identified, ENVELOPE};
use feeder_shared::{DacCalibration, Limits};

use crate::console::{field, uptime_s, Console};

/// How often the drive's step asks for the board's status.
const POLL: Duration = Duration::from_millis(200);
/// The longest the drive's step waits for the identification, in the board's seconds.
const DRIVE_LIMIT_S: f64 = 60.0;
/// The least a push by hand must move the plate, m: two counts of a 1 µm encoder.
const HAND_PUSH_MIN_M: f64 = 2e-6;

/// The plate moves on the calibration's start: Ctrl-C then stops it rather than the tool.
static MOVING: AtomicBool = AtomicBool::new(false);
/// Ctrl-C came while the plate moved.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Ctrl-C stops the plate while it moves and ends the tool at any other time; installed once
/// (a calibration typed at the prompt again keeps it).
fn stop_on_ctrl_c() {
    static INSTALLED: Once = Once::new();
    INSTALLED.call_once(install_ctrl_c);
}

fn install_ctrl_c() {
    let handler = || {
        if MOVING.load(Ordering::SeqCst) {
            INTERRUPTED.store(true, Ordering::SeqCst);
        } else {
            std::process::exit(130);
        }
    };
    if let Err(error) = ctrlc::set_handler(handler) {
        eprintln!("feeder-ctl: Ctrl-C will not stop the plate: {error}");
    }
}

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
    stop_on_ctrl_c();
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
    println!("step 1/7: the board");
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
    let limits = Limits {
        min_frequency_hz: config_number(console, "min_freq_hz")?,
        max_frequency_hz: config_number(console, "max_freq_hz")?,
        max_accel_mps2: config_number(console, "max_accel_mps2")?,
        max_stroke_m: config_number(console, "max_stroke_mm")? * 1e-3,
    };
    let Some(settings) = Running::of(&status) else {
        return Ok(Outcome::Refused(format!(
            "no frequency, duty and stroke in the board's status: {status}"
        )));
    };
    println!(
        "  stopped; DAC zero code {}, {} counts per m/s2; travel {} mm, peak command {} m/s2",
        dac.zero_code,
        dac.counts_per_mps2,
        limits.max_stroke_m * 1e3,
        limits.max_accel_mps2
    );
    report.note("dac_zero", dac.zero_code);
    report.note("dac_counts_per_mps2", dac.counts_per_mps2);

    println!("step 2/7: the encoder's direction");
    if io::stdin().is_terminal() {
        if let Some(refused) = direction_by_hand(console, report)? {
            return Ok(Outcome::Refused(refused));
        }
    } else {
        println!("  headless: the closed loop's settle checks it on the drive's step");
        report.note("direction", "checked by the drive's step");
    }

    let low_stroke_m = settings.stroke_m.min(CALIBRATION_STROKE_M);
    println!(
        "step 3/7: the drive at {} mm (start, settle, probe, identify, stop; Ctrl-C stops)",
        low_stroke_m * 1e3
    );
    let (drive, peak_m) = match low_amplitude(console, report, &settings, low_stroke_m)? {
        Ok(found) => found,
        Err(refused) => return Ok(Outcome::Refused(refused)),
    };
    let travel_half_m = limits.max_stroke_m / 2.0;
    let mut checks = Checks::default();
    if let Some(peak_m) = peak_m {
        checks.judge(
            report,
            "swing",
            swing_within(peak_m, limits.max_stroke_m),
            format!(
                "{:.0} um from the centre at most in the cycles the telemetry carried (the stops \
                 {:.0} um away)",
                peak_m * 1e6,
                travel_half_m * 1e6
            ),
        );
    }

    println!("step 4/7: the driver's zero");
    let verdict = DriveVerdict::judge(&drive, &dac);
    let period_s = 1.0 / settings.frequency_hz;
    checks.judge(
        report,
        "offset",
        verdict.offset_within,
        format!(
            "{:.3} m/s2 at a zero command, {:.1} counts: {:.1} um in a period from rest where \
             the slide's friction does not hold it (at most {:.2} m/s2)",
            drive.offset_mps2,
            verdict.offset_counts,
            drive.offset_mps2 * period_s * period_s / 2.0 * 1e6,
            ENVELOPE.offset_max_mps2()
        ),
    );

    println!("step 5/7: gains and lag");
    checks.judge(
        report,
        "gains",
        verdict.gains_within,
        format!(
            "+a {:.5}, -a {:.5} (within {} to {})",
            drive.gain_positive, drive.gain_negative, ENVELOPE.gain_min, ENVELOPE.gain_max
        ),
    );
    checks.judge(
        report,
        "lag",
        verdict.lag_within,
        format!(
            "{:.3} ms (at most {:.3} ms)",
            drive.lag_s * 1e3,
            ENVELOPE.lag_max_s() * 1e3
        ),
    );

    println!("step 6/7: the usable stroke at d = {}", settings.duty);
    for frequency_hz in [limits.min_frequency_hz, limits.max_frequency_hz] {
        let usable = UsableStroke::at(&drive, &limits, frequency_hz, settings.duty);
        println!(
            "  {:>6} Hz  {:.3} mm ({} bound, plate levels up to {:.1} m/s2)",
            frequency_hz,
            usable.stroke_m * 1e3,
            usable.bound.name(),
            usable.accel_mps2
        );
        report.note(
            &format!("usable_stroke_mm_at_{frequency_hz}_hz"),
            format!("{:.4} ({})", usable.stroke_m * 1e3, usable.bound.name()),
        );
    }
    let running = UsableStroke::at(&drive, &limits, settings.frequency_hz, settings.duty);
    checks.judge(
        report,
        "stroke",
        settings.stroke_m <= running.stroke_m,
        format!(
            "the settings' {} mm at {} Hz (usable {:.3} mm)",
            settings.stroke_m * 1e3,
            settings.frequency_hz,
            running.stroke_m * 1e3
        ),
    );
    if !checks.passed {
        return Ok(Outcome::Refused(
            "the machine lies outside the envelope the closed loop holds, or its settings \
             outside what it can do (docs/closed-loop.md)"
                .into(),
        ));
    }

    println!("step 7/7: saving");
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

/// The checks of steps 3 to 6: each printed and noted as judged, and whether all passed.
struct Checks {
    passed: bool,
}

impl Default for Checks {
    fn default() -> Self {
        Checks { passed: true }
    }
}

impl Checks {
    fn judge(&mut self, report: &mut Report, name: &str, passed: bool, text: String) {
        let word = if passed { "ok" } else { "FAIL" };
        println!("  {name:<7} {word:<4} {text}");
        report.note(name, format!("{} {text}", word.to_lowercase()));
        self.passed &= passed;
    }
}

/// The settings the board runs, as its status shows them.
struct Running {
    frequency_hz: f64,
    duty: f64,
    stroke_m: f64,
}

impl Running {
    fn of(status: &str) -> Option<Self> {
        let number = |key| field(status, key).and_then(|value| value.parse::<f64>().ok());
        Some(Running {
            frequency_hz: number("freq_hz")?,
            duty: number("duty")?,
            stroke_m: number("stroke_mm")? * 1e-3,
        })
    }
}

/// The drive's step at `stroke_m`: the stroke set, the telemetry on, the drive identified, the
/// feeder stopped, the telemetry off and the settings' stroke set back, whatever the outcome.
/// The drive and the largest distance from the centre the telemetry showed.
fn low_amplitude(
    console: &mut Console,
    report: &mut Report,
    settings: &Running,
    stroke_m: f64,
) -> io::Result<Result<(Identified, Option<f64>), String>> {
    let set = |stroke_m: f64| format!("set stroke {}", stroke_m * 1e3);
    let reply = console.command(&set(stroke_m))?;
    if !reply.starts_with("OK") {
        return Ok(Err(format!("the board refused the low amplitude: {reply}")));
    }
    console.command("telemetry on")?;
    let found = identify(console, report);
    console.command("telemetry off")?;
    let peak_m = console
        .take_telemetry()
        .iter()
        .filter_map(|record| record.peak_m)
        .reduce(f64::max);
    let back = console.command(&set(settings.stroke_m))?;
    if !back.starts_with("OK") {
        return Ok(Err(format!(
            "the board refused the settings' stroke back: {back}"
        )));
    }
    Ok(found?.map(|drive| (drive, peak_m)))
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
    MOVING.store(true, Ordering::SeqCst);
    let start_s = uptime_s(&console.command("status")?).unwrap_or(0.0);
    let found = loop {
        thread::sleep(POLL);
        if INTERRUPTED.swap(false, Ordering::SeqCst) {
            stop(console)?;
            MOVING.store(false, Ordering::SeqCst);
            return Ok(Err("stopped by the operator (Ctrl-C)".into()));
        }
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
    MOVING.store(false, Ordering::SeqCst);
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
