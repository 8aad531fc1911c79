//! The scheduler: boundary-only changes, ramps, and the drift bound over a million cycles,
//! checked by integrating the emitted segments independently in integers.

use feeder_shared::{
    Drive, Error, Level, Limits, Phase, Scheduler, Segment, SegmentKind, TickClock, TickPlan,
    Waveform, WaveformSpec,
};
use proptest::prelude::*;

fn plan(frequency_hz: f64, duty: f64, stroke_m: f64, clock_hz: u32) -> TickPlan {
    let spec = WaveformSpec::from_frequency(frequency_hz, duty, Drive::Stroke { stroke_m });
    TickPlan::new(
        &Waveform::new(spec, &Limits::NONE).unwrap(),
        TickClock::new(clock_hz),
    )
    .unwrap()
}

/// A scheduler of the paper's 2.5 mm stroke at 50 Hz and `duty` on a 1 MHz clock.
fn paper_scheduler(duty: f64, ramp_cycles: u16) -> Scheduler {
    Scheduler::new(plan(50.0, duty, 0.0025, 1_000_000), ramp_cycles)
}

/// Exact plate state from the emitted segments: velocity in `(a/steps)·tick`, twice the position
/// in `(a/steps)·tick²`. The plan must not change while it is used.
#[derive(Default)]
struct Plate {
    velocity: i128,
    twice_position: i128,
}

impl Plate {
    fn apply(&mut self, segment: &Segment) {
        let accel = i128::from(segment.level.sign()) * i128::from(segment.amplitude.step);
        let ticks = i128::from(segment.ticks);
        self.twice_position += 2 * self.velocity * ticks + accel * ticks * ticks;
        self.velocity += accel * ticks;
    }

    /// The position in metres, in the units of `scheduler`'s plan and soft start.
    fn position_m(&self, scheduler: &Scheduler) -> f64 {
        let unit_m = scheduler.plan().residual_unit_m() / f64::from(scheduler.ramp_cycles());
        self.twice_position as f64 / 2.0 * unit_m
    }
}

#[test]
fn soft_start_and_soft_stop_ramp_the_amplitude_cycle_by_cycle() {
    let mut scheduler = paper_scheduler(0.586, 4);
    // Stopped: idle periods of level 0.
    let idle = scheduler.next_segment();
    assert_eq!(
        (idle.kind, idle.level, idle.ticks, idle.phase),
        (SegmentKind::Idle, Level::Zero, 20_000, Phase::Stopped)
    );
    scheduler.start();
    let mut steps = Vec::new();
    for _ in 0..6 {
        let first = scheduler.next_segment();
        assert_eq!(first.kind, SegmentKind::Accelerate);
        steps.push((first.amplitude.step, first.phase));
        for _ in 0..3 {
            assert_eq!(scheduler.next_segment().amplitude, first.amplitude);
        }
    }
    use Phase::*;
    assert_eq!(
        steps,
        [
            (1, Starting),
            (2, Starting),
            (3, Starting),
            (4, Running),
            (4, Running),
            (4, Running)
        ]
    );
    scheduler.stop();
    let mut stopping = Vec::new();
    loop {
        let first = scheduler.next_segment();
        if first.kind == SegmentKind::Idle {
            assert_eq!(first.phase, Stopped);
            break;
        }
        stopping.push((first.amplitude.step, first.phase));
        for _ in 0..3 {
            scheduler.next_segment();
        }
    }
    assert_eq!(stopping, [(3, Stopping), (2, Stopping), (1, Stopping)]);
}

#[test]
fn requests_wait_for_the_cycle_boundary() {
    let mut scheduler = paper_scheduler(0.586, 1);
    scheduler.start();
    let first = scheduler.next_segment();
    assert_eq!(
        (first.kind, first.amplitude.step, first.phase),
        (SegmentKind::Accelerate, 1, Phase::Running)
    );
    scheduler.stop();
    scheduler
        .set_plan(plan(100.0, 0.6, 0.001, 1_000_000))
        .unwrap();
    for kind in [
        SegmentKind::Plateau,
        SegmentKind::Reverse,
        SegmentKind::Return,
    ] {
        let segment = scheduler.next_segment();
        assert_eq!(
            (segment.kind, segment.phase, segment.plan_applied),
            (kind, Phase::Running, false)
        );
        assert_eq!(segment.peak_accel_mps2, first.peak_accel_mps2);
    }
    let boundary = scheduler.next_segment();
    assert_eq!(boundary.start_tick, 20_000);
    assert_eq!(
        (boundary.kind, boundary.ticks, boundary.plan_applied),
        (SegmentKind::Idle, 10_000, true)
    );
}

