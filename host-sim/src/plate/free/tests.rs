//! The free slide against the general solver, from random states and through whole stretches,
//! and hand-derived cases.

use proptest::prelude::*;

use crate::contact::Contact;
use crate::plate::linear::{State, F, P, Q, U, V, X};
use crate::plate::model::{ContactEvent, Part, PlateModel, Slide};
use crate::plate::motion::GeneralSolver;
use crate::plate::params::PlateParams;
use crate::plate::solver::Solver;

use super::FreeSolver;

/// A free slide with a current loop of 0.1 Hz to 100 kHz (or none), a spring up to
/// 10⁷ N/m (up to 7 kHz on the lightest plate) and damping up to 5000 N·s/m.
fn free_plate() -> impl Strategy<Value = PlateParams> {
    (
        0.2..5.0_f64,
        prop_oneof![Just(None), (0.1..1e5_f64).prop_map(Some)],
        prop_oneof![Just(0.0), 0.0..1e5_f64, 0.0..1e7_f64],
        prop_oneof![Just(0.0), 0.0..200.0_f64, 0.0..5000.0_f64],
        prop_oneof![Just(None), (1e-3..1e-2_f64).prop_map(Some)],
    )
        .prop_map(
            |(mass_kg, f_c, spring_npm, damping, end_stop_m)| PlateParams {
                mass_kg,
                current_bandwidth_hz: f_c,
                spring_npm,
                spring_damping_nspm: damping,
                end_stop_m,
                ..PlateParams::default()
            },
        )
}

/// A solver's outcome over a stretch: its first event with its time, the state then, and
/// the plate's peak distance from the centre so far (at its ends and turning points).
type Finding = (Option<(ContactEvent, f64)>, State, f64);

/// Both solvers from the same state over a fresh segment of `duration_s`.
fn both(
    model: &PlateModel,
    part: Part,
    target_n: f64,
    z: &State,
    duration_s: f64,
) -> (Finding, Finding) {
    let free = FreeSolver::new(model).expect("a free slide");
    let general = GeneralSolver::new(model);
    let outcome = |mut solver: Box<dyn Solver>| {
        let mut peak = z[X].abs();
        solver.begin(target_n, duration_s, duration_s);
        let (event, end_z) = solver.next_event(Slide::Free, part, z, 0.0, &mut peak);
        (event, end_z, peak.max(end_z[X].abs()))
    };
    (outcome(Box::new(free)), outcome(Box::new(general)))
}

/// A plate without spring or damping up to a stiff, heavily damped one, from 1 g to 1 t.
fn extreme_plate() -> impl Strategy<Value = PlateParams> {
    (
        free_plate(),
        prop_oneof![0.001..0.1_f64, 0.2..5.0_f64, 10.0..1000.0_f64],
    )
        .prop_map(|(plate, mass_kg)| PlateParams { mass_kg, ..plate })
}

/// The part's contact and state, the command and the stretch's length of one check.
#[derive(Debug)]
struct Case {
    mu: f64,
    extra_static: f64,
    start: [f64; 6],
    stuck: bool,
    command_mps2: f64,
    duration_s: f64,
}

/// A part's contact and state, with commands and stretches from the strategies given.
fn case(
    command_mps2: impl Strategy<Value = f64>,
    duration_s: impl Strategy<Value = f64>,
) -> impl Strategy<Value = Case> {
    (
        0.05..1.0_f64,
        prop_oneof![Just(0.0), 0.0..0.5_f64],
        prop::array::uniform6(-1.0..1.0_f64),
        any::<bool>(),
        command_mps2,
        duration_s,
    )
        .prop_map(
            |(mu, extra_static, start, stuck, command_mps2, duration_s)| Case {
                mu,
                extra_static,
                start,
                stuck,
                command_mps2,
                duration_s,
            },
        )
}

