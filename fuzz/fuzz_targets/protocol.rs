//! Arbitrary bytes through the line assembler, the parser, `set` and `config set` validation and
//! every reply formatter, with a status whose closed-loop stage and drive and track state are drawn from the
//! input's first bytes: nothing panics, and every reply is one printable-ASCII `OK`/`ERR <code>`
//! line.
#![no_main]

use feeder_shared::closed_loop::{
    CourseError, FeedCompensation, Identified, LoopReport, Stage, TrackReport, TrackState,
};
use feeder_shared::configuration::{BoardFacts, Configuration, OutputKind};
use feeder_shared::protocol::REPLY_CAPACITY;
use feeder_shared::recipe::{self, RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::testing;
use feeder_shared::{
    Command, ConfigCommand, LineAssembler, Machine, Phase, RecipeSlot, Reply, ReplyError, Settings,
    Status,
};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

/// The tests' machine with a 16-bit timer: at most `u16::MAX` ticks per segment.
fn machine() -> Machine {
    let machine = testing::machine();
    Machine {
        clock: machine.clock.with_max_segment_ticks(u32::from(u16::MAX)),
        ..machine
    }
}

/// The closed loop's report as a board with one publishes it: any stage, with or without an
/// identified drive and a feed compensation of any values.
fn loop_report(input: &mut Unstructured) -> Result<Option<LoopReport>> {
    if !input.arbitrary()? {
        return Ok(None);
    }
    let stage = *input.choose(&Stage::ALL)?;
    let drive = match input.arbitrary()? {
        true => Some(Identified {
            gain_positive: input.arbitrary()?,
            gain_negative: input.arbitrary()?,
            offset_mps2: input.arbitrary()?,
            lag_s: input.arbitrary()?,
            coulomb_mps2: input.arbitrary()?,
            viscous_per_s: input.arbitrary()?,
            spring_per_s2: input.arbitrary()?,
            residual_m: input.arbitrary()?,
        }),
        false => None,
    };
    let feed = match input.arbitrary()? {
        true => Some(FeedCompensation {
            amplitude: input.arbitrary()?,
            feed_mps: input.arbitrary()?,
            ideal_mps: input.arbitrary()?,
            limited: input.arbitrary()?,
            stroke_factor: input.arbitrary()?,
        }),
        false => None,
    };
    let failure = match input.arbitrary()? {
        true => Some(CourseError::Centring {
            error_m: input.arbitrary()?,
        }),
        false => None,
    };
    Ok(Some(LoopReport {
        stage,
        drive,
        feed,
        failure,
    }))
}

/// Track control's report on a board with a part sensor: either state, any rate.
fn track_report(input: &mut Unstructured) -> Result<Option<TrackReport>> {
    if !input.arbitrary()? {
        return Ok(None);
    }
    let state = *input.choose(&[TrackState::Empty, TrackState::Full])?;
    Ok(Some(TrackReport {
        state,
        parts_per_minute: input.arbitrary()?,
    }))
}

fn check(reply: &Reply) {
    let text = reply.as_str();
    assert!(text.len() <= REPLY_CAPACITY);
    assert!(text.bytes().all(|b| (b' '..=b'~').contains(&b)), "{text:?}");
    let well_formed = text == "OK"
        || text.starts_with("OK ")
        || text.strip_prefix("ERR ").is_some_and(|rest| {
            let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
            digits > 0 && rest[digits..].starts_with(' ')
        });
    assert!(well_formed, "{text:?}");
}

fuzz_target!(|input: &[u8]| {
    let mut input = Unstructured::new(input);
    let (Ok(closed_loop), Ok(track)) = (loop_report(&mut input), track_report(&mut input)) else {
        return;
    };
    let input = input.take_rest();
    let machine = machine();
    let mut settings = Settings::DEFAULT;
    let mut applied = settings.validate(&machine).expect("defaults are valid");
    let mut flash = [[0xff_u8; RECORD_LEN]; RECIPE_SLOTS];
    let board = BoardFacts {
        clock: machine.clock,
        output: OutputKind::Dac,
        encoder: true,
    };
    let mut configuration = Configuration::DEFAULT;
    let mut assembler = LineAssembler::new();
    for &byte in input {
        let Some(request) = assembler.push(byte) else {
            continue;
        };
        assert!(matches!(byte, b'\r' | b'\n'), "a reply only at a line end");
        let status = Status {
            phase: Phase::Running,
            fault: Some("fuzz"),
            waveform: applied.plan.waveform,
            ramp_cycles: settings.ramp_cycles,
            feed_rate_mps: applied.feed_rate_mps,
            uptime_ms: u64::MAX,
            cycles: u64::MAX,
            closed_loop,
            track,
        };
        let reply = match request {
            Err(error) => Reply::error(&error),
            Ok(Command::Set(setting)) => match settings.apply(setting, &machine) {
                Ok(candidate) => {
                    settings = candidate.settings;
                    applied = candidate;
                    Reply::applied(&candidate)
                }
                Err(error) => Reply::error(&error.into()),
            },
            Ok(Command::Get(param)) => Reply::get(param, &status),
            Ok(Command::RecipeSave(slot)) => {
                flash[slot.index()] = recipe::encode(slot, &settings);
                Reply::recipe_saved(slot)
            }
            Ok(Command::RecipeLoad(slot)) => {
                match recipe::load(&flash[slot.index()], slot, &machine) {
                    Ok(loaded) => {
                        settings = loaded.settings;
                        applied = loaded;
                        Reply::recipe_loaded(slot, &loaded)
                    }
                    Err(issue) => Reply::error(&ReplyError::RecipeUnusable { slot, issue }),
                }
            }
            Ok(Command::RecipeList) => {
                let entries = core::array::from_fn(|index| {
                    let slot = RecipeSlot::new(index as u8).expect("index below RECIPE_SLOTS");
                    recipe::decode(&flash[index], slot)
                });
                Reply::recipe_list(&entries)
            }
            Ok(Command::Help) => Reply::help(),
            Ok(Command::Config(command)) => match command {
                ConfigCommand::List => Reply::config_list(&configuration),
                ConfigCommand::Get(key) => Reply::config_value(key, &configuration),
                ConfigCommand::Set(key, value) => match key.set(&configuration, value) {
                    Ok(edited) => {
                        configuration = edited;
                        Reply::config_set(key, &configuration)
                    }
                    Err(error) => Reply::error(&ReplyError::ConfigRefused(error)),
                },
                ConfigCommand::Save => match configuration.check(&board) {
                    Ok(()) => Reply::config_saved(true),
                    Err(error) => Reply::error(&ReplyError::ConfigRefused(error)),
                },
                ConfigCommand::Defaults => {
                    configuration = Configuration::DEFAULT;
                    Reply::config_defaults()
                }
            },
            Ok(_) => Reply::status(&status),
        };
        check(&reply);
    }
});
