//! The QEMU console image's Modbus RTU slave (`FEEDER_QEMU_ELF`, UART1 on loopback TCP) driven
//! by a real master, `tokio-modbus`'s RTU client: every holding register read, written and
//! refused as its console command would be, every input register read, a run through the
//! registers, the exceptions, frames that get no answer, a master that falls silent mid-run
//! (the link watchdog's soft stop, judged on the firmware's event stream), and the console and
//! the Modbus port driving two boards to the same settings.

mod support;

// The soak's log sink and whole-run checks (`host-sim`'s firmware-in-the-loop checker), shared
// as they are (this test uses a part of them); the checks name the soak's operator module,
// which comes along unused.
#[allow(dead_code)]
#[path = "soak/checks.rs"]
mod checks;
#[allow(dead_code)]
#[path = "soak/log.rs"]
mod log;
#[allow(dead_code)]
#[path = "soak/operator.rs"]
mod operator;

use std::collections::BTreeMap;
use std::path::Path;
use std::thread;
use std::time::{Duration, Instant};

use feeder_shared::event::{parse_line, Event, SegmentEvent};
use feeder_shared::modbus::{Holding, Input};
use feeder_shared::SegmentKind;
use support::modbus::{frame, Failure, Master, SLAVE};
use support::{console_image, Clocked, Console, Emulator, LogSink};
use tokio_modbus::{ExceptionCode, Request};

/// Longest the feeder may take to reach a requested state, in wall time.
const STATE_TIMEOUT: Duration = Duration::from_secs(30);
/// The configuration's default link timeout.
const LINK_TIMEOUT_MS: u64 = 2_000;
/// The stop ramp the link-loss test sets.
const STOP_RAMP_CYCLES: u16 = 10;

const EXCEPTION_FUNCTION: u8 = 1;
const EXCEPTION_ADDRESS: u8 = 2;
const EXCEPTION_VALUE: u8 = 3;
const EXCEPTION_STATE: u8 = 4;

/// The console's code for a value outside a register's choices (`OutOfRange`).
const ERR_OUT_OF_RANGE: u16 = 28;
/// The console's code for a parameter it does not know.
const ERR_UNKNOWN_PARAMETER: u16 = 23;
/// The console's code for a start while a fault is latched.
const ERR_FAULT_LATCHED: u16 = 61;
/// The console's code for a recipe slot with nothing saved.
const ERR_RECIPE_EMPTY: u16 = 63;

fn holding(register: Holding) -> u16 {
    register.spec().address
}

fn input(register: Input) -> u16 {
    register.spec().address
}

/// The exception's code on the wire.
fn code(exception: ExceptionCode) -> u8 {
    u8::from(exception)
}

/// The code of a console's `ERR <code> …` reply.
fn console_error(reply: &str) -> u16 {
    reply
        .strip_prefix("ERR ")
        .and_then(|rest| rest.split(' ').next())
        .and_then(|code| code.parse().ok())
        .unwrap_or_else(|| panic!("not an ERR reply: {reply:?}"))
}

/// The `key=value` words of a console reply.
fn words(reply: &str) -> BTreeMap<String, String> {
    reply
        .split(' ')
        .filter_map(|word| word.split_once('='))
        .map(|(key, value)| (key.to_string(), value.to_string()))
        .collect()
}

fn number(words: &BTreeMap<String, String>, key: &str) -> f64 {
    words
        .get(key)
        .and_then(|value| value.parse().ok())
        .unwrap_or_else(|| panic!("no number {key}= in {words:?}"))
}

/// Every holding register.
fn holdings(master: &mut Master) -> Vec<u16> {
    master
        .read_holding(0, Holding::ALL.len() as u16)
        .expect("the holding registers read")
}

/// Every input register.
fn inputs(master: &mut Master) -> Vec<u16> {
    master
        .read_input(0, Input::ALL.len() as u16)
        .expect("the input registers read")
}

/// The holding registers agree with the console's `status`: each parameter within one count
/// of its register's resolution (the reply shows rounded values), the ramp exactly.
fn check_holdings_match_status(registers: &[u16], status: &str) {
    let words = words(status);
    for register in Holding::ALL {
        let Some(param) = register.param() else {
            continue;
        };
        let stated = number(&words, param.reply_key());
        let expected = (stated * register.spec().scale).round();
        let read = f64::from(registers[usize::from(holding(register))]);
        let tolerance = if register == Holding::Ramp { 0.0 } else { 1.0 };
        assert!(
            (read - expected).abs() <= tolerance,
            "holding {} reads {read}, `status` says {stated} ({expected} counts): {registers:?} \
             vs {status}",
            register.spec().name
        );
    }
}

