//! The external programs the commands run, installed when missing, and the environment every
//! child process gets.
//!
//! Cargo-installed tools go into the project's own `target/tools` (`cargo install --root`), at
//! pinned versions, and every command xtask starts sees a `PATH` of that directory, the active
//! toolchain and the system's programs, but not `$CARGO_HOME/bin`. A tool that only a
//! developer's machine happens to have is therefore invisible here too, so a missing install
//! step fails on every machine, not only on a fresh one.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

use crate::command::{exec, root, THUMB_TARGET};
use crate::failure::Result;

/// A tool from crates.io, installed with `cargo install --locked` at a pinned version.
struct CargoTool {
    /// The executable, as `.cargo/config.toml` and `feeder-emulator` call it.
    program: &'static str,
    package: &'static str,
    version: &'static str,
    /// An argument it answers with success: flip-link has no `--version`.
    probe: &'static str,
    /// What needs it, for the error message when it cannot be installed.
    needed_by: &'static str,
}

/// The firmware's linker (`firmware/.cargo/config.toml`): stack-overflow protection.
const FLIP_LINK: CargoTool = CargoTool {
    program: "flip-link",
    package: "flip-link",
    version: "0.1.12",
    probe: "--help",
    needed_by: "linking every firmware image (firmware/.cargo/config.toml)",
};

/// Decodes the firmware's defmt log under QEMU.
const DEFMT_PRINT: CargoTool = CargoTool {
    program: feeder_emulator::DECODER,
    package: "defmt-print",
    version: "1.2.0",
    probe: "--version",
    needed_by: "decoding the emulated firmware's log",
};

/// A program from a Debian package, installed with `apt-get` (as root).
struct AptTool {
    program: &'static str,
    package: &'static str,
    needed_by: &'static str,
}

const QEMU: AptTool = AptTool {
    program: feeder_emulator::QEMU,
    package: "qemu-system-arm",
    needed_by: "running the firmware without a board (machine mps2-an386)",
};

const CMAKE: AptTool = AptTool {
    program: "cmake",
    package: "cmake",
    needed_by: "building the G474 twin's CPU engine (unicorn's C code)",
};

/// The Debian package with libclang, which the twin's CPU engine's bindings are generated with.
const LIBCLANG: &str = "libclang-dev";

/// Where the cargo-installed tools live: `target/tools/bin`.
fn tools_root() -> PathBuf {
    root().join("target").join("tools")
}

/// The cargo home whose `bin` holds globally installed tools (hidden from child processes).
fn cargo_home_bin() -> Option<PathBuf> {
    std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|home| Path::new(&home).join(".cargo")))
        .map(|home| home.join("bin"))
}

/// The directory of the toolchain's `cargo` and `rustc` that runs this xtask.
fn toolchain_bin() -> Result<PathBuf> {
    let cargo = std::env::var_os("CARGO").ok_or("CARGO is not set: run me as `cargo xtask`")?;
    Path::new(&cargo)
        .parent()
        .filter(|dir| dir.join("rustc").exists() || dir.join("rustc.exe").exists())
        .map(Path::to_path_buf)
        .ok_or_else(|| format!("no rustc beside {}", Path::new(&cargo).display()).into())
}

/// The `PATH` xtask was started with, kept by [`isolate`]: rustup is looked up on it.
static LAUNCH_PATH: OnceLock<OsString> = OnceLock::new();

/// Carries [`LAUNCH_PATH`] to an xtask that a test started by xtask starts in turn, whose own
/// `PATH` is already the isolated one.
const LAUNCH_PATH_VAR: &str = "FEEDER_XTASK_LAUNCH_PATH";

