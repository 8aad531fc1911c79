//! The shared closed loop against a real plate: the drive identified from a probe, then the
//! shared scheduler's cycles trimmed at every boundary by the shared cycle-rate loop, from the
//! plate's encoder latched at each cycle's start tick and turning tick.

use feeder_shared::closed_loop::{
    identify, CommandSegment, CycleLoop, CycleShape, Identified, IdentifyLimits, Latch, LoopError,
    LoopLimits, Stroke,
};
use feeder_shared::{Scheduler, SegmentKind, TickPlan, Waveform};

use crate::error::SimError;
use crate::plant::{Contact, PlateSegment};
use crate::plate::{EndStop, PlantFile, Stepper};
use crate::segments::{exact_cycle, in_seconds};
use crate::sensors::{Encoder, EncoderConfig};

/// The plate counts as centred within this of its centre at a cycle start …
const CENTRED_M: f64 = 25e-6;
/// … for this many idle cycles in a row, and the feeder starts.
const CENTRED_CYCLES: u32 = 3;
/// Positions latched per cycle for its mean, the start's included.
const MEAN_LATCHES: usize = 16;
/// Centring that takes longer than this (from the probe's start) fails.
const CENTRING_TIMEOUT_S: f64 = 5.0;

/// How the closed loop runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedLoopOptions {
    /// Cycles of motion after the probe, soft start included.
    pub cycles: u64,
    /// Soft start over this many cycles.
    pub ramp_cycles: u16,
    /// Cycles of the probe, at `probe_fraction` of the waveform's levels.
    pub probe_cycles: u32,
    pub probe_fraction: f64,
    /// Interval of the encoder's reads during the probe.
    pub probe_sample_s: f64,
    /// A new plan requested at the start of this cycle (counted from the first after the probe).
    pub plan_change: Option<(u64, TickPlan)>,
    /// The last cycles over which the feed rate is averaged.
    pub average_cycles: u64,
    pub limits: LoopLimits,
}

impl ClosedLoopOptions {
    /// `cycles` of motion with a 25-cycle soft start after a 3-cycle probe at 30 % amplitude
    /// read every 0.25 ms; the loop may add up to 10 m/s² and trim the stroke by ±20 %,
    /// and gives up 4 mm from centre.
    pub fn new(cycles: u64) -> Self {
        ClosedLoopOptions {
            cycles,
            ramp_cycles: 25,
            probe_cycles: 3,
            probe_fraction: 0.3,
            probe_sample_s: 2.5e-4,
            plan_change: None,
            average_cycles: 50.min(cycles),
            limits: LoopLimits {
                correction_max_mps2: 10.0,
                amplitude_max: 0.2,
                position_error_max_m: 4e-3,
            },
        }
    }
}

/// One cycle of the closed loop.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CycleRecord {
    pub cycle: u64,
    /// Time at the cycle's start, the probe included.
    pub time_s: f64,
    /// The plate's position latched by the encoder at the cycle's start tick.
    pub start_m: f64,
    /// The plate's mean position over the cycle (exact).
    pub mean_position_m: f64,
    /// The part's displacement at the cycle's start.
    pub part_m: f64,
    pub positive_trim: f64,
    pub negative_trim: f64,
    pub bias_mps2: f64,
    /// True for a cycle of the start-up's centring, before the scheduler runs.
    pub centring: bool,
    /// True for an idle cycle of the scheduler.
    pub idle: bool,
}

/// The outcome of a closed-loop run.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoopRun {
    pub identified: Identified,
    pub cycles: Vec<CycleRecord>,
    /// Mean part velocity over the last `average_cycles` cycles.
    pub feed_rate_mps: f64,
    /// The largest `|mean position|` of a cycle after the soft start.
    pub worst_mean_position_m: f64,
    pub end_stop: Option<EndStop>,
}

