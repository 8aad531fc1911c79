//! The G474's console image (`FEEDER_G474_CONSOLE_ELF`, built with `hil-trace` and `console`
//! by `cargo xtask test`) on the twin: its console on LPUART1 at 115200 baud answers the
//! operator's commands, byte by byte at the line's own rate, as the protocol says; its Modbus
//! RTU port on USART1 (19200 baud 8E1, the configuration's defaults) answers a master's requests
//! with the driver enable (PA12) up exactly while it answers; and the discrete lines run the
//! feeder: the release input (PC0) starts it and stops it softly, the ready output (PC6) high
//! and the fault output (PC8) low throughout.

use std::path::PathBuf;

use feeder_twin::outputs::OutputRecord;
use feeder_twin::peripherals::Output;
use feeder_twin::{Cycles, Machine, Stop, CORE_HZ};

fn console_image() -> PathBuf {
    std::env::var_os("FEEDER_G474_CONSOLE_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_CONSOLE_ELF names the console image (cargo xtask test sets it)")
}

/// Sends `line` and runs until a whole reply line has come back (at most 1 s): the reply
/// without its line end.
fn command(machine: &mut Machine, line: &str) -> String {
    machine.serial_send(format!("{line}\r\n").as_bytes());
    let mut reply = Vec::new();
    let limit = machine.now() + CORE_HZ;
    while !reply.ends_with(b"\n") && machine.now() < limit {
        let step = machine.now() + CORE_HZ / 1000;
        let stop = machine.run_until(step).expect("runs");
        assert_eq!(
            stop,
            Stop::Ended,
            "the board reset while it answered {line:?}"
        );
        reply.extend(machine.serial_take());
    }
    String::from_utf8(reply)
        .expect("a text reply")
        .trim_end()
        .to_string()
}

#[test]
#[ignore = "needs the G474 console image; run by cargo xtask test"]
fn the_console_answers_on_lpuart1() {
    let mut machine =
        Machine::load(&console_image(), Box::new(OutputRecord::default())).expect("loads");
    machine
        .run_until(CORE_HZ / 20)
        .expect("runs 50 ms from reset");
    let status = command(&mut machine, "status");
    assert!(status.starts_with("OK state=stopped"), "{status:?}");
    let set = command(&mut machine, "set duty 0.6");
    assert!(set.starts_with("OK freq_hz=50 duty=0.6 "), "{set:?}");
    let got = command(&mut machine, "get duty");
    assert!(got.starts_with("OK") && got.contains("duty=0.6"), "{got:?}");
    let refused = command(&mut machine, "set duty 2");
    assert!(refused.starts_with("ERR 4"), "{refused:?}");
    let unknown = command(&mut machine, "bogus");
    assert!(unknown.starts_with("ERR 20 "), "{unknown:?}");
}

/// The GPIO ports by index, as the machine numbers them.
const PORT_A: usize = 0;
const PORT_C: usize = 2;

/// Core cycles of one 8E1 character (11 bits) at 19200 baud: BRR = 170 MHz / 19200 = 8854.
const CHARACTER: Cycles = 11 * 8_854;

/// CRC-16/MODBUS (reflected polynomial 0xA001, initial 0xFFFF), as a frame carries it: low
/// byte first.
fn crc16(bytes: &[u8]) -> [u8; 2] {
    let mut crc: u16 = 0xFFFF;
    for &byte in bytes {
        crc ^= u16::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xA001
            } else {
                crc >> 1
            };
        }
    }
    crc.to_le_bytes()
}

/// `pdu` for slave 1, the board's address by default, as an RTU frame, its CRC appended.
fn frame(pdu: &[u8]) -> Vec<u8> {
    frame_to(1, pdu)
}

/// `pdu` for slave `unit` as an RTU frame, its CRC appended.
fn frame_to(unit: u8, pdu: &[u8]) -> Vec<u8> {
    let mut frame = vec![unit];
    frame.extend_from_slice(pdu);
    let crc = crc16(&frame);
    frame.extend_from_slice(&crc);
    frame
}

/// What the master sees of an exchange: the answer's bytes, each with the time its last stop bit
/// ended, and the driver enable (PA12) sampled from the request on.
struct Exchange {
    /// When the request's last stop bit ended (its bytes go out back to back from the send).
    request_end: Cycles,
    answer: Vec<(Cycles, u8)>,
    driver_enable: Vec<(Cycles, bool)>,
}

