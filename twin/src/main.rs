//! `feeder-twin ELF [--cycles N]`: runs a G474 image without a console on the twin as an
//! operator with the user button runs it (start, `N` motion cycles, soft stop) and writes its
//! decoded log to standard output, for `host-sim hil`; a summary goes to standard error.
//!
//! Exit code 0 when the run went through, 1 when it did not (a watchdog reset, a start that
//! never came), 2 when the twin could not run the image.

use std::io::{self, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use feeder_twin::log::LogTable;
use feeder_twin::scenario::button_run;
use feeder_twin::{Cycles, Machine, Plate, CORE_HZ};

/// Nothing on the outputs: the analog command and the enable go nowhere, the encoder reads 0.
struct Bench;

impl Plate for Bench {
    fn level(&mut self, _at: Cycles, _code: u32) {}
    fn enable(&mut self, _at: Cycles, _on: bool) {}
    fn count(&mut self, _at: Cycles) -> i32 {
        0
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (elf, cycles) = match args.as_slice() {
        [elf] => (PathBuf::from(elf), 200),
        [elf, flag, n] if flag == "--cycles" => match n.parse::<u64>() {
            Ok(n) if n >= 1 => (PathBuf::from(elf), n),
            _ => return usage(&format!("--cycles takes a whole number from 1, not {n:?}")),
        },
        _ => return usage("one ELF, then optionally --cycles N"),
    };
    let bytes = match std::fs::read(&elf) {
        Ok(bytes) => bytes,
        Err(error) => return failure(&format!("cannot read {}: {error}", elf.display())),
    };
    let table = match LogTable::load(&bytes) {
        Ok(table) => table,
        Err(error) => return failure(&error.to_string()),
    };
    let mut machine = match Machine::load(&elf, Box::new(Bench)) {
        Ok(machine) => machine,
        Err(error) => return failure(&error.to_string()),
    };
    let started = std::time::Instant::now();
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let outcome = button_run(&mut machine, table.decoder(), &mut out, cycles);
    let _ = out.flush();
    let core_s = machine.now() as f64 / CORE_HZ as f64;
    let wall_s = started.elapsed().as_secs_f64();
    eprintln!(
        "feeder-twin: {} instructions, {core_s:.3} s of core time in {wall_s:.2} s ({:.1} core seconds a second)",
        machine.instructions(),
        core_s / wall_s
    );
    match outcome {
        Ok(outcome) if outcome.completed => ExitCode::SUCCESS,
        Ok(outcome) => {
            match outcome.watchdog_reset {
                Some(at) => eprintln!(
                    "feeder-twin: the watchdog reset the board at {:.6} s",
                    at as f64 / CORE_HZ as f64
                ),
                None => eprintln!("feeder-twin: the feeder never started"),
            }
            ExitCode::from(1)
        }
        Err(error) => failure(&error.to_string()),
    }
}

fn usage(problem: &str) -> ExitCode {
    eprintln!("feeder-twin: {problem}\nusage: feeder-twin ELF [--cycles N]");
    ExitCode::from(2)
}

fn failure(problem: &str) -> ExitCode {
    eprintln!("feeder-twin: {problem}");
    ExitCode::from(2)
}