/// Writes `value` to `register`, which must accept it; returns the holding registers after.
fn accepted(master: &mut Master, console: &mut Console, register: Holding, value: u16) -> Vec<u16> {
    let name = register.spec().name;
    master
        .write_register(holding(register), value)
        .unwrap_or_else(|exception| panic!("{name} = {value} refused: {exception:?}"));
    let refusal = master
        .read_input(input(Input::Refusal), 2)
        .expect("refusal reads");
    assert_eq!(
        refusal,
        [0, 0xffff],
        "{name} = {value}: an accepted write clears the refusal"
    );
    let registers = holdings(master);
    check_holdings_match_status(&registers, &console.command("status"));
    registers
}

/// Writes `value` to `register`, which must refuse it with `exception` and leave the console's
/// `ERR` code in `refusal` (the code of `console_line` on the console, where one says the
/// same, else `code`) and the register in `refused_register`; nothing changes.
fn refused(
    master: &mut Master,
    console: &mut Console,
    register: u16,
    value: u16,
    exception: u8,
    console_line: Option<&str>,
    expected_code: Option<u16>,
) -> u16 {
    let before = holdings(master);
    let answer = master.write_register(register, value);
    assert_eq!(
        answer.map_err(code),
        Err(exception),
        "holding {register} = {value}"
    );
    let link = master
        .read_input(input(Input::Refusal), 2)
        .expect("refusal reads");
    assert_eq!(
        link[1], register,
        "refused_register after {register} = {value}"
    );
    let refusal = link[0];
    if let Some(expected) = expected_code {
        assert_eq!(refusal, expected, "refusal after {register} = {value}");
    }
    if let Some(line) = console_line {
        let reply = console.command(line);
        assert_eq!(
            console_error(&reply),
            refusal,
            "the console refuses {line:?} ({reply}) with the code Modbus reports for \
             {register} = {value}"
        );
    }
    assert_eq!(
        holdings(master),
        before,
        "a refused write of {value} to {register} changed the registers"
    );
    refusal
}

/// Polls the input registers (talking keeps the link watchdog fed) until `done` holds; returns
/// the registers then and every distinct (state, phase) seen on the way.
fn poll_inputs(
    master: &mut Master,
    what: &str,
    mut done: impl FnMut(&[u16]) -> bool,
) -> (Vec<u16>, Vec<(u16, u16)>) {
    let deadline = Instant::now() + STATE_TIMEOUT;
    let mut seen: Vec<(u16, u16)> = Vec::new();
    loop {
        let registers = inputs(master);
        let pair = (
            registers[usize::from(input(Input::State))],
            registers[usize::from(input(Input::Phase))],
        );
        if seen.last() != Some(&pair) {
            seen.push(pair);
        }
        if done(&registers) {
            return (registers, seen);
        }
        assert!(
            Instant::now() < deadline,
            "not {what} after {STATE_TIMEOUT:?}: {registers:?}, seen {seen:?}"
        );
        thread::sleep(Duration::from_millis(2));
    }
}

/// `seen` goes through (some of) `order`, in that order.
fn check_in_order(seen: &[(u16, u16)], order: &[(u16, u16)], what: &str) {
    let ranks: Vec<Option<usize>> = seen
        .iter()
        .map(|pair| order.iter().position(|expected| expected == pair))
        .collect();
    assert!(
        ranks.iter().all(Option::is_some) && ranks.windows(2).all(|pair| pair[0] < pair[1]),
        "{what}: (state, phase) went {seen:?}, not along {order:?}"
    );
}

fn state_and_phase(registers: &[u16]) -> (u16, u16) {
    (
        registers[usize::from(input(Input::State))],
        registers[usize::from(input(Input::Phase))],
    )
}

fn cycles(registers: &[u16]) -> u32 {
    u32::from(registers[usize::from(input(Input::CyclesHigh))]) << 16
        | u32::from(registers[usize::from(input(Input::CyclesLow))])
}

fn uptime_s(registers: &[u16]) -> u32 {
    u32::from(registers[usize::from(input(Input::UptimeHigh))]) << 16
        | u32::from(registers[usize::from(input(Input::UptimeLow))])
}

/// Ends the emulation and checks that the firmware logged no error and no fault.
fn shut_down_without_faults<S: LogSink>(emulator: Emulator<Clocked<S>>) {
    let (_, log) = emulator.shut_down().into_parts();
    assert!(
        !log.iter()
            .any(|line| line.contains("ERROR") || line.contains("fault")),
        "{}",
        log.join("\n")
    );
}

/// A board with its Modbus port, its log going to `sink` (with the log's clock), the console,
/// and a master on the Modbus port.
fn board<S: LogSink>(sink: S) -> (Emulator<Clocked<S>>, Console, Master) {
    let (sink, clock) = Clocked::new(sink);
    let mut emulator = Emulator::launch_with_modbus(&console_image(), sink);
    let console = emulator.connect();
    let master = Master::new(emulator.connect_modbus(), clock);
    (emulator, console, master)
}

/// No answer comes to what was just sent, while the firmware's time passes its frame gap.
fn no_answer(master: &mut Master, what: &str) {
    if let Err(found) = master.no_answer() {
        panic!("{what}: {found}");
    }
}

