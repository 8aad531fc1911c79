//! The real plate as the plant of the firmware's lockstep link (the QEMU `cosim` image): every
//! level the firmware's output applies drives the plate from its tick on, and every sample
//! request is answered with the plate encoder's count at its tick. QEMU runs no instruction
//! while the plate computes, so the co-simulation is deterministic.

use feeder_emulator::plant_link::Plant;
use feeder_shared::DacCalibration;

use crate::closed_loop::{JudgedCycle, RunFacts, Verdict, FEED_RATE_CYCLES};
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
        let plate_tick = tick + self.epoch_ticks;
        self.advance(plate_tick);
        let position_m = self.stepper.plate_position_m();
        let count = self.count();
        self.samples.push(PlateSample {
            tick: plate_tick,
            time_s: self.stepper.time_s(),
            position_m,
            count,
            position_integral_ms: self.stepper.position_integral_ms(),
            part_m: self.stepper.part_position_m(),
            peak_excursion_m: self.stepper.peak_excursion_m(),
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
                .map(|(_, tick)| *tick)
        });
        let fed: Vec<JudgedCycle> = match feeding_tick {
            Some(from) => self
                .cycles
                .windows(2)
                .filter(|w| {
                    w[0].start_tick >= from && self.stop_tick.is_none_or(|to| w[0].start_tick < to)
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
/// `plate` it drove: the window from the release of the soft start to the stop request (the
/// log's `EVT stop`), and the ideal plate's feed rate, for `contact`, at the plan in force then
/// (its last `EVT plan` before the stop).
pub fn judge(
    log: &str,
    plate: &PlatePlant,
    plant: &PlantFile,
    contact: &Contact,
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
    let cycles = cycles(plate.samples(), plate.levels());
    let verdict = CosimRun {
        log: &loop_log,
        samples: plate.samples(),
        cycles: &cycles,
        plant,
        end_stop: plate.end_stop(),
        peak_excursion_m: plate.peak_excursion_m(),
        stop_tick,
        ramp_cycles: u64::from(ramp_cycles),
        ideal_feed_rate_mps: ideal.steady().feed_rate_mps,
        velocity_scale_mps: ideal.velocity_scale_mps(),
    }
    .judge();
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
}
