//! The command line's output and exit codes, errors included, against the snapshots in
//! `tests/cmd/`; `TRYCMD=overwrite` rewrites them from the binary's present output.

#[test]
fn cli_snapshots() {
    trycmd::TestCases::new()
        .case("tests/cmd/*.toml")
        .case("tests/cmd/*.trycmd");
}
