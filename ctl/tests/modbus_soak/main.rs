//! A seeded random Modbus master soaks the QEMU console image's Modbus RTU slave
//! (`FEEDER_QEMU_ELF`, UART1 on loopback TCP) through `tokio-modbus`'s RTU client: reads and
//! writes of random addresses and values, functions the slave does not serve, garbage, corrupt
//! CRCs, frames for another slave and frames cut short, while the feeder starts, runs with live
//! changes and stops; halfway, the master falls silent once while the feeder runs and then
//! acknowledges the `link-lost` fault it meant to cause.
//!
//! Every request must get a well-formed answer of the kind the register map calls for (a
//! response, or the exception its rules give, with the console's code in `refusal`), a
//! refused write must change nothing (all or nothing), and every input register must read
//! what the feeder does; the bytes that are no request must get no answer. Then the firmware's
//! decoded log goes through the console soak's checks (`ctl/tests/soak`): every edge on its
//! planned tick, every change at a cycle boundary and run as its write's `status` stated, the
//! plate within its drift bound, no firmware error, and no fault but the one intended.
//!
//! `FEEDER_SOAK_SEED` chooses the master's script ([`DEFAULT_SEED`] when unset);
//! `FEEDER_MODBUS_SOAK_REQUESTS` its length ([`DEFAULT_REQUESTS`]). QEMU's timing against the
//! wall clock is not repeatable: the same seed repeats the requests, not the cycle each lands
//! in.

#[path = "../support/mod.rs"]
mod support;

// The console soak's log sink and whole-run checks, shared as they are; the checks name the
// console soak's operator module (its `Parameters`), which comes along.
#[path = "../soak/checks.rs"]
mod checks;
#[allow(dead_code)]
#[path = "../soak/log.rs"]
mod log;
#[allow(dead_code)]
#[path = "../soak/operator.rs"]
mod operator;

mod requests;

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::Path;
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use feeder_shared::modbus::{Holding, Input};
use feeder_shared::protocol::Param;
use log::{Progress, SoakLog};
use operator::Parameters;
use requests::{Generator, Hints, Planned, HOLDINGS, INPUTS, SAVED_SLOTS};
use support::modbus::{Failure, Master};
use support::{console_image, env_number, Clocked, Console, Emulator, LogClock};
use tokio_modbus::{Request, Response};

/// The master's seed when `FEEDER_SOAK_SEED` is unset.
const DEFAULT_SEED: u64 = 0x4d6f_6462_7573_2017;
/// Requests of the random script when `FEEDER_MODBUS_SOAK_REQUESTS` is unset (each followed,
/// where its answer calls for it, by reads that check it).
const DEFAULT_REQUESTS: u64 = 1_500;
/// The whole run must end within this much wall time per request, plus a base.
const WALL_TIME_BASE: Duration = Duration::from_secs(60);
const WALL_TIME_PER_REQUEST: Duration = Duration::from_millis(30);
/// Longest the feeder may take to reach a state, in wall time.
const STATE_TIMEOUT: Duration = Duration::from_secs(30);
/// The silence that loses the link (the default `link_timeout_ms`), with room, in ticks.
const LINK_LOSS_TICKS: u64 = 2_500_000;
/// The motion cycles the run must have had at least: the feeder ran for a good part of it.
const MIN_MOTION_CYCLES: u64 = 200;
/// At most one request in this many may be lost on its way in (and answered when sent again):
/// QEMU hands the board a request a byte at a time, and on a loaded host its virtual time can
/// run past the firmware's frame gap between two bytes of one frame.
const MAX_RETRIED_PER_FRAMES: u64 = 50;
/// Exchanges a failure report shows.
const HISTORY_EXCHANGES: usize = 16;

const EXCEPTION_FUNCTION: u8 = 1;
const EXCEPTION_ADDRESS: u8 = 2;
const EXCEPTION_VALUE: u8 = 3;
const EXCEPTION_STATE: u8 = 4;
const ERR_UNKNOWN_PARAMETER: u16 = 23;
const ERR_OUT_OF_RANGE: u16 = 28;
const ERR_FAULT_LATCHED: u16 = 61;
const ERR_RECIPE_EMPTY: u16 = 63;
/// The console's validation codes.
const VALIDATION_CODES: std::ops::RangeInclusive<u16> = 40..=58;
/// The `link-lost` fault's code.
const FAULT_LINK_LOST: u16 = 6;

