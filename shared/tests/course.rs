//! The closed loop's course driven by the shared scheduler against an ideal plate integrated
//! exactly here (no lag, no friction), read every 250 ticks of a 1 MHz clock and at each cycle
//! start. Decisions are applied as the firmware applies them: at the segment after the boundary
//! that made them, a cycle's trims fixed when its first segment is made.

use feeder_shared::closed_loop::identify::FITS_MAX;
use feeder_shared::closed_loop::{
    CommandSegment, Course, CourseConfig, CourseError, CycleShape, CycleTrims, Decision,
    Identification, Identified, IdentifyError, LateTrims, LoopError, PositionSample, Stage, Trims,
};
use feeder_shared::{
    Drive, Limits, Scheduler, Segment, SegmentKind, TickClock, TickPlan, Waveform, WaveformSpec,
};
use proptest::prelude::*;

const CLOCK_HZ: u32 = 1_000_000;
const SAMPLE_TICKS: u64 = 250;
const RAMP_CYCLES: u16 = 25;

/// The paper's cycle: 50 Hz, duty 0.586, a 2.5 mm stroke.
fn plan() -> TickPlan {
    let spec = WaveformSpec::from_frequency(50.0, 0.586, Drive::Stroke { stroke_m: 2.5e-3 });
    TickPlan::new(
        &Waveform::new(spec, &Limits::NONE).unwrap(),
        TickClock::new(CLOCK_HZ),
    )
    .unwrap()
}

/// The drive as the plate meets it: the gains `g₊`, `g₋` on a positive and a negative command
/// `u`, and the offset `e` (m/s²): `x'' = g±·u + e`.
type Gains = [f64; 3];
const IDEAL: Gains = [1.0, 1.0, 0.0];

/// An ideal plate on a drive, integrated exactly segment by segment.
#[derive(Default)]
struct Plate {
    drive: Gains,
    tick: u64,
    position_m: f64,
    velocity_mps: f64,
    /// Added to every reading (NaN: a sensor that returns garbage).
    sensor_error_m: f64,
    /// The largest `|x|` reached, turning points included.
    max_abs_m: f64,
    /// Readings since the last cycle start.
    samples: Vec<PositionSample>,
}

impl Plate {
    fn reading(&self, tick: u64, position_m: f64) -> PositionSample {
        PositionSample {
            tick,
            position_m: position_m + self.sensor_error_m,
        }
    }

    /// Plays `segment` at its trimmed level (nothing while the driver is off), read at every
    /// multiple of 250 ticks in it (the start tick of a cycle is read as the cycle's start
    /// instead).
    fn play(&mut self, segment: &Segment, trims: &Trims) {
        let command = trims.level(segment.kind.place(), segment.accel_mps2());
        let [plus, minus, offset_mps2] = self.drive;
        let a = if segment.kind.drives() {
            command * if command > 0.0 { plus } else { minus } + offset_mps2
        } else {
            0.0
        };
        let (x0, v0) = (self.position_m, self.velocity_mps);
        let at = |s: f64| x0 + v0 * s + a * s * s / 2.0;
        let end = self.tick + u64::from(segment.ticks);
        let mut tick = self.tick.div_ceil(SAMPLE_TICKS) * SAMPLE_TICKS;
        if segment.starts_cycle() && tick == self.tick {
            tick += SAMPLE_TICKS;
        }
        while tick < end {
            let sample = self.reading(tick, at((tick - self.tick) as f64 / f64::from(CLOCK_HZ)));
            self.samples.push(sample);
            tick += SAMPLE_TICKS;
        }
        let duration_s = f64::from(segment.ticks) / f64::from(CLOCK_HZ);
        let turn_s = -v0 / a;
        if a != 0.0 && turn_s > 0.0 && turn_s < duration_s {
            self.max_abs_m = self.max_abs_m.max(at(turn_s).abs());
        }
        self.position_m = at(duration_s);
        self.velocity_mps = v0 + a * duration_s;
        self.max_abs_m = self.max_abs_m.max(self.position_m.abs());
        self.tick = end;
    }
}

