//! Run/stop/fault supervision: hand-written sequences and invariants over all short sequences.

use feeder_shared::{
    Fault, Led, MotionRequest, RunState, StopCategory, Supervisor, SupervisorEvent,
};

use SupervisorEvent::{
    ButtonPressed as Press, OutputIdle as Idle, ResetRequested as Reset, StartRequested as Start,
    StopRequested as Stop, TrackEmpty as Empty, TrackFull as Full,
};

#[test]
fn comes_up_stopped_with_the_driver_disabled() {
    let supervisor = Supervisor::new(None);
    assert_eq!(supervisor.state(), RunState::Stopped);
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.led(), Led::Off);
}

#[test]
fn comes_up_faulted_after_a_watchdog_reset() {
    let mut supervisor = Supervisor::new(Some(Fault::WatchdogReset));
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::WatchdogReset));
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.led(), Led::Blink);
    assert_eq!(supervisor.handle(Press), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Stopped);
}

#[test]
fn start_soft_stop_and_idle() {
    let mut supervisor = Supervisor::new(None);
    assert_eq!(supervisor.handle(Press), MotionRequest::Start);
    assert_eq!(supervisor.state(), RunState::Running);
    assert!(supervisor.driver_enabled());
    assert_eq!(supervisor.led(), Led::On);
    // The first idle period after a start request is still playing: keep running.
    assert_eq!(supervisor.handle(Idle), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Running);

    assert_eq!(supervisor.handle(Press), MotionRequest::Stop);
    assert_eq!(supervisor.state(), RunState::Stopping);
    assert!(
        supervisor.driver_enabled(),
        "the driver carries the ramp down"
    );
    assert_eq!(supervisor.led(), Led::On);

    assert_eq!(supervisor.handle(Idle), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Stopped);
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.led(), Led::Off);
}

#[test]
fn a_press_during_the_soft_stop_starts_again() {
    let mut supervisor = Supervisor::new(None);
    supervisor.handle(Press);
    supervisor.handle(Press);
    assert_eq!(supervisor.handle(Press), MotionRequest::Start);
    assert_eq!(supervisor.state(), RunState::Running);
}

#[test]
fn faults_halt_at_once_and_latch_the_first_cause() {
    let mut supervisor = Supervisor::new(None);
    supervisor.handle(Press);
    let edge = SupervisorEvent::Fault(Fault::EdgeMissed);
    assert_eq!(supervisor.handle(edge), MotionRequest::Halt);
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::EdgeMissed));
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.led(), Led::Blink);

    // Nothing moves any more: a later controlled fault has nothing to finish.
    let settings = SupervisorEvent::Fault(Fault::InvalidSettings);
    assert_eq!(supervisor.handle(settings), MotionRequest::Halt);
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.handle(Idle), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::EdgeMissed));

    // The first press acknowledges only; the second starts.
    assert_eq!(supervisor.handle(Press), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Stopped);
    assert!(!supervisor.driver_enabled());
    assert_eq!(supervisor.handle(Press), MotionRequest::Start);
}

#[test]
fn a_controlled_fault_finishes_the_cycle_with_the_driver_on_then_disables_it() {
    let mut supervisor = Supervisor::new(None);
    supervisor.handle(Start);
    let settings = SupervisorEvent::Fault(Fault::InvalidSettings);
    assert_eq!(supervisor.handle(settings), MotionRequest::QuickStop);
    assert_eq!(
        supervisor.state(),
        RunState::Faulted(Fault::InvalidSettings)
    );
    assert!(
        supervisor.driver_enabled(),
        "the driver carries the cycle to rest"
    );
    assert_eq!(supervisor.led(), Led::Blink);
    // A missed edge while braking leaves nothing to trust: the stop becomes immediate.
    let mut escalated = supervisor;
    assert_eq!(
        escalated.handle(SupervisorEvent::Fault(Fault::EdgeMissed)),
        MotionRequest::Halt
    );
    assert!(!escalated.driver_enabled());
    assert_eq!(escalated.state(), RunState::Faulted(Fault::InvalidSettings));
    // Otherwise the first idle period ends the stop.
    assert_eq!(supervisor.handle(Idle), MotionRequest::Keep);
    assert!(!supervisor.driver_enabled());
    assert_eq!(
        supervisor.state(),
        RunState::Faulted(Fault::InvalidSettings)
    );
    assert_eq!(supervisor.handle(Reset), MotionRequest::Keep);
    assert_eq!(supervisor.handle(Start), MotionRequest::Start);
    assert!(supervisor.driver_enabled());
}

