//! The QEMU firmware images: which features each has and where it is built. `feeder-emulator`
//! runs them.

use std::path::PathBuf;

use crate::{exec, firmware_cargo, firmware_dir, Result, THUMB_TARGET};

/// The QEMU firmware with the scripted operator, with the serial console instead, or with the
/// scripted operator and the lockstep link to a plant on the host.
#[derive(Clone, Copy)]
pub enum Image {
    Scripted,
    Console,
    Cosim,
}

/// Builds a QEMU firmware image (in its own target directory, beside the board image) and
/// returns the ELF's path.
pub fn build_firmware(image: Image) -> Result<PathBuf> {
    let (directory, features) = match image {
        Image::Scripted => ("qemu", "board-qemu"),
        Image::Console => ("qemu-console", "board-qemu,console"),
        Image::Cosim => ("qemu-cosim", "cosim"),
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
