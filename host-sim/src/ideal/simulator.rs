//! Running the part on the ideal plate over a stream of plate segments: per-cycle statistics,
//! steady-state detection, plate excursion and the optional event trace.
//!
//! Two drivers share the same event stepping ([`advance`]):
//! * [`run_table`] repeats one precomputed cycle ([`CycleTable`]); it is the fast path for the
//!   exact waveform times.
//! * [`run_segments`] consumes any iterator of [`PlateSegment`]s: the shared scheduler's tick plan,
//!   or recorded edge times of real hardware.

use serde::Serialize;

use crate::contact::Contact;
use crate::segments::{exact_cycle, PlateSegment};

use super::stick_slip::{advance, EventKind, Observer, Rates, Span};

/// When a run counts as converged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Criteria {
    /// Relative tolerance on the remaining error of the block mean velocity.
    pub rel_tol: f64,
    /// Absolute floor of the tolerance, for feed rates at or near zero.
    pub abs_tol_mps: f64,
    /// Velocity below which the noise allowance stops shrinking with the mean (slow, sticking
    /// parts on a tick plan vary by a share of the waveform's velocity scale, not of their mean).
    pub noise_floor_mps: f64,
    /// Relative block-to-block change accepted as noise rather than transient (two blocks in a
    /// row); 0 for a strictly periodic waveform.
    pub rel_noise: f64,
    /// Cycles averaged per block (1 for a strictly periodic waveform; more when cycle variants
    /// alternate, as in the tick plan).
    pub block_cycles: u32,
    /// Give up (and report `converged = false`) after this many cycles.
    pub max_cycles: u64,
}

impl Criteria {
    /// Convergence of a strictly periodic waveform to `rel_tol` of the feed rate, with the
    /// velocity scale `a_max·T/4` of Eq. 15 as the floor's unit.
    pub fn periodic(rel_tol: f64, velocity_scale_mps: f64) -> Self {
        Criteria {
            rel_tol,
            abs_tol_mps: rel_tol * 1e-3 * velocity_scale_mps,
            rel_noise: 0.0,
            noise_floor_mps: 0.0,
            block_cycles: 1,
            max_cycles: 1_000_000,
        }
    }
}

/// How long to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunOptions {
    pub criteria: Criteria,
    /// Run exactly this many cycles instead of stopping at convergence.
    pub fixed_cycles: Option<u64>,
    /// Keep every cycle's statistics.
    pub record_cycles: bool,
    /// Keep the event trace (plate and part velocity at every event).
    pub trace: bool,
    /// Part velocity relative to the plate at the start (0: the part rests on the plate).
    pub initial_rel_velocity_mps: f64,
}

impl RunOptions {
    pub fn converge(criteria: Criteria) -> Self {
        RunOptions {
            criteria,
            fixed_cycles: None,
            record_cycles: false,
            trace: false,
            initial_rel_velocity_mps: 0.0,
        }
    }
}

/// Statistics of one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CycleStats {
    pub cycle: u64,
    pub duration_s: f64,
    /// Mean part velocity over the cycle.
    pub mean_velocity_mps: f64,
    pub stick_fraction: f64,
}

/// One point of the event trace. Plate and part velocity are linear between consecutive points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TracePoint {
    pub time_s: f64,
    pub plate_velocity_mps: f64,
    pub part_velocity_mps: f64,
    pub event: EventKind,
}

/// The outcome of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// Mean part velocity over the last block (the steady-state feed rate once converged).
    pub feed_rate_mps: f64,
    /// Fraction of the last block's time the part spent stuck to the plate.
    pub stick_fraction: f64,
    /// Cycles simulated.
    pub cycles: u64,
    pub converged: bool,
    /// Peak-to-peak plate travel over the run.
    pub plate_excursion_m: f64,
    /// Part velocity relative to the plate at the end of the run.
    pub final_rel_velocity_mps: f64,
    pub cycle_stats: Vec<CycleStats>,
    pub trace: Vec<TracePoint>,
}

/// One segment of a [`CycleTable`] with its precomputed rates and plate state at its start.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    span: Span,
    accel_mps2: f64,
    start_offset_s: f64,
    start_plate_velocity_mps: f64,
}

/// One waveform cycle prepared for repetition: rates, reciprocals, and the plate's own motion
/// (which does not depend on the part) computed once.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleTable {
    entries: Vec<Entry>,
    period_s: f64,
    inv_period_s: f64,
    /// Plate travel over one cycle (0 up to rounding for a valid waveform).
    plate_displacement_m: f64,
    plate_excursion_m: f64,
}

