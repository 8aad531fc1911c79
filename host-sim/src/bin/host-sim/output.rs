//! What every command writes, in one order: the CSV file, the chart, then the JSON document or
//! the human-readable report; and the progress bar of the long ones.

use std::io::IsTerminal;
use std::path::Path;

use host_sim::SimError;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;

use crate::args::OutputArgs;

/// Prints a line to stdout; a closed pipe (`host-sim … | head`) ends the output quietly.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}
pub(crate) use say;

/// Writes `rows` to the CSV file and draws the chart with `plot`, each if asked for, then prints
/// `json` for `--json` and the human-readable `report` otherwise.
pub fn emit<R: Serialize, J: Serialize + ?Sized>(
    output: &OutputArgs,
    rows: &[R],
    plot: impl FnOnce(&Path) -> Result<(), SimError>,
    json: &J,
    report: impl FnOnce(),
) -> Result<(), SimError> {
    if let Some(path) = &output.csv {
        write_csv(path, rows)?;
    }
    if let Some(path) = &output.plot {
        plot(path)?;
    }
    if output.json {
        print_json(json)
    } else {
        report();
        Ok(())
    }
}

/// A progress bar on stderr, hidden for `--json` or when stderr is not a terminal.
pub fn progress(total: usize, json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::hidden());
    }
    let bar = ProgressBar::new(total as u64);
    if let Ok(style) = ProgressStyle::with_template("{bar:40} {pos}/{len} points {elapsed}") {
        bar.set_style(style);
    }
    bar
}

fn print_json<T: Serialize + ?Sized>(value: &T) -> Result<(), SimError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| SimError::Output {
        path: "stdout".into(),
        reason: e.to_string(),
    })?;
    say!("{text}");
    Ok(())
}

fn write_csv<T: Serialize>(path: &Path, rows: &[T]) -> Result<(), SimError> {
    let failure = |reason: String| SimError::Output {
        path: path.display().to_string(),
        reason,
    };
    let mut writer = csv::Writer::from_path(path).map_err(|e| failure(e.to_string()))?;
    for row in rows {
        writer.serialize(row).map_err(|e| failure(e.to_string()))?;
    }
    writer.flush().map_err(|e| failure(e.to_string()))
}

/// The file name of `path` for a chart's title (the whole path if it has none).
pub fn file_name(path: &Path) -> String {
    path.file_name().map_or(path.display().to_string(), |name| {
        name.to_string_lossy().into_owned()
    })
}
