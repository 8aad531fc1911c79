//! `host-sim cosim`: the emulated firmware (the QEMU `cosim` image) driving a real plate in
//! lockstep: every level its output applies moves the plate from its tick on, and at every cycle
//! start the firmware reads the plate's encoder.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Args;
use feeder_emulator::plant::TICK_HZ;
use feeder_shared::DacCalibration;
use host_sim::cosim::{PlatePlant, PlateSample};
use host_sim::plate::{EndStop, PlantFile};
use host_sim::SimError;
use serde::Serialize;

use crate::args::{ContactArgs, OutputArgs};
use crate::output::{emit, say};

/// The longest co-simulation before it is stopped.
const LIMIT: Duration = Duration::from_secs(3600);

/// The flags of `host-sim cosim`.
#[derive(Args)]
pub struct CosimArgs {
    /// The `cosim` firmware image, an ELF built with `--features cosim`.
    #[arg(long, value_name = "FILE")]
    elf: PathBuf,
    /// The plate as a TOML plant file with a `[sensors.encoder]` table.
    #[arg(long, value_name = "FILE")]
    plant: PathBuf,
    /// The command exactly as the firmware plans it, with no correction (the emulated
    /// firmware's only mode; `host-sim closed-loop` runs the shared loop on the host).
    #[arg(long)]
    open_loop: bool,
    /// Also write the firmware's decoded event log to this file (for `host-sim hil --input`).
    #[arg(long, value_name = "FILE")]
    log: Option<PathBuf>,
    #[command(flatten)]
    contact: ContactArgs,
    #[command(flatten)]
    output: OutputArgs,
    /// Settings of the emulated run's scripted operator, after `--` (`cargo xtask run --help`
    /// lists them).
    #[arg(last = true, value_name = "KEY=VALUE", allow_hyphen_values = true)]
    scenario: Vec<String>,
}

#[derive(Serialize)]
struct CosimReport {
    plant: PathBuf,
    open_loop: bool,
    /// Cycle starts at which the firmware read the encoder.
    samples: usize,
    /// The firmware's time at the last sample.
    simulated_s: f64,
    wall_s: f64,
    plate_peak_excursion_m: f64,
    /// When the plate hit an end stop; null if it never did.
    end_stop_after_s: Option<f64>,
    end_stop: Option<EndStop>,
    firmware_exit_code: Option<i32>,
}

/// Runs `host-sim cosim`.
pub fn run(args: &CosimArgs) -> Result<(), SimError> {
    args.output.check()?;
    if !args.open_loop {
        return Err(SimError::Request(
            "the emulated firmware runs its command as planned: give --open-loop (host-sim \
             closed-loop runs the shared closed loop on the host)"
                .into(),
        ));
    }
    let plant_file = PlantFile::from_path(&args.plant)?;
    let plant = PlatePlant::new(
        &plant_file,
        &args.contact.contact()?,
        DacCalibration::DEFAULT,
        TICK_HZ,
    )?;
    let started = Instant::now();
    let run = feeder_emulator::run_with_plant(&args.elf, &args.scenario, LIMIT, plant)
        .map_err(|error| SimError::Request(format!("the co-simulation failed: {error}")))?;
    let wall_s = started.elapsed().as_secs_f64();
    if let Some(path) = &args.log {
        std::fs::write(path, &run.run.log).map_err(|error| SimError::Output {
            path: path.display().to_string(),
            reason: error.to_string(),
        })?;
    }
    let plate = &run.plant;
    if let Some(error) = plate.error() {
        return Err(error.clone());
    }
    let samples = plate.samples();
    let report = CosimReport {
        plant: args.plant.clone(),
        open_loop: true,
        samples: samples.len(),
        simulated_s: samples
            .last()
            .map_or(0.0, |s| s.tick as f64 / f64::from(TICK_HZ)),
        wall_s,
        plate_peak_excursion_m: plate.peak_excursion_m(),
        end_stop_after_s: plate.end_stop().map(|stop| stop.time_s),
        end_stop: plate.end_stop(),
        firmware_exit_code: run.run.status.code(),
    };
    emit(
        &args.output,
        samples,
        |_| Ok(()),
        &report,
        || print_report(&report, samples),
    )
}

fn print_report(report: &CosimReport, samples: &[PlateSample]) {
    say!("plant             {}", report.plant.display());
    say!(
        "run               {} cycle starts, {:.3} s simulated in {:.2} s ({:.1}× real time)",
        report.samples,
        report.simulated_s,
        report.wall_s,
        report.simulated_s / report.wall_s.max(1e-9)
    );
    if let (Some(first), Some(last)) = (samples.first(), samples.last()) {
        say!(
            "plate             {:.1} µm at the first cycle start, {:.1} µm at the last, peak |x| {:.3} mm",
            first.position_m * 1e6,
            last.position_m * 1e6,
            report.plate_peak_excursion_m * 1e3
        );
    }
    say!(
        "firmware          exit code {}",
        report
            .firmware_exit_code
            .map_or("none (killed)".to_string(), |code| code.to_string())
    );
    match report.end_stop {
        Some(stop) => say!(
            "open loop: end stop at {:+.1} mm after {:.4} s, at {:.3} m/s",
            stop.position_m * 1e3,
            stop.time_s,
            stop.velocity_mps
        ),
        None => say!(
            "open loop: no end stop in {:.3} s (peak |x| {:.3} mm)",
            report.simulated_s,
            report.plate_peak_excursion_m * 1e3
        ),
    }
}
