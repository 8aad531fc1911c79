//! The recipe store: a failed write, a round trip, and every unusable record.

use feeder_shared::recipe;
use feeder_shared::{Action, Controller, DacCalibration, Drive, Machine, Settings};

use crate::common::slot;
use crate::{configure, controller, machine, run, running, stopped, Memory};

#[test]
fn a_failed_write_is_reported_and_changes_nothing() {
    let mut controller = controller();
    let mut store = Memory::erased();
    store.fail = true;
    let outcome = run(&mut controller, "recipe save 2", &stopped(0), &mut store);
    assert!(outcome.reply.as_str().starts_with("ERR 62 "));
    assert_eq!(outcome.action, Action::None);
    assert_eq!(controller.settings(), &Settings::DEFAULT);
}

#[test]
fn recipes_round_trip_and_load_like_a_set() {
    let mut controller = controller();
    let mut store = Memory::erased();
    let at = stopped(0);
    for line in ["set accel 120", "set freq 75", "set duty 0.6", "set ramp 4"] {
        assert!(
            run(&mut controller, line, &at, &mut store).reply.is_ok(),
            "{line}"
        );
    }
    let saved = *controller.settings();
    run(&mut controller, "recipe save 6", &at, &mut store);
    run(&mut controller, "set freq 50", &at, &mut store);
    let list = run(&mut controller, "recipe list", &at, &mut store).reply;
    assert_eq!(
        list.as_str(),
        "OK recipes 0=empty 1=empty 2=empty 3=empty 4=empty 5=empty 6=75Hz/0.6/120m/s2/r4 7=empty"
    );
    // Loading is allowed while running and applied at a cycle boundary.
    let outcome = run(&mut controller, "recipe load 6", &running(9), &mut store);
    assert!(outcome
        .reply
        .as_str()
        .starts_with("OK recipe 6 loaded freq_hz=75 duty=0.6 "));
    assert_eq!(controller.settings(), &saved);
    assert_eq!(outcome.action, configure(&saved));
}

#[test]
fn unusable_records_are_refused_say_why_and_change_nothing() {
    let mut controller = controller();
    let mut store = Memory::erased();
    let at = stopped(0);
    for line in ["set freq 55", "set ramp 4", "recipe save 1"] {
        assert!(
            run(&mut controller, line, &at, &mut store).reply.is_ok(),
            "{line}"
        );
    }
    store.records[1][10] ^= 0x40;
    store.records[2] = recipe::encode(slot(3), &Settings::DEFAULT);
    store.records[3] = recipe::encode(
        slot(3),
        &Settings {
            frequency_hz: 150.0,
            ..Settings::DEFAULT
        },
    );
    let list = run(&mut controller, "recipe list", &at, &mut store).reply;
    assert!(
        list.as_str()
            .starts_with("OK recipes 0=empty 1=corrupt 2=wrong-slot 3=rejected 4=empty"),
        "{}",
        list.as_str()
    );
    let live = *controller.settings();
    assert_ne!(live, Settings::DEFAULT);
    for (slot, reply) in [
        (
            0,
            "ERR 63 recipe 0 not loaded: no recipe saved in this slot; nothing changed",
        ),
        (
            4,
            "ERR 63 recipe 4 not loaded: no recipe saved in this slot; nothing changed",
        ),
        (1, "ERR 64 recipe 1 not loaded: corrupt record: CRC"),
        (
            2,
            "ERR 64 recipe 2 not loaded: record belongs to slot 3, not slot 2; nothing changed",
        ),
        (
            3,
            "ERR 64 recipe 3 not loaded: stored parameters refused: frequency 150 Hz",
        ),
    ] {
        for at in [stopped(0), running(9)] {
            let outcome = run(
                &mut controller,
                &format!("recipe load {slot}"),
                &at,
                &mut store,
            );
            assert!(
                outcome.reply.as_str().starts_with(reply),
                "{}",
                outcome.reply
            );
            assert!(outcome.reply.as_str().ends_with("; nothing changed"));
            assert_eq!(controller.settings(), &live);
            assert_eq!(outcome.action, Action::None);
        }
    }
}

#[test]
fn where_the_closed_loop_runs_a_recipe_it_cannot_hold_is_refused_and_changes_nothing() {
    // The default DAC reaches 224.75 m/s²; the loop keeps room for its drives up to 171.675 m/s².
    let closed_loop = Machine {
        loop_linear_mps2: Some(DacCalibration::DEFAULT.linear_limit_mps2()),
        ..machine()
    };
    let mut controller = Controller::new(closed_loop, Settings::DEFAULT).unwrap();
    let mut store = Memory::erased();
    let strong = Settings {
        drive: Drive::Accel { accel_mps2: 190.0 },
        ..Settings::DEFAULT
    };
    assert!(
        strong.validate(&machine()).is_ok(),
        "within the motor limit"
    );
    store.records[2] = recipe::encode(slot(2), &strong);
    for at in [stopped(0), running(9)] {
        let set = run(&mut controller, "set accel 190", &at, &mut store);
        assert!(set.reply.as_str().starts_with("ERR 56 "), "{}", set.reply);
        let load = run(&mut controller, "recipe load 2", &at, &mut store);
        assert!(
            load.reply.as_str().starts_with(
                "ERR 64 recipe 2 not loaded: stored parameters refused: peak acceleration 190 m/s2 \
                 is more than the closed loop can hold"
            ),
            "{}",
            load.reply
        );
        for outcome in [set, load] {
            assert_eq!(outcome.action, Action::None);
        }
        assert_eq!(controller.settings(), &Settings::DEFAULT);
    }
    let list = run(&mut controller, "recipe list", &stopped(0), &mut store).reply;
    assert!(list.as_str().contains(" 2=rejected "), "{list}");
    let held = run(&mut controller, "set accel 170", &running(9), &mut store);
    assert!(held.reply.as_str().starts_with("OK "), "{}", held.reply);
}