/// The scheduler, the course and the plate, wired as the firmware's control loop wires them:
/// the scheduler held and settling before each start, each cycle's trims taken by
/// [`CycleTrims`].
struct Rig {
    scheduler: Scheduler,
    course: Course,
    plate: Plate,
    cycle_trims: CycleTrims,
    /// The next segment, made but not begun, and the trims of its cycle if it begins one.
    queued: Segment,
    queued_trims: Trims,
    /// The segment begun and not yet played; the trims of its cycle; where that cycle began.
    begun: Option<Segment>,
    trims: Trims,
    start: PositionSample,
    /// The decision of the last boundary, applied at the next segment.
    pending: Option<Decision>,
    /// The identification handed over last.
    handed: Option<Identification>,
}

impl Rig {
    /// A held scheduler and its course on a plate at rest on `drive`; the first segment made
    /// before the start is requested (an idle period) unless `started`.
    fn new(drive: Gains, started: bool) -> Self {
        let plate = Plate {
            drive,
            ..Plate::default()
        };
        let mut scheduler = Scheduler::new(plan(), RAMP_CYCLES);
        let course = Course::new(CourseConfig::new(1e-6, 0.0), scheduler.ramp_cycles());
        scheduler.hold_step(course.probe_step());
        scheduler.settle_before_start(course.config().settle_segments);
        if started {
            scheduler.start();
        }
        let queued = scheduler.next_segment();
        let start = plate.reading(0, 0.0);
        Rig {
            scheduler,
            course,
            plate,
            cycle_trims: CycleTrims::NONE,
            queued,
            queued_trims: Trims::NONE,
            begun: None,
            trims: Trims::NONE,
            start,
            pending: None,
            handed: None,
        }
    }

    /// Plays the segment begun and begins the next: the course's decision if that begins a
    /// cycle, an idle period or a settle segment.
    fn segment(&mut self) -> Option<Result<Decision, CourseError>> {
        if let Some(playing) = self.begun.take() {
            self.queued = self.scheduler.next_segment();
            if self.queued.starts_cycle() {
                let after_idle = playing.kind == SegmentKind::Idle;
                // A cycle without its decision (after a course error) runs the feedforward, as
                // the firmware's does while its fault stops the feeder.
                self.queued_trims = self
                    .cycle_trims
                    .for_cycle(&self.queued, after_idle)
                    .unwrap_or(Some(self.cycle_trims.feedforward()))
                    .unwrap_or(Trims::NONE);
            }
            self.plate.play(&playing, &self.trims);
        }
        let playing = self.queued;
        if let Some(decision) = self.pending.take() {
            if decision.release {
                self.scheduler.release_hold();
            }
            self.cycle_trims.take(&decision, self.course.feedforward());
        }
        self.begun = Some(playing);
        if !playing.starts_cycle() {
            return None;
        }
        self.trims = self.queued_trims;
        self.start = self.plate.reading(self.plate.tick, self.plate.position_m);
        let samples = std::mem::take(&mut self.plate.samples);
        let result = self
            .course
            .boundary(&playing, &self.scheduler, self.start, &samples);
        self.pending = result.ok();
        Some(result)
    }

    /// Plays to the start of the next cycle, idle period or settle segment: the course's
    /// decision there.
    fn boundary(&mut self) -> Result<Decision, CourseError> {
        loop {
            if let Some(result) = self.segment() {
                return result;
            }
        }
    }

    /// A course begun on `drive` as the firmware begins it: one idle period, then started.
    fn started(drive: Gains) -> Self {
        let mut rig = Rig::new(drive, false);
        assert_eq!(rig.boundary().map(|d| d.identify || d.release), Ok(false));
        assert_eq!(rig.course.stage(), Stage::Waiting);
        rig.scheduler.start();
        rig
    }