/// The case's model, drive target and settled state with the part's contact.
fn setup(params: PlateParams, case: &Case) -> (PlateModel, f64, State, Part) {
    let contact = Contact::new(case.mu, case.mu + case.extra_static, 9.81, 1e-4, 0.0).unwrap();
    let model = PlateModel::new(params, contact);
    let target_n = params.target_force_n(case.command_mps2);
    let x_lim = params.end_stop_m.unwrap_or(1e-2);
    let start = case.start;
    let mut z: State = [
        0.9 * x_lim * start[0],
        0.3 * start[1],
        params.mass_kg * 200.0 * start[2],
        0.3 * start[3],
        start[4],
        1e-3 * start[5],
        1.0,
    ];
    if params.current_bandwidth_hz.is_none() {
        z[F] = target_n;
    }
    let mut slide = Slide::Free;
    let mut part = if case.stuck {
        Part::Stuck
    } else {
        Part::Sliding((z[U] - z[V]).signum())
    };
    model.settle(&mut z, &mut slide, &mut part);
    (model, target_n, z, part)
}

/// The free slide's outcome and the general solver's from one state agree: the same event,
/// at the same time to 10⁻⁹ of the stretch, and the same state and peak excursion to 10⁻⁹ of
/// their scale (or of the value, where the plate has gone further).
fn close(
    params: &PlateParams,
    duration_s: f64,
    free: &Finding,
    general: &Finding,
) -> Result<(), TestCaseError> {
    let x_lim = params.end_stop_m.unwrap_or(1e-2);
    let kind = |e: Option<(ContactEvent, f64)>| e.map(|(event, _)| event);
    prop_assert_eq!(kind(free.0), kind(general.0));
    if let (Some((_, t_free)), Some((_, t))) = (free.0, general.0) {
        prop_assert!(
            (t_free - t).abs() <= 1e-9 * duration_s,
            "{} vs {}",
            t_free,
            t
        );
    }
    let scale = [x_lim, 1.0, params.mass_kg * 200.0, 1.0, 1.0, 1e-3];
    for (i, s) in [X, V, F, U, P, Q].into_iter().zip(scale) {
        prop_assert!(
            (free.1[i] - general.1[i]).abs() <= 1e-9 * s.max(general.1[i].abs()),
            "state {}: {:e} vs {:e}",
            i,
            free.1[i],
            general.1[i]
        );
    }
    // A stiff, damped spring rings down through turning points of rounding size near its
    // rest, which the general solver may pass over, so turning points are compared by the
    // peak they give.
    let (free_peak, general_peak) = (free.2, general.2);
    prop_assert!(
        (free_peak - general_peak).abs() <= 1e-9 * x_lim.max(general_peak),
        "peak {:e} vs {:e}",
        free_peak,
        general_peak
    );
    Ok(())
}

/// Both solvers from the case's state agree on the first event ([`close`]).
fn agree(params: PlateParams, case: Case) -> Result<(), TestCaseError> {
    let (model, target_n, z, part) = setup(params, &case);
    let (free, general) = both(&model, part, target_n, &z, case.duration_s);
    close(&params, case.duration_s, &free, &general)
}

