//! Puts the repository's top-level `memory.x` on the linker search path.

use std::path::PathBuf;

fn main() {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let repo_dir = manifest_dir
        .parent()
        .expect("firmware/ lives inside the repository");
    println!("cargo:rustc-link-search={}", repo_dir.display());
    println!(
        "cargo:rerun-if-changed={}",
        repo_dir.join("memory.x").display()
    );
    println!("cargo:rerun-if-changed=build.rs");
}