#[test]
#[ignore = "needs the QEMU console firmware; run by cargo xtask test"]
fn random_modbus_master_soak() {
    let seed = seed();
    let requests = requests_wanted();
    println!(
        "modbus soak: seed {seed} (FEEDER_SOAK_SEED), {requests} requests \
         (FEEDER_MODBUS_SOAK_REQUESTS)"
    );
    let started = Instant::now();
    let output = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let transcript_path = output.join("modbus-soak-transcript.txt");
    let (soak_log, progress) = SoakLog::create(&output.join("modbus-soak.log"));
    let (sink, clock) = Clocked::new(soak_log);
    let mut emulator = Emulator::launch_with_modbus(&console_image(), sink);
    let console = emulator.connect();
    let master = Master::new(emulator.connect_modbus(), Arc::clone(&clock));
    let mut session = Session::new(seed, master, console, clock, Arc::clone(&progress));
    session.transcript = Some(BufWriter::new(
        File::create(&transcript_path).expect("the transcript file"),
    ));
    let deadline = started + WALL_TIME_BASE + WALL_TIME_PER_REQUEST * requests as u32;
    let outcome = session.run(requests, deadline);
    session.close();
    let Session {
        console,
        master,
        counts,
        accepted,
        ..
    } = session;
    let retried = master.retried;
    drop((console, master));
    let (soak_log, lines) = emulator.shut_down().into_parts();
    let summary = soak_log.finish();
    let wall = started.elapsed();

    let mut failures: Vec<String> = outcome.err().into_iter().collect();
    let finished = failures.is_empty();
    let frames = counts.answered + counts.exceptions.values().sum::<u64>();
    if retried * MAX_RETRIED_PER_FRAMES > frames {
        failures.push(format!(
            "{retried} requests lost on their way in and sent again, in {frames} answered: more \
             than one in {MAX_RETRIED_PER_FRAMES}"
        ));
    }
    failures.extend(checks::edges(&summary.report).err());
    failures.extend(checks::log_lines(&summary).err());
    let mut replaced = 0;
    if finished {
        match checks::changes_applied(&accepted, &summary.plans) {
            Ok(count) => replaced = count,
            Err(found) => failures.push(found),
        }
        failures.extend(checks::motion_cycles(&summary.report, MIN_MOTION_CYCLES).err());
    }
    let drift = checks::drift(&summary)
        .map_err(|found| failures.push(found))
        .ok();
    // The one link loss intended, and no other fault.
    let lost = lines
        .iter()
        .filter(|line| line.contains("link lost: the Modbus master fell silent"))
        .count();
    let latched: Vec<&String> = lines
        .iter()
        .filter(|line| line.contains("fault latched"))
        .collect();
    if finished && (lost != 1 || latched.len() != 1) {
        failures.push(format!(
            "one link loss was intended; the log shows {lost} and these faults: {latched:?}"
        ));
    }
    let virtual_s = summary.edges.last().map_or(0.0, |edge| {
        edge.planned_tick as f64 / f64::from(summary.clock_hz.max(1))
    });
    println!(
        "modbus soak: seed {seed}: {} in {:.1} s of wall time ({virtual_s:.1} s of the board's \
         time): {} requests of the script, {} frames sent through the client ({} answered, \
         {} exceptions: {}; {retried} lost on their way in and sent again), {} sent raw with no \
         answer, the slowest answer {:.1} ms; {} \
         accepted changes ({replaced} replaced before the control loop took them), {} motion \
         cycles, {} edges as planned (latency up to {} ticks){}",
        if failures.is_empty() {
            "passed"
        } else {
            "FAILED"
        },
        wall.as_secs_f64(),
        counts.script,
        frames,
        counts.answered,
        counts.exceptions.values().sum::<u64>(),
        counts.exceptions_shown(),
        counts.no_answer,
        counts.slowest.as_secs_f64() * 1e3,
        accepted.len(),
        summary.report.motion_cycles,
        summary.report.matched,
        summary.report.max_deviation_ticks(),
        drift.map_or(String::new(), |drift| format!(
            ", plate within {:e} m of its start (bound {:e} m + {:e} m)",
            drift.worst_m, drift.bound_m, drift.rounding_m
        )),
    );
    println!("modbus soak: requests by kind: {:?}", counts.by_kind);
    assert!(
        failures.is_empty(),
        "modbus soak with seed {seed} failed:\n- {}\nevery request and answer: {}\ndecoded log: \
         {} (recheck: cargo run --release -p host-sim -- hil --input {} --open-ended)\n\
         FEEDER_SOAK_SEED={seed} repeats the master's requests",
        failures.join("\n- "),
        transcript_path.display(),
        summary.path.display(),
        summary.path.display(),
    );
}

