//! The shared closed loop against the real plate of `realistic.toml`: identification, centring,
//! feed rate against the ideal plate's, a live plan change, and the refusals.

use std::path::Path;

use feeder_shared::closed_loop::{Cause, IdentifyError};
use feeder_shared::{Drive, Limits, TickClock, TickPlan, Waveform, WaveformSpec};
use host_sim::closed_loop::verdict::feed_rate_mps;
use host_sim::closed_loop::{run_closed_loop, ClosedLoopOptions, ClosedLoopRun};
use host_sim::contact::Contact;
use host_sim::plate::PlantFile;
use host_sim::{OperatingPoint, SimError};

const CLOCK_HZ: u32 = 1_000_000;

fn realistic() -> PlantFile {
    PlantFile::from_path(&Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/realistic.toml"))
        .unwrap()
}

fn spec(duty: f64) -> WaveformSpec {
    WaveformSpec::from_frequency(50.0, duty, Drive::Stroke { stroke_m: 2.5e-3 })
}

fn plan(duty: f64) -> TickPlan {
    let waveform = Waveform::new(spec(duty), &Limits::NONE).unwrap();
    TickPlan::new(&waveform, TickClock::new(CLOCK_HZ)).unwrap()
}

fn contact() -> Contact {
    Contact::kinetic(1.0, 1e-4).unwrap()
}

/// The ideal plate's steady feed rate on the same tick plan.
fn ideal_feed_rate_mps(duty: f64) -> f64 {
    OperatingPoint::new(spec(duty), contact(), Some(CLOCK_HZ))
        .unwrap()
        .steady()
        .feed_rate_mps
}

/// The worst `|mean position|` of a cycle from the release on, soft start included.
fn worst_mean_position_m(run: &ClosedLoopRun) -> f64 {
    run.fed()
        .iter()
        .map(|c| c.mean_position_m.abs())
        .fold(0.0, f64::max)
}

fn run(options: &ClosedLoopOptions) -> ClosedLoopRun {
    let plan = plan(0.586);
    let run = run_closed_loop(&realistic(), &contact(), plan, options).unwrap();
    assert_eq!(run.gave_up, None);
    run
}

#[test]
fn the_realistic_plate_is_identified_centred_and_feeds_as_the_ideal_one() {
    let run = run(&ClosedLoopOptions::new(400));
    let plant = realistic().plate;
    let identified = run.identified.unwrap();
    println!("{identified:?}");
    let gain_error = |found: f64, truth: f64| (found / truth - 1.0).abs();
    assert!(gain_error(identified.gain_positive, plant.gain_positive) < 0.01);
    assert!(gain_error(identified.gain_negative, plant.gain_negative) < 0.01);
    // At rest the slide's friction holds the plate against the offset; the probe's cycles tell
    // the two apart to about 7 %, which the loop's disturbance estimate takes up.
    let offset_mps2 = plant.zero_offset_fraction * plant.full_scale_accel_mps2;
    assert!((identified.offset_mps2 - offset_mps2).abs() < 0.1 * offset_mps2);
    assert_eq!(run.end_stop, None);
    let running: Vec<_> = run.cycles.iter().filter(|c| !c.centring).collect();
    // The release's cycle and the 400 after it.
    assert_eq!(running.len(), 401);
    let settled = &running[300..];
    let worst_m = settled
        .iter()
        .map(|c| c.mean_position_m.abs())
        .fold(0.0, f64::max);
    assert!(worst_m < 20e-6, "{worst_m}");
    println!("worst mean position {} m", worst_mean_position_m(&run));
    assert!(worst_mean_position_m(&run) < 50e-6);
    let ideal = ideal_feed_rate_mps(0.586);
    let feed_rate_mps = feed_rate_mps(&run.fed(), 50).unwrap();
    let difference = feed_rate_mps / ideal - 1.0;
    println!("feed rate {feed_rate_mps} m/s, ideal {ideal} m/s ({difference:+e})");
    assert!(difference.abs() < 0.01);
}

#[test]
fn a_live_duty_change_keeps_the_plate_centred() {
    let mut options = ClosedLoopOptions::new(500);
    options.plan_change = Some((200, plan(0.615)));
    let run = run(&options);
    assert_eq!(run.end_stop, None);
    let running: Vec<_> = run.cycles.iter().filter(|c| !c.centring).collect();
    let after = &running[200..];
    let worst_m = after
        .iter()
        .map(|c| c.mean_position_m.abs())
        .fold(0.0, f64::max);
    println!("worst mean position after the change {worst_m} m");
    assert!(worst_m < 50e-6, "{worst_m}");
    // Nearer saturation the feed rate is more sensitive to the waveform's shape, which the
    // slide's lag and friction round inside every segment where the loop's levels cannot reach:
    // the plate with only the 1 kHz current loop and the 5 N·s/m feeds 2.5 % below the ideal one
    // at d = 0.62 (whose 2.5 mm stroke the closed loop no longer takes: 173 m/s²).
    let ideal = ideal_feed_rate_mps(0.615);
    let feed_rate_mps = feed_rate_mps(&run.fed(), 50).unwrap();
    let difference = feed_rate_mps / ideal - 1.0;
    println!("feed rate at d = 0.615: {feed_rate_mps} m/s, ideal {ideal} m/s ({difference:+e})");
    assert!(difference.abs() < 0.05, "{difference}");
}

/// At d = 0.65 the 2.5 mm stroke needs 204 m/s²: with the room the loop keeps in the DAC's
/// linear range for the envelope's drives (at most 171.675 m/s² on the default DAC) the run is
/// refused before anything runs, the first plan and a live change alike, with both figures.
#[test]
fn a_plan_that_leaves_the_loop_no_room_is_refused_before_the_run() {
    let expected = |accel_mps2| {
        SimError::Shared(feeder_shared::Error::AccelAboveLoopRoom {
            accel_mps2,
            limit_mps2: 171.675,
            linear_mps2: 224.75,
        })
    };
    let beyond = plan(0.65);
    let accel_mps2 = beyond.waveform.accel_mps2;
    assert!((accel_mps2 - 204.08).abs() < 0.01, "{accel_mps2}");
    let options = ClosedLoopOptions::new(500);
    let refused = run_closed_loop(&realistic(), &contact(), beyond, &options);
    assert_eq!(refused.err(), Some(expected(accel_mps2)));
    let mut options = ClosedLoopOptions::new(500);
    options.plan_change = Some((100, beyond));
    let refused = run_closed_loop(&realistic(), &contact(), plan(0.586), &options);
    assert_eq!(refused.err(), Some(expected(accel_mps2)));
}

#[test]
fn the_closed_loop_is_deterministic() {
    let options = ClosedLoopOptions::new(100);
    assert_eq!(run(&options), run(&options));
}

#[test]
fn a_plant_without_an_encoder_or_with_a_reversed_one_is_refused() {
    let plan = plan(0.586);
    let mut plant = realistic();
    plant.sensors.encoder = None;
    assert!(matches!(
        run_closed_loop(&plant, &contact(), plan, &ClosedLoopOptions::new(10)),
        Err(SimError::MissingSensor { sensor: "encoder" })
    ));
    // A drive whose gains are far from 1 (a 2× weaker motor) fails identification by name.
    let mut weak = realistic();
    weak.plate.gain_positive = 0.5;
    weak.plate.gain_negative = 0.5;
    let refused = run_closed_loop(&weak, &contact(), plan, &ClosedLoopOptions::new(10)).unwrap();
    assert!(matches!(refused.gave_up, Some(SimError::Identification(_))));
    assert_eq!(refused.identified, None);
    assert_eq!(refused.release_cycle, None);
}

/// Drives other than the realistic one, each a slide with end stops: gains off by up to 3 % in
/// either direction, offsets of either sign (with the gains pushing the same way or against it),
/// friction from none to 2 N, a slower current loop. The loop identifies each, never lets the
/// plate reach a stop and, after the soft start, holds every cycle's mean within 50 µm of the
/// centre.
#[test]
fn the_loop_holds_other_drives_centred() {
    let base = realistic();
    let drives = [
        (1.03, 0.97, 0.005, 2.0, 1000.0),
        (0.97, 1.03, 0.005, 2.0, 1000.0),
        (1.0, 1.0, 0.002, 0.0, 1000.0),
        (1.03, 1.01, -0.003, 1.0, 1000.0),
        (0.98, 1.02, 0.004, 1.0, 500.0),
        (0.97, 1.03, -0.005, 2.0, 1000.0),
    ];
    for (gain_positive, gain_negative, zero_offset_fraction, coulomb_friction_n, bandwidth_hz) in
        drives
    {
        let mut plant = base.clone();
        plant.plate.gain_positive = gain_positive;
        plant.plate.gain_negative = gain_negative;
        plant.plate.zero_offset_fraction = zero_offset_fraction;
        plant.plate.coulomb_friction_n = coulomb_friction_n;
        plant.plate.current_bandwidth_hz = Some(bandwidth_hz);
        let plan = plan(0.586);
        let options = ClosedLoopOptions::new(300);
        let run = run_closed_loop(&plant, &contact(), plan, &options)
            .unwrap_or_else(|error| panic!("{:?}: {error}", plant.plate));
        assert_eq!(run.gave_up, None, "{:?}", plant.plate);
        assert_eq!(run.end_stop, None);
        let identified = run.identified.unwrap();
        let gain_error = |found: f64, truth: f64| (found / truth - 1.0).abs();
        assert!(gain_error(identified.gain_positive, gain_positive) < 0.01);
        assert!(gain_error(identified.gain_negative, gain_negative) < 0.01);
        let after = run
            .cycles
            .iter()
            .filter(|c| !c.centring)
            .skip(usize::from(options.ramp_cycles));
        let worst_m = after.map(|c| c.mean_position_m.abs()).fold(0.0, f64::max);
        println!(
            "{gain_positive}/{gain_negative}, e {zero_offset_fraction}, F_c {coulomb_friction_n} N, \
             f_c {bandwidth_hz} Hz: worst {:.1} µm in all, {:.1} µm after the soft start",
            worst_mean_position_m(&run) * 1e6,
            worst_m * 1e6
        );
        assert!(worst_m < 50e-6, "{worst_m}");
    }
}

/// The settle holds the plate from the first start: on `realistic.toml` the start-up, from
/// power-up to the release, stays within the 1 mm bound (0.49 mm, the probe's own stroke of
/// 0.75 mm peak to peak included), and the drive is off through the idle periods before the
/// start, so the plate stands where it rests until then.
#[test]
fn the_start_up_stays_within_its_bound() {
    let run = run(&ClosedLoopOptions::new(30));
    assert!(run.startup_peak_m < 1e-3, "{} m", run.startup_peak_m);
    let idle: Vec<_> = run.cycles.iter().take_while(|c| c.idle).collect();
    assert_eq!(idle.len(), 2);
    assert!(idle.iter().all(|c| c.peak_m <= 1e-6));
}

/// Runs `plant` and expects the loop to refuse it for `cause`: the refusal and the run.
fn refused(plant: &PlantFile, cause: Cause) -> (IdentifyError, ClosedLoopRun) {
    let run = run_closed_loop(plant, &contact(), plan(0.586), &ClosedLoopOptions::new(30)).unwrap();
    let Some(SimError::Identification(error)) = run.gave_up.clone() else {
        panic!("not refused: {:?}", run.gave_up);
    };
    assert_eq!(error.cause(), Some(cause), "{error}");
    assert!(run.identified.is_none());
    (error, run)
}

/// A drive whose zero offset lies beyond the envelope (8 m/s², twice its limit) is refused by
/// the settle, before the probe: by its cause, with the plate moved less than half a millimetre.
#[test]
fn an_offset_beyond_the_envelope_is_refused_before_the_probe() {
    for offset_fraction in [0.04, -0.04] {
        let mut plant = realistic();
        plant.plate.zero_offset_fraction = offset_fraction;
        let (_, run) = refused(&plant, Cause::Offset);
        assert!(run.peak_excursion_m < 0.5e-3, "{} m", run.peak_excursion_m);
        assert!(run.simulated_s < 0.3, "{} s", run.simulated_s);
    }
}

/// An encoder coarser than the envelope's 5 µm a count is refused by name before anything moves.
#[test]
fn a_sensor_coarser_than_the_envelope_is_refused_before_anything_moves() {
    let mut plant = realistic();
    if let Some(encoder) = plant.sensors.encoder.as_mut() {
        encoder.resolution_m = 8e-6;
    }
    let (error, run) = refused(&plant, Cause::Sensor);
    assert_eq!(
        error.to_string(),
        "the position sensor counts 8.00 µm, coarser than the 5.00 µm the loop reads: fit a \
         finer position sensor"
    );
    assert!(run.peak_excursion_m < 1e-6, "{} m", run.peak_excursion_m);
}

/// A current loop slower than the envelope's 150 Hz is refused by the identification, named as
/// the lag it is and not as the gains it rounds.
#[test]
fn a_current_loop_slower_than_the_envelope_is_refused_for_its_lag() {
    let mut plant = realistic();
    plant.plate.current_bandwidth_hz = Some(90.0);
    let (error, _) = refused(&plant, Cause::Lag);
    let IdentifyError::Lag { lag_s, .. } = error else {
        panic!("{error}");
    };
    let truth_s = 1.0 / (2.0 * std::f64::consts::PI * 90.0);
    assert!(
        (lag_s / truth_s - 1.0).abs() < 0.05,
        "{lag_s} s against {truth_s} s"
    );
    assert!(error
        .to_string()
        .contains("raise the drive's current-loop bandwidth"));
}

/// The feed's compensation on `realistic.toml` with a slow current loop and a draggy slide: at
/// 50 and 100 Hz, d = 0.53 and 0.61, the part feeds within 1 % of the ideal plate where the
/// drive's linear range allows the amplitude the model asks, and within 1 % of the feed the
/// course said it would give where it does not (a 150 Hz current loop at 100 Hz: the drive's
/// 200 m/s² full scale leaves 1.3 times the 140 m/s² levels, where d = 0.53 needs 1.31 and
/// d = 0.61 about 1.8).
/// At 100 Hz, d = 0.61 on the draggy slide the probe's four cycles read the drag 50 % high and a
/// spring that is not there, and the feed, nearest saturation of the four, is off by 2.3 %: the
/// test holds that point to 3 %.
#[test]
fn the_feed_is_compensated_for_the_drives_lag_and_the_slides_drag() {
    let point = |frequency_hz: f64, duty: f64| {
        let spec =
            WaveformSpec::from_frequency(frequency_hz, duty, Drive::Accel { accel_mps2: 140.0 });
        let waveform = Waveform::new(spec, &Limits::NONE).unwrap();
        let plan = TickPlan::new(&waveform, TickClock::new(CLOCK_HZ)).unwrap();
        let ideal = OperatingPoint::new(spec, contact(), Some(CLOCK_HZ))
            .unwrap()
            .steady()
            .feed_rate_mps;
        (plan, ideal)
    };
    for (bandwidth_hz, viscous_nspm) in [(150.0, 0.0), (100_000.0, 20.0)] {
        let mut plant = realistic();
        plant.plate.zero_offset_fraction = 0.0;
        plant.plate.gain_positive = 1.0;
        plant.plate.gain_negative = 1.0;
        plant.plate.coulomb_friction_n = 0.0;
        plant.plate.current_bandwidth_hz = Some(bandwidth_hz);
        plant.plate.viscous_friction_nspm = viscous_nspm;
        plant.plate.force_limit_n = None;
        for (frequency_hz, duty) in [(50.0, 0.53), (50.0, 0.61), (100.0, 0.53), (100.0, 0.61)] {
            let (plan, ideal_mps) = point(frequency_hz, duty);
            let run =
                run_closed_loop(&plant, &contact(), plan, &ClosedLoopOptions::new(200)).unwrap();
            let what =
                format!("{bandwidth_hz} Hz, {viscous_nspm} N·s/m at {frequency_hz} Hz, d = {duty}");
            assert_eq!(run.gave_up, None, "{what}");
            let found = run.feed.unwrap();
            let feed_mps = feed_rate_mps(&run.fed(), 50).unwrap();
            assert_eq!(
                found.limited,
                bandwidth_hz == 150.0 && frequency_hz == 100.0,
                "{what}: {found:?}"
            );
            let expected_mps = if found.limited {
                found.feed_mps
            } else {
                ideal_mps
            };
            println!(
                "{what}: ×{:.4}, feed {:.2} mm/s, expected {:.2} mm/s",
                found.amplitude,
                feed_mps * 1e3,
                expected_mps * 1e3
            );
            let tolerance = if viscous_nspm > 0.0 && (frequency_hz, duty) == (100.0, 0.61) {
                0.03
            } else {
                0.01
            };
            assert!(
                (feed_mps / expected_mps - 1.0).abs() < tolerance,
                "{what}: {feed_mps} vs {expected_mps}"
            );
        }
    }
}
