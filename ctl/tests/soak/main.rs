//! A seeded random operator soaks the QEMU firmware built with the `console` feature
//! (`FEEDER_QEMU_ELF`) over its serial port: `set` across the machine's range and past it,
//! `start` and `stop` at any moment (mid-ramp too), `status`, `get`, recipes, garbage, overlong
//! lines and pipelined bursts, until the firmware has run `FEEDER_SOAK_CYCLES` motion cycles
//! (20,000 by default).
//!
//! While it runs, every line must get exactly one reply of the kind its command calls for, and
//! the firmware must never report a fault. Then the decoded log goes through `host-sim`'s
//! firmware-in-the-loop checker: no missing, extra or different edge, no glitch, every change at
//! the first cycle boundary after the control loop took it, every accepted change run as
//! stated, and the plate on the planned ticks within the plans' drift bound.
//!
//! The operator's script follows from the seed (`FEEDER_SOAK_SEED`, random when unset, printed
//! at the start and on failure); QEMU's timing against the wall clock is not repeatable, so the
//! same seed repeats the lines and pauses, not the exact cycle each line lands in.

#[path = "../support/mod.rs"]
mod support;

mod checks;
mod log;
mod operator;

use std::collections::hash_map::RandomState;
use std::collections::VecDeque;
use std::fs::File;
use std::hash::{BuildHasher, Hasher};
use std::io::{BufWriter, Write as _};
use std::path::Path;
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use feeder_shared::protocol::Param;
use log::{FirmwareError, Progress, SoakLog, Summary};
use operator::{Expect, Line, Operator, Parameters, Verdict, Write};
use support::{console_image, env_number, Console, Emulator};

/// Motion cycles when `FEEDER_SOAK_CYCLES` is unset.
const DEFAULT_MOTION_CYCLES: u64 = 20_000;
/// Wall time the run may take: this much, plus [`WALL_TIME_PER_CYCLE`] per motion cycle
/// (QEMU needs about 4 ms per cycle on a 2-core machine).
const WALL_TIME_BASE: Duration = Duration::from_secs(120);
const WALL_TIME_PER_CYCLE: Duration = Duration::from_millis(25);
/// Exchanges a failure report shows.
const HISTORY_EXCHANGES: usize = 12;
/// A soft stop at the end may take this long (the ramp is shortened first).
const STOP_TIMEOUT: Duration = Duration::from_secs(30);
/// Pause between `status` polls while waiting for the stop.
const STATUS_POLL_INTERVAL: Duration = Duration::from_millis(50);
/// Idle time at the end, and how long nothing may arrive after the last reply.
const SETTLE: Duration = Duration::from_millis(300);
/// Longest wait for one reply. QEMU's pace against the wall clock follows the host's load, so a
/// reply later than the other tests' limit is reported, and only a missing one fails the soak.
const LATE_REPLY_LIMIT: Duration = Duration::from_secs(120);

#[test]
#[ignore = "needs the QEMU console firmware; run by cargo xtask test"]
fn random_operator_soak() {
    let seed = seed();
    let target = motion_cycles_wanted();
    println!("soak: seed {seed} (FEEDER_SOAK_SEED), {target} motion cycles (FEEDER_SOAK_CYCLES)");
    let started = Instant::now();
    let output = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let transcript_path = output.join("soak-transcript.txt");
    let (sink, progress) = SoakLog::create(&output.join("soak.log"));
    let mut emulator = Emulator::launch(&console_image(), sink);
    let mut console = emulator.connect();
    let mut session = Session::new(seed, target, Arc::clone(&progress), &transcript_path);
    let operator_failure = session.run(&mut console).err();
    session.close_transcript();
    drop(console);
    let summary = emulator.shut_down().finish();
    let findings = run_checks(&summary, &session, operator_failure);
    let wall = started.elapsed();
    if !findings.failures.is_empty() {
        panic!(
            "soak with seed {seed} failed after {:.1} s ({} motion cycles, {} lines):\n- {}\n\
             every line and reply: {}\n\
             decoded log: {} (recheck: cargo run --release -p host-sim -- hil --input {} \
             --open-ended)\nFEEDER_SOAK_SEED={seed} repeats the operator's lines",
            wall.as_secs_f64(),
            progress.motion_cycles(),
            session.lines_sent,
            findings.failures.join("\n- "),
            transcript_path.display(),
            summary.path.display(),
            summary.path.display()
        );
    }
    let drift = findings.drift.expect("measured when nothing failed");
    println!(
        "soak: seed {seed} passed in {:.1} s: {} motion cycles, {} lines, {} accepted changes \
         ({} replaced by a newer one before the control loop took them), {} edges as planned \
         (latency up to {} ticks), plate within {:e} m of its start on the planned ticks \
         (bound {:e} m + {:e} m rounding), slowest reply {:.3} s of wall time ({} over {:?})",
        wall.as_secs_f64(),
        summary.report.motion_cycles,
        session.lines_sent,
        session.accepted.len(),
        findings.replaced_changes.unwrap_or_default(),
        summary.report.matched,
        summary.report.max_deviation_ticks(),
        drift.worst_m,
        drift.bound_m,
        drift.rounding_m,
        session.slowest_reply.as_secs_f64(),
        session.late_replies,
        support::REPLY_TIMEOUT
    );
}