/// Sets this process's `PATH` (inherited by every command it starts) to `target/tools/bin`,
/// the active toolchain and the rest of `PATH` without `$CARGO_HOME/bin`, and points `CARGO`
/// at the toolchain's cargo rather than the rustup proxy.
pub fn isolate() -> Result {
    let toolchain = toolchain_bin()?;
    let hidden = cargo_home_bin();
    let inherited = std::env::var_os("PATH").unwrap_or_default();
    let launch = std::env::var_os(LAUNCH_PATH_VAR).unwrap_or_else(|| inherited.clone());
    LAUNCH_PATH.get_or_init(|| launch.clone());
    let mut directories = vec![tools_root().join("bin"), toolchain.clone()];
    directories.extend(std::env::split_paths(&inherited).filter(|dir| {
        hidden
            .as_deref()
            .is_none_or(|hidden| !same_dir(dir, hidden))
    }));
    let path: OsString =
        std::env::join_paths(directories).map_err(|error| format!("cannot build PATH: {error}"))?;
    // Single-threaded here: nothing else reads the environment concurrently.
    std::env::set_var("PATH", path);
    std::env::set_var("CARGO", toolchain.join("cargo"));
    std::env::set_var(LAUNCH_PATH_VAR, launch);
    Ok(())
}

fn same_dir(a: &Path, b: &Path) -> bool {
    a == b || matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b)
}

fn answers(program: &str, probe: &str) -> bool {
    Command::new(program)
        .arg(probe)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|status| status.success())
}

/// Adds the thumb target to the active toolchain if missing (rustup is looked up on the `PATH`
/// xtask was started with).
fn ensure_thumb_target() -> Result {
    let rustup = |args: &[&str]| {
        let mut command = Command::new("rustup");
        command.args(args);
        if let Some(path) = LAUNCH_PATH.get() {
            command.env("PATH", path);
        }
        command
    };
    let installed = rustup(&["target", "list", "--installed"])
        .output()
        .map_err(|error| {
            format!("cannot run rustup ({error}): add the target by hand with `rustup target add {THUMB_TARGET}`")
        })?;
    if String::from_utf8_lossy(&installed.stdout)
        .lines()
        .any(|line| line.trim() == THUMB_TARGET)
    {
        return Ok(());
    }
    exec(&mut rustup(&["target", "add", THUMB_TARGET]))
}

fn ensure_cargo_tool(tool: &CargoTool) -> Result {
    if answers(tool.program, tool.probe) {
        return Ok(());
    }
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    exec(
        Command::new(cargo)
            .current_dir(root())
            .args(["install", "--locked", "--root"])
            .arg(tools_root())
            .arg(tool.package)
            .args(["--version", tool.version]),
    )
    .map_err(|error| {
        format!(
            "{} is needed for {} and could not be installed: {error}",
            tool.program, tool.needed_by
        )
    })?;
    if answers(tool.program, tool.probe) {
        Ok(())
    } else {
        Err(format!(
            "{} was installed into {} but does not run",
            tool.program,
            tools_root().display()
        )
        .into())
    }
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|output| output.stdout.trim_ascii() == b"0")
}

/// Whether dpkg lists `package` as installed.
fn package_installed(package: &str) -> bool {
    Command::new("dpkg-query")
        .args(["--show", "--showformat=${Status}", package])
        .output()
        .is_ok_and(|output| output.status.success() && output.stdout == b"install ok installed")
}

/// Where apt-get looks for its sources: the system's, or the system's and its release's
/// backports suite for one install.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Sources<'a> {
    System,
    /// The directory of the system's sources and the backports suite, and the suite's name.
    Backports {
        parts: &'a Path,
        suite: &'a str,
    },
}

/// `apt-get` with `sources`: the backports suite preferred for what it installs.
fn apt_get(sources: Sources<'_>) -> Command {
    let mut command = Command::new("apt-get");
    if let Sources::Backports { parts, suite } = sources {
        command
            .arg("-o")
            .arg(format!("Dir::Etc::sourceparts={}", parts.display()))
            .args(["--target-release", suite]);
    }
    command.env("DEBIAN_FRONTEND", "noninteractive");
    command
}

/// `apt-get install` of `packages` and what they depend on, and nothing else: no recommended
/// packages, and no removal (apt-get refuses the whole install instead); with `simulate`, only
/// what it would do.
fn apt_install(packages: &[&str], simulate: bool, sources: Sources<'_>) -> Command {
    let mut command = apt_get(sources);
    command
        .args(["install", "--yes", "--no-install-recommends", "--no-remove"])
        .args(simulate.then_some("--simulate"))
        .args(packages);
    command
}

/// The release's codename (`VERSION_CODENAME` of `/etc/os-release`).
fn codename(os_release: &str) -> Option<&str> {
    os_release
        .lines()
        .find_map(|line| line.strip_prefix("VERSION_CODENAME="))
        .map(|name| name.trim().trim_matches('"'))
        .filter(|name| !name.is_empty())
}