    /// Plays through the settle and the soft start's rise to the held step, up to the first
    /// held cycle's start (the probe's first).
    fn to_probe(&mut self) -> Decision {
        loop {
            let decision = self.boundary().expect("a course on a plate within reach");
            if self.course.stage() == Stage::Probing {
                return decision;
            }
            assert!(matches!(
                self.course.stage(),
                Stage::Waiting | Stage::Settling
            ));
        }
    }

    /// Identifies the drive from a complete probe and hands it over; `None` without one.
    fn identify(&mut self) -> Option<()> {
        let found = self.course.probe()?.identify();
        self.hand_over(found);
        Some(())
    }

    fn hand_over(&mut self, identification: Identification) {
        self.handed = Some(identification);
        self.course.set_identified(identification);
    }

    /// The planned (untrimmed) mean displacement from rest of the cycle begun.
    fn planned_mean_m(&self) -> f64 {
        let plan = *self.scheduler.plan();
        let mut ahead = self.scheduler.clone();
        let mut segments = vec![CommandSegment::of(&self.begun.unwrap(), &plan)];
        while !ahead.at_boundary() {
            segments.push(CommandSegment::of(&ahead.next_segment(), &plan));
        }
        CycleShape::new(&segments).map_or(0.0, |shape| shape.mean_m)
    }
}

/// A boundary: the stage the decision left (before any identification), whether a probe was
/// offered, the cycle's step, its start against its plan, the largest `|x|` since the last.
#[derive(Debug, Clone, Copy)]
struct Record {
    stage: Stage,
    decision: Decision,
    probe: bool,
    step: u16,
    start_error_m: f64,
    max_abs_m: f64,
}

/// Runs a started course until `after` cycles past the release.
fn run_course(rig: &mut Rig, after: usize) -> Vec<Record> {
    let mut records = Vec::new();
    let mut fed = 0;
    while fed < after {
        assert!(records.len() < 1000, "no release: {:?}", records.last());
        let decision = rig.boundary().expect("a course on an ideal plate");
        let record = Record {
            stage: rig.course.stage(),
            decision,
            probe: rig.course.probe().is_some(),
            step: rig.begun.unwrap().amplitude.step,
            start_error_m: rig.start.position_m + rig.planned_mean_m(),
            max_abs_m: std::mem::take(&mut rig.plate.max_abs_m),
        };
        if decision.identify {
            rig.identify().expect("a probe to identify");
        }
        fed += usize::from(record.stage == Stage::Feeding && !record.decision.release);
        records.push(record);
    }
    records
}

/// The indices of the records that `pick` picks.
fn indices(records: &[Record], pick: impl Fn(&Record) -> bool) -> Vec<usize> {
    (0..records.len()).filter(|&i| pick(&records[i])).collect()
}

fn largest(values: impl Iterator<Item = f64>) -> f64 {
    values.fold(0.0, f64::max)
}

