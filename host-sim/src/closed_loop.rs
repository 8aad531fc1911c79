//! The shared closed loop against a real plate: the shared scheduler held for the course's probe
//! and centring, then released, its cycles trimmed at every boundary by the shared course
//! ([`feeder_shared::closed_loop::Course`]) from the plate's encoder, sampled at a fixed interval
//! and at each cycle's start tick as the firmware's sensor does. Decisions are applied at the
//! segment after the boundary that made them, and a cycle's trims are fixed when its first
//! segment is made, as in the firmware's control loop.

use feeder_shared::closed_loop::{
    Course, CourseConfig, CourseError, CycleTrims, Decision, FeedCompensation, Identified,
    LoopLimits, PositionSample, Stage, Trims, ENVELOPE,
};
use feeder_shared::{DacCalibration, Scheduler, Segment, SegmentKind, TickPlan};

use crate::contact::Contact;
use crate::error::SimError;
use crate::plate::{EndStop, PlantFile, PlateParams, Stepper};
use crate::segments::PlateSegment;
use crate::sensors::EncoderConfig;

pub mod family;
pub mod verdict;

pub use verdict::{
    JudgedCycle, RunFacts, Verdict, FEED_RATE_CYCLES, FEED_RATE_TOLERANCE, GAIN_TOLERANCE,
    MEAN_POSITION_LIMIT_M,
};

/// How the closed loop runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedLoopOptions {
    /// Cycles after the one at whose start the course released the soft start (soft start
    /// included): the run ends with the last, as the firmware's scenario (`cycles=N`) requests
    /// the stop at its start. The verdict judges the release's cycle too.
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
    pub feed_cycles: usize,
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
            feed_cycles: FEED_RATE_CYCLES.min(usize::try_from(cycles).unwrap_or(usize::MAX)),
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
    /// Time at the cycle's start, from power-up.
    pub time_s: f64,
    /// How long it ran (shorter than planned where the run ended in it).
    pub duration_s: f64,
    /// The plate's position sampled by the encoder at the cycle's start tick.
    pub start_m: f64,
    /// The plate's mean position over the cycle (exact).
    pub mean_position_m: f64,
    /// The largest `|x|` the encoder sampled in the cycle, its end included.
    pub peak_m: f64,
    /// The part's displacement at the cycle's start, and how far it moved in the cycle.
    pub part_m: f64,
    pub part_moved_m: f64,
    pub positive_trim: f64,
    pub negative_trim: f64,
    pub bias_mps2: f64,
    /// True for a cycle of the course before feeding: the probe, the identification's idle
    /// periods and the centring.
    pub centring: bool,
    /// True for an idle period.
    pub idle: bool,
}

/// The outcome of a closed-loop run: a run the loop gave up on is an outcome too.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoopRun {
    /// The drive identified by the course (none if it never was).
    pub identified: Option<Identified>,
    /// The feed's compensation of the drive's lag for the last plan (none before the drive is
    /// identified).
    pub feed: Option<FeedCompensation>,
    pub cycles: Vec<CycleRecord>,
    /// The scheduler's cycle at whose start the course decided to release the soft start (the
    /// firmware logs it as `closed loop: Feeding at cycle N`); none if it never did.
    pub release_cycle: Option<u64>,
    /// Largest `|x|` from power-up to the release (to the end if there was none), and over the
    /// whole run.
    pub startup_peak_m: f64,
    pub peak_excursion_m: f64,
    pub end_stop: Option<EndStop>,
    /// Why the loop gave up: the course stopped, the identification refused the drive, or a
    /// trimmed level left the DAC's range.
    pub gave_up: Option<SimError>,
    /// Time from power-up to the run's end.
    pub simulated_s: f64,
}

impl ClosedLoopRun {
    /// The running cycles from the release on, as the verdict reads them.
    pub fn fed(&self) -> Vec<JudgedCycle> {
        self.cycles
            .iter()
            .filter(|c| !c.centring && !c.idle)
            .map(|c| JudgedCycle {
                time_s: c.time_s,
                duration_s: c.duration_s,
                mean_position_m: c.mean_position_m,
                part_moved_m: c.part_moved_m,
            })
            .collect()
    }

    /// The run judged: `plate` its plant's, `ideal_feed_rate_mps` and `velocity_scale_mps` the
    /// ideal plate's feed rate and `a_max·T/4` at the plan in force at the end.
    pub fn verdict(
        &self,
        plate: &PlateParams,
        options: &ClosedLoopOptions,
        ideal_feed_rate_mps: f64,
        velocity_scale_mps: f64,
    ) -> Verdict {
        let fed = self.fed();
        let gave_up = self.gave_up.as_ref().map(ToString::to_string);
        Verdict::judge(&RunFacts {
            fed: &fed,
            released: self.release_cycle.is_some(),
            ramp_cycles: u64::from(options.ramp_cycles),
            feed_cycles: options.feed_cycles,
            startup_peak_m: self.startup_peak_m,
            peak_excursion_m: self.peak_excursion_m,
            end_stop_m: plate.end_stop_m,
            end_stop: self.end_stop,
            gave_up: gave_up.as_deref(),
            identified_gains: self
                .identified
                .map(|found| [found.gain_positive, found.gain_negative]),
            plant_gains: [plate.gain_positive, plate.gain_negative],
            ideal_feed_rate_mps,
            velocity_scale_mps,
        })
    }
}

