//! The real plate behind the firmware's lockstep link, fed by hand: DAC codes read back as
//! accelerations, held from their ticks, and encoder counts at the sample ticks.

use feeder_emulator::plant_link::Plant;
use feeder_shared::DacCalibration;
use host_sim::contact::Contact;
use host_sim::cosim::PlatePlant;
use host_sim::plate::{PlantFile, PlateParams};
use host_sim::sensors::{EncoderConfig, SensorsConfig};
use host_sim::SimError;

const TICK_HZ: u32 = 1_000_000;

fn plant(plate: PlateParams) -> PlantFile {
    PlantFile {
        plate,
        sensors: SensorsConfig {
            encoder: Some(EncoderConfig {
                resolution_m: 1e-6,
                index_m: None,
                reversed: false,
            }),
            ..SensorsConfig::default()
        },
    }
}

fn contact() -> Contact {
    Contact::kinetic(0.3, 1e-4).unwrap()
}

#[test]
fn a_held_level_moves_the_ideal_plate_as_the_code_says() {
    let dac = DacCalibration::DEFAULT;
    let mut plate =
        PlatePlant::new(&plant(PlateParams::default()), &contact(), dac, TICK_HZ).unwrap();
    // 800 counts above zero is 100 m/s² for 1 ms, then zero for 1 ms: 50 µm, then 100 µm more.
    plate.level(0, 2048 + 800);
    plate.enable(0, true);
    plate.level(1000, 2048);
    assert_eq!(plate.sample(1000), 50);
    assert_eq!(plate.sample(2000), 150);
    let samples = plate.samples();
    assert_eq!(samples.len(), 2);
    assert!((samples[1].position_m - 150e-6).abs() < 1e-15);
    assert!((samples[1].time_s - 2e-3).abs() < 1e-15);
}

#[test]
fn the_zero_code_lets_an_offset_plate_drift_by_half_e_t_squared() {
    let params = PlateParams {
        zero_offset_fraction: 0.005,
        ..PlateParams::default()
    };
    let e_mps2 = 0.005 * params.full_scale_accel_mps2;
    let mut plate =
        PlatePlant::new(&plant(params), &contact(), DacCalibration::DEFAULT, TICK_HZ).unwrap();
    plate.level(0, 2048);
    plate.enable(0, true);
    for k in 1..=20_u64 {
        let t_s = k as f64 * 1e-3;
        let expected = (0.5 * e_mps2 * t_s * t_s / 1e-6).floor() as i32;
        let count = plate.sample(k * 1000);
        assert!((count - expected).abs() <= 1, "{t_s}: {count} {expected}");
    }
}

#[test]
fn the_plate_stops_at_its_end_stop_and_says_when() {
    let params = PlateParams {
        end_stop_m: Some(1e-3),
        ..PlateParams::default()
    };
    let mut plate =
        PlatePlant::new(&plant(params), &contact(), DacCalibration::DEFAULT, TICK_HZ).unwrap();
    // 10 m/s² (80 counts) reaches 1 mm after √(2·1e-3/10) = 14.14 ms.
    plate.level(0, 2048 + 80);
    plate.enable(0, true);
    plate.sample(20_000);
    let stop = plate.end_stop().unwrap();
    assert!(
        (stop.time_s - (2e-3_f64 / 10.0).sqrt()).abs() < 1e-12,
        "{stop:?}"
    );
    assert_eq!(plate.sample(30_000), 1000);
}

/// The driver comes up disabled: until the firmware enables it no code moves the plate, its
/// offset included; from the enable's tick on the plate moves as the code says, and once
/// disabled again it coasts on at the velocity it had.
#[test]
fn a_disabled_driver_drives_nothing() {
    let params = PlateParams {
        zero_offset_fraction: 0.005,
        ..PlateParams::default()
    };
    let mut plate =
        PlatePlant::new(&plant(params), &contact(), DacCalibration::DEFAULT, TICK_HZ).unwrap();
    plate.level(0, 2048 + 800);
    assert_eq!(plate.sample(5_000), 0);
    plate.level(5_000, 2048 + 792);
    plate.enable(5_000, true);
    // 99 m/s² of code and 1 m/s² of offset for 1 ms: 50 µm.
    assert_eq!(plate.sample(6_000), 50);
    plate.enable(6_000, false);
    // At 0.1 m/s for 1 ms more: 100 µm further.
    assert_eq!(plate.sample(7_000), 150);
}