/// On an ideal drive the course goes through every stage once, in order: the settle, the soft
/// start's rise to the held step, the probe on the held cycles, one offer of the probe for
/// identification, held cycles until the hold for it ends, centring on the identified drive,
/// and one release after which the soft start goes on from the held step. The drive found is
/// the ideal one.
#[test]
fn an_ideal_drive_is_settled_probed_identified_centred_and_released() {
    let mut rig = Rig::started(IDEAL);
    let records = run_course(&mut rig, 30);
    let mut stages: Vec<Stage> = records.iter().map(|r| r.stage).collect();
    stages.dedup();
    use Stage::*;
    assert_eq!(stages, [Settling, Probing, Identifying, Centring, Feeding]);
    // The settle's segments at step 0, then one cycle a step up to the held one, which begins
    // the probe; its fifth start completes it.
    let settle = usize::from(rig.course.config().settle_segments);
    let held = rig.course.probe_step();
    let probe = records.iter().position(|r| r.stage == Probing).unwrap();
    assert_eq!(probe, settle + usize::from(held) - 1);
    let steps: Vec<u16> = records[..=probe].iter().map(|r| r.step).collect();
    let rise: Vec<u16> = (1..=held).collect();
    assert_eq!(steps[..settle], vec![0; settle]);
    assert_eq!(steps[settle..], rise);
    assert_eq!(indices(&records, |r| r.decision.identify), [probe + 4]);
    // Handed over at once, the drive is taken at the first boundary the hold its work is given
    // after the probe's (0.25 s and 0.1125 s a fit): the probe is there until then.
    let handed = rig.handed.unwrap();
    assert!((10..=30).contains(&handed.fits), "{handed:?}");
    let hold = hold_cycles(0.25 + f64::from(handed.fits) * 0.1125);
    assert_eq!(hold, hold_cycles(hold_s(&rig, handed.fits)));
    assert_eq!(
        indices(&records, |r| r.probe),
        (probe + 4..probe + 4 + hold).collect::<Vec<_>>()
    );
    let centring = indices(&records, |r| r.stage == Centring);
    assert_eq!(centring.first(), Some(&(probe + 4 + hold)));
    let releases = indices(&records, |r| r.decision.release);
    assert_eq!(releases.len(), 1);
    let release = releases[0];
    assert!(records[probe..=release].iter().all(|r| r.step == held));
    assert_eq!(records[release].stage, Feeding);
    // The held levels are excited to 1.5 times and back (the starts, measured against the
    // unexcited plan's, move by a sixth of a millimetre), and released at the boundary after the
    // excitation ends, the plate centred within 25 µm there and at the release.
    let excited_m = records[centring[0]..release]
        .iter()
        .map(|r| r.start_error_m.abs())
        .fold(0.0, f64::max);
    assert!(excited_m > 100e-6, "{excited_m} m");
    assert!(records[release - 1..=release]
        .iter()
        .all(|r| r.start_error_m.abs() <= 25e-6));
    let steps: Vec<u16> = records[release + 1..].iter().map(|r| r.step).collect();
    assert_eq!(steps[..3], [held + 1, held + 2, held + 3]);
    assert_eq!(steps.last(), Some(&RAMP_CYCLES));
    let found = rig.course.identified().copied().unwrap();
    assert!((found.gain_positive - 1.0).abs() < 1e-6, "{found:?}");
    assert!((found.gain_negative - 1.0).abs() < 1e-6, "{found:?}");
    assert!(found.offset_mps2.abs() < 1e-6, "{found:?}");
}

/// A drive of gains 1.02/0.98 with an offset of 1 m/s²: the course on the plate and the records
/// of its boundaries up to 200 cycles past the soft start.
fn mismatched_course() -> (Rig, Vec<Record>) {
    let mut rig = Rig::started([1.02, 0.98, 1.0]);
    let records = run_course(&mut rig, RAMP_CYCLES as usize + 200);
    (rig, records)
}

/// Such a drive is found to 0.1 % of its gains and 1 mm/s² of its offset; from the
/// identification on the plate stays within 4 mm; and once the soft start is through every
/// cycle starts within 50 µm of where its plan centres its mean (at `−mean`; during the soft
/// start the target leads it by half a cycle's move of the target).
#[test]
fn a_mismatched_drive_is_identified_and_its_cycles_centred() {
    let (rig, records) = mismatched_course();
    let found = rig.course.identified().copied().unwrap();
    assert!((found.gain_positive / 1.02 - 1.0).abs() < 1e-3, "{found:?}");
    assert!((found.gain_negative / 0.98 - 1.0).abs() < 1e-3, "{found:?}");
    assert!((found.offset_mps2 - 1.0).abs() < 1e-3, "{found:?}");
    let identified = records.iter().position(|r| r.decision.identify).unwrap();
    assert!(largest(records[identified + 1..].iter().map(|r| r.max_abs_m)) < 4e-3);
    let release = records.iter().position(|r| r.decision.release).unwrap();
    let steady = &records[release + 1 + usize::from(RAMP_CYCLES)..];
    assert!(steady.len() >= 200 && steady.iter().all(|r| r.step == RAMP_CYCLES));
    let worst = largest(steady.iter().map(|r| r.start_error_m.abs()));
    assert!(worst < 50e-6, "{worst} m");
}

