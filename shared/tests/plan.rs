//! The integer-tick plan: exact invariants checked by independent integer kinematics.

use feeder_shared::{
    CycleTicks, Drive, Error, Limits, SegmentKind, TickClock, TickPlan, Waveform, WaveformSpec,
};
use proptest::prelude::*;

/// Net velocity (units `a·tick`) and twice the net displacement (units `a·tick²`) of one cycle,
/// integrated segment by segment from rest without using the plan's residual formula.
fn integrate_cycle(cycle: &CycleTicks) -> (i128, i128) {
    let mut velocity: i128 = 0;
    let mut twice_position: i128 = 0;
    for (index, sign) in [1i128, 0, -1, 1].into_iter().enumerate() {
        let ticks = i128::from(cycle.segment_ticks(index));
        twice_position += 2 * velocity * ticks + sign * ticks * ticks;
        velocity += sign * ticks;
    }
    (velocity, twice_position)
}

fn waveform(frequency_hz: f64, duty: f64, stroke_m: f64) -> Waveform {
    Waveform::new(
        WaveformSpec::from_frequency(frequency_hz, duty, Drive::Stroke { stroke_m }),
        &Limits::NONE,
    )
    .unwrap()
}

#[test]
fn paper_point_at_1_mhz_is_hand_checkable() {
    let plan = TickPlan::new(&waveform(50.0, 0.586, 0.0025), TickClock::new(1_000_000)).unwrap();
    assert_eq!(plan.period_ticks, 20_000);
    // Exact edges: t1 = 1712.71, t2 = 10007.29, t3 = 15860 µs.
    for cycle in plan.variants {
        let [t1, t2, t3] = cycle.edge_ticks();
        assert!((i64::from(t1) - 1713).abs() <= 1, "{cycle:?}");
        assert!((i64::from(t2) - 10007).abs() <= 2, "{cycle:?}");
        assert!((i64::from(t3) - 15860).abs() <= 2, "{cycle:?}");
    }
    // Naive rounding (1713, 8294, 5853, 4140) leaves X = 1713·10007 − 4140² = 2391 a·µs², i.e.
    // 0.35 µm per cycle; the feedback bound must not exceed a few such cycles.
    assert!(plan.drift_bound_m < 1.0e-6, "{}", plan.drift_bound_m);
    assert!(plan.worst_edge_offset_ticks <= 1.5);
}

#[test]
fn realized_frequency_is_clock_over_whole_period() {
    let plan = TickPlan::new(&waveform(73.0, 0.58, 0.002), TickClock::new(1_000_000)).unwrap();
    // 1e6 / 73 = 13698.63 → 13699 ticks.
    assert_eq!(plan.period_ticks, 13_699);
    assert!((plan.realized_frequency_hz() - 1.0e6 / 13_699.0).abs() < 1e-9);
}

