//! `feeder-twin ELF [--cycles N] [--plant FILE [--log FILE]]`: runs a G474 image without a
//! console on the twin as an operator with the user button runs it (start, `N` motion cycles,
//! soft stop) and writes its decoded log to standard output, for `host-sim hil`; a summary goes
//! to standard error.
//!
//! With `--plant`, the plant file's plate is on the outputs and counts into the encoder (the
//! image built with `--features encoder` closes its loop on it): the decoded log goes to the
//! `--log` file instead, and standard output gets the closed loop's verdict, judged as
//! `host-sim cosim` judges QEMU's run.
//!
//! Every segment the firmware reports is checked on the twin's output (the DAC, or TIM1's PWM
//! and direction): its level on its tick.
//! Exit code 0 when the run went through, the DAC agreed and (with `--plant`) the closed loop
//! passed, 1 when not (a watchdog reset, a start that never came, a level the DAC did not take,
//! a failed verdict), 2 when the twin could not run the image.

use std::io::{self, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use feeder_twin::log::LogTable;
use feeder_twin::outputs::{Levels, OutputRecord};
use feeder_twin::plant::{judge, PlantRun};
use feeder_twin::scenario::button_run;
use feeder_twin::{Machine, Plate, CORE_HZ};

/// The command line.
struct Args {
    elf: PathBuf,
    cycles: u64,
    plant: Option<PathBuf>,
    log: Option<PathBuf>,
}

/// The arguments after the program's name, or what is wrong with them.
fn parse(args: &[String]) -> Result<Args, String> {
    let (elf, mut rest) = match args.split_first() {
        Some((elf, rest)) if !elf.starts_with("--") => (PathBuf::from(elf), rest),
        _ => return Err("the ELF comes first".into()),
    };
    let mut parsed = Args {
        elf,
        cycles: 200,
        plant: None,
        log: None,
    };
    while let [flag, value, more @ ..] = rest {
        match flag.as_str() {
            "--cycles" => {
                parsed.cycles = value
                    .parse::<u64>()
                    .ok()
                    .filter(|n| *n >= 1)
                    .ok_or(format!(
                        "--cycles takes a whole number from 1, not {value:?}"
                    ))?
            }
            "--plant" => parsed.plant = Some(PathBuf::from(value)),
            "--log" => parsed.log = Some(PathBuf::from(value)),
            _ => return Err(format!("no flag {flag}")),
        }
        rest = more;
    }
    if let [flag] = rest {
        return Err(format!("{flag} takes a value"));
    }
    if parsed.log.is_some() && parsed.plant.is_none() {
        return Err("--log goes with --plant (without it the log goes to standard output)".into());
    }
    Ok(parsed)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Args {
        elf,
        cycles,
        plant,
        log: log_path,
    } = match parse(&args) {
        Ok(args) => args,
        Err(problem) => return usage(&problem),
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
    let plant = match plant.as_deref().map(PlantRun::new).transpose() {
        Ok(plant) => plant,
        Err(error) => return failure(&error),
    };
    let outputs: Box<dyn Plate> = match &plant {
        Some(plant) => Box::new(plant.outputs(record.clone())),
        None => Box::new(record.clone()),
    };
    let mut machine = match Machine::load(&elf, outputs) {
        Ok(machine) => machine,
        Err(error) => return failure(&error.to_string()),
    };
    let started = std::time::Instant::now();
    let mut kept = Vec::new();
    let stdout = io::stdout();
    let outcome = match plant {
        Some(_) => {
            let levels = Levels::Trimmed;
            button_run(
                &mut machine,
                table.decoder(),
                &mut kept,
                cycles,
                &record,
                levels,
            )
        }
        None => {
            let levels = Levels::Planned;
            button_run(
                &mut machine,
                table.decoder(),
                &mut stdout.lock(),
                cycles,
                &record,
                levels,
            )
        }
    };
    let _ = stdout.lock().flush();
    let core_s = machine.now() as f64 / CORE_HZ as f64;
    let wall_s = started.elapsed().as_secs_f64();
    eprintln!(
        "feeder-twin: {} instructions, {core_s:.3} s of core time in {wall_s:.2} s ({:.1} core seconds a second)",
        machine.instructions(),
        core_s / wall_s
    );
    if let Some((used, size)) = machine.stack_use() {
        eprintln!(
            "feeder-twin: the stack reached {used} of its {size} bytes ({} left)",
            i64::from(size) - i64::from(used)
        );
    }
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
    let mut passed = true;
    if let Some(plant) = &plant {
        let log = String::from_utf8_lossy(&kept);
        if let Some(path) = &log_path {
            if let Err(error) = std::fs::write(path, log.as_bytes()) {
                return failure(&format!("cannot write {}: {error}", path.display()));
            }
        }
        let origin = machine.board().output_origin().unwrap_or(0);
        match judge(&log, plant, origin) {
            Ok(report) => {
                passed = report.passed;
                println!("{}", report.text);
            }
            Err(error) => return failure(&error),
        }
    }
    match outcome {
        Ok(outcome)
            if outcome.completed
                && outcome.outputs.problems.is_empty()
                && outcome.outputs.stray == 0
                && passed =>
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
    eprintln!(
        "feeder-twin: {problem}\nusage: feeder-twin ELF [--cycles N] [--plant FILE [--log FILE]]"
    );
    ExitCode::from(2)
}

fn failure(problem: &str) -> ExitCode {
    eprintln!("feeder-twin: {problem}");
    ExitCode::from(2)
}
