//! The one source of truth of the feeder: waveform, integer-tick plan, scheduler and models.
//!
//! From the period `T`, the duty cycle `d` and the stroke `x_max` (or peak acceleration `a_max`)
//! of a longitudinally vibrating plate this crate derives the three-level acceleration waveform
//! (paper Eq. 1–5, [`waveform`]), turns it into whole ticks of a timer clock without letting the
//! plate drift ([`plan`]), schedules it with soft start and stop and boundary-only changes
//! ([`scheduler`]), and predicts the part's feed rate ([`model`]). The firmware and the host
//! simulator both run this code; neither has a waveform of its own.
//!
//! `no_std`, no allocation, no `unsafe`; every fallible call returns a typed [`Error`].
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_debug_implementations)]

pub mod calibration;
pub mod closed_loop;
pub mod configuration;
pub mod control;
pub mod drive;
pub mod error;
pub mod event;
pub mod line;
pub mod modbus;
pub mod model;
pub mod number;
pub mod plan;
pub mod protocol;
pub mod recipe;
pub mod scenario;
pub mod scheduler;
pub mod segment;
pub mod settings;
pub mod supervisor;
pub mod telemetry;
#[cfg(feature = "testing")]
pub mod testing;
pub mod waveform;

pub use control::{Action, ConfigurationStore, Controller, Outcome, RecipeStore, Snapshot};
pub use drive::{
    DacCalibration, DacLevels, Direction, DriveError, PwmCalibration, PwmCommand, PwmLevels,
};
pub use error::{Error, Quantity};
pub use model::{Friction, Regime, SteadyState};
pub use plan::{CycleTicks, TickClock, TickPlan};
pub use protocol::{Command, ConfigCommand, LineAssembler, Param, Reply, ReplyError, Status};
pub use recipe::{RecipeSlot, RecordError};
pub use scenario::{ScenarioError, ScenarioSetting};
pub use scheduler::{Amplitude, Phase, Scheduler, Segment};
pub use segment::SegmentKind;
pub use settings::{Applied, Machine, Setting, Settings};
pub use supervisor::{
    Fault, Led, MotionRequest, RunState, StopCategory, Supervisor, SupervisorEvent,
};
pub use waveform::{Drive, ExactSegment, Level, Limits, Waveform, WaveformSpec};
