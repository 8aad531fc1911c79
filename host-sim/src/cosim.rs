//! The real plate as the plant of the firmware's lockstep link (the QEMU `cosim` image): every
//! level the firmware's output applies drives the plate from its tick on, and every sample
//! request is answered with the plate encoder's count at its tick. QEMU runs no instruction
//! while the plate computes, so the co-simulation is deterministic.

use feeder_emulator::plant_link::Plant;
use feeder_shared::DacCalibration;

use crate::closed_loop::{
    feed_compensation_line, JudgedCycle, RunFacts, Verdict, FEED_RATE_CYCLES,
};
use crate::contact::Contact;
use crate::error::SimError;
use crate::hil::{parse_line, Event};
use crate::operating_point::OperatingPoint;
use crate::plate::{EndStop, PlantFile, Stepper};
use crate::segments::PlateSegment;
use crate::sensors::EncoderConfig;

/// The plate at a sample request: a cycle start of the firmware's output.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PlateSample {
    /// The output's tick, counted on through a restart of the board.
    pub tick: u64,
    pub time_s: f64,
    pub position_m: f64,
    /// The count answered.
    pub count: i32,
    /// `∫x dt` since the start, for mean positions between samples.
    pub position_integral_ms: f64,
    /// The part's displacement.
    pub part_m: f64,
    /// Largest `|x|` since power-up.
    pub peak_excursion_m: f64,
}

/// The plate at one instant.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PlateState {
    pub time_s: f64,
    pub position_m: f64,
    pub velocity_mps: f64,
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
    /// The plate's tick at which the firmware's ticks began: 0, and after a restart of the
    /// board (which configures its encoder again and counts its ticks from 0 again) the plate's
    /// tick then. The plate's time goes on; the link's ticks are the firmware's.
    epoch_ticks: u64,
    /// Samples the firmware has not taken yet: `(tick, count)`.
    pending: Vec<(u64, i32)>,
    /// Every level the output applied: `(tick, acceleration)`.
    levels: Vec<(u64, f64)>,
    samples: Vec<PlateSample>,
    error: Option<SimError>,
    /// The driver's enable as the firmware last set it.
    drive_enabled: bool,
}

/// How the plate ends once the firmware has: where it comes to rest, or the end stop it reaches,
/// or how it still moves after the time allowed.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RunOut {
    /// The driver's enable as the firmware left it.
    pub driver_enabled: bool,
    /// Time from the firmware's end.
    pub after_s: f64,
    pub state: PlateState,
    pub outcome: RunOutcome,
}