impl CycleTable {
    /// Prepares one cycle given as segments; the plate starts it at rest.
    pub fn new(segments: &[PlateSegment], contact: &Contact) -> Self {
        let mut entries = Vec::with_capacity(segments.len());
        let mut plate = PlateKinematics::default();
        for segment in segments {
            entries.push(Entry {
                span: Span::new(segment.duration_s, Rates::new(contact, segment.accel_mps2)),
                accel_mps2: segment.accel_mps2,
                start_offset_s: plate.time_s,
                start_plate_velocity_mps: plate.velocity_mps,
            });
            plate.advance(segment.duration_s, segment.accel_mps2);
        }
        let period_s = plate.time_s;
        CycleTable {
            entries,
            period_s,
            inv_period_s: 1.0 / period_s,
            plate_displacement_m: plate.position_m,
            plate_excursion_m: plate.max_m - plate.min_m,
        }
    }

    /// The waveform's exact real-valued segments (`Waveform::segments`, Eq. 1–5).
    pub fn exact(waveform: &feeder_shared::Waveform, contact: &Contact) -> Self {
        Self::new(&exact_cycle(waveform), contact)
    }

    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    pub fn plate_excursion_m(&self) -> f64 {
        self.plate_excursion_m
    }
}

/// Plate position and velocity by exact integration of piecewise-constant acceleration.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct PlateKinematics {
    time_s: f64,
    velocity_mps: f64,
    position_m: f64,
    min_m: f64,
    max_m: f64,
}

impl PlateKinematics {
    fn advance(&mut self, duration_s: f64, accel_mps2: f64) {
        let u0 = self.velocity_mps;
        let u1 = u0 + accel_mps2 * duration_s;
        // The plate turns inside the segment: its position has an extremum where u = 0.
        if u0 * u1 < 0.0 {
            let turn_m = self.position_m - 0.5 * u0 * u0 / accel_mps2;
            self.min_m = self.min_m.min(turn_m);
            self.max_m = self.max_m.max(turn_m);
        }
        self.position_m += 0.5 * (u0 + u1) * duration_s;
        self.velocity_mps = u1;
        self.time_s += duration_s;
        self.min_m = self.min_m.min(self.position_m);
        self.max_m = self.max_m.max(self.position_m);
    }
}

/// Block averaging and steady-state detection.
#[derive(Debug, Clone)]
struct Recorder {
    criteria: Criteria,
    fixed_cycles: Option<u64>,
    record_cycles: bool,
    /// Blocks closing at this cycle count or later are evaluated. A run of fixed length reports
    /// only its last block and the convergence test of the last three, so earlier blocks just
    /// restart the sums.
    evaluate_from_cycle: u64,
    cycles: u64,
    block_displacement_m: f64,
    block_time_s: f64,
    block_stick_s: f64,
    block_len: u32,
    last_mean_mps: Option<f64>,
    last_delta_mps: Option<f64>,
    feed_rate_mps: f64,
    stick_fraction: f64,
    converged: bool,
    cycle_stats: Vec<CycleStats>,
}

impl Recorder {
    fn new(options: &RunOptions) -> Self {
        let evaluate_from_cycle = options.fixed_cycles.map_or(0, |cycles| {
            let block_cycles = u64::from(options.criteria.block_cycles.max(1));
            (cycles / block_cycles).saturating_sub(3) * block_cycles + 1
        });
        Recorder {
            criteria: options.criteria,
            fixed_cycles: options.fixed_cycles,
            record_cycles: options.record_cycles,
            evaluate_from_cycle,
            cycles: 0,
            block_displacement_m: 0.0,
            block_time_s: 0.0,
            block_stick_s: 0.0,
            block_len: 0,
            last_mean_mps: None,
            last_delta_mps: None,
            feed_rate_mps: 0.0,
            stick_fraction: 0.0,
            converged: false,
            cycle_stats: Vec::new(),
        }
    }

    /// Cycles to run at most.
    fn limit(&self) -> u64 {
        self.fixed_cycles.unwrap_or(self.criteria.max_cycles)
    }

