//! `feeder-twin ELF [--cycles N]`: runs a G474 image without a console on the twin as an
//! operator with the user button runs it (start, `N` motion cycles, soft stop) and writes its
//! decoded log to standard output, for `host-sim hil`; a summary goes to standard error.
//!
//! Every segment the firmware reports is checked on the twin's output (the DAC, or TIM1's PWM
//! and direction): its level on its tick.
//! Exit code 0 when the run went through and the DAC agreed, 1 when it did not (a watchdog
//! reset, a start that never came, a level the DAC did not take), 2 when the twin could not run
//! the image.

use std::io::{self, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use feeder_twin::log::LogTable;
use feeder_twin::outputs::OutputRecord;
use feeder_twin::scenario::button_run;
use feeder_twin::{Machine, CORE_HZ};

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
    let record = OutputRecord::default();
    let mut machine = match Machine::load(&elf, Box::new(record.clone())) {
        Ok(machine) => machine,
        Err(error) => return failure(&error.to_string()),
    };
    let started = std::time::Instant::now();
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let outcome = button_run(&mut machine, table.decoder(), &mut out, cycles, &record);
    let _ = out.flush();
    let core_s = machine.now() as f64 / CORE_HZ as f64;
    let wall_s = started.elapsed().as_secs_f64();
    eprintln!(
        "feeder-twin: {} instructions, {core_s:.3} s of core time in {wall_s:.2} s ({:.1} core seconds a second)",
        machine.instructions(),
        core_s / wall_s
    );
    let (work, edges) = machine.edge_work();
    let wait_states = u64::from(machine.board().flash_wait_states());
    if edges > 0 {
        eprintln!(
            "feeder-twin: the worst of {edges} edges took {} instructions ({} bytes, {} reads \
             from flash) to the next preload: at most {} cycles at {wait_states} wait states \
             with no cache hit",
            work.instructions,
            work.code_bytes,
            work.flash_reads,
            work.cycles_without_cache(wait_states)
        );
    }
    if let Ok(outcome) = &outcome {
        let check = &outcome.outputs;
        eprintln!(
            "feeder-twin: the output took {} segments' levels on their ticks, {} did not, {} \
             levels at no segment's start",
            check.matched,
            check.problems.len(),
            check.stray
        );
        for problem in check.problems.iter().take(5) {
            eprintln!("  {problem}");
        }
    }
    match outcome {
        Ok(outcome)
            if outcome.completed
                && outcome.outputs.problems.is_empty()
                && outcome.outputs.stray == 0 =>
        {
            ExitCode::SUCCESS
        }
        Ok(outcome) if outcome.completed => ExitCode::from(1),
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