#[test]
fn the_crc_of_the_specification_example() {
    // Modbus over serial line V1.02, appendix B: 02 07 has the CRC 0x1241, sent 41 12.
    assert_eq!(frame::build(2, 7, &[]), [0x02, 0x07, 0x41, 0x12]);
}

/// Each holding register reads what `status` shows, takes the values its console command takes
/// (each read back), and refuses the values the console refuses, with the console's code.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn every_holding_register_reads_writes_and_refuses_as_its_console_command() {
    let (emulator, mut console, mut master) = board(());

    let power_up = holdings(&mut master);
    assert_eq!(
        power_up,
        [0, 65535, 5860, 5000, 2500, 1459, 1254, 25, 0],
        "the compiled defaults"
    );
    check_holdings_match_status(&power_up, &console.command("status"));
    for register in Holding::ALL {
        let alone = master
            .read_holding(holding(register), 1)
            .expect("one register reads");
        assert_eq!(
            alone[0],
            power_up[usize::from(holding(register))],
            "{register:?}"
        );
    }

    // Accepted writes, each read back.
    for (register, value, line, reply) in [
        (Holding::Frequency, 5500, "get freq", "OK freq_hz=55"),
        (Holding::Duty, 6000, "get duty", "OK duty=0.6"),
        (Holding::Stroke, 2000, "get stroke", "OK stroke_mm=2"),
        (Holding::Accel, 1200, "get accel", "OK accel_mps2=120"),
    ] {
        let after = accepted(&mut master, &mut console, register, value);
        assert_eq!(after[usize::from(holding(register))], value, "{register:?}");
        console.expect(line, reply);
    }
    let after = accepted(&mut master, &mut console, Holding::Feed, 1000);
    let feed = after[usize::from(holding(Holding::Feed))];
    // The inverse model picks the duty for the feed: its prediction within its tolerance.
    assert!(feed.abs_diff(1000) <= 2, "feed reads {feed} after 1000");
    console.expect("get feed", "OK feed_mmps=");
    let after = accepted(&mut master, &mut console, Holding::Ramp, 10);
    assert_eq!(after[usize::from(holding(Holding::Ramp))], 10);
    console.expect("get ramp", "OK ramp_cycles=10");
    // Every ramp length is a valid one.
    accepted(&mut master, &mut console, Holding::Ramp, 0);
    accepted(&mut master, &mut console, Holding::Ramp, 65535);
    accepted(&mut master, &mut console, Holding::Ramp, 10);
    // A recipe saved on the console loads through the register, which reads it until a setting
    // changes.
    console.expect("recipe save 2", "OK recipe 2 saved");
    let saved = holdings(&mut master);
    accepted(&mut master, &mut console, Holding::Frequency, 6000);
    let loaded = accepted(&mut master, &mut console, Holding::Recipe, 2);
    assert_eq!(loaded[usize::from(holding(Holding::Recipe))], 2);
    assert_eq!(
        loaded[2..8],
        saved[2..8],
        "recipe 2 brings back its settings"
    );
    let changed = accepted(&mut master, &mut console, Holding::Duty, 6100);
    assert_eq!(changed[usize::from(holding(Holding::Recipe))], 65535);
    // A stop while stopped, an acknowledgement without a fault: accepted, and they read 0.
    let after = accepted(&mut master, &mut console, Holding::Run, 0);
    assert_eq!(after[usize::from(holding(Holding::Run))], 0);
    let after = accepted(&mut master, &mut console, Holding::Acknowledge, 1);
    assert_eq!(after[usize::from(holding(Holding::Acknowledge))], 0);
    // A write of several registers: all of them.
    master
        .write_registers(holding(Holding::Duty), &[6200, 5800])
        .expect("duty and freq together");
    let after = holdings(&mut master);
    assert_eq!(after[2..4], [6200, 5800]);
    check_holdings_match_status(&after, &console.command("status"));

    // Refusals: each register's, with its exception and the console's code.
    let run = holding(Holding::Run);
    refused(
        &mut master,
        &mut console,
        run,
        2,
        EXCEPTION_VALUE,
        None,
        Some(ERR_OUT_OF_RANGE),
    );
    let recipe = holding(Holding::Recipe);
    refused(
        &mut master,
        &mut console,
        recipe,
        8,
        EXCEPTION_VALUE,
        None,
        Some(ERR_OUT_OF_RANGE),
    );
    refused(
        &mut master,
        &mut console,
        recipe,
        5,
        EXCEPTION_STATE,
        Some("recipe load 5"),
        Some(ERR_RECIPE_EMPTY),
    );
    let cases: [(Holding, u16, &str); 8] = [
        (Holding::Duty, 9000, "set duty 0.9"),
        (Holding::Duty, 4000, "set duty 0.4"),
        (Holding::Frequency, 0, "set freq 0"),
        (Holding::Frequency, 20000, "set freq 200"),
        (Holding::Stroke, 6000, "set stroke 6"),
        (Holding::Accel, 3000, "set accel 300"),
        (Holding::Feed, 60000, "set feed 6000"),
        (Holding::Feed, 0, "set feed 0"),
    ];
    for (register, value, line) in cases {
        let refusal = refused(
            &mut master,
            &mut console,
            holding(register),
            value,
            EXCEPTION_VALUE,
            Some(line),
            None,
        );
        assert!(
            (40..=58).contains(&refusal),
            "{line}: refusal {refusal} is no validation code"
        );
        println!(
            "{} = {value}: exception 3, refusal {refusal} (as {line:?})",
            register.spec().name
        );
    }
    let acknowledge = holding(Holding::Acknowledge);
    for value in [0, 2] {
        refused(
            &mut master,
            &mut console,
            acknowledge,
            value,
            EXCEPTION_VALUE,
            None,
            Some(ERR_OUT_OF_RANGE),
        );
    }
    refused(
        &mut master,
        &mut console,
        Holding::ALL.len() as u16,
        1,
        EXCEPTION_ADDRESS,
        Some("set speed 1"),
        Some(ERR_UNKNOWN_PARAMETER),
    );
    // All or nothing: the duty is not kept when the frequency beside it is refused, nor the
    // ramp when the write runs past the last register.
    let before = holdings(&mut master);
    let answer = master.write_registers(holding(Holding::Duty), &[6500, 0]);
    assert_eq!(answer.map_err(code), Err(EXCEPTION_VALUE));
    let link = master.read_input(input(Input::Refusal), 2).expect("reads");
    assert_eq!(link[1], holding(Holding::Frequency), "{link:?}");
    assert_eq!(holdings(&mut master), before);
    let answer = master.write_registers(holding(Holding::Ramp), &[12, 1, 7]);
    assert_eq!(answer.map_err(code), Err(EXCEPTION_ADDRESS));
    let link = master.read_input(input(Input::Refusal), 2).expect("reads");
    assert_eq!(link, [ERR_UNKNOWN_PARAMETER, Holding::ALL.len() as u16]);
    assert_eq!(holdings(&mut master), before);

    // Reads past the map.
    for (address, count) in [(9, 1), (8, 2), (0, 10), (100, 1)] {
        let answer = master.read_holding(address, count);
        assert_eq!(
            answer.map_err(code),
            Err(EXCEPTION_ADDRESS),
            "holding {address}+{count}"
        );
    }
    // Reads leave the refusal as it was.
    let link = master.read_input(input(Input::Refusal), 2).expect("reads");
    assert_eq!(link, [ERR_UNKNOWN_PARAMETER, Holding::ALL.len() as u16]);
    drop(console);
    shut_down_without_faults(emulator);
}

