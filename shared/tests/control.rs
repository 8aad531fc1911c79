//! The command controller: every command by table, the run/stop/fault rules, the recipe store,
//! and properties over arbitrary command sequences and feeder states.

use feeder_shared::control::SETTLE_CYCLES;
use feeder_shared::protocol::{self, REPLY_CAPACITY};
use feeder_shared::recipe::{self, RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{
    Action, Command, Controller, Drive, Fault, Friction, Limits, LineAssembler, Machine, Outcome,
    Param, Phase, RecipeSlot, RecipeStore, RunState, Setting, Settings, Snapshot, TickClock,
    WaveformSpec,
};
use proptest::prelude::*;

fn machine() -> Machine {
    Machine {
        limits: Limits {
            min_frequency_hz: 50.0,
            max_frequency_hz: 100.0,
            max_accel_mps2: 200.0,
            max_stroke_m: 5.0e-3,
        },
        friction: Friction::new(0.3, 9.80665).unwrap(),
        clock: TickClock::new(1_000_000),
    }
}

fn slot(number: u8) -> RecipeSlot {
    RecipeSlot::new(number).unwrap()
}

/// Recipe records in RAM; `fail` makes every write fail.
#[derive(Clone, PartialEq)]
struct Memory {
    records: [[u8; RECORD_LEN]; RECIPE_SLOTS],
    fail: bool,
}

#[derive(Debug)]
struct WriteFailed;

impl Memory {
    fn erased() -> Self {
        Memory {
            records: [[0xff; RECORD_LEN]; RECIPE_SLOTS],
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

fn snapshot(state: RunState, phase: Phase, cycles: u64) -> Snapshot {
    Snapshot {
        state,
        phase,
        uptime_ms: 12_345,
        cycles,
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
        ("reset", faulted(0), Ok("OK fault cleared"), Some(Action::Reset)),
        ("reset", stopped(0), Ok("OK no fault latched"), Some(Action::None)),
        (
            "status",
            running(617),
            Ok("OK state=running freq_hz=50 duty=0.5858 stroke_mm=2.5 "),
            Some(Action::None),
        ),
        ("get freq", running(0), Ok("OK freq_hz=50"), Some(Action::None)),
        ("get duty", running(0), Ok("OK duty=0.5858"), Some(Action::None)),
        ("get stroke", running(0), Ok("OK stroke_mm=2.5"), Some(Action::None)),
        ("get accel", running(0), Ok("OK accel_mps2="), Some(Action::None)),
        ("get feed", running(0), Ok("OK feed_mmps="), Some(Action::None)),
        ("get ramp", running(0), Ok("OK ramp_cycles=10"), Some(Action::None)),
        ("set freq 55", running(0), Ok("OK freq_hz=55 "), None),
        ("set duty 0.6", running(0), Ok("OK freq_hz=50 duty=0.6 "), None),
        ("set stroke 2", running(0), Ok("OK freq_hz=50 duty=0.5858 stroke_mm=2 "), None),
        ("set accel 100", running(0), Ok("OK freq_hz=50 duty=0.5858 stroke_mm="), None),
        ("set feed 30", running(0), Ok("OK freq_hz=50 duty=0.5"), None),
        ("set ramp 5", running(0), Ok("OK freq_hz=50 "), None),
        ("set ramp 5", faulted(0), Ok("OK freq_hz=50 "), None),
        ("set freq 20", stopped(0), Err(44), Some(Action::None)),
        ("set duty 0.4", stopped(0), Err(42), Some(Action::None)),
        ("set duty 1", stopped(0), Err(43), Some(Action::None)),
        ("set stroke 9", stopped(0), Err(45), Some(Action::None)),
        ("set stroke 0", stopped(0), Err(41), Some(Action::None)),
        ("set accel 900", stopped(0), Err(45), Some(Action::None)),
        ("set feed 0.0001", stopped(0), Err(48), Some(Action::None)),
        ("set feed 1e6", stopped(0), Err(53), Some(Action::None)),
        ("recipe save 3", stopped(0), Ok("OK recipe 3 saved"), Some(Action::None)),
        ("recipe save 3", faulted(0), Ok("OK recipe 3 saved"), Some(Action::None)),
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
        ("recipe load 4", running(0), Ok("OK recipe 4 loaded freq_hz=55 "), None),
        (
            "recipe load 5",
            running(0),
            Ok("OK recipe 5 not usable (no recipe saved in this slot), defaults loaded freq_hz=50 "),
            None,
        ),
        ("recipe list", running(0), Ok("OK recipes 0=empty "), Some(Action::None)),
        ("help", running(0), Ok("OK commands: start | stop "), Some(Action::None)),
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
    };
    let reply = run(&mut controller, "status", &at, &mut store).reply;
    let text = reply.as_str();
    assert!(text.starts_with("OK state=fault freq_hz=50 duty=0.5858 stroke_mm=2.5 "));
    assert!(text.contains(" ramp_cycles=10 feed_mmps="), "{text}");
    assert!(
        text.ends_with(" uptime_s=61.005 cycles=3050 fault=watchdog-reset"),
        "{text}"
    );
    let starting = snapshot(RunState::Running, Phase::Starting, 7);
    let reply = run(&mut controller, "status", &starting, &mut store).reply;
    assert!(reply.as_str().starts_with("OK state=starting "));
    assert!(reply.as_str().ends_with(" cycles=7 fault=none"));
}

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
fn unusable_records_load_the_defaults_and_say_why() {
    let mut controller = controller();
    let mut store = Memory::erased();
    let at = stopped(0);
    run(&mut controller, "set freq 80", &at, &mut store);
    run(&mut controller, "recipe save 1", &at, &mut store);
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
    for (slot, reason) in [
        (1, "corrupt record: CRC"),
        (2, "record belongs to slot 3, not slot 2"),
        (3, "stored parameters refused: "),
    ] {
        let outcome = run(
            &mut controller,
            &format!("recipe load {slot}"),
            &at,
            &mut store,
        );
        let head = format!("OK recipe {slot} not usable ({reason}");
        assert!(
            outcome.reply.as_str().starts_with(&head),
            "{}",
            outcome.reply
        );
        assert!(outcome
            .reply
            .as_str()
            .contains("defaults loaded freq_hz=50 duty=0.5858 "));
        assert_eq!(controller.settings(), &Settings::DEFAULT);
        assert_eq!(outcome.action, configure(&Settings::DEFAULT));
    }
}

#[test]
fn a_session_through_the_line_assembler() {
    let mut controller = controller();
    let mut store = Memory::erased();
    let mut assembler = LineAssembler::new();
    let mut input = b"set duty 0.62\r\nstart\r\n\x00\xff\x13garbage\r\n".to_vec();
    input.extend_from_slice(&[b'x'; 100]);
    input.extend_from_slice(b"\r\nget duty\nstop\r\n\r\n");
    let replies: Vec<String> = input
        .iter()
        .filter_map(|&byte| assembler.push(byte))
        .map(|line| {
            controller
                .handle(line, &running(0), &mut store)
                .reply
                .to_string()
        })
        .collect();
    let heads: Vec<&str> = replies.iter().map(|r| &r[..r.len().min(6)]).collect();
    assert_eq!(
        heads,
        ["OK fre", "OK sta", "ERR 11", "ERR 10", "OK dut", "OK sto"],
        "{replies:#?}"
    );
    assert_eq!(replies[4], "OK duty=0.62");
}

/// Commands of every kind with plausible and implausible values.
fn command() -> impl Strategy<Value = Command> {
    let value = prop_oneof![
        any::<f64>(),
        -10.0f64..300.0,
        prop::sample::select(vec![0.5, 0.55, 0.6, 0.62, 0.9, 50.0, 100.0, 2.5, 150.0]),
    ];
    let setting = (0..6u8, value, any::<u16>()).prop_map(|(kind, value, ramp)| match kind {
        0 => Setting::FrequencyHz(value),
        1 => Setting::Duty(value),
        2 => Setting::StrokeMm(value),
        3 => Setting::AccelMps2(value),
        4 => Setting::FeedMmps(value),
        _ => Setting::RampCycles(ramp),
    });
    let slot = (0..RECIPE_SLOTS as u8).prop_map(slot);
    prop_oneof![
        1 => Just(Command::Start),
        1 => Just(Command::Stop),
        1 => Just(Command::Status),
        1 => Just(Command::Reset),
        1 => Just(Command::Help),
        1 => Just(Command::RecipeList),
        1 => prop::sample::select(Param::ALL.to_vec()).prop_map(Command::Get),
        4 => setting.prop_map(Command::Set),
        1 => slot.clone().prop_map(Command::RecipeSave),
        1 => slot.prop_map(Command::RecipeLoad),
    ]
}

fn run_state() -> impl Strategy<Value = (RunState, Phase)> {
    prop::sample::select(vec![
        (RunState::Stopped, Phase::Stopped),
        (RunState::Running, Phase::Stopped),
        (RunState::Running, Phase::Starting),
        (RunState::Running, Phase::Running),
        (RunState::Stopping, Phase::Stopping),
        (RunState::Stopped, Phase::Stopping),
        (RunState::Faulted(Fault::EdgeMissed), Phase::Stopped),
        (RunState::Faulted(Fault::InvalidSettings), Phase::Stopped),
    ])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// Any command in any state: one well-formed reply line, settings valid throughout, and an
    /// `ERR` changes neither the settings nor the store and asks nothing of the control loop.
    #[test]
    fn any_sequence_keeps_the_rules(
        steps in prop::collection::vec((command(), run_state(), 0u64..4), 1..40),
        fail_writes in any::<bool>(),
    ) {
        let machine = machine();
        let mut controller = controller();
        let mut store = Memory::erased();
        store.fail = fail_writes;
        let mut cycles = 0;
        for (command, (state, phase), advance) in steps {
            cycles += advance;
            let at = snapshot(state, phase, cycles);
            let before = *controller.settings();
            let stored = store.clone();
            let outcome = controller.execute(command, &at, &mut store);
            let reply = outcome.reply.as_str();
            prop_assert!(reply.len() <= REPLY_CAPACITY);
            prop_assert!(reply.bytes().all(|b| (b' '..=b'~').contains(&b)), "{}", reply);
            prop_assert!(controller.settings().validate(&machine).is_ok());
            if reply.starts_with("ERR ") {
                prop_assert_eq!(outcome.action, Action::None);
                prop_assert_eq!(controller.settings(), &before);
                prop_assert!(store == stored);
            } else {
                prop_assert!(reply == "OK" || reply.starts_with("OK "), "{}", reply);
            }
            match command {
                Command::Set(_) | Command::RecipeLoad(_) if outcome.reply.is_ok() => {
                    prop_assert_eq!(outcome.action, configure(controller.settings()));
                }
                Command::RecipeSave(_) if outcome.reply.is_ok() => {
                    prop_assert!(matches!(state, RunState::Stopped | RunState::Faulted(_)));
                    prop_assert_eq!(phase, Phase::Stopped);
                }
                Command::Start if matches!(state, RunState::Faulted(_)) => {
                    prop_assert!(matches!(outcome.action, Action::Start | Action::None));
                }
                _ => {}
            }
        }
    }

    /// Any bytes through the line assembler: one reply per reported line, never a panic.
    #[test]
    fn arbitrary_bytes_get_one_reply_per_line(
        input in prop::collection::vec(any::<u8>(), 0..400),
    ) {
        let mut controller = controller();
        let mut store = Memory::erased();
        let mut assembler = LineAssembler::new();
        let mut lines = 0;
        let mut replies = 0;
        for &byte in &input {
            if let Some(line) = assembler.push(byte) {
                lines += 1;
                let outcome = controller.handle(line, &stopped(0), &mut store);
                prop_assert!(!outcome.reply.as_str().contains(['\r', '\n']));
                replies += 1;
            }
        }
        prop_assert_eq!(lines, replies);
        prop_assert!(controller.settings().validate(&machine()).is_ok());
    }
}
