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

/// Builds a QEMU firmware image and returns the path of its ELF. Every image is built in one
/// target directory, so that the dependencies they share are built once, and copied out of it
/// under its own name (`firmware/target/qemu/images/`), so that a later build leaves it be.
pub fn build_firmware(image: Image) -> Result<PathBuf> {
    let (name, features) = match image {
        Image::Scripted => ("qemu", "board-qemu"),
        Image::Console => ("qemu-console", "board-qemu,console"),
        Image::Cosim => ("qemu-cosim", "cosim"),
        Image::ClosedLoop => ("qemu-closed-loop", "cosim-encoder"),
        Image::ClosedLoopConsole => ("qemu-closed-loop-console", "cosim-encoder,console"),
    };
    let target_dir = firmware_dir().join("target").join("qemu");
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
    let built = target_dir
        .join(THUMB_TARGET)
        .join("release")
        .join("feeder-firmware");
    let images = target_dir.join("images");
    std::fs::create_dir_all(&images)
        .map_err(|error| format!("cannot make {}: {error}", images.display()))?;
    let elf = images.join(name);
    std::fs::copy(&built, &elf).map_err(|error| {
        format!(
            "cannot copy {} to {}: {error}",
            built.display(),
            elf.display()
        )
    })?;
    Ok(elf)
}