/// Identifies the drive, then runs the loop. An identification the shared limits refuse, a loop
/// that gives up and a plant file without an encoder are errors; an end stop ends the run.
pub fn run_closed_loop(
    plant: &PlantFile,
    contact: &Contact,
    waveform: &Waveform,
    plan: TickPlan,
    options: &ClosedLoopOptions,
) -> Result<ClosedLoopRun, SimError> {
    let encoder_config = plant
        .sensors
        .encoder
        .ok_or(SimError::MissingSensor { sensor: "encoder" })?;
    let mut stepper = Stepper::new(&plant.plate, contact)?.with_trajectory();
    let identified = probe(&mut stepper, encoder_config, waveform, options)?;
    let mut cycle_loop = CycleLoop::new(&identified, options.limits);
    let mut scheduler = Scheduler::new(plan, options.ramp_cycles);
    let first = scheduled_shapes(&cycle_loop, &scheduler, true);
    // Cycles in a row the plate has started centred while the loop centres it.
    let mut centred = 0;
    let mut records = Vec::new();
    let mut trims = cycle_loop.trims();
    // The last cycle's start and turning positions, its plan, its positions through the cycle
    // and whether it ran at full amplitude, for its stroke and its mean.
    let mut last: Option<(f64, f64, CycleShape, Vec<f64>, bool)> = None;
    let mut worst_mean_position_m = 0.0_f64;
    let mut cycle = 0;
    while cycle < options.cycles {
        if let Some((at, new_plan)) = options.plan_change {
            if cycle == at {
                scheduler.set_plan(new_plan)?;
            }
        }
        // Until the scheduler runs, the probe's cycle keeps the slide moving while the loop
        // centres it.
        let centring = !scheduler.run_requested();
        let (commanded, idle, full) = if centring {
            (probe_cycle(waveform, options), false, false)
        } else {
            next_cycle(&mut scheduler)
        };
        let shape = if idle {
            CycleShape::idle(commanded[0].duration_s)
        } else {
            cycle_loop.plan(&commanded).ok_or(SimError::BadRange {
                what: "a planned cycle must turn back",
            })?
        };
        let start_s = stepper.time_s();
        let start_m = latch(&stepper, encoder_config)?;
        let integral_start = stepper.position_integral_ms();
        let part_m = stepper.part_position_m();
        // While centring, the probe's cycle aims at the start of the soft start's first cycle,
        // so that the motion begins centred and at rest.
        let aim = CycleShape {
            mean_m: first[0].mean_m,
            ..shape
        };
        let starting = centring && (start_m + aim.mean_m).abs() <= CENTRED_M && {
            centred += 1;
            centred == CENTRED_CYCLES
        };
        if centring && !starting && (start_m + aim.mean_m).abs() > CENTRED_M {
            centred = 0;
            if start_s > CENTRING_TIMEOUT_S {
                return Err(SimError::Loop {
                    time_s: start_s,
                    error: LoopError::Position {
                        error_m: start_m + aim.mean_m,
                    },
                });
            }
        }
        let (now, upcoming) = match (centring, starting) {
            (false, _) => (shape, scheduled_shapes(&cycle_loop, &scheduler, false)),
            (true, true) => (aim, first),
            (true, false) => (aim, [aim; 2]),
        };
        let next = cycle_loop
            .update(
                start_m,
                // Stroke and mean are only held at full amplitude: friction shortens a soft
                // start's strokes, and moves its means, more than the full one's.
                last.as_ref()
                    .filter(|last| !centring && last.4)
                    .map(|(s, t, plan, _, _)| Stroke::latched(*s, *t, start_m, plan)),
                last.as_ref()
                    .filter(|last| !centring && last.4)
                    .map(|(_, _, _, positions_m, _)| trapezoid_mean_m(positions_m, start_m)),
                &now,
                [&upcoming[0], &upcoming[1]],
            )
            .map_err(|error| SimError::Loop {
                time_s: start_s,
                error,
            })?;
        if starting {
            scheduler.start();
        }
        // The encoder is latched at the turning tick and at MEAN_LATCHES − 1 evenly spaced ticks
        // inside the cycle, for its stroke and its mean position.
        let cycle_s: f64 = commanded.iter().map(|s| s.duration_s).sum();
        let mut instants: Vec<(f64, bool)> = (1..MEAN_LATCHES)
            .map(|i| (i as f64 * cycle_s / MEAN_LATCHES as f64, false))
            .collect();
        if !idle {
            instants.push((shape.turn_s, true));
        }
        instants.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut turn_m = None;
        let mut positions_m = vec![start_m];
        let mut offset_s = 0.0;
        let mut next_instant = 0;
        for segment in &commanded {
            let accel_mps2 = trims.apply(segment.accel_mps2);
            let end_s = offset_s + segment.duration_s;
            let mut at_s = offset_s;
            while next_instant < instants.len() && instants[next_instant].0 < end_s {
                let (t_s, is_turn) = instants[next_instant];
                if t_s > at_s {
                    stepper.segment(&PlateSegment {
                        duration_s: t_s - at_s,
                        accel_mps2,
                        starts_cycle: false,
                    })?;
                    at_s = t_s;
                }
                let x_m = latch(&stepper, encoder_config)?;
                if is_turn {
                    turn_m = Some(x_m);
                } else {
                    positions_m.push(x_m);
                }
                next_instant += 1;
            }
            stepper.segment(&PlateSegment {
                duration_s: end_s - at_s,
                accel_mps2,
                starts_cycle: false,
            })?;
            offset_s = end_s;
        }
        last = turn_m.map(|turn_m| (start_m, turn_m, shape, positions_m, full));
        let period_s = stepper.time_s() - start_s;
        let mean_position_m = (stepper.position_integral_ms() - integral_start) / period_s;
        if !idle && !centring && stepper.end_stop().is_none() {
            worst_mean_position_m = worst_mean_position_m.max(mean_position_m.abs());
        }
        records.push(CycleRecord {
            cycle,
            time_s: start_s,
            start_m,
            mean_position_m,
            part_m,
            positive_trim: trims.positive,
            negative_trim: trims.negative,
            bias_mps2: trims.bias_mps2,
            centring,
            idle,
        });
        trims = next;
        if !idle && !centring {
            cycle += 1;
        }
        if stepper.end_stop().is_some() {
            break;
        }
    }
    let feed_rate_mps = feed_rate(&records, &stepper, options.average_cycles);
    Ok(ClosedLoopRun {
        identified,
        cycles: records,
        feed_rate_mps,
        worst_mean_position_m,
        end_stop: stepper.end_stop(),
    })
}

