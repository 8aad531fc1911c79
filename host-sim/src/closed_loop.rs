//! The shared closed loop against a real plate: the shared scheduler held for the course's probe
//! and centring, then released, its cycles trimmed at every boundary by the shared course
//! ([`feeder_shared::closed_loop::Course`]) from the plate's encoder, sampled at a fixed interval
//! and at each cycle's start tick as the firmware's sensor does. Decisions are applied at the
//! segment after the boundary that made them, and a cycle's trims are fixed when its first
//! segment is made, as in the firmware's control loop.

use feeder_shared::closed_loop::{
    Course, CourseConfig, CourseError, CycleTrims, Decision, Identified, LoopLimits,
    PositionSample, Stage, Trims,
};
use feeder_shared::{DacCalibration, Scheduler, Segment, SegmentKind, TickPlan};

use crate::error::SimError;
use crate::plant::{Contact, PlateSegment};
use crate::plate::{EndStop, PlantFile, Stepper};
use crate::sensors::EncoderConfig;

/// The closed loop's figures, the same for a run on the host and for the co-simulated
/// firmware's: every cycle's mean position within this of centre …
pub const MEAN_POSITION_LIMIT_M: f64 = 50e-6;
/// … the feed rate over the last [`FEED_RATE_CYCLES`] cycles within this of the ideal plate's …
pub const FEED_RATE_TOLERANCE: f64 = 0.01;
pub const FEED_RATE_CYCLES: usize = 50;
/// … and each identified gain within this of the plant file's.
pub const GAIN_TOLERANCE: f64 = 0.01;

/// How the closed loop runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedLoopOptions {
    /// Cycles of motion after the course's centring, soft start included.
    pub cycles: u64,
    /// Soft start over this many cycles.
    pub ramp_cycles: u16,
    /// Cycles of the probe, at `probe_fraction` of the waveform's levels.
    pub probe_cycles: u32,
    pub probe_fraction: f64,
    /// Interval of the encoder's samples.
    pub sample_s: f64,
    /// A new plan requested at the start of this cycle (counted from the first after the
    /// centring).
    pub plan_change: Option<(u64, TickPlan)>,
    /// The last cycles over which the feed rate is averaged.
    pub average_cycles: u64,
    pub limits: LoopLimits,
    /// The output's DAC: every level is commanded in its codes.
    pub dac: DacCalibration,
}

impl ClosedLoopOptions {
    /// `cycles` of motion with a 25-cycle soft start, after the course's defaults
    /// ([`CourseConfig::new`]): a 3-cycle probe at 30 % of the levels, the encoder sampled every
    /// 0.25 ms, the levels in the codes of the default DAC (as the firmware's).
    pub fn new(cycles: u64) -> Self {
        let dac = DacCalibration::DEFAULT;
        let course = CourseConfig::new(1e-6, 1.0 / dac.counts_per_mps2);
        ClosedLoopOptions {
            cycles,
            ramp_cycles: 25,
            probe_cycles: course.probe_cycles,
            probe_fraction: course.probe_fraction,
            sample_s: 2.5e-4,
            plan_change: None,
            average_cycles: (FEED_RATE_CYCLES as u64).min(cycles),
            limits: course.loop_limits,
            dac,
        }
    }
}

/// One cycle (or idle period) of the closed loop.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CycleRecord {
    /// Feeding cycles counted from the first; the course's cycles before it count as 0.
    pub cycle: u64,
    /// Time at the cycle's start, the probe included.
    pub time_s: f64,
    /// The plate's position sampled by the encoder at the cycle's start tick.
    pub start_m: f64,
    /// The plate's mean position over the cycle (exact).
    pub mean_position_m: f64,
    /// The part's displacement at the cycle's start.
    pub part_m: f64,
    pub positive_trim: f64,
    pub negative_trim: f64,
    pub bias_mps2: f64,
    /// True for a cycle of the course before feeding: the probe, the identification's idle
    /// periods and the centring.
    pub centring: bool,
    /// True for an idle period.
    pub idle: bool,
}

/// The outcome of a closed-loop run.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoopRun {
    pub identified: Identified,
    pub cycles: Vec<CycleRecord>,
    /// Mean part velocity over the last `average_cycles` cycles.
    pub feed_rate_mps: f64,
    /// The largest `|mean position|` of a feeding cycle, soft start included.
    pub worst_mean_position_m: f64,
    pub end_stop: Option<EndStop>,
}