/// Where a [`RunOut`] ended.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RunOutcome {
    AtRest,
    EndStop,
    StillMoving,
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
        // The driver comes up disabled; the firmware's enable messages switch it.
        let mut stepper = Stepper::new(&plant.plate, contact)?;
        stepper.set_drive_enabled(false);
        Ok(PlatePlant {
            stepper,
            dac,
            encoder,
            clock_hz,
            held: None,
            interval_ticks: None,
            epoch_ticks: 0,
            pending: Vec::new(),
            levels: Vec::new(),
            samples: Vec::new(),
            error: None,
            drive_enabled: false,
        })
    }

    /// Runs the plate on from the firmware's last tick, its drive as the firmware left it, until
    /// it rests (slower than 1 µm/s over a whole millisecond), reaches an end stop or `limit_s`
    /// has passed.
    pub fn run_out(&mut self, limit_s: f64) -> RunOut {
        let step_ticks = (u64::from(self.clock_hz) / 1000).max(1);
        let from_tick = self.held.map_or(0, |(tick, _)| tick);
        let limit_ticks = (limit_s * f64::from(self.clock_hz)) as u64;
        let mut tick = from_tick;
        let outcome = loop {
            if self.stepper.end_stop().is_some() {
                break RunOutcome::EndStop;
            }
            if self.stepper.plate_velocity_mps().abs() < 1e-6 && tick > from_tick {
                break RunOutcome::AtRest;
            }
            if tick - from_tick >= limit_ticks || self.error.is_some() {
                break RunOutcome::StillMoving;
            }
            tick += step_ticks;
            self.advance(tick);
        };
        RunOut {
            driver_enabled: self.drive_enabled,
            after_s: (tick - from_tick) as f64 / f64::from(self.clock_hz),
            state: self.last_state(),
            outcome,
        }
    }

    /// Runs the held level up to the plate's `tick`, sampling the encoder at every multiple of
    /// the firmware's interval (on the firmware's ticks) on the way.
    fn advance(&mut self, tick: u64) {
        let Some((from, accel_mps2)) = self.held else {
            return;
        };
        let epoch = self.epoch_ticks;
        let mut at = from;
        while at < tick && self.error.is_none() {
            let next_sample = self.interval_ticks.map_or(u64::MAX, |interval| {
                (at.saturating_sub(epoch) / interval + 1) * interval + epoch
            });
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
                self.pending.push((to - epoch, count));
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

    /// Every capture ([`PlatePlant::capture`]; over the link, every sample answered), in
    /// order.
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

    /// Where the plate is and how fast it moves at the last tick the firmware reached.
    pub fn last_state(&self) -> PlateState {
        PlateState {
            time_s: self.stepper.time_s(),
            position_m: self.stepper.plate_position_m(),
            velocity_mps: self.stepper.plate_velocity_mps(),
        }
    }

    /// A plate the solver could not continue (it then stands still), if any.
    pub fn error(&self) -> Option<&SimError> {
        self.error.as_ref()
    }

    /// The encoder's count at `tick` (the firmware's, counted on through a restart), the plate
    /// run there and kept as a [`PlateSample`]: a capture of the count.
    pub fn capture(&mut self, tick: u64) -> i32 {
        let plate_tick = tick + self.epoch_ticks;
        self.advance(plate_tick);
        let count = self.count();
        self.samples.push(PlateSample {
            tick: plate_tick,
            time_s: self.stepper.time_s(),
            position_m: self.stepper.plate_position_m(),
            count,
            position_integral_ms: self.stepper.position_integral_ms(),
            part_m: self.stepper.part_position_m(),
            peak_excursion_m: self.stepper.peak_excursion_m(),
        });
        count
    }
}

impl Plant for PlatePlant {
    fn level(&mut self, tick: u64, code: i32) {
        let plate_tick = tick + self.epoch_ticks;
        self.advance(plate_tick);
        let accel_mps2 = self.dac.accel_mps2(code);
        self.held = Some((plate_tick, accel_mps2));
        self.levels.push((plate_tick, accel_mps2));
    }

    fn enable(&mut self, tick: u64, on: bool) {
        self.advance(tick + self.epoch_ticks);
        self.stepper.set_drive_enabled(on);
        self.drive_enabled = on;
    }

    fn sample(&mut self, tick: u64) -> i32 {
        let count = self.capture(tick);
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
        if self.interval_ticks.is_some() {
            // The board restarted: its ticks begin again where the plate is now.
            self.epoch_ticks = self.held.map_or(self.epoch_ticks, |(tick, _)| tick);
            self.pending.clear();
        }
        self.interval_ticks = Some(interval_ticks);
        Ok(())
    }

    fn stream(&mut self, tick: u64) -> Vec<(u64, i32)> {
        let taken = self.pending.partition_point(|&(at, _)| at <= tick);
        self.pending.drain(..taken).collect()
    }
}

/// What the firmware's log says of its closed loop (its `closed loop:` and `drive identified:`
/// lines, and the `EVT seg` events that begin each cycle).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LoopLog {
    /// The identified gains `+`, `−` and offset.
    pub identified: Option<[f64; 3]>,
    /// The cycle at which the course released the soft start.
    pub feeding_cycle: Option<u64>,
    /// The output tick of each cycle start (an idle period's and a settle segment's included)
    /// the firmware logged, by cycle.
    pub cycle_ticks: Vec<(u64, u64)>,
    /// The course stopped: its message.
    pub stopped: Option<String>,
    /// The feed's compensation the firmware found last: the amplitude, the ideal plate's feed
    /// and, where the drive's range limits it, the feed it gives instead (m/s).
    pub feed: Option<LoggedFeed>,
}

