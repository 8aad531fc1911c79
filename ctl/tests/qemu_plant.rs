//! The closed-loop console image (`FEEDER_CLOSED_LOOP_CONSOLE_ELF`: features
//! `cosim-encoder,console`) in lockstep with `realistic.toml`'s plate: `feeder-ctl watch
//! --record --seconds` records telemetry whose cycle means are the plate's own, from the plant's
//! record of where it was; `feeder-ctl calibrate` finds the drive's offset and saves the zero
//! code that takes it off, and refuses an encoder that counts backwards, naming the flip.

mod support;

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use feeder_emulator::plant_link::{PlantThread, TICK_HZ};
use feeder_emulator::{Board, Serial};
use feeder_shared::telemetry::{Record, COLUMNS};
use feeder_shared::{DacCalibration, Friction};
use host_sim::cosim::PlatePlant;
use host_sim::plate::PlantFile;
use host_sim::Contact;

/// The image named by `FEEDER_CLOSED_LOOP_CONSOLE_ELF` (`cargo xtask test` sets it).
fn image() -> PathBuf {
    std::env::var_os("FEEDER_CLOSED_LOOP_CONSOLE_ELF")
        .filter(|path| !path.is_empty())
        .map(PathBuf::from)
        .expect("FEEDER_CLOSED_LOOP_CONSOLE_ELF must name the closed-loop console image")
}

/// How far a recorded cycle mean may lie from the plate's: one count of the encoder (1 µm),
/// for its rounding and the trapezoids over 250 µs samples (0.1 µm apart on this plate).
const MEAN_TOLERANCE_M: f64 = 1e-6;

/// The board in lockstep with `realistic.toml`'s plate, its flash in a directory of its own.
struct Lockstep {
    board: Board,
    link: PlantThread<PlatePlant>,
    address: String,
    flash: tempfile::TempDir,
}

/// `realistic.toml`, the plant file.
fn realistic() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/plants/realistic.toml")
}

impl Lockstep {
    /// The board in lockstep with the plate of the plant file at `plant_path`.
    fn start(plant_path: &std::path::Path) -> Self {
        let plant_file = PlantFile::from_path(plant_path).expect("the plant file");
        let part = Contact::paper_part(Friction::CONFIGURED.mu, Friction::CONFIGURED.gravity_mps2)
            .expect("the part");
        let plate = PlatePlant::new(&plant_file, &part, DacCalibration::DEFAULT, TICK_HZ)
            .expect("the plate");
        let flash = tempfile::tempdir().expect("a directory for the board's flash");
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|listener| listener.local_addr())
            .expect("a free port")
            .port();
        let (board, link) = Board::start_with_plant(
            &image(),
            &[] as &[&str],
            Serial::Tcp { port },
            Stdio::null(),
            plate,
            Some(flash.path()),
        )
        .expect("the board starts in lockstep with the plate");
        Lockstep {
            board,
            link,
            address: format!("127.0.0.1:{port}"),
            flash,
        }
    }

    /// `feeder-ctl --tcp … words`, once the console takes connections: exit code, stdout,
    /// stderr.
    fn ctl(&self, words: &[&str]) -> (Option<i32>, String, String) {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let output = Command::new(env!("CARGO_BIN_EXE_feeder-ctl"))
                .args(["--tcp", &self.address, "--timeout-ms", "30000"])
                .args(words)
                .stdin(Stdio::null())
                .output()
                .expect("feeder-ctl runs");
            let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
            let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
            if output.status.code() == Some(2)
                && stderr.contains("cannot open")
                && Instant::now() < deadline
            {
                std::thread::sleep(Duration::from_millis(50));
                continue;
            }
            return (output.status.code(), stdout, stderr);
        }
    }

    /// Ends the board; the plate as it was left.
    fn stop(mut self) -> PlatePlant {
        self.board.stop().expect("the board stops");
        self.link.join().expect("the plate's thread ends").0
    }
}

