//! `feeder-ctl script`: runs a command script headless. A script is console lines, one a line,
//! plus `wait SECONDS` lines, which wait until the board's own clock (`status`'s `uptime_s`)
//! has advanced that far; `#` starts a comment and blank lines are skipped. Every command and
//! its reply go to standard output; with a recording, telemetry is on for the whole script and
//! its records are written as CSV at the end, also when the script stops early.

use std::io;
use std::path::Path;
use std::time::Duration;

use feeder_shared::telemetry::Record;

use crate::console::{uptime_s, Console};
use crate::recording;

/// How often `wait` asks the board for its clock.
const WAIT_POLL: Duration = Duration::from_millis(50);

/// One step of a script.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// A console line, sent as it is.
    Command(String),
    /// Wait until the board's clock has advanced this many seconds.
    Wait { seconds: f64 },
}

/// Why a script did not run to its end.
#[derive(Debug)]
pub enum ScriptError {
    /// A line of the file is not a step: its number and why.
    Syntax { line: usize, reason: String },
    /// The link, the file or the recording failed.
    Io(io::Error),
}

impl std::fmt::Display for ScriptError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ScriptError::Syntax { line, reason } => write!(f, "line {line}: {reason}"),
            ScriptError::Io(error) => write!(f, "{error}"),
        }
    }
}

/// The steps of a script's text.
pub fn parse(text: &str) -> Result<Vec<Step>, ScriptError> {
    let mut steps = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let mut words = line.split_whitespace();
        if words
            .next()
            .is_some_and(|word| word.eq_ignore_ascii_case("wait"))
        {
            let seconds = match (words.next().map(str::parse::<f64>), words.next()) {
                (Some(Ok(seconds)), None) if seconds.is_finite() && seconds >= 0.0 => seconds,
                _ => {
                    return Err(ScriptError::Syntax {
                        line: index + 1,
                        reason: format!("`wait` takes one number of seconds, not {line:?}"),
                    })
                }
            };
            steps.push(Step::Wait { seconds });
        } else {
            steps.push(Step::Command(line.to_string()));
        }
    }
    Ok(steps)
}

/// The board's clock, from a `status` reply.
fn board_clock_s(console: &mut Console) -> io::Result<f64> {
    let reply = console.command("status")?;
    uptime_s(&reply).ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("no uptime in {reply:?}"),
        )
    })
}

/// Runs `steps` on `console`, printing every command and its reply; records the telemetry into
/// `record` if given. True when every command got `OK`.
pub fn run(
    console: &mut Console,
    steps: &[Step],
    record: Option<&Path>,
) -> Result<bool, ScriptError> {
    let mut records: Vec<Record> = Vec::new();
    if record.is_some() {
        let reply = console.command("telemetry on").map_err(ScriptError::Io)?;
        eprintln!("feeder-ctl: recording: {reply}");
    }
    let result = run_steps(console, steps, &mut records);
    if let Some(path) = record {
        if let Ok(reply) = console.command("telemetry off") {
            eprintln!("feeder-ctl: recording ends: {reply}");
        }
        records.extend(console.take_telemetry());
        recording::write(path, &records).map_err(ScriptError::Io)?;
        eprintln!(
            "feeder-ctl: {} telemetry records written to {}",
            records.len(),
            path.display()
        );
    }
    result
}

fn run_steps(
    console: &mut Console,
    steps: &[Step],
    records: &mut Vec<Record>,
) -> Result<bool, ScriptError> {
    let mut all_ok = true;
    for step in steps {
        match step {
            Step::Command(line) => {
                let reply = console.command(line).map_err(ScriptError::Io)?;
                println!("> {line}");
                println!("{reply}");
                all_ok &= reply.starts_with("OK");
            }
            Step::Wait { seconds } => {
                println!("> wait {seconds}");
                let until = board_clock_s(console).map_err(ScriptError::Io)? + seconds;
                while board_clock_s(console).map_err(ScriptError::Io)? < until {
                    records.extend(console.take_telemetry());
                    console.listen(WAIT_POLL).map_err(ScriptError::Io)?;
                }
            }
        }
        records.extend(console.take_telemetry());
    }
    Ok(all_ok)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_script_is_commands_and_waits() {
        let steps = parse("# bring-up\nconfig list\n\n  wait 1.5  # settle\nstart\n").unwrap();
        assert_eq!(
            steps,
            [
                Step::Command("config list".into()),
                Step::Wait { seconds: 1.5 },
                Step::Command("start".into()),
            ]
        );
    }

    #[test]
    fn a_wait_without_one_number_is_refused_with_its_line() {
        for text in ["wait", "wait soon", "wait 1 2", "wait -1", "wait inf"] {
            let error = parse(&format!("start\n{text}\n")).unwrap_err();
            assert!(
                matches!(error, ScriptError::Syntax { line: 2, .. }),
                "{text}: {error}"
            );
        }
    }
}