/// Each input register reads what the feeder does; a start and a stop through `run` show in
/// `state` and `phase`.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn every_input_register_reads_and_a_run_shows_in_state_and_phase() {
    let (emulator, mut console, mut master) = board(());

    let first = inputs(&mut master);
    assert_eq!(first.len(), Input::ALL.len());
    assert_eq!(state_and_phase(&first), (0, 0), "stopped: {first:?}");
    assert_eq!(first[usize::from(input(Input::Fault))], 0);
    assert_eq!(first[usize::from(input(Input::Refusal))], 0);
    assert_eq!(first[usize::from(input(Input::RefusedRegister))], 65535);
    // No closed loop, no part sensor on this image.
    for register in [
        Input::LoopStage,
        Input::GainPositive,
        Input::GainNegative,
        Input::Offset,
        Input::Lag,
        Input::PartsPerMinute,
    ] {
        assert_eq!(first[usize::from(input(register))], 0, "{register:?}");
    }
    let feed = holdings(&mut master)[usize::from(holding(Holding::Feed))];
    assert_eq!(first[usize::from(input(Input::FeedPredicted))], feed);
    // Every register alone reads as in the block (the clocks only move forward).
    for register in Input::ALL {
        let alone = master
            .read_input(input(register), 1)
            .expect("one register reads")[0];
        let in_block = first[usize::from(input(register))];
        match register {
            Input::CyclesLow | Input::UptimeLow => assert!(alone >= in_block, "{register:?}"),
            _ => assert_eq!(alone, in_block, "{register:?}"),
        }
    }
    for (address, count) in [(16, 1), (15, 2), (0, 17)] {
        let answer = master.read_input(address, count);
        assert_eq!(
            answer.map_err(code),
            Err(EXCEPTION_ADDRESS),
            "input {address}+{count}"
        );
    }
    // The clocks run, and `uptime` is the console's.
    thread::sleep(Duration::from_millis(300));
    let later = inputs(&mut master);
    assert!(cycles(&later) > cycles(&first), "{first:?} then {later:?}");
    let status = console.command("status");
    let console_uptime = number(&words(&status), "uptime_s");
    let uptime = f64::from(uptime_s(&inputs(&mut master)));
    assert!(
        uptime >= console_uptime.floor() && uptime <= console_uptime + 2.0,
        "uptime {uptime} s, the console's {console_uptime} s"
    );
    // The input `feed_predicted` follows the holding `feed`.
    master
        .write_register(holding(Holding::Frequency), 5500)
        .expect("freq 55");
    let feed = holdings(&mut master)[usize::from(holding(Holding::Feed))];
    assert_eq!(
        inputs(&mut master)[usize::from(input(Input::FeedPredicted))],
        feed
    );

    // A run: starting, running, stopping, stopped.
    master
        .write_register(holding(Holding::Ramp), 10)
        .expect("ramp");
    master
        .write_register(holding(Holding::Run), 1)
        .expect("run = 1");
    let (running, seen) = poll_inputs(&mut master, "running", |registers| {
        state_and_phase(registers) == (1, 2)
    });
    assert_eq!(holdings(&mut master)[usize::from(holding(Holding::Run))], 1);
    assert_eq!(running[usize::from(input(Input::Fault))], 0);
    // The state turns at the request, the phase at the next cycle boundary.
    check_in_order(&seen, &[(0, 0), (1, 0), (1, 1), (1, 2)], "starting");
    assert!(seen.contains(&(1, 1)), "never seen starting: {seen:?}");
    console.expect("status", "OK state=running ");
    master
        .write_register(holding(Holding::Run), 0)
        .expect("run = 0");
    let (stopped, seen) = poll_inputs(&mut master, "stopped", |registers| {
        state_and_phase(registers) == (0, 0)
    });
    check_in_order(&seen, &[(1, 2), (2, 2), (2, 3), (0, 3), (0, 0)], "stopping");
    assert!(seen.contains(&(2, 3)), "never seen stopping: {seen:?}");
    assert!(cycles(&stopped) > cycles(&running));
    assert_eq!(holdings(&mut master)[usize::from(holding(Holding::Run))], 0);
    console.expect("status", "OK state=stopped ");
    drop(console);
    shut_down_without_faults(emulator);
}

