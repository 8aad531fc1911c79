//! Errors of the simulator: the shared crate's [`Error`] for every physical or configuration
//! refusal, plus the few conditions only the simulator can detect.

use core::fmt;

use feeder_shared::Error;

#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// A parameter refused by the shared crate (its message is shown as is).
    Shared(Error),
    /// Static friction below kinetic friction has no consistent stick–slip motion.
    StaticBelowKinetic { mu: f64, mu_static: f64 },
    /// A sweep, fit or search was asked for with too few or inconsistent points.
    BadRange { what: &'static str },
    /// Writing an output file failed.
    Output { path: String, reason: String },
    /// Reading an input (file or stream) failed.
    Input { source: String, reason: String },
    /// A firmware-in-the-loop run did not match the shared plan (details in the report).
    CheckFailed { problems: usize },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Shared(error) => error.fmt(f),
            SimError::StaticBelowKinetic { mu, mu_static } => write!(
                f,
                "static friction coefficient μ_s = {mu_static} must not be below the kinetic \
                 coefficient μ = {mu}"
            ),
            SimError::BadRange { what } => write!(f, "{what}"),
            SimError::Output { path, reason } => write!(f, "cannot write {path}: {reason}"),
            SimError::Input { source, reason } => write!(f, "cannot read {source}: {reason}"),
            SimError::CheckFailed { problems } => write!(
                f,
                "the firmware-in-the-loop check failed with {problems} problem(s), listed above"
            ),
        }
    }
}

impl std::error::Error for SimError {}

impl From<Error> for SimError {
    fn from(error: Error) -> Self {
        SimError::Shared(error)
    }
}
