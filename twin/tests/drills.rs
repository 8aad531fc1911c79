//! Fault drills on the G474's own image on the twin, judged on the twin's pins and registers:
//! after the fault the driver enable (PA10) must go low and stay low, and the command must go to
//! the zero code (or the DAC off, by a reset) and stay there, within the time the firmware
//! documents. A dead edge counter must be caught by the power-up self-test before anything
//! runs. A panic and an NMI take the safe state's stores at once; masked interrupts, a hang and
//! a lockup leave the feeds off, and the independent watchdog resets the board; a stack overflow
//! reaches the HardFault entry's stores (without a stack) or the reset, whichever comes first.
//!
//! `FEEDER_G474_DRILLS` names a directory with an image per drill (`panic.elf`, …, built with
//! `FEEDER_FAULT_DRILL`), `FEEDER_G474_ELF` the image without one (for the NMI); `cargo xtask
//! test` builds and sets both.

use std::path::{Path, PathBuf};

use feeder_twin::log::LogTable;
use feeder_twin::outputs::OutputRecord;
use feeder_twin::peripherals::Output;
use feeder_twin::scenario::{drill_run, Drill, DrillOutcome};
use feeder_twin::{Cycles, Machine, CORE_HZ};

/// The safe state's stores, made by the panic handler and the HardFault entry before anything
/// else: within this of the fault, s (the panic's own machinery and log line come first).
const STORES_S: f64 = 100e-6;
/// The independent watchdog's timeout as `firmware/src/board/g474/watchdog.rs` documents it, at
/// most 1.09 ms with the slowest LSI (the twin's runs at its nominal 32 kHz).
const WATCHDOG_S: f64 = 1.09e-3;

fn drill(elf: &Path, kind: Drill) -> (DrillOutcome, String) {
    let bytes = std::fs::read(elf).unwrap_or_else(|error| panic!("{}: {error}", elf.display()));
    let table = LogTable::load(&bytes).expect("the image's defmt table");
    let record = OutputRecord::default();
    let mut machine = Machine::load(elf, Box::new(record.clone())).expect("loads");
    let mut log = Vec::new();
    let outcome = drill_run(&mut machine, table.decoder(), &mut log, &record, kind)
        .expect("runs")
        .expect("the fault came");
    (outcome, String::from_utf8_lossy(&log).into_owned())
}

fn drills_dir() -> PathBuf {
    std::env::var_os("FEEDER_G474_DRILLS")
        .map(PathBuf::from)
        .expect("FEEDER_G474_DRILLS names the drill images' directory (cargo xtask test sets it)")
}

fn after(outcome: &DrillOutcome, at: Option<Cycles>) -> f64 {
    let at = at.expect("the output became safe");
    (at - outcome.fault_at) as f64 / CORE_HZ as f64
}

fn assert_safe_within(name: &str, outcome: &DrillOutcome, bound_s: f64, log: &str) {
    let enable_s = after(outcome, outcome.enable_off_at);
    let command_s = after(outcome, outcome.command_safe_at);
    assert!(
        enable_s <= bound_s && command_s <= bound_s,
        "{name}: the enable off {:.1} µs and the command safe {:.1} µs after the fault, over \
         {:.1} µs\n{log}",
        enable_s * 1e6,
        command_s * 1e6,
        bound_s * 1e6
    );
}

#[test]
#[ignore = "needs the G474 drill images; run by cargo xtask test"]
fn a_panic_makes_the_output_safe_at_once_and_the_watchdog_resets_the_board() {
    let (outcome, log) = drill(&drills_dir().join("panic.elf"), Drill::Firmware);
    assert_safe_within("panic", &outcome, STORES_S, &log);
    assert!(outcome.watchdog_reset.is_some(), "{log}");
    assert!(log.contains("panic in exception"), "{log}");
}

#[test]
#[ignore = "needs the G474 image; run by cargo xtask test"]
fn an_nmi_takes_the_hardfault_entry_and_its_stores() {
    let elf = std::env::var_os("FEEDER_G474_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_ELF names the G474 image");
    let (outcome, log) = drill(&elf, Drill::Nmi);
    assert_safe_within("NMI", &outcome, 1e-6, &log);
    assert!(
        log.contains("NMI in thread mode") || log.contains("NMI in handler mode"),
        "{log}"
    );
}

#[test]
#[ignore = "needs the G474 drill images; run by cargo xtask test"]
fn a_stack_overflow_masked_interrupts_a_hang_and_a_lockup_end_safe_by_the_watchdog() {
    for name in ["stack-overflow", "critical-section", "hang", "lockup"] {
        let (outcome, log) = drill(&drills_dir().join(format!("{name}.elf")), Drill::Firmware);
        assert_safe_within(name, &outcome, WATCHDOG_S, &log);
        let reset = outcome
            .watchdog_reset
            .expect("the watchdog reset the board");
        // A stack overflow reaches the HardFault entry's stores when the recursion crosses the
        // bottom of RAM before the watchdog's reset (on the twin, 16 µs before it); the others
        // are made safe by the reset itself.
        let enable_off = outcome.enable_off_at.expect("the driver went off");
        match name {
            "stack-overflow" => assert!(enable_off <= reset, "{name}: safe by the reset at latest"),
            _ => assert_eq!(enable_off, reset, "{name}: safe by the reset"),
        }
        // 7 to 8 counts of 125 µs after the last feed: a feed reloads the count, not the
        // prescaler's phase.
        let feed = outcome.last_feed.expect("the watchdog was fed before");
        let since_feed_s = (reset - feed) as f64 / CORE_HZ as f64;
        assert!(
            (0.875e-3..=1.0e-3).contains(&since_feed_s),
            "{name}: the reset {:.1} µs after the last feed",
            since_feed_s * 1e6
        );
        assert!(
            log.contains("fault latched: WatchdogReset"),
            "{name}: the board came up faulted\n{log}"
        );
    }
}