/// Runs the course, then `options.cycles` feeding cycles. An identification the shared limits
/// refuse, a course that stops and a plant file without an encoder are errors; an end stop
/// ends the run.
pub fn run_closed_loop(
    plant: &PlantFile,
    contact: &Contact,
    plan: TickPlan,
    options: &ClosedLoopOptions,
) -> Result<ClosedLoopRun, SimError> {
    let encoder = plant
        .sensors
        .encoder
        .ok_or(SimError::MissingSensor { sensor: "encoder" })?;
    let mut plate = SampledPlate {
        stepper: Stepper::new(&plant.plate, contact)?,
        dac: options.dac,
        encoder,
        clock_hz: plan.clock_hz,
        tick: 0,
        sample_ticks: ((options.sample_s * f64::from(plan.clock_hz)).round() as u64).max(1),
        samples: Vec::new(),
    };
    let config = CourseConfig {
        probe_cycles: options.probe_cycles,
        probe_fraction: options.probe_fraction,
        loop_limits: options.limits,
        ..CourseConfig::new(encoder.resolution_m, 1.0 / options.dac.counts_per_mps2)
    };
    let mut scheduler = Scheduler::new(plan, options.ramp_cycles);
    let mut course = Course::new(config, scheduler.ramp_cycles());
    scheduler.hold_step(course.probe_step());
    let mut identified = None;
    let mut records: Vec<CycleRecord> = Vec::new();
    let mut worst_mean_position_m = 0.0_f64;
    // The decision made at the last boundary, applied at the next segment begun.
    let mut pending: Option<Decision> = None;
    let mut cycle_trims = CycleTrims::NONE;
    // The feeder comes up idle, the drive enabled at zero command, and is started at once: the
    // probe begins one idle period later.
    let mut queued = scheduler.next_segment();
    scheduler.start();
    let mut queued_trims = Trims::NONE;
    let mut trims = Trims::NONE;
    let mut feeding_cycles = 0;
    let mut open: Option<OpenCycle> = None;
    loop {
        let playing = queued;
        if let Some(decision) = pending.take() {
            if decision.release {
                scheduler.release_hold();
            }
            cycle_trims.take(&decision, course.feedforward());
        }
        if playing.starts_cycle() {
            trims = queued_trims;
            let start = plate.sample_now()?;
            let samples = std::mem::take(&mut plate.samples);
            if let Some(open) = open.take() {
                let record = open.close(&plate);
                if !record.centring && !record.idle && plate.stepper.end_stop().is_none() {
                    worst_mean_position_m = worst_mean_position_m.max(record.mean_position_m.abs());
                }
                records.push(record);
            }
            if plate.stepper.end_stop().is_some()
                || (course.stage() == Stage::Feeding && feeding_cycles >= options.cycles)
            {
                break;
            }
            let time_s = plate.time_s();
            let fail = |error: CourseError| match error {
                CourseError::Identify(error) => SimError::Identification(error),
                error => SimError::Loop { time_s, error },
            };
            let decision = course
                .boundary(&playing, &scheduler, start, &samples)
                .map_err(fail)?;
            if let Some(probe) = course.probe() {
                let found = probe.identify();
                course.set_identified(found).map_err(fail)?;
                identified = course.identified().copied();
            }
            let feeding = course.stage() == Stage::Feeding;
            let idle = playing.kind == SegmentKind::Idle;
            if feeding && !idle {
                if let Some((at, new_plan)) = options.plan_change {
                    if feeding_cycles == at {
                        scheduler.set_plan(new_plan)?;
                    }
                }
                feeding_cycles += 1;
            }
            open = Some(OpenCycle {
                record: CycleRecord {
                    cycle: if feeding { feeding_cycles } else { 0 },
                    time_s,
                    start_m: start.position_m,
                    mean_position_m: 0.0,
                    part_m: plate.stepper.part_position_m(),
                    positive_trim: trims.positive,
                    negative_trim: trims.negative,
                    bias_mps2: trims.bias_mps2,
                    centring: !feeding,
                    idle,
                },
                integral_ms: plate.stepper.position_integral_ms(),
            });
            pending = Some(decision);
        }
        queued = scheduler.next_segment();
        if queued.starts_cycle() {
            let after_idle = playing.kind == SegmentKind::Idle;
            queued_trims = cycle_trims
                .for_cycle(&queued, after_idle)
                .map_err(|late| SimError::Request(format!("no trims for cycle {}", late.cycle)))?
                .unwrap_or(Trims::NONE);
        }
        plate.play(&playing, &trims)?;
    }
    let identified = identified.ok_or(SimError::Loop {
        time_s: plate.time_s(),
        error: CourseError::Plan,
    })?;
    let feed_rate_mps = feed_rate(&records, &plate.stepper, options.average_cycles);
    Ok(ClosedLoopRun {
        identified,
        cycles: records,
        feed_rate_mps,
        worst_mean_position_m,
        end_stop: plate.stepper.end_stop(),
    })
}

