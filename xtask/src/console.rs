//! `cargo xtask console`: live control of the emulated feeder in one command. The QEMU console
//! image runs with its serial port on a free loopback TCP port, its decoded log captured to
//! `target/console-run.log` and its flash in `target/emulated-board/`; the operator gets the
//! `feeder-ctl` prompt on the terminal, and when they leave it, the plate is brought to rest (a
//! soft stop), QEMU is stopped and `host-sim hil` checks what happened.
//!
//! With `--plant FILE` the console image with the plant's encoder runs the closed loop in
//! lockstep with that plate (and a part of the configured μ on it); with `--script FILE` a
//! command script runs headless instead of the prompt (`feeder-ctl script`), its telemetry
//! recorded to CSV with `--record FILE`. With `--modbus 127.0.0.1:PORT` the board's Modbus RTU
//! port listens there too (RTU frames over TCP), for a Modbus master beside the prompt.

use std::fs::File;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::thread;
use std::time::{Duration, Instant};

use clap::Args;
use feeder_emulator::plant_link::{PlantThread, TICK_HZ};
use feeder_emulator::{Board, Serial, FLASH_FILE};
use feeder_shared::{DacCalibration, Friction};
use host_sim::cosim::PlatePlant;
use host_sim::plate::PlantFile;
use host_sim::Contact;

use crate::command::{cargo, exec, exec_output, host_sim, root, workspace_binary};
use crate::failure::{Failure, Result};
use crate::qemu::{self, Image};
use crate::tools;

/// Longest to wait for QEMU to open its serial port.
const PORT_OPEN_TIMEOUT: Duration = Duration::from_secs(20);
/// Pause between attempts to reach the serial port.
const PORT_POLL_INTERVAL: Duration = Duration::from_millis(20);
/// Longest to wait for the soft stop after the operator leaves (the longest ramps take longer:
/// the check then sees the plate still ramping down).
const REST_TIMEOUT: Duration = Duration::from_secs(60);
/// Pause between `status` polls while the plate comes to rest.
const REST_POLL_INTERVAL: Duration = Duration::from_millis(200);

/// Where the decoded log of the session goes.
fn log_path() -> PathBuf {
    root().join("target").join("console-run.log")
}

/// Where the emulated board keeps its flash file (`feeder-flash.bin`: the saved configuration
/// and recipes), from one session to the next, as a board keeps its flash.
fn board_dir() -> Result<PathBuf> {
    let dir = root().join("target").join("emulated-board");
    std::fs::create_dir_all(&dir)
        .map_err(|error| format!("cannot create {}: {error}", dir.display()))?;
    Ok(dir)
}

/// The flags of `cargo xtask console`.
#[derive(Args)]
pub struct ConsoleArgs {
    /// Runs the closed-loop console image in lockstep with this plant file's plate
    /// (host-sim/plants/), a part of the configured μ on it.
    #[arg(long, value_name = "FILE")]
    plant: Option<PathBuf>,
    /// Runs this command script headless instead of the prompt: console lines, one a line,
    /// and `wait SECONDS` lines; every reply goes to standard output.
    #[arg(long, value_name = "FILE")]
    script: Option<PathBuf>,
    /// With --script: records the telemetry to this CSV file, one row per record.
    #[arg(long, value_name = "FILE", requires = "script")]
    record: Option<PathBuf>,
    /// Puts the board's Modbus RTU port (its second UART) on this loopback address, RTU frames
    /// over TCP, for a Modbus master (a PLC's software, a client library).
    #[arg(long, value_name = "127.0.0.1:PORT")]
    modbus: Option<SocketAddr>,
}