/// What the whole-run checks found.
struct Findings {
    failures: Vec<String>,
    drift: Option<checks::Drift>,
    /// Accepted changes a newer one replaced before the control loop took them.
    replaced_changes: Option<usize>,
}

/// Checks the whole run after the operator's own verdict. The motion-cycle count and the
/// changes are judged only when the operator finished its run.
fn run_checks(summary: &Summary, session: &Session, operator_failure: Option<String>) -> Findings {
    let mut failures: Vec<String> = operator_failure.into_iter().collect();
    let operator_finished = failures.is_empty();
    failures.extend(checks::edges(&summary.report).err());
    failures.extend(checks::log_lines(summary).err());
    let mut replaced_changes = None;
    if operator_finished {
        failures.extend(checks::motion_cycles(&summary.report, session.target).err());
        match checks::changes_applied(&session.accepted, &summary.plans) {
            Ok(replaced) => replaced_changes = Some(replaced),
            Err(found) => failures.push(found),
        }
    }
    let drift = checks::drift(summary)
        .map_err(|found| failures.push(found))
        .ok();
    Findings {
        failures,
        drift,
        replaced_changes,
    }
}

/// `FEEDER_SOAK_SEED`, or a fresh random seed.
fn seed() -> u64 {
    env_number("FEEDER_SOAK_SEED", false)
        .unwrap_or_else(|| RandomState::new().build_hasher().finish())
}

/// `FEEDER_SOAK_CYCLES`, or [`DEFAULT_MOTION_CYCLES`].
fn motion_cycles_wanted() -> u64 {
    env_number("FEEDER_SOAK_CYCLES", true).unwrap_or(DEFAULT_MOTION_CYCLES)
}

/// The operator at the console, with what it has seen.
struct Session {
    operator: Operator,
    progress: Arc<Progress>,
    target: u64,
    deadline: Instant,
    /// The last lines sent with their replies, oldest first.
    history: VecDeque<String>,
    /// The parameters of every accepted change, in order.
    accepted: Vec<Parameters>,
    lines_sent: u64,
    /// The longest wall time spent waiting for one reply.
    slowest_reply: Duration,
    /// Replies that took longer than [`support::REPLY_TIMEOUT`].
    late_replies: u64,
    /// Every line sent and its reply.
    transcript: BufWriter<File>,
}

impl Session {
    fn new(seed: u64, target: u64, progress: Arc<Progress>, transcript: &Path) -> Self {
        let cycles = u32::try_from(target).unwrap_or(u32::MAX);
        let transcript = File::create(transcript)
            .unwrap_or_else(|error| panic!("cannot create {}: {error}", transcript.display()));
        Session {
            operator: Operator::new(seed),
            progress,
            target,
            deadline: Instant::now() + WALL_TIME_BASE + WALL_TIME_PER_CYCLE * cycles,
            history: VecDeque::with_capacity(HISTORY_EXCHANGES),
            accepted: Vec::new(),
            lines_sent: 0,
            slowest_reply: Duration::ZERO,
            late_replies: 0,
            transcript: BufWriter::new(transcript),
        }
    }

    fn close_transcript(&mut self) {
        if let Err(error) = self.transcript.flush() {
            panic!("cannot write the transcript: {error}");
        }
    }

    /// Random writes until the target is reached, then a stop; `Err` says what went wrong.
    fn run(&mut self, console: &mut Console) -> Result<(), String> {
        let report_every = (self.target / 10).max(1);
        let mut next_report = report_every;
        while self.progress.motion_cycles() < self.target {
            if Instant::now() > self.deadline {
                return Err(format!(
                    "only {} of {} motion cycles before the wall-time limit",
                    self.progress.motion_cycles(),
                    self.target
                ));
            }
            let write = self.operator.next_write();
            self.exchange(console, &write)?;
            thread::sleep(self.operator.think_time());
            self.check_firmware_log()?;
            if self.progress.motion_cycles() >= next_report {
                println!(
                    "soak: {} motion cycles, {} lines",
                    self.progress.motion_cycles(),
                    self.lines_sent
                );
                next_report += report_every;
            }
        }
        self.wind_down(console)
    }

