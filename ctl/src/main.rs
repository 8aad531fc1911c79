//! `feeder-ctl`: talks to the feeder's serial console, over a serial port (the NUCLEO's ST-LINK
//! virtual COM port) or over TCP (QEMU's `-serial tcp:…`).
//!
//! ```text
//! feeder-ctl (--port PATH [--baud N] | --tcp HOST:PORT) [--timeout-ms N] [COMMAND WORDS…]
//! feeder-ctl … export FILE
//! feeder-ctl … import FILE [--save]
//! feeder-ctl … watch [--record FILE] [--seconds N]
//! feeder-ctl … script FILE [--record FILE]
//! feeder-ctl … calibrate [--save] [--report FILE]
//! ```
//!
//! With command words, sends them as one line, prints the reply and exits with 0 for `OK`, 1 for
//! `ERR`. Without, reads commands from standard input (with a prompt on a terminal) and prints
//! each reply. `export` and `import` move the board's configuration to and from a file
//! (`config_file`); `watch` shows and records the board's telemetry (`watch`); `script` runs a
//! command script headless (`script`); `calibrate` guides the drive's calibration
//! (`calibrate`). Exit code 2: bad arguments or a connection or timeout error.

mod calibrate;
mod config_file;
mod console;
mod recording;
mod script;
mod watch;

use std::io::{self, IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::error::ErrorKind;
use clap::{ArgGroup, CommandFactory, Parser, Subcommand};
use config_file::TransferError;
use console::{Console, Target};

/// Baud rate of the serial port when `--baud` is not given (the firmware's LPUART1 setting).
const DEFAULT_BAUD: u32 = 115_200;

/// Longest reply timeout accepted: an hour.
const MAX_TIMEOUT_MS: u32 = 3_600_000;

/// Talks to the feeder's serial console: one command per line, one `OK …` or `ERR …` reply.
#[derive(Parser)]
#[command(
    name = "feeder-ctl",
    version,
    allow_negative_numbers = true,
    group(ArgGroup::new("target").required(true).args(["port", "tcp"])),
    disable_help_subcommand = true,
    override_usage = "feeder-ctl [OPTIONS] <--port <PATH>|--tcp <HOST:PORT>> [COMMAND]...\n       \
                      feeder-ctl [OPTIONS] <--port <PATH>|--tcp <HOST:PORT>> <TOOL> [ARGS]...",
    subcommand_value_name = "TOOL",
    subcommand_help_heading = "Tools"
)]
struct Options {
    #[command(subcommand)]
    tool: Option<Tool>,
    /// Serial port, e.g. /dev/ttyACM0 (the NUCLEO's ST-LINK virtual COM port).
    #[arg(long, value_name = "PATH")]
    port: Option<String>,
    /// Baud rate of the serial port [default: 115200].
    #[arg(long, value_name = "N", requires = "port", conflicts_with = "tcp",
          value_parser = clap::value_parser!(u32).range(1..))]
    baud: Option<u32>,
    /// TCP serial, e.g. QEMU's `-serial tcp:127.0.0.1:4444,server=on,wait=off`.
    #[arg(long, value_name = "HOST:PORT")]
    tcp: Option<String>,
    /// How long to wait for a reply, in milliseconds.
    #[arg(long, value_name = "N", default_value_t = 3000,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_TIMEOUT_MS)))]
    timeout_ms: u32,
    /// One command (e.g. `set feed 30`, `set duty -0.5`); without it, commands are read from
    /// standard input. Exit code 0 for `OK`, 1 for `ERR`, 2 for bad arguments, a connection
    /// error or no reply in time.
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "COMMAND"
    )]
    command: Vec<String>,
}