/// Unknown addresses, refused values and functions the slave does not serve get their
/// exceptions; the functions no `tokio-modbus` request covers are sent as custom requests.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn unknown_functions_answer_exception_1() {
    let (emulator, console, mut master) = board(());
    for request in [
        Request::ReadCoils(0, 1),
        Request::ReadDiscreteInputs(0, 1),
        Request::WriteSingleCoil(0, true),
        Request::WriteMultipleCoils(0, vec![true, false].into()),
    ] {
        let shown = format!("{request:?}");
        let answer = master.call(request);
        assert_eq!(
            answer.map(|_| ()).map_err(code),
            Err(EXCEPTION_FUNCTION),
            "{shown}"
        );
    }
    // Function 0x2B (encapsulated interface) in a frame of the 8 bytes the slave's framing
    // expects: `tokio-modbus` reads the exception but, as it names 0x2B otherwise, reports a
    // function-code mismatch around it.
    let answer = master.try_call(Request::Custom(0x2b, vec![0x0e, 0x01, 0x00, 0x00].into()));
    match answer {
        Err(Failure::Transport(tokio_modbus::Error::Protocol(
            tokio_modbus::ProtocolError::FunctionCodeMismatch { result, .. },
        ))) => {
            let exception = result.expect_err("an exception");
            assert_eq!(exception.function.value(), 0x2b);
            assert_eq!(code(exception.exception), EXCEPTION_FUNCTION);
        }
        other => panic!("0x2B answered {other:?}"),
    }
    // A raw 0x2B frame, answered by hand: 01 AB 01 and its CRC.
    let answer = master.raw_exchange(&frame::build(SLAVE, 0x2b, &[0x0e, 0x01, 0x00, 0x00]), 5);
    assert_eq!(answer, frame::build(SLAVE, 0xab, &[EXCEPTION_FUNCTION]));
    // The link is still in step.
    master
        .read_holding(0, 1)
        .expect("a read after the exceptions");

    // The functions whose requests have no length the slave knows: Read Device
    // Identification (0x2B / 0x0E, 7 bytes) and Report Server ID (0x11, 4 bytes). The slave's
    // framing (`feeder_shared::modbus::FrameAssembler`) ends them at the silence after them,
    // and their CRC holds: exception 01, as for the 8-byte one above.
    master.set_retries(0);
    for request in [
        Request::ReadDeviceIdentification(tokio_modbus::prelude::ReadCode::Basic, 0),
        Request::ReportServerId,
    ] {
        let shown = format!("{request:?}");
        match master.try_call(request) {
            Ok(Err(exception)) => assert_eq!(code(exception), EXCEPTION_FUNCTION, "{shown}"),
            Err(Failure::Transport(tokio_modbus::Error::Protocol(
                tokio_modbus::ProtocolError::FunctionCodeMismatch { result, .. },
            ))) => {
                let exception = result.expect_err("an exception");
                assert_eq!(code(exception.exception), EXCEPTION_FUNCTION, "{shown}");
            }
            other => panic!("{shown} answered {other:?}"),
        }
        master
            .read_holding(0, 9)
            .expect("the next request is served");
    }
    master.set_retries(support::modbus::RETRIES);
    drop(console);
    emulator.shut_down();
}

