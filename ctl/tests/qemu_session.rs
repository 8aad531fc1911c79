//! A scripted operator session against the QEMU firmware built with the `console` feature
//! (`FEEDER_QEMU_ELF`): every reply is checked, then the firmware's `EVT` stream shows that every
//! change landed on a cycle boundary and that no edge is missing.

mod support;

use std::thread;
use std::time::Duration;

use feeder_shared::event::{parse_line, Event, SegmentEvent};
use support::{console_image, Emulator};

/// Longest the feeder may take to reach a requested state.
const STATE_TIMEOUT: Duration = Duration::from_secs(30);

#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn scripted_session_over_the_serial_console() {
    let mut emulator = Emulator::launch(&console_image(), Vec::new());
    let mut console = emulator.connect();
    console.expect("status", "OK state=stopped ");
    console.expect("set freq 55", "OK freq_hz=55 ");
    console.expect("set ramp 5 cycles", "OK freq_hz=55 ");
    console.expect("get ramp", "OK ramp_cycles=5");
    console.expect("start", "OK starting");
    console.wait_for_state("running", STATE_TIMEOUT);
    console.expect("set duty 0.6", "OK freq_hz=55 duty=0.6 ");
    thread::sleep(Duration::from_millis(300));
    let feed = console.expect("set feed 30", "OK freq_hz=55 duty=");
    assert!(feed.ends_with(" feed_mmps=30"), "{feed}");
    console.expect("get feed", "OK feed_mmps=30");
    let garbage = console.send(b"\x00\x01\xfe\xff\x1b[A junk\r\n");
    assert!(garbage.starts_with("ERR 11 "), "{garbage:?}");
    let overlong = console.send(format!("set duty {}\r\n", "9".repeat(100)).as_bytes());
    assert!(overlong.starts_with("ERR 10 "), "{overlong:?}");
    console.expect("launch", "ERR 20 ");
    console.expect("set duty 2", "ERR 43 ");
    console.expect("set duty 0,6", "ERR 24 not a number: use a decimal point");
    console.expect("set stroke 6", "ERR 57 stroke 0.006 m exceeds ");
    console.expect("set freq nan", "ERR 25 ");
    console.expect("recipe save 1", "ERR 60 ");
    console.expect("start", "OK starting");
    let running = console.expect("status", "OK state=running freq_hz=55 ");
    assert!(running.ends_with(" fault=none"), "{running}");
    console.expect("stop", "OK stopping");
    console.wait_for_state("stopped", STATE_TIMEOUT);
    console.expect("recipe save 1", "OK recipe 1 saved");
    console.expect("recipe load 1", "OK recipe 1 loaded freq_hz=55 ");
    console.expect(
        "recipe load 2",
        "ERR 63 recipe 2 not loaded: no recipe saved",
    );
    console.expect("get freq", "OK freq_hz=55");
    console.expect("help", "OK commands: ");
    // Let the last plan (recipe 1's) reach the output.
    thread::sleep(Duration::from_millis(300));
    drop(console);
    let log = emulator.shut_down();

    check_event_stream(&log);
}

/// Every plan change lands on a cycle boundary and the segments are contiguous.
fn check_event_stream(log: &[String]) {
    assert!(
        !log.iter().any(|line| line.contains("fault")),
        "the firmware faulted:\n{}",
        log.join("\n")
    );
    let events: Vec<Event> = log
        .iter()
        .filter_map(|line| parse_line(line).unwrap_or_else(|error| panic!("{error}: {line}")))
        .collect();
    let segments: Vec<SegmentEvent> = events
        .iter()
        .filter_map(|event| match event {
            Event::Segment(segment) => Some(*segment),
            _ => None,
        })
        .collect();
    assert!(segments.len() > 100, "too few segments: {}", segments.len());
    for pair in segments.windows(2) {
        let (previous, next) = (&pair[0], &pair[1]);
        assert_eq!(
            next.planned_tick,
            previous.planned_tick + u64::from(previous.ticks),
            "missing edge between {previous:?} and {next:?}"
        );
        if next.starts_cycle() {
            assert_eq!(next.cycle, previous.cycle + 1, "{previous:?} -> {next:?}");
        } else {
            assert_eq!(next.cycle, previous.cycle, "{previous:?} -> {next:?}");
            assert_eq!(
                (next.step, next.steps),
                (previous.step, previous.steps),
                "amplitude changed inside a cycle: {previous:?} -> {next:?}"
            );
        }
    }
    // Each plan takes effect at the first cycle boundary at or after its request.
    let mut plans = 0;
    for (tick, spec) in events.iter().filter_map(|event| match event {
        Event::Plan { tick, spec, .. } => Some((*tick, spec)),
        _ => None,
    }) {
        if tick == 0 {
            continue;
        }
        plans += 1;
        let period_ticks = (spec.period_s * 1e6).round() as u64;
        let first = segments
            .iter()
            .position(|seg| seg.planned_tick >= tick && seg.starts_cycle())
            .unwrap_or_else(|| panic!("the plan at tick {tick} never took effect"));
        let cycle = segments[first].cycle;
        let length: u64 = segments
            .iter()
            .filter(|seg| seg.cycle == cycle)
            .map(|seg| u64::from(seg.ticks))
            .sum();
        assert!(
            length.abs_diff(period_ticks) <= 1,
            "cycle {cycle} after the plan at tick {tick} lasts {length} ticks, not {period_ticks}"
        );
    }
    assert!(
        plans >= 5,
        "expected a plan per accepted change, saw {plans}"
    );
}