/// Runs the course, then `options.cycles` feeding cycles. A plant file without an encoder, a
/// plan whose levels leave the loop no room in the DAC's linear range
/// ([`feeder_shared::closed_loop::Envelope::check_loop_accel`]) and a plate the solver cannot
/// run are errors, refused before anything runs; where the loop gives up (a course that stops, an
/// identification the shared limits refuse, a trimmed level beyond the DAC) or the plate hits
/// an end stop, the run ends there and says so.
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
    let linear_mps2 = options.dac.linear_limit_mps2();
    for planned in core::iter::once(&plan).chain(options.plan_change.as_ref().map(|(_, p)| p)) {
        ENVELOPE.check_loop_accel(planned.waveform.accel_mps2, linear_mps2)?;
    }
    let plate = SampledPlate {
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
            .with_feed(contact.kinetic_accel_mps2(), linear_mps2)
    };
    let scheduler = Scheduler::new(plan, options.ramp_cycles);
    let course = Course::new(config, scheduler.ramp_cycles());
    let mut runner = Runner {
        plate,
        scheduler,
        course,
        records: Vec::new(),
        open: None,
        startup_peak_m: None,
        release_cycle: None,
    };
    let gave_up = match runner.run(options) {
        Ok(()) => None,
        Err(error @ (SimError::Loop { .. } | SimError::Identification(_))) => Some(error),
        Err(error @ SimError::TrimmedLevel { .. }) => Some(error),
        Err(error) => return Err(error),
    };
    if let Some(open) = runner.open.take() {
        let peak_m = sampled_peak_m(&runner.plate.samples, open.record.start_m);
        runner.records.push(open.close(&runner.plate, peak_m));
    }
    let stepper = &runner.plate.stepper;
    Ok(ClosedLoopRun {
        identified: runner.course.identified().copied(),
        feed: runner.course.report().feed,
        release_cycle: runner.release_cycle,
        startup_peak_m: runner
            .startup_peak_m
            .unwrap_or_else(|| stepper.peak_excursion_m()),
        peak_excursion_m: stepper.peak_excursion_m(),
        end_stop: stepper.end_stop(),
        gave_up,
        simulated_s: stepper.time_s(),
        cycles: runner.records,
    })
}

/// The run's state: the plate, the scheduler and the course, and what is recorded.
struct Runner {
    plate: SampledPlate,
    scheduler: Scheduler,
    course: Course,
    records: Vec<CycleRecord>,
    /// The cycle playing, its record waiting for its end.
    open: Option<OpenCycle>,
    /// The peak `|x|` at the release, once released.
    startup_peak_m: Option<f64>,
    /// The cycle whose boundary decided the release.
    release_cycle: Option<u64>,
}

