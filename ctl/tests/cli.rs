//! `feeder-ctl`'s command line against a stand-in console on a loopback port: negative values
//! after a space reach the firmware as typed, and no argument, however hostile, makes the tool
//! panic, hang or exit with anything but 0 (`OK`), 1 (`ERR`) or 2 (refused or unreachable).

use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::process::{Command, Output, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use proptest::prelude::*;

/// Longest one invocation may take: every connection is local and every timeout short.
const INVOCATION_LIMIT: Duration = Duration::from_secs(10);

/// A console that answers each line with `reply(line)` and returns the lines it received.
fn stand_in_console(reply: fn(&str) -> String) -> (String, thread::JoinHandle<Vec<String>>) {
    let listener = TcpListener::bind("127.0.0.1:0").expect("a loopback port");
    let address = listener.local_addr().expect("bound address").to_string();
    let server = thread::spawn(move || {
        let (stream, _) = listener.accept().expect("feeder-ctl connects");
        let mut writer = stream.try_clone().expect("a second handle");
        let mut received = Vec::new();
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { break };
            let line = line.trim_end_matches('\r').to_string();
            writer
                .write_all(format!("{}\r\n", reply(&line)).as_bytes())
                .expect("reply sent");
            received.push(line);
        }
        received
    });
    (address, server)
}

/// Runs feeder-ctl to completion, killing it (and failing) past [`INVOCATION_LIMIT`].
fn feeder_ctl(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_feeder-ctl"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("feeder-ctl starts");
    let started = Instant::now();
    while child.try_wait().expect("waitable").is_none() {
        if started.elapsed() > INVOCATION_LIMIT {
            let _ = child.kill();
            panic!("feeder-ctl {args:?} still ran after {INVOCATION_LIMIT:?}");
        }
        thread::sleep(Duration::from_millis(5));
    }
    child.wait_with_output().expect("output")
}

#[test]
fn a_negative_value_after_a_space_is_sent_as_typed() {
    let (address, server) = stand_in_console(|line| {
        if line == "set duty -0.5" {
            "ERR 43 duty cycle -0.5 must be above 0.5; nothing changed".into()
        } else {
            format!("ERR 1 unexpected `{line}`")
        }
    });
    let output = feeder_ctl(&[
        "--tcp",
        &address,
        "--timeout-ms",
        "2000",
        "set",
        "duty",
        "-0.5",
    ]);
    assert_eq!(output.status.code(), Some(1), "ERR replies exit with 1");
    assert_eq!(
        String::from_utf8_lossy(&output.stdout),
        "ERR 43 duty cycle -0.5 must be above 0.5; nothing changed\n"
    );
    assert_eq!(server.join().unwrap(), ["set duty -0.5"]);
}

#[test]
fn a_negative_timeout_after_a_space_is_refused_with_its_value_named() {
    let output = feeder_ctl(&["--tcp", "127.0.0.1:9", "--timeout-ms", "-5", "status"]);
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("'-5'") && stderr.contains("1..=3600000"),
        "{stderr}"
    );
}

#[test]
fn an_unreachable_console_is_one_line_naming_the_address() {
    let unused = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = unused.local_addr().unwrap().to_string();
    drop(unused);
    let output = feeder_ctl(&["--tcp", &address, "status"]);
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains(&address), "{stderr}");
}

/// Values a hostile or careless operator types for a number or a name.
fn hostile_value() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("-1".to_string()),
        Just("0".to_string()),
        Just("-0".to_string()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e300".to_string()),
        Just("18446744073709551616".to_string()),
        Just("4294967295".to_string()),
        Just("".to_string()),
        Just("--".to_string()),
        Just("/dev/null".to_string()),
        Just("/nonexistent/tty".to_string()),
        any::<i64>().prop_map(|n| n.to_string()),
        "[ -~]{0,12}",
    ]
}

/// `--tcp` addresses that are malformed or closed, never a name to look up: the test sends
/// nothing beyond the loopback interface.
fn hostile_address() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("127.0.0.1:1".to_string()),
        Just("127.0.0.1:0".to_string()),
        Just("127.0.0.1".to_string()),
        Just("127.0.0.1:-5".to_string()),
        Just("127.0.0.1:99999".to_string()),
        Just("[::1]:1".to_string()),
        Just("".to_string()),
        Just("-1".to_string()),
        Just(":".to_string()),
    ]
}

fn hostile_arguments() -> impl Strategy<Value = Vec<String>> {
    let pair = prop_oneof![
        hostile_value().prop_map(|value| vec!["--port".to_string(), value]),
        hostile_value().prop_map(|value| vec!["--baud".to_string(), value]),
        hostile_value().prop_map(|value| vec!["--timeout-ms".to_string(), value]),
        hostile_value().prop_map(|value| vec!["--bogus".to_string(), value]),
        hostile_address().prop_map(|address| vec!["--tcp".to_string(), address]),
    ];
    prop::collection::vec(pair, 0..4).prop_map(|pairs| pairs.concat())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn hostile_arguments_end_with_0_1_or_2_and_no_panic(
        args in hostile_arguments(),
        words in prop::collection::vec(hostile_value(), 0..3),
    ) {
        let mut all: Vec<&str> = args.iter().map(String::as_str).collect();
        all.extend(["--timeout-ms", "300"]);
        all.extend(words.iter().map(String::as_str));
        let output = feeder_ctl(&all);
        let stderr = String::from_utf8_lossy(&output.stderr);
        prop_assert!(
            matches!(output.status.code(), Some(0..=2)),
            "{all:?} ended with {:?}: {stderr}", output.status
        );
        prop_assert!(!stderr.contains("panicked"), "{all:?}: {stderr}");
    }
}
