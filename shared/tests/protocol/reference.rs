//! `shared/PROTOCOL.md` agrees with the code: its defaults, its status example and its table of
//! error codes.

use feeder_shared::testing::machine;
use feeder_shared::{Drive, Phase, Reply, Settings, Status};

const REFERENCE: &str = include_str!("../../PROTOCOL.md");

#[test]
fn the_reference_states_the_defaults() {
    let defaults = Settings::DEFAULT;
    let Drive::Stroke { stroke_m } = defaults.drive else {
        panic!("the defaults hold a stroke: {defaults:?}");
    };
    let sentence = format!(
        "Defaults, the settings at power-up: {} Hz, `d = {}`, {} mm stroke, {} ramp cycles.",
        defaults.frequency_hz,
        defaults.duty,
        stroke_m * 1e3,
        defaults.ramp_cycles
    );
    assert!(
        REFERENCE.contains(&sentence),
        "PROTOCOL.md lacks {sentence:?}"
    );
}

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
    expected.extend(20..=29);
    expected.extend(40..=58);
    expected.extend(60..=66);
    assert_eq!(documented, expected);
}

#[test]
fn the_reference_telemetry_example_reads_as_a_record_and_names_every_column() {
    use feeder_shared::telemetry::{Record, COLUMNS};
    let example = REFERENCE
        .lines()
        .find_map(|line| line.strip_prefix("    T "))
        .expect("PROTOCOL.md shows a telemetry line");
    let record = Record::parse_line(example).expect("the example reads as a record");
    let mut written = String::new();
    record.write_line(&mut written).unwrap();
    assert_eq!(written, format!("T {example}"));
    for column in COLUMNS {
        let mut header = String::new();
        column.write_header(&mut header).unwrap();
        assert!(
            REFERENCE.contains(&format!("`{header}`")),
            "PROTOCOL.md does not name {header}"
        );
    }
}
