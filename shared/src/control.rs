//! The command controller: executes one command line against the operator's settings, the
//! feeder's state and the recipe store, and answers with exactly one [`Reply`] and at most one
//! [`Action`] for the control loop.
//!
//! The controller owns the operator's [`Settings`] (always valid on its [`Machine`]); the control
//! loop owns the motion. A command never touches the output directly: it yields an action that
//! the transport queues for the control loop, which applies it at a segment start (and the
//! scheduler at the next cycle boundary). A refused command yields [`Action::None`] and leaves the
//! settings and the store as they were.
//!
//! Rules beyond validation:
//! * `start` is refused while a fault is latched (`ERR 61`); `reset` clears it.
//! * `recipe save` writes only while the feeder is stopped (`ERR 60`); a failed write is `ERR 62`.
//! * `recipe load` applies the slot like a `set`; an empty or unusable slot is `ERR 63` or
//!   `ERR 64` and changes nothing.
//! * `config set` edits a copy of the configuration the board runs, each value checked on its
//!   own (`ERR 65`); a key that changes what the output does only while stopped (`ERR 60`).
//!   `config save` checks the copy as a whole and stores it, only while stopped; the board runs
//!   it from its next start (`restart`, only while stopped). A board that keeps no
//!   configuration answers `ERR 66`.
//!
//! The [`Snapshot`] the transport passes in lags the requests it has just queued by up to a few
//! cycles. The controller therefore remembers its last `start`, `stop` or `reset` until
//! [`SETTLE_CYCLES`] cycles have begun: a `recipe save` right after `start` is refused, and a
//! `start` right after `reset` is accepted.

use crate::configuration::{record as config_record, BoardFacts, ConfigError, Configuration};
use crate::error::Error;
use crate::plan::TickPlan;
use crate::protocol::{Command, ConfigCommand, Reply, ReplyError, Status};
use crate::recipe::{self, RecipeSlot, RecordError, RECIPE_SLOTS, RECORD_LEN};
use crate::scheduler::Phase;
use crate::settings::{Applied, Machine, Settings};
use crate::supervisor::{Fault, RunState, SupervisorEvent};
use crate::waveform::WaveformSpec;

/// Cycles (or idle periods) after which a queued motion request shows in the snapshot: the
/// control loop takes it at the next segment start and the scheduler acts on it at the cycle
/// boundary after the one already prepared.
pub const SETTLE_CYCLES: u64 = 3;

/// Persistent storage of the recipe records, one [`RECORD_LEN`]-byte record per slot.
pub trait RecipeStore {
    /// Why a record could not be written.
    type Error;

    /// The record stored in `slot`; erased storage reads as all `0xFF`.
    fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN];

    /// Replaces the record in `slot`, leaving the other slots as they are.
    fn write(&mut self, slot: RecipeSlot, record: &[u8; RECORD_LEN]) -> Result<(), Self::Error>;
}

/// Persistent storage of the machine's configuration record
/// ([`crate::configuration::record`]).
pub trait ConfigurationStore {
    /// Why the record could not be written.
    type WriteError;

    /// The stored record; erased storage reads as all `0xFF`.
    fn read_configuration(&mut self) -> [u8; config_record::RECORD_LEN];

    /// Replaces the stored record.
    fn write_configuration(
        &mut self,
        record: &[u8; config_record::RECORD_LEN],
    ) -> Result<(), Self::WriteError>;
}

/// The feeder as the control loop last published it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Snapshot {
    /// The supervisor's state, with the latched fault's cause.
    pub state: RunState,
    /// Phase of the cycle being output.
    pub phase: Phase,
    pub uptime_ms: u64,
    /// Cycles (including idle periods) begun since power-up.
    pub cycles: u64,
    /// The closed loop, on a board that runs one.
    pub closed_loop: Option<crate::closed_loop::LoopReport>,
    /// Track control, on a board with a part sensor.
    pub track: Option<crate::closed_loop::TrackReport>,
}