/// Garbage, a frame with a corrupt CRC, a frame for another slave and a frame cut short get no
/// answer and change nothing; the next valid request after a silence is answered.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn garbage_and_corrupt_frames_get_no_answer_and_the_next_request_does() {
    let (emulator, console, mut master) = board(());
    let before = holdings(&mut master);
    let duty = holding(Holding::Duty);

    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("text", b"garbage, not a frame\r\n".to_vec()),
        (
            "binary noise",
            vec![0xff, 0x00, 0x13, 0x37, 0xfe, 0x80, 0x7f, 0x01],
        ),
        (
            "a write with a corrupt CRC",
            frame::corrupt(frame::write_register(SLAVE, duty, 6000), 0x0001),
        ),
        (
            "a read with a corrupt CRC",
            frame::corrupt(frame::read(SLAVE, 3, 0, 9), 0x8000),
        ),
        (
            "a write to another slave",
            frame::write_register(SLAVE + 1, duty, 6000),
        ),
        (
            "a read cut short",
            frame::read(SLAVE, 4, 0, 16)[..5].to_vec(),
        ),
        (
            "a write of several registers with a corrupt CRC",
            frame::corrupt(
                frame::build(SLAVE, 16, &[0, 2, 0, 2, 4, 0x17, 0x70, 0x15, 0x7c]),
                0x0100,
            ),
        ),
        (
            "a valid write run into garbage",
            [
                b"\x01\x02\x03".to_vec(),
                frame::write_register(SLAVE, duty, 6000),
            ]
            .concat(),
        ),
        ("one byte", vec![SLAVE]),
    ];
    for (what, bytes) in cases {
        master.send_raw(&bytes);
        no_answer(&mut master, what);
        let after = master
            .read_holding(0, 9)
            .unwrap_or_else(|exception| panic!("after {what}: {exception:?}"));
        assert_eq!(after, before, "{what} changed the registers");
        let link = master.read_input(input(Input::Refusal), 2).expect("reads");
        assert_eq!(link, [0, 65535], "{what} left a refusal");
    }
    // Garbage sent right behind a valid request is not taken for its answer: the answer is
    // the request's, then the garbage is dropped.
    let request = [frame::read(SLAVE, 3, duty, 1), b"\x00\x00\x00".to_vec()].concat();
    let answer = master.raw_exchange(&request, 7);
    assert_eq!(
        answer,
        frame::build(SLAVE, 3, &[2, 0x16, 0xe4]),
        "duty 5860"
    );
    no_answer(&mut master, "garbage after a request");
    master.write_register(duty, 6000).expect("a valid write");
    assert_eq!(holdings(&mut master)[usize::from(duty)], 6000);
    drop(console);
    emulator.shut_down();
}

/// What the log of a run shows.
struct Stream {
    events: Vec<Event>,
    segments: Vec<SegmentEvent>,
}

impl Stream {
    fn of(lines: &[String]) -> Self {
        let events: Vec<Event> = lines
            .iter()
            .filter_map(|line| parse_line(line).unwrap_or_else(|error| panic!("{error}: {line}")))
            .collect();
        let segments = events
            .iter()
            .filter_map(|event| match event {
                Event::Segment(segment) => Some(*segment),
                _ => None,
            })
            .collect();
        Stream { events, segments }
    }

    /// The planned start of `cycle`.
    fn cycle_start(&self, cycle: u64) -> u64 {
        self.segments
            .iter()
            .find(|segment| segment.cycle == cycle)
            .unwrap_or_else(|| panic!("no segment of cycle {cycle}"))
            .planned_tick
    }
}