#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn a_headless_watch_records_the_plates_own_cycle_means() {
    let lockstep = Lockstep::start(&realistic());
    let ctl = |words: &[&str]| lockstep.ctl(words);
    assert_eq!(ctl(&["start"]).1.trim(), "OK starting");
    let feeding = Instant::now() + Duration::from_secs(120);
    while !ctl(&["status"]).1.contains(" loop=feeding ") {
        assert!(Instant::now() < feeding, "the closed loop never fed");
        std::thread::sleep(Duration::from_millis(200));
    }
    let recording = lockstep.flash.path().join("watch.csv");
    let (code, _, stderr) = ctl(&[
        "watch",
        "--record",
        recording.to_str().expect("a UTF-8 path"),
        "--seconds",
        "2",
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(ctl(&["stop"]).1.trim(), "OK stopping");
    let text = std::fs::read_to_string(&recording).expect("the recording");
    let plate = lockstep.stop();

    let mut lines = text.lines();
    let header = lines.next().expect("a header");
    assert_eq!(header.split(',').count(), COLUMNS.len());
    assert!(header.contains("mean_um"), "{header}");
    let records: Vec<Record> = lines
        .map(|row| Record::parse_line(&row.replace(',', " ")).expect("a row reads as a record"))
        .collect();
    assert!(records.len() > 50, "{} records in 2 s", records.len());

    // The plate's own mean over each cycle, from the plant's record at every cycle start.
    let samples = plate.samples();
    let plate_mean_m = |cycle: u64| -> Option<f64> {
        let (start, end) = (
            samples.get(cycle as usize - 1)?,
            samples.get(cycle as usize)?,
        );
        Some((end.position_integral_ms - start.position_integral_ms) / (end.time_s - start.time_s))
    };
    let mut compared = 0;
    for record in records.iter().filter(|record| record.stage.is_some()) {
        let Some(mean_m) = record.mean_m else {
            continue;
        };
        let plate_m = plate_mean_m(record.cycle).expect("the plate has the cycle");
        assert!(
            (mean_m - plate_m).abs() <= MEAN_TOLERANCE_M,
            "cycle {}: recorded {:.2} um, the plate's {:.2} um",
            record.cycle,
            mean_m * 1e6,
            plate_m * 1e6
        );
        compared += 1;
    }
    assert!(compared > 50, "{compared} cycle means compared");
}

/// The value of `key` in a calibration report.
fn report_value<'a>(text: &'a str, key: &str) -> &'a str {
    text.lines()
        .find_map(|line| line.strip_prefix(key)?.strip_prefix('='))
        .unwrap_or_else(|| panic!("no {key} in {text}"))
}

/// The drive's calibration finds `realistic.toml`'s zero offset (1.05 m/s², 8.4 counts), saves
/// the zero code that takes it off and restarts the board with it; on the same plate with its
/// encoder mounted the other way round (a plant file of its own) it is refused, naming the
/// setting to flip, and flipping it lets the calibration through.
#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn calibration_takes_the_offset_off_and_refuses_a_backwards_encoder() {
    let lockstep = Lockstep::start(&realistic());
    let report = lockstep.flash.path().join("calibration.txt");
    let report_path = report.to_str().expect("a UTF-8 path");
    let (code, stdout, stderr) = lockstep.ctl(&["calibrate", "--save", "--report", report_path]);
    assert_eq!(code, Some(0), "{stdout}{stderr}");
    assert!(stdout.contains("step 7/7: saving"), "{stdout}");
    let text = std::fs::read_to_string(&report).expect("the report");
    assert!(text.contains("proposed_dac_zero=2040\n"), "{text}");
    // The plate's drive (gains 1.02 / 0.98, offset 1 m/s², peak command 200 m/s²) gives the
    // plate levels up to min(1.02·200 + 1, 0.98·200 − 1) = 195 m/s²: by Eq. 5 3.342 mm at
    // 50 Hz, d = 0.586, 0.836 mm at 100 Hz; the settings' 2.5 mm fits.
    for (key, expected_mm) in [
        ("usable_stroke_mm_at_50_hz", 3.342),
        ("usable_stroke_mm_at_100_hz", 0.8355),
    ] {
        let value: f64 = report_value(&text, key)
            .split(' ')
            .next()
            .and_then(|number| number.parse().ok())
            .unwrap_or_else(|| panic!("{key} in {text}"));
        assert!(
            (value / expected_mm - 1.0).abs() < 0.01,
            "{key}={value}: {text}"
        );
    }
    for check in ["swing", "offset", "gains", "lag", "stroke"] {
        assert!(
            report_value(&text, check).starts_with("ok "),
            "{check}: {text}"
        );
    }
    assert!(
        text.contains("saved=yes\n") && text.contains("outcome=accepted\n"),
        "{text}"
    );
    let (_, zero, _) = lockstep.ctl(&["config", "get", "dac_zero"]);
    assert_eq!(zero.trim(), "OK dac_zero=2040");
    lockstep.stop();

    let plants = tempfile::tempdir().expect("a directory for the plant file");
    let reversed = plants.path().join("realistic-reversed-encoder.toml");
    let text = std::fs::read_to_string(realistic()).expect("realistic.toml");
    let text = text.replace(
        "[sensors.encoder]\n",
        "[sensors.encoder]\nreversed = true\n",
    );
    assert!(
        text.contains("reversed = true"),
        "the encoder's table is there"
    );
    std::fs::write(&reversed, text).expect("the plant file");
    let lockstep = Lockstep::start(&reversed);
    let (code, stdout, stderr) = lockstep.ctl(&["calibrate"]);
    assert_eq!(code, Some(1), "{stdout}{stderr}");
    assert!(
        stderr.contains("calibration refused")
            && stderr.contains("config set encoder_dir reversed"),
        "{stderr}"
    );
    for line in ["config set encoder_dir reversed", "config save", "restart"] {
        let (code, reply, _) = lockstep.ctl(&line.split(' ').collect::<Vec<_>>());
        assert_eq!(code, Some(0), "{line}: {reply}");
    }
    let (code, stdout, stderr) = lockstep.ctl(&["calibrate"]);
    assert_eq!(code, Some(0), "{stdout}{stderr}");
    assert!(stdout.contains("proposed: dac_zero 2040"), "{stdout}");
    lockstep.stop();
}