/// Sends `request` on the RS-485 port and runs until `answer_len` bytes have come back and the
/// line has been quiet for two characters after them (at most 200 ms), sampling DE every 50 µs.
fn modbus(machine: &mut Machine, request: &[u8], answer_len: usize) -> Exchange {
    machine.rs485_send(request);
    let mut exchange = Exchange {
        request_end: machine.now() + request.len() as Cycles * CHARACTER,
        answer: Vec::new(),
        driver_enable: Vec::new(),
    };
    let limit = machine.now() + CORE_HZ / 5;
    let mut quiet_from = None;
    while machine.now() < limit && quiet_from.is_none_or(|at| machine.now() < at) {
        let step = machine.now() + CORE_HZ / 20_000;
        let stop = machine.run_until(step).expect("runs");
        assert_eq!(stop, Stop::Ended, "the board reset while it answered");
        exchange
            .driver_enable
            .push((machine.now(), machine.pin(PORT_A, 12)));
        exchange.answer.extend(machine.rs485_take());
        if exchange.answer.len() >= answer_len && quiet_from.is_none() {
            quiet_from = Some(machine.now() + 2 * CHARACTER);
        }
    }
    exchange
}

impl Exchange {
    fn bytes(&self) -> Vec<u8> {
        self.answer.iter().map(|&(_, byte)| byte).collect()
    }

    /// The driver enable is up while the answer's characters go out, from the first start bit
    /// to the last stop bit, and down before and after.
    fn assert_driver_enable_frames_the_answer(&self) {
        let (Some(&(first_end, _)), Some(&(last_end, _))) =
            (self.answer.first(), self.answer.last())
        else {
            panic!("no answer");
        };
        let first_start = first_end - CHARACTER;
        for &(at, up) in &self.driver_enable {
            let sending = (first_start..last_end).contains(&at);
            assert_eq!(
                up,
                sending,
                "DE {} at {at} (the answer from {first_start} to {last_end})",
                if up { "up" } else { "down" }
            );
        }
        assert!(
            self.driver_enable.iter().any(|&(_, up)| up),
            "DE never seen up"
        );
        // The serial line's frame gap, 3.5 characters, before the answer's first start bit.
        let silence = first_start - self.request_end;
        assert!(
            2 * silence >= 7 * CHARACTER,
            "the answer began {silence} cycles after the request, within 3.5 characters"
        );
    }
}

fn assert_crc(frame: &[u8]) {
    let (body, crc) = frame.split_at(frame.len() - 2);
    assert_eq!(crc, crc16(body), "the answer's CRC: {frame:02x?}");
}

