//! Default parameters of the feeder, in one place. Units are in the names.

use feeder_shared::configuration::{Configuration, OutputKind};

/// The compiled defaults of every per-machine setting: shared's
/// ([`Configuration::DEFAULT`]), with the closed loop on where the image has the encoder. The
/// board runs the configuration saved on it instead (`crate::configured`), which the console's
/// `config` commands edit; `config defaults` comes back to these.
pub const CONFIGURATION: Configuration = Configuration {
    closed_loop: cfg!(feature = "encoder"),
    ..Configuration::DEFAULT
};

/// The output stage this image drives.
pub const OUTPUT: OutputKind = if cfg!(feature = "output-pwm") {
    OutputKind::Pwm
} else {
    OutputKind::Dac
};

// No level the default limits allow leaves the default output's linear range.
const _: () =
    assert!(CONFIGURATION.limits.max_accel_mps2 <= CONFIGURATION.linear_limit_mps2(OUTPUT));

/// PWM carrier frequency; it is also the tick clock of the segments in PWM mode.
#[cfg(feature = "output-pwm")]
pub const PWM_FREQUENCY_HZ: u32 = 20_000;

/// The longest the control loop may go without a beat before the monitor stops feeding the
/// watchdog on a machine whose lowest frequency is `min_frequency_hz`: twice the longest segment
/// it waits for, an idle period at that frequency (rounded up to whole monitor periods).
pub fn control_progress_window_us(min_frequency_hz: f64) -> u64 {
    (2.0e6 / min_frequency_hz) as u64
}

/// How often the control loop beats while parked (invalid settings): well within the window.
pub const PARK_HEARTBEAT_MS: u64 = 10;

/// How often the tasks' executor (button, LED, console: thread mode, or with a position sensor
/// the task executor) beats for the monitor, where the monitor watches it (see
/// `ports::Watchdog::WATCHES_TASKS`).
pub const TASKS_HEARTBEAT_MS: u64 = 50;

/// The longest the tasks' executor may go without a beat: a recipe write blocks it for a page
/// erase and 256 double-word writes (about 22 + 21 ms, at most 48 ms, DS12288 "Flash memory
/// characteristics"), plus a beat period, with room to spare.
pub const TASKS_PROGRESS_WINDOW_US: u64 = 200_000;

/// How often the monitor logs the CPU cost of the edges.
pub const REPORT_PERIOD_US: u64 = 1_000_000;

/// Button contacts settle within this time.
pub const DEBOUNCE_MS: u64 = 20;

/// Half period of the LED blink that signals a fault.
pub const BLINK_HALF_PERIOD_MS: u64 = 250;
