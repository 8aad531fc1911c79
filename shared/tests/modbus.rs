//! Modbus RTU, the production line's link: a request frame in, the response out, and what the
//! write did to the controller. Every request is built here by hand, its CRC by the `crc` crate
//! (not by the codec the server uses), and every response's CRC is checked the same way. A write
//! must do exactly what the console's command with the same value does.

#[path = "common/mod.rs"]
mod common;

use common::machine;
use feeder_shared::closed_loop::{Identified, LoopReport, Stage, TrackReport, TrackState};
use feeder_shared::modbus::map::{self, Holding, Input};
use feeder_shared::modbus::{frame_gap_us, Exchange, FrameAssembler, Response, Server};
use feeder_shared::{
    protocol, Controller, Fault, Outcome, Phase, RecipeSlot, RunState, Settings, Snapshot,
    SupervisorEvent,
};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Fixtures: the control tests' machine, store and snapshots.

use feeder_shared::testing::MemoryStore as Memory;

fn snapshot(state: RunState, phase: Phase, cycles: u64) -> Snapshot {
    Snapshot {
        state,
        phase,
        uptime_ms: 12_345,
        cycles,
        closed_loop: None,
        track: None,
    }
}

fn stopped() -> Snapshot {
    snapshot(RunState::Stopped, Phase::Stopped, 0)
}

fn running() -> Snapshot {
    snapshot(RunState::Running, Phase::Running, 0)
}

fn faulted() -> Snapshot {
    snapshot(RunState::Faulted(Fault::LinkLost), Phase::Stopped, 0)
}

fn controller() -> Controller {
    Controller::new(machine(), Settings::DEFAULT).unwrap()
}

/// One console line, as the console runs it.
fn run(controller: &mut Controller, line: &str, at: &Snapshot, store: &mut Memory) -> Outcome {
    controller.handle(protocol::parse(line), at, store)
}

/// The console's `ERR` code of a line run on a fresh controller, none if it is accepted.
fn console_code(line: &str, at: &Snapshot) -> Option<u16> {
    run(&mut controller(), line, at, &mut Memory::erased())
        .refusal
        .map(|error| error.code())
}

// ---------------------------------------------------------------------------------------------
// Frames, by hand.

/// This board's slave address.
const ADDRESS: u8 = 17;

const CRC: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS);

/// `body` with its CRC, low byte first.
fn frame(body: &[u8]) -> Vec<u8> {
    let mut frame = body.to_vec();
    frame.extend_from_slice(&CRC.checksum(body).to_le_bytes());
    frame
}

/// The frame's last two bytes are the CRC of the rest, low byte first.
fn crc_holds(frame: &[u8]) -> bool {
    frame.len() >= 4 && {
        let (body, crc) = frame.split_at(frame.len() - 2);
        CRC.checksum(body).to_le_bytes() == crc
    }
}

fn read_request(address: u8, function: u8, first: u16, count: u16) -> Vec<u8> {
    let [first_high, first_low] = first.to_be_bytes();
    let [count_high, count_low] = count.to_be_bytes();
    frame(&[
        address, function, first_high, first_low, count_high, count_low,
    ])
}

/// Function code 3: read holding registers.
fn read_holding(first: u16, count: u16) -> Vec<u8> {
    read_request(ADDRESS, 3, first, count)
}

/// Function code 4: read input registers.
fn read_input(first: u16, count: u16) -> Vec<u8> {
    read_request(ADDRESS, 4, first, count)
}

/// Function code 6: write a single register.
fn write_single_to(address: u8, register: u16, value: u16) -> Vec<u8> {
    let [register_high, register_low] = register.to_be_bytes();
    let [value_high, value_low] = value.to_be_bytes();
    frame(&[
        address,
        6,
        register_high,
        register_low,
        value_high,
        value_low,
    ])
}

fn write_single(register: u16, value: u16) -> Vec<u8> {
    write_single_to(ADDRESS, register, value)
}

/// Function code 16: write consecutive registers.
fn write_multiple(first: u16, values: &[u16]) -> Vec<u8> {
    let count = values.len() as u16;
    let mut body = vec![ADDRESS, 16];
    body.extend_from_slice(&first.to_be_bytes());
    body.extend_from_slice(&count.to_be_bytes());
    body.push(2 * values.len() as u8);
    for value in values {
        body.extend_from_slice(&value.to_be_bytes());
    }
    frame(&body)
}

/// The registers a read response (function code `function`) carries.
fn registers(response: &[u8], function: u8) -> Vec<u16> {
    assert!(crc_holds(response), "CRC of {response:02x?}");
    assert_eq!(response[..2], [ADDRESS, function], "{response:02x?}");
    let data = &response[3..response.len() - 2];
    assert_eq!(usize::from(response[2]), data.len(), "{response:02x?}");
    data.chunks_exact(2)
        .map(|pair| u16::from_be_bytes([pair[0], pair[1]]))
        .collect()
}

/// An exception response: `[address, function | 0x80, code, CRC]`.
fn exception(function: u8, code: u8) -> Vec<u8> {
    frame(&[ADDRESS, function | 0x80, code])
}

// ---------------------------------------------------------------------------------------------
// A slave with its controller and store.

struct Slave {
    server: Server,
    controller: Controller,
    store: Memory,
}

impl Slave {
    fn new() -> Self {
        Slave {
            server: Server::new(ADDRESS),
            controller: controller(),
            store: Memory::erased(),
        }
    }

