//! The link watchdog: a link that runs the feeder (the Modbus master, or the console where its
//! watchdog is on) must keep speaking. It is armed when the link starts the feeder and
//! disarmed when the feeder stops; armed, a silence longer than the configured timeout fires
//! it once, and the transport then latches [`crate::Fault::LinkLost`], which stops the plate
//! softly and keeps it stopped until the fault is acknowledged.

/// The link watchdog of one link; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkWatchdog {
    /// The longest silence, ms; 0: never fires.
    timeout_ms: u64,
    /// When the link was last heard, ms.
    heard_ms: u64,
    armed: bool,
}

impl LinkWatchdog {
    /// A watchdog that fires after `timeout_ms` of silence, never with 0.
    pub const fn new(timeout_ms: u16) -> Self {
        Self {
            timeout_ms: timeout_ms as u64,
            heard_ms: 0,
            armed: false,
        }
    }

    /// The link spoke at `now_ms` (a frame for this board, a command line).
    pub fn heard(&mut self, now_ms: u64) {
        self.heard_ms = now_ms;
    }

    /// The link started the feeder at `now_ms`: silence from now on counts.
    pub fn started(&mut self, now_ms: u64) {
        self.heard_ms = now_ms;
        self.armed = self.timeout_ms > 0;
    }

    /// Whether it is armed.
    pub const fn armed(&self) -> bool {
        self.armed
    }

    /// The time at which it fires if the link stays silent, ms.
    pub const fn deadline_ms(&self) -> Option<u64> {
        match self.armed {
            true => Some(self.heard_ms + self.timeout_ms),
            false => None,
        }
    }

    /// Checks at `now_ms` with the feeder `running` (started and not yet stopping or faulted):
    /// true once when an armed watchdog's silence has run out. A stopped feeder disarms it.
    pub fn expired(&mut self, now_ms: u64, running: bool) -> bool {
        if !running {
            self.armed = false;
        }
        let fired = self
            .deadline_ms()
            .is_some_and(|deadline_ms| now_ms > deadline_ms);
        if fired {
            self.armed = false;
        }
        fired
    }
}
