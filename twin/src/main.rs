//! `feeder-twin ELF [SECONDS]`: runs the G474 image on the twin with nothing on its outputs and
//! writes its defmt log (raw frames) to standard output.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use feeder_twin::{Cycles, Machine, Plate, CORE_HZ};

struct Bench;

impl Plate for Bench {
    fn level(&mut self, _at: Cycles, _code: u32) {}
    fn enable(&mut self, _at: Cycles, _on: bool) {}
    fn count(&mut self, _at: Cycles) -> i32 {
        0
    }
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let Some(elf) = args.next().map(PathBuf::from) else {
        eprintln!("usage: feeder-twin ELF [SECONDS]");
        return ExitCode::from(2);
    };
    let seconds: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let mut machine = match Machine::load(&elf, Box::new(Bench)) {
        Ok(machine) => machine,
        Err(error) => {
            eprintln!("feeder-twin: {error}");
            return ExitCode::from(2);
        }
    };
    let started = std::time::Instant::now();
    let at = |s: f64| (s * CORE_HZ as f64) as Cycles;
    let mut result = machine.run_until(at(0.05));
    machine.button(true);
    if result.is_ok() {
        result = machine.run_until(at(0.1));
    }
    machine.button(false);
    if result.is_ok() {
        result = machine.run_until(at(seconds));
    }
    let log = machine.take_log();
    let _ = std::io::stdout().write_all(&log);
    eprintln!(
        "feeder-twin: {:?} at pc 0x{:08x} ({}) after {} instructions, {:.6} s of core time, {:.2} s wall",
        result,
        machine.pc(),
        machine.function(machine.pc()),
        machine.instructions(),
        machine.now() as f64 / CORE_HZ as f64,
        started.elapsed().as_secs_f64()
    );
    match result {
        Ok(_) => ExitCode::SUCCESS,
        Err(_) => ExitCode::from(1),
    }
}