#[test]
fn a_reset_during_a_controlled_stop_keeps_the_driver_until_idle() {
    let mut supervisor = Supervisor::new(None);
    supervisor.handle(Press);
    supervisor.handle(SupervisorEvent::Fault(Fault::InvalidSettings));
    supervisor.handle(Reset);
    assert_eq!(supervisor.state(), RunState::Stopped);
    assert!(
        supervisor.driver_enabled(),
        "the cycle in progress still needs it"
    );
    supervisor.handle(Idle);
    assert!(!supervisor.driver_enabled());
}

#[test]
fn explicit_commands_start_stop_and_reset() {
    let mut supervisor = Supervisor::new(None);
    assert_eq!(supervisor.handle(Stop), MotionRequest::Keep);
    assert_eq!(supervisor.handle(Start), MotionRequest::Start);
    assert_eq!(supervisor.handle(Start), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Running);
    assert_eq!(supervisor.handle(Stop), MotionRequest::Stop);
    assert_eq!(supervisor.state(), RunState::Stopping);
    assert_eq!(supervisor.handle(Start), MotionRequest::Start);
    assert_eq!(supervisor.handle(Reset), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Running);
    supervisor.handle(SupervisorEvent::Fault(Fault::EdgeMissed));
    // A latched fault refuses an explicit start; only a reset clears it.
    assert_eq!(supervisor.handle(Start), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Faulted(Fault::EdgeMissed));
    assert_eq!(supervisor.handle(Reset), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Stopped);
    assert_eq!(supervisor.handle(Start), MotionRequest::Start);
}

const EVENTS: [SupervisorEvent; 12] = [
    Press,
    Idle,
    Start,
    Stop,
    Reset,
    SupervisorEvent::Fault(Fault::EdgeMissed),
    SupervisorEvent::Fault(Fault::WatchdogReset),
    SupervisorEvent::Fault(Fault::InvalidSettings),
    SupervisorEvent::Fault(Fault::ClosedLoop),
    SupervisorEvent::Fault(Fault::EdgeCounter),
    Full,
    Empty,
];

/// Every sequence of up to six events from every power-up state: stopped, after the
/// watchdog's reset, after a failed self-test.
fn for_all_sequences(
    mut check: impl FnMut(&Supervisor, SupervisorEvent, MotionRequest, &Supervisor),
) {
    const LENGTH: u32 = 6;
    for latched in [None, Some(Fault::WatchdogReset), Some(Fault::EdgeCounter)] {
        for code in 0..EVENTS.len().pow(LENGTH) {
            let mut supervisor = Supervisor::new(latched);
            let mut rest = code;
            for _ in 0..LENGTH {
                let event = EVENTS[rest % EVENTS.len()];
                rest /= EVENTS.len();
                let before = supervisor;
                let request = supervisor.handle(event);
                check(&before, event, request, &supervisor);
            }
        }
    }
}

#[test]
fn the_driver_is_enabled_only_while_running_ramping_down_or_braking() {
    for_all_sequences(|before, event, request, after| {
        let moving = matches!(after.state(), RunState::Running | RunState::Stopping);
        // Braking: a controlled stop was asked for and no idle period or immediate stop has
        // ended it since.
        let braking = match event {
            SupervisorEvent::Fault(_) => request == MotionRequest::QuickStop,
            Idle => false,
            _ => before.braking(),
        };
        assert_eq!(after.braking(), braking);
        assert_eq!(after.driver_enabled(), moving || braking);
        assert_eq!(after.led() == Led::On, moving);
        assert_eq!(
            after.led() == Led::Blink,
            matches!(after.state(), RunState::Faulted(_))
        );
    });
}

