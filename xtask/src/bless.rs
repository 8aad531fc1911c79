//! `cargo xtask bless`: makes every expected output anew and says which changed. The QEMU logs
//! come from the scripted image started by `feeder-emulator`, as the QEMU tests start it; the
//! closed-loop co-simulation's log and the plant family's sample from their tests; the figures'
//! CSVs from the `host-sim` CLI; the command-line snapshots and the documentation's sessions
//! (`docs/`) from their `trycmd` runners.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Duration;

use feeder_shared::scenario::parse_setting;

use crate::command::{cargo, cargo_test, exec, exec_output, host_sim, root};
use crate::failure::Result;
use crate::qemu::{self, Image};
use crate::tools;

/// A scripted run may take this long before it is ended and bless fails.
const RUN_LIMIT: Duration = Duration::from_secs(120);

/// The scenario words of a QEMU run end in this, its decoded log beside them in `.log`.
const SCENARIO_EXTENSION: &str = "args";

/// Each figure's CSV and the `host-sim` arguments that write it (with `--csv FILE`); what each
/// figure shows: `tests/expected/README.md`.
const FIGURES: [(&str, &[&str]); 4] = [
    ("sweep.csv", &["sweep", "--exact-times"]),
    ("viscosity.csv", &["viscosity", "--exact-times"]),
    ("saturation.csv", &["saturation"]),
    (
        "trace.csv",
        &["trace", "--duty", "0.7", "--exact-times", "--cycles", "5"],
    ),
];

/// The packages whose `trycmd` runner (`tests/cli_snapshots.rs`) keeps its cases in
/// `tests/cmd/`, with their directories.
const SNAPSHOTS: [(&str, &str); 2] = [("host-sim", "host-sim"), ("feeder-ctl", "ctl")];

fn expected_dir() -> PathBuf {
    root().join("tests").join("expected")
}

/// Makes every expected output anew, then prints which files changed.
pub fn bless() -> Result {
    let watched: Vec<PathBuf> = [expected_dir(), root().join("docs")]
        .into_iter()
        .chain(snapshot_packages().map(|(_, dir)| dir.join("tests").join("cmd")))
        .collect();
    let before = contents(&watched)?;
    qemu_logs()?;
    closed_loop_log()?;
    family_sample()?;
    figures()?;
    for (package, _) in snapshot_packages() {
        exec(
            cargo()
                .args(["test", "--locked", "--package", package])
                .args(["--test", "cli_snapshots"])
                .env("TRYCMD", "overwrite"),
        )?;
    }
    exec(cargo_test("docs").env("TRYCMD", "overwrite"))?;
    exec(
        cargo()
            .args([
                "test",
                "--locked",
                "--package",
                "feeder-ctl",
                "--bin",
                "feeder-ctl",
            ])
            .args(["--", "watch::view"])
            .env("FEEDER_BLESS", "overwrite"),
    )?;
    report(&before, &contents(&watched)?);
    Ok(())
}

/// The packages of [`SNAPSHOTS`] that have their runner, with their directories.
fn snapshot_packages() -> impl Iterator<Item = (&'static str, PathBuf)> {
    SNAPSHOTS
        .into_iter()
        .map(|(package, dir)| (package, root().join(dir)))
        .filter(|(_, dir)| dir.join("tests").join("cli_snapshots.rs").is_file())
}