    /// Sends `request` with the feeder at `at`: the response (empty for none) and the exchange.
    fn ask(&mut self, request: &[u8], at: &Snapshot) -> (Vec<u8>, Exchange) {
        let mut response = Response::new();
        let exchange = self.server.handle(
            request,
            &mut self.controller,
            at,
            &mut self.store,
            &mut response,
        );
        if !response.is_empty() {
            assert!(crc_holds(&response), "CRC of {response:02x?}");
        }
        (response.to_vec(), exchange)
    }

    fn holding(&mut self, first: u16, count: u16) -> Vec<u16> {
        let (response, _) = self.ask(&read_holding(first, count), &stopped());
        registers(&response, 3)
    }

    fn input(&mut self, first: u16, count: u16, at: &Snapshot) -> Vec<u16> {
        let (response, _) = self.ask(&read_input(first, count), at);
        registers(&response, 4)
    }

    /// Input registers `refusal` and `refused_register`.
    fn refusal(&mut self) -> [u16; 2] {
        let registers = self.input(2, 2, &stopped());
        [registers[0], registers[1]]
    }
}

// ---------------------------------------------------------------------------------------------
// The frame checks themselves.

#[test]
fn the_crc_of_these_tests_is_the_one_in_the_modbus_specification() {
    // The specification's example: read 3 holding registers from 0x006B at slave 0x11.
    assert_eq!(
        frame(&[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]),
        [0x11, 0x03, 0x00, 0x6B, 0x00, 0x03, 0x76, 0x87]
    );
    assert!(crc_holds(&[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03, 0x76, 0x87]));
    assert!(!crc_holds(&[
        0x11, 0x03, 0x00, 0x6B, 0x00, 0x03, 0x87, 0x76
    ]));
}

// ---------------------------------------------------------------------------------------------
// The register map.

#[test]
fn the_holding_registers_are_the_console_parameters_at_their_scales() {
    // (register, address, name, counts per unit, console command)
    let table = [
        (Holding::Run, 0, "run", 1.0, "start / stop"),
        (Holding::Recipe, 1, "recipe", 1.0, "recipe load N"),
        (Holding::Duty, 2, "duty", 10_000.0, "set duty"),
        (Holding::Frequency, 3, "freq", 100.0, "set freq"),
        (Holding::Stroke, 4, "stroke", 1_000.0, "set stroke"),
        (Holding::Accel, 5, "accel", 10.0, "set accel"),
        (Holding::Feed, 6, "feed", 10.0, "set feed"),
        (Holding::Ramp, 7, "ramp", 1.0, "set ramp"),
        (Holding::Acknowledge, 8, "acknowledge", 1.0, "reset"),
    ];
    assert_eq!(Holding::ALL.len(), table.len());
    for (register, address, name, scale, console) in table {
        let spec = register.spec();
        assert_eq!(
            (spec.address, spec.name, spec.scale, register.console()),
            (address, name, scale, console)
        );
        assert_eq!(Holding::at(address), Some(register));
    }
    assert_eq!(Holding::at(9), None);
    assert_eq!(Holding::at(u16::MAX), None);
}

#[test]
fn the_input_registers_are_numbered_from_zero_in_order() {
    for (address, register) in Input::ALL.into_iter().enumerate() {
        assert_eq!(register.spec().address, address as u16);
        assert_eq!(Input::at(address as u16), Some(register));
    }
    assert_eq!(Input::at(Input::ALL.len() as u16), None);
}

/// What `docs/modbus.md` shows between these lines is what `map::write_table` writes.
const TABLE_BEGINS: &str = "<!-- register table: shared/src/modbus/map.rs -->";
const TABLE_ENDS: &str = "<!-- end of register table -->";

#[test]
fn docs_modbus_md_shows_the_register_map() {
    let page = include_str!("../../docs/modbus.md");
    let (_, rest) = page
        .split_once(TABLE_BEGINS)
        .expect("docs/modbus.md marks where its register table begins");
    let (shown, _) = rest
        .split_once(TABLE_ENDS)
        .expect("docs/modbus.md marks where its register table ends");
    let mut table = String::new();
    map::write_table(&mut table).unwrap();
    assert_eq!(
        shown.trim_matches('\n'),
        table.trim_matches('\n'),
        "docs/modbus.md's register table; it should read:\n{table}"
    );
}

#[test]
fn docs_modbus_md_names_every_fault_by_its_code() {
    let page = include_str!("../../docs/modbus.md");
    // Rows `| code | `name` | what |` of the fault table.
    let rows: Vec<(u16, &str)> = page
        .lines()
        .filter_map(|line| {
            let mut cells = line.strip_prefix('|')?.split('|').map(str::trim);
            let code = cells.next()?.parse().ok()?;
            let name = cells.next()?.strip_prefix('`')?.strip_suffix('`')?;
            Some((code, name))
        })
        .collect();
    let mut expected = vec![(0, "none")];
    expected.extend(Fault::ALL.iter().map(|fault| (fault.code(), fault.name())));
    assert_eq!(rows, expected);
}

