//! The run/stop/fault rules: `start` after a fault, and recipes saved only while stopped.

use feeder_shared::control::SETTLE_CYCLES;
use feeder_shared::recipe;
use feeder_shared::{Action, Phase, RunState, Settings};

use crate::common::slot;
use crate::{controller, faulted, run, running, snapshot, stopped, Memory};

#[test]
fn start_is_refused_while_a_fault_is_latched_and_allowed_after_reset() {
    let mut controller = controller();
    let mut store = Memory::erased();
    let at = faulted(40);
    let refused = run(&mut controller, "start", &at, &mut store);
    assert!(refused.reply.as_str().starts_with("ERR 61 "));
    assert_eq!(refused.action, Action::None);
    assert_eq!(
        run(&mut controller, "reset", &at, &mut store).action,
        Action::Reset
    );
    // The snapshot still shows the fault: the reset is on its way to the control loop.
    assert_eq!(
        run(&mut controller, "start", &at, &mut store).action,
        Action::Start
    );
    // Later the snapshot shows a new fault: start is refused again.
    let later = faulted(40 + SETTLE_CYCLES);
    let outcome = run(&mut controller, "start", &later, &mut store);
    assert!(outcome.reply.as_str().starts_with("ERR 61 "));
}

#[test]
fn recipes_are_written_only_while_stopped_and_never_right_after_start() {
    let mut controller = controller();
    let mut store = Memory::erased();
    run(&mut controller, "start", &stopped(10), &mut store);
    // The control loop has not taken the start yet.
    for cycles in 10..10 + SETTLE_CYCLES {
        let outcome = run(
            &mut controller,
            "recipe save 0",
            &stopped(cycles),
            &mut store,
        );
        assert!(outcome.reply.as_str().starts_with("ERR 60 "), "{cycles}");
    }
    assert!(store == Memory::erased());
    let outcome = run(&mut controller, "recipe save 0", &running(20), &mut store);
    assert!(outcome.reply.as_str().starts_with("ERR 60 "));
    run(&mut controller, "stop", &running(30), &mut store);
    let stopping = snapshot(RunState::Stopping, Phase::Stopping, 40);
    let outcome = run(&mut controller, "recipe save 0", &stopping, &mut store);
    assert!(outcome.reply.as_str().starts_with("ERR 60 "));
    let outcome = run(&mut controller, "recipe save 0", &stopped(80), &mut store);
    assert_eq!(outcome.reply.as_str(), "OK recipe 0 saved");
    assert_eq!(
        store.records[0],
        recipe::encode(slot(0), &Settings::DEFAULT)
    );
}
