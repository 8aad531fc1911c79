//! Refusals: one line on stderr and exit code 2, for clap's usage errors and the commands' own.

use std::io::Write as _;
use std::process::ExitCode;

/// Prints `message` as one line on stderr, control characters escaped, and exits with code 2.
pub fn refuse(message: &str) -> ExitCode {
    let mut line = String::with_capacity(message.len());
    for c in message.chars() {
        if c.is_control() {
            line.extend(c.escape_default());
        } else {
            line.push(c);
        }
    }
    let _ = writeln!(std::io::stderr().lock(), "{line}");
    ExitCode::from(2)
}

/// Clap's refusal as one line: the message and its tips, without the usage and the pointer to
/// `--help` that follow.
pub fn usage_error(error: &clap::Error) -> String {
    let rendered = error.render().to_string();
    let mut line = String::new();
    for part in rendered
        .lines()
        .map(str::trim)
        .take_while(|part| !part.starts_with("Usage:") && !part.starts_with("For more information"))
        .filter(|part| !part.is_empty())
    {
        if !line.is_empty() {
            line.push_str(if line.ends_with(':') { " " } else { "; " });
        }
        line.push_str(part);
    }
    line
}
