use proptest::prelude::*;

use super::*;

fn full() -> Record {
    Record {
        stage: Some(Stage::Feeding),
        mean_m: Some(1.2e-6),
        peak_m: Some(1280.4e-6),
        trim_positive: Some(1.0012),
        trim_negative: Some(0.9987),
        bias_mps2: Some(0.0123),
        slack_ticks: Some(19938),
        edge_work_cycles: Some(4236),
        cpu_load_pct: Some(3.1),
        track: Some(TrackState::Empty),
        parts_per_minute: Some(12.0),
        ..Record::new(1234, 24_680, Phase::Running, None)
    }
}

fn line(record: &Record) -> heapless::String<MAX_LINE_BYTES> {
    let mut text = heapless::String::new();
    record.write_line(&mut text).expect("a line fits");
    text
}

#[test]
fn a_record_is_the_documented_line() {
    assert_eq!(
        line(&full()).as_str(),
        "T 1234 24.68 running feeding 1.2 1280.4 1.0012 0.9987 0.0123 19938 4236 3.1 room 12 none"
    );
    assert_eq!(
        line(&Record::new(
            7,
            140,
            Phase::Stopped,
            Some(Fault::EdgeMissed)
        ))
        .as_str(),
        "T 7 0.14 stopped - - - - - - - - - - - edge-missed"
    );
}

#[test]
fn the_header_names_every_field_with_its_unit() {
    assert_eq!(COLUMNS.len(), 15);
    let mut row = heapless::String::<MAX_LINE_BYTES>::new();
    full().write_fields(&mut row, ',').unwrap();
    assert_eq!(row.split(',').count(), COLUMNS.len());
    let mut header = heapless::String::<256>::new();
    for (index, column) in COLUMNS.iter().enumerate() {
        if index > 0 {
            header.push(',').unwrap();
        }
        column.write_header(&mut header).unwrap();
    }
    assert_eq!(
        header.as_str(),
        "cycle,uptime_s,phase,loop,mean_um,peak_um,trim_pos,trim_neg,bias_mps2,slack_ticks,\
         edge_work_cycles,cpu_load_pct,track,parts_per_min,fault"
    );
}

#[test]
fn lines_that_are_no_record_name_their_column() {
    assert_eq!(Record::parse_line("T x"), Err(ParseError { column: 0 }));
    assert_eq!(
        Record::parse_line("T 1 0.1 walking - - - - - - - - - - - none"),
        Err(ParseError { column: 2 })
    );
    assert_eq!(
        Record::parse_line("T 1 0.1 stopped - - - - - - - - - - - none extra"),
        Err(ParseError {
            column: COLUMNS.len()
        })
    );
    assert_eq!(
        Record::parse_line("T 1 0.1 stopped"),
        Err(ParseError { column: 3 })
    );
}

#[test]
fn a_cycle_s_positions_give_its_time_mean_and_farthest_excursion() {
    let at = |tick, um: f64| PositionSample {
        tick,
        position_m: um * 1e-6,
    };
    // Trapezoids over 0–100–300 ticks: (0 + 10)/2·100 + (10 − 50)/2·200 = −3500 µm·ticks.
    let (mean_m, peak_m) = cycle_positions(at(0, 0.0), &[at(100, 10.0)], at(300, -50.0));
    assert!((mean_m - -3500e-6 / 300.0).abs() < 1e-15, "{mean_m}");
    assert_eq!(peak_m, 50.0 * 1e-6, "the farthest sample, as written");
}

#[test]
fn the_pacer_keeps_telemetry_to_its_share_of_the_link() {
    let mut pacer = Pacer::new(115_200);
    assert!(pacer.ready(0));
    pacer.sent(0, 80);
    // 80 bytes at 115200 baud take 6944 µs; at half the link the next waits twice that.
    assert!(!pacer.ready(13_888));
    assert!(pacer.ready(13_889));
    assert!((pacer.line_us(80) - 6944.4).abs() < 0.1);
}

fn records() -> impl Strategy<Value = Record> {
    let stage = prop::option::of(prop::sample::select(STAGES.to_vec()));
    let track = prop::option::of(prop::sample::select(TRACK_STATES.to_vec()));
    let fault = prop::option::of(prop::sample::select(FAULTS.to_vec()));
    let phase = prop::sample::select(PHASES.to_vec());
    let number = |range: core::ops::Range<f64>| prop::option::of(range);
    (
        (any::<u64>(), 0u64..1u64 << 40, phase, stage, fault, track),
        (
            number(-5e-3..5e-3),
            number(0.0..5e-3),
            number(0.5..1.5),
            number(0.5..1.5),
        ),
        (
            number(-50.0..50.0),
            prop::option::of(any::<u32>()),
            prop::option::of(any::<u32>()),
        ),
        (number(0.0..100.0), number(0.0..1e4)),
    )
        .prop_map(
            |(
                (cycle, uptime_ms, phase, stage, fault, track),
                (mean_m, peak_m, trim_positive, trim_negative),
                (bias_mps2, slack_ticks, edge_work_cycles),
                (cpu_load_pct, parts_per_minute),
            )| Record {
                cycle,
                uptime_ms,
                phase,
                stage,
                mean_m,
                peak_m,
                trim_positive,
                trim_negative,
                bias_mps2,
                slack_ticks,
                edge_work_cycles,
                cpu_load_pct,
                track,
                parts_per_minute,
                fault,
            },
        )
}

