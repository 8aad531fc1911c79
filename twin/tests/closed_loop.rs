//! The G474's encoder image (`FEEDER_G474_ENCODER_ELF`, built with `hil-trace` and `encoder`
//! by `cargo xtask test`) closes its loop on the plate of `realistic.toml` on the twin: the
//! plate driven from the DAC's latches and gated by PA10, TIM4 counting its encoder for the
//! DMA's samples and captures. The run is judged as `host-sim cosim` judges QEMU's (the plant
//! file's gains within 1 %, every fed cycle's mean within 50 µm of centre, the feed within 1 %
//! of the ideal plate's, the start-up within its bound); every segment takes its level on its
//! tick; and the stack keeps a margin at its deepest.

use std::path::PathBuf;

use feeder_shared::plan::{EDGE_WORK_INSTRUCTIONS, EDGE_WORK_MARGIN};
use feeder_twin::log::LogTable;
use feeder_twin::outputs::{Levels, OutputRecord};
use feeder_twin::plant::{judge, PlantRun};
use feeder_twin::scenario::button_run;
use feeder_twin::Machine;

/// Motion cycles from the start to the stop: the course releases the soft start after about
/// 230 (settle, probe, identification, centring), and the verdict's feed rate takes the last 50
/// before the stop.
const CYCLES: u64 = 450;

/// The stack left at its deepest, bytes at least: room for what this run does not reach at the
/// same moment (a fault's entry on top of the deepest nesting, a longer identification).
const STACK_MARGIN_BYTES: u32 = 8 * 1024;

fn encoder_image() -> PathBuf {
    std::env::var_os("FEEDER_G474_ENCODER_ELF")
        .map(PathBuf::from)
        .expect("FEEDER_G474_ENCODER_ELF names the encoder image (cargo xtask test sets it)")
}

#[test]
#[ignore = "needs the G474 encoder image; run by cargo xtask test"]
fn the_encoder_image_holds_the_realistic_plate() {
    let elf = encoder_image();
    let bytes = std::fs::read(&elf).expect("the image");
    let table = LogTable::load(&bytes).expect("its defmt table");
    let plant = PlantRun::new(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/plants/realistic.toml"),
    )
    .expect("realistic.toml's plate");
    let record = OutputRecord::default();
    let mut machine = Machine::load(&elf, Box::new(plant.outputs(record.clone()))).expect("loads");
    let mut log = Vec::new();
    let outcome = button_run(
        &mut machine,
        table.decoder(),
        &mut log,
        CYCLES,
        &record,
        Levels::Trimmed,
    )
    .expect("runs");
    let log = String::from_utf8(log).expect("a text log");
    assert!(outcome.completed, "{outcome:?}");
    assert!(
        outcome.outputs.problems.is_empty() && outcome.outputs.stray == 0,
        "{:?}",
        outcome.outputs
    );
    assert!(outcome.outputs.matched > 2 * CYCLES as usize);
    let origin = machine.board().output_origin().expect("the output started");
    let report = judge(&log, &plant, origin).expect("the run can be judged");
    assert!(report.passed, "{}", report.text);
    // The loop's trims at each cycle start make the worst edge: within the instructions the
    // segment floor gives an edge, and even with no hit in the ART accelerator within the floor
    // itself (`EDGE_WORK_MARGIN` × `EDGE_WORK_INSTRUCTIONS` × 1.5 cycles).
    let (work, _) = machine.edge_work();
    let wait_states = u64::from(machine.board().flash_wait_states());
    let cycles = work.cycles_without_cache(wait_states);
    assert!(
        work.instructions as f64 <= EDGE_WORK_INSTRUCTIONS
            && cycles as f64 <= EDGE_WORK_MARGIN * EDGE_WORK_INSTRUCTIONS * 1.5,
        "{work:?}: at most {cycles} cycles"
    );
    let (used, size) = machine
        .stack_use()
        .expect("the image names its stack's bounds");
    assert!(
        used + STACK_MARGIN_BYTES <= size,
        "the stack reached {used} of its {size} bytes"
    );
}
