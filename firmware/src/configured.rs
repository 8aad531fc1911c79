//! The configuration this board runs: read from its store once at power-up, before any task
//! starts, and fixed until the next start. Where the board keeps none, or the stored record is
//! missing, corrupt, of another layout or refused, the compiled defaults
//! ([`config::CONFIGURATION`]), with the reason logged.

use core::cell::Cell;

use defmt::{info, warn};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use feeder_shared::configuration::record::{self, LoadError};
use feeder_shared::configuration::{BoardFacts, Configuration};
use feeder_shared::{ConfigurationStore, Machine, RecordError, TickClock};

use crate::config;

static RUNNING: Mutex<CriticalSectionRawMutex, Cell<Configuration>> =
    Mutex::new(Cell::new(config::CONFIGURATION));

/// What this image is, on an output timed by `clock`.
pub const fn facts(clock: TickClock) -> BoardFacts {
    BoardFacts {
        clock,
        output: config::OUTPUT,
        encoder: cfg!(feature = "encoder"),
    }
}

/// Reads the stored configuration for an output timed by `clock` and makes it the one the board
/// runs; the compiled defaults where it is not usable.
#[cfg_attr(
    all(feature = "board-qemu", not(feature = "console")),
    expect(dead_code, reason = "the scripted QEMU images keep no flash")
)]
pub fn at_power_up<S: ConfigurationStore>(store: &mut S, clock: TickClock) -> Configuration {
    let configuration = match record::load(&store.read_configuration(), &facts(clock)) {
        Ok(configuration) => {
            info!("configuration: the one saved on the board");
            configuration
        }
        Err(LoadError::Record(RecordError::Empty)) => {
            info!("configuration: as compiled (none saved)");
            config::CONFIGURATION
        }
        Err(error) => {
            warn!(
                "configuration: as compiled, the saved one is not used: {}",
                error
            );
            config::CONFIGURATION
        }
    };
    RUNNING.lock(|running| running.set(configuration));
    configuration
}

/// The configuration the board runs.
pub fn get() -> Configuration {
    RUNNING.lock(Cell::get)
}

/// The machine every waveform is validated for, on an output timed by `clock`.
pub fn machine(clock: TickClock) -> Machine {
    get().machine(&facts(clock))
}
