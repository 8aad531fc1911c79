//! The emulated board while it runs: QEMU with `defmt-print` decoding its log, and a scripted
//! run taken to its end.

use std::io::{self, Read};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, ExitStatus, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use crate::command::{command, Serial};
use crate::plant_link::{LinkCounts, Plant, PlantThread};
use crate::{LaunchError, DECODER, QEMU};

/// The board's flash file in QEMU's working directory (the console image's `file_store`).
pub const FLASH_FILE: &str = "feeder-flash.bin";

/// Pause between looks at whether a run has ended.
const EXIT_POLL_INTERVAL: Duration = Duration::from_millis(20);

/// QEMU running a firmware image and the decoder of its log. Dropping it ends QEMU, after which
/// the decoder ends at the end of its input.
pub struct Board {
    emulator: Child,
    decoder: Child,
}

impl Board {
    /// Starts `elf` under QEMU with the scenario words and UART0 on `serial`, and `defmt-print`
    /// on QEMU's standard output; the decoded log goes to `decoded` (with [`Stdio::piped`], take
    /// it with [`Board::decoded_log`]). QEMU runs in `dir`, where the console image keeps its
    /// flash file (`feeder-flash.bin`): a board started again in the same directory finds what
    /// the last one saved.
    pub fn start<S: AsRef<str>>(
        elf: &Path,
        scenario: &[S],
        serial: Serial,
        decoded: Stdio,
        dir: &Path,
    ) -> Result<Self, LaunchError> {
        // QEMU runs elsewhere: the image's path must not depend on the working directory.
        let elf = std::path::absolute(elf).map_err(LaunchError::Image)?;
        let mut emulator = command(&elf, scenario, serial);
        emulator.current_dir(dir);
        Self::spawn(emulator, &elf, decoded)
    }

    /// Starts the `cosim` image `elf` as [`Board::start`] does, in lockstep with `plant`: QEMU
    /// runs in the directory of the link's FIFOs, which the returned thread serves `plant` on
    /// (see [`crate::plant_link`]). Join the thread once the board has ended. With `flash_dir`,
    /// the board's flash file is the one in that directory (a console image keeps what it saves
    /// there); without, it is the link directory's, gone with it.
    pub fn start_with_plant<S: AsRef<str>, P: Plant + Send + 'static>(
        elf: &Path,
        scenario: &[S],
        serial: Serial,
        decoded: Stdio,
        plant: P,
        flash_dir: Option<&Path>,
    ) -> Result<(Self, PlantThread<P>), LaunchError> {
        // QEMU runs elsewhere: the image's path must not depend on the working directory.
        let elf = std::path::absolute(elf).map_err(LaunchError::Image)?;
        let link = PlantThread::start(plant).map_err(LaunchError::Plant)?;
        if let Some(dir) = flash_dir {
            let flash = std::path::absolute(dir.join(FLASH_FILE)).map_err(LaunchError::Image)?;
            std::os::unix::fs::symlink(flash, link.dir().join(FLASH_FILE))
                .map_err(LaunchError::Plant)?;
        }
        let mut emulator = command(&elf, scenario, serial);
        emulator.current_dir(link.dir());
        let board = Self::spawn(emulator, &elf, decoded)?;
        Ok((board, link))
    }

    /// Starts QEMU's `emulator` command for `elf` with its standard output decoded into
    /// `decoded`.
    fn spawn(mut emulator: Command, elf: &Path, decoded: Stdio) -> Result<Self, LaunchError> {
        let mut emulator =
            emulator
                .stdout(Stdio::piped())
                .spawn()
                .map_err(|source| LaunchError::Start {
                    program: QEMU,
                    source,
                })?;
        let decoder = match emulator.stdout.take() {
            Some(raw) => Command::new(DECODER)
                .arg("-e")
                .arg(elf)
                .stdin(raw)
                .stdout(decoded)
                .spawn()
                .map_err(|source| LaunchError::Start {
                    program: DECODER,
                    source,
                }),
            None => Err(LaunchError::NoOutput { program: QEMU }),
        };
        match decoder {
            Ok(decoder) => Ok(Board { emulator, decoder }),
            Err(error) => {
                let _ = emulator.kill();
                let _ = emulator.wait();
                Err(error)
            }
        }
    }

    /// The decoded log, when it was started with [`Stdio::piped`] and not taken yet.
    pub fn decoded_log(&mut self) -> Result<ChildStdout, LaunchError> {
        self.decoder
            .stdout
            .take()
            .ok_or(LaunchError::NoOutput { program: DECODER })
    }

    /// The firmware's exit status, once QEMU has ended.
    pub fn try_exit_status(&mut self) -> Result<Option<ExitStatus>, LaunchError> {
        self.emulator
            .try_wait()
            .map_err(|source| LaunchError::Wait {
                program: QEMU,
                source,
            })
    }

    /// Waits for the firmware to end and for the decoder to write the rest of the log; the
    /// firmware's exit status.
    pub fn wait(&mut self) -> Result<ExitStatus, LaunchError> {
        let status = self.emulator.wait().map_err(|source| LaunchError::Wait {
            program: QEMU,
            source,
        })?;
        self.decoder.wait().map_err(|source| LaunchError::Wait {
            program: DECODER,
            source,
        })?;
        Ok(status)
    }

    /// Ends QEMU and waits for the decoder to write the rest of the log.
    pub fn stop(&mut self) -> Result<(), LaunchError> {
        let _ = self.emulator.kill();
        self.wait().map(drop)
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        let _ = self.stop();
    }
}

