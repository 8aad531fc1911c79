//! `host-sim`: predict a feeder before building it, and reproduce the paper's figures.
//!
//! One module per command; [`args`] holds the argument groups they share, [`output`] writes what
//! they produce, [`plot`] draws their charts and [`refusal`] reports what they cannot run.

mod args;
mod closed_loop;
mod cosim;
mod drift;
mod family;
mod hil;
mod output;
mod plot;
mod refusal;
mod saturation;
mod simulate;
mod sweep;
mod trace;
mod viscosity;

use std::process::ExitCode;

use clap::error::ErrorKind;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "host-sim",
    version,
    about = "Exact stick–slip simulator of the vibrating-plate parts feeder"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate one operating point to steady state (or for --cycles N), within the machine's
    /// drive limits unless --no-drive-limits.
    Simulate(simulate::SimulateArgs),
    /// Feed rate vs duty for one or more a_max, beside the models (Fig. 4, Fig. 9); a paper study,
    /// not held to the machine's drive limits.
    Sweep(sweep::SweepArgs),
    /// Steady velocity vs external force and the least-squares viscosity K (Fig. 10, Eq. 10); a
    /// paper study, not held to the machine's drive limits.
    Viscosity(viscosity::ViscosityArgs),
    /// Saturation duty d_sat,nqs vs a_max for several μ, model and simulation (Fig. 7, Eq. 16); a
    /// paper study, not held to the machine's drive limits.
    Saturation(saturation::SaturationArgs),
    /// Plate and part velocity through N cycles (Fig. 3, 5, 6, 8); a paper study, not held to the
    /// machine's drive limits.
    Trace(trace::TraceArgs),
    /// Check a running firmware's decoded event stream against the shared scheduler, edge by
    /// edge, and simulate the part on its actual edge times.
    Hil(hil::HilArgs),
    /// What each non-ideality of a real plate does to one operating point in open loop: feed
    /// rate, plate position, end stop; within the machine's drive limits unless
    /// --no-drive-limits.
    Drift(drift::DriftArgs),
    /// The shared closed loop on a real plate: the drive it identifies, how well it centres the
    /// plate and its feed rate beside the ideal plate's, with a verdict.
    ClosedLoop(closed_loop::ClosedLoopArgs),
    /// The emulated firmware (the QEMU `cosim` image) driving a real plate in lockstep.
    Cosim(cosim::CosimArgs),
    /// The closed loop on a seeded family of plants across its envelope and just outside it.
    Family(family::FamilyArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error)
            if error.use_stderr()
                && error.kind() != ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand =>
        {
            return refusal::refuse(&refusal::usage_error(&error));
        }
        Err(error) => error.exit(),
    };
    let outcome = match cli.command {
        Command::Simulate(args) => simulate::run(&args),
        Command::Sweep(args) => sweep::run(&args),
        Command::Viscosity(args) => viscosity::run(&args),
        Command::Saturation(args) => saturation::run(&args),
        Command::Trace(args) => trace::run(&args),
        Command::Drift(args) => drift::run(&args),
        // A run that fails its criteria is not a refusal: its report is out, and exit code 1
        // says so.
        Command::Hil(args) => match hil::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(error) => Err(error),
        },
        Command::Cosim(args) => match cosim::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(error) => Err(error),
        },
        Command::Family(args) => match family::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(error) => Err(error),
        },
        Command::ClosedLoop(args) => match closed_loop::run(&args) {
            Ok(code) => return code,
            Err(error) => Err(error),
        },
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => refusal::refuse(&format!("error: {error}")),
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// Every flag that takes a number reads a negative one after a space (`--force-n -1e-5`);
    /// only file names are left to clap's usual reading.
    #[test]
    fn every_numeric_flag_takes_hyphen_values() {
        let cli = super::Cli::command();
        cli.clone().debug_assert();
        for command in cli.get_subcommands() {
            for arg in command.get_arguments() {
                let file = arg
                    .get_value_names()
                    .is_some_and(|names| names.iter().any(|name| name == "FILE"));
                if arg.get_action().takes_values() && !file {
                    assert!(
                        arg.is_allow_hyphen_values_set(),
                        "{} --{}",
                        command.get_name(),
                        arg.get_id()
                    );
                }
            }
        }
    }
}
