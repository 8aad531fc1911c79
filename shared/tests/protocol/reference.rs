//! `shared/PROTOCOL.md` agrees with the code: its status example and its table of error codes.

use feeder_shared::testing::machine;
use feeder_shared::{Phase, Reply, Settings, Status};

const REFERENCE: &str = include_str!("../../PROTOCOL.md");

#[test]
fn the_reference_example_is_what_status_prints() {
    let applied = Settings::DEFAULT.validate(&machine()).unwrap();
    let reply = Reply::status(&Status::<&str> {
        phase: Phase::Running,
        fault: None,
        waveform: applied.plan.waveform,
        ramp_cycles: applied.settings.ramp_cycles,
        feed_rate_mps: applied.feed_rate_mps,
        uptime_ms: 12_345,
        cycles: 617,
        closed_loop: None,
        track: None,
    });
    let example = format!("    {reply}\n");
    assert!(
        REFERENCE.contains(&example),
        "PROTOCOL.md lacks {example:?}"
    );
}

#[test]
fn the_reference_documents_every_error_code() {
    let documented: Vec<u16> = REFERENCE
        .lines()
        .filter_map(|line| {
            line.strip_prefix('|')?
                .split('|')
                .next()?
                .trim()
                .parse()
                .ok()
        })
        .collect();
    let mut expected: Vec<u16> = vec![10, 11];
    expected.extend(20..=28);
    expected.extend(40..=56);
    expected.extend(60..=62);
    assert_eq!(documented, expected);
}
