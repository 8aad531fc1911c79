//! What can go wrong when starting or running the emulated board.

use std::fmt;
use std::io;
use std::time::Duration;

/// A failure to start, run or read the emulated board.
#[derive(Debug)]
pub enum LaunchError {
    /// A program could not be started (usually: not installed, or not on `PATH`).
    Start {
        program: &'static str,
        source: io::Error,
    },
    /// A program's standard output was not handed over.
    NoOutput { program: &'static str },
    /// A program could not be waited for.
    Wait {
        program: &'static str,
        source: io::Error,
    },
    /// The decoded log could not be read, or is not UTF-8 text.
    Log(io::Error),
    /// The run went on longer than allowed and was ended.
    Timeout { limit: Duration },
    /// The plant link's FIFOs could not be made, or the link failed on the host's side.
    Plant(io::Error),
    /// The firmware image's path could not be made absolute.
    Image(io::Error),
}

impl fmt::Display for LaunchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LaunchError::Start { program, source } => write!(f, "cannot start {program}: {source}"),
            LaunchError::NoOutput { program } => write!(f, "no standard output from {program}"),
            LaunchError::Wait { program, source } => {
                write!(f, "cannot wait for {program}: {source}")
            }
            LaunchError::Log(source) => write!(f, "cannot read the decoded log: {source}"),
            LaunchError::Plant(source) => write!(f, "the plant link failed: {source}"),
            LaunchError::Image(source) => {
                write!(f, "cannot resolve the firmware image's path: {source}")
            }
            LaunchError::Timeout { limit } => {
                write!(
                    f,
                    "the emulated run took longer than {limit:?} and was ended"
                )
            }
        }
    }
}

impl std::error::Error for LaunchError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LaunchError::Start { source, .. }
            | LaunchError::Wait { source, .. }
            | LaunchError::Log(source)
            | LaunchError::Plant(source)
            | LaunchError::Image(source) => Some(source),
            LaunchError::NoOutput { .. } | LaunchError::Timeout { .. } => None,
        }
    }
}