/// `FEEDER_SOAK_SEED`, or [`DEFAULT_SEED`].
fn seed() -> u64 {
    env_number("FEEDER_SOAK_SEED", false).unwrap_or(DEFAULT_SEED)
}

/// `FEEDER_MODBUS_SOAK_REQUESTS`, or [`DEFAULT_REQUESTS`].
fn requests_wanted() -> u64 {
    env_number("FEEDER_MODBUS_SOAK_REQUESTS", true).unwrap_or(DEFAULT_REQUESTS)
}

/// What the requests got.
#[derive(Default)]
struct Counts {
    /// Requests of the random script (the drill's and the checks' reads not counted).
    script: u64,
    by_kind: BTreeMap<&'static str, u64>,
    /// Frames the client sent that got a normal response.
    answered: u64,
    /// Frames the client sent that got an exception, by its code.
    exceptions: BTreeMap<u8, u64>,
    /// Bytes sent raw that got no answer, as they must.
    no_answer: u64,
    slowest: Duration,
}

impl Counts {
    fn exceptions_shown(&self) -> String {
        self.exceptions
            .iter()
            .map(|(code, count)| format!("{count} x {code:02}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// What a write of one register calls for under the register map's rules.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Rule {
    Accept,
    Refuse {
        exception: u8,
        code: u16,
    },
    /// A setting: accepted, or refused by validation (exception 03, codes 40–58).
    Validate,
}

/// The master with what it knows of the feeder.
struct Session {
    generator: Generator,
    master: Master,
    console: Console,
    clock: Arc<LogClock>,
    progress: Arc<Progress>,
    /// The holding registers as last read back (`run` aside).
    shadow: Vec<u16>,
    /// `refusal` and `refused_register` as this link's last write left them.
    refusal: [u16; 2],
    /// The intended fault is latched.
    faulted: bool,
    running: bool,
    cycles: u32,
    uptime_s: u32,
    /// The parameters of every accepted change, as `status` stated them after it.
    accepted: Vec<Parameters>,
    counts: Counts,
    history: VecDeque<String>,
    transcript: Option<BufWriter<File>>,
}

impl Session {
    fn new(
        seed: u64,
        master: Master,
        console: Console,
        clock: Arc<LogClock>,
        progress: Arc<Progress>,
    ) -> Self {
        Session {
            generator: Generator::new(seed),
            master,
            console,
            clock,
            progress,
            shadow: Vec::new(),
            refusal: [0, 0xffff],
            faulted: false,
            running: false,
            cycles: 0,
            uptime_s: 0,
            accepted: Vec::new(),
            counts: Counts::default(),
            history: VecDeque::with_capacity(HISTORY_EXCHANGES),
            transcript: None,
        }
    }

    fn close(&mut self) {
        if let Some(mut transcript) = self.transcript.take() {
            transcript.flush().expect("the transcript is written");
        }
    }

    /// Saves the recipes, runs the script with the link-loss drill halfway, and stops.
    fn run(&mut self, requests: u64, deadline: Instant) -> Result<(), String> {
        self.prepare()?;
        for index in 0..requests {
            if index == requests / 2 {
                self.link_loss_drill()
                    .map_err(|found| self.with_history(&format!("link-loss drill: {found}")))?;
            }
            let planned = self.generator.next(&Hints {
                running: self.running,
            });
            self.counts.script += 1;
            *self.counts.by_kind.entry(planned.kind()).or_default() += 1;
            self.note(&format!("#{index} {planned:?}"));
            self.exchange(&planned).map_err(|found| {
                self.with_history(&format!("request #{index} {planned:?}: {found}"))
            })?;
            if index % 100 == 0 {
                if let Some(error) = self.progress.first_error() {
                    return Err(self.with_history(&format!(
                        "the firmware logged {:?} after {:?}",
                        error.line, error.context
                    )));
                }
            }
            if Instant::now() > deadline {
                return Err(format!(
                    "only {index} of {requests} requests in the wall time"
                ));
            }
        }
        self.wind_down()
            .map_err(|found| self.with_history(&format!("the final stop: {found}")))
    }

    /// Recipes in the first slots, each with settings of its own, saved on the console.
    fn prepare(&mut self) -> Result<(), String> {
        self.shadow = self.read_holdings(0, HOLDINGS)?;
        // Stroke (µm), frequency (0.01 Hz), duty: a valid order for each.
        let recipes: [[u16; 3]; SAVED_SLOTS as usize] = [
            [2_500, 5_000, 5_860],
            [2_000, 5_500, 6_000],
            [1_500, 6_000, 6_500],
            [1_000, 7_000, 6_200],
        ];
        for (slot, [stroke, freq, duty]) in recipes.iter().enumerate() {
            for (register, value) in [
                (Holding::Stroke, *stroke),
                (Holding::Frequency, *freq),
                (Holding::Duty, *duty),
            ] {
                let address = register.spec().address;
                self.write(address, &[value], false)?;
                if self.refusal != [0, 0xffff] {
                    return Err(format!("the recipe's {register:?} = {value} was refused"));
                }
            }
            let reply = self.console.command(&format!("recipe save {slot}"));
            if reply != format!("OK recipe {slot} saved") {
                return Err(format!("recipe save {slot}: {reply}"));
            }
        }
        Ok(())
    }

    fn exchange(&mut self, planned: &Planned) -> Result<(), String> {
        match planned {
            Planned::ReadHolding { address, count } => {
                let answer = self.ask(Request::ReadHoldingRegisters(*address, *count))?;
                match (answer, address + count <= HOLDINGS) {
                    (Ok(Response::ReadHoldingRegisters(words)), true)
                        if words.len() == usize::from(*count) =>
                    {
                        self.check_holdings(*address, &words)
                    }
                    (Err(EXCEPTION_ADDRESS), false) => Ok(()),
                    (answer, _) => Err(format!("answered {answer:?}")),
                }
            }
            Planned::ReadInput { address, count } => {
                let answer = self.ask(Request::ReadInputRegisters(*address, *count))?;
                match (answer, address + count <= INPUTS) {
                    (Ok(Response::ReadInputRegisters(words)), true)
                        if words.len() == usize::from(*count) =>
                    {
                        self.check_inputs(*address, &words)
                    }
                    (Err(EXCEPTION_ADDRESS), false) => Ok(()),
                    (answer, _) => Err(format!("answered {answer:?}")),
                }
            }
            Planned::Write {
                address,
                values,
                multiple,
            } => self.write(*address, values, *multiple),
            Planned::Unsupported(request) => match self.ask(request.clone())? {
                Err(EXCEPTION_FUNCTION) => Ok(()),
                answer => Err(format!("answered {answer:?}, not exception 01")),
            },
            Planned::Raw { bytes, .. } => {
                self.master.send_raw(bytes);
                self.no_answer()?;
                self.counts.no_answer += 1;
                Ok(())
            }
            Planned::Pause(pause) => {
                thread::sleep(*pause);
                Ok(())
            }
        }
    }

    /// Sends `request` through the client: the response, or the exception's code; `Err` when
    /// no well-formed answer came.
    fn ask(&mut self, request: Request<'_>) -> Result<Result<Response, u8>, String> {
        let shown = format!("{request:?}");
        let answer = match self.master.try_call(request) {
            Ok(answer) => answer.map_err(u8::from),
            // `tokio-modbus` names function 0x2B otherwise than a custom request's code, and
            // reports the exception inside a mismatch.
            Err(Failure::Transport(tokio_modbus::Error::Protocol(
                tokio_modbus::ProtocolError::FunctionCodeMismatch {
                    request: tokio_modbus::FunctionCode::Custom(0x2b),
                    result: Err(exception),
                },
            ))) if exception.function.value() == 0x2b => Err(u8::from(exception.exception)),
            Err(failure) => {
                self.note(&format!("  {shown} -> {failure}"));
                return Err(format!("{shown}: {failure}"));
            }
        };
        self.counts.slowest = self.counts.slowest.max(self.master.last_round_trip);
        match &answer {
            Ok(_) => self.counts.answered += 1,
            Err(code) => *self.counts.exceptions.entry(*code).or_default() += 1,
        }
        self.note(&format!("  {shown} -> {answer:?}"));
        Ok(answer)
    }

    fn read_holdings(&mut self, address: u16, count: u16) -> Result<Vec<u16>, String> {
        match self.ask(Request::ReadHoldingRegisters(address, count))? {
            Ok(Response::ReadHoldingRegisters(words)) => Ok(words),
            answer => Err(format!("holding {address}+{count} answered {answer:?}")),
        }
    }

    fn read_inputs(&mut self, address: u16, count: u16) -> Result<Vec<u16>, String> {
        match self.ask(Request::ReadInputRegisters(address, count))? {
            Ok(Response::ReadInputRegisters(words)) => {
                self.check_inputs(address, &words)?;
                Ok(words)
            }
            answer => Err(format!("input {address}+{count} answered {answer:?}")),
        }
    }

    /// The holding registers from `address` read what the last writes left.
    fn check_holdings(&self, address: u16, words: &[u16]) -> Result<(), String> {
        for (register, &value) in (address..).zip(words) {
            let index = usize::from(register);
            let fine = match Holding::at(register) {
                Some(Holding::Run) => value == 0 || (value == 1 && !self.faulted),
                _ => value == self.shadow[index],
            };
            if !fine {
                return Err(format!(
                    "holding {register} reads {value}, the last writes left {} (all: {:?})",
                    self.shadow[index], self.shadow
                ));
            }
        }
        Ok(())
    }

    /// The input registers from `address` read what the feeder does.
    fn check_inputs(&mut self, address: u16, words: &[u16]) -> Result<(), String> {
        let at = |register: Input| {
            let index = register.spec().address.checked_sub(address)?;
            words.get(usize::from(index)).copied()
        };
        if let Some(state) = at(Input::State) {
            match state {
                3 if !self.faulted => return Err(format!("the feeder faulted: {words:?}")),
                0..=3 => self.running = state == 1,
                _ => return Err(format!("state {state}")),
            }
        }
        if let Some(fault) = at(Input::Fault) {
            if fault != 0 && !(self.faulted && fault == FAULT_LINK_LOST) {
                return Err(format!("fault {fault} (inputs from {address}: {words:?})"));
            }
        }
        if let Some(phase) = at(Input::Phase) {
            if phase > 3 {
                return Err(format!("phase {phase}"));
            }
        }
        for (register, expected) in [
            (Input::Refusal, self.refusal[0]),
            (Input::RefusedRegister, self.refusal[1]),
            (Input::LoopStage, 0),
            (Input::GainPositive, 0),
            (Input::GainNegative, 0),
            (Input::Offset, 0),
            (Input::Lag, 0),
            (Input::PartsPerMinute, 0),
            (
                Input::FeedPredicted,
                self.shadow[usize::from(Holding::Feed.spec().address)],
            ),
        ] {
            if let Some(value) = at(register) {
                if value != expected {
                    return Err(format!(
                        "{} reads {value}, not {expected} (inputs from {address}: {words:?})",
                        register.spec().name
                    ));
                }
            }
        }
        if let (Some(high), Some(low)) = (at(Input::CyclesHigh), at(Input::CyclesLow)) {
            let cycles = u32::from(high) << 16 | u32::from(low);
            if cycles < self.cycles {
                return Err(format!("cycles went back from {} to {cycles}", self.cycles));
            }
            self.cycles = cycles;
        }
        if let (Some(high), Some(low)) = (at(Input::UptimeHigh), at(Input::UptimeLow)) {
            let uptime = u32::from(high) << 16 | u32::from(low);
            if uptime < self.uptime_s {
                return Err(format!(
                    "uptime went back from {} to {uptime}",
                    self.uptime_s
                ));
            }
            self.uptime_s = uptime;
        }
        Ok(())
    }

    /// What a write of `value` to `address` calls for.
    fn rule(&self, address: u16, value: u16) -> Rule {
        let refuse = |exception, code| Rule::Refuse { exception, code };
        match Holding::at(address) {
            None => refuse(EXCEPTION_ADDRESS, ERR_UNKNOWN_PARAMETER),
            Some(Holding::Run) => match value {
                0 => Rule::Accept,
                1 if self.faulted => refuse(EXCEPTION_STATE, ERR_FAULT_LATCHED),
                1 => Rule::Accept,
                _ => refuse(EXCEPTION_VALUE, ERR_OUT_OF_RANGE),
            },
            Some(Holding::Recipe) => match value {
                slot if slot < SAVED_SLOTS => Rule::Accept,
                slot if slot < 8 => refuse(EXCEPTION_STATE, ERR_RECIPE_EMPTY),
                _ => refuse(EXCEPTION_VALUE, ERR_OUT_OF_RANGE),
            },
            Some(Holding::Ramp) => Rule::Accept,
            Some(Holding::Acknowledge) => match value {
                1 => Rule::Accept,
                _ => refuse(EXCEPTION_VALUE, ERR_OUT_OF_RANGE),
            },
            Some(_) => Rule::Validate,
        }
    }

    /// Writes `values` from `address` and judges the answer: an accepted write is read back, a
    /// refused one must have changed nothing.
    fn write(&mut self, address: u16, values: &[u16], multiple: bool) -> Result<(), String> {
        let request = match multiple {
            true => Request::WriteMultipleRegisters(address, values.to_vec().into()),
            false => Request::WriteSingleRegister(address, values[0]),
        };
        let count = values.len() as u16;
        match self.ask(request)? {
            Ok(Response::WriteSingleRegister(echoed, value))
                if !multiple && (echoed, value) == (address, values[0]) => {}
            Ok(Response::WriteMultipleRegisters(echoed, written))
                if multiple && (echoed, written) == (address, count) => {}
            Ok(response) => return Err(format!("answered {response:?}")),
            Err(exception) => return self.refused(address, values, exception),
        }
        for (register, &value) in (address..).zip(values) {
            if let Rule::Refuse { .. } = self.rule(register, value) {
                return Err(format!("accepted {value} in holding {register}"));
            }
        }
        self.refusal = [0, 0xffff];
        let written = |register: Holding| {
            let at = register.spec().address.checked_sub(address)?;
            values.get(usize::from(at)).copied()
        };
        if written(Holding::Run) == Some(1) {
            self.running = true;
        }
        let configures = (address..address + count).any(|register| (1..=7).contains(&register));
        if !configures {
            return Ok(());
        }
        let before = self.shadow.clone();
        self.shadow = self.read_holdings(0, HOLDINGS)?;
        let after = self.shadow.clone();
        let read = |register: Holding| after[usize::from(register.spec().address)];
        // The last setting written reads back (the ones before it may have been derived anew:
        // a stroke from an acceleration, a duty from a feed rate).
        let settings = [
            Holding::Duty,
            Holding::Frequency,
            Holding::Stroke,
            Holding::Accel,
            Holding::Feed,
        ];
        if let Some((register, value)) = settings
            .iter()
            .rev()
            .find_map(|&register| written(register).map(|value| (register, value)))
        {
            let tolerance = match register {
                Holding::Feed => 1 + value / 500,
                _ => 0,
            };
            if read(register).abs_diff(value) > tolerance {
                return Err(format!(
                    "{} = {value} reads back {} ({before:?} -> {after:?})",
                    register.spec().name,
                    read(register)
                ));
            }
        }
        if let Some(ramp) = written(Holding::Ramp) {
            if read(Holding::Ramp) != ramp {
                return Err(format!("ramp = {ramp} reads back {}", read(Holding::Ramp)));
            }
        }
        let recipe = match written(Holding::Recipe) {
            Some(slot) if address + count <= 2 => slot,
            _ => u16::MAX,
        };
        if read(Holding::Recipe) != recipe {
            return Err(format!(
                "recipe reads {}, not {recipe}",
                read(Holding::Recipe)
            ));
        }
        // The change as the console states it, for the log's checks; the registers agree.
        let status = self.console.command("status");
        self.note(&format!("  status -> {status}"));
        let parameters = parameters(&status)?;
        check_holdings_match_status(&after, &status)?;
        self.accepted.push(parameters);
        Ok(())
    }

    /// Judges a refused write: `refusal` and `refused_register` name the register and the
    /// console's code, the exception goes with the code, and nothing changed.
    fn refused(&mut self, address: u16, values: &[u16], exception: u8) -> Result<(), String> {
        let link = self.read_inputs_unchecked(Input::Refusal.spec().address, 2)?;
        let (code, register) = (link[0], link[1]);
        let offset = register.wrapping_sub(address);
        let Some(&value) = values.get(usize::from(offset)) else {
            return Err(format!(
                "exception {exception:02}, refused_register {register} outside the write"
            ));
        };
        for (earlier, &earlier_value) in (address..register).zip(values) {
            if let Rule::Refuse { .. } = self.rule(earlier, earlier_value) {
                return Err(format!(
                    "refused at {register}, but {earlier} = {earlier_value} before it is refused"
                ));
            }
        }
        let fine = match self.rule(register, value) {
            Rule::Accept => false,
            Rule::Refuse {
                exception: wanted,
                code: wanted_code,
            } => (exception, code) == (wanted, wanted_code),
            Rule::Validate => exception == EXCEPTION_VALUE && VALIDATION_CODES.contains(&code),
        };
        if !fine {
            return Err(format!(
                "{register} = {value} refused with exception {exception:02} and refusal \
                 {code}; the rules call for {:?}",
                self.rule(register, value)
            ));
        }
        self.refusal = [code, register];
        let now = self.read_holdings(0, HOLDINGS)?;
        self.check_holdings(0, &now)
            .map_err(|found| format!("a refused write changed something: {found}"))
    }

    /// Reads input registers for a check of their own, before the model knows what they say.
    fn read_inputs_unchecked(&mut self, address: u16, count: u16) -> Result<Vec<u16>, String> {
        match self.ask(Request::ReadInputRegisters(address, count))? {
            Ok(Response::ReadInputRegisters(words)) if words.len() == usize::from(count) => {
                Ok(words)
            }
            answer => Err(format!("input {address}+{count} answered {answer:?}")),
        }
    }

    /// Nothing comes back while the firmware's time passes its frame gap.
    fn no_answer(&mut self) -> Result<(), String> {
        self.master.no_answer()?;
        self.note("  (no answer)");
        Ok(())
    }

    /// Polls the inputs (feeding the link watchdog) until the state and phase are `wanted`.
    fn wait_for(&mut self, wanted: (u16, u16)) -> Result<(), String> {
        let deadline = Instant::now() + STATE_TIMEOUT;
        loop {
            let words = self.read_inputs(0, INPUTS)?;
            let now = (
                words[usize::from(Input::State.spec().address)],
                words[usize::from(Input::Phase.spec().address)],
            );
            if now == wanted {
                return Ok(());
            }
            if Instant::now() > deadline {
                return Err(format!("not {wanted:?} in time: {words:?}"));
            }
            thread::sleep(Duration::from_millis(2));
        }
    }

    /// The master starts the feeder, falls silent past the link timeout, finds `link-lost`
    /// latched and the feeder stopped softly, is refused a start, and acknowledges.
    fn link_loss_drill(&mut self) -> Result<(), String> {
        self.note("link-loss drill");
        self.write(Holding::Run.spec().address, &[1], false)?;
        if self.refusal != [0, 0xffff] {
            return Err(format!("run = 1 refused: {:?}", self.refusal));
        }
        self.wait_for((1, 2))?;
        self.faulted = true;
        self.clock
            .wait_for(LINK_LOSS_TICKS, Duration::ZERO, STATE_TIMEOUT)?;
        self.wait_for((3, 0))?;
        let fault = self.read_inputs(Input::Fault.spec().address, 1)?;
        if fault != [FAULT_LINK_LOST] {
            return Err(format!("fault {fault:?}, not link-lost"));
        }
        let status = self.console.command("status");
        if !(status.starts_with("OK state=fault ") && status.ends_with(" fault=link-lost")) {
            return Err(format!("status: {status}"));
        }
        self.write(Holding::Run.spec().address, &[1], false)?;
        if self.refusal != [ERR_FAULT_LATCHED, Holding::Run.spec().address] {
            return Err(format!("a start while faulted: refusal {:?}", self.refusal));
        }
        self.write(Holding::Acknowledge.spec().address, &[1], false)?;
        self.wait_for((0, 0))?;
        self.faulted = false;
        self.read_inputs(0, INPUTS).map(|_| ())
    }

    /// A short ramp, a stop, the feeder stopped, and nothing more on the line.
    fn wind_down(&mut self) -> Result<(), String> {
        self.write(Holding::Ramp.spec().address, &[5], false)?;
        self.write(Holding::Run.spec().address, &[0], false)?;
        self.wait_for((0, 0))?;
        self.master.expect_silence(Duration::from_millis(100))?;
        // Let the last plan reach the log.
        self.clock
            .wait_for(200_000, Duration::from_millis(20), STATE_TIMEOUT)
    }

    fn note(&mut self, text: &str) {
        if let Some(transcript) = self.transcript.as_mut() {
            writeln!(transcript, "{text}").expect("the transcript is written");
        }
        if self.history.len() == HISTORY_EXCHANGES {
            self.history.pop_front();
        }
        self.history.push_back(text.to_string());
    }

    fn with_history(&self, what: &str) -> String {
        let mut text = format!("{what}\n  the last exchanges, oldest first:");
        for exchange in &self.history {
            text.push_str("\n    ");
            text.push_str(exchange);
        }
        text
    }
}

/// The `key=value` number of a reply.
fn number(reply: &str, key: &str) -> Result<f64, String> {
    reply
        .split(' ')
        .find_map(|word| word.strip_prefix(key)?.strip_prefix('='))
        .and_then(|value| value.parse().ok())
        .ok_or_else(|| format!("no number {key}= in {reply:?}"))
}

/// The parameters `status` states.
fn parameters(status: &str) -> Result<Parameters, String> {
    if !status.starts_with("OK state=") {
        return Err(format!("status: {status}"));
    }
    Ok(Parameters {
        freq_hz: number(status, Param::Frequency.reply_key())?,
        duty: number(status, Param::Duty.reply_key())?,
        stroke_mm: number(status, Param::Stroke.reply_key())?,
        accel_mps2: number(status, Param::Accel.reply_key())?,
        ramp_cycles: number(status, Param::Ramp.reply_key())? as u16,
    })
}

/// The holding registers agree with `status` to within a count (the reply rounds), the ramp
/// exactly.
fn check_holdings_match_status(registers: &[u16], status: &str) -> Result<(), String> {
    for register in Holding::ALL {
        let Some(param) = register.param() else {
            continue;
        };
        let stated = number(status, param.reply_key())?;
        let expected = (stated * register.spec().scale).round();
        let read = f64::from(registers[usize::from(register.spec().address)]);
        let tolerance = if register == Holding::Ramp { 0.0 } else { 1.0 };
        if (read - expected).abs() > tolerance {
            return Err(format!(
                "holding {} reads {read}, `status` says {stated}: {registers:?} vs {status}",
                register.spec().name
            ));
        }
    }
    Ok(())
}