/// Every `NAME.args` in the expected folder: the scripted image run with those scenario words,
/// its decoded log written to `NAME.log`.
fn qemu_logs() -> Result {
    let mut scenarios = Vec::new();
    for entry in read_dir(&expected_dir())? {
        if entry
            .extension()
            .is_some_and(|ext| ext == SCENARIO_EXTENSION)
        {
            scenarios.push(entry);
        }
    }
    if scenarios.is_empty() {
        return Ok(());
    }
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
    let elf = qemu::build_firmware(Image::Scripted)?;
    for scenario in scenarios {
        let text = fs::read_to_string(&scenario)
            .map_err(|error| format!("cannot read {}: {error}", scenario.display()))?;
        let words: Vec<&str> = text.split_whitespace().collect();
        for word in &words {
            parse_setting(word).map_err(|error| format!("{}: {error}", scenario.display()))?;
        }
        eprintln!("xtask: running the QEMU firmware with {words:?}");
        let run = feeder_emulator::run_to_end(&elf, &words, RUN_LIMIT)
            .map_err(|error| format!("{}: {error}", scenario.display()))?;
        if !run.status.success() {
            return Err(format!(
                "the firmware ended with {} running {}; its log:\n{}",
                run.status,
                scenario.display(),
                run.log
            )
            .into());
        }
        write(&scenario.with_extension("log"), run.log.as_bytes())?;
    }
    Ok(())
}

/// The closed-loop co-simulation's golden log, written by its own test (which runs the
/// closed-loop image against `realistic.toml` with the words in `cosim-closed-loop.words`).
fn closed_loop_log() -> Result {
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
    let elf = qemu::build_firmware(Image::ClosedLoop)?;
    exec(
        cargo_test("cosim")
            .args([
                "--",
                "--ignored",
                "the_closed_loop_log_matches_the_golden_file",
            ])
            .env("FEEDER_CLOSED_LOOP_ELF", &elf)
            .env("FEEDER_BLESS", "overwrite"),
    )
}

/// The plant family's fixed sample, written by its own test.
fn family_sample() -> Result {
    exec(
        cargo_test("family")
            .args(["--", "a_fixed_sample"])
            .env("FEEDER_BLESS", "overwrite"),
    )
}

/// The figures' CSVs, written by the `host-sim` CLI (its report on standard output is left out).
fn figures() -> Result {
    for (file, arguments) in FIGURES {
        exec_output(
            host_sim()
                .args(arguments)
                .arg("--csv")
                .arg(expected_dir().join(file))
                .stdout(Stdio::null()),
        )?;
    }
    Ok(())
}

/// The files in `dir`, sorted.
fn read_dir(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries =
        fs::read_dir(dir).map_err(|error| format!("cannot list {}: {error}", dir.display()))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|error| format!("cannot list {}: {error}", dir.display()))?
            .path();
        if path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// The contents of the files in `dirs` (a directory that does not exist has none).
fn contents(dirs: &[PathBuf]) -> Result<BTreeMap<PathBuf, Vec<u8>>> {
    let mut files = BTreeMap::new();
    for dir in dirs.iter().filter(|dir| dir.is_dir()) {
        for path in read_dir(dir)? {
            let bytes = fs::read(&path)
                .map_err(|error| format!("cannot read {}: {error}", path.display()))?;
            files.insert(path, bytes);
        }
    }
    Ok(files)
}

fn write(path: &Path, bytes: &[u8]) -> Result {
    fs::write(path, bytes)
        .map_err(|error| format!("cannot write {}: {error}", path.display()).into())
}

/// Prints each file that is new or changed, relative to the workspace root, on standard output;
/// the count on standard error.
fn report(before: &BTreeMap<PathBuf, Vec<u8>>, after: &BTreeMap<PathBuf, Vec<u8>>) {
    let root = root();
    let name = |path: &Path| {
        path.strip_prefix(&root)
            .unwrap_or(path)
            .display()
            .to_string()
    };
    let mut changes = 0;
    for (path, bytes) in after {
        let change = match before.get(path) {
            None => "new",
            Some(old) if old != bytes => "changed",
            Some(_) => continue,
        };
        println!("{change}: {}", name(path));
        changes += 1;
    }
    if changes == 0 {
        eprintln!(
            "bless: every expected output is unchanged ({} files)",
            after.len()
        );
    } else {
        let files = if changes == 1 { "file" } else { "files" };
        eprintln!("bless: {changes} {files} changed; review them with `git diff`");
    }
}