impl Runner {
    fn run(&mut self, options: &ClosedLoopOptions) -> Result<(), SimError> {
        self.scheduler.hold_step(self.course.probe_step());
        self.scheduler
            .settle_before_start(self.course.config().settle_segments);
        // The decision made at the last boundary, applied at the next segment begun.
        let mut pending: Option<Decision> = None;
        let mut cycle_trims = CycleTrims::NONE;
        // The feeder comes up idle, the drive enabled at zero command, its output playing an
        // idle period with the next one made. The start, requested at once, is taken at the
        // first edge, as the firmware's control loop takes a request: the probe begins two idle
        // periods after power-up.
        let mut queued = self.scheduler.next_segment();
        let mut start_requested = true;
        let mut queued_trims = Trims::NONE;
        let mut trims = Trims::NONE;
        let mut feeding_cycles = 0;
        loop {
            let playing = queued;
            if let Some(decision) = pending.take() {
                if decision.release {
                    self.scheduler.release_hold();
                    self.startup_peak_m = Some(self.plate.stepper.peak_excursion_m());
                }
                cycle_trims.take(&decision, self.course.feedforward());
            }
            if playing.starts_cycle() {
                trims = queued_trims;
                let start = self.plate.sample_now()?;
                let samples = std::mem::take(&mut self.plate.samples);
                if let Some(open) = self.open.take() {
                    let peak_m = sampled_peak_m(&samples, start.position_m);
                    self.records.push(open.close(&self.plate, peak_m));
                }
                if self.plate.stepper.end_stop().is_some()
                    || (self.course.stage() == Stage::Feeding && feeding_cycles > options.cycles)
                {
                    return Ok(());
                }
                let time_s = self.plate.time_s();
                let fail = |error: CourseError| match error {
                    CourseError::Identify(error) => SimError::Identification(error),
                    error => SimError::Loop { time_s, error },
                };
                // A new plan is queued before the course decides, as the firmware adopts one:
                // the course sees it in the cycles ahead.
                let idle = playing.kind == SegmentKind::Idle;
                if self.course.stage() == Stage::Feeding && !idle {
                    if let Some((at, new_plan)) = options.plan_change {
                        if feeding_cycles == at {
                            self.scheduler.set_plan(new_plan)?;
                        }
                    }
                }
                let decision = self
                    .course
                    .boundary(&playing, &self.scheduler, start, &samples)
                    .map_err(fail)?;
                if let Some(request) = self.course.feed_request() {
                    self.course.set_feed(request, request.solve());
                }

                // Identified at once; the course takes it at the end of its hold.
                if let Some(probe) = self.course.probe().filter(|_| decision.identify) {
                    let found = probe.identify();
                    self.course.set_identified(found);
                }
                let feeding = self.course.stage() == Stage::Feeding;
                if decision.release {
                    self.release_cycle = Some(playing.cycle);
                }
                if feeding && !idle {
                    feeding_cycles += 1;
                }
                self.open = Some(OpenCycle {
                    record: CycleRecord {
                        cycle: if feeding { feeding_cycles } else { 0 },
                        time_s,
                        duration_s: 0.0,
                        start_m: start.position_m,
                        mean_position_m: 0.0,
                        peak_m: 0.0,
                        part_m: self.plate.stepper.part_position_m(),
                        part_moved_m: 0.0,
                        positive_trim: trims.positive,
                        negative_trim: trims.negative,
                        bias_mps2: trims.bias_mps2,
                        centring: !feeding,
                        idle,
                    },
                    integral_ms: self.plate.stepper.position_integral_ms(),
                });
                pending = Some(decision);
            }
            if playing.start_tick > 0 && std::mem::take(&mut start_requested) {
                self.scheduler.start();
            }
            queued = self.scheduler.next_segment();
            if queued.starts_cycle() {
                let after_idle = playing.kind == SegmentKind::Idle;
                queued_trims = cycle_trims
                    .for_cycle(&queued, after_idle)
                    .map_err(|late| {
                        SimError::Request(format!("no trims for cycle {}", late.cycle))
                    })?
                    .unwrap_or(Trims::NONE);
            }
            // The firmware's driver enable: on while motion is requested (from the start on
            // here) and the segment playing drives.
            self.plate.stepper.set_drive_enabled(playing.kind.drives());
            self.plate.play(&playing, &trims)?;
        }
    }
}

/// The largest `|x|` among `samples` and the position `also_m`.
fn sampled_peak_m(samples: &[PositionSample], also_m: f64) -> f64 {
    samples
        .iter()
        .map(|sample| sample.position_m.abs())
        .fold(also_m.abs(), f64::max)
}

/// A cycle begun, its record waiting for the mean position at its end.
struct OpenCycle {
    record: CycleRecord,
    integral_ms: f64,
}

impl OpenCycle {
    /// The record at the cycle's end, `peak_m` the largest `|x|` sampled in it.
    fn close(self, plate: &SampledPlate, peak_m: f64) -> CycleRecord {
        let stepper = &plate.stepper;
        let duration_s = stepper.time_s() - self.record.time_s;
        let mean_position_m = if duration_s > 0.0 {
            (stepper.position_integral_ms() - self.integral_ms) / duration_s
        } else {
            self.record.start_m
        };
        CycleRecord {
            duration_s,
            mean_position_m,
            peak_m,
            part_moved_m: stepper.part_position_m() - self.record.part_m,
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
            .code(trims.level(segment.kind.place(), segment.accel_mps2()))
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

/// The feed's compensation in one line of a report: the amplitude on the levels and the ideal
/// plate's feed, or, where the drive's range limits it (`limited_mps`), the feed given instead.
pub fn feed_compensation_line(amplitude: f64, ideal_mps: f64, limited_mps: Option<f64>) -> String {
    match limited_mps {
        Some(feed_mps) => format!(
            "feed compensated  levels ×{amplitude:.4}, the most the drive's linear range allows: \
             {:.2} mm/s instead of the ideal plate's {:.2} mm/s ({:+.1} %)",
            feed_mps * 1e3,
            ideal_mps * 1e3,
            (feed_mps / ideal_mps - 1.0) * 1e2
        ),
        None => format!(
            "feed compensated  levels ×{amplitude:.4} for the ideal plate's {:.2} mm/s behind the \
             drive's lag",
            ideal_mps * 1e3
        ),
    }
}