/// A feed compensation as the firmware logs it (`feed compensated: levels x…`).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LoggedFeed {
    pub amplitude: f64,
    pub ideal_mps: f64,
    pub limited_mps: Option<f64>,
}

impl LoggedFeed {
    /// The numbers of a `feed compensated:` line's `rest`.
    fn read(rest: &str) -> Option<Self> {
        let numbers: Vec<f64> = rest
            .split([' ', ',', 'x'])
            .filter_map(|word| word.parse().ok())
            .collect();
        match (rest.contains("instead of"), numbers.as_slice()) {
            (false, [amplitude, ideal_mmps]) => Some(LoggedFeed {
                amplitude: *amplitude,
                ideal_mps: ideal_mmps * 1e-3,
                limited_mps: None,
            }),
            (true, [amplitude, feed_mmps, ideal_mmps]) => Some(LoggedFeed {
                amplitude: *amplitude,
                ideal_mps: ideal_mmps * 1e-3,
                limited_mps: Some(feed_mmps * 1e-3),
            }),
            _ => None,
        }
    }
}

impl LoopLog {
    /// Reads a decoded firmware log.
    pub fn read(log: &str) -> Self {
        let mut found = LoopLog::default();
        for line in log.lines() {
            if let Some(rest) = line.split("closed loop: Feeding at cycle ").nth(1) {
                found.feeding_cycle = rest.trim().parse().ok();
            } else if let Some(rest) = line.split("feed compensated: ").nth(1) {
                found.feed = LoggedFeed::read(rest).or(found.feed);
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
            } else if let Ok(Some(Event::Segment(segment))) = parse_line(line) {
                let new = found
                    .cycle_ticks
                    .last()
                    .is_none_or(|&(cycle, _)| cycle != segment.cycle);
                if new {
                    found.cycle_ticks.push((segment.cycle, segment.actual_tick));
                }
            }
        }
        found
    }
}

/// Where the output's ticks (the log's) fall on the plate's: the plate's tick of the output's
/// tick 0 and the plate's ticks per output tick. Over QEMU's link the plate counts the output's
/// own ticks ([`Timeline::SAME`]); the G474 twin's plate counts the core's cycles from power-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timeline {
    pub origin: u64,
    pub plate_ticks_per_tick: u64,
}

impl Timeline {
    /// The plate counts the output's ticks.
    pub const SAME: Timeline = Timeline {
        origin: 0,
        plate_ticks_per_tick: 1,
    };

    /// The plate's tick of the output's `tick`.
    pub fn plate_tick(&self, tick: u64) -> u64 {
        self.origin + tick * self.plate_ticks_per_tick
    }
}