    /// Closes a cycle; returns true when the run should stop.
    #[inline(always)]
    fn close_cycle(&mut self, displacement_m: f64, duration_s: f64, stick_s: f64) -> bool {
        if self.record_cycles {
            self.cycle_stats.push(CycleStats {
                cycle: self.cycles,
                duration_s,
                mean_velocity_mps: displacement_m / duration_s,
                stick_fraction: stick_s / duration_s,
            });
        }
        self.cycles += 1;
        self.block_displacement_m += displacement_m;
        self.block_time_s += duration_s;
        self.block_stick_s += stick_s;
        self.block_len += 1;
        if self.block_len >= self.criteria.block_cycles {
            if self.cycles >= self.evaluate_from_cycle {
                self.close_block();
            } else {
                self.restart_block();
            }
        }
        (self.converged && self.fixed_cycles.is_none()) || self.cycles >= self.limit()
    }

    #[inline(always)]
    fn restart_block(&mut self) {
        self.block_displacement_m = 0.0;
        self.block_time_s = 0.0;
        self.block_stick_s = 0.0;
        self.block_len = 0;
    }

    #[inline(never)]
    fn close_block(&mut self) {
        let mean = self.block_displacement_m / self.block_time_s;
        self.feed_rate_mps = mean;
        self.stick_fraction = self.block_stick_s / self.block_time_s;
        self.restart_block();
        let Some(last) = self.last_mean_mps.replace(mean) else {
            return;
        };
        let delta = (mean - last).abs();
        let tol = (self.criteria.rel_tol * mean.abs()).max(self.criteria.abs_tol_mps);
        let noise = self.criteria.rel_noise * mean.abs().max(self.criteria.noise_floor_mps);
        // A geometric approach (ratio ρ) has at most |Δ|·ρ/(1 − ρ) left to go.
        self.converged = delta == 0.0
            || self.last_delta_mps.is_some_and(|previous| {
                let ratio = delta / previous;
                (ratio < 1.0 && delta <= tol * (1.0 - ratio))
                    || (delta <= noise && previous <= noise)
            });
        self.last_delta_mps = Some(delta);
    }
}

/// Collects [`TracePoint`]s with absolute time and velocities for one segment.
struct TraceObserver<'a> {
    points: &'a mut Vec<TracePoint>,
    start_s: f64,
    plate_velocity_mps: f64,
    accel_mps2: f64,
}

impl Observer for TraceObserver<'_> {
    const ACTIVE: bool = true;
    fn event(&mut self, kind: EventKind, offset_s: f64, w_mps: f64) {
        let plate = self.plate_velocity_mps + self.accel_mps2 * offset_s;
        self.points.push(TracePoint {
            time_s: self.start_s + offset_s,
            plate_velocity_mps: plate,
            part_velocity_mps: plate + w_mps,
            event: kind,
        });
    }
}

/// Repeats `table` from the plate at rest and the part at the initial relative velocity.
pub fn run_table(table: &CycleTable, options: &RunOptions) -> RunResult {
    let mut recorder = Recorder::new(options);
    let mut trace = Vec::new();
    let mut w = options.initial_rel_velocity_mps;
    if options.trace {
        run_table_traced(table, &mut recorder, &mut w, &mut trace);
    } else {
        run_table_fast(table, &mut recorder, &mut w);
    }
    finish(recorder, table.plate_excursion_m, w, trace)
}

/// The hot loop: no allocation, no division, no trace.
fn run_table_fast(table: &CycleTable, recorder: &mut Recorder, w: &mut f64) {
    if recorder.limit() == 0 {
        return;
    }
    loop {
        let mut displacement = table.plate_displacement_m;
        let mut stick = 0.0;
        for entry in &table.entries {
            let step = advance(w, &entry.span, &mut ());
            displacement += step.rel_displacement_m;
            stick += step.stick_s;
        }
        if recorder.close_cycle(displacement, table.period_s, stick) {
            return;
        }
    }
}

fn run_table_traced(
    table: &CycleTable,
    recorder: &mut Recorder,
    w: &mut f64,
    trace: &mut Vec<TracePoint>,
) {
    if recorder.limit() == 0 {
        return;
    }
    let mut cycle_start_s = 0.0;
    loop {
        let mut displacement = table.plate_displacement_m;
        let mut stick = 0.0;
        for entry in &table.entries {
            let mut observer = TraceObserver {
                points: trace,
                start_s: cycle_start_s + entry.start_offset_s,
                plate_velocity_mps: entry.start_plate_velocity_mps,
                accel_mps2: entry.accel_mps2,
            };
            observer.event(EventKind::Edge, 0.0, *w);
            let step = advance(w, &entry.span, &mut observer);
            displacement += step.rel_displacement_m;
            stick += step.stick_s;
        }
        cycle_start_s += table.period_s;
        if recorder.close_cycle(displacement, table.period_s, stick) {
            trace.push(TracePoint {
                time_s: cycle_start_s,
                plate_velocity_mps: 0.0,
                part_velocity_mps: *w,
                event: EventKind::Edge,
            });
            return;
        }
    }
}