/// The Debian archive's entry for `suite`, in deb822 form.
fn backports_source(suite: &str) -> String {
    format!(
        "Types: deb\nURIs: http://deb.debian.org/debian\nSuites: {suite}\nComponents: main\n\
         Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg\n"
    )
}

/// A sources directory for one install: the system's enabled sources and `suite`'s, under
/// `target/tools/apt` (the system's own sources are left as they are).
fn backports_parts(suite: &str) -> Result<PathBuf> {
    let parts = tools_root().join("apt").join("sources.list.d");
    if parts.exists() {
        std::fs::remove_dir_all(&parts)
            .map_err(|error| format!("cannot clear {}: {error}", parts.display()))?;
    }
    std::fs::create_dir_all(&parts)
        .map_err(|error| format!("cannot create {}: {error}", parts.display()))?;
    let system = Path::new("/etc/apt/sources.list.d");
    for entry in std::fs::read_dir(system).into_iter().flatten().flatten() {
        let path = entry.path();
        let enabled = path
            .extension()
            .is_some_and(|extension| extension == "list" || extension == "sources");
        if enabled {
            std::fs::copy(&path, parts.join(entry.file_name()))
                .map_err(|error| format!("cannot copy {}: {error}", path.display()))?;
        }
    }
    std::fs::write(
        parts.join(format!("{suite}.sources")),
        backports_source(suite),
    )
    .map_err(|error| format!("cannot write {suite}'s source: {error}"))?;
    Ok(parts)
}

/// The packages an `apt-get --simulate` run would install (its `Inst` lines).
fn simulated_installs(simulation: &str) -> Vec<&str> {
    simulation
        .lines()
        .filter_map(|line| line.strip_prefix("Inst "))
        .filter_map(|rest| rest.split_whitespace().next())
        .collect()
}

fn ensure_apt_tool(tool: &AptTool) -> Result {
    if answers(tool.program, "--version") {
        return Ok(());
    }
    if package_installed(tool.package) {
        return Err(format!(
            "{} is installed but `{} --version` does not run; it is needed for {}",
            tool.package, tool.program, tool.needed_by
        )
        .into());
    }
    let by_hand = format!(
        "{} is needed for {}: install it with `sudo apt-get install --no-install-recommends \
         --no-remove {}` (Debian/Ubuntu)",
        tool.program, tool.needed_by, tool.package
    );
    if !is_root() {
        return Err(format!("{by_hand}; xtask installs it itself only as root").into());
    }
    install_packages(&[tool.package]).map_err(|error| format!("{by_hand} ({error})"))?;
    if answers(tool.program, "--version") {
        Ok(())
    } else {
        Err(by_hand.into())
    }
}

/// Installs `packages` with apt-get after saying on standard error what that installs; a plan
/// that would remove any package is refused by apt-get, and nothing is installed. Where the
/// release's own packages would remove some (a newer build of a related package came from the
/// release's backports, as `qemu-utils` does on some machines), the same install is tried with
/// the backports suite preferred.
fn install_packages(packages: &[&str]) -> Result {
    exec(Command::new("apt-get").arg("update"))?;
    let Err(error) = install_from(packages, Sources::System) else {
        return Ok(());
    };
    let os_release = std::fs::read_to_string("/etc/os-release").unwrap_or_default();
    let Some(release) = codename(&os_release) else {
        return Err(error);
    };
    let suite = format!("{release}-backports");
    eprintln!("xtask: {error}; trying {suite}");
    let parts = backports_parts(&suite)?;
    let sources = Sources::Backports {
        parts: &parts,
        suite: &suite,
    };
    exec(apt_get(sources).arg("update"))?;
    install_from(packages, sources)
        .map_err(|again| format!("{error}; from {suite}: {again}").into())
}

