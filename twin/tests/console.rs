//! The G474's console image (`FEEDER_G474_CONSOLE_ELF`, built with `hil-trace` and `console`
//! by `cargo xtask test`) on the twin: its console on LPUART1 at 115200 baud answers the
//! operator's commands, byte by byte at the line's own rate, as the protocol says.

use std::path::PathBuf;

use feeder_twin::outputs::OutputRecord;
use feeder_twin::{Machine, Stop, CORE_HZ};

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
