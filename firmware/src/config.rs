//! Default parameters of the feeder, in one place. Units are in the names.

use feeder_shared::drive::MACHINE_LIMITS;
use feeder_shared::{DacCalibration, Limits, Settings, WaveformSpec};

/// The operator's settings at power-up: shared's defaults ([`Settings::DEFAULT`]), which a console
/// `set` or `recipe load` replaces.
pub const SETTINGS: Settings = Settings::DEFAULT;

/// Waveform at power-up, from [`SETTINGS`].
pub const WAVEFORM: WaveformSpec = SETTINGS.spec();

/// Cycles over which soft start and soft stop ramp the amplitude at power-up, from [`SETTINGS`].
pub const RAMP_CYCLES: u16 = SETTINGS.ramp_cycles;

/// What this machine can do ([`MACHINE_LIMITS`], which the host simulator holds its runs to
/// too); every waveform is validated against it.
pub const LIMITS: Limits = MACHINE_LIMITS;

/// Coulomb friction between the plate and the parts (`Friction::CONFIGURED`, μ = 0.3): the
/// feed-rate model behind `status` and `set feed` on the console, and the closed loop's
/// compensation of the feed.
pub const FRICTION: feeder_shared::Friction = feeder_shared::Friction::CONFIGURED;

/// Track control (`ports::PartSensor`): the barrier blocked for 0.5 s without a break means the
/// track is full and the feeder pauses; clear for 1 s, the track has room and it feeds again.
pub const TRACK: feeder_shared::closed_loop::TrackConfig =
    feeder_shared::closed_loop::TrackConfig {
        full_after_s: 0.5,
        empty_after_s: 1.0,
    };

/// Calibration of the analog driver input (see [`DacCalibration::DEFAULT`]).
pub const DAC: DacCalibration = DacCalibration::DEFAULT;

// No level the machine's limits allow leaves the DAC's linear range.
const _: () = assert!(LIMITS.max_accel_mps2 <= DAC.linear_limit_mps2());

/// In a build with the encoder, where the closed loop runs, the peak acceleration the DAC's linear
/// range reaches: every waveform must leave the loop its room below it
/// (`Machine::loop_linear_mps2`).
pub const LOOP_LINEAR_MPS2: Option<f64> = if cfg!(feature = "encoder") {
    Some(DAC.linear_limit_mps2())
} else {
    None
};

/// Calibration of the PWM driver input (see `PwmCalibration::DEFAULT`).
#[cfg(feature = "output-pwm")]
pub const PWM: feeder_shared::PwmCalibration = feeder_shared::PwmCalibration::DEFAULT;

/// PWM carrier frequency; it is also the tick clock of the segments in PWM mode.
#[cfg(feature = "output-pwm")]
pub const PWM_FREQUENCY_HZ: u32 = 20_000;

/// The longest the control loop may go without a beat before the monitor stops feeding the
/// watchdog: twice the longest segment it waits for, an idle period at the lowest frequency
/// (rounded up to whole monitor periods).
pub const CONTROL_PROGRESS_WINDOW_US: u64 = (2.0e6 / LIMITS.min_frequency_hz) as u64;

/// How often the control loop beats while parked (invalid settings): well within the window.
pub const PARK_HEARTBEAT_MS: u64 = 10;

/// How often thread mode (button, LED, console) beats for the monitor, where the monitor watches
/// it (see `ports::Watchdog::WATCHES_THREAD_MODE`).
pub const THREAD_HEARTBEAT_MS: u64 = 50;

/// The longest thread mode may go without a beat: a recipe write blocks it for a page erase and
/// 256 double-word writes (about 22 + 21 ms, at most 48 ms, DS12288 "Flash memory
/// characteristics"), plus a beat period, with room to spare.
pub const THREAD_PROGRESS_WINDOW_US: u64 = 200_000;

/// How often the monitor logs the CPU cost of the edges.
pub const REPORT_PERIOD_US: u64 = 1_000_000;

/// Button contacts settle within this time.
pub const DEBOUNCE_MS: u64 = 20;

/// Half period of the LED blink that signals a fault.
pub const BLINK_HALF_PERIOD_MS: u64 = 250;
