//! The production line's side of the feeder besides Modbus: the link watchdog, the debounced
//! release and recipe-select inputs, the ready and fault outputs, and what the supervisor does
//! with a lost link.

use feeder_shared::line::{LineInputs, LineOutputs, LinkWatchdog, RecipeSelect};
use feeder_shared::{
    Command, Fault, Led, MotionRequest, RecipeSlot, RunState, StopCategory, Supervisor,
    SupervisorEvent,
};

// ---------------------------------------------------------------------------------------------
// The link watchdog.

#[test]
fn an_unarmed_watchdog_never_fires() {
    let mut watchdog = LinkWatchdog::new(500);
    assert!(!watchdog.armed());
    assert_eq!(watchdog.deadline_ms(), None);
    for now_ms in [0, 499, 500, 501, 10_000, u64::MAX / 2] {
        assert!(!watchdog.expired(now_ms, true), "{now_ms}");
    }
    // Hearing the link does not arm it: only a start by the link does.
    watchdog.heard(1_000);
    assert!(!watchdog.expired(100_000, true));
}

#[test]
fn an_armed_watchdog_fires_once_after_the_timeout_while_running() {
    let mut watchdog = LinkWatchdog::new(500);
    watchdog.started(1_000);
    assert!(watchdog.armed());
    assert_eq!(watchdog.deadline_ms(), Some(1_500));
    assert!(!watchdog.expired(1_200, true));
    assert!(
        !watchdog.expired(1_500, true),
        "a silence of exactly the timeout is allowed"
    );
    assert!(watchdog.expired(1_501, true), "longer than the timeout");
    assert!(!watchdog.armed());
    for now_ms in [1_502, 2_000, 100_000] {
        assert!(!watchdog.expired(now_ms, true), "once only: {now_ms}");
    }
    // A new start arms it again.
    watchdog.started(200_000);
    assert!(watchdog.expired(200_501, true));
}

#[test]
fn hearing_the_link_postpones_the_deadline() {
    let mut watchdog = LinkWatchdog::new(500);
    watchdog.started(0);
    for now_ms in (400..=4_000).step_by(400) {
        watchdog.heard(now_ms);
        assert!(!watchdog.expired(now_ms + 499, true), "{now_ms}");
    }
    assert_eq!(watchdog.deadline_ms(), Some(4_500));
    assert!(!watchdog.expired(4_500, true));
    assert!(watchdog.expired(4_501, true));
}

#[test]
fn a_stopped_feeder_disarms_the_watchdog() {
    let mut watchdog = LinkWatchdog::new(500);
    watchdog.started(0);
    assert!(
        !watchdog.expired(100, false),
        "stopped (or stopping, or faulted)"
    );
    assert!(!watchdog.armed());
    assert!(
        !watchdog.expired(10_000, true),
        "running again without the link's start"
    );
    // A silence that has run out while the feeder stopped does not fire.
    watchdog.started(20_000);
    assert!(!watchdog.expired(30_000, false));
    assert!(!watchdog.expired(30_001, true));
}

#[test]
fn a_timeout_of_0_never_fires() {
    let mut watchdog = LinkWatchdog::new(0);
    watchdog.started(0);
    assert!(!watchdog.armed());
    for now_ms in [0, 1, 1_000, u64::MAX / 2] {
        assert!(!watchdog.expired(now_ms, true), "{now_ms}");
    }
}

#[test]
fn the_longest_timeout_fires_after_65535_ms() {
    let mut watchdog = LinkWatchdog::new(u16::MAX);
    watchdog.started(5);
    assert!(!watchdog.expired(5 + 65_535, true));
    assert!(watchdog.expired(5 + 65_536, true));
}

// ---------------------------------------------------------------------------------------------
// The release and recipe-select inputs.

const DEBOUNCE_MS: u64 = 20;

const NONE: RecipeSelect = RecipeSelect {
    bit0: false,
    bit1: false,
};

fn select(bit1: bool, bit0: bool) -> RecipeSelect {
    RecipeSelect { bit0, bit1 }
}

fn slot(number: u8) -> RecipeSlot {
    RecipeSlot::new(number).unwrap()
}

/// Samples `release` every millisecond from `from_ms` to `to_ms`: the commands, with when.
fn hold(
    inputs: &mut LineInputs,
    release: bool,
    selected: RecipeSelect,
    from_ms: u64,
    to_ms: u64,
) -> Vec<(u64, Vec<Command>)> {
    (from_ms..=to_ms)
        .filter_map(|now_ms| {
            let commands = inputs.sample(release, selected, now_ms);
            (!commands.is_empty()).then(|| (now_ms, commands.to_vec()))
        })
        .collect()
}

