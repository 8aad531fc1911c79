//! Snapshots of `feeder-ctl`'s output and exit code, one case per file in `tests/cmd/`: the
//! help, refused arguments and consoles that cannot be reached. `cargo xtask bless` (or
//! `TRYCMD=overwrite`) writes the expected output anew after an intended change; a new case
//! starts with empty `.stdout` and `.stderr` files beside its `.toml`.

#[test]
fn command_line_snapshots() {
    trycmd::TestCases::new()
        .register_bin(
            "feeder-ctl",
            std::path::Path::new(env!("CARGO_BIN_EXE_feeder-ctl")),
        )
        .case("tests/cmd/*.toml");
}