/// Builds and runs everything, hands the terminal to `feeder-ctl` (or runs the script), then
/// checks the log.
pub fn console(args: &ConsoleArgs) -> Result {
    let plant = args
        .plant
        .as_deref()
        .map(|path| PlantFile::from_path(path).map_err(|error| Failure::Refused(error.to_string())))
        .transpose()?;
    if let Some(script) = &args.script {
        std::fs::metadata(script).map_err(|error| {
            Failure::Refused(format!("cannot read {}: {error}", script.display()))
        })?;
    }
    let modbus = args.modbus.map(modbus_port).transpose()?;
    tools::ensure_linker()?;
    tools::ensure_emulation()?;
    let image = match plant {
        Some(_) => Image::ClosedLoopConsole,
        None => Image::Console,
    };
    let elf = qemu::build_firmware(image)?;
    exec(cargo().args(["build", "--release", "--locked"]).args([
        "--package",
        "feeder-ctl",
        "--package",
        "host-sim",
    ]))?;
    let log = log_path();
    let operator = {
        let mut feeder = Feeder::start(&elf, &log, plant.as_ref(), modbus)?;
        eprintln!(
            "xtask: the feeder runs under QEMU, its console on {}{}, its log in {} and its \
             flash in {}{}",
            address(feeder.port),
            match modbus {
                Some(port) => format!(", its Modbus RTU port on {} (slave 1)", address(port)),
                None => String::new(),
            },
            log.display(),
            board_dir()?.join(FLASH_FILE).display(),
            match &args.script {
                Some(script) => format!("; running {}", script.display()),
                None => "; `help` lists the board's commands, `watch`, `calibrate`, `export`, \
                         `import` and `script` are feeder-ctl's tools, `quit`, `exit` or Ctrl-D \
                         leave and check the run"
                    .into(),
            }
        );
        let operated = match &args.script {
            Some(script) => run_script(feeder.port, script, args.record.as_deref()),
            None => operate(feeder.port),
        };
        let operator = operated.and_then(|()| bring_to_rest(feeder.port));
        feeder.stop()?;
        operator
    };
    if args.plant.is_some() {
        // The closed loop's course trims every cycle: `hil` checks plans the scheduler alone
        // makes, so the plate's own record (above) is the report.
        return operator;
    }
    let checked = last_boot(&log)?;
    eprintln!("\nWhat the firmware did, checked by host-sim hil:");
    let check = exec_output(
        host_sim()
            .args(["hil", "--input"])
            .arg(&checked)
            .arg("--open-ended"),
    );
    operator.and(check)
}

/// What the firmware logs as it restarts (`firmware/src/console.rs`).
const RESTART_MARKER: &str = "restart: the board restarts";

/// The log of the board's last start: `log` itself, or after a `restart` the lines after the
/// last one, written beside it (`hil` checks one run of the scheduler from its power-up).
fn last_boot(log: &Path) -> Result<PathBuf> {
    let text = std::fs::read_to_string(log)
        .map_err(|error| format!("cannot read {}: {error}", log.display()))?;
    let Some(at) = text.rfind(RESTART_MARKER) else {
        return Ok(log.to_path_buf());
    };
    let after = text[at..].split_once('\n').map_or("", |(_, rest)| rest);
    let last = log.with_file_name("console-run-last-start.log");
    std::fs::write(&last, after)
        .map_err(|error| format!("cannot write {}: {error}", last.display()))?;
    eprintln!(
        "xtask: the board restarted during the session: the check covers its last start ({})",
        last.display()
    );
    Ok(last)
}

/// The emulated feeder: QEMU and the decoder writing its log, and the plate in lockstep with
/// it where there is one. All end when this is dropped.
struct Feeder {
    board: Board,
    port: u16,
    plate: Option<PlantThread<PlatePlant>>,
}

impl Feeder {
    /// Starts the console image `elf` with its decoded log going to `log`, in lockstep with the
    /// plate of `plant` where there is one, its Modbus port on loopback port `modbus` where
    /// asked, and waits until its serial port accepts connections.
    fn start(
        elf: &Path,
        log: &Path,
        plant: Option<&PlantFile>,
        modbus: Option<u16>,
    ) -> Result<Self> {
        let port = free_port()?;
        let serial = match modbus {
            Some(modbus) => Serial::Lines {
                console: port,
                modbus,
            },
            None => Serial::Tcp { port },
        };
        let file = File::create(log)
            .map_err(|error| format!("cannot create {}: {error}", log.display()))?;
        let dir = board_dir()?;
        let (board, plate) = match plant {
            None => (
                Board::start(elf, &[] as &[&str], serial, Stdio::from(file), &dir)
                    .map_err(|error| error.to_string())?,
                None,
            ),
            Some(plant) => {
                let part =
                    Contact::paper_part(Friction::CONFIGURED.mu, Friction::CONFIGURED.gravity_mps2)
                        .map_err(|error| error.to_string())?;
                let plate = PlatePlant::new(plant, &part, DacCalibration::DEFAULT, TICK_HZ)
                    .map_err(|error| Failure::Refused(error.to_string()))?;
                let (board, link) = Board::start_with_plant(
                    elf,
                    &[] as &[&str],
                    serial,
                    Stdio::from(file),
                    plate,
                    Some(&dir),
                )
                .map_err(|error| error.to_string())?;
                (board, Some(link))
            }
        };
        let mut feeder = Feeder { board, port, plate };
        feeder.wait_for_port()?;
        Ok(feeder)
    }

