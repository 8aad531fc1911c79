//! The command controller: every command by table, the run/stop/fault rules, the recipe store,
//! and properties over arbitrary command sequences and feeder states. The fixtures are here.

#[path = "../common/mod.rs"]
mod common;

use common::machine;

mod commands;
mod configuration;
mod recipes;
mod rules;
mod sequences;

use feeder_shared::configuration::record as config_record;
use feeder_shared::protocol;
use feeder_shared::recipe::{RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{
    Action, ConfigurationStore, Controller, Fault, Outcome, Phase, RecipeSlot, RecipeStore,
    RunState, Settings, Snapshot, WaveformSpec,
};

/// Recipe and configuration records in RAM; `fail` makes every write fail.
#[derive(Debug, Clone, PartialEq)]
struct Memory {
    records: [[u8; RECORD_LEN]; RECIPE_SLOTS],
    configuration: [u8; config_record::RECORD_LEN],
    fail: bool,
}

#[derive(Debug)]
struct WriteFailed;

impl Memory {
    fn erased() -> Self {
        Memory {
            records: [[0xff; RECORD_LEN]; RECIPE_SLOTS],
            configuration: [0xff; config_record::RECORD_LEN],
            fail: false,
        }
    }
}

impl RecipeStore for Memory {
    type Error = WriteFailed;

    fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN] {
        self.records[slot.index()]
    }

    fn write(&mut self, slot: RecipeSlot, record: &[u8; RECORD_LEN]) -> Result<(), WriteFailed> {
        if self.fail {
            return Err(WriteFailed);
        }
        self.records[slot.index()] = *record;
        Ok(())
    }
}

impl ConfigurationStore for Memory {
    type WriteError = WriteFailed;

    fn read_configuration(&mut self) -> [u8; config_record::RECORD_LEN] {
        self.configuration
    }

    fn write_configuration(
        &mut self,
        record: &[u8; config_record::RECORD_LEN],
    ) -> Result<(), WriteFailed> {
        if self.fail {
            return Err(WriteFailed);
        }
        self.configuration = *record;
        Ok(())
    }
}

fn snapshot(state: RunState, phase: Phase, cycles: u64) -> Snapshot {
    Snapshot {
        state,
        phase,
        uptime_ms: 12_345,
        cycles,
        closed_loop: None,
        track: None,
    }
}

fn stopped(cycles: u64) -> Snapshot {
    snapshot(RunState::Stopped, Phase::Stopped, cycles)
}

fn running(cycles: u64) -> Snapshot {
    snapshot(RunState::Running, Phase::Running, cycles)
}

fn faulted(cycles: u64) -> Snapshot {
    snapshot(RunState::Faulted(Fault::EdgeMissed), Phase::Stopped, cycles)
}

fn controller() -> Controller {
    Controller::new(machine(), Settings::DEFAULT).unwrap()
}

fn run(controller: &mut Controller, line: &str, at: &Snapshot, store: &mut Memory) -> Outcome {
    controller.handle(protocol::parse(line), at, store)
}

fn configure(settings: &Settings) -> Action {
    Action::Configure {
        spec: WaveformSpec::from_frequency(settings.frequency_hz, settings.duty, settings.drive),
        plan: settings.validate(&machine()).unwrap().plan,
        ramp_cycles: settings.ramp_cycles,
    }
}
