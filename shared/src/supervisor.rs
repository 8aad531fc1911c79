//! Run, stop and fault supervision: what the start/stop button does, what the status LED shows
//! and when the motor driver may be enabled.
//!
//! The supervisor comes up [`RunState::Stopped`] after every reset (or [`RunState::Faulted`] when
//! the reset was the watchdog's), with the driver disabled: the feeder never resumes motion by
//! itself. A press starts; a press while running begins a soft stop, and the driver stays enabled
//! until the output has reached idle. A fault stops the motor in its [`StopCategory`] and is
//! latched: the next press (or an explicit reset) only acknowledges it, back to stopped, and a
//! further press or start starts again. Explicit start and stop requests (command line, scripts)
//! act like the button but never toggle. Track control: a full track (its part sensor,
//! `closed_loop::Track`) pauses a running feeder with a soft stop, and it resumes when the track
//! has room; a start into a full track runs once there is room.

/// Why the output was halted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// A segment was prepared after the edge it belonged to: the output timing was lost.
    EdgeMissed,
    /// The previous run ended in a watchdog reset.
    WatchdogReset,
    /// The configured waveform or output calibration was refused.
    InvalidSettings,
    /// The closed loop stopped: the drive's identification was refused, the plate could not be
    /// held, the position sensor failed, or the loop's decision came too late for its cycle.
    ClosedLoop,
    /// The output's edge counter did not count the forced update of the power-up self-test:
    /// edges cannot be told from missed ones, so the output never starts. No acknowledgement
    /// clears it: only a reset after the fault is fixed.
    EdgeCounter,
    /// The line's master (Modbus, or the console where its watchdog is on) fell silent for
    /// longer than the configured link timeout while the feeder ran: a soft stop, latched so
    /// that the feeder does not run again until it is told to.
    LinkLost,
}

/// How a fault brings the motor to a safe state (the stop categories of IEC 60204-1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopCategory {
    /// Category 0: zero command and driver disabled at once. For a fault that leaves no output
    /// segment to trust; the plate keeps whatever velocity it had.
    Immediate,
    /// Category 1: the output still works, so the cycle in progress runs to its end, where the
    /// plate is at rest, and only then is the command zero and the driver disabled.
    Controlled,
    /// Category 1 with the soft stop's ramp: nothing is wrong with the output or the plate, so
    /// the amplitude ramps down as after a stop request, and then the driver is disabled.
    Soft,
}

impl Fault {
    /// The stop this fault calls for: a missed edge has lost the output timing, a watchdog reset
    /// finds the output already off; refused settings and a closed loop that stopped leave the
    /// output working.
    pub const fn stop_category(self) -> StopCategory {
        match self {
            Fault::EdgeMissed | Fault::WatchdogReset | Fault::EdgeCounter => {
                StopCategory::Immediate
            }
            Fault::InvalidSettings | Fault::ClosedLoop => StopCategory::Controlled,
            Fault::LinkLost => StopCategory::Soft,
        }
    }

    /// Every fault, in the order of their codes ([`Fault::code`]).
    pub const ALL: [Fault; 6] = [
        Fault::EdgeMissed,
        Fault::WatchdogReset,
        Fault::InvalidSettings,
        Fault::ClosedLoop,
        Fault::EdgeCounter,
        Fault::LinkLost,
    ];

    /// The fault's stable number on the line (Modbus input register `fault`): 1 and up, in the
    /// order of [`Fault::ALL`]; 0 is no fault.
    pub const fn code(self) -> u16 {
        match self {
            Fault::EdgeMissed => 1,
            Fault::WatchdogReset => 2,
            Fault::InvalidSettings => 3,
            Fault::ClosedLoop => 4,
            Fault::EdgeCounter => 5,
            Fault::LinkLost => 6,
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            Fault::EdgeMissed => "edge-missed",
            Fault::WatchdogReset => "watchdog-reset",
            Fault::InvalidSettings => "invalid-settings",
            Fault::ClosedLoop => "closed-loop",
            Fault::EdgeCounter => "edge-counter",
            Fault::LinkLost => "link-lost",
        }
    }

    /// Whether the button or a reset request clears it: every fault but a failed self-test.
    pub const fn acknowledgeable(self) -> bool {
        !matches!(self, Fault::EdgeCounter)
    }
}

impl core::fmt::Display for Fault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// What the feeder is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunState {
    Stopped,
    Running,
    /// Soft stop in progress: the amplitude ramps down to idle.
    Stopping,
    /// Halted, with the first fault's cause, until acknowledged.
    Faulted(Fault),
}

/// What the status LED shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Led {
    Off,
    On,
    Blink,
}

/// Something the supervisor reacts to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SupervisorEvent {
    /// The start/stop button was pressed (debounced).
    ButtonPressed,
    /// An explicit start (command line, script). Refused while a fault is latched.
    StartRequested,
    /// An explicit soft stop.
    StopRequested,
    /// An explicit acknowledgement of a latched fault.
    ResetRequested,
    /// An idle period has begun on the output: no motion is being commanded.
    OutputIdle,
    /// The track's part sensor says it is full (`closed_loop::Track`): pause feeding.
    TrackFull,
    /// The track has room again: feed, if running.
    TrackEmpty,
    Fault(Fault),
}