/// A master that starts the feeder and falls silent: after the link timeout the feeder latches
/// `link-lost` and stops softly on its ramp, on the planned ticks; a start is refused until
/// `acknowledge`.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn a_master_that_falls_silent_mid_run_loses_the_link_and_the_feeder_stops_softly() {
    let output = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let (soak_log, _progress) = log::SoakLog::create(&output.join("modbus-link-lost.log"));
    let (emulator, mut console, mut master) = board(soak_log);

    master
        .write_register(holding(Holding::Ramp), STOP_RAMP_CYCLES)
        .expect("ramp");
    master
        .write_register(holding(Holding::Run), 1)
        .expect("run = 1");
    let (running, _) = poll_inputs(&mut master, "running", |registers| {
        state_and_phase(registers) == (1, 2)
    });
    // The master's last request: the read that saw it running, in this cycle.
    let last_cycle = u64::from(cycles(&running));
    let silent_from = Instant::now();
    console.wait_for_state("fault", STATE_TIMEOUT);
    let fault_after_wall = silent_from.elapsed();
    let status = console.command("status");
    assert!(status.ends_with(" fault=link-lost"), "{status}");
    // Talking again does not clear it; the soft stop runs to its end.
    let (faulted, _) = poll_inputs(&mut master, "stopped with the fault", |registers| {
        state_and_phase(registers) == (3, 0)
    });
    assert_eq!(
        faulted[usize::from(input(Input::Fault))],
        6,
        "link-lost: {faulted:?}"
    );
    assert_eq!(holdings(&mut master)[usize::from(holding(Holding::Run))], 0);
    // A start while the fault is latched: refused by the state, as on the console.
    let refusal = refused(
        &mut master,
        &mut console,
        holding(Holding::Run),
        1,
        EXCEPTION_STATE,
        Some("start"),
        Some(ERR_FAULT_LATCHED),
    );
    assert_eq!(refusal, ERR_FAULT_LATCHED);
    // `acknowledge` clears it; the feeder runs again.
    master
        .write_register(holding(Holding::Acknowledge), 1)
        .expect("acknowledge");
    let (cleared, _) = poll_inputs(&mut master, "cleared", |registers| {
        state_and_phase(registers) == (0, 0)
    });
    assert_eq!(cleared[usize::from(input(Input::Fault))], 0);
    console.expect("status", "OK state=stopped ");
    master
        .write_register(holding(Holding::Run), 1)
        .expect("run = 1 again");
    poll_inputs(&mut master, "running again", |registers| {
        state_and_phase(registers) == (1, 2)
    });
    master
        .write_register(holding(Holding::Run), 0)
        .expect("run = 0");
    poll_inputs(&mut master, "stopped", |registers| {
        state_and_phase(registers) == (0, 0)
    });
    thread::sleep(Duration::from_millis(100));
    drop(console);
    let (soak_log, lines) = emulator.shut_down().into_parts();
    let summary = soak_log.finish();

    // Every edge on its planned tick, changes only at cycle boundaries, no firmware error.
    let mut failures: Vec<String> = Vec::new();
    failures.extend(checks::edges(&summary.report).err());
    failures.extend(checks::log_lines(&summary).err());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    let stream = Stream::of(&lines);
    let stops: Vec<u64> = stream
        .events
        .iter()
        .filter_map(|event| match event {
            Event::Stop { tick } => Some(*tick),
            _ => None,
        })
        .collect();
    assert!(
        !stream
            .events
            .iter()
            .any(|event| matches!(event, Event::Halt { .. } | Event::QuickStop { .. })),
        "a halt, not a soft stop"
    );
    assert_eq!(
        stops.len(),
        2,
        "the link loss's stop and the last one: {stops:?}"
    );
    let stop_tick = stops[0];
    let lost = lines
        .iter()
        .filter(|line| line.contains("link lost: the Modbus master fell silent"))
        .count();
    assert_eq!(lost, 1, "one link loss logged");

    // The stop came the link timeout after the last request, which was answered in cycle
    // `last_cycle`: the request lies in that cycle (give or take one: the register counts the
    // cycle the control loop last published), the watchdog wakes 1 ms after its deadline, and
    // the stop takes the next segment start.
    let period = stream.cycle_start(last_cycle + 1) - stream.cycle_start(last_cycle);
    let period_ms = period as f64 / 1e3;
    let longest_ms = stream
        .segments
        .iter()
        .filter(|segment| segment.cycle >= last_cycle && segment.planned_tick < stop_tick)
        .map(|segment| f64::from(segment.ticks) / 1e3)
        .fold(0.0, f64::max);
    let silence_ms = (stop_tick - stream.cycle_start(last_cycle)) as f64 / 1e3;
    let timeout_ms = LINK_TIMEOUT_MS as f64;
    println!(
        "link lost: the soft stop came {silence_ms:.1} ms of virtual time after the start of the \
         cycle of the last request (link timeout {LINK_TIMEOUT_MS} ms, cycles of {period_ms:.1} \
         ms, segments up to {longest_ms:.1} ms); the console saw the fault {:.0} ms of wall \
         time after the master fell silent",
        fault_after_wall.as_secs_f64() * 1e3
    );
    assert!(
        (timeout_ms - period_ms..=timeout_ms + period_ms + 1.0 + longest_ms).contains(&silence_ms),
        "the stop came {silence_ms} ms after the start of the last request's cycle, not the \
         link timeout {LINK_TIMEOUT_MS} ms after the request"
    );

    // The stop ramps down: from the first cycle after it, one step less a cycle to idle.
    let after_stop: Vec<&SegmentEvent> = stream
        .segments
        .iter()
        .filter(|segment| segment.planned_tick >= stop_tick)
        .collect();
    let first_cycle = after_stop
        .iter()
        .find(|segment| segment.starts_cycle())
        .expect("a cycle after the stop")
        .cycle;
    let mut steps: Vec<(u64, u16, SegmentKind)> = Vec::new();
    for segment in after_stop
        .iter()
        .filter(|segment| segment.cycle >= first_cycle)
    {
        if steps.last().map(|(cycle, _, _)| *cycle) != Some(segment.cycle) {
            steps.push((segment.cycle, segment.step, segment.kind));
        }
        if segment.kind == SegmentKind::Idle {
            break;
        }
    }
    let ramp: Vec<u16> = steps.iter().map(|(_, step, _)| *step).collect();
    let expected: Vec<u16> = (0..STOP_RAMP_CYCLES).rev().collect();
    assert_eq!(
        ramp, expected,
        "the soft stop's steps, cycle by cycle: {steps:?}"
    );
    let idle_at = stream.cycle_start(steps.last().expect("an idle cycle").0);
    let idle_after_ms = (idle_at - stream.cycle_start(last_cycle)) as f64 / 1e3;
    println!(
        "link lost: idle {idle_after_ms:.1} ms after the last request's cycle began \
         ({STOP_RAMP_CYCLES}-cycle ramp)"
    );
    assert!(
        idle_after_ms
            <= (LINK_TIMEOUT_MS as f64 + (f64::from(STOP_RAMP_CYCLES) + 2.0) * period as f64 / 1e3),
        "idle only {idle_after_ms} ms after the last request"
    );
}

