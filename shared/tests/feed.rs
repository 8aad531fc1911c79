//! The part's feed on a plate behind the drive's lag against independent expectations: the
//! paper's closed forms without a lag (Eq. 15 sliding, Eq. 18 saturated), the lag's limits, and
//! the amplitude that gives the ideal feed back.

use feeder_shared::closed_loop::{
    compensate, feed_rate_mps, CommandSegment, CycleShape, PlateModel,
};
use feeder_shared::{model, Drive, Friction, Limits, Waveform, WaveformSpec};
use proptest::prelude::*;

const MU_G: f64 = 0.3 * model::STANDARD_GRAVITY_MPS2;

fn cycle(frequency_hz: f64, duty: f64, accel_mps2: f64) -> (Waveform, Vec<CommandSegment>) {
    let spec = WaveformSpec::from_frequency(frequency_hz, duty, Drive::Accel { accel_mps2 });
    let waveform = Waveform::new(spec, &Limits::NONE).unwrap();
    let segments = CommandSegment::cycle_of(&waveform).to_vec();
    (waveform, segments)
}

fn lagged(lag_s: f64) -> PlateModel {
    PlateModel {
        lag_s,
        ..PlateModel::IDEAL
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Without a lag the plate is the paper's, and the feed its closed form: Eq. 15 while the
    /// part slides all cycle, Eq. 18 once it sticks on the plateau.
    #[test]
    fn without_a_lag_the_feed_is_the_papers(
        frequency_hz in 50.0..100.0f64,
        duty in 0.52..0.62f64,
        accel_mps2 in 60.0..180.0f64,
    ) {
        let (waveform, segments) = cycle(frequency_hz, duty, accel_mps2);
        let friction = Friction::new(0.3, model::STANDARD_GRAVITY_MPS2).unwrap();
        let expected = model::steady_state(&waveform, &friction).feed_rate_mps;
        let feed = feed_rate_mps(&segments, PlateModel::IDEAL, MU_G);
        prop_assert!((feed / expected - 1.0).abs() < 3e-4, "{feed} vs {expected}");
    }

    /// The amplitude found gives the ideal feed back wherever it is within its limit, and says
    /// so where it is not.
    #[test]
    fn the_compensated_amplitude_gives_the_ideal_feed(
        frequency_hz in 50.0..100.0f64,
        duty in 0.52..0.62f64,
        bandwidth_hz in 150.0..2000.0f64,
    ) {
        let (_, segments) = cycle(frequency_hz, duty, 140.0);
        let lag_s = 1.0 / (2.0 * core::f64::consts::PI * bandwidth_hz);
        let model = lagged(lag_s);
        let found = compensate(&segments, model, MU_G, 1.4);
        let scaled: Vec<_> = segments
            .iter()
            .map(|s| CommandSegment { accel_mps2: s.accel_mps2 * found.amplitude, ..*s })
            .collect();
        let feed = feed_rate_mps(&scaled, model, MU_G);
        prop_assert!((feed - found.feed_mps).abs() < 1e-9);
        prop_assert!((found.ideal_mps / feed_rate_mps(&segments, PlateModel::IDEAL, MU_G) - 1.0).abs() < 1e-12);
        if found.limited {
            prop_assert!(found.amplitude == 1.4 || found.amplitude == 1.0 / 1.4);
            prop_assert!((feed / found.ideal_mps - 1.0).abs() > 1e-3);
        } else {
            prop_assert!((feed / found.ideal_mps - 1.0).abs() < 2e-3, "{found:?}");
        }
    }
}

/// A lag far shorter than the cycle changes nothing; the slower the current loop, the less the
/// feed (the lag rounds the profile's corners).
#[test]
fn a_slower_current_loop_feeds_less() {
    let (_, segments) = cycle(100.0, 0.53, 140.0);
    let ideal = feed_rate_mps(&segments, PlateModel::IDEAL, MU_G);
    let tiny = feed_rate_mps(&segments, lagged(1e-7), MU_G);
    assert!((tiny / ideal - 1.0).abs() < 1e-4, "{tiny} vs {ideal}");
    let mut previous = ideal;
    for bandwidth_hz in [2000.0, 1000.0, 500.0, 300.0, 150.0] {
        let lag_s = 1.0 / (2.0 * core::f64::consts::PI * bandwidth_hz);
        let feed = feed_rate_mps(&segments, lagged(lag_s), MU_G);
        assert!(
            feed < previous,
            "{bandwidth_hz} Hz: {feed} after {previous}"
        );
        previous = feed;
    }
    assert!(previous < 0.9 * ideal);
}

/// The stroke a lagged plate shows between `τ` after the start and `τ` after the turn, and its
/// mean about the start, against a fine integration of `τ·ȧ + a = u` run until its motion
/// repeats.
#[test]
fn the_stroke_behind_the_lag_is_the_integrated_ones() {
    let cases = [
        (50.0, 0.53, 150.0),
        (100.0, 0.61, 150.0),
        (75.0, 0.58, 600.0),
        (50.0, 0.53, 2000.0),
    ];
    for (frequency_hz, duty, bandwidth_hz) in cases {
        let (_, segments) = cycle(frequency_hz, duty, 140.0);
        let lag_s = 1.0 / (2.0 * core::f64::consts::PI * bandwidth_hz);
        let shape = CycleShape::new(&segments)
            .unwrap()
            .behind_lag(&segments, lag_s);
        let steps = 200_000;
        let dt = shape.period_s / steps as f64;
        let command = |t: f64| {
            let mut end = 0.0;
            for s in &segments {
                end += s.duration_s;
                if t < end {
                    return s.accel_mps2;
                }
            }
            segments[segments.len() - 1].accel_mps2
        };
        let (mut a, mut v, mut x) = (0.0, 0.0, 0.0);
        let (mut at_start, mut at_turn) = (0.0, 0.0);
        let (mut start_x, mut area) = (0.0, 0.0);
        for cycle in 0..30 {
            if cycle == 29 {
                start_x = x;
            }
            for k in 0..steps {
                let t = (k as f64 + 0.5) * dt;
                let u = command(t);
                let a_next = u + (a - u) * (-dt / lag_s).exp();
                v += (a + a_next) / 2.0 * dt;
                x += v * dt;
                a = a_next;
                if cycle == 29 {
                    area += x * dt;
                    let t_end = (k + 1) as f64 * dt;
                    if (t_end - lag_s).abs() < dt / 2.0 {
                        at_start = x;
                    }
                    if (t_end - shape.turn_s - lag_s).abs() < dt / 2.0 {
                        at_turn = x;
                    }
                }
            }
        }
        // About the start, the integration's drift (its velocity's mean) taken out, as the
        // loop's centring takes it out.
        let mean_about_start = area / shape.period_s - start_x - (x - start_x) / 2.0;
        assert!(
            (mean_about_start - shape.mean_m).abs() < 2e-8,
            "{frequency_hz} Hz, d = {duty}: mean {mean_about_start} vs {}",
            shape.mean_m
        );
        let stroke = at_turn - at_start;
        assert!(
            (stroke - shape.latched_stroke_m).abs() < 2e-8,
            "{frequency_hz} Hz, d = {duty}: {stroke} vs {}",
            shape.latched_stroke_m
        );
        // Where the lag settles within every segment, the paper's cycle loses `a·τ²`.
        if segments.iter().all(|s| s.duration_s > 8.0 * lag_s) {
            let loss = shape.stroke_m - shape.latched_stroke_m;
            assert!(
                (loss / (140.0 * lag_s * lag_s) - 1.0).abs() < 0.01,
                "{loss}"
            );
        }
    }
}