/// A stop during the probe (the soft stop from the held step, then idle periods) sends the
/// course back to waiting with the probe dropped; after a new start the settle and the rise
/// come again, the probe begins again at the first held cycle and keeps 4 whole cycles from
/// that cycle's start, led in by the levels of the cycle before, from which the drive is found.
#[test]
fn a_stop_during_the_probe_begins_the_probe_again_at_the_next_start() {
    let mut rig = Rig::started(IDEAL);
    rig.to_probe();
    rig.boundary().unwrap();
    assert_eq!(rig.course.stage(), Stage::Probing);
    rig.scheduler.stop();
    let mut steps = Vec::new();
    for _ in 0..10 {
        let decision = rig.boundary().unwrap();
        assert_eq!(
            (rig.course.stage(), decision.identify),
            (Stage::Waiting, false)
        );
        assert!(rig.course.probe().is_none());
        steps.push(rig.begun.unwrap().amplitude.step);
    }
    assert_eq!(steps, [7, 6, 5, 4, 3, 2, 1, 0, 0, 0]);
    rig.scheduler.start();
    rig.to_probe();
    let start_tick = rig.start.tick;
    for cycle in 0..4 {
        assert_eq!(rig.begun.unwrap().amplitude.step, rig.course.probe_step());
        assert_eq!(rig.course.stage(), Stage::Probing, "cycle {cycle}");
        rig.boundary().unwrap();
    }
    assert_eq!(rig.course.stage(), Stage::Identifying);
    let probe = rig.course.probe().unwrap();
    let positions = probe.positions();
    // Every 250 ticks over 4 cycles of 20 000, both ends included, timed from the lead-in's
    // start a cycle before.
    assert_eq!((positions.len(), probe.segments().len()), (321, 20));
    assert!((positions[0].t_s - 0.02).abs() < 1e-12);
    assert!((positions[320].t_s - 0.1).abs() < 1e-12);
    assert_eq!(rig.start.tick, start_tick + 80_000);
    let found = probe.identify().result.unwrap();
    let gains = [found.gain_positive, found.gain_negative];
    assert!(gains.iter().all(|g| (g - 1.0).abs() < 1e-6), "{found:?}");
}

/// A failed course trims nothing from then on: every later boundary decides the plan's levels
/// for the next cycle, releases nothing and offers no probe, and the cycles run untrimmed.
fn assert_trims_nothing(rig: &mut Rig) {
    assert_eq!(rig.course.stage(), Stage::Failed);
    for _ in 0..10 {
        let decision = rig.boundary().expect("a failed course decides on");
        // The next cycle made: after a settle segment, one segment long, the one after.
        let begun = rig.begun.unwrap();
        let ahead = if begun.kind == SegmentKind::Settle {
            2
        } else {
            1
        };
        assert_eq!(decision.cycle, begun.cycle + ahead);
        assert_eq!((decision.trims, decision.release), (Trims::NONE, false));
        assert!(!decision.identify && rig.course.probe().is_none());
        assert_eq!(rig.course.stage(), Stage::Failed);
    }
    assert_eq!(rig.trims, Trims::NONE);
}