/// What the control loop must do after a command. `Configure` carries the whole plan: it is
/// made once per command and moved to the control loop without an allocator to box it.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Action {
    None,
    Start,
    Stop,
    /// Acknowledge the latched fault.
    Reset,
    /// Restart the board (the output is stopped).
    Restart,
    /// Stream telemetry on the link (`true`) or stop.
    Telemetry(bool),
    /// Run this validated waveform, already planned on the machine's clock, and ramp length
    /// from the next cycle boundary.
    Configure {
        spec: WaveformSpec,
        plan: TickPlan,
        ramp_cycles: u16,
    },
}

impl Action {
    /// The supervisor's request this action makes, for the motion actions.
    pub const fn request(&self) -> Option<SupervisorEvent> {
        match self {
            Action::Start => Some(SupervisorEvent::StartRequested),
            Action::Stop => Some(SupervisorEvent::StopRequested),
            Action::Reset => Some(SupervisorEvent::ResetRequested),
            _ => None,
        }
    }
}

/// The answer to one command line.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The one reply line, without its terminator.
    pub reply: Reply,
    pub action: Action,
    /// Why the command was refused, where it was: the reply's `ERR` line says the same.
    pub refusal: Option<ReplyError>,
}

impl Outcome {
    fn reply(reply: Reply) -> Self {
        Outcome {
            reply,
            action: Action::None,
            refusal: None,
        }
    }

    fn error(error: ReplyError) -> Self {
        Outcome {
            refusal: Some(error),
            ..Self::reply(Reply::error(&error))
        }
    }

    fn act(reply: Reply, action: Action) -> Self {
        Outcome {
            action,
            ..Self::reply(reply)
        }
    }

    fn answer(answer: Result<Reply, ReplyError>) -> Self {
        match answer {
            Ok(reply) => Self::reply(reply),
            Err(error) => Self::error(error),
        }
    }
}

/// A motion request the snapshot may not show yet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Issued {
    Start,
    Stop,
    Reset,
}

/// The configuration of a board that keeps one.
#[derive(Debug, Clone, Copy)]
struct Configured {
    board: BoardFacts,
    /// The image's compiled defaults.
    defaults: Configuration,
    /// What the board runs, from its start.
    running: Configuration,
    /// What `config set` has made of it.
    edited: Configuration,
}

/// Executes commands; see the module documentation.
#[derive(Debug, Clone)]
pub struct Controller {
    machine: Machine,
    applied: Applied,
    /// The last motion request and the snapshot's cycle count when it was issued.
    issued: Option<(Issued, u64)>,
    configured: Option<Configured>,
    /// The recipe whose settings are the operator's, until a `set` changes them.
    recipe: Option<RecipeSlot>,
}

impl Controller {
    /// A controller for `machine` starting from `settings`, which must be valid on it, on a board
    /// that keeps no configuration.
    pub fn new(machine: Machine, settings: Settings) -> Result<Self, Error> {
        Ok(Controller {
            machine,
            applied: settings.validate(&machine)?,
            issued: None,
            configured: None,
            recipe: None,
        })
    }

    /// A controller for `board` running `configuration` (which must hold on it), starting from
    /// its start-up settings; `defaults` are the image's compiled ones, for `config defaults`.
    pub fn configured(
        board: BoardFacts,
        defaults: Configuration,
        configuration: Configuration,
    ) -> Result<Self, ConfigError> {
        configuration.check(&board)?;
        let machine = configuration.machine(&board);
        let applied = configuration.startup.validate(&machine).map_err(|error| {
            ConfigError::new(
                crate::configuration::Key::startup(&configuration.startup),
                crate::configuration::Problem::Startup(error),
            )
        })?;
        Ok(Controller {
            machine,
            applied,
            issued: None,
            configured: Some(Configured {
                board,
                defaults,
                running: configuration,
                edited: configuration,
            }),
            recipe: None,
        })
    }

    /// The operator's settings: in force, or taking effect at the next cycle boundary.
    pub fn settings(&self) -> &Settings {
        &self.applied.settings
    }

    /// The settings with their tick plan and predicted feed rate.
    pub fn applied(&self) -> &Applied {
        &self.applied
    }