#[test]
#[ignore = "needs the G474 console image; run by cargo xtask test"]
fn the_modbus_port_answers_on_usart1_with_its_driver_enable() {
    let mut machine =
        Machine::load(&console_image(), Box::new(OutputRecord::default())).expect("loads");
    machine
        .run_until(CORE_HZ / 20)
        .expect("runs 50 ms from reset");
    // USART1: 19200 baud from 170 MHz, 8E1 (M0: a 9-bit word with PCE, even), the driver
    // enable in hardware (CR3 DEM); PC4, PC5 and PA12 on AF7.
    assert_eq!(machine.register(0x4001_380C), Some(8_854), "USART1 BRR");
    let cr1 = machine.register(0x4001_3800).expect("USART1 CR1");
    assert_eq!(
        cr1 & (1 << 12 | 1 << 10 | 1 << 9),
        1 << 12 | 1 << 10,
        "CR1 {cr1:#x}"
    );
    assert_eq!(cr1 & 0xD, 0xD, "UE, TE and RE: CR1 {cr1:#x}");
    let cr2 = machine.register(0x4001_3804).expect("USART1 CR2");
    assert_eq!((cr2 >> 12) & 3, 0, "one stop bit: CR2 {cr2:#x}");
    let cr3 = machine.register(0x4001_3808).expect("USART1 CR3");
    assert_eq!(
        cr3 & (1 << 14 | 1 << 15),
        1 << 14,
        "DEM, DE active high: CR3 {cr3:#x}"
    );
    let gpioc_moder = machine.register(0x4800_0800).expect("GPIOC MODER");
    let gpioc_afrl = machine.register(0x4800_0820).expect("GPIOC AFRL");
    for pin in [4, 5] {
        assert_eq!((gpioc_moder >> (2 * pin)) & 3, 2, "PC{pin} alternate");
        assert_eq!((gpioc_afrl >> (4 * pin)) & 0xF, 7, "PC{pin} AF7");
    }
    // RX pulled up: the transceiver's receiver output floats while it drives the bus.
    let gpioc_pupdr = machine.register(0x4800_080C).expect("GPIOC PUPDR");
    assert_eq!(
        (gpioc_pupdr >> 10) & 3,
        1,
        "PC5 pulled up: {gpioc_pupdr:#x}"
    );
    let gpioa_moder = machine.register(0x4800_0000).expect("GPIOA MODER");
    let gpioa_afrh = machine.register(0x4800_0024).expect("GPIOA AFRH");
    assert_eq!((gpioa_moder >> 24) & 3, 2, "PA12 alternate");
    assert_eq!((gpioa_afrh >> 16) & 0xF, 7, "PA12 AF7");
    assert!(!machine.pin(PORT_A, 12), "DE down while the port listens");
    // USART1's interrupt (37) enabled at LPUART1's (91) priority 3, below the edge (0), the
    // control executor (1) and the EXTI lines (2).
    let priority = |irq: u32| {
        machine
            .register(0xE000_E400 + (irq & !3))
            .map(|word| (word >> (8 * (irq & 3))) & 0xFF)
    };
    let enabled = machine.register(0xE000_E104).expect("NVIC ISER1");
    assert_ne!(enabled & (1 << (37 - 32)), 0, "USART1's interrupt enabled");
    assert_eq!(priority(37), Some(0x30), "USART1's priority");
    assert_eq!(priority(91), Some(0x30), "LPUART1's priority");

    // Read holding registers 0–8 (all nine): `duty` at 2 is the compiled 0.586.
    let read = modbus(&mut machine, &frame(&[3, 0, 0, 0, 9]), 5 + 2 * 9);
    let answer = read.bytes();
    assert_eq!(answer.len(), 5 + 2 * 9, "{answer:02x?}");
    assert_eq!(answer[..3], [1, 3, 18], "{answer:02x?}");
    assert_crc(&answer);
    let duty = u16::from_be_bytes([answer[3 + 4], answer[3 + 5]]);
    assert_eq!(duty, 5_860, "{answer:02x?}");
    read.assert_driver_enable_frames_the_answer();

    // Write `duty` = 6000: the answer echoes the request, and the console sees 0.6.
    let request = frame(&[6, 0, 2, 0x17, 0x70]);
    let write = modbus(&mut machine, &request, request.len());
    assert_eq!(write.bytes(), request);
    write.assert_driver_enable_frames_the_answer();
    let got = command(&mut machine, "get duty");
    assert!(got.starts_with("OK") && got.contains("duty=0.6"), "{got:?}");

    // A register that does not exist: exception 02.
    let refused = modbus(&mut machine, &frame(&[6, 0, 9, 0, 1]), 5);
    let answer = refused.bytes();
    assert_eq!(answer[..3], [1, 0x86, 2], "{answer:02x?}");
    assert_crc(&answer);
    // Another slave's request: no answer, DE stays down.
    let ignored = modbus(&mut machine, &frame_to(2, &[3, 0, 0, 0, 1]), 1);
    assert!(ignored.answer.is_empty(), "{:02x?}", ignored.bytes());
    assert!(ignored.driver_enable.iter().all(|&(_, up)| !up));
    // The first three bytes of a request, then nothing: after a frame gap of silence they are
    // dropped, and the next request is read from its first byte.
    let cut = modbus(&mut machine, &frame(&[3, 0, 0, 0, 1])[..3], 1);
    assert!(cut.answer.is_empty(), "{:02x?}", cut.bytes());
    let next = modbus(&mut machine, &frame(&[3, 0, 2, 0, 1]), 7);
    assert_eq!(next.bytes(), frame(&[3, 2, 0x17, 0x70]), "duty, 6000");
    // A function the slave does not serve, of a length it cannot know (report server ID, 4
    // bytes): ended by the silence after it, answered with exception 01.
    let unknown = modbus(&mut machine, &frame(&[0x11]), 5);
    assert_eq!(unknown.bytes(), frame(&[0x91, 1]));
    unknown.assert_driver_enable_frames_the_answer();
}