#[test]
fn halt_drops_to_idle_at_once() {
    let mut scheduler = paper_scheduler(0.586, 1);
    scheduler.start();
    let first = scheduler.next_segment();
    scheduler.halt();
    let next = scheduler.next_segment();
    assert_eq!(
        (next.kind, next.level, next.start_tick),
        (SegmentKind::Idle, Level::Zero, first.end_tick())
    );
    assert_eq!(next.cycle, first.cycle + 1);
    assert!(!scheduler.run_requested());
}

#[test]
fn a_plan_for_another_clock_is_refused() {
    let mut scheduler = paper_scheduler(0.586, 1);
    let other = plan(50.0, 0.586, 0.0025, 2_000_000);
    assert_eq!(
        scheduler.set_plan(other),
        Err(Error::ClockMismatch {
            running_hz: 1_000_000,
            requested_hz: 2_000_000
        })
    );
    assert!(scheduler.pending_plan().is_none());
}

/// Runs `cycles` cycles and checks velocity is exactly 0 at every boundary and the boundary
/// position stays within the plan's drift bound. Returns the largest |position| seen in metres.
fn run_cycles(scheduler: &mut Scheduler, cycles: u64) -> f64 {
    let plan = *scheduler.plan();
    let mut plate = Plate::default();
    let mut worst_m: f64 = 0.0;
    let mut segments_in_cycle = 0;
    for _ in 0..cycles * 4 {
        let segment = scheduler.next_segment();
        plate.apply(&segment);
        segments_in_cycle += 1;
        if segment.kind == SegmentKind::Return || segment.kind == SegmentKind::Idle {
            assert_eq!(
                plate.velocity, 0,
                "plate not at rest after {segments_in_cycle} segments"
            );
            segments_in_cycle = 0;
            let position_m = plate.position_m(scheduler);
            worst_m = worst_m.max(position_m.abs());
            assert!(
                position_m.abs() <= plan.drift_bound_m * (1.0 + 1e-12),
                "{position_m} > {}",
                plan.drift_bound_m
            );
        }
    }
    worst_m
}

#[test]
fn naive_rounding_would_walk_but_the_feedback_holds_the_paper_point() {
    let plan = plan(50.0, 0.586, 0.0025, 1_000_000);
    // Naive rounding of the edges walks X·a/f² per cycle: about 3.5e-7 m, 1 mm per minute at 50 Hz.
    let naive = plan
        .variants
        .iter()
        .find(|c| c.accelerate_ticks == 1713 && c.return_ticks == 4140);
    let naive_walk_m = naive.map_or(2391.0, |c| c.residual as f64) * plan.residual_unit_m();
    assert!(naive_walk_m * 50.0 * 60.0 > 1e-3);
    let mut scheduler = Scheduler::new(plan, 1);
    scheduler.start();
    let worst_m = run_cycles(&mut scheduler, 1_000_000);
    assert!(worst_m <= plan.drift_bound_m);
    assert!(worst_m < 1e-6);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]
    #[test]
    fn drift_stays_within_the_bound_over_a_million_cycles(
        frequency_hz in 20.0f64..200.0,
        duty in 0.51f64..0.95,
        stroke_m in 1e-4f64..0.005,
        clock_hz in prop_oneof![Just(1_000_000u32), Just(170_000_000), 100_000u32..100_000_000],
        ramp_cycles in 1u16..20,
    ) {
        let plan = plan(frequency_hz, duty, stroke_m, clock_hz);
        let mut scheduler = Scheduler::new(plan, ramp_cycles);
        scheduler.start();
        run_cycles(&mut scheduler, 1_000_000);
    }
}

#[derive(Debug, Clone)]
enum Request {
    Start,
    Stop,
    Halt,
    Plan(f64, f64),
    Ramp(u16),
    Advance(u8),
}

