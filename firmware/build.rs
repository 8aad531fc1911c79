//! Puts the selected board's `memory.x` on the linker search path: the repository's top-level
//! one for the NUCLEO-G474RE, `qemu/memory.x` for QEMU's mps2-an386.

use std::path::PathBuf;

fn main() {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let memory_dir = if std::env::var_os("CARGO_FEATURE_BOARD_QEMU").is_some() {
        manifest_dir.join("qemu")
    } else {
        manifest_dir
            .parent()
            .expect("firmware/ lives inside the repository")
            .to_path_buf()
    };
    println!("cargo:rustc-link-search={}", memory_dir.display());
    println!(
        "cargo:rerun-if-changed={}",
        memory_dir.join("memory.x").display()
    );
    println!("cargo:rerun-if-changed=build.rs");
}
