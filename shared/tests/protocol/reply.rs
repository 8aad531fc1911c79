//! The reply lines: status, get, set, the simple replies, recipes, and truncation.

use std::fmt::Write as _;

use feeder_shared::protocol::REPLY_CAPACITY;
use feeder_shared::recipe::{self, RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::testing::machine;
use feeder_shared::{
    Drive, Limits, Param, Phase, Reply, ReplyError, Setting, Settings, Status, Waveform,
    WaveformSpec,
};

use crate::common::slot;

fn status(fault: Option<&str>) -> Status<&str> {
    let waveform = Waveform::new(
        WaveformSpec::from_frequency(50.0, 0.6, Drive::Stroke { stroke_m: 0.0025 }),
        &Limits::NONE,
    )
    .unwrap();
    Status {
        phase: Phase::Running,
        fault,
        waveform,
        ramp_cycles: 10,
        feed_rate_mps: 0.0731234,
        uptime_ms: 12_345,
        cycles: 617,
        closed_loop: None,
        track: None,
    }
}

/// On a board that runs the closed loop, `status` names the course's stage, why it stopped
/// where it has and, once the drive is identified, its gains (5 decimals) and offset (3); on a board with a part sensor, the
/// track's state and parts per minute (1 decimal, ties to even); both before the fault, which
/// stays last.
#[test]
fn status_reports_the_closed_loop_before_the_fault() {
    use feeder_shared::closed_loop::{FeedCompensation, Identified, LoopReport, Stage};
    let probing = Reply::status(&Status {
        closed_loop: Some(LoopReport {
            stage: Stage::Probing,
            drive: None,
            feed: None,
            failure: None,
        }),
        ..status(None)
    });
    assert!(
        probing
            .as_str()
            .ends_with(" cycles=617 loop=probing fault=none"),
        "{probing}"
    );
    let feeding = Reply::status(&Status {
        closed_loop: Some(LoopReport {
            stage: Stage::Feeding,
            drive: Some(Identified {
                gain_positive: 1.018_404,
                gain_negative: 0.980_236,
                offset_mps2: -1.0296,
                ..Identified::NOMINAL
            }),
            feed: Some(FeedCompensation {
                amplitude: 1.4,
                feed_mps: 0.056_878_2,
                ideal_mps: 0.077,
                limited: true,
                stroke_factor: 1.0,
            }),
            failure: None,
        }),
        ..status(Some("closed-loop"))
    });
    assert!(
        feeding.as_str().ends_with(
            " cycles=617 loop=feeding gain_pos=1.0184 gain_neg=0.98024 offset_mps2=-1.03 lag_ms=0 \
             feed_amplitude=1.4 feed_limited_mmps=56.878 fault=closed-loop"
        ),
        "{feeding}"
    );
    assert!(feeding.as_str().len() <= REPLY_CAPACITY);
    let failed = Reply::status(&Status {
        closed_loop: Some(LoopReport {
            stage: Stage::Failed,
            drive: None,
            feed: None,
            failure: Some(feeder_shared::closed_loop::CourseError::Centring { error_m: 1e-3 }),
        }),
        ..status(Some("closed-loop"))
    });
    assert!(
        failed
            .as_str()
            .ends_with(" cycles=617 loop=failed loop_error=centring fault=closed-loop"),
        "{failed}"
    );
    let full = Reply::status(&Status {
        track: Some(feeder_shared::closed_loop::TrackReport {
            state: feeder_shared::closed_loop::TrackState::Full,
            parts_per_minute: 37.25,
        }),
        ..status(None)
    });
    assert!(
        full.as_str()
            .ends_with(" cycles=617 track=full parts_per_min=37.2 fault=none"),
        "{full}"
    );
}

#[test]
fn status_reports_state_parameters_fault_uptime_and_cycles() {
    // a = x / (T(1 − d)/2)² = 0.0025 / 0.004² = 156.25 m/s².
    let expected = "OK state=running freq_hz=50 duty=0.6 stroke_mm=2.5 accel_mps2=156.25 \
                    ramp_cycles=10 feed_mmps=73.123 uptime_s=12.345 cycles=617 fault=none";
    assert_eq!(Reply::status(&status(None)).as_str(), expected);
    let faulted = Reply::status(&status(Some("overcurrent on phase A")));
    assert!(
        faulted.as_str().starts_with("OK state=fault freq_hz=50 "),
        "{faulted}"
    );
    assert!(
        faulted.as_str().ends_with(" fault=overcurrent on phase A"),
        "{faulted}"
    );
    for (phase, name) in [
        (Phase::Stopped, "stopped"),
        (Phase::Starting, "starting"),
        (Phase::Stopping, "stopping"),
    ] {
        let reply = Reply::status(&Status {
            phase,
            ..status(None)
        });
        assert!(
            reply.as_str().starts_with(&format!("OK state={name} ")),
            "{reply}"
        );
    }
}

#[test]
fn get_reports_one_parameter() {
    let snapshot = status(None);
    let table = [
        (Param::Frequency, "OK freq_hz=50"),
        (Param::Duty, "OK duty=0.6"),
        (Param::Stroke, "OK stroke_mm=2.5"),
        (Param::Accel, "OK accel_mps2=156.25"),
        (Param::Feed, "OK feed_mmps=73.123"),
        (Param::Ramp, "OK ramp_cycles=10"),
    ];
    for (param, expected) in table {
        assert_eq!(Reply::get(param, &snapshot).as_str(), expected);
    }
}

#[test]
fn set_reply_lists_the_candidate() {
    let applied = Settings::DEFAULT
        .apply(Setting::Duty(0.6), &machine())
        .unwrap();
    let reply = Reply::applied(&applied);
    assert!(
        reply.as_str().starts_with(
            "OK freq_hz=50 duty=0.6 stroke_mm=2.5 accel_mps2=156.25 ramp_cycles=25 feed_mmps="
        ),
        "{reply}"
    );
}

#[test]
fn simple_replies() {
    assert_eq!(Reply::ok(format_args!("")).as_str(), "OK");
    assert_eq!(
        Reply::ok(format_args!("stopping at the next cycle")).as_str(),
        "OK stopping at the next cycle"
    );
    assert_eq!(Reply::recipe_saved(slot(4)).as_str(), "OK recipe 4 saved");
    let help = Reply::help();
    assert!(help.is_ok());
    for word in [
        "start",
        "stop",
        "status",
        "get",
        "set freq <Hz>",
        "set feed <mm/s>",
        "recipe list",
        "reset",
        "help",
    ] {
        assert!(help.as_str().contains(word), "{help} lacks {word}");
    }
    assert!(help.as_str().len() < REPLY_CAPACITY);
}

#[test]
fn replies_are_ascii_single_lines_and_truncate_instead_of_failing() {
    let reply = Reply::ok(format_args!("a\r\nb\tc μg ² − ≤ ≥ … · 漢"));
    assert_eq!(reply.as_str(), "OK a  b c mug 2 - <= >= ... * ?");
    let long = "y".repeat(2 * REPLY_CAPACITY);
    let reply = Reply::ok(format_args!("{long}"));
    assert_eq!(reply.as_str().len(), REPLY_CAPACITY);
    assert!(reply.as_str().starts_with("OK yyy"));
    let mut reply = Reply::ok(format_args!("x"));
    write!(reply, "{}", "²".repeat(2 * REPLY_CAPACITY)).unwrap();
    assert_eq!(reply.as_str().len(), REPLY_CAPACITY);
}

#[test]
fn recipe_replies() {
    let machine = machine();
    let mut flash = [[0xffu8; RECORD_LEN]; RECIPE_SLOTS];
    let stored = Settings {
        frequency_hz: 60.0,
        duty: 0.6,
        ..Settings::DEFAULT
    };
    flash[1] = recipe::encode(slot(1), &stored);
    let accel = Settings {
        drive: Drive::Accel { accel_mps2: 150.0 },
        ramp_cycles: 3,
        ..stored
    };
    flash[2] = recipe::encode(slot(2), &accel);
    flash[3] = recipe::encode(slot(3), &stored);
    flash[3][9] ^= 0x10;
    flash[4] = recipe::encode(slot(5), &stored);

    let applied = recipe::load(&flash[1], slot(1), &machine).unwrap();
    let reply = Reply::recipe_loaded(slot(1), &applied);
    assert!(
        reply
            .as_str()
            .starts_with("OK recipe 1 loaded freq_hz=60 duty=0.6 "),
        "{reply}"
    );

    let reasons = [
        (
            0,
            "ERR 63 recipe 0 not loaded: no recipe saved in this slot; nothing changed",
        ),
        (3, "ERR 64 recipe 3 not loaded: corrupt record: CRC 0x"),
        (
            4,
            "ERR 64 recipe 4 not loaded: record belongs to slot 5, not slot 4; nothing changed",
        ),
    ];
    for (number, expected) in reasons {
        let issue = recipe::load(&flash[number], slot(number as u8), &machine).unwrap_err();
        let error = ReplyError::RecipeUnusable {
            slot: slot(number as u8),
            issue,
        };
        let reply = Reply::error(&error);
        assert!(reply.as_str().starts_with(expected), "{reply}");
    }

    let entries: [_; RECIPE_SLOTS] =
        std::array::from_fn(|index| recipe::decode(&flash[index], slot(index as u8)));
    assert_eq!(
        Reply::recipe_list(&entries).as_str(),
        "OK recipes 0=empty 1=60Hz/0.6/2.5mm/r25 2=60Hz/0.6/150m/s2/r3 3=corrupt 4=wrong-slot \
         5=empty 6=empty 7=empty"
    );
}