/// A sensor that returns NaN while feeding stops the course with a sensor error; a plate
/// 10 mm from where it should be during the probe stops it with the distance from the cycle's
/// target, its start at `−mean`.
#[test]
fn a_position_that_is_not_a_number_or_far_away_fails_the_course() {
    let mut rig = Rig::started(IDEAL);
    run_course(&mut rig, 5);
    rig.plate.sensor_error_m = f64::NAN;
    assert_eq!(rig.boundary(), Err(CourseError::Loop(LoopError::Sensor)));
    assert_trims_nothing(&mut rig);

    let mut rig = Rig::started(IDEAL);
    rig.boundary().unwrap();
    rig.boundary().unwrap();
    rig.plate.position_m += 10e-3;
    let Err(CourseError::Loop(LoopError::Position { error_m })) = rig.boundary() else {
        panic!("no position error");
    };
    assert!((error_m - rig.start.position_m - rig.planned_mean_m()).abs() < 1e-12);
    assert!(error_m > 9e-3);
    assert_trims_nothing(&mut rig);
}

/// The cycles of 50 Hz from the probe's end to the first start at or after a hold of
/// `hold_s`.
fn hold_cycles(hold_s: f64) -> usize {
    (hold_s * 50.0).ceil() as usize
}

/// The hold the rig's course gives an identification of `fits` fits.
fn hold_s(rig: &Rig, fits: u32) -> f64 {
    rig.course.config().identify_hold_s(fits)
}

/// The boundaries of an identification's hold of `hold_s` (from the probe's end), each still
/// identifying, up to the error at its end.
fn hold_until_stopped(rig: &mut Rig, hold_s: f64) -> CourseError {
    for _ in 1..hold_cycles(hold_s) {
        rig.boundary().unwrap();
        assert_eq!(rig.course.stage(), Stage::Identifying);
    }
    rig.boundary().unwrap_err()
}

/// An identification of `result` that took `fits` fits.
fn identification(result: Result<Identified, IdentifyError>, fits: u32) -> Identification {
    Identification { result, fits }
}

/// An identification handed over before the probe is complete is ignored; a refused one
/// stops the course with the refusal at the end of the hold.
#[test]
fn a_refused_identification_fails_the_course() {
    let mut rig = Rig::started(IDEAL);
    rig.hand_over(identification(Err(IdentifyError::Singular), 30));
    assert_eq!(rig.course.stage(), Stage::Waiting);
    rig.to_probe();
    while !rig.boundary().unwrap().identify {
        assert_eq!(rig.course.stage(), Stage::Probing);
    }
    let refusal = IdentifyError::NoMotion { excursion_m: 0.0 };
    rig.hand_over(identification(Err(refusal), 0));
    let hold_s = hold_s(&rig, 0);
    assert_eq!(hold_s, 0.25);
    assert_eq!(
        hold_until_stopped(&mut rig, hold_s),
        CourseError::Identify(refusal)
    );
    assert!(rig.course.identified().is_none());
    assert_trims_nothing(&mut rig);
}

/// An identification not handed over by the end of the hold of the most work stops the
/// course, naming the hold (5.425 s for 46 fits).
#[test]
fn an_identification_later_than_the_hold_fails_the_course() {
    let mut rig = Rig::started(IDEAL);
    while !rig.boundary().unwrap().identify {}
    let hold_s = hold_s(&rig, FITS_MAX);
    assert!((hold_s - 5.425).abs() < 1e-9, "{hold_s}");
    assert_eq!(
        hold_until_stopped(&mut rig, hold_s),
        CourseError::IdentifyLate { hold_s }
    );
    assert_trims_nothing(&mut rig);
}

/// An identification handed over after the hold its own work is given has ended stops the
/// course as late, at the boundary it comes at: a runner that identifies at once would have
/// taken it earlier, and the two would no longer run one course.
#[test]
fn an_identification_handed_over_after_its_own_hold_fails_the_course() {
    let mut rig = Rig::started(IDEAL);
    while !rig.boundary().unwrap().identify {}
    let found = rig.course.probe().unwrap().identify();
    let hold_s = hold_s(&rig, found.fits);
    for _ in 0..hold_cycles(hold_s) {
        rig.boundary().unwrap();
        assert_eq!(rig.course.stage(), Stage::Identifying);
    }
    rig.hand_over(found);
    assert_eq!(rig.boundary(), Err(CourseError::IdentifyLate { hold_s }));
    assert_trims_nothing(&mut rig);
}