#[test]
fn docs_modbus_md_numbers_the_loop_stages_in_their_order() {
    let page = include_str!("../../docs/modbus.md");
    let words = page.split_whitespace().collect::<Vec<_>>().join(" ");
    let stages: Vec<String> = Stage::ALL
        .iter()
        .enumerate()
        .map(|(index, stage)| format!("{} {}", index + 1, stage.name()))
        .collect();
    let sentence = format!(
        "`loop_stage`: 0 no closed loop, then {}.",
        stages.join(", ")
    );
    assert!(
        words.contains(&sentence),
        "docs/modbus.md lacks {sentence:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// Reads.

#[test]
fn at_power_up_the_holding_registers_read_the_default_settings() {
    let mut slave = Slave::new();
    let registers = slave.holding(0, 9);
    // Eq. 5: a_max = x_max / (T(1 − d)/2)² at 50 Hz, d = 0.586 and a 2.5 mm stroke.
    let accel_mps2 = 2.5e-3 / (0.02 * (1.0 - 0.586) / 2.0_f64).powi(2);
    assert!((145.8..145.9).contains(&accel_mps2), "{accel_mps2}");
    assert_eq!(
        [
            registers[0],
            registers[1],
            registers[2],
            registers[3],
            registers[4],
            registers[5],
            registers[7],
            registers[8]
        ],
        [
            0,     // run: stopped
            65535, // recipe: none loaded
            5860,  // duty 0.586
            5000,  // 50.00 Hz
            2500,  // 2.500 mm
            1459,  // 145.9 m/s²
            25,    // ramp cycles
            0,     // acknowledge reads 0
        ],
        "{registers:?}"
    );
    // The feed register is the console's `get feed` (mm/s, three decimals) to 0.1 mm/s.
    let reply = run(
        &mut controller(),
        "get feed",
        &stopped(),
        &mut Memory::erased(),
    )
    .reply;
    let feed_mmps: f64 = reply
        .as_str()
        .strip_prefix("OK feed_mmps=")
        .unwrap_or_else(|| panic!("{reply}"))
        .parse()
        .unwrap();
    assert!(feed_mmps > 0.0, "{reply}");
    assert!(
        (f64::from(registers[6]) / 10.0 - feed_mmps).abs() <= 0.05 + 0.0005,
        "feed register {} against {reply}",
        registers[6]
    );
}

#[test]
fn reads_may_start_anywhere_in_the_map() {
    let mut slave = Slave::new();
    assert_eq!(slave.holding(2, 2), [5860, 5000]);
    assert_eq!(slave.holding(7, 1), [25]);
}

#[test]
fn run_reads_1_while_the_feeder_runs() {
    let mut slave = Slave::new();
    let (response, _) = slave.ask(&read_holding(0, 1), &running());
    assert_eq!(registers(&response, 3), [1]);
}

#[test]
fn the_input_registers_report_the_feeder() {
    let mut slave = Slave::new();
    let at = Snapshot {
        uptime_ms: 70_000_999,
        ..snapshot(RunState::Running, Phase::Running, 0x0003_1234)
    };
    let registers = slave.input(0, 16, &at);
    assert_eq!(registers[0], 1, "state: running");
    assert_eq!(registers[1], 0, "no fault");
    assert_eq!(registers[2], 0, "no refusal");
    assert_eq!(registers[3], 65535, "no refused register");
    assert_eq!(registers[4..6], [0x0003, 0x1234], "cycles, high word first");
    assert_eq!(registers[6], 2, "phase: running");
    assert_eq!(registers[7], 0, "no closed loop");
    assert_eq!(
        registers[8..13],
        [0, 0, 0, 0, 0],
        "no drive identified, no track"
    );
    // 70 000 s = 1 · 65536 + 4464.
    assert_eq!(
        registers[14..16],
        [1, 4464],
        "uptime in seconds, high word first"
    );
}

#[test]
fn the_input_registers_name_a_latched_fault_by_its_code() {
    let mut slave = Slave::new();
    for fault in Fault::ALL {
        let at = snapshot(RunState::Faulted(fault), Phase::Stopped, 0);
        assert_eq!(slave.input(0, 2, &at), [3, fault.code()], "{fault}");
    }
    let stopping = snapshot(RunState::Stopping, Phase::Stopping, 0);
    assert_eq!(slave.input(0, 2, &stopping), [2, 0]);
    assert_eq!(slave.input(6, 1, &stopping), [3], "phase: stopping");
    assert_eq!(slave.input(0, 2, &stopped()), [0, 0]);
}

#[test]
fn the_input_registers_report_the_closed_loop_and_the_track() {
    let mut slave = Slave::new();
    let drive = Identified {
        gain_positive: 0.8123,
        gain_negative: 1.25,
        offset_mps2: -1.5,
        lag_s: 0.0012,
        coulomb_mps2: 3.0,
        viscous_per_s: 4.0,
        spring_per_s2: 5.0,
        residual_m: 1e-6,
    };
    for (index, stage) in Stage::ALL.into_iter().enumerate() {
        let at = Snapshot {
            closed_loop: Some(LoopReport {
                stage,
                drive: Some(drive),
                feed: None,
                failure: None,
            }),
            track: Some(TrackReport {
                state: TrackState::Empty,
                parts_per_minute: 12.34,
            }),
            ..running()
        };
        let registers = slave.input(7, 6, &at);
        assert_eq!(registers[0], index as u16 + 1, "{stage:?}, 1 and up");
        // 0.8123 and 1.25 in 0.0001; -1.500 m/s² in 0.001, two's complement; 1200 µs;
        // 12.3 parts per minute in 0.1.
        assert_eq!(
            registers[1..],
            [8123, 12_500, (-1500_i16) as u16, 1200, 123],
            "{stage:?}"
        );
    }
    // A loop that has not identified the drive yet reads 0 for it.
    let at = Snapshot {
        closed_loop: Some(LoopReport {
            stage: Stage::Probing,
            drive: None,
            feed: None,
            failure: None,
        }),
        ..running()
    };
    assert_eq!(slave.input(7, 6, &at), [3, 0, 0, 0, 0, 0]);
}

#[test]
fn reading_an_input_register_beyond_the_map_is_exception_02() {
    let mut slave = Slave::new();
    let (response, exchange) = slave.ask(&read_input(99, 1), &stopped());
    assert_eq!(response, exception(4, 0x02));
    assert!(exchange.heard);
    // A read that runs past the last register is refused as a whole.
    let (response, _) = slave.ask(&read_input(14, 3), &stopped());
    assert_eq!(response, exception(4, 0x02));
    let (response, _) = slave.ask(&read_holding(8, 2), &stopped());
    assert_eq!(response, exception(3, 0x02));
}

#[test]
fn reading_no_register_or_more_than_125_is_exception_03() {
    let mut slave = Slave::new();
    let (response, _) = slave.ask(&read_holding(0, 0), &stopped());
    assert_eq!(response, exception(3, 0x03));
    let (response, _) = slave.ask(&read_input(0, 126), &stopped());
    assert_eq!(response, exception(4, 0x03));
}

// ---------------------------------------------------------------------------------------------
// Writes: the console's commands.

#[test]
fn a_single_write_is_the_console_set_and_echoes_the_request() {
    let mut slave = Slave::new();
    let request = write_single(2, 6000);
    let (response, exchange) = slave.ask(&request, &running());
    assert_eq!(response, request, "function code 6 echoes the request");
    assert!(exchange.heard && !exchange.broken);
    assert!(exchange.requests.is_empty());

    let mut console = controller();
    let outcome = run(
        &mut console,
        "set duty 0.6",
        &running(),
        &mut Memory::erased(),
    );
    assert_eq!(outcome.refusal, None);
    assert_eq!(slave.controller.settings(), console.settings());
    assert_eq!(slave.controller.settings().duty, 0.6);
    assert_eq!(exchange.configure, Some(outcome.action));
    assert_eq!(slave.holding(2, 1), [6000]);
}

#[test]
fn a_refused_write_is_exception_03_with_the_console_code_in_the_input_registers() {
    let mut slave = Slave::new();
    let (response, exchange) = slave.ask(&write_single(2, 9000), &running());
    assert_eq!(response[..3], [ADDRESS, 0x86, 0x03]);
    assert_eq!(response, exception(6, 0x03));
    assert_eq!(exchange.configure, None);
    assert_eq!(slave.controller.settings(), &Settings::DEFAULT);

    let code = console_code("set duty 0.9", &running()).expect("the console refuses it too");
    assert!((40..=58).contains(&code), "a validation code: {code}");
    assert_eq!(slave.refusal(), [code, 2]);
    assert_eq!(slave.server.link().refusal, Some((code, 2)));

    // An accepted write clears it.
    slave.ask(&write_single(2, 6000), &running());
    assert_eq!(slave.refusal(), [0, 65535]);
}

#[test]
fn a_write_of_several_registers_is_all_or_nothing() {
    let mut slave = Slave::new();
    // duty 0.9 (refused), then freq 55 Hz (accepted alone): the frequency does not change.
    let (response, exchange) = slave.ask(&write_multiple(2, &[9000, 5500]), &running());
    assert_eq!(response, exception(16, 0x03), "the duty refused");
    assert_eq!(exchange.configure, None);
    assert_eq!(slave.controller.settings(), &Settings::DEFAULT);
    assert_eq!(slave.refusal()[1], 2);

    // duty 0.586 and freq 55 Hz (accepted), then a 9 mm stroke (refused): nothing changes.
    let (response, exchange) = slave.ask(&write_multiple(2, &[5860, 5500, 9000]), &running());
    assert_eq!(response, exception(16, 0x03));
    assert_eq!(exchange.configure, None);
    assert_eq!(slave.controller.settings(), &Settings::DEFAULT);
    let mut console = controller();
    let mut store = Memory::erased();
    assert_eq!(
        run(&mut console, "set freq 55", &running(), &mut store).refusal,
        None
    );
    let refusal = run(&mut console, "set stroke 9", &running(), &mut store).refusal;
    let code = refusal.expect("the console refuses it too").code();
    assert_eq!(
        slave.refusal(),
        [code, 4],
        "the stroke, at register 4, refused"
    );

    // The same after a frequency of its own: the refused write leaves it.
    let mut slave = Slave::new();
    let (response, _) = slave.ask(&write_multiple(3, &[5500]), &running());
    assert_eq!(response, frame(&[ADDRESS, 16, 0, 3, 0, 1]));
    let before = *slave.controller.settings();
    assert_eq!(before.frequency_hz, 55.0);
    let (response, _) = slave.ask(&write_multiple(2, &[9000, 5000]), &running());
    assert_eq!(response, exception(16, 0x03));
    assert_eq!(slave.controller.settings(), &before);
}

#[test]
fn an_accepted_write_of_several_registers_is_the_console_lines_in_order() {
    let mut slave = Slave::new();
    // duty 0.55, freq 62.5 Hz, stroke 2 mm, at registers 2, 3 and 4.
    let (response, exchange) = slave.ask(&write_multiple(2, &[5500, 6250, 2000]), &running());
    assert_eq!(response, frame(&[ADDRESS, 16, 0, 2, 0, 3]));
    let mut console = controller();
    let mut store = Memory::erased();
    let mut last = None;
    for line in ["set duty 0.55", "set freq 62.5", "set stroke 2"] {
        let outcome = run(&mut console, line, &running(), &mut store);
        assert_eq!(outcome.refusal, None, "{line}");
        last = Some(outcome.action);
    }
    assert_eq!(slave.controller.settings(), console.settings());
    assert_eq!(
        exchange.configure, last,
        "the waveform the last register leaves"
    );
    assert_eq!(slave.holding(2, 3), [5500, 6250, 2000]);
}

#[test]
fn a_write_beyond_the_map_is_exception_02() {
    let mut slave = Slave::new();
    let (response, _) = slave.ask(&write_single(40, 1), &running());
    assert_eq!(response, exception(6, 0x02));
    assert_eq!(slave.refusal()[1], 40);
    // A write that runs past the last register changes nothing.
    let (response, _) = slave.ask(&write_multiple(7, &[10, 1, 5]), &running());
    assert_eq!(response, exception(16, 0x02));
    assert_eq!(slave.controller.settings(), &Settings::DEFAULT);
    assert_eq!(slave.refusal()[1], 9);
}

#[test]
fn run_1_starts_and_run_0_stops() {
    let mut slave = Slave::new();
    let request = write_single(0, 1);
    let (response, exchange) = slave.ask(&request, &stopped());
    assert_eq!(response, request);
    assert_eq!(exchange.requests, [SupervisorEvent::StartRequested]);
    assert!(exchange.started());
    assert_eq!(exchange.configure, None);

    let (response, exchange) = slave.ask(&write_single(0, 0), &running());
    assert_eq!(response, write_single(0, 0));
    assert_eq!(exchange.requests, [SupervisorEvent::StopRequested]);
    assert!(!exchange.started());

    let (response, exchange) = slave.ask(&write_single(0, 2), &running());
    assert_eq!(response, exception(6, 0x03));
    assert!(exchange.requests.is_empty());
}

#[test]
fn a_start_in_a_refused_write_does_not_start() {
    let mut slave = Slave::new();
    let (response, exchange) = slave.ask(&write_multiple(0, &[1, 65535, 6200]), &stopped());
    // The recipe register refuses 65535, so nothing happens at all.
    assert_eq!(response, exception(16, 0x03));
    assert!(exchange.requests.is_empty());
    assert_eq!(slave.refusal()[1], 1);

    let mut slave = Slave::new();
    let (response, exchange) = slave.ask(&write_multiple(2, &[6200]), &stopped());
    assert!(crc_holds(&response) && response[1] == 16);
    assert!(exchange.requests.is_empty());
    let (_, exchange) = slave.ask(&write_multiple(0, &[1]), &stopped());
    assert_eq!(exchange.requests, [SupervisorEvent::StartRequested]);
}

#[test]
fn a_start_while_a_fault_is_latched_is_exception_04_with_code_61() {
    let mut slave = Slave::new();
    let (response, exchange) = slave.ask(&write_single(0, 1), &faulted());
    assert_eq!(response, exception(6, 0x04));
    assert!(exchange.requests.is_empty());
    assert_eq!(console_code("start", &faulted()), Some(61));
    assert_eq!(slave.refusal(), [61, 0]);

    // Acknowledging it is the console's `reset`, and a start may follow at once.
    let (response, exchange) = slave.ask(&write_single(8, 1), &faulted());
    assert_eq!(response, write_single(8, 1));
    assert_eq!(exchange.requests, [SupervisorEvent::ResetRequested]);
    let (response, exchange) = slave.ask(&write_single(0, 1), &faulted());
    assert_eq!(response, write_single(0, 1));
    assert_eq!(exchange.requests, [SupervisorEvent::StartRequested]);
}

#[test]
fn the_recipe_register_loads_a_recipe_as_the_console_does() {
    let mut slave = Slave::new();
    // An empty slot: the console's ERR 63, exception 04.
    let (response, _) = slave.ask(&write_single(1, 3), &stopped());
    assert_eq!(response, exception(6, 0x04));
    assert_eq!(console_code("recipe load 3", &stopped()), Some(63));
    assert_eq!(slave.refusal(), [63, 1]);
    // Slot 8 does not exist.
    let (response, _) = slave.ask(&write_single(1, 8), &stopped());
    assert_eq!(response, exception(6, 0x03));

    // A recipe saved at the console, loaded over the link.
    let mut console = controller();
    let lines = [
        "set stroke 2",
        "set freq 62.5",
        "set duty 0.6",
        "recipe save 3",
        "set duty 0.58",
    ];
    for line in lines {
        let outcome = run(&mut console, line, &stopped(), &mut slave.store);
        assert_eq!(outcome.refusal, None, "{line}");
    }
    let (response, exchange) = slave.ask(&write_single(1, 3), &stopped());
    assert_eq!(response, write_single(1, 3));
    assert!(exchange.configure.is_some());
    assert_eq!(slave.holding(1, 4), [3, 6000, 6250, 2000]);
    assert_eq!(slave.controller.recipe(), RecipeSlot::new(3));
    // A change since makes it no recipe's settings.
    slave.ask(&write_single(7, 30), &stopped());
    assert_eq!(slave.holding(1, 1), [65535]);
}

// ---------------------------------------------------------------------------------------------
// Frames that get no answer, and functions the slave does not have.

#[test]
fn a_frame_with_a_bad_crc_gets_no_answer() {
    let mut slave = Slave::new();
    let mut request = write_single(2, 6000);
    request[7] ^= 0x01;
    let (response, exchange) = slave.ask(&request, &running());
    assert!(response.is_empty(), "{response:02x?}");
    assert!(exchange.broken);
    assert!(!exchange.heard);
    assert_eq!(slave.controller.settings(), &Settings::DEFAULT);

    let mut request = read_holding(0, 9);
    request[3] ^= 0x40;
    let (response, exchange) = slave.ask(&request, &running());
    assert!(response.is_empty() && exchange.broken);
    assert_eq!(slave.server.answered(), 0);
}

#[test]
fn a_frame_for_another_slave_gets_no_answer() {
    let mut slave = Slave::new();
    let (response, exchange) = slave.ask(&write_single_to(ADDRESS + 1, 2, 6000), &running());
    assert!(response.is_empty());
    assert!(!exchange.heard && !exchange.broken);
    assert_eq!(slave.controller.settings(), &Settings::DEFAULT);
    let (response, exchange) = slave.ask(&read_request(ADDRESS + 1, 3, 0, 1), &running());
    assert!(response.is_empty() && !exchange.heard);
}

#[test]
fn a_broadcast_write_is_applied_without_an_answer() {
    let mut slave = Slave::new();
    let (response, exchange) = slave.ask(&write_single_to(0, 2, 6000), &running());
    assert!(response.is_empty(), "{response:02x?}");
    assert!(exchange.heard && !exchange.broken);
    assert_eq!(slave.controller.settings().duty, 0.6);
    assert_eq!(slave.server.answered(), 0);

    let (response, exchange) = slave.ask(&write_single_to(0, 0, 1), &stopped());
    assert!(response.is_empty());
    assert_eq!(exchange.requests, [SupervisorEvent::StartRequested]);
}

#[test]
fn an_unsupported_function_is_exception_01() {
    let mut slave = Slave::new();
    // 0x2B, encapsulated interface transport (read device identification).
    let request = frame(&[ADDRESS, 0x2B, 0x0E, 0x01, 0x00]);
    let (response, exchange) = slave.ask(&request, &stopped());
    assert_eq!(response, exception(0x2B, 0x01));
    assert!(exchange.heard);
    // Coils and discrete inputs: the slave has none.
    for function in [1, 2] {
        let (response, _) = slave.ask(&read_request(ADDRESS, function, 0, 1), &stopped());
        assert_eq!(response, exception(function, 0x01), "function {function}");
    }
    let (response, _) = slave.ask(&frame(&[ADDRESS, 5, 0, 0, 0xFF, 0]), &stopped());
    assert_eq!(response, exception(5, 0x01), "write single coil");
}

#[test]
fn an_unsupported_function_with_a_bad_crc_gets_no_answer() {
    let mut slave = Slave::new();
    let mut request = frame(&[ADDRESS, 0x2B, 0x0E, 0x01, 0x00]);
    let last = request.len() - 1;
    request[last] ^= 0xFF;
    let (response, exchange) = slave.ask(&request, &stopped());
    assert!(response.is_empty(), "{response:02x?}");
    assert!(exchange.broken);
}

#[test]
fn a_function_code_with_the_exception_bit_gets_no_answer() {
    // Codes from 0x80 are exception responses, never requests: no exception to them exists.
    let mut slave = Slave::new();
    for function in [0x80, 0x83, 0xAB, 0xFF] {
        let (response, exchange) = slave.ask(&frame(&[ADDRESS, function, 0, 0, 0, 1]), &stopped());
        assert!(response.is_empty(), "{function:#x}: {response:02x?}");
        assert!(exchange.broken, "{function:#x}");
    }
}

#[test]
fn every_answer_is_counted() {
    let mut slave = Slave::new();
    slave.ask(&read_holding(0, 1), &stopped());
    slave.ask(&read_input(99, 1), &stopped());
    slave.ask(&write_single_to(0, 2, 6000), &stopped());
    slave.ask(&write_single_to(3, 2, 6000), &stopped());
    assert_eq!(slave.server.answered(), 2);
}

// ---------------------------------------------------------------------------------------------
// The console and the link agree on every value.

/// The scaled holding registers: address, counts per unit and the console's `set` word, written
/// here independently of the map.
const SCALED: [(u16, f64, &str); 6] = [
    (2, 10_000.0, "duty"),
    (3, 100.0, "freq"),
    (4, 1_000.0, "stroke"),
    (5, 10.0, "accel"),
    (6, 10.0, "feed"),
    (7, 1.0, "ramp"),
];

/// Where the agreement starts: the defaults, held acceleration, another frequency.
const START: [&str; 4] = ["help", "set accel 120", "set freq 55", "set duty 0.55"];

proptest! {
    #[test]
    fn a_write_and_the_console_line_agree(
        register in 0..SCALED.len(),
        value in prop_oneof![any::<u16>(), 0u16..10_000],
        start in prop::sample::select(START.to_vec()),
        state in prop::sample::select(vec![stopped(), running()]),
    ) {
        let (address, scale, word) = SCALED[register];
        let line = format!("set {word} {}", f64::from(value) / scale);
        let mut store = Memory::erased();

        let mut console = controller();
        prop_assert_eq!(run(&mut console, start, &state, &mut store).refusal, None);
        let mut slave = Slave { controller: console.clone(), ..Slave::new() };
        let typed = run(&mut console, &line, &state, &mut store);
        let (response, exchange) = slave.ask(&write_single(address, value), &state);

        match typed.refusal {
            None => {
                prop_assert_eq!(&response, &write_single(address, value), "{}", line);
                prop_assert_eq!(exchange.configure, Some(typed.action));
                prop_assert_eq!(slave.refusal(), [0, 65535]);
            }
            Some(error) => {
                prop_assert_eq!(&response, &exception(6, 0x03), "{} {}", line, typed.reply);
                prop_assert_eq!(exchange.configure, None);
                prop_assert_eq!(slave.refusal(), [error.code(), address]);
            }
        }
        prop_assert_eq!(slave.controller.settings(), console.settings(), "{}", line);
    }
}

// ---------------------------------------------------------------------------------------------
// Frame assembly.

#[test]
fn the_frame_gap_is_3_5_characters_and_1750_us_above_19200_baud() {
    // 3.5 characters of 11 bits, rounded up: 38.5 / 9600 s = 4010.4 µs.
    assert_eq!(frame_gap_us(9600), 4011);
    assert_eq!(frame_gap_us(19_200), 2006);
    assert_eq!(frame_gap_us(1200), 32_084);
    for baud in [19_201, 38_400, 57_600, 115_200] {
        assert_eq!(frame_gap_us(baud), 1750, "{baud}");
    }
}

/// Pushes `bytes` from `start_us` on, `step_us` apart: the frames completed.
fn push_all(
    assembler: &mut FrameAssembler,
    bytes: &[u8],
    start_us: u64,
    step_us: u64,
) -> Vec<Vec<u8>> {
    let mut frames = Vec::new();
    for (index, &byte) in bytes.iter().enumerate() {
        if let Some(frame) = assembler.push(byte, start_us + index as u64 * step_us) {
            frames.push(frame.to_vec());
        }
    }
    frames
}

#[test]
fn a_frame_split_across_pushes_is_completed_at_its_last_byte() {
    let gap_us = frame_gap_us(9600);
    let mut assembler = FrameAssembler::new(gap_us);
    assert_eq!(assembler.gap_us(), gap_us);
    let request = write_multiple(2, &[6200, 6000, 2000]);
    let (head, tail) = request.split_at(5);
    assert!(push_all(&mut assembler, head, 0, 1_146).is_empty());
    // Less than the gap since the last byte: still the same frame.
    let frames = push_all(&mut assembler, tail, 4 * 1_146 + gap_us, 1_146);
    assert_eq!(frames, [request]);
    assert_eq!(assembler.dropped(), 0);
}

#[test]
fn frames_back_to_back_are_told_apart_by_their_lengths() {
    let mut assembler = FrameAssembler::new(frame_gap_us(115_200));
    let mut bytes = read_holding(0, 9);
    bytes.extend(write_multiple(2, &[6200]));
    bytes.extend(write_single(0, 1));
    let frames = push_all(&mut assembler, &bytes, 1_000, 100);
    assert_eq!(
        frames,
        [
            read_holding(0, 9),
            write_multiple(2, &[6200]),
            write_single(0, 1)
        ]
    );
}

#[test]
fn a_silence_longer_than_the_gap_drops_a_partial_frame() {
    let gap_us = frame_gap_us(9600);
    let mut assembler = FrameAssembler::new(gap_us);
    let request = read_holding(0, 9);
    assert!(push_all(&mut assembler, &request[..5], 0, 1_000).is_empty());
    // The next byte comes after more than the gap: the five are dropped, the frame starts anew.
    let frames = push_all(&mut assembler, &request, 4_000 + gap_us + 1, 1_000);
    assert_eq!(frames, std::slice::from_ref(&request));
    assert_eq!(assembler.dropped(), 1);

    // The same, told by `silence` when a receive times out.
    assert!(push_all(&mut assembler, &request[..3], 100_000, 1_000).is_empty());
    assembler.silence(102_000 + gap_us / 2);
    assert_eq!(assembler.dropped(), 1, "not silent long enough yet");
    assembler.silence(102_000 + gap_us + 1);
    assert_eq!(assembler.dropped(), 2);
    let frames = push_all(&mut assembler, &request, 102_001 + gap_us, 1_000);
    assert_eq!(frames, [request]);
    // A silence with nothing received drops nothing.
    assembler.silence(10_000_000);
    assert_eq!(assembler.dropped(), 2);
}

#[test]
fn a_request_of_a_function_without_a_length_ends_at_a_silence() {
    let gap_us = frame_gap_us(19_200);
    let mut assembler = FrameAssembler::new(gap_us);
    // Read device identification (7 bytes) and report server ID (4 bytes): no length rule.
    for request in [
        frame(&[ADDRESS, 0x2B, 0x0E, 0x01, 0x00]),
        frame(&[ADDRESS, 0x11]),
    ] {
        assert!(push_all(&mut assembler, &request, 0, 500).is_empty());
        let last_us = (request.len() as u64 - 1) * 500;
        assert_eq!(
            assembler.silence(last_us + gap_us / 2),
            None,
            "not quiet yet"
        );
        let framed = assembler.silence(last_us + gap_us + 1).map(<[u8]>::to_vec);
        assert_eq!(framed, Some(request.clone()));
        let mut slave = Slave::new();
        let function = request[1];
        let (response, _) = slave.ask(&request, &stopped());
        assert_eq!(response, exception(function, 0x01));
    }
    // Its bytes with a broken CRC are dropped at the silence.
    let mut broken = frame(&[ADDRESS, 0x2B, 0x0E, 0x01, 0x00]);
    broken[6] ^= 1;
    assert!(push_all(&mut assembler, &broken, 0, 500).is_empty());
    let dropped = assembler.dropped();
    assert_eq!(assembler.silence(3_000 + gap_us + 1), None);
    assert_eq!(assembler.dropped(), dropped + 1);
}

#[test]
fn after_a_discard_bytes_are_ignored_until_a_silence() {
    let gap_us = frame_gap_us(19_200);
    let mut assembler = FrameAssembler::new(gap_us);
    let request = read_holding(0, 2);
    assert_eq!(
        push_all(&mut assembler, &request, 0, 500),
        std::slice::from_ref(&request)
    );
    assembler.discard();
    assert_eq!(assembler.dropped(), 1);
    // Whole frames right after it belong to the discarded one.
    assert!(push_all(&mut assembler, &request, 4_000, 500).is_empty());
    assert!(push_all(&mut assembler, &request, 8_000, 500).is_empty());
    // After a silence the next frame is read from its first byte.
    let frames = push_all(&mut assembler, &request, 11_500 + gap_us + 1, 500);
    assert_eq!(frames, [request]);
    assert_eq!(assembler.dropped(), 1);
}

#[test]
fn a_frame_longer_than_the_longest_is_dropped_and_its_rest_ignored() {
    let gap_us = frame_gap_us(38_400);
    let mut assembler = FrameAssembler::new(gap_us);
    // A write of 125 registers says 250 data bytes: 259 bytes, more than an RTU frame holds.
    let mut bytes = vec![ADDRESS, 16, 0, 0, 0, 125, 250];
    bytes.extend(std::iter::repeat_n(0u8, 252));
    assert!(push_all(&mut assembler, &bytes, 0, 200).is_empty());
    assert_eq!(assembler.dropped(), 1);
    let request = read_holding(0, 1);
    let frames = push_all(&mut assembler, &request, 259 * 200 + gap_us, 200);
    assert_eq!(frames, [request]);
}

// ---------------------------------------------------------------------------------------------
// Any bytes on the line.

/// Input for the link: noise, or whole frames (valid CRC) of any function to any address.
fn chunk() -> impl Strategy<Value = Vec<u8>> {
    let address = prop_oneof![Just(ADDRESS), Just(0u8), any::<u8>()];
    let function = prop_oneof![
        prop::sample::select(vec![1u8, 2, 3, 4, 5, 6, 15, 16, 0x2B]),
        any::<u8>()
    ];
    // The four bytes after the function code of every request but 15 and 16, or any number.
    let rest = prop_oneof![
        prop::collection::vec(any::<u8>(), 4),
        prop::collection::vec(any::<u8>(), 0..260),
    ];
    let body = (address, function, rest).prop_map(|(address, function, mut rest)| {
        if function == 16 && rest.len() >= 5 {
            // A plausible byte count, sometimes.
            rest[4] = rest[4].min((rest.len() - 5) as u8);
        }
        let mut body = vec![address, function];
        body.extend(rest);
        frame(&body)
    });
    let write = (2u16..9, prop::collection::vec(any::<u16>(), 1..8))
        .prop_map(|(first, values)| write_multiple(first, &values));
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..300),
        body,
        write,
        (0u16..20, any::<u16>()).prop_map(|(register, value)| write_single(register, value)),
        (3u8..5, 0u16..20, 0u16..130)
            .prop_map(|(function, first, count)| read_request(ADDRESS, function, first, count)),
    ]
}