/// Runs `machine` for `seconds` in 1 ms steps, checking at each the ready output (PC6) high and
/// the fault output (PC8) low.
fn run_ready(machine: &mut Machine, seconds: f64) {
    let until = machine.now() + (seconds * CORE_HZ as f64) as Cycles;
    while machine.now() < until {
        let step = machine.now() + CORE_HZ / 1000;
        assert_eq!(machine.run_until(step).expect("runs"), Stop::Ended);
        assert!(
            machine.pin(PORT_C, 6),
            "ready (PC6) low at {}",
            machine.now()
        );
        assert!(
            !machine.pin(PORT_C, 8),
            "fault (PC8) high at {}",
            machine.now()
        );
    }
}

/// The driver enable's changes (PA10) the output record holds, from `from` on.
fn enable_changes(record: &OutputRecord, from: Cycles) -> Vec<(Cycles, bool)> {
    record
        .changes()
        .into_iter()
        .filter_map(|change| match change {
            Output::Enable { at, on } if at >= from => Some((at, on)),
            _ => None,
        })
        .collect()
}

#[test]
#[ignore = "needs the G474 console image; run by cargo xtask test"]
fn the_release_line_starts_the_feeder_and_stops_it_softly() {
    let record = OutputRecord::default();
    let mut machine = Machine::load(&console_image(), Box::new(record.clone())).expect("loads");
    machine
        .run_until(CORE_HZ / 20)
        .expect("runs 50 ms from reset");
    // The lines: PC0, PC2, PC3 inputs pulled down; PC6 and PC8 push-pull outputs.
    let moder = machine.register(0x4800_0800).expect("GPIOC MODER");
    let pupdr = machine.register(0x4800_080C).expect("GPIOC PUPDR");
    let otyper = machine.register(0x4800_0804).expect("GPIOC OTYPER");
    for pin in [0, 2, 3] {
        assert_eq!((moder >> (2 * pin)) & 3, 0, "PC{pin} an input: {moder:#x}");
        assert_eq!(
            (pupdr >> (2 * pin)) & 3,
            2,
            "PC{pin} pulled down: {pupdr:#x}"
        );
    }
    for pin in [6, 8] {
        assert_eq!((moder >> (2 * pin)) & 3, 1, "PC{pin} an output: {moder:#x}");
        assert_eq!(otyper & (1 << pin), 0, "PC{pin} push-pull");
    }
    run_ready(&mut machine, 0.05);
    assert!(enable_changes(&record, 0).iter().all(|&(_, on)| !on));

    // Release on: past the 20 ms debounce the feeder starts (recipe select 00 keeps the
    // settings), the driver enabled at the next period's boundary.
    let released = machine.now();
    machine.drive_pin(PORT_C, 0, Some(true));
    run_ready(&mut machine, 0.2);
    let on = enable_changes(&record, released);
    assert!(
        matches!(on[..], [(_, true)]),
        "the driver enabled once after the release: {on:?}"
    );
    let status = command(&mut machine, "status");
    assert!(
        status.starts_with("OK state=starting") || status.starts_with("OK state=running"),
        "{status:?}"
    );
    run_ready(&mut machine, 0.5);
    let status = command(&mut machine, "status");
    assert!(status.starts_with("OK state=running"), "{status:?}");

    // Release off: a soft stop, its 25-cycle ramp (0.5 s at 50 Hz) before the driver is off.
    let dropped = machine.now();
    machine.drive_pin(PORT_C, 0, Some(false));
    run_ready(&mut machine, 0.1);
    let status = command(&mut machine, "status");
    assert!(status.starts_with("OK state=stopping"), "{status:?}");
    assert!(
        enable_changes(&record, dropped).is_empty(),
        "off before the ramp"
    );
    run_ready(&mut machine, 0.6);
    let off = enable_changes(&record, dropped);
    let [(off_at, false)] = off[..] else {
        panic!("the driver disabled once after the ramp: {off:?}");
    };
    let ramp_s = (off_at - dropped) as f64 / CORE_HZ as f64;
    assert!((0.45..0.65).contains(&ramp_s), "disabled {ramp_s} s after");
    let status = command(&mut machine, "status");
    assert!(status.starts_with("OK state=stopped"), "{status:?}");
}