#[test]
fn clocks_that_cannot_represent_the_waveform_are_refused() {
    // P = 100 ticks · √(2·0.50001 − 1) = 0.45 ticks.
    let slow = TickPlan::new(&waveform(100.0, 0.50001, 0.001), TickClock::new(10_000));
    assert!(
        matches!(
            slow,
            Err(Error::SegmentTooShort {
                segment: SegmentKind::Plateau,
                ..
            })
        ),
        "{slow:?}"
    );
    let sixteen_bit = TickClock::new(1_000_000).with_max_segment_ticks(u32::from(u16::MAX));
    let long = TickPlan::new(&waveform(10.0, 0.6, 0.001), sixteen_bit);
    assert!(
        matches!(
            long,
            Err(Error::TicksOverflow {
                segment: SegmentKind::Idle,
                max_ticks: 65_535,
                ..
            })
        ),
        "{long:?}"
    );
    assert!(matches!(
        TickPlan::new(&waveform(50.0, 0.6, 0.001), TickClock::new(0)),
        Err(Error::NotPositive { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn plan_invariants_hold_exactly(
        frequency_hz in 5.0f64..500.0,
        duty in 0.501f64..0.99,
        stroke_m in 1e-4f64..0.01,
        clock_hz in prop_oneof![Just(32_768u32), Just(1_000_000), Just(16_000_000), Just(170_000_000), 20_000u32..200_000_000],
    ) {
        let w = waveform(frequency_hz, duty, stroke_m);
        let n = clock_hz as f64 / frequency_hz;
        let shortest_ticks = (n * (duty - (2.0 * duty - 1.0).sqrt()) / 2.0)
            .min(n * (2.0 * duty - 1.0).sqrt())
            .min(n * (1.0 - duty) / 2.0);
        let Ok(plan) = TickPlan::new(&w, TickClock::new(clock_hz)) else {
            // Refusal is only allowed when a segment is shorter than about two ticks.
            prop_assert!(shortest_ticks < 2.5, "refused a plan whose shortest segment is {shortest_ticks} ticks");
            return Ok(());
        };
        let exact_period = clock_hz as f64 / frequency_hz;
        prop_assert!((f64::from(plan.period_ticks) - exact_period).abs() <= 0.5);
        let unit_m = w.accel_mps2 / (clock_hz as f64).powi(2);
        for (index, cycle) in plan.variants.iter().enumerate() {
            let total: u64 = (0..4).map(|i| u64::from(cycle.segment_ticks(i))).sum();
            prop_assert_eq!(total, u64::from(plan.period_ticks));
            prop_assert_eq!(cycle.reverse_ticks, cycle.accelerate_ticks + cycle.return_ticks);
            let (velocity, twice_position) = integrate_cycle(cycle);
            prop_assert_eq!(velocity, 0);
            prop_assert_eq!(twice_position, 2 * i128::from(cycle.residual));
            if index == 0 { prop_assert!(cycle.residual >= 0) } else { prop_assert!(cycle.residual <= 0) }
            let [t1, t2, t3] = cycle.edge_ticks();
            prop_assert!(0 < t1 && t1 < t2 && t2 < t3 && t3 < plan.period_ticks);
            let n = f64::from(plan.period_ticks);
            let root = (2.0 * duty - 1.0).sqrt();
            for (edge, exact) in [(t1, n * (duty - root) / 2.0), (t2, n * (duty + root) / 2.0), (t3, n * (1.0 + duty) / 2.0)] {
                // Rounding of the exact edges themselves grows with N.
                prop_assert!((f64::from(edge) - exact).abs() <= plan.worst_edge_offset_ticks + 1e-12 * n);
            }
        }
        if shortest_ticks >= 4.0 {
            prop_assert!(plan.worst_edge_offset_ticks <= 1.5, "{plan:?}");
        }
        let worst = plan.variants[0].residual.max(-plan.variants[1].residual) as f64;
        prop_assert!((plan.drift_bound_m - worst * unit_m).abs() <= 1e-12 * plan.drift_bound_m.max(1e-300));
    }
}

#[test]
fn a_segment_below_the_output_floor_is_refused_with_its_length_and_the_floor() {
    // 100 Hz, d = 0.9: the first segment is T(1 − d)²/(2(d + √(2d − 1))) = 27.9 µs.
    let clock = TickClock::new(1_000_000).with_min_segment_s(120e-6);
    assert_eq!(clock.min_segment_ticks, 120);
    match TickPlan::new(&waveform(100.0, 0.9, 0.0005), clock) {
        Err(Error::SegmentBelowFloor {
            segment: SegmentKind::Accelerate,
            ticks,
            min_ticks: 120,
            clock_hz: 1_000_000,
        }) => assert!((27..=29).contains(&ticks), "{ticks}"),
        other => panic!("{other:?}"),
    }
    // The paper's point has its shortest segment at 1713 µs: well above the floor.
    assert!(TickPlan::new(&waveform(50.0, 0.586, 0.0025), clock).is_ok());
    // The floor rounds up to whole ticks and is never below one.
    assert_eq!(
        TickClock::new(1_000_000)
            .with_min_segment_s(120.2e-6)
            .min_segment_ticks,
        121
    );
    assert_eq!(
        TickClock::new(1_000_000)
            .with_min_segment_s(0.0)
            .min_segment_ticks,
        1
    );
}

proptest! {
    /// Either every segment of both variants (and so every ramp step, which only scales the
    /// amplitude) is at least the floor long, or the plan is refused naming a segment below it.
    #[test]
    fn no_accepted_plan_has_a_segment_below_the_floor(
        frequency_hz in 50.0f64..100.0,
        duty in 0.5001f64..0.999,
        clock_hz in prop_oneof![Just(1_000_000u32), Just(170_000_000), Just(20_000)],
        min_segment_s in 0.0f64..500e-6,
    ) {
        let clock = TickClock::new(clock_hz).with_min_segment_s(min_segment_s);
        match TickPlan::new(&waveform(frequency_hz, duty, 0.001), clock) {
            Ok(plan) => {
                for cycle in plan.variants {
                    for index in 0..4 {
                        prop_assert!(cycle.segment_ticks(index) >= clock.min_segment_ticks);
                    }
                }
                prop_assert!(plan.period_ticks >= clock.min_segment_ticks);
            }
            Err(Error::SegmentBelowFloor { ticks, min_ticks, clock_hz: hz, .. }) => {
                prop_assert!(ticks < min_ticks);
                prop_assert_eq!(min_ticks, clock.min_segment_ticks);
                prop_assert_eq!(hz, clock_hz);
            }
            Err(Error::SegmentTooShort { .. }) => {}
            Err(other) => prop_assert!(false, "unexpected refusal {other:?}"),
        }
    }
}