/// The captures that begin each of the log's cycles: for each cycle start, the first capture
/// at or after it and before the next (a board that captures at every segment start, or more
/// often, has one there; QEMU's link captures at cycle starts alone).
pub fn cycle_starts(
    captures: &[PlateSample],
    log: &LoopLog,
    timeline: Timeline,
) -> Vec<PlateSample> {
    let starts: Vec<u64> = log
        .cycle_ticks
        .iter()
        .map(|&(_, tick)| timeline.plate_tick(tick))
        .collect();
    starts
        .iter()
        .enumerate()
        .filter_map(|(index, &start)| {
            let at = captures.partition_point(|capture| capture.tick < start);
            let capture = captures.get(at)?;
            let next = starts.get(index + 1).copied().unwrap_or(u64::MAX);
            (capture.tick < next).then_some(*capture)
        })
        .collect()
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

/// The closed loop of a co-simulated run held to the shared verdict ([`Verdict`]): `stop_tick`
/// is the scheduler tick of the stop request (the end of the run if none),
/// `ideal_feed_rate_mps` and `velocity_scale_mps` the ideal plate's feed rate and `a_max·T/4` at
/// the plan in force then, `peak_excursion_m` the plate's over the whole run.
pub struct CosimRun<'a> {
    pub log: &'a LoopLog,
    pub samples: &'a [PlateSample],
    pub cycles: &'a [CosimCycle],
    pub plant: &'a PlantFile,
    pub end_stop: Option<EndStop>,
    pub peak_excursion_m: f64,
    pub stop_tick: Option<u64>,
    /// Where the log's ticks (`stop_tick`, the log's cycle starts) fall on the plate's.
    pub timeline: Timeline,
    pub ramp_cycles: u64,
    pub ideal_feed_rate_mps: f64,
    pub velocity_scale_mps: f64,
}

impl CosimRun<'_> {
    /// The verdict on the run.
    pub fn judge(&self) -> Verdict {
        let feeding_tick = self.log.feeding_cycle.and_then(|cycle| {
            self.log
                .cycle_ticks
                .iter()
                .find(|(c, _)| *c == cycle)
                .map(|(_, tick)| self.timeline.plate_tick(*tick))
        });
        let stop_tick = self.stop_tick.map(|tick| self.timeline.plate_tick(tick));
        let fed: Vec<JudgedCycle> = match feeding_tick {
            Some(from) => self
                .cycles
                .windows(2)
                .filter(|w| {
                    w[0].start_tick >= from && stop_tick.is_none_or(|to| w[0].start_tick < to)
                })
                .map(|w| {
                    let duration_s = w[1].time_s - w[0].time_s;
                    JudgedCycle {
                        time_s: w[0].time_s,
                        duration_s,
                        mean_position_m: w[0].mean_position_m,
                        part_moved_m: w[0].part_velocity_mps * duration_s,
                    }
                })
                .collect(),
            None => Vec::new(),
        };
        let startup_peak_m = match feeding_tick {
            Some(from) => self
                .samples
                .iter()
                .take_while(|s| s.tick <= from)
                .map(|s| s.peak_excursion_m)
                .fold(0.0, f64::max),
            None => self.peak_excursion_m,
        };
        let plate = &self.plant.plate;
        Verdict::judge(&RunFacts {
            fed: &fed,
            released: feeding_tick.is_some(),
            ramp_cycles: self.ramp_cycles,
            feed_cycles: FEED_RATE_CYCLES,
            startup_peak_m,
            peak_excursion_m: self.peak_excursion_m,
            end_stop_m: plate.end_stop_m,
            end_stop: self.end_stop,
            gave_up: self.log.stopped.as_deref(),
            identified_gains: self.log.identified.map(|[p, n, _]| [p, n]),
            plant_gains: [plate.gain_positive, plate.gain_negative],
            ideal_feed_rate_mps: self.ideal_feed_rate_mps,
            velocity_scale_mps: self.velocity_scale_mps,
        })
    }
}

/// The closed loop of a co-simulated run judged from the firmware's decoded `log` and the
/// `plate` it drove, whose ticks fall on the log's as `timeline` says: the window from the
/// release of the soft start to the stop request (the log's `EVT stop`), and the ideal plate's
/// feed rate, for `contact`, at the plan in force then (its last `EVT plan` before the stop).
pub fn judge(
    log: &str,
    plate: &PlatePlant,
    plant: &PlantFile,
    contact: &Contact,
    timeline: Timeline,
) -> Result<(LoopLog, Verdict), SimError> {
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
    let samples = cycle_starts(plate.samples(), &loop_log, timeline);
    let cycles = cycles(&samples, plate.levels());
    let verdict = CosimRun {
        log: &loop_log,
        samples: &samples,
        cycles: &cycles,
        plant,
        end_stop: plate.end_stop(),
        peak_excursion_m: plate.peak_excursion_m(),
        stop_tick,
        timeline,
        ramp_cycles: u64::from(ramp_cycles),
        ideal_feed_rate_mps: ideal.steady().feed_rate_mps,
        velocity_scale_mps: ideal.velocity_scale_mps(),
    }
    .judge();
    Ok((loop_log, verdict))
}