/// Up to this many distinct plate accelerations keep their [`Rates`] cached.
const RATE_CACHE: usize = 8;

/// Consumes `segments` (which must start a cycle with their first element) from the plate at
/// rest and the part at the initial relative velocity. Stops at convergence, after the fixed cycle count, or when the segments
/// run out.
pub fn run_segments<I>(segments: I, contact: &Contact, options: &RunOptions) -> RunResult
where
    I: IntoIterator<Item = PlateSegment>,
{
    let mut recorder = Recorder::new(options);
    let mut trace = Vec::new();
    let mut plate = PlateKinematics::default();
    let mut cache: Vec<(u64, Rates)> = Vec::with_capacity(RATE_CACHE);
    let mut w = options.initial_rel_velocity_mps;
    let mut cycle_open = false;
    let mut cycle_start_s = 0.0;
    let mut cycle_start_m = 0.0;
    let mut rel_displacement = 0.0;
    let mut stick = 0.0;
    let mut stopped = recorder.limit() == 0;
    for segment in segments {
        if stopped {
            break;
        }
        if segment.starts_cycle && cycle_open {
            let displacement = plate.position_m - cycle_start_m + rel_displacement;
            stopped = recorder.close_cycle(displacement, plate.time_s - cycle_start_s, stick);
            rel_displacement = 0.0;
            stick = 0.0;
            cycle_start_s = plate.time_s;
            cycle_start_m = plate.position_m;
            if stopped {
                break;
            }
        }
        cycle_open = true;
        let span = Span::new(
            segment.duration_s,
            cached_rates(&mut cache, contact, segment.accel_mps2),
        );
        let step = if options.trace {
            let mut observer = TraceObserver {
                points: &mut trace,
                start_s: plate.time_s,
                plate_velocity_mps: plate.velocity_mps,
                accel_mps2: segment.accel_mps2,
            };
            observer.event(EventKind::Edge, 0.0, w);
            advance(&mut w, &span, &mut observer)
        } else {
            advance(&mut w, &span, &mut ())
        };
        rel_displacement += step.rel_displacement_m;
        stick += step.stick_s;
        plate.advance(segment.duration_s, segment.accel_mps2);
    }
    if cycle_open && !stopped && plate.time_s > cycle_start_s {
        let displacement = plate.position_m - cycle_start_m + rel_displacement;
        recorder.close_cycle(displacement, plate.time_s - cycle_start_s, stick);
    }
    if options.trace {
        trace.push(TracePoint {
            time_s: plate.time_s,
            plate_velocity_mps: plate.velocity_mps,
            part_velocity_mps: plate.velocity_mps + w,
            event: EventKind::Edge,
        });
    }
    finish(recorder, plate.max_m - plate.min_m, w, trace)
}

fn cached_rates(cache: &mut Vec<(u64, Rates)>, contact: &Contact, accel_mps2: f64) -> Rates {
    let key = accel_mps2.to_bits();
    if let Some((_, rates)) = cache.iter().find(|(bits, _)| *bits == key) {
        return *rates;
    }
    let rates = Rates::new(contact, accel_mps2);
    if cache.len() == RATE_CACHE {
        cache.clear();
    }
    cache.push((key, rates));
    rates
}

fn finish(recorder: Recorder, plate_excursion_m: f64, w: f64, trace: Vec<TracePoint>) -> RunResult {
    let mut recorder = recorder;
    if recorder.block_len > 0 && recorder.last_mean_mps.is_none() {
        recorder.close_block();
    }
    RunResult {
        feed_rate_mps: recorder.feed_rate_mps,
        stick_fraction: recorder.stick_fraction,
        cycles: recorder.cycles,
        converged: recorder.converged,
        plate_excursion_m,
        final_rel_velocity_mps: w,
        cycle_stats: recorder.cycle_stats,
        trace,
    }
}