#[test]
fn the_recipe_select_inputs_choose_recipes_1_to_3() {
    assert_eq!(NONE.slot(), None);
    assert_eq!(select(false, true).slot(), Some(slot(1)));
    assert_eq!(select(true, false).slot(), Some(slot(2)));
    assert_eq!(select(true, true).slot(), Some(slot(3)));
}

#[test]
fn the_release_input_is_off_at_power_up() {
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    assert!(!inputs.released());
    assert!(hold(&mut inputs, false, NONE, 0, 1_000).is_empty());
}

#[test]
fn a_held_rise_starts_once_the_debounce_time_has_passed() {
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    let commands = hold(&mut inputs, true, NONE, 100, 1_000);
    assert_eq!(commands, [(100 + DEBOUNCE_MS, vec![Command::Start])]);
    assert!(inputs.released());
}

#[test]
fn a_rise_with_a_recipe_selected_loads_it_and_starts() {
    for (selected, number) in [
        (select(false, true), 1),
        (select(true, false), 2),
        (select(true, true), 3),
    ] {
        let mut inputs = LineInputs::new(DEBOUNCE_MS);
        let commands = hold(&mut inputs, true, selected, 0, 500);
        assert_eq!(
            commands,
            [(
                DEBOUNCE_MS,
                vec![Command::RecipeLoad(slot(number)), Command::Start]
            )],
            "{selected:?}"
        );
    }
}

#[test]
fn the_selection_is_read_when_the_release_turns_on() {
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    assert!(inputs.sample(true, NONE, 0).is_empty());
    // The selection changes while the rise debounces: the one at the moment it counts is used.
    let commands = inputs.sample(true, select(true, false), DEBOUNCE_MS);
    assert_eq!(commands, [Command::RecipeLoad(slot(2)), Command::Start]);
    // Changing it while running does nothing.
    assert!(hold(&mut inputs, true, select(true, true), 21, 500).is_empty());
}

#[test]
fn a_held_fall_stops() {
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    hold(&mut inputs, true, NONE, 0, 100);
    let commands = hold(&mut inputs, false, select(true, true), 200, 1_000);
    assert_eq!(commands, [(200 + DEBOUNCE_MS, vec![Command::Stop])]);
    assert!(!inputs.released());
}

#[test]
fn bounces_shorter_than_the_debounce_time_do_nothing() {
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    // On for 19 ms, off for 1 ms, over and over: never on for the debounce time.
    for period in 0..50 {
        let start_ms = period * 20;
        assert!(hold(&mut inputs, true, NONE, start_ms, start_ms + 18).is_empty());
        assert!(inputs.sample(false, NONE, start_ms + 19).is_empty());
    }
    assert!(!inputs.released());

    // And the same around a released input: no stop.
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    hold(&mut inputs, true, NONE, 0, 100);
    for period in 0..50 {
        let start_ms = 200 + period * 20;
        assert!(hold(&mut inputs, false, NONE, start_ms, start_ms + 18).is_empty());
        assert!(inputs.sample(true, NONE, start_ms + 19).is_empty());
    }
    assert!(inputs.released());
}

#[test]
fn a_bounce_restarts_the_debounce_time() {
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    assert!(inputs.sample(true, NONE, 0).is_empty());
    assert!(inputs.sample(true, NONE, 15).is_empty());
    assert!(inputs.sample(false, NONE, 16).is_empty());
    assert!(inputs.sample(true, NONE, 17).is_empty());
    assert!(
        inputs.sample(true, NONE, 36).is_empty(),
        "19 ms since the bounce"
    );
    assert_eq!(inputs.sample(true, NONE, 37), [Command::Start]);
}

#[test]
fn sampled_seldom_a_change_counts_at_the_sample_after_the_debounce_time() {
    let mut inputs = LineInputs::new(DEBOUNCE_MS);
    assert!(inputs.sample(true, NONE, 1_000).is_empty());
    assert_eq!(inputs.sample(true, NONE, 1_050), [Command::Start]);
    assert!(inputs.sample(false, NONE, 2_000).is_empty());
    assert_eq!(inputs.sample(false, NONE, 2_050), [Command::Stop]);
}

// ---------------------------------------------------------------------------------------------
// The ready and fault outputs.

