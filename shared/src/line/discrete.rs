//! The discrete lines of a production line: a release input that runs the feeder while it is
//! on, two recipe-select inputs read when it turns on, and the ready and fault outputs.
//!
//! The release input is debounced: a level counts once it has held for the debounce time.
//! Turning on loads the selected recipe (none selected: the settings stay) and starts with a
//! soft start; turning off stops softly. Both are the console's commands, checked by the same
//! rules: a start while a fault is latched is refused, and a recipe that cannot be loaded
//! refuses the start. The outputs follow the supervisor: ready while no fault is latched (a
//! broken wire reads as not ready), fault while one is, until it is acknowledged.

use crate::protocol::Command;
use crate::recipe::RecipeSlot;
use crate::supervisor::RunState;

/// The recipe-select inputs: both off keeps the settings, the others select recipes 1 to 3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecipeSelect {
    pub bit0: bool,
    pub bit1: bool,
}

impl RecipeSelect {
    /// The recipe slot selected, none for both off.
    pub fn slot(self) -> Option<RecipeSlot> {
        RecipeSlot::new(u8::from(self.bit0) | u8::from(self.bit1) << 1)
            .filter(|slot| slot.index() > 0)
    }
}

/// The release input's state; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineInputs {
    debounce_ms: u64,
    /// The debounced level.
    released: bool,
    /// A level that differs from it, and since when, ms.
    changing: Option<(bool, u64)>,
}

/// What a change of the release input asks for, in order.
pub type LineCommands = heapless::Vec<Command, 2>;

impl LineInputs {
    /// The input at power-up: off (its pull-down holds it so when nothing drives it).
    pub const fn new(debounce_ms: u64) -> Self {
        Self {
            debounce_ms,
            released: false,
            changing: None,
        }
    }

    /// The debounced release level.
    pub const fn released(&self) -> bool {
        self.released
    }

    /// The release input reads `release` at `now_ms`, the select inputs `select`: the commands
    /// a debounced change makes (none while the level holds or bounces).
    pub fn sample(&mut self, release: bool, select: RecipeSelect, now_ms: u64) -> LineCommands {
        let mut commands = LineCommands::new();
        if release == self.released {
            self.changing = None;
            return commands;
        }
        let since_ms = match self.changing {
            Some((level, since_ms)) if level == release => since_ms,
            _ => {
                self.changing = Some((release, now_ms));
                now_ms
            }
        };
        if now_ms.saturating_sub(since_ms) < self.debounce_ms {
            return commands;
        }
        self.released = release;
        self.changing = None;
        // Two commands at most: room by construction.
        if release {
            if let Some(slot) = select.slot() {
                let _ = commands.push(Command::RecipeLoad(slot));
            }
            let _ = commands.push(Command::Start);
        } else {
            let _ = commands.push(Command::Stop);
        }
        commands
    }
}

/// The levels of the ready and fault outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LineOutputs {
    pub ready: bool,
    pub fault: bool,
}

impl LineOutputs {
    /// The outputs in supervisor state `state`.
    pub const fn of(state: RunState) -> Self {
        let fault = matches!(state, RunState::Faulted(_));
        Self {
            ready: !fault,
            fault,
        }
    }
}
