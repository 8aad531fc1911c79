//! The real plate as the plant of the firmware's lockstep link (the QEMU `cosim` image): every
//! level the firmware's output applies drives the plate from its tick on, and every sample
//! request is answered with the plate encoder's count at its tick. QEMU runs no instruction
//! while the plate computes, so the co-simulation is deterministic.

use feeder_emulator::plant::Plant;
use feeder_shared::DacCalibration;

use crate::closed_loop::{
    FEED_RATE_CYCLES, FEED_RATE_TOLERANCE, GAIN_TOLERANCE, MEAN_POSITION_LIMIT_M,
};
use crate::error::SimError;
use crate::hil::{parse_line, Event};
use crate::plant::{Contact, PlateSegment};
use crate::plate::{EndStop, PlantFile, Stepper};
use crate::scenario::OperatingPoint;
use crate::sensors::EncoderConfig;

/// The plate at a sample request: a cycle start of the firmware's output.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PlateSample {
    /// The output's tick.
    pub tick: u64,
    pub time_s: f64,
    pub position_m: f64,
    /// The count answered.
    pub count: i32,
    /// `∫x dt` since the start, for mean positions between samples.
    pub position_integral_ms: f64,
    /// The part's displacement.
    pub part_m: f64,
}

/// A real plate behind the link.
#[derive(Debug)]
pub struct PlatePlant {
    stepper: Stepper,
    dac: DacCalibration,
    encoder: EncoderConfig,
    clock_hz: u32,
    /// The acceleration held and the tick from which it has been.
    held: Option<(u64, f64)>,
    /// The firmware's encoder sample interval, once configured.
    interval_ticks: Option<u64>,
    /// Samples the firmware has not taken yet: `(tick, count)`.
    pending: Vec<(u64, i32)>,
    /// Every level the output applied: `(tick, acceleration)`.
    levels: Vec<(u64, f64)>,
    samples: Vec<PlateSample>,
    error: Option<SimError>,
}

impl PlatePlant {
    /// The plate of `plant` carrying a part of `contact`, its drive fed through `dac` by an output
    /// timed in ticks of `clock_hz`; the plant file must list an encoder.
    pub fn new(
        plant: &PlantFile,
        contact: &Contact,
        dac: DacCalibration,
        clock_hz: u32,
    ) -> Result<Self, SimError> {
        let encoder = plant
            .sensors
            .encoder
            .ok_or(SimError::MissingSensor { sensor: "encoder" })?;
        Ok(PlatePlant {
            stepper: Stepper::new(&plant.plate, contact)?,
            dac,
            encoder,
            clock_hz,
            held: None,
            interval_ticks: None,
            pending: Vec::new(),
            levels: Vec::new(),
            samples: Vec::new(),
            error: None,
        })
    }

    /// Runs the held level up to `tick`, sampling the encoder at every multiple of the
    /// firmware's interval on the way.
    fn advance(&mut self, tick: u64) {
        let Some((from, accel_mps2)) = self.held else {
            return;
        };
        let mut at = from;
        while at < tick && self.error.is_none() {
            let next_sample = self
                .interval_ticks
                .map_or(u64::MAX, |interval| (at / interval + 1) * interval);
            let to = next_sample.min(tick);
            let segment = PlateSegment {
                duration_s: (to - at) as f64 / f64::from(self.clock_hz),
                accel_mps2,
                starts_cycle: false,
            };
            if let Err(error) = self.stepper.segment(&segment) {
                self.error = Some(error);
            }
            at = to;
            if to == next_sample {
                let count = self.count();
                self.pending.push((to, count));
            }
        }
        self.held = Some((tick.max(from), accel_mps2));
    }

    /// The encoder's count now.
    fn count(&self) -> i32 {
        self.encoder
            .count(self.stepper.plate_position_m())
            .map_or(0, |c| {
                c.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
            })
    }

    /// Every level the output applied, `(tick, acceleration)`, in order.
    pub fn levels(&self) -> &[(u64, f64)] {
        &self.levels
    }

    /// Every sample answered, in order.
    pub fn samples(&self) -> &[PlateSample] {
        &self.samples
    }

    /// Where and when the plate hit an end stop, if it did.
    pub fn end_stop(&self) -> Option<EndStop> {
        self.stepper.end_stop()
    }

