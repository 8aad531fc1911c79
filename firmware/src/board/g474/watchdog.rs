//! The independent watchdog and the feed pulses on PB5 for the external enable keeper.

use embassy_stm32::gpio::{self, Level, Speed};
use embassy_stm32::peripherals::{IWDG, PB5};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;

use super::segment_timer;
use crate::ports::Watchdog;

/// Independent watchdog timeout: what the plate affords.
///
/// A processor that stops leaves the output holding a level (the DAC keeps its code, TIM2 replays
/// the last preloaded segment). At the default operating point (50 Hz, d = 0.586, 2.5 mm stroke,
/// a = 145.9 m/s²) the plate passes mid-stroke at 0.60 m/s while −a is commanded; held there, it
/// reaches an end stop, 2.5 mm away (`LIMITS.max_stroke_m` = 5 mm peak to peak), after 3.0 ms
/// (2.5 mm = 0.60 m/s · t + ½ · 145.9 m/s² · t²); from a turning point, 1.25 mm short of the stop,
/// after 4.1 ms. Half of the 3.0 ms is the firmware's: the rest is left to the driver (its
/// disable response, the motor current's decay), which the bring-up checklist measures. The IWDG
/// counts LSI / 4, 125 µs a count at 32 kHz (RM0440, IWDG, prescaler 4, the shortest), but the
/// LSI may run as slow as 29.5 kHz (DS12288, "LSI oscillator characteristics"), 135.6 µs a
/// count: 1.5 ms allows 11 counts. `IndependentWatchdog::new` rounds a timeout down to whole
/// counts and is exact for multiples of 500 µs, so 1.0 ms: a reload of 8 counts. A feed reloads
/// the count but not the prescaler, whose phase runs on from the start, so the reset comes 7 to
/// 8 counts after the last feed: from 0.82 ms (7 counts at the fastest LSI, 34 kHz) to 1.09 ms
/// (8 at the slowest); 0.875–1.0 ms at the nominal 32 kHz, as the G474 twin shows. Larger strokes
/// leave less room, none at 5 mm: there only the end stops help.
pub const WATCHDOG_TIMEOUT_US: u32 = 1_000;

/// The independent watchdog, fed only while the output plays what the control loop preloaded,
/// and the feed pulses on PB5: every feed toggles it, for an external retriggerable monostable
/// that keeps the driver enabled only while the pulses go on (`firmware/README.md`).
pub struct OutputWatchdog {
    iwdg: IndependentWatchdog<'static, IWDG>,
    feed_pulses: gpio::Output<'static>,
}

impl OutputWatchdog {
    /// Starts the watchdog. Its first period counts down from the reset value 0xFFF (512 ms at
    /// LSI/4, RM0440, IWDG, "Independent watchdog functional description"), which covers the rest
    /// of the start-up; every feed then reloads the configured timeout.
    pub fn start(iwdg: Peri<'static, IWDG>, feed_pulses: Peri<'static, PB5>) -> Self {
        let mut watchdog = Self {
            iwdg: IndependentWatchdog::new(iwdg, WATCHDOG_TIMEOUT_US),
            feed_pulses: gpio::Output::new(feed_pulses, Level::Low, Speed::Low),
        };
        watchdog.iwdg.unleash();
        watchdog
    }
}

impl Watchdog for OutputWatchdog {
    /// A quarter of the timeout: the monitor shares the control executor, so a check may wait for
    /// the control loop's work at an edge (at most about 94 µs), and one feed withheld for a
    /// replayed segment still leaves a feed in time, even with the reset at its earliest (7
    /// counts at the fastest LSI, 0.82 ms).
    const MONITOR_PERIOD_US: u64 = WATCHDOG_TIMEOUT_US as u64 / 4;
    /// A recipe write blocks the tasks' executor for tens of milliseconds, far longer than the
    /// timeout.
    const WATCHES_TASKS: bool = true;

    /// Feeds unless the output replays a segment.
    fn feed(&mut self) -> bool {
        if segment_timer::replaying() {
            return false;
        }
        self.iwdg.pet();
        self.feed_pulses.toggle();
        true
    }
}
