//! Random subcommands with random and extreme arguments and garbage files: the binary exits with
//! 0, 1 (a run that failed its verdict, which its report names) or 2, never panics, is never
//! killed, prints at most one `error:` line, and finishes in bounded time and memory.
//!
//! Counts are drawn around their limits but never at large valid values, and the commands that
//! run many operating points always get a count: a point whose part never settles runs to the
//! simulator's cycle limit, so a run of many such points may rightly take a while. The limits
//! themselves are tested in `cli.rs`.

mod support;

use std::sync::OnceLock;
use std::time::Duration;

use proptest::prelude::*;
use proptest::sample::select;

use support::{golden_log, run, scratch_dir, Outcome};

/// A run that takes longer than this fails the property.
const TIME_LIMIT: Duration = Duration::from_secs(10);

#[derive(Debug, Clone, Copy)]
enum Kind {
    Real,
    List,
    Count,
    Clock,
    Switch,
    Csv,
    Plot,
    Input,
}

const WAVE: &[(&str, Kind)] = &[
    ("--freq-hz", Kind::Real),
    ("--duty", Kind::Real),
    ("--stroke-m", Kind::Real),
    ("--accel-mps2", Kind::Real),
];
const CONTACT: &[(&str, Kind)] = &[
    ("--mu", Kind::Real),
    ("--mu-static", Kind::Real),
    ("--gravity-mps2", Kind::Real),
    ("--mass-kg", Kind::Real),
    ("--force-n", Kind::Real),
];
const TIMING: &[(&str, Kind)] = &[("--clock-hz", Kind::Clock), ("--exact-times", Kind::Switch)];
const OUTPUT: &[(&str, Kind)] = &[
    ("--json", Kind::Switch),
    ("--csv", Kind::Csv),
    ("--plot", Kind::Plot),
];
/// A token no subcommand knows.
const STRAY: &[(&str, Kind)] = &[("-0", Kind::Switch)];

/// A subcommand, the count it always gets (if any) and the flags drawn from.
type Command = (
    &'static str,
    Option<&'static str>,
    Vec<(&'static str, Kind)>,
);

fn commands() -> Vec<Command> {
    let with = |own: &[(&'static str, Kind)], groups: &[&[(&'static str, Kind)]]| {
        let mut flags = own.to_vec();
        for group in groups.iter().chain([&STRAY, &OUTPUT]) {
            flags.extend_from_slice(group);
        }
        flags
    };
    vec![
        (
            "simulate",
            None,
            with(&[("--cycles", Kind::Count)], &[WAVE, CONTACT, TIMING]),
        ),
        (
            "sweep",
            Some("--duties"),
            with(
                &[("--freq-hz", Kind::Real), ("--accel-mps2", Kind::List)],
                &[CONTACT, TIMING],
            ),
        ),
        (
            "viscosity",
            Some("--points"),
            with(
                &[
                    ("--freq-hz", Kind::Real),
                    ("--duty", Kind::Real),
                    ("--accel-mps2", Kind::Real),
                    ("--mu", Kind::Real),
                    ("--mu-static", Kind::Real),
                    ("--gravity-mps2", Kind::Real),
                    ("--mass-kg", Kind::Real),
                    ("--force-min-n", Kind::Real),
                    ("--force-max-n", Kind::Real),
                ],
                &[TIMING],
            ),
        ),
        (
            "saturation",
            Some("--points"),
            with(
                &[
                    ("--freq-hz", Kind::Real),
                    ("--mu", Kind::List),
                    ("--accel-min-mps2", Kind::Real),
                    ("--accel-max-mps2", Kind::Real),
                    ("--gravity-mps2", Kind::Real),
                ],
                &[],
            ),
        ),
        (
            "trace",
            None,
            with(&[("--cycles", Kind::Count)], &[WAVE, CONTACT, TIMING]),
        ),
        (
            "hil",
            None,
            with(
                &[("--input", Kind::Input), ("--open-ended", Kind::Switch)],
                &[CONTACT],
            ),
        ),
    ]
}

fn real() -> BoxedStrategy<String> {
    prop_oneof![
        3 => (0.5..1.0f64).prop_map(|value| value.to_string()),
        3 => (-3.0..3.0f64).prop_map(|exponent| format!("{}", 10f64.powf(exponent))),
        2 => select(vec![
            "nan", "NaN", "inf", "-inf", "infinity", "0", "-0", "-1", "1", "0.6", "1e300", "-1e300",
            "1e-300", "4e-324", "1.8e308", "18446744073709551615", "-0.0001", "", " ", "x", "--json",
            "1,2",
        ])
        .prop_map(String::from),
        1 => any::<f64>().prop_map(|value| value.to_string()),
        1 => (-1e3..1e3f64).prop_map(|value| value.to_string()),
        1 => "[^\\x00]{0,12}",
    ]
    .boxed()
}

fn value(kind: Kind, files: &Files) -> BoxedStrategy<Option<String>> {
    let some = |strategy: BoxedStrategy<String>| strategy.prop_map(Some).boxed();
    match kind {
        Kind::Switch => Just(None).boxed(),
        Kind::Real => some(real()),
        Kind::List => some(
            proptest::collection::vec(real(), 1..4)
                .prop_map(|values| values.join(","))
                .boxed(),
        ),
        Kind::Count => some(
            prop_oneof![
                select(vec![
                    "0",
                    "1",
                    "2",
                    "3",
                    "10001",
                    "10000001",
                    "100000000",
                    "18446744073709551615",
                    "18446744073709551616",
                    "-1",
                    "1e300",
                    "nan",
                    "",
                    "x",
                ])
                .prop_map(String::from),
                (1u64..4).prop_map(|count| count.to_string()),
            ]
            .boxed(),
        ),
        Kind::Clock => some(
            select(vec![
                "0",
                "1",
                "1000",
                "1000000",
                "4294967295",
                "4294967296",
                "-5",
                "1e6",
                "x",
            ])
            .prop_map(String::from)
            .boxed(),
        ),
        Kind::Csv => some(select(files.csv.clone()).boxed()),
        Kind::Plot => some(select(files.plot.clone()).boxed()),
        Kind::Input => some(select(files.input.clone()).boxed()),
    }
}

