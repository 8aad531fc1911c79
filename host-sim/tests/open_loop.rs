//! What `host-sim drift` reports, against the plate's motion worked out by hand: a constant
//! offset adds `e·t²/2` to the ideal plate's position, and a current loop alone (DC gain 1)
//! leaves its mean position where the ideal plate's is.

use feeder_shared::{Drive, WaveformSpec};
use host_sim::contact::PAPER_PART_MASS_KG;
use host_sim::figures::{self, DriftCase};
use host_sim::plate::PlateRunOptions;
use host_sim::{Contact, OperatingPoint};

const CYCLES: u64 = 20;
const AVERAGE_CYCLES: u64 = 10;
const PERIOD_S: f64 = 0.02;

/// The paper's operating point on exact switching times, every case for [`CYCLES`] cycles.
fn drift() -> Vec<DriftCase> {
    let spec = WaveformSpec {
        period_s: PERIOD_S,
        duty: 0.586,
        drive: Drive::Stroke { stroke_m: 0.0025 },
    };
    let contact =
        Contact::new(1.0, 1.0, 9.80665, PAPER_PART_MASS_KG, 0.0).expect("the paper's contact");
    let point = OperatingPoint::new(spec, contact, None).expect("the paper's point");
    let options = PlateRunOptions {
        cycles: CYCLES,
        average_cycles: AVERAGE_CYCLES,
    };
    let cases = figures::open_loop_cases().expect("the cases");
    figures::open_loop_drift(&point, &cases, &options, false).expect("every case runs")
}

fn case<'a>(cases: &'a [DriftCase], name: &str) -> &'a DriftCase {
    cases
        .iter()
        .find(|case| case.name.starts_with(name))
        .expect("a case of that name")
}

#[test]
fn an_offset_alone_adds_half_e_t_squared_to_the_mean_position() {
    let cases = drift();
    let ideal = case(&cases, "none");
    let offset = case(&cases, "zero offset");
    assert_eq!(offset.cycles, CYCLES);
    // e = 0.5 % of 200 m/s²; the mean of e·t²/2 over the last cycles [t0, t1].
    let e_mps2 = 0.005 * 200.0;
    let t1_s = CYCLES as f64 * PERIOD_S;
    let t0_s = (CYCLES - AVERAGE_CYCLES) as f64 * PERIOD_S;
    let expected_m = e_mps2 * (t1_s.powi(3) - t0_s.powi(3)) / (6.0 * (t1_s - t0_s));
    let drift_m = offset.mean_position_m - ideal.mean_position_m;
    assert!(
        (drift_m / expected_m - 1.0).abs() < 1e-12,
        "{drift_m} m, expected {expected_m} m"
    );
}

#[test]
fn a_current_loop_alone_keeps_the_ideal_plate_s_mean_position() {
    let cases = drift();
    let ideal = case(&cases, "none");
    assert!((ideal.mean_position_m - 0.00125).abs() < 1e-5, "{ideal:?}");
    for name in ["current loop 1 kHz", "current loop 159 Hz"] {
        let lagging = case(&cases, name);
        assert!(
            (lagging.mean_position_m - ideal.mean_position_m).abs() < 1e-12,
            "{name}: {} m, ideal {} m",
            lagging.mean_position_m,
            ideal.mean_position_m
        );
        assert_ne!(lagging.feed_rate_mps, ideal.feed_rate_mps, "{name}");
        assert_eq!(lagging.end_stop, None);
    }
}