/// Work done by the tool rather than one console line; at the prompt too.
#[derive(Subcommand)]
enum Tool {
    /// Writes the board's configuration (`config list`, unsaved changes included) to FILE, one
    /// key=value per line.
    Export {
        /// The configuration file to write.
        #[arg(value_name = "FILE")]
        file: PathBuf,
    },
    /// Sends every key=value line of FILE as `config set`; a refusal sets every key back and
    /// exits with 1.
    Import {
        /// The configuration file to read.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// Saves the configuration on the board afterwards (`config save`); it runs from the
        /// board's next start.
        #[arg(long)]
        save: bool,
    },
    /// Shows the board's telemetry live (position, trims, slack, parts per minute); q leaves.
    Watch {
        /// Records every record received to FILE as CSV, a header naming each column and unit.
        #[arg(long, value_name = "FILE")]
        record: Option<PathBuf>,
        /// Headless: listens this many seconds, then writes the recording and ends.
        #[arg(long, value_name = "N", value_parser = seconds)]
        seconds: Option<f64>,
    },
    /// Guides the drive's calibration: the encoder's direction (by hand, on a terminal), the
    /// drive identified by the closed loop (gains, zero offset, lag) and judged against the
    /// envelope, the DAC zero code that takes the offset off, saved with consent. Exit code 1
    /// if refused.
    Calibrate {
        /// Saves the proposed configuration on the board without asking, and restarts it.
        #[arg(long)]
        save: bool,
        /// Writes every step's findings to FILE, one key=value a line.
        #[arg(long, value_name = "FILE")]
        report: Option<PathBuf>,
    },
    /// Runs a command script: console lines, one a line, and `wait SECONDS` lines (the board's
    /// clock); every command and reply on standard output. Exit code 1 if a reply was ERR.
    Script {
        /// The script.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// Records the telemetry while the script runs to FILE as CSV.
        #[arg(long, value_name = "FILE")]
        record: Option<PathBuf>,
    },
}

/// A number of seconds: finite, positive, at most a day.
fn seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(value) if value > 0.0 && value <= 86_400.0 => Ok(value),
        _ => Err(format!(
            "{text:?} is not a number of seconds from 0 to 86400"
        )),
    }
}

impl Options {
    fn target(&self) -> Target<'_> {
        match (&self.port, &self.tcp) {
            (Some(path), _) => Target::Serial {
                path,
                baud: self.baud.unwrap_or(DEFAULT_BAUD),
            },
            (None, Some(address)) => Target::Tcp(address),
            (None, None) => unreachable!("clap requires one of --port and --tcp"),
        }
    }
}

/// A tool typed at the prompt (`watch`, `calibrate` …), parsed as on the command line.
#[derive(Parser)]
#[command(
    name = "feeder-ctl",
    no_binary_name = true,
    disable_help_subcommand = true
)]
struct PromptTool {
    #[command(subcommand)]
    tool: Tool,
}

/// The names of the tools, which the prompt runs itself instead of sending them.
fn is_tool(word: &str) -> bool {
    PromptTool::command()
        .get_subcommands()
        .any(|tool| tool.get_name() == word)
}

fn interactive(console: &mut Console, target: &Target) -> io::Result<()> {
    let stdin = io::stdin();
    let prompt = stdin.is_terminal();
    let mut buffer = String::new();
    loop {
        if prompt {
            print!("feeder> ");
            io::stdout().flush()?;
        }
        // One line at a time, standard input locked only while it is read: a tool reads it too
        // (`calibrate` asks the operator).
        buffer.clear();
        if stdin.read_line(&mut buffer)? == 0 {
            return Ok(());
        }
        let line = buffer.trim();
        if line.is_empty() {
            continue;
        }
        if matches!(line, "quit" | "exit") {
            return Ok(());
        }
        if line.split_whitespace().next().is_some_and(is_tool) {
            match PromptTool::try_parse_from(line.split_whitespace()) {
                Ok(prompt) => {
                    run_tool(&prompt.tool, console, target);
                }
                Err(error) => eprintln!("{}", error.render()),
            }
            continue;
        }
        println!("{}", console.command(line)?);
        // At the prompt telemetry is not shown: `watch` draws it.
        console.take_telemetry();
    }
}