/// The configuration saved on the board is what it runs after a restart and after the emulation
/// starts again with the same flash; a corrupt record is refused by name and the board runs the
/// compiled defaults.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn a_saved_configuration_survives_a_restart_and_a_power_cycle() {
    let flash = tempfile::tempdir().expect("a directory for the board's flash");
    let mut emulator = Emulator::launch_in(&console_image(), Vec::new(), flash.path());
    let mut console = emulator.connect();
    console.expect("config get start_freq_hz", "OK start_freq_hz=50");
    console.expect(
        "config set start_freq_hz 60",
        "OK start_freq_hz=60 (not saved)",
    );
    console.expect(
        "config save",
        "ERR 65 start_stroke_mm: the start-up settings are refused: stroke 0.0025 m exceeds",
    );
    console.expect(
        "config set start_freq_hz 55",
        "OK start_freq_hz=55 (not saved)",
    );
    console.expect("config set dac_zero 2050", "OK dac_zero=2050 (not saved)");
    console.expect("config save", "OK config saved; restart to run it");
    console.expect("get freq", "OK freq_hz=50");
    console.expect("restart", "OK restarting");
    drop(console);
    let mut console = emulator.connect();
    console.expect("get freq", "OK freq_hz=55");
    console.expect("config get dac_zero", "OK dac_zero=2050");
    drop(console);
    let log = emulator.shut_down();
    assert!(
        log.iter()
            .any(|line| line.contains("configuration: the one saved on the board")),
        "{}",
        log.join("\n")
    );

    let mut emulator = Emulator::launch_in(&console_image(), Vec::new(), flash.path());
    let mut console = emulator.connect();
    console.expect("get freq", "OK freq_hz=55");
    console.expect("config save", "OK config saved");
    drop(console);
    emulator.shut_down();

    let file = flash.path().join("feeder-flash.bin");
    let mut bytes = std::fs::read(&file).expect("the flash file");
    bytes[20] ^= 0x01;
    std::fs::write(&file, &bytes).expect("the flash file is written");
    let mut emulator = Emulator::launch_in(&console_image(), Vec::new(), flash.path());
    let mut console = emulator.connect();
    console.expect("get freq", "OK freq_hz=50");
    drop(console);
    let log = emulator.shut_down();
    assert!(
        log.iter().any(|line| line
            .contains("configuration: as compiled, the saved one is not used: Record(CrcMismatch")),
        "{}",
        log.join("\n")
    );
}

/// `feeder-ctl export` writes what `config list` shows; `import --save` sets and saves a file's
/// keys; a file the board refuses changes nothing.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn a_configuration_file_goes_out_and_comes_back() {
    let dir = tempfile::tempdir().expect("a directory for the files");
    let mut emulator = Emulator::launch(&console_image(), Vec::new());
    let mut console = emulator.connect();
    let before = console.expect("config list", "OK config dac_zero=2048 ");
    drop(console);
    let ctl = |words: &[&str]| {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_feeder-ctl"))
            .arg("--tcp")
            .arg(emulator.address())
            .args(words)
            .output()
            .expect("feeder-ctl runs");
        (
            output.status.code(),
            String::from_utf8_lossy(&output.stdout).into_owned(),
            String::from_utf8_lossy(&output.stderr).into_owned(),
        )
    };
    let file = dir.path().join("feeder.conf");
    let path = file.to_str().expect("a UTF-8 path");
    let (code, _, stderr) = ctl(&["export", path]);
    assert_eq!(code, Some(0), "{stderr}");
    let text = std::fs::read_to_string(&file).expect("the exported file");
    let listed: Vec<String> = before
        .trim_start_matches("OK config ")
        .split(' ')
        .map(str::to_string)
        .collect();
    let exported: Vec<String> = text
        .lines()
        .filter(|line| !line.starts_with('#'))
        .map(str::to_string)
        .collect();
    assert_eq!(exported, listed);

    let edited = text
        .replace("dac_zero=2048", "dac_zero=2052")
        .replace("start_duty=0.586", "start_duty=0.6");
    std::fs::write(&file, edited).expect("the edited file");
    let (code, stdout, stderr) = ctl(&["import", path, "--save"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(stdout.trim(), "OK config saved; restart to run it");

    let bad = dir.path().join("bad.conf");
    std::fs::write(&bad, "dac_zero=2000\npart_mu=5\n").expect("the bad file");
    let (code, _, stderr) = ctl(&["import", bad.to_str().expect("a UTF-8 path")]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("the board refused config set part_mu 5: ERR 65 part_mu: 5 lies outside")
            && stderr.contains("every key is back as it was"),
        "{stderr}"
    );
    // The tools run at the prompt as on the command line.
    let typed = dir.path().join("typed.conf");
    let mut prompt = std::process::Command::new(env!("CARGO_BIN_EXE_feeder-ctl"))
        .arg("--tcp")
        .arg(emulator.address())
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("feeder-ctl runs");
    {
        use std::io::Write as _;
        let mut stdin = prompt.stdin.take().expect("the prompt's input");
        writeln!(stdin, "export {}\nconfig get dac_zero", typed.display()).expect("typed");
    }
    let output = prompt.wait_with_output().expect("the prompt ends");
    assert_eq!(
        String::from_utf8_lossy(&output.stdout).trim(),
        "OK dac_zero=2052"
    );
    let exported = std::fs::read_to_string(&typed).expect("the file the prompt exported");
    assert!(exported.contains("\ndac_zero=2052\n"), "{exported}");

    let mut console = emulator.connect();
    let after = console.expect("config list", "OK config dac_zero=2052 ");
    assert!(after.contains(" start_duty=0.6 "), "{after}");
    drop(console);
    emulator.shut_down();
}
