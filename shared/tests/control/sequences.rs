//! Sessions through the line assembler, and any command sequence in any feeder state.

use feeder_shared::protocol::REPLY_CAPACITY;
use feeder_shared::recipe::RECIPE_SLOTS;
use feeder_shared::{Action, Command, Fault, LineAssembler, Param, Phase, RunState, Setting};
use proptest::prelude::*;

use crate::common::slot;
use crate::{configure, controller, machine, running, snapshot, stopped, Memory};

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