/// A cycle begun, its record waiting for the mean position at its end.
struct OpenCycle {
    record: CycleRecord,
    integral_ms: f64,
}

impl OpenCycle {
    fn close(self, plate: &SampledPlate) -> CycleRecord {
        let period_s = plate.time_s() - self.record.time_s;
        CycleRecord {
            mean_position_m: (plate.stepper.position_integral_ms() - self.integral_ms) / period_s,
            ..self.record
        }
    }
}

/// The plate on the scheduler's ticks, driven through a DAC and its encoder sampled at every
/// multiple of `sample_ticks` and at each cycle start, as the firmware's output and sensor do.
struct SampledPlate {
    stepper: Stepper,
    dac: DacCalibration,
    encoder: EncoderConfig,
    clock_hz: u32,
    tick: u64,
    sample_ticks: u64,
    /// Samples since the last cycle start.
    samples: Vec<PositionSample>,
}

impl SampledPlate {
    fn time_s(&self) -> f64 {
        self.tick as f64 / f64::from(self.clock_hz)
    }

    /// Plays `segment` at the trimmed level, sampling on the way.
    fn play(&mut self, segment: &Segment, trims: &Trims) -> Result<(), SimError> {
        let code = self
            .dac
            .code(trims.apply(segment.accel_mps2()))
            .map_err(|error| SimError::TrimmedLevel {
                time_s: self.time_s(),
                error,
            })?;
        let accel_mps2 = self.dac.accel_mps2(i32::from(code));
        let end_tick = self.tick + u64::from(segment.ticks);
        loop {
            let next_sample = (self.tick / self.sample_ticks + 1) * self.sample_ticks;
            let to_tick = next_sample.min(end_tick);
            self.stepper.segment(&PlateSegment {
                duration_s: (to_tick - self.tick) as f64 / f64::from(self.clock_hz),
                accel_mps2,
                starts_cycle: false,
            })?;
            self.tick = to_tick;
            if self.stepper.end_stop().is_some() || to_tick == end_tick {
                if to_tick == end_tick && to_tick == next_sample {
                    let sample = self.sample_now()?;
                    self.samples.push(sample);
                }
                return Ok(());
            }
            let sample = self.sample_now()?;
            self.samples.push(sample);
        }
    }

    /// The encoder now, as a timer capture latches it at a tick: the middle of its count.
    fn sample_now(&self) -> Result<PositionSample, SimError> {
        let count =
            self.encoder
                .count(self.stepper.plate_position_m())
                .ok_or(SimError::SensorInput {
                    sensor: "encoder",
                    t_s: self.time_s(),
                    reason: "the position is beyond 2^53 counts",
                })?;
        Ok(PositionSample {
            tick: self.tick,
            position_m: (count as f64 + 0.5) * self.encoder.resolution_m,
        })
    }
}

/// Mean part velocity over the last `average_cycles` cycles recorded (to the stepper's end).
fn feed_rate(records: &[CycleRecord], stepper: &Stepper, average_cycles: u64) -> f64 {
    let window = (average_cycles as usize).min(records.len());
    match records
        .len()
        .checked_sub(window)
        .and_then(|i| records.get(i))
    {
        Some(first) if stepper.time_s() > first.time_s => {
            (stepper.part_position_m() - first.part_m) / (stepper.time_s() - first.time_s)
        }
        _ => 0.0,
    }
}