#[test]
fn a_plant_without_an_encoder_is_refused() {
    let file = PlantFile {
        plate: PlateParams::default(),
        sensors: SensorsConfig::default(),
    };
    assert!(matches!(
        PlatePlant::new(&file, &contact(), DacCalibration::DEFAULT, TICK_HZ),
        Err(SimError::MissingSensor { sensor: "encoder" })
    ));
}

/// Once the firmware has ended, the plate runs on with its drive as the firmware left it: off,
/// a plate moving at 0.1 m/s on a slide of 2 m/s² friction stops after `v/a` = 50 ms and
/// `v²/2a` = 2.5 mm further; without friction it is still moving when the time allowed is up.
#[test]
fn the_plate_runs_out_to_rest_once_the_firmware_has_ended() {
    let params = PlateParams {
        coulomb_friction_n: 2.0,
        ..PlateParams::default()
    };
    let mut plate =
        PlatePlant::new(&plant(params), &contact(), DacCalibration::DEFAULT, TICK_HZ).unwrap();
    // 100 m/s² (802 counts, 2 of them against the friction) for 1 ms: 0.1 m/s.
    plate.level(0, 2048 + 816);
    plate.enable(0, true);
    plate.level(1000, 2048);
    plate.enable(1000, false);
    let start = plate.last_state();
    let out = plate.run_out(2.0);
    assert_eq!(out.outcome, host_sim::cosim::RunOutcome::AtRest);
    assert!(!out.driver_enabled);
    let v = start.velocity_mps;
    assert!(
        (out.state.position_m - start.position_m - v * v / 4.0).abs() < 1e-6,
        "{out:?}"
    );
    assert!((out.after_s - v / 2.0).abs() <= 1e-3, "{out:?}");

    let mut free = PlatePlant::new(
        &plant(PlateParams::default()),
        &contact(),
        DacCalibration::DEFAULT,
        TICK_HZ,
    )
    .unwrap();
    free.level(0, 2048 + 80);
    free.enable(0, true);
    free.level(1000, 2048);
    free.enable(1000, false);
    let out = free.run_out(0.5);
    assert_eq!(out.outcome, host_sim::cosim::RunOutcome::StillMoving);
    assert!((out.state.velocity_mps - 0.01).abs() < 1e-12, "{out:?}");
}

/// The firmware's log of the course read back: the drive, the release and the last feed
/// compensation, whether the drive's range gives it or limits it.
#[test]
fn the_loop_log_reads_the_feed_compensation_the_firmware_logged() {
    use host_sim::cosim::{LoggedFeed, LoopLog};
    let log = "INFO  drive identified: gain + 1.02, gain − 0.98, offset 1.0 m/s², lag 0.00016 s\n\
               INFO  feed compensated: levels x1.0030 for the ideal plate's 125.44 mm/s behind the drive's lag\n\
               INFO  closed loop: Feeding at cycle 373\n\
               INFO  feed compensated: levels x1.0961, the most the drive's linear range allows: 154.44 mm/s instead of the ideal plate's 170.71 mm/s\n";
    let read = LoopLog::read(log);
    assert_eq!(read.identified, Some([1.02, 0.98, 1.0]));
    assert_eq!(read.feeding_cycle, Some(373));
    assert_eq!(
        read.feed,
        Some(LoggedFeed {
            amplitude: 1.0961,
            ideal_mps: 170.71e-3,
            limited_mps: Some(154.44e-3),
        })
    );
    let first = LoopLog::read(log.lines().take(2).collect::<Vec<_>>().join("\n").as_str());
    assert_eq!(
        first.feed,
        Some(LoggedFeed {
            amplitude: 1.003,
            ideal_mps: 125.44e-3,
            limited_mps: None,
        })
    );
}
