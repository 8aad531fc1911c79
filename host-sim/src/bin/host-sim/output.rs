//! What every command writes, in one order: the CSV file, the chart, then the JSON document or
//! the human-readable report; the check that an output file can be written before a run; and
//! the progress bar of the long ones.

use std::fs::OpenOptions;
use std::io::{ErrorKind, IsTerminal};
use std::path::Path;

use host_sim::SimError;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;

use crate::args::OutputArgs;
use crate::plot;

impl OutputArgs {
    /// Refuses an output file that cannot be written (see [`check_writable`]) and a chart format
    /// that cannot be drawn, before anything is computed.
    pub fn check(&self) -> Result<(), SimError> {
        if let Some(path) = &self.csv {
            check_writable(path)?;
        }
        if let Some(path) = &self.plot {
            plot::check_path(path)?;
            check_writable(path)?;
        }
        Ok(())
    }

    /// The files asked for besides the report, each named by what it holds (`csv`, `plot`).
    pub fn files(&self) -> impl Iterator<Item = (&'static str, &Path)> {
        [("csv", &self.csv), ("plot", &self.plot)]
            .into_iter()
            .filter_map(|(what, path)| Some((what, path.as_deref()?)))
    }
}

/// Prints a line to stdout; a closed pipe (`host-sim … | head`) ends the output quietly.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}
pub(crate) use say;

/// Writes `rows` to the CSV file and draws the chart with `plot`, each if asked for, then prints
/// `json` for `--json` and the human-readable `report` otherwise. The report is printed whatever
/// happened to the files; a file that could not be written is the error returned after it.
pub fn emit<R: Serialize, J: Serialize + ?Sized>(
    output: &OutputArgs,
    rows: &[R],
    plot: impl FnOnce(&Path) -> Result<(), SimError>,
    json: &J,
    report: impl FnOnce(),
) -> Result<(), SimError> {
    let csv = output
        .csv
        .as_deref()
        .map_or(Ok(()), |path| write_csv(path, rows));
    let chart = output.plot.as_deref().map_or(Ok(()), plot);
    let printed = if output.json {
        print_json(json)
    } else {
        report();
        Ok(())
    };
    printed.and(join_failures([csv, chart]))
}

/// One error for the outputs that failed, each named; `Ok` if none did.
pub fn join_failures<const N: usize>(results: [Result<(), SimError>; N]) -> Result<(), SimError> {
    let mut failures = results.into_iter().filter_map(Result::err);
    let Some(first) = failures.next() else {
        return Ok(());
    };
    let rest: Vec<String> = failures.map(|failure| failure.to_string()).collect();
    if rest.is_empty() {
        return Err(first);
    }
    Err(SimError::Request(
        std::iter::once(first.to_string())
            .chain(rest)
            .collect::<Vec<_>>()
            .join("; "),
    ))
}

/// Refuses an output file that cannot be written, before anything runs: its directory must
/// exist and the file must be creatable there (a file already there is left as it is).
pub fn check_writable(path: &Path) -> Result<(), SimError> {
    let refusal = |reason: String| SimError::Output {
        path: path.display().to_string(),
        reason,
    };
    let directory = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    if !directory.is_dir() {
        return Err(refusal(format!(
            "its directory {} does not exist",
            directory.display()
        )));
    }
    match std::fs::metadata(path) {
        Ok(metadata) if metadata.is_dir() => Err(refusal("it is a directory".into())),
        Ok(_) => OpenOptions::new()
            .append(true)
            .open(path)
            .map(drop)
            .map_err(|error| refusal(error.to_string())),
        Err(error) if error.kind() == ErrorKind::NotFound => {
            OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(path)
                .map_err(|error| refusal(error.to_string()))?;
            std::fs::remove_file(path).map_err(|error| refusal(error.to_string()))
        }
        Err(error) => Err(refusal(error.to_string())),
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

/// A spinner on stderr with a message the run updates, hidden for `--json` or when stderr is not a
/// terminal.
pub fn spinner(json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
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
