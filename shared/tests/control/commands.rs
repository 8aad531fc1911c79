//! Every command by table, and what `set` and `status` report.

use feeder_shared::recipe;
use feeder_shared::{Action, Controller, Drive, Fault, Phase, RunState, Settings, Snapshot};

use crate::common::slot;
use crate::{configure, controller, faulted, machine, run, running, snapshot, stopped, Memory};

#[test]
fn refuses_settings_the_machine_cannot_run() {
    let bad = Settings {
        frequency_hz: 20.0,
        ..Settings::DEFAULT
    };
    assert!(Controller::new(machine(), bad).is_err());
}

#[test]
fn every_command_by_table() {
    enum Expect {
        Ok(&'static str),
        Err(u16),
    }
    use Expect::{Err, Ok};
    let slot_4 = recipe::encode(
        slot(4),
        &Settings {
            frequency_hz: 55.0,
            ..Settings::DEFAULT
        },
    );
    // (line, snapshot, reply prefix, action: None, or Some(true) for the settings' Configure)
    let table: &[(&str, Snapshot, Expect, Option<Action>)] = &[
        ("start", stopped(0), Ok("OK starting"), Some(Action::Start)),
        ("start", faulted(0), Err(61), Some(Action::None)),
        ("stop", running(0), Ok("OK stopping"), Some(Action::Stop)),
        ("stop", stopped(0), Ok("OK stopping"), Some(Action::Stop)),
        (
            "reset",
            faulted(0),
            Ok("OK fault cleared"),
            Some(Action::Reset),
        ),
        (
            "reset",
            stopped(0),
            Ok("OK no fault latched"),
            Some(Action::None),
        ),
        (
            "status",
            running(617),
            Ok("OK state=running freq_hz=50 duty=0.586 stroke_mm=2.5 "),
            Some(Action::None),
        ),
        (
            "get freq",
            running(0),
            Ok("OK freq_hz=50"),
            Some(Action::None),
        ),
        (
            "get duty",
            running(0),
            Ok("OK duty=0.586"),
            Some(Action::None),
        ),
        (
            "get stroke",
            running(0),
            Ok("OK stroke_mm=2.5"),
            Some(Action::None),
        ),
        (
            "get accel",
            running(0),
            Ok("OK accel_mps2="),
            Some(Action::None),
        ),
        (
            "get feed",
            running(0),
            Ok("OK feed_mmps="),
            Some(Action::None),
        ),
        (
            "get ramp",
            running(0),
            Ok("OK ramp_cycles=25"),
            Some(Action::None),
        ),
        ("set freq 55", running(0), Ok("OK freq_hz=55 "), None),
        (
            "set duty 0.6",
            running(0),
            Ok("OK freq_hz=50 duty=0.6 "),
            None,
        ),
        (
            "set stroke 2",
            running(0),
            Ok("OK freq_hz=50 duty=0.586 stroke_mm=2 "),
            None,
        ),
        (
            "set accel 100",
            running(0),
            Ok("OK freq_hz=50 duty=0.586 stroke_mm="),
            None,
        ),
        (
            "set feed 30",
            running(0),
            Ok("OK freq_hz=50 duty=0.5"),
            None,
        ),
        ("set ramp 5", running(0), Ok("OK freq_hz=50 "), None),
        ("set ramp 5", faulted(0), Ok("OK freq_hz=50 "), None),
        ("set freq 20", stopped(0), Err(44), Some(Action::None)),
        ("set duty 0.4", stopped(0), Err(42), Some(Action::None)),
        ("set duty 1", stopped(0), Err(43), Some(Action::None)),
        ("set stroke 9", stopped(0), Err(57), Some(Action::None)),
        ("set stroke 4", running(0), Err(57), Some(Action::None)),
        ("set stroke 0", stopped(0), Err(41), Some(Action::None)),
        ("set accel 900", stopped(0), Err(45), Some(Action::None)),
        ("set duty 0,6", running(0), Err(24), Some(Action::None)),
        ("set feed 0.0001", stopped(0), Err(48), Some(Action::None)),
        ("set feed 1e6", stopped(0), Err(53), Some(Action::None)),
        (
            "recipe save 3",
            stopped(0),
            Ok("OK recipe 3 saved"),
            Some(Action::None),
        ),
        (
            "recipe save 3",
            faulted(0),
            Ok("OK recipe 3 saved"),
            Some(Action::None),
        ),
        ("recipe save 3", running(0), Err(60), Some(Action::None)),
        (
            "recipe save 3",
            snapshot(RunState::Stopping, Phase::Stopping, 0),
            Err(60),
            Some(Action::None),
        ),
        (
            "recipe save 3",
            snapshot(RunState::Running, Phase::Stopped, 0),
            Err(60),
            Some(Action::None),
        ),
        (
            "recipe load 4",
            running(0),
            Ok("OK recipe 4 loaded freq_hz=55 "),
            None,
        ),
        ("recipe load 5", running(0), Err(63), Some(Action::None)),
        ("recipe load 5", stopped(0), Err(63), Some(Action::None)),
        (
            "recipe list",
            running(0),
            Ok("OK recipes 0=empty "),
            Some(Action::None),
        ),
        (
            "help",
            running(0),
            Ok("OK commands: start | stop "),
            Some(Action::None),
        ),
        ("?", running(0), Ok("OK commands: "), Some(Action::None)),
        ("launch", running(0), Err(20), Some(Action::None)),
        ("set", running(0), Err(21), Some(Action::None)),
        ("start now", running(0), Err(22), Some(Action::None)),
        ("get speed", running(0), Err(23), Some(Action::None)),
        ("set freq x", running(0), Err(24), Some(Action::None)),
        ("set freq inf", running(0), Err(25), Some(Action::None)),
        ("set freq 50 mm", running(0), Err(26), Some(Action::None)),
        ("set ramp 1.5", running(0), Err(27), Some(Action::None)),
        ("recipe load 8", running(0), Err(28), Some(Action::None)),
    ];
    for (line, at, expect, action) in table {
        let mut controller = controller();
        let mut store = Memory::erased();
        store.records[4] = slot_4;
        let before = controller.settings().to_owned();
        let outcome = run(&mut controller, line, at, &mut store);
        let reply = outcome.reply.as_str();
        match expect {
            Ok(prefix) => assert!(reply.starts_with(prefix), "{line:?}: {reply}"),
            Err(code) => {
                assert!(
                    reply.starts_with(&format!("ERR {code} ")),
                    "{line:?}: {reply}"
                );
                assert_eq!(
                    controller.settings(),
                    &before,
                    "{line:?} changed the settings"
                );
            }
        }
        let expected = action.unwrap_or_else(|| configure(controller.settings()));
        assert_eq!(outcome.action, expected, "{line:?}");
    }
}

#[test]
fn a_stroke_above_what_the_motor_allows_names_the_stroke_and_its_limit() {
    let mut controller = controller();
    let mut store = Memory::erased();
    // 200 m/s² · (0.02 s · (1 − 0.586)/2)² = 3.42792 mm at the defaults (Eq. 5).
    for (line, expected) in [
        (
            "set stroke 6",
            "ERR 57 stroke 0.006 m exceeds the 0.00342792 m that the motor limit of 200 m/s2 \
             allows at 50 Hz and duty cycle 0.586; nothing changed",
        ),
        (
            "set stroke 3.5",
            "ERR 57 stroke 0.0035 m exceeds the 0.00342792 m that the motor limit of 200 m/s2 \
             allows at 50 Hz and duty cycle 0.586; nothing changed",
        ),
    ] {
        let outcome = run(&mut controller, line, &running(0), &mut store);
        assert_eq!(outcome.reply.as_str(), expected, "{line:?}");
        assert_eq!(controller.settings(), &Settings::DEFAULT);
        assert_eq!(outcome.action, Action::None);
    }
    let accepted = run(&mut controller, "set stroke 3.4", &running(0), &mut store);
    assert!(accepted
        .reply
        .as_str()
        .starts_with("OK freq_hz=50 duty=0.586 stroke_mm=3.4 "));
}

#[test]
fn set_is_applied_through_configure_and_reported_by_get() {
    let mut controller = controller();
    let mut store = Memory::erased();
    let at = running(100);
    let outcome = run(&mut controller, "set freq 55", &at, &mut store);
    assert_eq!(controller.settings().frequency_hz, 55.0);
    match outcome.action {
        Action::Configure {
            spec,
            plan,
            ramp_cycles,
        } => {
            assert!((spec.period_s - 1.0 / 55.0).abs() < 1e-15);
            assert_eq!(plan.waveform.period_s, spec.period_s);
            assert_eq!(plan.period_ticks, 18_182, "1 MHz / 55 Hz, rounded");
            assert_eq!(spec.duty, Settings::DEFAULT.duty);
            assert_eq!(ramp_cycles, Settings::DEFAULT.ramp_cycles);
        }
        other => panic!("{other:?}"),
    }
    let reply = run(&mut controller, "get freq", &at, &mut store).reply;
    assert_eq!(reply.as_str(), "OK freq_hz=55");
    run(&mut controller, "set feed 30", &at, &mut store);
    let feed = run(&mut controller, "get feed", &at, &mut store).reply;
    assert_eq!(
        feed.as_str(),
        "OK feed_mmps=30",
        "the inverse model hits the target"
    );
    run(&mut controller, "set accel 120", &at, &mut store);
    assert_eq!(
        controller.settings().drive,
        Drive::Accel { accel_mps2: 120.0 }
    );
}

#[test]
fn status_reports_the_snapshot_and_the_settings() {
    let mut controller = controller();
    let mut store = Memory::erased();
    let at = Snapshot {
        state: RunState::Faulted(Fault::WatchdogReset),
        phase: Phase::Stopped,
        uptime_ms: 61_005,
        cycles: 3050,
        closed_loop: None,
        track: None,
    };
    let reply = run(&mut controller, "status", &at, &mut store).reply;
    let text = reply.as_str();
    assert!(text.starts_with("OK state=fault freq_hz=50 duty=0.586 stroke_mm=2.5 "));
    assert!(text.contains(" ramp_cycles=25 feed_mmps="), "{text}");
    assert!(
        text.ends_with(" uptime_s=61.005 cycles=3050 fault=watchdog-reset"),
        "{text}"
    );
    let starting = snapshot(RunState::Running, Phase::Starting, 7);
    let reply = run(&mut controller, "status", &starting, &mut store).reply;
    assert!(reply.as_str().starts_with("OK state=starting "));
    assert!(reply.as_str().ends_with(" cycles=7 fault=none"));
}