    /// Largest `|x|` so far.
    pub fn peak_excursion_m(&self) -> f64 {
        self.stepper.peak_excursion_m()
    }

    /// A plate the solver could not continue (it then stands still), if any.
    pub fn error(&self) -> Option<&SimError> {
        self.error.as_ref()
    }
}

impl Plant for PlatePlant {
    fn level(&mut self, tick: u64, code: i32) {
        self.advance(tick);
        let accel_mps2 = self.dac.accel_mps2(code);
        self.held = Some((tick, accel_mps2));
        self.levels.push((tick, accel_mps2));
    }

    fn sample(&mut self, tick: u64) -> i32 {
        self.advance(tick);
        let position_m = self.stepper.plate_position_m();
        let count = self.count();
        self.samples.push(PlateSample {
            tick,
            time_s: self.stepper.time_s(),
            position_m,
            count,
            position_integral_ms: self.stepper.position_integral_ms(),
            part_m: self.stepper.part_position_m(),
        });
        if self.pending.last().is_none_or(|&(last, _)| last < tick) {
            self.pending.push((tick, count));
        }
        count
    }

    fn configure(&mut self, interval_ticks: u64, resolution_nm: i32) -> Result<(), String> {
        let resolution_m = f64::from(resolution_nm) * 1e-9;
        if interval_ticks == 0 {
            return Err("the firmware samples its encoder every 0 ticks".into());
        }
        if (resolution_m / self.encoder.resolution_m - 1.0).abs() > 1e-9 {
            return Err(format!(
                "the firmware reads {resolution_nm} nm per encoder count, the plant file's \
                 encoder counts {} m",
                self.encoder.resolution_m
            ));
        }
        self.interval_ticks = Some(interval_ticks);
        Ok(())
    }

    fn stream(&mut self, tick: u64) -> Vec<(u64, i32)> {
        let taken = self.pending.partition_point(|&(at, _)| at <= tick);
        self.pending.drain(..taken).collect()
    }
}

/// What the firmware's log says of its closed loop (its `closed loop:`, `drive identified:` and
/// `plant: cycle` lines).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LoopLog {
    /// The identified gains `+`, `−` and offset.
    pub identified: Option<[f64; 3]>,
    /// The cycle at which the course released the soft start.
    pub feeding_cycle: Option<u64>,
    /// The output tick of each cycle start the firmware logged, by cycle.
    pub cycle_ticks: Vec<(u64, u64)>,
    /// The course stopped: its message.
    pub stopped: Option<String>,
}

impl LoopLog {
    /// Reads a decoded firmware log.
    pub fn read(log: &str) -> Self {
        let mut found = LoopLog::default();
        for line in log.lines() {
            if let Some(rest) = line.split("closed loop: Feeding at cycle ").nth(1) {
                found.feeding_cycle = rest.trim().parse().ok();
            } else if let Some(rest) = line.split("closed loop stopped: ").nth(1) {
                found.stopped = Some(rest.trim().to_string());
            } else if let Some(rest) = line.split("drive identified: ").nth(1) {
                let number = |key: &str| {
                    rest.split(key)
                        .nth(1)
                        .and_then(|v| v.split([',', ' ']).find(|w| !w.is_empty()))
                        .and_then(|v| v.parse::<f64>().ok())
                };
                if let (Some(p), Some(n), Some(e)) =
                    (number("gain + "), number("gain − "), number("offset "))
                {
                    found.identified = Some([p, n, e]);
                }
            } else if let Some(rest) = line.split("plant: cycle ").nth(1) {
                let mut words = rest.split_whitespace();
                let cycle = words.next().and_then(|w| w.parse().ok());
                let tick = words
                    .next()
                    .and_then(|w| w.strip_prefix("tick="))
                    .and_then(|w| w.parse().ok());
                if let (Some(cycle), Some(tick)) = (cycle, tick) {
                    found.cycle_ticks.push((cycle, tick));
                }
            }
        }
        found
    }
}

/// One cycle the plate ran, from two captures.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CosimCycle {
    pub start_tick: u64,
    pub time_s: f64,
    pub start_m: f64,
    pub mean_position_m: f64,
    pub part_velocity_mps: f64,
    /// The highest, the second and the lowest level the output applied in the cycle: the
    /// `+a`, zero and `−a` levels as the loop trimmed them (all one for an idle period).
    pub positive_mps2: f64,
    pub zero_mps2: f64,
    pub negative_mps2: f64,
}

