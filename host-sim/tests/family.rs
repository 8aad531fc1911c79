//! The plant family: its members lie where the envelope says, each outside member past exactly
//! the limit its cause names, and a seed gives the same family every time.

use feeder_shared::closed_loop::{Cause, ENVELOPE};
use host_sim::closed_loop::family::{members, run_member, Member, POINTS};
use host_sim::plate::PlateParams;

const INSIDE: usize = 300;
const OUTSIDE: usize = 60;

/// Which of the envelope's limits `plant` passes.
fn beyond(member: &Member) -> Vec<Cause> {
    let e = ENVELOPE;
    let p: &PlateParams = &member.plant.plate;
    let resolution_m = member
        .plant
        .sensors
        .encoder
        .expect("an encoder")
        .resolution_m;
    let mut causes = Vec::new();
    if p.spring_npm > e.spring_max_npm {
        causes.push(Cause::Spring);
    }
    if p.coulomb_friction_n > e.coulomb_max_n {
        causes.push(Cause::Friction);
    }
    if p.zero_offset_fraction.abs() > e.zero_offset_fraction_max {
        causes.push(Cause::Offset);
    }
    let gains = e.gain_min..=e.gain_max;
    if !gains.contains(&p.gain_positive) || !gains.contains(&p.gain_negative) {
        causes.push(Cause::Gain);
    }
    if p.current_bandwidth_hz
        .is_some_and(|hz| hz < e.current_bandwidth_min_hz)
    {
        causes.push(Cause::Lag);
    }
    if resolution_m > e.resolution_max_m {
        causes.push(Cause::Sensor);
    }
    causes
}

#[test]
fn inside_members_keep_every_limit_and_outside_ones_break_exactly_their_own() {
    let family = members(7, INSIDE, OUTSIDE);
    assert_eq!(family.len(), INSIDE + OUTSIDE);
    let e = ENVELOPE;
    for member in &family {
        let p = &member.plant.plate;
        p.validate().unwrap();
        assert!((e.mass_min_kg..=e.mass_max_kg).contains(&p.mass_kg));
        assert!(p.viscous_friction_nspm <= e.viscous_max_nspm);
        assert!(p.end_stop_m.is_some_and(|stop| stop >= e.end_stop_min_m));
        assert_eq!(
            beyond(member),
            member.outside.into_iter().collect::<Vec<_>>(),
            "{member:?}"
        );
    }
    // The outside members take the causes in turn, each as often as the others.
    for cause in Cause::ALL {
        let count = family.iter().filter(|m| m.outside == Some(cause)).count();
        assert_eq!(count, OUTSIDE / Cause::ALL.len(), "{cause:?}");
    }
    // Half the inside members, give or take, sit on a flexure.
    let sprung = family[..INSIDE]
        .iter()
        .filter(|m| m.plant.plate.spring_npm > 0.0)
        .count();
    assert!((INSIDE / 3..2 * INSIDE / 3).contains(&sprung), "{sprung}");
}

#[test]
fn a_seed_gives_the_same_family_and_a_member_does_not_depend_on_the_size() {
    let small = members(11, 20, 6);
    let large = members(11, 20, 12);
    assert_eq!(small, members(11, 20, 6));
    assert_eq!(small[..26], large[..26]);
    assert_ne!(small, members(12, 20, 6));
}

/// A member's run is judged by the one verdict: its outcome is the verdict's, with the start-up
/// bound added, and the same member gives the same run.
#[test]
fn a_member_run_is_deterministic_and_judged_by_the_verdict() {
    let member = &members(3, 1, 0)[0];
    let first = run_member(member, POINTS[0]).unwrap();
    assert_eq!(first, run_member(member, POINTS[0]).unwrap());
    let verdict = &first.verdict;
    assert_eq!(
        first.passed,
        verdict.passed && verdict.startup_peak_m <= verdict.startup_limit_m
    );
    assert!(!first.refused_by_cause);
}

/// A fixed sample of the family (seed 1: 12 plants inside, 6 outside, one of each cause, at
/// every operating point) keeps the outcomes in `tests/expected/family-sample.txt`: a change to
/// the loop that holds a plant more or fewer shows there, and `cargo xtask bless` writes it anew.
#[test]
fn a_fixed_sample_of_the_family_keeps_its_expected_outcomes() {
    let mut lines = String::new();
    for member in members(1, 12, 6) {
        for point in POINTS {
            let run = run_member(&member, point).unwrap();
            lines.push_str(&run.line());
            lines.push('\n');
        }
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/expected/family-sample.txt");
    if std::env::var_os("FEEDER_BLESS").is_some_and(|value| value == "overwrite") {
        std::fs::write(&path, &lines).expect("the expected file is writable");
        return;
    }
    let expected = std::fs::read_to_string(&path).expect("the expected file exists");
    for (number, (expected, actual)) in expected.lines().zip(lines.lines()).enumerate() {
        assert_eq!(
            expected,
            actual,
            "{} differs at line {} (if the change is intended, run `cargo xtask bless` and \
             review the diff)",
            path.display(),
            number + 1
        );
    }
    assert_eq!(expected.lines().count(), lines.lines().count());
}