    /// Answers one line from the [`crate::LineAssembler`]: a refused line gets its `ERR`.
    pub fn handle<S: RecipeStore + ConfigurationStore>(
        &mut self,
        line: Result<Command, ReplyError>,
        snapshot: &Snapshot,
        store: &mut S,
    ) -> Outcome {
        match line {
            Ok(command) => self.execute(command, snapshot, store),
            Err(error) => Outcome::error(error),
        }
    }

    /// Executes `command` given the feeder's `snapshot`.
    pub fn execute<S: RecipeStore + ConfigurationStore>(
        &mut self,
        command: Command,
        snapshot: &Snapshot,
        store: &mut S,
    ) -> Outcome {
        if self
            .issued
            .is_some_and(|(_, at_cycle)| snapshot.cycles >= at_cycle.saturating_add(SETTLE_CYCLES))
        {
            self.issued = None;
        }
        match command {
            Command::Start if self.fault_latched(snapshot) => {
                Outcome::error(ReplyError::FaultLatched)
            }
            Command::Start => self.issue(Issued::Start, snapshot, "starting"),
            Command::Stop => self.issue(Issued::Stop, snapshot, "stopping"),
            Command::Reset if self.fault_latched(snapshot) => {
                self.issue(Issued::Reset, snapshot, "fault cleared")
            }
            Command::Reset => Outcome::reply(Reply::ok(format_args!("no fault latched"))),
            Command::Status => Outcome::reply(Reply::status(&self.status(snapshot))),
            Command::Get(param) => Outcome::reply(Reply::get(param, &self.status(snapshot))),
            Command::Set(setting) => match self.applied.settings.apply(setting, &self.machine) {
                Ok(applied) => {
                    self.recipe = None;
                    self.adopt(applied, Reply::applied(&applied))
                }
                Err(error) => Outcome::error(error.into()),
            },
            Command::RecipeSave(_) if !self.stopped(snapshot) => {
                Outcome::error(ReplyError::NotStopped)
            }
            Command::RecipeSave(slot) => {
                let record = recipe::encode(slot, &self.applied.settings);
                match store.write(slot, &record) {
                    Ok(()) => Outcome::reply(Reply::recipe_saved(slot)),
                    Err(_) => Outcome::error(ReplyError::StorageFailed),
                }
            }
            Command::RecipeLoad(slot) => {
                match recipe::load(&store.read(slot), slot, &self.machine) {
                    Ok(applied) => {
                        self.recipe = Some(slot);
                        self.adopt(applied, Reply::recipe_loaded(slot, &applied))
                    }
                    Err(issue) => Outcome::error(ReplyError::RecipeUnusable { slot, issue }),
                }
            }
            Command::RecipeList => {
                let mut entries = [Err(RecordError::Empty); RECIPE_SLOTS];
                for (entry, slot) in entries.iter_mut().zip(RecipeSlot::all()) {
                    *entry = self.entry(store, slot);
                }
                Outcome::reply(Reply::recipe_list(&entries))
            }
            Command::Help => Outcome::reply(Reply::help()),
            Command::Restart if !self.stopped(snapshot) => Outcome::error(ReplyError::NotStopped),
            Command::Restart => {
                Outcome::act(Reply::ok(format_args!("restarting")), Action::Restart)
            }
            Command::Telemetry(on) => Outcome::act(
                Reply::ok(format_args!("telemetry {}", if on { "on" } else { "off" })),
                Action::Telemetry(on),
            ),
            Command::Config(command) => {
                let stopped = self.stopped(snapshot);
                match self.configured.as_mut() {
                    Some(configured) => {
                        Outcome::answer(configured.execute(command, stopped, store))
                    }
                    None => Outcome::error(ReplyError::NoConfiguration),
                }
            }
        }
    }

    /// The configuration the board runs, where it keeps one.
    pub fn configuration(&self) -> Option<&Configuration> {
        self.configured
            .as_ref()
            .map(|configured| &configured.running)
    }

