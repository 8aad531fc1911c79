//! Arbitrary bytes on the Modbus line: through the frame assembler (each byte's arrival time
//! drawn from the input, around the frame gap) into the slave with a controller, in a feeder
//! state drawn from the first byte. Nothing panics, a frame that is no frame is discarded, and
//! every response is this slave's, at most 256 bytes, answers the request's function (or is its
//! exception, code 01 to 04) and carries a valid CRC; the controller's settings stay valid.
#![no_main]

use feeder_shared::modbus::{frame_gap_us, FrameAssembler, Response, Server, MAX_FRAME_BYTES};
use feeder_shared::testing::{machine, MemoryStore};
use feeder_shared::{Controller, Fault, Phase, RunState, Settings, Snapshot};
use libfuzzer_sys::fuzz_target;

/// The slave's address.
const ADDRESS: u8 = 17;


/// CRC-16/MODBUS, bitwise: independent of the codec the slave uses.
fn crc16(bytes: &[u8]) -> u16 {
    let mut crc = 0xFFFF_u16;
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
    crc
}

/// The feeder's state, from one byte.
fn snapshot(byte: u8) -> Snapshot {
    let (state, phase) = match byte % 4 {
        0 => (RunState::Stopped, Phase::Stopped),
        1 => (RunState::Running, Phase::Running),
        2 => (RunState::Stopping, Phase::Stopping),
        _ => (
            RunState::Faulted(Fault::ALL[usize::from(byte / 4) % Fault::ALL.len()]),
            Phase::Stopped,
        ),
    };
    Snapshot {
        state,
        phase,
        uptime_ms: u64::from(byte) << 30,
        cycles: u64::from(byte) << 24,
        closed_loop: None,
        track: None,
    }
}

fuzz_target!(|input: &[u8]| {
    let Some((&state, bytes)) = input.split_first() else {
        return;
    };
    let at = snapshot(state);
    let machine = machine();
    let mut controller = Controller::new(machine, Settings::DEFAULT).expect("defaults are valid");
    let mut store = MemoryStore::erased();
    let mut server = Server::new(ADDRESS);
    let gap_us = frame_gap_us(9600);
    let mut assembler = FrameAssembler::new(gap_us);
    let mut response = Response::new();
    let mut now_us = 0_u64;
    // Each byte on the line with the time since the one before: 0 to 5100 µs, around the gap.
    for pair in bytes.chunks_exact(2) {
        let (byte, delay) = (pair[0], pair[1]);
        now_us += u64::from(delay) * 20;
        let Some(frame) = assembler.push(byte, now_us) else {
            continue;
        };
        let mut buffer = [0_u8; MAX_FRAME_BYTES];
        let len = frame.len();
        buffer[..len].copy_from_slice(frame);
        let request = &buffer[..len];
        let exchange = server.handle(request, &mut controller, &at, &mut store, &mut response);
        if exchange.broken {
            assembler.discard();
        }
        assert!(
            controller.settings().validate(&machine).is_ok(),
            "{:?}",
            controller.settings()
        );
        if response.is_empty() {
            continue;
        }
        assert!(response.len() <= MAX_FRAME_BYTES);
        let (body, crc) = response.split_at(response.len() - 2);
        assert_eq!(crc16(body).to_le_bytes(), crc, "{response:02x?}");
        assert_eq!(response[0], ADDRESS);
        assert_eq!(
            request[0], ADDRESS,
            "only this slave's requests are answered"
        );
        assert!(exchange.heard && !exchange.broken);
        let function = response[1];
        assert!(function == request[1] || function == request[1] | 0x80);
        if function & 0x80 != 0 {
            assert_eq!(response.len(), 5, "{response:02x?}");
            assert!((1..=4).contains(&response[2]), "{response:02x?}");
        }
    }
});