/// The cycles between consecutive captures, with the levels applied in each (`levels` as
/// [`PlatePlant::levels`] gives them).
pub fn cycles(samples: &[PlateSample], levels: &[(u64, f64)]) -> Vec<CosimCycle> {
    samples
        .windows(2)
        .map(|pair| {
            let (a, b) = (pair[0], pair[1]);
            let span_s = b.time_s - a.time_s;
            let from = levels.partition_point(|&(tick, _)| tick < a.tick);
            let to = levels.partition_point(|&(tick, _)| tick < b.tick);
            let applied: Vec<f64> = levels[from..to].iter().map(|&(_, accel)| accel).collect();
            let first = applied.first().copied().unwrap_or(0.0);
            CosimCycle {
                start_tick: a.tick,
                time_s: a.time_s,
                start_m: a.position_m,
                mean_position_m: (b.position_integral_ms - a.position_integral_ms) / span_s,
                part_velocity_mps: (b.part_m - a.part_m) / span_s,
                positive_mps2: applied.iter().copied().fold(first, f64::max),
                zero_mps2: applied.get(1).copied().unwrap_or(first),
                negative_mps2: applied.iter().copied().fold(first, f64::min),
            }
        })
        .collect()
}

/// The closed loop of a co-simulated run, held to the figures above.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LoopVerdict {
    /// Worst `|mean position|` of a cycle from the release to the stop request.
    pub worst_mean_position_m: Option<f64>,
    /// After the soft start (`ramp_cycles` cycles after the release).
    pub settled_mean_position_m: Option<f64>,
    pub feed_rate_mps: Option<f64>,
    pub ideal_feed_rate_mps: f64,
    /// The identified gains' relative errors `+`, `−`.
    pub gain_errors: Option<[f64; 2]>,
    /// Empty when the closed loop passed; else each figure it missed.
    pub failures: Vec<String>,
}

impl LoopVerdict {
    /// Judges the run: `stop_tick` is the scheduler tick of the stop request (the end of the
    /// run if none), `ideal_feed_rate_mps` the ideal plate's at the plan in force then.
    pub fn judge(
        log: &LoopLog,
        cycles: &[CosimCycle],
        plant: &PlantFile,
        end_stop: Option<EndStop>,
        stop_tick: Option<u64>,
        ramp_cycles: u64,
        ideal_feed_rate_mps: f64,
    ) -> Self {
        let mut failures = Vec::new();
        if let Some(stopped) = &log.stopped {
            failures.push(format!("the firmware's closed loop stopped: {stopped}"));
        }
        if let Some(stop) = end_stop {
            failures.push(format!(
                "end stop at {:+.1} mm after {:.4} s",
                stop.position_m * 1e3,
                stop.time_s
            ));
        }
        let gain_errors = log.identified.map(|[p, n, _]| {
            [
                p / plant.plate.gain_positive - 1.0,
                n / plant.plate.gain_negative - 1.0,
            ]
        });
        match gain_errors {
            Some(errors) if errors.iter().any(|e| e.abs() > GAIN_TOLERANCE) => {
                failures.push(format!(
                    "identified gains off by {:+.2} % / {:+.2} %: over {} %",
                    errors[0] * 100.0,
                    errors[1] * 100.0,
                    GAIN_TOLERANCE * 100.0
                ))
            }
            Some(_) => {}
            None => failures.push("the drive was not identified".into()),
        }
        let feeding_tick = log.feeding_cycle.and_then(|cycle| {
            log.cycle_ticks
                .iter()
                .find(|(c, _)| *c == cycle)
                .map(|(_, tick)| *tick)
        });
        let window: Vec<&CosimCycle> = match feeding_tick {
            Some(from) => cycles
                .iter()
                .filter(|c| c.start_tick >= from && stop_tick.is_none_or(|to| c.start_tick < to))
                .collect(),
            None => {
                failures.push("the course never released the soft start".into());
                Vec::new()
            }
        };
        let worst = |cycles: &[&CosimCycle]| {
            cycles
                .iter()
                .map(|c| c.mean_position_m.abs())
                .reduce(f64::max)
        };
        let worst_mean_position_m = worst(&window);
        let settled: Vec<&CosimCycle> = window.iter().skip(ramp_cycles as usize).copied().collect();
        let settled_mean_position_m = worst(&settled);
        if let Some(worst) = worst_mean_position_m.filter(|w| *w > MEAN_POSITION_LIMIT_M) {
            failures.push(format!(
                "worst mean position {:.1} µm: over {:.0} µm",
                worst * 1e6,
                MEAN_POSITION_LIMIT_M * 1e6
            ));
        }
        let last = &window[window.len().saturating_sub(FEED_RATE_CYCLES)..];
        let feed_rate_mps = (last.len() == FEED_RATE_CYCLES).then(|| {
            let span_s: f64 = last
                .windows(2)
                .map(|w| w[1].time_s - w[0].time_s)
                .sum::<f64>();
            let moved_m: f64 = last
                .windows(2)
                .map(|w| w[0].part_velocity_mps * (w[1].time_s - w[0].time_s))
                .sum();
            moved_m / span_s
        });
        match feed_rate_mps {
            Some(rate) if (rate / ideal_feed_rate_mps - 1.0).abs() > FEED_RATE_TOLERANCE => {
                failures.push(format!(
                    "feed rate {:.2} mm/s, {:+.2} % from the ideal plate's: over {} %",
                    rate * 1e3,
                    (rate / ideal_feed_rate_mps - 1.0) * 100.0,
                    FEED_RATE_TOLERANCE * 100.0
                ))
            }
            Some(_) => {}
            None if feeding_tick.is_some() => failures.push(format!(
                "fewer than {FEED_RATE_CYCLES} cycles fed before the stop"
            )),
            None => {}
        }
        LoopVerdict {
            worst_mean_position_m,
            settled_mean_position_m,
            feed_rate_mps,
            ideal_feed_rate_mps,
            gain_errors,
            failures,
        }
    }