#[test]
fn every_fault_stops_in_its_category_and_only_a_press_or_start_starts() {
    for_all_sequences(|before, event, request, after| {
        if let SupervisorEvent::Fault(fault) = event {
            let was_moving = before.driver_enabled();
            let controlled = fault.stop_category() == StopCategory::Controlled && was_moving;
            if controlled {
                assert_eq!(request, MotionRequest::QuickStop);
                assert!(after.driver_enabled());
            } else {
                assert_eq!(request, MotionRequest::Halt);
                assert!(!after.driver_enabled());
            }
        }
        if request == MotionRequest::Start {
            assert!(event == Press || event == Start || event == Empty);
            assert!(
                !matches!(before.state(), RunState::Faulted(_)),
                "a fault needs acknowledging"
            );
            assert!(!after.paused(), "a full track is not fed");
        }
        if event == Empty && request == MotionRequest::Start {
            assert!(before.paused(), "only a paused feeder resumes by itself");
        }
        if matches!(request, MotionRequest::Halt | MotionRequest::QuickStop) {
            assert!(matches!(after.state(), RunState::Faulted(_)));
        }
    });
}

#[test]
fn a_fault_is_left_only_by_a_press_or_reset_and_only_to_stopped() {
    for_all_sequences(|before, event, _, after| {
        if let RunState::Faulted(first) = before.state() {
            match after.state() {
                RunState::Faulted(latched) => assert!(
                    latched == first
                        || (first.acknowledgeable()
                            && !latched.acknowledgeable()
                            && event == SupervisorEvent::Fault(latched)),
                    "{first:?} became {latched:?} on {event:?}"
                ),
                RunState::Stopped => {
                    assert!(event == Press || event == Reset);
                    assert!(first.acknowledgeable(), "{first:?} acknowledged");
                }
                other => panic!("left a fault to {other:?}"),
            }
        }
    });
}

/// A failed self-test (the edge counter's) is never left, whatever comes after it, and the
/// driver is never enabled once it is latched.
#[test]
fn a_failed_self_test_stays_whatever_the_operator_does() {
    for_all_sequences(|before, _, request, after| {
        if before.state() == RunState::Faulted(Fault::EdgeCounter) {
            assert_eq!(after.state(), RunState::Faulted(Fault::EdgeCounter));
            assert!(!after.driver_enabled());
            assert_ne!(request, MotionRequest::Start);
        }
    });
}

/// Track control: a full track pauses a running feeder with a soft stop and the feeder resumes
/// when the track has room; a start into a full track waits for room; an operator's stop while
/// paused stays a stop.
#[test]
fn a_full_track_pauses_the_feeder_until_it_has_room() {
    let mut supervisor = Supervisor::new(None);
    assert_eq!(supervisor.handle(Start), MotionRequest::Start);
    assert_eq!(supervisor.handle(Full), MotionRequest::Stop);
    assert!(supervisor.paused());
    assert_eq!(supervisor.state(), RunState::Running);
    assert_eq!(supervisor.handle(Full), MotionRequest::Keep);
    assert_eq!(supervisor.handle(Idle), MotionRequest::Keep);
    assert_eq!(supervisor.handle(Empty), MotionRequest::Start);
    assert!(!supervisor.paused());

    assert_eq!(supervisor.handle(Full), MotionRequest::Stop);
    assert_eq!(supervisor.handle(Stop), MotionRequest::Stop);
    assert_eq!(supervisor.handle(Idle), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Stopped);
    assert_eq!(supervisor.handle(Empty), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Stopped);

    assert_eq!(supervisor.handle(Full), MotionRequest::Keep);
    assert_eq!(supervisor.handle(Press), MotionRequest::Keep);
    assert_eq!(supervisor.state(), RunState::Running);
    assert!(supervisor.paused());
    assert_eq!(supervisor.handle(Empty), MotionRequest::Start);
}
