//! NUCLEO-G474RE: clocks, pins, the output stage, the edge counter, the watchdog and the safe
//! state.
//!
//! | Signal                      | Pin  | Nucleo header |
//! |-----------------------------|------|---------------|
//! | analog command (DAC1 ch1)   | PA4  | A2            |
//! | PWM magnitude (TIM1 CH1)    | PA8  | D7            |
//! | direction (TIM1 CH2)        | PA9  | D8            |
//! | driver enable (high = on)   | PA10 | D2            |
//! | feed pulses (enable keeper) | PB5  | D4            |
//! | start/stop button B1        | PC13 | —             |
//! | status LED LD2              | PA5  | D13           |
//! | console TX (LPUART1)        | PA2  | ST-LINK VCP   |
//! | console RX (LPUART1)        | PA3  | ST-LINK VCP   |
//!
//! The operator's console runs on LPUART1 (115200 8N1), which the NUCLEO routes to the ST-LINK's
//! virtual COM port; recipes live in flash ([`recipes`]).
//!
//! Both output stages time every edge in hardware ([`segment_timer`]). DAC ([`dac`]): TIM2
//! (32 bits, 170 MHz) counts one segment; its update event loads the preloaded auto-reload (the
//! next length) and, through TRGO, makes the DAC latch the preloaded holding register (the next
//! code). PWM ([`pwm`], `--features output-pwm`): TIM1 runs the carrier and its repetition
//! counter counts the segment in carrier periods; the update event at the end of the repetitions
//! loads the preloaded compare values (duty and direction) and repetition count.
//!
//! The safe state is [`SAFE_STATE_WRITES`]. On a debugger halt the timers freeze (TIM1's outputs
//! then go inactive) and the independent watchdog, left running, resets the board; a core lockup
//! breaks TIM1. Every feed of the watchdog also toggles PB5, for an external retriggerable
//! monostable that keeps the driver enabled only while the feeds go on (`firmware/README.md`).

#[cfg(feature = "console")]
mod console;
#[cfg(not(feature = "output-pwm"))]
mod dac;
mod drill;
#[cfg(feature = "output-pwm")]
mod pwm;
#[cfg(feature = "console")]
mod recipes;
mod segment_timer;
mod setup;
mod watchdog;

use defmt_rtt as _;
use embassy_executor::SendSpawner;
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::gpio;
use embassy_stm32::mode::Async;

use crate::fault::RegisterWrite;

#[cfg(feature = "console")]
pub use console::{console_task, Console};
pub use setup::init;

pub type Output = Stage;
pub type DriverEnable = gpio::Output<'static>;
pub type Led = gpio::Output<'static>;
pub type Button = ExtiInput<'static, Async>;
pub type Watchdog = watchdog::OutputWatchdog;

/// The output stage this image drives: the DAC, or PWM + direction with `output-pwm`.
#[cfg(not(feature = "output-pwm"))]
type Stage = dac::DacStage;
#[cfg(feature = "output-pwm")]
type Stage = pwm::PwmStage;

/// The output stage's name in the log.
pub const OUTPUT_STAGE: &str = Stage::NAME;

/// Everything the application needs from the board.
pub struct Board {
    pub output: Output,
    pub driver_enable: DriverEnable,
    pub led: Led,
    pub button: Button,
    pub watchdog: Watchdog,
    /// The last reset was the independent watchdog's.
    pub after_watchdog_reset: bool,
    /// Spawner of the executor that runs the control loop above the other tasks.
    pub control_spawner: SendSpawner,
    /// The console's peripherals.
    #[cfg(feature = "console")]
    pub console: Console,
}

/// The stores that make the output safe, in order (see [`Stage::SAFE_STATE_WRITES`]).
pub static SAFE_STATE_WRITES: [RegisterWrite; Stage::SAFE_STATE_WRITES.len()] =
    Stage::SAFE_STATE_WRITES;

/// After a panic or HardFault, whose handler has made the safe state: interrupts off, so that no
/// handler (the control loop) runs again and undoes it, the safe state once more (the segment
/// timer stopped, its update interrupt off), then no more feeds: the independent watchdog
/// resets the board within its timeout, and the enable keeper drops the enable.
pub fn after_fault() -> ! {
    cortex_m::interrupt::disable();
    crate::fault::make_safe();
    loop {
        cortex_m::asm::wfi();
    }
}