    /// Sends one write and judges the reply to each of its lines.
    fn exchange(&mut self, console: &mut Console, write: &Write) -> Result<(), String> {
        let bytes = write.bytes();
        let sent = match write.split_at {
            Some(at) => console.write(&bytes[..at]).and_then(|()| {
                thread::sleep(self.operator.split_pause());
                console.write(&bytes[at..])
            }),
            None => console.write(&bytes),
        };
        sent.map_err(|error| format!("the console refused a write: {error}"))?;
        self.lines_sent += write.lines.len() as u64;
        for line in &write.lines {
            self.answer(console, line)?;
        }
        Ok(())
    }

    /// Sends `line` on its own and returns the verdict on its reply.
    fn single(&mut self, console: &mut Console, line: Line) -> Result<Option<Verdict>, String> {
        console
            .write(&line.bytes)
            .map_err(|error| format!("the console refused a write: {error}"))?;
        self.lines_sent += 1;
        self.answer(console, &line)
    }

    /// Reads and judges the reply to `line`: `None` for a blank line, which gets none. An
    /// accepted change is recorded; a wrong reply or a fault is an `Err`.
    fn answer(&mut self, console: &mut Console, line: &Line) -> Result<Option<Verdict>, String> {
        if !line.replied() {
            self.remember(line, None);
            return Ok(None);
        }
        let asked = Instant::now();
        let reply = match console.reply_within(LATE_REPLY_LIMIT) {
            Ok(reply) => {
                let waited = asked.elapsed();
                self.slowest_reply = self.slowest_reply.max(waited);
                if waited > support::REPLY_TIMEOUT {
                    self.late_replies += 1;
                    println!("soak: {} replied after {waited:?}", line.shown());
                }
                reply
            }
            Err(error) => {
                self.remember(line, None);
                return Err(self.with_history(&format!("no reply to {}: {error}", line.shown())));
            }
        };
        self.remember(line, Some(&reply));
        match line.expect.judge(&reply) {
            Ok(Verdict::Fault(what)) => {
                Err(self.fault_report(&format!("the firmware reports a fault: {what}")))
            }
            Ok(verdict) => {
                if let Verdict::Applied(parameters) = &verdict {
                    self.accepted.push(*parameters);
                }
                Ok(Some(verdict))
            }
            Err(why) => Err(self.with_history(&format!("{} got {reply:?}: {why}", line.shown()))),
        }
    }

    /// Keeps `line` and its reply in the transcript and the recent history.
    fn remember(&mut self, line: &Line, reply: Option<&str>) {
        let exchange = match reply {
            Some(reply) => format!("{} -> {reply:?}", line.shown()),
            None => format!("{} -> (no reply)", line.shown()),
        };
        if let Err(error) = writeln!(self.transcript, "{exchange}") {
            panic!("cannot write the transcript: {error}");
        }
        if self.history.len() == HISTORY_EXCHANGES {
            self.history.pop_front();
        }
        self.history.push_back(exchange);
    }

    /// Fails on the first error line of the firmware's log (a fault shows there first).
    fn check_firmware_log(&self) -> Result<(), String> {
        match self.progress.first_error() {
            Some(error) => Err(self.fault_report(&format!("the firmware logged {:?}", error.line))),
            None => Ok(()),
        }
    }

    /// Shortens the ramp, stops, waits for the feeder to stop and checks that nothing more
    /// arrives: every line has had exactly its one reply.
    fn wind_down(&mut self, console: &mut Console) -> Result<(), String> {
        let short_ramp = Expect::Set {
            param: Param::Ramp,
            value: 5.0,
            in_range: true,
        };
        self.single(console, Operator::plain("set ramp 5", short_ramp))?;
        self.single(
            console,
            Operator::plain("stop", Expect::Ok("stopping".into())),
        )?;
        let stopped_by = Instant::now() + STOP_TIMEOUT;
        loop {
            let status = Operator::plain("status", Expect::Status);
            match self.single(console, status)? {
                Some(Verdict::State(state)) if state == "stopped" => break,
                _ if Instant::now() < stopped_by => thread::sleep(STATUS_POLL_INTERVAL),
                _ => return Err(self.with_history("the feeder did not stop")),
            }
        }
        thread::sleep(SETTLE);
        console
            .expect_silence(SETTLE)
            .map_err(|found| self.with_history(&found))?;
        self.check_firmware_log()
    }

    /// `what`, with the last exchanges.
    fn with_history(&self, what: &str) -> String {
        let mut text = format!("{what}\n  last lines sent, oldest first:");
        for exchange in &self.history {
            text.push_str("\n    ");
            text.push_str(exchange);
        }
        text
    }

    /// A fault: the last exchanges and the firmware's log leading up to its first error.
    fn fault_report(&self, what: &str) -> String {
        let mut text = self.with_history(what);
        if let Some(FirmwareError { line, context }) = self.progress.first_error() {
            text.push_str("\n  firmware log up to its first error:");
            for logged in context.iter().chain([&line]) {
                text.push_str("\n    ");
                text.push_str(logged);
            }
        }
        text
    }
}