    /// The verdict line: `closed loop: PASSED` or `closed loop: FAILED (…)`.
    pub fn line(&self) -> String {
        if self.failures.is_empty() {
            "closed loop: PASSED".into()
        } else {
            format!("closed loop: FAILED ({})", self.failures.join("; "))
        }
    }
}

/// The closed loop of a co-simulated run judged from the firmware's decoded `log` and the
/// `plate` it drove: the window from the release of the soft start to the stop request (the
/// log's `EVT stop`), and the ideal plate's feed rate, for `contact`, at the plan in force then
/// (its last `EVT plan` before the stop).
pub fn judge(
    log: &str,
    plate: &PlatePlant,
    plant: &PlantFile,
    contact: &Contact,
) -> Result<(LoopLog, LoopVerdict), SimError> {
    let events: Vec<Event> = log
        .lines()
        .filter_map(|line| parse_line(line).ok().flatten())
        .collect();
    let stop_tick = events.iter().find_map(|event| match event {
        Event::Stop { tick } => Some(*tick),
        _ => None,
    });
    let plan = events.iter().rev().find_map(|event| match event {
        Event::Plan {
            tick,
            spec,
            clock_hz,
            ramp_cycles,
        } if stop_tick.is_none_or(|stop| *tick <= stop) => Some((*spec, *clock_hz, *ramp_cycles)),
        _ => None,
    });
    let (spec, clock_hz, ramp_cycles) = plan.ok_or(SimError::Request(
        "the firmware's log has no plan (EVT plan): is it the closed-loop image's?".into(),
    ))?;
    let ideal = OperatingPoint::new(spec, *contact, Some(clock_hz))?;
    let loop_log = LoopLog::read(log);
    let verdict = LoopVerdict::judge(
        &loop_log,
        &cycles(plate.samples(), plate.levels()),
        plant,
        plate.end_stop(),
        stop_tick,
        u64::from(ramp_cycles),
        ideal.steady().feed_rate_mps,
    );
    Ok((loop_log, verdict))
}

/// The lines of a decoded firmware log that a golden file keeps: all but the per-segment
/// `EVT seg` lines, so that a closed-loop run of several hundred cycles stays readable.
pub fn golden_lines(log: &str) -> String {
    log.lines()
        .filter(|line| !line.starts_with("EVT seg "))
        .flat_map(|line| [line, "\n"])
        .collect()
}