    fn wait_for_port(&mut self) -> Result {
        let deadline = Instant::now() + PORT_OPEN_TIMEOUT;
        loop {
            if let Ok(Some(status)) = self.board.try_exit_status() {
                return Err(format!("QEMU ended before its serial port opened: {status}").into());
            }
            // QEMU takes the next client once this probe has disconnected.
            if TcpStream::connect(("127.0.0.1", self.port)).is_ok() {
                return Ok(());
            }
            if Instant::now() > deadline {
                return Err(format!(
                    "QEMU did not open its serial port within {PORT_OPEN_TIMEOUT:?}"
                )
                .into());
            }
            thread::sleep(PORT_POLL_INTERVAL);
        }
    }

    /// Ends QEMU, waits for the decoder to write the rest of the log and, with a plate, says
    /// where it went.
    fn stop(&mut self) -> Result {
        self.board.stop().map_err(|error| error.to_string())?;
        if let Some(link) = self.plate.take() {
            let (plate, _) = link.join().map_err(|error| error.to_string())?;
            let state = plate.last_state();
            eprintln!(
                "xtask: the plate went {:.1} um from its centre at most{}; it ended at {:.1} um",
                plate.peak_excursion_m() * 1e6,
                match plate.end_stop() {
                    Some(stop) => format!(", into its end stop at {:.3} s", stop.time_s),
                    None => ", no end stop".into(),
                },
                state.position_m * 1e6
            );
        }
        Ok(())
    }
}

/// The loopback port of `--modbus`: QEMU's serial servers listen on loopback only.
fn modbus_port(address: SocketAddr) -> Result<u16> {
    if !address.ip().is_loopback() || address.port() == 0 {
        return Err(Failure::Refused(format!(
            "--modbus {address}: give a loopback address with a port, such as 127.0.0.1:5020"
        )));
    }
    TcpListener::bind(address).map_err(|error| {
        Failure::Refused(format!("--modbus {address}: the port is not free: {error}"))
    })?;
    Ok(address.port())
}

/// The console's address on the loopback port `port`, as `feeder-ctl --tcp` takes it.
fn address(port: u16) -> String {
    format!("127.0.0.1:{port}")
}

/// A loopback port nobody listens on (free when this returns; QEMU takes it right after).
fn free_port() -> Result<u16> {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|listener| listener.local_addr())
        .map(|address| address.port())
        .map_err(|error| format!("no free loopback port: {error}").into())
}

/// The `feeder-ctl` prompt on this terminal, connected to the console on `port`.
fn operate(port: u16) -> Result {
    exec_output(
        workspace_binary("feeder-ctl")
            .arg("--tcp")
            .arg(address(port)),
    )
}

/// `feeder-ctl script` on the console on `port`: every reply to standard output, the telemetry
/// to `record`.
fn run_script(port: u16, script: &Path, record: Option<&Path>) -> Result {
    let mut command = workspace_binary("feeder-ctl");
    command
        .arg("--tcp")
        .arg(address(port))
        .arg("--timeout-ms")
        .arg("30000")
        .arg("script")
        .arg(script);
    if let Some(record) = record {
        command.arg("--record").arg(record);
    }
    exec_output(&mut command)
}

/// One command to the console on `port`; its reply line.
fn command(port: u16, words: &[&str]) -> Result<String> {
    let output = workspace_binary("feeder-ctl")
        .arg("--tcp")
        .arg(address(port))
        .args(words)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|error| format!("cannot run feeder-ctl: {error}"))?;
    match output.status.code() {
        Some(0 | 1) => Ok(String::from_utf8_lossy(&output.stdout).trim().to_string()),
        _ => Err(format!(
            "feeder-ctl {} failed with {}",
            words.join(" "),
            output.status
        )
        .into()),
    }
}

/// Leaves the plate at rest before the emulator ends: a soft stop, then `status` until the
/// feeder says it is stopped (or faulted, which has stopped it already).
fn bring_to_rest(port: u16) -> Result {
    eprintln!("xtask: bringing the plate to rest (soft stop) before the check");
    command(port, &["stop"])?;
    let deadline = Instant::now() + REST_TIMEOUT;
    loop {
        let status = command(port, &["status"])?;
        if status.starts_with("OK state=stopped") || status.starts_with("OK state=fault") {
            return Ok(());
        }
        if Instant::now() > deadline {
            eprintln!("xtask: still not at rest after {REST_TIMEOUT:?}: {status}");
            return Ok(());
        }
        thread::sleep(REST_POLL_INTERVAL);
    }
}