#[test]
fn ready_while_no_fault_is_latched_and_fault_while_one_is() {
    let ready = LineOutputs {
        ready: true,
        fault: false,
    };
    for state in [RunState::Stopped, RunState::Running, RunState::Stopping] {
        assert_eq!(LineOutputs::of(state), ready, "{state:?}");
    }
    for fault in Fault::ALL {
        assert_eq!(
            LineOutputs::of(RunState::Faulted(fault)),
            LineOutputs {
                ready: false,
                fault: true
            },
            "{fault}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// A lost link, as the supervisor handles it.

#[test]
fn the_fault_codes_are_1_to_6_in_the_order_of_all() {
    let codes: Vec<u16> = Fault::ALL.iter().map(|fault| fault.code()).collect();
    assert_eq!(codes, [1, 2, 3, 4, 5, 6]);
    assert_eq!(Fault::LinkLost.code(), 6);
    assert_eq!(Fault::EdgeMissed.code(), 1);
    assert_eq!(Fault::LinkLost.name(), "link-lost");
}

#[test]
fn a_lost_link_stops_softly_and_is_acknowledgeable() {
    assert_eq!(Fault::LinkLost.stop_category(), StopCategory::Soft);
    assert!(Fault::LinkLost.acknowledgeable());
}

#[test]
fn a_link_lost_while_running_ramps_down_and_latches() {
    let mut supervisor = Supervisor::new(None);
    assert_eq!(
        supervisor.handle(SupervisorEvent::StartRequested),
        MotionRequest::Start
    );
    assert_eq!(
        supervisor.handle(SupervisorEvent::Fault(Fault::LinkLost)),
        MotionRequest::Stop,
        "a soft stop, with its ramp"
    );
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::LinkLost));
    assert_eq!(supervisor.led(), Led::Blink);
    assert!(
        supervisor.driver_enabled(),
        "the driver carries the ramp down"
    );

    // A start is refused while the fault is latched, and the ramp goes on.
    assert_eq!(
        supervisor.handle(SupervisorEvent::StartRequested),
        MotionRequest::Keep
    );
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::LinkLost));
    assert!(supervisor.driver_enabled());

    // The output reaches idle: the driver is disabled, the fault stays.
    assert_eq!(
        supervisor.handle(SupervisorEvent::OutputIdle),
        MotionRequest::Keep
    );
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::LinkLost));
    assert_eq!(
        supervisor.handle(SupervisorEvent::StartRequested),
        MotionRequest::Keep
    );
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::LinkLost));

    // Acknowledged, it starts again.
    assert_eq!(
        supervisor.handle(SupervisorEvent::ResetRequested),
        MotionRequest::Keep
    );
    assert_eq!(supervisor.state(), RunState::Stopped);
    assert_eq!(
        supervisor.handle(SupervisorEvent::StartRequested),
        MotionRequest::Start
    );
    assert_eq!(supervisor.state(), RunState::Running);
}

#[test]
fn a_link_lost_while_stopped_halts() {
    let mut supervisor = Supervisor::new(None);
    assert_eq!(
        supervisor.handle(SupervisorEvent::Fault(Fault::LinkLost)),
        MotionRequest::Halt
    );
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::LinkLost));
    assert!(!supervisor.driver_enabled());
}

#[test]
fn a_link_lost_during_a_soft_stop_keeps_ramping_down() {
    let mut supervisor = Supervisor::new(None);
    supervisor.handle(SupervisorEvent::StartRequested);
    assert_eq!(
        supervisor.handle(SupervisorEvent::StopRequested),
        MotionRequest::Stop
    );
    assert_eq!(
        supervisor.handle(SupervisorEvent::Fault(Fault::LinkLost)),
        MotionRequest::Stop
    );
    assert!(supervisor.driver_enabled());
    supervisor.handle(SupervisorEvent::OutputIdle);
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::LinkLost));
}

#[test]
fn a_worse_fault_during_the_ramp_down_stops_at_once() {
    let mut supervisor = Supervisor::new(None);
    supervisor.handle(SupervisorEvent::StartRequested);
    supervisor.handle(SupervisorEvent::Fault(Fault::LinkLost));
    assert_eq!(
        supervisor.handle(SupervisorEvent::Fault(Fault::EdgeMissed)),
        MotionRequest::Halt
    );
    assert!(!supervisor.driver_enabled());
    assert_eq!(
        supervisor.state(),
        RunState::Faulted(Fault::LinkLost),
        "the first cause stays latched"
    );
}

#[test]
fn the_watchdog_the_supervisor_and_the_outputs_together() {
    // The link starts the feeder, then falls silent.
    let mut watchdog = LinkWatchdog::new(1_000);
    let mut supervisor = Supervisor::new(None);
    supervisor.handle(SupervisorEvent::StartRequested);
    watchdog.started(0);
    let mut fired_at = None;
    for now_ms in (0..5_000).step_by(10) {
        let running = supervisor.state() == RunState::Running;
        if watchdog.expired(now_ms, running) {
            assert_eq!(fired_at, None, "fires once");
            fired_at = Some(now_ms);
            assert_eq!(
                supervisor.handle(SupervisorEvent::Fault(Fault::LinkLost)),
                MotionRequest::Stop
            );
        }
    }
    assert_eq!(fired_at, Some(1_010));
    assert_eq!(
        LineOutputs::of(supervisor.state()),
        LineOutputs {
            ready: false,
            fault: true
        }
    );
}