/// ContactEvent by event through the case's stretch, as the stepper runs it, split into segments
/// at the fractions `splits` of it (the target holding through all): after each of the
/// part's events the course goes on in its chunk, and across each segment's end; every step
/// agrees with the general solver from the same state over the rest of its segment
/// ([`close`]). Returns how many events the course found.
fn agree_through(params: PlateParams, case: Case, splits: &[f64]) -> Result<usize, TestCaseError> {
    let (model, target_n, mut z, mut part) = setup(params, &case);
    let mut free = FreeSolver::new(&model).expect("a free slide");
    let mut general = GeneralSolver::new(&model);
    let mut slide = Slide::Free;
    // The peaks run on through the stretch, as the stepper's: the course need not seek the
    // turning points of a chunk that stays below its peak.
    let (mut free_peak, mut general_peak) = (z[X].abs(), z[X].abs());
    let ends_s: Vec<f64> = splits
        .iter()
        .map(|fraction| fraction * case.duration_s)
        .chain([case.duration_s])
        .collect();
    let mut events = 0;
    let mut start_s = 0.0;
    for &end_s in &ends_s {
        let duration_s = end_s - start_s;
        free.begin(target_n, duration_s, case.duration_s - start_s);
        general.begin(target_n, duration_s, case.duration_s - start_s);
        start_s = end_s;
        let mut offset_s = 0.0;
        loop {
            model.settle(&mut z, &mut slide, &mut part);
            let (event, end_z) = free.next_event(slide, part, &z, offset_s, &mut free_peak);
            free_peak = free_peak.max(end_z[X].abs());
            let (general_event, general_z) =
                general.next_event(slide, part, &z, offset_s, &mut general_peak);
            general_peak = general_peak.max(general_z[X].abs());
            close(
                &params,
                duration_s,
                &(event, end_z, free_peak),
                &(general_event, general_z, general_peak),
            )?;
            z = end_z;
            if part == Part::Stuck {
                z[U] = z[V];
            }
            match event {
                None => break,
                Some((ContactEvent::EndStop, _)) => return Ok(events),
                Some((event, t)) => {
                    events += 1;
                    if events == 100 {
                        return Ok(events);
                    }
                    offset_s += t;
                    model.apply(event, &mut z, &mut slide, &mut part);
                }
            }
        }
    }
    Ok(events)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// From any state of a feeder's plate, the scalar solution agrees with the general
    /// solver.
    #[test]
    fn the_free_slide_agrees_with_the_general_solver(
        params in free_plate(),
        case in case(-200.0..200.0_f64, 1e-4..2e-2_f64),
    ) {
        agree(params, case)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Through a whole stretch of a feeder's plate, event by event, the course that goes
    /// on in its chunk after the part's events, and across a segment's end where the next
    /// holds the target, agrees with the general solver.
    #[test]
    fn a_course_through_a_stretch_agrees_with_the_general_solver(
        params in free_plate(),
        case in case(-200.0..200.0_f64, 1e-3..2e-2_f64),
        split in prop_oneof![Just(None), (0.01..0.99_f64).prop_map(Some)],
    ) {
        agree_through(params, case, split.as_slice())?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Far outside a feeder's range (masses of 1 g to 1 t, commands of 10⁴ m/s², stretches
    /// of a nanosecond to a second) the two solvers still agree.
    #[test]
    fn the_free_slide_agrees_far_outside_a_feeder_s_range(
        params in extreme_plate(),
        case in case(
            prop_oneof![-200.0..200.0_f64, -1e4..1e4_f64],
            prop_oneof![1e-9..1e-4_f64, 1e-4..2e-2_f64, 2e-2..1.0_f64],
        ),
    ) {
        agree(params, case)?;
    }
}

/// A part ahead of a stiffly sprung plate meets it where the gap dips below zero inside a
/// chunk and opens again before the chunk ends: the bounds over the chunk must see the dip.
#[test]
fn a_meeting_inside_a_chunk_whose_ends_are_apart_is_found() {
    let params = PlateParams {
        mass_kg: 1.5445275830089054,
        current_bandwidth_hz: Some(4618.427662729602),
        spring_npm: 71404.21044409128,
        spring_damping_nspm: 170.2373076535165,
        end_stop_m: Some(0.003149768373894266),
        ..PlateParams::default()
    };
    let contact = Contact::kinetic(0.6278634258754741, 1e-4).unwrap();
    let model = PlateModel::new(params, contact);
    let target_n = params.target_force_n(81.8732739340645);
    let z: State = [2.852e-4, 0.0, 0.0, 0.2657, 0.0, 0.0, 1.0];
    let (free, general) = both(&model, Part::Sliding(1.0), target_n, &z, 0.0135);
    let (Some((ContactEvent::PartMeetsPlate, t_free)), Some((ContactEvent::PartMeetsPlate, t))) =
        (free.0, general.0)
    else {
        panic!("the part meets the plate: {free:?} {general:?}");
    };
    assert!((t_free - t).abs() < 1e-15, "{t_free} vs {t}");
}

/// The benchmark's plate: 1.5 kg, a 1 kHz current loop, an 18 Hz spring (2·10⁴ N/m) with
/// 20 N·s/m of damping.
fn lag_spring_plate() -> PlateParams {
    PlateParams {
        mass_kg: 1.5,
        current_bandwidth_hz: Some(1000.0),
        spring_npm: 2e4,
        spring_damping_nspm: 20.0,
        ..PlateParams::default()
    }
}

/// A part that has just met the plate starts its regime on the boundary (`u = v`) and must
/// not end it at once: the first event is the next one, as the general solver has it.
#[test]
fn a_regime_entered_on_its_boundary_does_not_end_at_once() {
    let params = lag_spring_plate();
    let model = PlateModel::new(params, Contact::kinetic(0.3, 1e-4).unwrap());
    // Accelerating at 67 m/s², the drive turning to −146 m/s²: the part slides behind, then
    // meets the plate when it has slowed.
    let target_n = params.target_force_n(-146.0);
    let mut z: State = [1e-4, 0.05, 100.0, 0.0, 0.0, 0.0, 1.0];
    z[U] = z[V];
    let mut slide = Slide::Free;
    let mut part = Part::Stuck;
    model.settle(&mut z, &mut slide, &mut part);
    assert!(matches!(part, Part::Sliding(_)));
    let (free, general) = both(&model, part, target_n, &z, 5e-3);
    assert_eq!(free.0.map(|(e, _)| e), general.0.map(|(e, _)| e));
    let (Some((_, t_free)), Some((_, t))) = (free.0, general.0) else {
        panic!("the part meets the plate again: {free:?} {general:?}");
    };
    assert!(t > 1e-4 && (t_free - t).abs() < 1e-15, "{t_free} vs {t}");
}

/// 8 ms of a 1.5 kg plate on an 18 Hz spring (whose chunks last up to 8.7 ms) with three of
/// the part's events.
fn three_events() -> (PlateParams, Case) {
    let params = lag_spring_plate();
    let case = Case {
        mu: 0.1,
        extra_static: 0.0,
        start: [0.0, 0.5, 0.0, -0.5, 0.0, 0.0],
        stuck: true,
        command_mps2: 146.0,
        duration_s: 8e-3,
    };
    (params, case)
}

/// Three of the part's events within one chunk: the course goes on in its chunk after each,
/// and agrees with the general solver.
#[test]
fn a_course_goes_on_in_its_chunk_after_the_part_s_events() {
    let (params, case) = three_events();
    let events = agree_through(params, case, &[]).expect("the solvers agree");
    assert_eq!(events, 3);
}

/// The same stretch cut into three segments of one target: the course goes on across their
/// ends, through the same three events.
#[test]
fn a_course_goes_on_across_segments_that_hold_the_target() {
    let (params, case) = three_events();
    let events = agree_through(params, case, &[0.3, 0.6]).expect("the solvers agree");
    assert_eq!(events, 3);
}

/// Slide friction and a current loop at one of the slide's own rates are left to the general
/// solver.
#[test]
fn only_a_free_slide_with_a_separable_current_loop_is_solved_in_closed_form() {
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let friction = PlateParams {
        coulomb_friction_n: 1.0,
        ..PlateParams::default()
    };
    assert!(FreeSolver::new(&PlateModel::new(friction, contact)).is_none());
    // M·ρ² − c·ρ + k = 0 at ρ = 2π·100 Hz with M = 1 kg and c = 2·M·ρ: k = M·ρ².
    let rho = 2.0 * std::f64::consts::PI * 100.0;
    let resonant = PlateParams {
        current_bandwidth_hz: Some(100.0),
        spring_npm: rho * rho,
        spring_damping_nspm: 2.0 * rho,
        ..PlateParams::default()
    };
    assert!(FreeSolver::new(&PlateModel::new(resonant, contact)).is_none());
    assert!(FreeSolver::new(&PlateModel::new(PlateParams::default(), contact)).is_some());
}
