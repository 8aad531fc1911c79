//! A plant file's plate on the twin's pins: `host-sim`'s real plate (the same solver QEMU's
//! lockstep link drives), its drive commanded by the DAC's code from each latch on, gated by the
//! driver's enable (PA10), and its encoder counted into TIM4 whenever the firmware or a DMA
//! channel reads the count. The plate counts the core's cycles from power-up; every read is kept
//! as a capture, so the closed loop's verdict finds the plate at each cycle start the firmware
//! logged (`host_sim::cosim::judge`, on the log's ticks through a [`Timeline`]).

use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;

use feeder_emulator::plant_link::Plant;
use feeder_shared::event::{parse_line, Event};
use feeder_shared::{DacCalibration, Friction};
use host_sim::cosim::{self, closed_loop_lines, PlatePlant, Timeline};
use host_sim::plate::PlantFile;
use host_sim::Contact;

use crate::machine::Plate;
use crate::outputs::OutputRecord;
use crate::{Cycles, CORE_HZ};

/// The plate behind the outputs, shared with the run that judges it; the outputs also go to
/// `record`, for the check of every segment on the DAC.
pub struct PlantPlate {
    record: OutputRecord,
    plate: Rc<RefCell<PlatePlant>>,
}

impl PlantPlate {
    /// `plate` (timed in core cycles) behind the outputs, which `record` also keeps.
    pub fn new(plate: Rc<RefCell<PlatePlant>>, record: OutputRecord) -> Self {
        PlantPlate { record, plate }
    }
}

impl Plate for PlantPlate {
    fn level(&mut self, at: Cycles, code: u32) {
        self.record.level(at, code);
        let code = i32::try_from(code).unwrap_or(i32::MAX);
        self.plate.borrow_mut().level(at, code);
    }

    fn enable(&mut self, at: Cycles, on: bool) {
        self.record.enable(at, on);
        self.plate.borrow_mut().enable(at, on);
    }

    fn count(&mut self, at: Cycles) -> i32 {
        self.plate.borrow_mut().capture(at)
    }

    fn pwm(&mut self, at: Cycles, duty_counts: u32, forward: bool) {
        self.record.pwm(at, duty_counts, forward);
    }

    fn reset(&mut self, at: Cycles) {
        self.record.reset(at);
        self.plate.borrow_mut().enable(at, false);
    }
}

/// A plant file's plate for a run, with what judges it.
pub struct PlantRun {
    plate: Rc<RefCell<PlatePlant>>,
    file: PlantFile,
    contact: Contact,
}

/// The closed loop's verdict on a run, and its report.
pub struct PlantReport {
    pub passed: bool,
    /// The report's lines, the verdict's last.
    pub text: String,
}

impl PlantRun {
    /// The plate of the plant file at `path`, carrying the part the firmware is configured for,
    /// behind a DAC of the default calibration, timed in the core's cycles.
    pub fn new(path: &Path) -> Result<Self, String> {
        let file = PlantFile::from_path(path).map_err(|error| error.to_string())?;
        let friction = Friction::CONFIGURED;
        let contact = Contact::paper_part(friction.mu, friction.gravity_mps2)
            .map_err(|error| error.to_string())?;
        let core_hz =
            u32::try_from(CORE_HZ).map_err(|_| "the core's clock overflows a tick rate")?;
        let plate = PlatePlant::new(&file, &contact, DacCalibration::DEFAULT, core_hz)
            .map_err(|error| error.to_string())?;
        Ok(PlantRun {
            plate: Rc::new(RefCell::new(plate)),
            file,
            contact,
        })
    }

    /// The plate on the board's outputs, which `record` also keeps.
    pub fn outputs(&self, record: OutputRecord) -> PlantPlate {
        PlantPlate::new(self.plate.clone(), record)
    }
}

/// The closed loop of the run whose decoded log is `log`, on `plant`'s plate, the output's tick
/// 0 at core time `origin`: judged as `host-sim cosim` judges QEMU's.
pub fn judge(log: &str, plant: &PlantRun, origin: Cycles) -> Result<PlantReport, String> {
    let clock_hz = log
        .lines()
        .find_map(|line| match parse_line(line) {
            Ok(Some(Event::Plan { clock_hz, .. })) => Some(clock_hz),
            _ => None,
        })
        .ok_or("the log has no plan (EVT plan): is it the image built with hil-trace?")?;
    let timeline = Timeline {
        origin,
        plate_ticks_per_tick: CORE_HZ / u64::from(clock_hz.max(1)),
    };
    let plate = plant.plate.borrow();
    if let Some(error) = plate.error() {
        return Err(format!("the plate could not go on: {error}"));
    }
    let (loop_log, verdict) = cosim::judge(log, &plate, &plant.file, &plant.contact, timeline)
        .map_err(|error| error.to_string())?;
    let mut lines = vec![format!(
        "plate             peak |x| {:.3} mm, {}",
        plate.peak_excursion_m() * 1e3,
        plate
            .end_stop()
            .map_or("no end stop".into(), |stop| format!(
                "end stop at {:.3} s",
                stop.time_s
            ))
    )];
    lines.extend(closed_loop_lines(&loop_log, &verdict));
    lines.push(verdict.line());
    Ok(PlantReport {
        passed: verdict.passed,
        text: lines.join("\n"),
    })
}