fn request() -> impl Strategy<Value = Request> {
    prop_oneof![
        3 => Just(Request::Start),
        2 => Just(Request::Stop),
        1 => Just(Request::Halt),
        2 => (50.0f64..100.0, 0.51f64..0.9).prop_map(|(f, d)| Request::Plan(f, d)),
        1 => (0u16..10).prop_map(Request::Ramp),
        6 => (1u8..12).prop_map(Request::Advance),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]
    #[test]
    fn any_request_sequence_changes_the_output_only_at_cycle_boundaries(
        requests in proptest::collection::vec(request(), 1..60),
    ) {
        let mut scheduler = paper_scheduler(0.586, 3);
        let mut previous: Option<Segment> = None;
        let mut halted = false;
        for request in requests {
            match request {
                Request::Start => scheduler.start(),
                Request::Stop => scheduler.stop(),
                Request::Halt => { scheduler.halt(); halted = true; }
                Request::Plan(f, d) => scheduler.set_plan(plan(f, d, 0.002, 1_000_000)).unwrap(),
                Request::Ramp(cycles) => scheduler.set_ramp_cycles(cycles),
                Request::Advance(count) => {
                    for _ in 0..count {
                        let segment = scheduler.next_segment();
                        prop_assert!(segment.ticks > 0);
                        prop_assert!(segment.amplitude.step <= segment.amplitude.steps);
                        prop_assert_eq!(segment.kind == SegmentKind::Idle, segment.amplitude.step == 0);
                        if let Some(last) = previous {
                            prop_assert_eq!(segment.start_tick, last.end_tick());
                            let boundary = last.kind == SegmentKind::Return || last.kind == SegmentKind::Idle || halted;
                            if boundary {
                                prop_assert!(segment.starts_cycle());
                                prop_assert_eq!(segment.cycle, last.cycle + 1);
                            } else {
                                // Mid-cycle: same cycle, amplitude, plan and phase; the next kind in order.
                                let expected_kind = match last.kind {
                                    SegmentKind::Accelerate => SegmentKind::Plateau,
                                    SegmentKind::Plateau => SegmentKind::Reverse,
                                    _ => SegmentKind::Return,
                                };
                                prop_assert_eq!(segment.kind, expected_kind);
                                prop_assert_eq!(segment.cycle, last.cycle);
                                prop_assert_eq!(segment.amplitude, last.amplitude);
                                prop_assert_eq!(segment.peak_accel_mps2, last.peak_accel_mps2);
                                prop_assert_eq!(segment.phase, last.phase);
                                prop_assert!(!segment.plan_applied);
                            }
                        }
                        halted = false;
                        previous = Some(segment);
                    }
                }
            }
        }
    }
}

proptest! {
    /// A controlled stop requested after any segment, at full amplitude or mid-ramp, lets the
    /// cycle in progress end (velocity exactly zero in integer ticks, position within the drift
    /// bound) and idles from the next boundary on, without a ramp.
    #[test]
    fn a_controlled_stop_at_any_moment_leaves_the_plate_at_rest(
        ramp_cycles in 1u16..8,
        cycles_before in 0u64..12,
        segments_into_cycle in 0usize..4,
        duty in 0.52f64..0.9,
    ) {
        let mut scheduler = paper_scheduler(duty, ramp_cycles);
        scheduler.next_segment();
        scheduler.start();
        let mut plate = Plate::default();
        for _ in 0..(cycles_before * 4 + segments_into_cycle as u64) {
            let segment = scheduler.next_segment();
            prop_assert_eq!(segment.amplitude.steps, ramp_cycles);
            plate.apply(&segment);
        }
        scheduler.quick_stop();
        let mut after_stop = 0;
        loop {
            let segment = scheduler.next_segment();
            if segment.kind == SegmentKind::Idle {
                prop_assert_eq!(segment.phase, Phase::Stopped);
                prop_assert_eq!(segment.level, Level::Zero);
                break;
            }
            prop_assert!(segment.amplitude.step > 0);
            plate.apply(&segment);
            after_stop += 1;
            prop_assert!(after_stop <= 4, "the stop took more than the cycle in progress");
        }
        prop_assert_eq!((after_stop + segments_into_cycle) % 4, 0);
        prop_assert_eq!(plate.velocity, 0);
        let position_m = plate.position_m(&scheduler);
        let bound_m = scheduler.plan().drift_bound_m;
        prop_assert!(
            position_m.abs() <= bound_m * (1.0 + 1e-9),
            "left at {position_m} m, bound {bound_m} m"
        );
        for _ in 0..3 {
            prop_assert_eq!(scheduler.next_segment().kind, SegmentKind::Idle);
        }
    }
}

#[test]
fn a_start_after_a_controlled_stop_ramps_up_from_rest() {
    let mut scheduler = paper_scheduler(0.586, 3);
    scheduler.start();
    for _ in 0..9 {
        scheduler.next_segment();
    }
    scheduler.quick_stop();
    while scheduler.next_segment().kind != SegmentKind::Idle {}
    scheduler.start();
    let first = scheduler.next_segment();
    assert_eq!(
        (first.kind, first.amplitude.step, first.phase),
        (SegmentKind::Accelerate, 1, Phase::Starting)
    );
}