/// The options, refused with clap's usage and exit code 2 where a word that should start the
/// command is an option clap does not know: console commands never start with `-`.
fn options() -> Options {
    let options = Options::parse();
    if let Some(word) = options.command.first().filter(|word| word.starts_with('-')) {
        Options::command()
            .error(
                ErrorKind::UnknownArgument,
                format!("unexpected argument '{word}': a command starts with a word like `status`"),
            )
            .exit();
    }
    options
}

fn main() -> ExitCode {
    let options = options();
    let timeout = Duration::from_millis(options.timeout_ms.into());
    let target = options.target();
    let mut console = match Console::open(&target, timeout) {
        Ok(console) => console,
        Err(error) => {
            eprintln!("feeder-ctl: cannot open {target}: {error}");
            return ExitCode::from(2);
        }
    };
    let result = if let Some(tool) = &options.tool {
        return run_tool(tool, &mut console, &target);
    } else if options.command.is_empty() {
        interactive(&mut console, &target).map(|()| true)
    } else {
        console.command(&options.command.join(" ")).map(|reply| {
            println!("{reply}");
            reply.starts_with("OK")
        })
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(error) => {
            eprintln!("feeder-ctl: {error}");
            ExitCode::from(2)
        }
    }
}

/// Runs `tool` on `console`: exit code 0 when done, 1 when the board refused, 2 when the link or
/// the file failed.
fn run_tool(tool: &Tool, console: &mut Console, target: &Target) -> ExitCode {
    let outcome = match tool {
        Tool::Export { file } => config_file::export(console, file, &target.to_string())
            .map(|keys| format!("feeder-ctl: {keys} keys written to {}", file.display())),
        Tool::Import { file, save } => config_file::import(console, file, *save).map(|last| {
            println!("{last}");
            format!("feeder-ctl: {} imported", file.display())
        }),
        Tool::Watch { record, seconds } => {
            let watched = match seconds {
                Some(seconds) => watch::headless(console, *seconds, record.as_deref()),
                None => watch::live(console, record.as_deref(), target.to_string()),
            };
            return match watched {
                Ok(records) => {
                    eprintln!("feeder-ctl: {records} telemetry records");
                    ExitCode::SUCCESS
                }
                Err(error) => {
                    eprintln!("feeder-ctl: {error}");
                    ExitCode::from(2)
                }
            };
        }
        Tool::Calibrate { save, report } => {
            return match calibrate::run(console, *save, report.as_deref()) {
                Ok(calibrate::Outcome::Accepted) => {
                    eprintln!("feeder-ctl: calibration accepted");
                    ExitCode::SUCCESS
                }
                Ok(calibrate::Outcome::Refused(reason)) => {
                    eprintln!("feeder-ctl: calibration refused: {reason}");
                    ExitCode::FAILURE
                }
                Err(error) => {
                    eprintln!("feeder-ctl: {error}");
                    ExitCode::from(2)
                }
            };
        }
        Tool::Script { file, record } => {
            let ran = std::fs::read_to_string(file)
                .map_err(script::ScriptError::Io)
                .and_then(|text| script::parse(&text))
                .and_then(|steps| script::run(console, &steps, record.as_deref()));
            return match ran {
                Ok(true) => ExitCode::SUCCESS,
                Ok(false) => ExitCode::FAILURE,
                Err(error) => {
                    eprintln!("feeder-ctl: {}: {error}", file.display());
                    ExitCode::from(2)
                }
            };
        }
    };
    match outcome {
        Ok(done) => {
            eprintln!("{done}");
            ExitCode::SUCCESS
        }
        Err(error @ TransferError::Refused { .. }) => {
            eprintln!("feeder-ctl: {error}");
            ExitCode::FAILURE
        }
        Err(error) => {
            eprintln!("feeder-ctl: {error}");
            ExitCode::from(2)
        }
    }
}
