//! A telemetry recording: one CSV row per record, under a header naming each column with its
//! unit (`feeder_shared::telemetry::COLUMNS`).

use std::fmt::Write as _;
use std::io;
use std::path::Path;

use feeder_shared::telemetry::{Record, COLUMNS};

/// The recording of `records` as CSV text.
pub fn csv(records: &[Record]) -> String {
    let mut text = String::new();
    for (index, column) in COLUMNS.iter().enumerate() {
        if index > 0 {
            text.push(',');
        }
        let _ = column.write_header(&mut text);
    }
    text.push('\n');
    for record in records {
        let _ = record.write_fields(&mut text, ',');
        let _ = writeln!(text);
    }
    text
}

/// Writes the recording of `records` to `path`.
pub fn write(path: &Path, records: &[Record]) -> io::Result<()> {
    std::fs::write(path, csv(records))
}

#[cfg(test)]
mod tests {
    use feeder_shared::Phase;

    use super::*;

    #[test]
    fn a_recording_has_the_header_and_one_row_per_record() {
        let records = [
            Record::new(1, 20, Phase::Stopped, None),
            Record::new(2, 40, Phase::Starting, None),
        ];
        let text = csv(&records);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[0].starts_with("cycle,uptime_s,phase,loop,mean_um,"));
        assert_eq!(lines[2], "2,0.04,starting,-,-,-,-,-,-,-,-,-,-,-,none");
    }
}