/// One step of the agreement test: the same change through the console and through Modbus.
struct Change {
    console: &'static str,
    register: Holding,
    value: u16,
}

const fn change(console: &'static str, register: Holding, value: u16) -> Change {
    Change {
        console,
        register,
        value,
    }
}

/// The `status` reply without what differs between two boards (uptime, cycles).
fn settings_of(status: &str) -> String {
    status
        .split(' ')
        .filter(|word| !word.starts_with("uptime_s=") && !word.starts_with("cycles="))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Two boards, one driven through its console and one through Modbus with the same changes,
/// end with the same settings after each: `status`, `get` and the holding registers agree,
/// and each refusal's console code is the other's `refusal` register.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn the_console_and_modbus_make_the_same_changes() {
    let (by_console, mut console, mut watcher) = board(());
    let (by_modbus, mut side_console, mut master) = board(());

    let steps = [
        Some(change("set freq 55", Holding::Frequency, 5500)),
        Some(change("set duty 0.6", Holding::Duty, 6000)),
        Some(change("set stroke 2", Holding::Stroke, 2000)),
        Some(change("set accel 120", Holding::Accel, 1200)),
        Some(change("set feed 100", Holding::Feed, 1000)),
        Some(change("set ramp 10", Holding::Ramp, 10)),
        None, // both save recipe 4 on the console
        Some(change("set freq 60", Holding::Frequency, 6000)),
        Some(change("set duty 0.9", Holding::Duty, 9000)),
        Some(change("recipe load 4", Holding::Recipe, 4)),
        Some(change("set stroke 6", Holding::Stroke, 6000)),
        Some(change("recipe load 6", Holding::Recipe, 6)),
        Some(change("set freq 0", Holding::Frequency, 0)),
        Some(change("set feed 6000", Holding::Feed, 60000)),
        Some(change("set accel 300", Holding::Accel, 3000)),
        Some(change("set stroke 1.5", Holding::Stroke, 1500)),
        Some(change("set duty 0.55", Holding::Duty, 5500)),
        Some(change("set ramp 3", Holding::Ramp, 3)),
    ];
    let mut refusals = 0;
    for step in &steps {
        let Some(step) = step else {
            console.expect("recipe save 4", "OK recipe 4 saved");
            side_console.expect("recipe save 4", "OK recipe 4 saved");
            continue;
        };
        let reply = console.command(step.console);
        let answer = master.write_register(holding(step.register), step.value);
        let link = master.read_input(input(Input::Refusal), 2).expect("reads");
        match answer {
            Ok(()) => {
                assert!(reply.starts_with("OK "), "{}: {reply}", step.console);
                assert_eq!(link, [0, 65535], "{}", step.console);
            }
            Err(exception) => {
                refusals += 1;
                let expected = console_error(&reply);
                assert_eq!(
                    link,
                    [expected, holding(step.register)],
                    "{} refused on the console with {reply:?}, through Modbus with {exception:?}",
                    step.console
                );
                let wanted = if (60..=64).contains(&expected) {
                    EXCEPTION_STATE
                } else {
                    EXCEPTION_VALUE
                };
                assert_eq!(code(exception), wanted, "{}", step.console);
            }
        }
        let left = settings_of(&console.command("status"));
        let right = settings_of(&side_console.command("status"));
        assert_eq!(left, right, "after {}", step.console);
        assert_eq!(
            holdings(&mut watcher),
            holdings(&mut master),
            "after {}",
            step.console
        );
        for param in ["freq", "duty", "stroke", "accel", "feed", "ramp"] {
            let line = format!("get {param}");
            assert_eq!(
                console.command(&line),
                side_console.command(&line),
                "after {}",
                step.console
            );
        }
    }
    assert_eq!(refusals, 6, "the refused steps");
    drop((console, side_console));
    by_console.shut_down();
    by_modbus.shut_down();
}
