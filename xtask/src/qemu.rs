//! The QEMU firmware images: which features each has and where it is built. `feeder-emulator`
//! runs them.

use std::path::PathBuf;

use crate::command::{exec, firmware_cargo, firmware_dir, THUMB_TARGET};
use crate::failure::Result;

/// The QEMU firmware with the scripted operator, with the serial console instead, or with the
/// scripted operator and the lockstep link to a plant on the host, without or with the plant's
/// encoder (open or closed loop).
#[derive(Clone, Copy)]
pub enum Image {
    Scripted,
    Console,
    Cosim,
    /// The co-simulated image with the plant's encoder: the closed loop.
    ClosedLoop,
    /// The closed loop with the serial console instead of the scripted operator.
    ClosedLoopConsole,
}

/// Builds a QEMU firmware image (in its own target directory, beside the board image) and
/// returns the ELF's path.
pub fn build_firmware(image: Image) -> Result<PathBuf> {
    let (directory, features) = match image {
        Image::Scripted => ("qemu", "board-qemu"),
        Image::Console => ("qemu-console", "board-qemu,console"),
        Image::Cosim => ("qemu-cosim", "cosim"),
        Image::ClosedLoop => ("qemu-closed-loop", "cosim-encoder"),
        Image::ClosedLoopConsole => ("qemu-closed-loop-console", "cosim-encoder,console"),
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
