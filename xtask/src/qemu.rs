//! The emulated board: building the QEMU firmware and running it with its decoded log piped
//! onward.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use crate::{exec, firmware_cargo, firmware_dir, Result, THUMB_TARGET};

/// `-icount shift=4`: one instruction is 16 ns of virtual time, so runs are deterministic.
const ICOUNT_SHIFT: &str = "4";

/// The QEMU firmware with the scripted operator, or with the serial console instead.
#[derive(Clone, Copy)]
pub enum Image {
    Scripted,
    Console,
}

/// Builds a QEMU firmware image (in its own target directory, beside the board image) and
/// returns the ELF's path.
pub fn build_firmware(image: Image) -> Result<PathBuf> {
    let (directory, features) = match image {
        Image::Scripted => ("qemu", "board-qemu"),
        Image::Console => ("qemu-console", "board-qemu,console"),
    };
    let target_dir = firmware_dir().join("target").join(directory);
    exec(
        firmware_cargo()
            .args([
                "build",
                "--release",
                "--locked",
                "--no-default-features",
                "--features",
                features,
                "--target-dir",
            ])
            .arg(&target_dir),
    )?;
    Ok(target_dir
        .join(THUMB_TARGET)
        .join("release")
        .join("feeder-firmware"))
}

/// Where QEMU connects the board's UART0 (the serial console of the console image).
#[derive(Clone, Copy)]
pub enum Serial {
    /// Not connected: the scripted image has no console.
    None,
    /// A TCP server on this loopback port that a client may connect to at any time.
    Tcp { port: u16 },
}

impl Serial {
    fn backend(self) -> String {
        match self {
            Serial::None => "none".into(),
            Serial::Tcp { port } => format!("tcp:127.0.0.1:{port},server=on,wait=off"),
        }
    }
}

/// QEMU running `elf` with the scenario arguments (`key=value`) and UART0 on `serial`; the
/// firmware's defmt output appears on QEMU's stdout.
pub fn command(elf: &Path, scenario: &[String], serial: Serial) -> Command {
    // The first argument is the program's name, as in C's argv: without any `arg=`, QEMU would
    // pass the kernel's path in its place.
    let mut semihosting = String::from("enable=on,target=native,arg=feeder-firmware");
    for argument in scenario {
        semihosting.push_str(",arg=");
        semihosting.push_str(argument);
    }
    let mut command = Command::new("qemu-system-arm");
    command
        .args([
            "-machine",
            "mps2-an386",
            "-cpu",
            "cortex-m4",
            "-display",
            "none",
            "-monitor",
            "none",
            "-serial",
            &serial.backend(),
        ])
        .args([
            "-semihosting-config",
            &semihosting,
            "-icount",
            &format!("shift={ICOUNT_SHIFT}"),
            "-kernel",
        ])
        .arg(elf);
    command
}

/// Starts QEMU and defmt-print; the decoded log goes to `decoded` (the returned decoder's
/// stdout when that is [`Stdio::piped`]).
pub fn spawn_decoded(
    elf: &Path,
    scenario: &[String],
    serial: Serial,
    decoded: Stdio,
) -> Result<(Child, Child)> {
    let mut emulator = command(elf, scenario, serial)
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|error| format!("cannot start qemu-system-arm: {error}"))?;
    let raw = emulator.stdout.take().ok_or("no QEMU output")?;
    let decoder = Command::new("defmt-print")
        .arg("-e")
        .arg(elf)
        .stdin(raw)
        .stdout(decoded)
        .spawn();
    match decoder {
        Ok(decoder) => Ok((emulator, decoder)),
        Err(error) => {
            let _ = emulator.kill();
            let _ = emulator.wait();
            Err(format!("cannot start defmt-print: {error}"))
        }
    }
}