#[test]
fn the_longest_ramp_set_at_full_amplitude_keeps_full_amplitude() {
    let mut scheduler = paper_scheduler(0.586, 2);
    scheduler.start();
    for _ in 0..12 {
        scheduler.next_segment();
    }
    scheduler.set_ramp_cycles(u16::MAX);
    for _ in 0..3 {
        let first = scheduler.next_segment();
        assert_eq!(first.kind, SegmentKind::Accelerate);
        assert_eq!(
            (first.amplitude.step, first.amplitude.steps),
            (u16::MAX, u16::MAX)
        );
        assert_eq!(first.phase, Phase::Running);
        for _ in 0..3 {
            scheduler.next_segment();
        }
    }
}

proptest! {
    /// A held start rises one step a cycle to the held step and runs every cycle there, each
    /// ending at rest within the drift bound; released, the soft start goes on one step a cycle
    /// from there.
    #[test]
    fn a_held_start_rises_to_its_step_stays_and_a_release_ramps_on_from_it(
        ramp_cycles in 2u16..30,
        held in 1u16..40,
        held_cycles in 1u64..20,
        duty in 0.52f64..0.9,
    ) {
        let mut scheduler = paper_scheduler(duty, ramp_cycles);
        scheduler.hold_step(held);
        scheduler.start();
        let expected = held.min(ramp_cycles);
        let bound_m = scheduler.plan().drift_bound_m;
        let mut plate = Plate::default();
        let rise = u64::from(expected) - 1;
        for cycle in 0..rise + held_cycles {
            for _ in 0..4 {
                let segment = scheduler.next_segment();
                let step = (cycle + 1).min(u64::from(expected));
                prop_assert_eq!(u64::from(segment.amplitude.step), step);
                plate.apply(&segment);
            }
            prop_assert_eq!(plate.velocity, 0);
            prop_assert!(plate.position_m(&scheduler).abs() <= bound_m * (1.0 + 1e-9));
        }
        scheduler.release_hold();
        let mut step = expected;
        while step < ramp_cycles {
            step += 1;
            let first = scheduler.next_segment();
            prop_assert_eq!(first.amplitude.step, step);
            prop_assert_eq!(
                first.phase,
                if step == ramp_cycles { Phase::Running } else { Phase::Starting }
            );
            for _ in 0..3 {
                scheduler.next_segment();
            }
        }
    }

    /// Each start from rest begins with the settle segments asked for: level zero, step 0, the
    /// plan's settle length, each its own cycle, back to back; then the soft start's first
    /// cycle. A start while running, or a restart of a soft stop, settles nothing.
    #[test]
    fn a_start_from_rest_settles_first(
        segments in 0u16..50,
        freq_hz in 50.0f64..100.0,
        idle_periods in 0usize..3,
    ) {
        let spec = WaveformSpec::from_frequency(freq_hz, 0.586, Drive::Stroke { stroke_m: 1e-3 });
        let plan = TickPlan::new(&Waveform::new(spec, &Limits::NONE).unwrap(), TickClock::new(1_000_000)).unwrap();
        let mut scheduler = Scheduler::new(plan, 4);
        scheduler.settle_before_start(segments);
        for _ in 0..idle_periods {
            prop_assert_eq!(scheduler.next_segment().kind, SegmentKind::Idle);
        }
        scheduler.start();
        let ticks = plan.settle_ticks();
        prop_assert!(f64::from(ticks) >= 2.5e-3 * 1e6 && ticks <= plan.period_ticks);
        let mut tick = scheduler.next_tick();
        let mut cycle = scheduler.cycle();
        for _ in 0..segments {
            let settle = scheduler.next_segment();
            prop_assert_eq!(
                (settle.kind, settle.level, settle.amplitude.step, settle.ticks),
                (SegmentKind::Settle, Level::Zero, 0, ticks)
            );
            prop_assert_eq!((settle.start_tick, settle.cycle), (tick, cycle));
            prop_assert!(settle.starts_cycle() && scheduler.at_boundary());
            tick += u64::from(ticks);
            cycle += 1;
        }
        let first = scheduler.next_segment();
        prop_assert_eq!((first.kind, first.amplitude.step, first.start_tick), (SegmentKind::Accelerate, 1, tick));
        for _ in 0..3 {
            scheduler.next_segment();
        }
        scheduler.stop();
        scheduler.start();
        prop_assert_eq!(scheduler.next_segment().kind, SegmentKind::Accelerate);
    }
}