/// `value` rounded as its column writes it.
fn rounded(value: Option<f64>, scale: f64, decimals: i32) -> Option<f64> {
    let factor = 10f64.powi(decimals);
    value.map(|v| (v * scale * factor).round() / factor / scale)
}

proptest! {
    /// Every record fits its line and reads back as itself, to the decimals its columns keep.
    #[test]
    fn a_line_reads_back_as_its_record(record in records()) {
        let text = line(&record);
        prop_assert!(text.len() <= MAX_LINE_BYTES);
        let read = Record::parse_line(&text).unwrap();
        let close = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => (a - b).abs() <= 1e-9 * a.abs().max(1e-6),
            (None, None) => true,
            _ => false,
        };
        prop_assert_eq!(
            (read.cycle, read.uptime_ms, read.phase, read.stage, read.track, read.fault),
            (record.cycle, record.uptime_ms, record.phase, record.stage, record.track, record.fault)
        );
        prop_assert_eq!((read.slack_ticks, read.edge_work_cycles), (record.slack_ticks, record.edge_work_cycles));
        prop_assert!(close(read.mean_m, rounded(record.mean_m, 1e6, 1)));
        prop_assert!(close(read.peak_m, rounded(record.peak_m, 1e6, 1)));
        prop_assert!(close(read.trim_positive, rounded(record.trim_positive, 1.0, 5)));
        prop_assert!(close(read.bias_mps2, rounded(record.bias_mps2, 1.0, 4)));
        prop_assert!(close(read.parts_per_minute, rounded(record.parts_per_minute, 1.0, 1)));
    }
}

/// The console's link as the board drives it: lines queue in the transmitter's buffer and go out
/// a byte at a time at 115200 baud, 8N1.
struct Link {
    us_per_byte: f64,
    /// When the bytes queued so far have all gone, µs.
    idle_at_us: f64,
}

impl Link {
    /// Queues `bytes` at `now_us`; returns when the first of them starts out and how many bytes
    /// the buffer then holds, these included.
    fn queue(&mut self, now_us: f64, bytes: usize) -> (f64, f64) {
        let start_us = self.idle_at_us.max(now_us);
        let held = (start_us - now_us) / self.us_per_byte + bytes as f64;
        self.idle_at_us = start_us + bytes as f64 * self.us_per_byte;
        (start_us, held)
    }
}

proptest! {
    /// The console's loop with telemetry on, as the firmware runs it: every `TELEMETRY_POLL_MS`
    /// it writes the newest cycle's line where the pacer lets it, and a command's reply is
    /// queued as soon as the command's line is in. Whatever the lines' lengths, the cycle's
    /// period and the commands' instants, a reply starts within one longest line's time
    /// (160 bytes and the terminator: 14.0 ms), under the 20 ms a reply may wait, and the
    /// transmitter never holds more than two lines.
    #[test]
    fn a_reply_waits_behind_one_telemetry_line_at_most(
        period_us in 10_000u32..=20_000,
        line_bytes in prop::collection::vec(20usize..=MAX_LINE_BYTES + 2, 200),
        gaps_us in prop::collection::vec(30_000u32..200_000, 12),
        reply_bytes in prop::collection::vec(4usize..=64, 12),
    ) {
        const POLL_US: u64 = 5_000;
        let mut pacer = Pacer::new(115_200);
        let mut link = Link { us_per_byte: 10.0e6 / 115_200.0, idle_at_us: 0.0 };
        let longest_us = pacer.line_us(MAX_LINE_BYTES + 2);
        let mut commands_us = gaps_us.iter().scan(0u64, |at, gap| {
            *at += u64::from(*gap) + 1;
            Some(*at)
        });
        let mut next_command_us = commands_us.next();
        let mut replies = reply_bytes.iter();
        let mut lines = line_bytes.iter().cycle();
        let mut last_cycle = None;
        let mut worst_us: f64 = 0.0;
        let mut poll_us = 0;
        while let Some(command_us) = next_command_us {
            if command_us < poll_us {
                let (start_us, _) = link.queue(command_us as f64, *replies.next().unwrap());
                worst_us = worst_us.max(start_us - command_us as f64);
                next_command_us = commands_us.next();
                continue;
            }
            let cycle = poll_us / u64::from(period_us);
            if last_cycle != Some(cycle) && pacer.ready(poll_us) {
                let bytes = *lines.next().unwrap();
                let (_, held) = link.queue(poll_us as f64, bytes);
                prop_assert!(held <= 2.0 * (MAX_LINE_BYTES + 2) as f64, "{held} bytes held");
                pacer.sent(poll_us, bytes);
                last_cycle = Some(cycle);
            }
            poll_us += POLL_US;
        }
        prop_assert!(worst_us <= longest_us, "a reply waited {worst_us} µs");
        prop_assert!(longest_us < 20_000.0);
    }
}