/// The course's probe counts its cycles from the first held one, however the scheduler starts:
/// started before its first segment (no idle period first), it still settles and probes 4 whole
/// cycles.
#[test]
fn a_course_started_at_once_probes_its_full_cycles() {
    let mut rig = Rig::new(IDEAL, true);
    assert!(!rig.to_probe().identify);
    for _ in 0..3 {
        assert!(!rig.boundary().unwrap().identify);
        assert_eq!(rig.course.stage(), Stage::Probing);
    }
    assert!(rig.boundary().unwrap().identify);
    let probe = rig.course.probe().unwrap();
    assert_eq!((probe.positions().len(), probe.segments().len()), (321, 20));
    assert_eq!(rig.identify(), Some(()));
}

fn finite(trims: Trims) -> bool {
    trims.positive.is_finite() && trims.negative.is_finite() && trims.bias_mps2.is_finite()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Operator starts and stops after any segment, on any drive within 10 % of its gains and
    /// 1 m/s² of offset: the course never panics, every trim decided or run is finite, and an
    /// error (the frictionless plate may drift off while idle) leaves the course failed.
    #[test]
    fn any_start_stop_sequence_keeps_the_trims_finite(
        drive in (0.9f64..1.1, 0.9f64..1.1, -1.0f64..1.0),
        requests in proptest::collection::vec((1usize..60, any::<bool>()), 1..10),
    ) {
        let mut rig = Rig::new([drive.0, drive.1, drive.2], false);
        for (segments, start) in requests {
            if start {
                rig.scheduler.start();
            } else {
                rig.scheduler.stop();
            }
            for _ in 0..segments {
                match rig.segment() {
                    Some(Ok(decision)) => {
                        prop_assert!(finite(decision.trims));
                        if decision.identify {
                            rig.identify();
                        }
                    }
                    Some(Err(_)) => prop_assert_eq!(rig.course.stage(), Stage::Failed),
                    None => {}
                }
                prop_assert!(finite(rig.trims) && finite(rig.course.feedforward()));
            }
        }
    }
}

/// Which trims a cycle runs: the ones decided for it; after an idle period, whose first segment
/// was made before the decision, the feedforward; an idle period none; and a running cycle after
/// a running one without its decision is late, named by its cycle.
#[test]
fn a_cycle_runs_its_decided_trims_the_feedforward_after_idle_or_is_late() {
    let mut scheduler = Scheduler::new(plan(), 4);
    let idle = scheduler.next_segment();
    scheduler.start();
    let first = scheduler.next_segment();
    let decided = Trims {
        positive: 0.98,
        negative: 1.02,
        bias_mps2: -1.0,
        segments_mps2: [0.5, 0.25, -0.25, -0.5],
    };
    let feedforward = Trims {
        bias_mps2: -0.5,
        ..Trims::NONE
    };
    let mut trims = CycleTrims::NONE;
    assert_eq!(trims.for_cycle(&idle, true), Ok(None));
    assert_eq!(trims.for_cycle(&first, true), Ok(Some(Trims::NONE)));
    assert_eq!(
        trims.for_cycle(&first, false),
        Err(LateTrims { cycle: first.cycle })
    );
    let decision = Decision {
        cycle: first.cycle,
        trims: decided,
        release: false,
        identify: false,
    };
    trims.take(&decision, feedforward);
    assert_eq!(trims.for_cycle(&first, false), Ok(Some(decided)));
    for _ in 0..3 {
        scheduler.next_segment();
    }
    let second = scheduler.next_segment();
    assert_eq!(trims.for_cycle(&second, true), Ok(Some(feedforward)));
    assert_eq!(
        trims.for_cycle(&second, false),
        Err(LateTrims {
            cycle: second.cycle
        })
    );
}