proptest! {
    #[test]
    fn any_bytes_get_well_formed_answers_or_none(
        chunks in prop::collection::vec((chunk(), 0u64..10_000, 0u64..3_000), 0..12),
        state in prop::sample::select(vec![stopped(), running(), faulted()]),
    ) {
        let mut assembler = FrameAssembler::new(frame_gap_us(9600));
        let mut slave = Slave::new();
        let mut now_us = 0;
        for (bytes, silence_us, spacing_us) in chunks {
            now_us += silence_us;
            for byte in bytes {
                now_us += spacing_us;
                let Some(request) = assembler.push(byte, now_us).map(<[u8]>::to_vec) else {
                    continue;
                };
                let (response, exchange) = slave.ask(&request, &state);
                if exchange.broken {
                    assembler.discard();
                }
                if response.is_empty() {
                    continue;
                }
                prop_assert!(response.len() <= 256);
                prop_assert!(crc_holds(&response), "{:02x?}", response);
                prop_assert_eq!(response[0], ADDRESS);
                prop_assert_eq!(request[0], ADDRESS, "only this slave's requests are answered");
                prop_assert!(exchange.heard && !exchange.broken);
                let function = response[1];
                prop_assert!(function == request[1] || function == request[1] | 0x80);
                if function & 0x80 != 0 {
                    prop_assert_eq!(response.len(), 5);
                    prop_assert!((1..=4).contains(&response[2]), "{:02x?}", response);
                }
            }
        }
        prop_assert_eq!(run(&mut slave.controller, "status", &state, &mut slave.store).refusal, None);
    }
}