    /// What `recipe list` shows for `slot`: the stored settings if they are usable here.
    fn entry<S: RecipeStore>(
        &self,
        store: &mut S,
        slot: RecipeSlot,
    ) -> Result<Settings, RecordError> {
        let settings = recipe::decode(&store.read(slot), slot)?;
        match settings.validate(&self.machine) {
            Ok(_) => Ok(settings),
            Err(error) => Err(RecordError::Rejected(error)),
        }
    }

    /// Makes `applied` the operator's settings and asks the control loop to run them.
    fn adopt(&mut self, applied: Applied, reply: Reply) -> Outcome {
        self.applied = applied;
        Outcome::act(
            reply,
            Action::Configure {
                spec: applied.settings.spec(),
                plan: applied.plan,
                ramp_cycles: applied.settings.ramp_cycles,
            },
        )
    }

    fn issue(&mut self, issued: Issued, snapshot: &Snapshot, what: &str) -> Outcome {
        self.issued = Some((issued, snapshot.cycles));
        let action = match issued {
            Issued::Start => Action::Start,
            Issued::Stop => Action::Stop,
            Issued::Reset => Action::Reset,
        };
        Outcome::act(Reply::ok(format_args!("{}", what)), action)
    }

    /// A fault is latched and no `reset` is on its way.
    fn fault_latched(&self, snapshot: &Snapshot) -> bool {
        matches!(snapshot.state, RunState::Faulted(_))
            && !matches!(self.issued, Some((Issued::Reset, _)))
    }

    /// The output is idle and stays idle: no motion in progress, requested or on its way.
    fn stopped(&self, snapshot: &Snapshot) -> bool {
        let idle = matches!(snapshot.state, RunState::Stopped | RunState::Faulted(_))
            && snapshot.phase == Phase::Stopped;
        idle && !matches!(self.issued, Some((Issued::Start | Issued::Stop, _)))
    }

    /// The recipe loaded last, while no `set` has changed its settings.
    pub fn recipe(&self) -> Option<RecipeSlot> {
        self.recipe
    }

    /// What `status` reports, from the feeder's `snapshot`.
    pub fn status(&self, snapshot: &Snapshot) -> Status<Fault> {
        Status {
            phase: snapshot.phase,
            fault: match snapshot.state {
                RunState::Faulted(fault) => Some(fault),
                _ => None,
            },
            waveform: self.applied.plan.waveform,
            ramp_cycles: self.applied.settings.ramp_cycles,
            feed_rate_mps: self.applied.feed_rate_mps,
            uptime_ms: snapshot.uptime_ms,
            cycles: snapshot.cycles,
            closed_loop: snapshot.closed_loop,
            track: snapshot.track,
        }
    }
}

impl Configured {
    /// One `config` command; `stopped` as [`Controller::stopped`] says.
    fn execute<S: ConfigurationStore>(
        &mut self,
        command: ConfigCommand,
        stopped: bool,
        store: &mut S,
    ) -> Result<Reply, ReplyError> {
        match command {
            ConfigCommand::List => Ok(Reply::config_list(&self.edited)),
            ConfigCommand::Get(key) => Ok(Reply::config_value(key, &self.edited)),
            ConfigCommand::Set(key, _) if key.changes_output() && !stopped => {
                Err(ReplyError::NotStopped)
            }
            ConfigCommand::Set(key, value) => match key.set(&self.edited, value) {
                Ok(edited) => {
                    self.edited = edited;
                    Ok(Reply::config_set(key, &self.edited))
                }
                Err(error) => Err(ReplyError::ConfigRefused(error)),
            },
            ConfigCommand::Save if !stopped => Err(ReplyError::NotStopped),
            ConfigCommand::Save => match self.edited.check(&self.board) {
                Err(error) => Err(ReplyError::ConfigRefused(error)),
                Ok(()) => match store.write_configuration(&config_record::encode(&self.edited)) {
                    Ok(()) => Ok(Reply::config_saved(self.edited != self.running)),
                    Err(_) => Err(ReplyError::StorageFailed),
                },
            },
            ConfigCommand::Defaults => {
                self.edited = self.defaults;
                Ok(Reply::config_defaults())
            }
        }
    }
}