/// The closed loop's report below the run's, a line each (`host-sim cosim`'s and the G474
/// twin's): the drive identified, the feed's compensation, the release, the start-up's peak, the
/// mean positions and the feed rate.
pub fn closed_loop_lines(log: &LoopLog, verdict: &Verdict) -> Vec<String> {
    let mut lines = Vec::new();
    if let (Some([p, n, e]), Some([ep, en])) = (log.identified, verdict.gain_errors) {
        lines.push(format!(
            "drive             identified gains {p:.5} / {n:.5} ({:+.3} % / {:+.3} %), offset {e:.3} m/s²",
            ep * 100.0,
            en * 100.0
        ));
    }
    if let Some(feed) = log.feed {
        lines.push(feed_compensation_line(
            feed.amplitude,
            feed.ideal_mps,
            feed.limited_mps,
        ));
    }
    if let Some(cycle) = log.feeding_cycle {
        lines.push(format!(
            "course            soft start released at cycle {cycle}"
        ));
    }
    lines.push(format!(
        "start-up          peak |x| {:.1} µm from power-up to the release (bound {:.0} µm)",
        verdict.startup_peak_m * 1e6,
        verdict.startup_limit_m * 1e6
    ));
    if let Some(worst) = verdict.worst_mean_position_m {
        lines.push(format!(
            "mean position     worst |cycle mean| {:.1} µm from the release to the stop, {:.1} µm after the soft start",
            worst * 1e6,
            verdict.settled_mean_position_m.unwrap_or(0.0) * 1e6
        ));
    }
    if let Some(rate) = verdict.feed_rate_mps {
        lines.push(format!(
            "feed rate         {:.2} mm/s over the last {} cycles before the stop, ideal plate {:.2} mm/s ({:+.2} %)",
            rate * 1e3,
            verdict.feed_cycles,
            verdict.ideal_feed_rate_mps * 1e3,
            (rate / verdict.ideal_feed_rate_mps - 1.0) * 100.0
        ));
    }
    lines
}

