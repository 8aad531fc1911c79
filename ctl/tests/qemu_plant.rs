//! The closed-loop console image (`FEEDER_CLOSED_LOOP_CONSOLE_ELF`: features
//! `cosim-encoder,console`) in lockstep with `realistic.toml`'s plate: `feeder-ctl watch
//! --record --seconds` records telemetry whose cycle means are the plate's own, from the plant's
//! record of where it was.

mod support;

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use feeder_emulator::plant_link::TICK_HZ;
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

#[test]
#[ignore = "needs the QEMU firmware; run by cargo xtask test"]
fn a_headless_watch_records_the_plates_own_cycle_means() {
    let plant_path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/plants/realistic.toml");
    let plant_file = PlantFile::from_path(&plant_path).expect("the plant file");
    let part = Contact::paper_part(Friction::CONFIGURED.mu, Friction::CONFIGURED.gravity_mps2)
        .expect("the part");
    let plate =
        PlatePlant::new(&plant_file, &part, DacCalibration::DEFAULT, TICK_HZ).expect("the plate");
    let flash = tempfile::tempdir().expect("a directory for the board's flash");
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|listener| listener.local_addr())
        .expect("a free port")
        .port();
    let (mut board, link) = Board::start_with_plant(
        &image(),
        &[] as &[&str],
        Serial::Tcp { port },
        Stdio::null(),
        plate,
        Some(flash.path()),
    )
    .expect("the board starts in lockstep with the plate");
    let address = format!("127.0.0.1:{port}");
    let ctl = |words: &[&str]| {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let output = Command::new(env!("CARGO_BIN_EXE_feeder-ctl"))
                .args(["--tcp", &address, "--timeout-ms", "30000"])
                .args(words)
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
    };
    assert_eq!(ctl(&["start"]).1.trim(), "OK starting");
    let feeding = Instant::now() + Duration::from_secs(120);
    while !ctl(&["status"]).1.contains(" loop=feeding ") {
        assert!(Instant::now() < feeding, "the closed loop never fed");
        std::thread::sleep(Duration::from_millis(200));
    }
    let recording = flash.path().join("watch.csv");
    let (code, _, stderr) = ctl(&[
        "watch",
        "--record",
        recording.to_str().expect("a UTF-8 path"),
        "--seconds",
        "2",
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(ctl(&["stop"]).1.trim(), "OK stopping");
    board.stop().expect("the board stops");
    let (plate, _) = link.join().expect("the plate's thread ends");

    let text = std::fs::read_to_string(&recording).expect("the recording");
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