/// [`install_packages`] from `sources`, after the package lists are up to date.
fn install_from(packages: &[&str], sources: Sources<'_>) -> Result {
    let simulation = apt_install(packages, true, sources)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|error| format!("cannot run apt-get: {error}"))?;
    if !simulation.status.success() {
        return Err(format!(
            "apt-get cannot install {} without removing packages or otherwise ({})",
            packages.join(" "),
            simulation.status
        )
        .into());
    }
    let simulation = String::from_utf8_lossy(&simulation.stdout);
    eprintln!(
        "xtask: installing with apt-get, removing nothing: {}",
        simulated_installs(&simulation).join(" ")
    );
    exec(&mut apt_install(packages, false, sources))
}

/// The thumb target and the linker every firmware build needs.
pub fn ensure_linker() -> Result {
    ensure_thumb_target()?;
    ensure_cargo_tool(&FLIP_LINK)
}

/// What building the G474 twin's CPU engine needs: cmake and libclang.
pub fn ensure_twin_build() -> Result {
    ensure_apt_tool(&CMAKE)?;
    if package_installed(LIBCLANG) {
        return Ok(());
    }
    let by_hand = format!(
        "libclang is needed for building the G474 twin's CPU engine (its bindings): install it \
         with `sudo apt-get install --no-install-recommends --no-remove {LIBCLANG}` \
         (Debian/Ubuntu)"
    );
    if !is_root() {
        return Err(format!("{by_hand}; xtask installs it itself only as root").into());
    }
    install_packages(&[LIBCLANG]).map_err(|error| format!("{by_hand} ({error})").into())
}

/// The emulator and the log decoder the QEMU runs need.
pub fn ensure_emulation() -> Result {
    ensure_apt_tool(&QEMU)?;
    ensure_cargo_tool(&DEFMT_PRINT)
}

#[cfg(test)]
mod tests {
    use std::ffi::OsStr;

    use super::*;

    #[test]
    fn apt_get_installs_only_the_packages_asked_for_and_removes_nothing() {
        let install = apt_install(&["qemu-system-arm"], false, Sources::System);
        assert_eq!(install.get_program(), "apt-get");
        assert_eq!(
            install.get_args().collect::<Vec<_>>(),
            [
                "install",
                "--yes",
                "--no-install-recommends",
                "--no-remove",
                "qemu-system-arm"
            ]
        );
        let simulate = apt_install(&["qemu-system-arm"], true, Sources::System);
        let simulate: Vec<_> = simulate.get_args().collect();
        assert!(simulate.contains(&OsStr::new("--no-remove")));
        assert!(simulate.contains(&OsStr::new("--simulate")));
        assert!(install
            .get_envs()
            .any(|(key, value)| key == "DEBIAN_FRONTEND"
                && value.is_some_and(|value| value == "noninteractive")));
    }

    #[test]
    fn a_backports_install_reads_the_suite_beside_the_systems_sources_and_prefers_it() {
        let parts = Path::new("/tmp/parts");
        let install = apt_install(
            &["qemu-system-arm"],
            false,
            Sources::Backports {
                parts,
                suite: "bookworm-backports",
            },
        );
        let args: Vec<_> = install.get_args().collect();
        assert_eq!(
            args[..4],
            [
                "-o",
                "Dir::Etc::sourceparts=/tmp/parts",
                "--target-release",
                "bookworm-backports"
            ]
        );
        assert!(args.contains(&OsStr::new("--no-remove")));
        assert_eq!(
            codename("NAME=\"Debian GNU/Linux\"\nVERSION_CODENAME=bookworm\n"),
            Some("bookworm")
        );
        assert_eq!(codename("NAME=Other\n"), None);
        assert!(backports_source("bookworm-backports").contains("Suites: bookworm-backports\n"));
    }

    #[test]
    fn the_packages_to_install_are_read_from_the_simulation() {
        let simulation = "Reading package lists...\n\
            The following NEW packages will be installed:\n  qemu-system-arm qemu-system-common\n\
            Inst qemu-system-common (1:7.2+dfsg-7 Debian:12 [amd64])\n\
            Inst qemu-system-arm (1:7.2+dfsg-7 Debian:12 [amd64])\n\
            Conf qemu-system-common (1:7.2+dfsg-7 Debian:12 [amd64])\n";
        assert_eq!(
            simulated_installs(simulation),
            ["qemu-system-common", "qemu-system-arm"]
        );
    }

    #[test]
    fn a_package_that_is_not_installed_is_not_taken_for_installed() {
        assert!(!package_installed("feeder-no-such-package"));
    }
}
