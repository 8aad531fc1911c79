//! The documentation's sessions: every `console` block in `README.md` and `docs/*.md` is run from
//! the repository's root, and the binary must print what the page shows (`[..]` where a run
//! differs: a speed, a wall time). `TRYCMD=overwrite` writes the pages' blocks anew from the
//! binary's present output, for review with `git diff`.

#[test]
fn documented_sessions_print_what_the_pages_show() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    std::env::set_current_dir(&root).expect("the repository's root");
    trycmd::TestCases::new().case("README.md").case("docs/*.md");
}