/// The probe: `probe_cycles` of the waveform at `probe_fraction`, the encoder read every
/// `probe_sample_s`; the drive identified from it.
fn probe(
    stepper: &mut Stepper,
    config: EncoderConfig,
    waveform: &Waveform,
    options: &ClosedLoopOptions,
) -> Result<Identified, SimError> {
    let probe: Vec<CommandSegment> = (0..options.probe_cycles)
        .flat_map(|_| probe_cycle(waveform, options))
        .collect();
    let length_s: f64 = probe.iter().map(|s| s.duration_s).sum();
    for segment in &probe {
        stepper.segment(&PlateSegment {
            duration_s: segment.duration_s,
            accel_mps2: segment.accel_mps2,
            starts_cycle: false,
        })?;
    }
    let trajectory = stepper.stop_trajectory();
    let mut encoder = Encoder::new(config)?;
    let samples = (length_s / options.probe_sample_s).floor() as u64;
    let latches = (0..=samples)
        .map(|k| {
            let t_s = (k as f64 * options.probe_sample_s).min(length_s);
            Ok(Latch {
                t_s,
                position_m: middle(encoder.sample(&trajectory, t_s)?.count, config),
            })
        })
        .collect::<Result<Vec<_>, SimError>>()?;
    let limits = IdentifyLimits::for_probe(
        waveform.accel_mps2 * options.probe_fraction,
        config.resolution_m,
    );
    identify(&probe, &latches, &limits).map_err(SimError::Identification)
}

/// The plans of the scheduler's next two cycles, from a copy of it (`start`ed first when it has
/// not been yet).
fn scheduled_shapes(cycle_loop: &CycleLoop, scheduler: &Scheduler, start: bool) -> [CycleShape; 2] {
    let mut ahead = scheduler.clone();
    if start {
        ahead.start();
    }
    let mut shape = || {
        let (commanded, idle, _) = next_cycle(&mut ahead);
        let idle_shape = CycleShape::idle(commanded[0].duration_s);
        if idle {
            idle_shape
        } else {
            cycle_loop.plan(&commanded).unwrap_or(idle_shape)
        }
    };
    [shape(), shape()]
}

/// The mean of a cycle's positions latched at evenly spaced ticks from its start, closed by
/// `end_m` at the next start (trapezoids).
fn trapezoid_mean_m(positions_m: &[f64], end_m: f64) -> f64 {
    let inner: f64 = positions_m[1..].iter().sum();
    (inner + (positions_m[0] + end_m) / 2.0) / positions_m.len() as f64
}

/// One cycle of the waveform at the probe's fraction of its levels.
fn probe_cycle(waveform: &Waveform, options: &ClosedLoopOptions) -> Vec<CommandSegment> {
    exact_cycle(waveform)
        .iter()
        .map(|s| CommandSegment {
            duration_s: s.duration_s,
            accel_mps2: s.accel_mps2 * options.probe_fraction,
        })
        .collect()
}

/// The scheduler's next cycle in seconds (the four segments of a running cycle, or one idle
/// period), whether it is idle, and whether it runs at the plan's full amplitude.
fn next_cycle(scheduler: &mut Scheduler) -> (Vec<CommandSegment>, bool, bool) {
    let first = scheduler.next_segment();
    let idle = first.kind == SegmentKind::Idle;
    let full = !idle && first.amplitude.step == first.amplitude.steps;
    let mut segments = vec![first];
    if !idle {
        while segments.len() < 4 {
            segments.push(scheduler.next_segment());
        }
    }
    let plan = scheduler.plan();
    let commanded = segments
        .iter()
        .map(|s| {
            let segment = in_seconds(plan, s);
            CommandSegment {
                duration_s: segment.duration_s,
                accel_mps2: segment.accel_mps2,
            }
        })
        .collect();
    (commanded, idle, full)
}

/// The position the firmware takes from a count: the middle of it.
fn middle(count: i64, config: EncoderConfig) -> f64 {
    (count as f64 + 0.5) * config.resolution_m
}

/// The encoder latched now, as a timer capture does at a tick.
fn latch(stepper: &Stepper, config: EncoderConfig) -> Result<f64, SimError> {
    let count = config
        .count(stepper.plate_position_m())
        .ok_or(SimError::SensorInput {
            sensor: "encoder",
            t_s: stepper.time_s(),
            reason: "the position is beyond 2^53 counts",
        })?;
    Ok(middle(count, config))
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