/// A stop asked for during the settle idles at the next settle boundary, and the next start
/// from rest settles its whole count again.
#[test]
fn a_stop_during_the_settle_idles_and_the_next_start_settles_anew() {
    let mut scheduler = paper_scheduler(0.586, 4);
    scheduler.settle_before_start(6);
    scheduler.start();
    for _ in 0..3 {
        assert_eq!(scheduler.next_segment().kind, SegmentKind::Settle);
    }
    scheduler.stop();
    assert_eq!(scheduler.next_segment().kind, SegmentKind::Idle);
    scheduler.start();
    let kinds: Vec<SegmentKind> = (0..7).map(|_| scheduler.next_segment().kind).collect();
    assert_eq!(kinds[..6], [SegmentKind::Settle; 6]);
    assert_eq!(kinds[6], SegmentKind::Accelerate);
}

#[test]
fn a_hold_set_while_running_drops_to_its_step_at_the_next_boundary() {
    let mut scheduler = paper_scheduler(0.586, 10);
    scheduler.start();
    for _ in 0..(12 * 4 + 1) {
        scheduler.next_segment();
    }
    scheduler.hold_step(3);
    for _ in 0..3 {
        assert_eq!(scheduler.next_segment().amplitude.step, 10);
    }
    let first = scheduler.next_segment();
    assert_eq!((first.amplitude.step, first.phase), (3, Phase::Starting));
}

#[test]
fn a_hold_at_zero_idles_while_motion_is_requested_and_a_new_hold_rises_again() {
    let mut scheduler = paper_scheduler(0.586, 10);
    scheduler.hold_step(4);
    scheduler.start();
    for step in [1, 2, 3, 4, 4] {
        for _ in 0..4 {
            assert_eq!(scheduler.next_segment().amplitude.step, step);
        }
    }
    scheduler.hold_step(0);
    for _ in 0..3 {
        let idle = scheduler.next_segment();
        assert_eq!((idle.kind, idle.phase), (SegmentKind::Idle, Phase::Stopped));
    }
    assert!(scheduler.run_requested());
    scheduler.hold_step(4);
    let first = scheduler.next_segment();
    assert_eq!(
        (first.kind, first.amplitude.step),
        (SegmentKind::Accelerate, 1)
    );
}

/// A new ramp length keeps a hold's fraction of the amplitude: 8 of 25 steps becomes 3 of 8
/// (0.32 rounds to 0.375), not 8 of 8.
#[test]
fn a_new_ramp_length_scales_the_held_step() {
    let mut scheduler = paper_scheduler(0.586, 25);
    scheduler.hold_step(8);
    scheduler.start();
    for step in 1..=8 {
        assert_eq!(scheduler.next_segment().amplitude.step, step);
        for _ in 0..3 {
            scheduler.next_segment();
        }
    }
    assert_eq!(scheduler.next_segment().amplitude.step, 8);
    scheduler.set_ramp_cycles(8);
    for _ in 0..3 {
        scheduler.next_segment();
    }
    let first = scheduler.next_segment();
    assert_eq!((first.amplitude.step, first.amplitude.steps), (3, 8));
    assert_eq!(scheduler.held_step(), Some(3));
}

/// A hold asked for after a new ramp length, before it takes effect, counts the new length's
/// steps: 2 of 8 stays 2 of 8 where the 8 of 25 held before would scale to 3.
#[test]
fn a_hold_with_a_new_ramp_length_pending_counts_its_steps() {
    let mut scheduler = paper_scheduler(0.586, 25);
    scheduler.hold_step(8);
    scheduler.set_ramp_cycles(8);
    scheduler.hold_step(2);
    assert_eq!(scheduler.held_step(), Some(8));
    scheduler.start();
    let first = scheduler.next_segment();
    assert_eq!((first.amplitude.step, first.amplitude.steps), (1, 8));
    assert_eq!(scheduler.held_step(), Some(2));
    for _ in 0..3 {
        scheduler.next_segment();
    }
    assert_eq!(scheduler.next_segment().amplitude.step, 2);
    scheduler.release_hold();
    for _ in 0..3 {
        scheduler.next_segment();
    }
    assert_eq!(scheduler.next_segment().amplitude.step, 3);
}