/// An edge counter that does not count: the power-up self-test catches it, the fault latches
/// before anything runs, and neither the button nor anything else starts the output.
#[test]
#[ignore = "needs the G474 image; run by cargo xtask test"]
fn a_dead_edge_counter_is_caught_at_power_up_and_nothing_starts() {
    let elf = std::env::var_os("FEEDER_G474_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_ELF names the G474 image");
    let bytes = std::fs::read(&elf).expect("the image");
    let table = LogTable::load(&bytes).expect("its defmt table");
    let record = OutputRecord::default();
    let mut machine = Machine::load(&elf, Box::new(record.clone())).expect("loads");
    machine.kill_edge_counter();
    let mut decoder = table.decoder();
    let at = |s: f64| (s * CORE_HZ as f64) as Cycles;
    machine.run_until(at(0.01)).expect("runs");
    // Two presses: the first would acknowledge a fault that can be, the second start.
    for press_s in [0.01, 0.2] {
        machine.run_until(at(press_s)).expect("runs");
        machine.button(true);
        machine.run_until(at(press_s + 0.1)).expect("runs");
        machine.button(false);
    }
    machine.run_until(at(0.6)).expect("runs");
    let log = decoder.lines(&machine.take_log()).join("\n");
    assert!(log.contains("self-test: the edge counter"), "{log}");
    assert!(log.contains("fault latched: EdgeCounter"), "{log}");
    assert!(!log.contains("Stopped -> Running"), "{log}");
    for change in record.changes() {
        match change {
            Output::Enable { on, .. } => assert!(!on, "the driver was enabled\n{log}"),
            Output::Dac { code, .. } => assert_eq!(code, 2048, "a level\n{log}"),
            _ => {}
        }
    }
}

/// The encoder's sampling DMA stopped by a transfer error (the twin breaks DMA1 channel 1 once
/// the closed loop runs): the firmware must notice the channel off rather than hand the
/// buffer's last counts on as new, and the closed loop must stop with the driver off.
#[test]
#[ignore = "needs the G474 encoder image; run by cargo xtask test"]
fn a_dma_transfer_error_on_the_encoders_channel_stops_the_closed_loop() {
    let elf = std::env::var_os("FEEDER_G474_ENCODER_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_ENCODER_ELF names the encoder image");
    let bytes = std::fs::read(&elf).expect("the image");
    let table = LogTable::load(&bytes).expect("its defmt table");
    let record = OutputRecord::default();
    let mut machine = Machine::load(&elf, Box::new(record.clone())).expect("loads");
    let mut decoder = table.decoder();
    let at = |s: f64| (s * CORE_HZ as f64) as Cycles;
    machine.run_until(at(0.01)).expect("runs");
    machine.button(true);
    machine.run_until(at(0.11)).expect("runs");
    machine.button(false);
    machine.run_until(at(0.115)).expect("runs");
    let broken_at = machine.now();
    machine.break_dma_channel(0);
    machine.run_until(at(0.6)).expect("runs");
    let log = decoder.lines(&machine.take_log()).join("\n");
    assert!(log.contains("encoder: the sampling DMA stopped"), "{log}");
    assert!(log.contains("closed loop"), "{log}");
    // After the break the driver ends disabled and the command at its zero code.
    let changes = record.changes();
    let last_enable = changes.iter().rev().find_map(|change| match change {
        Output::Enable { at, on } if *at >= broken_at => Some(*on),
        _ => None,
    });
    assert_eq!(last_enable, Some(false), "the driver ends disabled\n{log}");
    let zero = changes.iter().find_map(|change| match change {
        Output::Dac { code, .. } => Some(*code),
        _ => None,
    });
    let last_code = changes.iter().rev().find_map(|change| match change {
        Output::Dac { code, .. } => Some(*code),
        _ => None,
    });
    assert_eq!(last_code, zero, "the command ends at the zero code\n{log}");
}

/// The HardFault entry's stores, as the twin's bus sees them on an NMI while the feeder runs:
/// the DAC stage's `SAFE_STATE_WRITES` (`firmware/src/board/g474/dac.rs`) before anything else,
/// in their order: PA10 low through BSRR, the zero code into DHR12R1, TIM2's forced update (its
/// TRGO latches the code), TIM2 stopped with ARPE and URS kept, its interrupt off.
#[test]
#[ignore = "needs the G474 image; run by cargo xtask test"]
fn the_hardfault_entrys_stores_are_the_safe_state_in_order() {
    let elf = std::env::var_os("FEEDER_G474_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_ELF names the G474 image");
    let mut machine = Machine::load(&elf, Box::new(OutputRecord::default())).expect("loads");
    let at = |s: f64| (s * CORE_HZ as f64) as Cycles;
    machine.run_until(at(0.01)).expect("runs");
    machine.button(true);
    machine.run_until(at(0.11)).expect("runs");
    machine.button(false);
    machine.run_until(at(1.0)).expect("runs");
    machine.trace_writes();
    machine.nmi();
    machine.run_until(at(1.0001)).expect("runs");
    let expected = [
        (0x4800_0018, 1 << 26),
        (0x5000_0808, 2048),
        (0x4000_0014, 1),
        (0x4000_0000, 1 << 7 | 1 << 2),
        (0x4000_000C, 0),
    ];
    let writes = machine.traced_writes();
    assert!(writes.len() >= expected.len(), "{writes:x?}");
    assert_eq!(&writes[..expected.len()], &expected, "{writes:x?}");
}
