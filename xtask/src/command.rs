//! The workspace's places and the commands xtask runs in it: cargo for either workspace, the
//! host binaries, and how a command is run, shown and named when it fails.

use std::io;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::failure::Result;

/// The firmware's target.
pub const THUMB_TARGET: &str = "thumbv7em-none-eabihf";

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// The firmware's own workspace.
pub fn firmware_dir() -> PathBuf {
    root().join("firmware")
}

/// Runs a command to completion, its standard output going to standard error with the rest of
/// what xtask says while it works; fails with its description if it fails.
pub fn exec(command: &mut Command) -> Result {
    exec_output(command.stdout(io::stderr()))
}

/// Runs a command to completion with its standard output on xtask's: the result of the task
/// (a report, or JSON alone); fails with its description if it fails.
pub fn exec_output(command: &mut Command) -> Result {
    let shown = shown(command);
    eprintln!("xtask: running {shown}");
    let status = command
        .status()
        .map_err(|error| format!("cannot start {shown}: {error}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{} failed with {status}", brief(command)).into())
    }
}

/// `command` in a few words, for its failure after [`shown`] has printed it whole: the program,
/// its first argument and, for cargo, the package and what runs after `--`.
fn brief(command: &Command) -> String {
    let arguments: Vec<_> = command.get_args().map(|a| a.to_string_lossy()).collect();
    let program = Path::new(command.get_program());
    let mut words = vec![program
        .file_name()
        .unwrap_or(program.as_os_str())
        .to_string_lossy()];
    words.extend(arguments.first().cloned());
    let after = |flag: &str| {
        let at = arguments.iter().position(|a| a == flag)?;
        arguments.get(at + 1).cloned()
    };
    for flag in ["--package", "--test"] {
        if let Some(value) = after(flag) {
            words.extend([flag.into(), value]);
        }
    }
    if let Some(program) = after("--").filter(|_| arguments.first().is_some_and(|a| a == "run")) {
        words.extend(["--".into(), program]);
    }
    words.join(" ")
}

/// `command` as one would type it in a shell: the directory it runs in when that is not the
/// workspace root, the program's file name (xtask's `PATH` finds it), and the arguments, each
/// in single quotes only where a shell needs them.
pub fn shown(command: &Command) -> String {
    let root = root();
    let mut words = Vec::new();
    if let Some(dir) = command.get_current_dir().filter(|dir| *dir != root) {
        let dir = dir.strip_prefix(&root).unwrap_or(dir);
        words.extend([
            "cd".to_string(),
            quoted(&dir.to_string_lossy()),
            "&&".into(),
        ]);
    }
    let program = Path::new(command.get_program());
    let name = program.file_name().unwrap_or(program.as_os_str());
    words.push(quoted(&name.to_string_lossy()));
    words.extend(command.get_args().map(|arg| quoted(&arg.to_string_lossy())));
    words.join(" ")
}

/// `word` as a shell reads it back: as it is if it holds only characters no shell treats
/// specially, otherwise in single quotes (a quote inside written `'\''`).
fn quoted(word: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./:=,+@%".contains(c);
    if !word.is_empty() && word.chars().all(plain) {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', r"'\''"))
    }
}

/// `cargo` in the workspace root.
pub fn cargo() -> Command {
    let mut command = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    command.current_dir(root());
    command
}

/// `cargo` for the firmware workspace, which keeps its own target directory.
pub fn firmware_cargo() -> Command {
    let mut command = cargo();
    command
        .current_dir(firmware_dir())
        .env_remove("CARGO_TARGET_DIR");
    command
}

/// `cargo test` of the host workspace as the test command builds it: the release profile (with
/// overflow checks, as the tests' own profile has them), every member's features resolved
/// together, so that a step that runs one test target reuses the first step's build instead
/// of building its package again with its own features.
pub fn workspace_test() -> Command {
    let mut command = cargo();
    command.args(["test", "--release", "--locked", "--workspace"]);
    command
}

/// [`workspace_test`] of the integration test target `test` (its name is the workspace's only
/// one of that name).
pub fn cargo_test(test: &str) -> Command {
    let mut command = workspace_test();
    command.args(["--test", test]);
    command
}

/// [`cargo_test`] of the tests of `test` that need the QEMU firmware `elf`.
pub fn ignored_tests(test: &str, elf: &Path) -> Command {
    let mut command = cargo_test(test);
    command
        .args(["--", "--ignored"])
        .env("FEEDER_QEMU_ELF", elf);
    command
}

/// A binary of the host workspace (release build, through `cargo run`) with the arguments
/// that follow.
pub fn workspace_binary(package: &str) -> Command {
    let mut command = cargo();
    command.args([
        "run",
        "--quiet",
        "--release",
        "--locked",
        "--package",
        package,
        "--",
    ]);
    command
}

/// `host-sim` (release build) with the arguments that follow.
pub fn host_sim() -> Command {
    workspace_binary("host-sim")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_is_shown_as_typed_in_a_shell() {
        let mut command = Command::new("/toolchain/bin/cargo");
        command.current_dir(root().join("firmware")).args([
            "run",
            "--",
            "--tcp",
            "127.0.0.1:42493",
            "a b",
            "it's",
            "",
        ]);
        assert_eq!(
            shown(&command),
            r"cd firmware && cargo run -- --tcp 127.0.0.1:42493 'a b' 'it'\''s' ''"
        );
        let mut command = cargo();
        command.arg("line\nbreak");
        assert_eq!(shown(&command), "cargo 'line\nbreak'");
    }

    #[test]
    fn a_failed_command_is_named_in_a_few_words() {
        let mut cosim = host_sim();
        cosim.args(["cosim", "--elf", "fw.elf", "--plant", "plate.toml"]);
        assert_eq!(brief(&cosim), "cargo run --package host-sim -- cosim");
        assert_eq!(
            brief(firmware_cargo().args(["build", "--release", "--locked"])),
            "cargo build"
        );
        assert_eq!(
            brief(cargo_test("qemu_plant").args(["--", "--ignored"])),
            "cargo test --test qemu_plant"
        );
    }
}
