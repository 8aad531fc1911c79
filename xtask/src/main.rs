//! `cargo xtask <command>`: the project's two main entry points (`run`, `test`) and the tasks
//! around them, one module each; this file holds the command line and the dispatch.
//!
//! * `run`  — the main job: the firmware under QEMU drives the simulated plate and part.
//! * `test` — the whole test suite: host tests, the `no_std` crate and the firmware for
//!   `thumbv7em-none-eabihf`, the firmware size budget, and the firmware-in-the-loop scenarios
//!   under QEMU.
//! * `size` — the firmware's flash and static RAM use against the budget.
//! * `console` — live control: the QEMU console image at the `feeder-ctl` prompt, then
//!   `host-sim hil` on what happened.
//! * `soak` — only the random-operator soak against the QEMU console image, at any length.
//! * `bless` — makes the expected outputs the tests compare with anew (`tests/expected/`, the
//!   command-line snapshots) and says which changed.
//!
//! Each command installs what it needs (the thumb target, flip-link, qemu-system-arm,
//! defmt-print; see `tools`) so it works on a fresh machine; [`command`] runs what they run.

mod bless;
mod command;
mod console;
mod failure;
mod progress;
mod qemu;
mod run;
mod size;
mod soak;
mod test;
mod tools;
mod twin;

use std::io;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use command::{exec_output, host_sim};
use run::RunArgs;
use soak::SoakArgs;

#[derive(Parser)]
#[command(
    name = "cargo xtask",
    bin_name = "cargo xtask",
    about = "The feeder's main job, its test suite, live control and the firmware size report",
    allow_negative_numbers = true
)]
struct Cli {
    #[command(subcommand)]
    task: Task,
}

#[derive(Subcommand)]
enum Task {
    /// The main job: the prediction at the paper's operating point, then the firmware under
    /// QEMU driving the simulated part, checked edge by edge by `host-sim hil`.
    Run(RunArgs),
    /// The whole test suite: host tests, the thumb builds, size budgets, QEMU scenarios.
    Test,
    /// Flash and static RAM of both board images against their budgets.
    Size,
    /// Live control: the QEMU console image with the `feeder-ctl` prompt on this terminal and
    /// its decoded log in target/console-run.log; on leaving the prompt (`quit`, `exit`,
    /// Ctrl-D), `host-sim hil` checks the run. With --plant, the closed loop on that plate.
    Console(console::ConsoleArgs),
    /// The random-operator soak against the QEMU console image alone (also part of `test`).
    Soak(SoakArgs),
    /// The closed loop on the seeded plant family across its envelope (`host-sim family`:
    /// 500 plants inside, 50 just outside, each at four operating points); its flags after `--`.
    Family(FamilyArgs),
    /// Makes the expected outputs anew after an intended change (tests/expected/: the QEMU
    /// golden log, the figures' CSVs; the command-line snapshots) and lists the files that
    /// changed.
    Bless,
}

#[derive(Args)]
struct FamilyArgs {
    /// `host-sim family` flags (`-- --seed 7 --json`).
    #[arg(last = true, value_name = "FLAGS", allow_hyphen_values = true)]
    flags: Vec<String>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = tools::isolate().and_then(|()| match cli.task {
        Task::Run(args) => run::run(&args),
        Task::Test => test::test(),
        Task::Size => size::firmware_size(&mut io::stdout()),
        Task::Console(args) => console::console(&args),
        Task::Soak(args) => soak::soak_alone(&args),
        Task::Family(args) => exec_output(host_sim().arg("family").args(&args.flags)),
        Task::Bless => bless::bless(),
    });
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            eprintln!("xtask: {failure}");
            failure.exit_code()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> std::result::Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("cargo xtask").chain(args.iter().copied()))
    }

    #[test]
    fn negative_values_after_a_space_reach_hil_as_typed() {
        let Task::Run(args) = parse(&["run", "cycles=50", "--", "--force-n", "-0.0001"])
            .expect("accepted")
            .task
        else {
            panic!("not a run");
        };
        assert_eq!(args.scenario, ["cycles=50"]);
        assert_eq!(args.hil_flags, ["--force-n", "-0.0001"]);
    }

    #[test]
    fn console_takes_a_plant_a_script_and_a_recording_only() {
        assert!(matches!(
            parse(&["console"]).expect("accepted").task,
            Task::Console(_)
        ));
        assert!(parse(&["console", "cycles=5"]).is_err());
        assert!(
            parse(&["console", "--plant", "p.toml", "--script", "s", "--record", "r.csv"]).is_ok()
        );
        assert!(
            parse(&["console", "--record", "r.csv"]).is_err(),
            "a recording needs a script"
        );
    }

    #[test]
    fn bless_takes_no_arguments() {
        assert!(matches!(
            parse(&["bless"]).expect("accepted").task,
            Task::Bless
        ));
        assert!(parse(&["bless", "cycles=5"]).is_err());
    }

    #[test]
    fn a_soak_of_zero_cycles_is_refused() {
        let Task::Soak(args) = parse(&["soak", "--cycles", "1000000", "--seed", "7"])
            .expect("accepted")
            .task
        else {
            panic!("not a soak");
        };
        assert_eq!((args.cycles, args.seed), (Some(1_000_000), Some(7)));
        assert!(parse(&["soak", "--cycles", "0"]).is_err());
    }

    #[test]
    fn a_negative_scenario_value_is_refused_with_the_word_named() {
        let error = parse(&["run", "cycles=-5"])
            .err()
            .expect("refused")
            .to_string();
        assert!(
            error.contains("cycles=-5: cycles must be a whole number from 1"),
            "{error}"
        );
        let error = parse(&["run", "duty=-inf"])
            .err()
            .expect("refused")
            .to_string();
        assert!(error.contains("duty=-inf"), "{error}");
    }
}