/// Output paths and input files shared by every case.
struct Files {
    csv: Vec<String>,
    plot: Vec<String>,
    input: Vec<String>,
}

fn files() -> &'static Files {
    static FILES: OnceLock<Files> = OnceLock::new();
    FILES.get_or_init(|| {
        let dir = scratch_dir("props");
        let at = |name: &str| dir.join(name).to_string_lossy().into_owned();
        let directory = dir.to_string_lossy().into_owned();
        let golden = std::fs::read_to_string(golden_log()).expect("golden log");
        let inputs: Vec<(&str, Vec<u8>)> = vec![
            ("empty.log", Vec::new()),
            ("binary.bin", (0..=255u8).cycle().take(3000).collect()),
            (
                "text.log",
                b"INFO  hello\nERROR something failed\n".to_vec(),
            ),
            ("golden.log", golden.clone().into_bytes()),
            (
                "cut.log",
                golden
                    .lines()
                    .take(40)
                    .collect::<Vec<_>>()
                    .join("\n")
                    .into_bytes(),
            ),
            ("extreme.log", extreme_events().into_bytes()),
            (
                "shuffled.log",
                golden
                    .lines()
                    .rev()
                    .collect::<Vec<_>>()
                    .join("\n")
                    .into_bytes(),
            ),
        ];
        let mut input: Vec<String> = inputs
            .iter()
            .map(|(name, bytes)| {
                std::fs::write(dir.join(name), bytes).expect("write an input");
                at(name)
            })
            .collect();
        input.extend([directory.clone(), at("missing.log")]);
        let unwritable = [
            directory.clone(),
            "/nonexistent/dir/out".into(),
            String::new(),
        ];
        Files {
            csv: [at("out.csv"), at("line\nbreak.csv")]
                .into_iter()
                .chain(unwritable.clone())
                .collect(),
            plot: [
                at("out.svg"),
                at("out.png"),
                at("out.jpg"),
                at("no/such/out.svg"),
            ]
            .into_iter()
            .chain(unwritable)
            .collect(),
            input,
        }
    })
}

/// A log of well-formed events with values at the edges of their types.
fn extreme_events() -> String {
    let max = u64::MAX;
    [
        "EVT plan tick=0 period_s=0.02 duty=0.586 stroke_m=0.0025 clock_hz=1000000 ramp=0".into(),
        "EVT start tick=0".into(),
        format!("EVT seg cycle=0 kind=accelerate planned=0 actual={max} ticks=4294967295 level=1 step=1 steps=1"),
        format!("EVT seg cycle={max} kind=plateau planned={max} actual=0 ticks=0 level=0 step=65535 steps=0"),
        "EVT plan tick=5 period_s=1e-300 duty=0.999999 accel_mps2=1e300 clock_hz=4294967295 ramp=65535".into(),
        format!("EVT seg cycle=1 kind=idle planned=9223372036854775808 actual={max} ticks=1 level=-1 step=0 steps=1"),
        format!("EVT halt tick={max}"),
        format!("EVT end tick={max}"),
    ]
    .join("\n")
}

/// A subcommand and its arguments.
fn invocation() -> impl Strategy<Value = Vec<String>> {
    let files = files();
    let commands = commands();
    (0..commands.len()).prop_flat_map(move |index| {
        let (name, count, flags) = commands[index].clone();
        let flag = (0..flags.len()).prop_flat_map(move |pick| {
            let (flag, kind) = flags[pick];
            value(kind, files).prop_map(move |value| (flag, value))
        });
        let picked = proptest::collection::vec(flag, 0..5);
        (value(Kind::Count, files), picked).prop_map(move |(size, picked)| {
            let mut args = vec![name.to_string()];
            if let Some(count) = count {
                args.push(count.to_string());
                args.extend(size);
            }
            for (flag, value) in picked {
                args.push(flag.to_string());
                args.extend(value);
            }
            args
        })
    })
}

fn check(outcome: &Outcome) -> Result<(), TestCaseError> {
    prop_assert!(
        outcome.status.is_some(),
        "ran past {TIME_LIMIT:?}: {outcome:#?}"
    );
    prop_assert!(
        outcome.signal().is_none(),
        "killed by a signal: {outcome:#?}"
    );
    prop_assert!(!outcome.stderr.contains("panicked"), "{outcome:#?}");
    match outcome.code() {
        Some(0) => prop_assert_eq!(&outcome.stderr, "", "{:#?}", outcome),
        Some(1) => {
            prop_assert_eq!(&outcome.stderr, "", "{:#?}", outcome);
            prop_assert!(
                outcome.stdout.contains(": FAILED (")
                    || outcome.stdout.contains("\"passed\": false"),
                "{outcome:#?}"
            );
        }
        Some(2) => {
            let lines = outcome.stderr_lines();
            prop_assert_eq!(lines.len(), 1, "{:#?}", outcome);
            prop_assert!(lines[0].starts_with("error: "), "{outcome:#?}");
        }
        _ => prop_assert!(false, "exit code other than 0, 1 or 2: {outcome:#?}"),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn any_input_ends_in_a_result_or_one_error_line(args in invocation()) {
        check(&run(&args, TIME_LIMIT))?;
    }
}