/// A scripted run that has ended.
#[derive(Debug)]
pub struct Run {
    /// The firmware's exit status: success unless the run failed.
    pub status: ExitStatus,
    /// The decoded log, every line as `defmt-print` wrote it.
    pub log: String,
}

/// Runs `elf` with the scenario words and UART0 unconnected until the firmware ends, at most
/// `limit` (then QEMU is ended and the run fails).
pub fn run_to_end<S: AsRef<str>>(
    elf: &Path,
    scenario: &[S],
    limit: Duration,
) -> Result<Run, LaunchError> {
    let board = Board::start(
        elf,
        scenario,
        Serial::None,
        Stdio::piped(),
        &std::env::temp_dir(),
    )?;
    run_board(board, limit)
}

/// A scripted run in lockstep with a plant that has ended.
#[derive(Debug)]
pub struct PlantRun<P> {
    pub run: Run,
    /// The plant as the run left it.
    pub plant: P,
    /// What the link carried.
    pub counts: LinkCounts,
}

/// Runs the `cosim` image `elf` with the scenario words, in lockstep with `plant` (see
/// [`Board::start_with_plant`]), until the firmware ends, at most `limit`.
pub fn run_with_plant<S: AsRef<str>, P: Plant + Send + 'static>(
    elf: &Path,
    scenario: &[S],
    limit: Duration,
    plant: P,
) -> Result<PlantRun<P>, LaunchError> {
    let (board, link) =
        Board::start_with_plant(elf, scenario, Serial::None, Stdio::piped(), plant, None)?;
    let run = run_board(board, limit);
    let (plant, counts) = link.join()?;
    Ok(PlantRun {
        run: run?,
        plant,
        counts,
    })
}

/// Takes `board`, started with its decoded log piped, to its end, at most `limit`.
fn run_board(mut board: Board, limit: Duration) -> Result<Run, LaunchError> {
    let mut decoded = board.decoded_log()?;
    let reader = thread::spawn(move || {
        let mut log = String::new();
        decoded.read_to_string(&mut log).map(|_| log)
    });
    let started = Instant::now();
    while board.try_exit_status()?.is_none() {
        if started.elapsed() > limit {
            board.stop()?;
            return Err(LaunchError::Timeout { limit });
        }
        thread::sleep(EXIT_POLL_INTERVAL);
    }
    let status = board.wait()?;
    let log = reader
        .join()
        .map_err(|_| LaunchError::Log(io::Error::other("the log reader panicked")))?
        .map_err(LaunchError::Log)?;
    Ok(Run { status, log })
}