/// The lines of a decoded firmware log that a golden file keeps: all but the per-segment
/// `EVT seg` lines, so that a closed-loop run of several hundred cycles stays readable. The edge
/// work's total is a measurement, not a result: an interrupt that lands inside an edge's work
/// (the plant link's, when the host's socket delivers it) counts there, and a fresh clone's run
/// read 8,955,330 cycles where others read 8,955,349; it is kept as `total_cycles=[measured]`
/// (the worst edge is held to its budget by its own test).
pub fn golden_lines(log: &str) -> String {
    log.lines()
        .filter(|line| !line.starts_with("EVT seg "))
        .map(|line| match line.split_once(" total_cycles=") {
            Some((head, tail)) if line.starts_with("EVT work ") => {
                let rest = tail.split_once(' ').map_or("", |(_, rest)| rest);
                let rest = if rest.is_empty() {
                    String::new()
                } else {
                    format!(" {rest}")
                };
                format!("{head} total_cycles=[measured]{rest}\n")
            }
            _ => format!("{line}\n"),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plate() -> PlatePlant {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/plants/realistic.toml");
        let plant = PlantFile::from_path(std::path::Path::new(file)).expect("the plant file");
        let part = Contact::paper_part(0.3, 9.80665).expect("the part");
        PlatePlant::new(&plant, &part, DacCalibration::DEFAULT, 1_000_000).expect("the plate")
    }

    #[test]
    fn a_golden_log_keeps_every_line_but_the_segments_and_the_edge_works_measured_total() {
        let log = "INFO  closed loop: Feeding at cycle 522\nEVT seg kind=plateau\n\
                   EVT work edges=3614 max_cycles=6153 total_cycles=8955349 clock_hz=25000000\n";
        assert_eq!(
            golden_lines(log),
            "INFO  closed loop: Feeding at cycle 522\n\
             EVT work edges=3614 max_cycles=6153 total_cycles=[measured] clock_hz=25000000\n"
        );
    }

    #[test]
    fn a_restarted_board_counts_its_ticks_anew_while_the_plate_goes_on() {
        let mut plate = plate();
        plate.configure(250, 1000).unwrap();
        plate.level(0, 2048);
        plate.enable(0, true);
        plate.sample(20_000);
        plate.configure(250, 1000).unwrap();
        plate.level(0, 2048);
        plate.sample(20_000);
        let last = plate.samples().last().copied().unwrap();
        assert_eq!(last.tick, 40_000);
        assert!((last.time_s - 0.04).abs() < 1e-12, "{}", last.time_s);
        let streamed = plate.stream(20_000);
        assert_eq!(
            streamed.len(),
            80,
            "every 250 ticks of the new count, 250 to 20000"
        );
        assert!(streamed
            .iter()
            .all(|&(tick, _)| tick % 250 == 0 && tick <= 20_000));
    }

    /// A log's cycles begin at the first segment of each cycle number: an idle period, a
    /// settle segment (a cycle of its own) and a motion cycle of four segments.
    const LOG: &str = "\
EVT seg cycle=0 kind=idle planned=0 actual=0 ticks=20000 level=0 step=0 steps=25
EVT seg cycle=1 kind=settle planned=20000 actual=20000 ticks=2500 level=0 step=0 steps=25
EVT seg cycle=2 kind=accelerate planned=22500 actual=22500 ticks=5000 level=1 step=1 steps=25
EVT seg cycle=2 kind=plateau planned=27500 actual=27500 ticks=5000 level=0 step=1 steps=25
EVT seg cycle=2 kind=reverse planned=32500 actual=32500 ticks=5000 level=-1 step=1 steps=25
EVT seg cycle=2 kind=return planned=37500 actual=37500 ticks=5000 level=1 step=1 steps=25
EVT seg cycle=3 kind=idle planned=42500 actual=42500 ticks=20000 level=0 step=0 steps=25
";

    #[test]
    fn the_loop_log_takes_each_cycles_start_from_its_first_segment() {
        let read = LoopLog::read(LOG);
        assert_eq!(
            read.cycle_ticks,
            [(0, 0), (1, 20_000), (2, 22_500), (3, 42_500)]
        );
    }

    /// On a board that captures every 250 µs and at every segment start, on a plate that counts
    /// core cycles (170 per output tick, the output's tick 0 at cycle 1000), each cycle begins at
    /// the capture on its start; a cycle with no capture before the next one's start has none.
    #[test]
    fn a_cycle_starts_at_the_first_capture_on_its_start_tick() {
        let mut plate = plate();
        let timeline = Timeline {
            origin: 1000,
            plate_ticks_per_tick: 170,
        };
        for tick in [0, 500, 20_000, 22_500, 27_500, 30_000, 42_501] {
            plate.capture(timeline.plate_tick(tick));
        }
        let starts: Vec<u64> = cycle_starts(plate.samples(), &LoopLog::read(LOG), timeline)
            .iter()
            .map(|capture| capture.tick)
            .collect();
        assert_eq!(
            starts,
            [0, 20_000, 22_500, 42_501].map(|tick| timeline.plate_tick(tick))
        );
        let sparse = &plate.samples()[..2];
        assert_eq!(
            cycle_starts(sparse, &LoopLog::read(LOG), timeline).len(),
            1,
            "only the idle period's start has a capture"
        );
    }
}