/// What the scheduler must be told after an event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MotionRequest {
    /// Nothing changes.
    Keep,
    /// Soft start (or reverse a soft stop) at the next cycle boundary.
    Start,
    /// Soft stop from the next cycle boundary.
    Stop,
    /// Zero the output now and drop to idle (stop category 0).
    Halt,
    /// Let the cycle in progress end at rest, then idle, without a ramp (stop category 1).
    QuickStop,
}

/// The run/stop/fault state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Supervisor {
    state: RunState,
    /// A controlled fault stop is finishing its cycle: the driver stays enabled until idle.
    braking: bool,
    /// The track is full: while running, the plate rests until it has room.
    track_full: bool,
}

impl Supervisor {
    /// The state after a reset: stopped, or faulted with what power-up found (the watchdog's
    /// reset, a failed self-test).
    pub const fn new(latched: Option<Fault>) -> Self {
        let state = match latched {
            Some(fault) => RunState::Faulted(fault),
            None => RunState::Stopped,
        };
        Self {
            state,
            braking: false,
            track_full: false,
        }
    }

    /// Applies `event` and says what the scheduler must do.
    pub fn handle(&mut self, event: SupervisorEvent) -> MotionRequest {
        use MotionRequest::{Keep, Start, Stop};
        use RunState::{Faulted, Running, Stopped, Stopping};
        if event == SupervisorEvent::OutputIdle {
            self.braking = false;
        }
        // A start into a full track runs without motion until the track has room.
        let feed = if self.track_full { Keep } else { Start };
        let (state, request) = match (self.state, event) {
            (_, SupervisorEvent::Fault(fault)) => return self.fault(fault),
            (state, SupervisorEvent::TrackFull) => {
                let request = match (state, self.track_full) {
                    (Running, false) => Stop,
                    _ => Keep,
                };
                self.track_full = true;
                (state, request)
            }
            (state, SupervisorEvent::TrackEmpty) => {
                let request = match (state, self.track_full) {
                    (Running, true) => Start,
                    _ => Keep,
                };
                self.track_full = false;
                (state, request)
            }
            (Stopped, SupervisorEvent::ButtonPressed) => (Running, feed),
            (Running, SupervisorEvent::ButtonPressed) => (Stopping, Stop),
            (Stopping, SupervisorEvent::ButtonPressed) => (Running, feed),
            (Faulted(fault), SupervisorEvent::ButtonPressed) if fault.acknowledgeable() => {
                (Stopped, Keep)
            }
            (Stopped | Stopping, SupervisorEvent::StartRequested) => (Running, feed),
            (Running | Stopping, SupervisorEvent::StopRequested) => (Stopping, Stop),
            (Faulted(fault), SupervisorEvent::ResetRequested) if fault.acknowledgeable() => {
                (Stopped, Keep)
            }
            (Faulted(fault), SupervisorEvent::ButtonPressed) => (Faulted(fault), Keep),
            (
                state,
                SupervisorEvent::StartRequested
                | SupervisorEvent::StopRequested
                | SupervisorEvent::ResetRequested,
            ) => (state, Keep),
            (Stopping, SupervisorEvent::OutputIdle) => (Stopped, Keep),
            (state, SupervisorEvent::OutputIdle) => (state, Keep),
        };
        self.state = state;
        request
    }

    /// Latches `fault` (the first cause stays, unless the new one cannot be acknowledged and
    /// the first can) and chooses its stop: controlled while the plate moves and the fault
    /// allows it, immediate otherwise.
    fn fault(&mut self, fault: Fault) -> MotionRequest {
        let moving = self.braking || matches!(self.state, RunState::Running | RunState::Stopping);
        let request = match fault.stop_category() {
            StopCategory::Controlled if moving => MotionRequest::QuickStop,
            StopCategory::Soft if moving => MotionRequest::Stop,
            _ => MotionRequest::Halt,
        };
        self.braking = matches!(request, MotionRequest::QuickStop | MotionRequest::Stop);
        let replaces = match self.state {
            RunState::Faulted(latched) => latched.acknowledgeable() && !fault.acknowledgeable(),
            _ => true,
        };
        if replaces {
            self.state = RunState::Faulted(fault);
        }
        request
    }

    pub const fn state(&self) -> RunState {
        self.state
    }

    /// Whether the motor driver may be enabled: while running, ramping down, or finishing the
    /// cycle of a controlled fault stop.
    pub const fn driver_enabled(&self) -> bool {
        self.braking || matches!(self.state, RunState::Running | RunState::Stopping)
    }

    /// Running, but resting because the track is full.
    pub const fn paused(&self) -> bool {
        self.track_full && matches!(self.state, RunState::Running)
    }

    /// Whether a controlled fault stop is still finishing its cycle.
    pub const fn braking(&self) -> bool {
        self.braking
    }

    /// Off when stopped, on while running or ramping down, blinking when faulted.
    pub const fn led(&self) -> Led {
        match self.state {
            RunState::Stopped => Led::Off,
            RunState::Running | RunState::Stopping => Led::On,
            RunState::Faulted(_) => Led::Blink,
        }
    }
}
