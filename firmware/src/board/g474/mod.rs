//! NUCLEO-G474RE: clocks, pins, the output stage, the edge counter, the watchdog and the safe
//! state.
//!
//! | Signal                      | Pin  | Nucleo header   |
//! |-----------------------------|------|-----------------|
//! | analog command (DAC1 ch1)   | PA4  | A2              |
//! | PWM magnitude (TIM1 CH1)    | PA8  | D7              |
//! | direction (TIM1 CH2)        | PA9  | D8              |
//! | driver enable (high = on)   | PA10 | D2              |
//! | feed pulses (enable keeper) | PB5  | D4              |
//! | start/stop button B1        | PC13 | —               |
//! | status LED LD2              | PA5  | D13             |
//! | console TX (LPUART1)        | PA2  | ST-LINK VCP     |
//! | console RX (LPUART1)        | PA3  | ST-LINK VCP     |
//! | encoder A (TIM4 CH1)        | PB6  | D10             |
//! | encoder B (TIM4 CH2)        | PB7  | CN7 pin 21      |
//! | light barrier (part sensor) | PB10 | D6              |
//! | Modbus TX (USART1, RS-485)  | PC4  | D1, CN10 pin 34 |
//! | Modbus RX (USART1, RS-485)  | PC5  | D0, CN10 pin 6  |
//! | Modbus driver enable (DE)   | PA12 | CN10 pin 12     |
//! | release input               | PC0  | A5, CN7 pin 38  |
//! | recipe select bit 0 input   | PC2  | CN7 pin 35      |
//! | recipe select bit 1 input   | PC3  | CN7 pin 37      |
//! | ready output                | PC6  | CN10 pin 4      |
//! | fault output                | PC8  | CN10 pin 2      |
//!
//! The operator's console runs on LPUART1 (115200 8N1), which the NUCLEO routes to the ST-LINK's
//! virtual COM port; the configuration and the recipes live in flash ([`flash_store`]). Beside
//! it the console image serves the production line (`docs/production-line.md`): a Modbus RTU
//! slave on USART1 to an RS-485 transceiver, whose driver enable is the UART's own (DE on PA12),
//! at the configuration's rate and parity (8E1, or 8N2), and the discrete lines, plain inputs
//! with pull-downs and push-pull outputs, low from power-up until the task sets them.
//!
//! With `--features encoder` the closed loop runs on a quadrature encoder on TIM4, sampled by DMA
//! on TIM6 and on the segment timer's update (`encoder`); TIM6 and DMA1 channels 1 and 2 are then
//! taken, and the application's tasks run on an interrupt executor (UART5's vector) so that thread
//! mode is left to the drive's identification.
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

#[cfg(not(feature = "output-pwm"))]
mod dac;
mod drill;
#[cfg(feature = "encoder")]
mod encoder;
mod flash_store;
mod light_barrier;
#[cfg(feature = "console")]
#[path = "console.rs"]
mod operator;
#[cfg(not(feature = "console"))]
#[path = "button_only.rs"]
mod operator;
mod pins;
#[cfg(feature = "output-pwm")]
mod pwm;
mod segment_timer;
mod setup;
mod watchdog;

// NMI, and every exception and interrupt without a handler of its own, take the HardFault entry
// (`crate::fault`): the safe state's stores before anything touches the stack, then the log
// names the exception. cortex-m-rt would otherwise send them to a `DefaultHandler` that spins
// with the output as it was.
core::arch::global_asm!(
    ".global NonMaskableInt",
    ".thumb_set NonMaskableInt, HardFault",
    ".global DefaultHandler",
    ".thumb_set DefaultHandler, HardFault",
);

use defmt_rtt as _;
use embassy_executor::{Executor, SendSpawner};
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::gpio;
use embassy_stm32::mode::Async;

use crate::ports::{self, Board, Parts, RegisterWrite};

/// The output stage this image drives: the DAC, or PWM + direction with `output-pwm`.
#[cfg(not(feature = "output-pwm"))]
type Stage = dac::DacStage;
#[cfg(feature = "output-pwm")]
type Stage = pwm::PwmStage;

/// The timer whose update event begins every segment of [`Stage`].
#[cfg(all(feature = "encoder", not(feature = "output-pwm")))]
type SegmentTimerPeri = embassy_stm32::peripherals::TIM2;
#[cfg(all(feature = "encoder", feature = "output-pwm"))]
type SegmentTimerPeri = embassy_stm32::peripherals::TIM1;

/// The plate's position sensor: the quadrature encoder with `encoder`, none without (open loop).
#[cfg(feature = "encoder")]
type Sensor = encoder::Encoder;
#[cfg(not(feature = "encoder"))]
type Sensor = ports::NoSensor;

/// The NUCLEO-G474RE's parts.
pub enum Hardware {}

impl Parts for Hardware {
    type Output = Stage;
    type DriverEnable = gpio::Output<'static>;
    type Led = gpio::Output<'static>;
    type Button = ExtiInput<'static, Async>;
    type Watchdog = watchdog::OutputWatchdog;
    type Operator = operator::Operator;
    type Sensor = Sensor;
    type PartSensor = light_barrier::LightBarrier;
}

/// The stores that make the output safe, in order (see [`Stage::SAFE_STATE_WRITES`]).
pub static SAFE_STATE_WRITES: [RegisterWrite; Stage::SAFE_STATE_WRITES.len()] =
    Stage::SAFE_STATE_WRITES;

/// Brings the board up with the output at zero and the driver disabled, hands it to `app`, which
/// spawns its tasks, and runs the thread-mode executor.
pub fn run(app: fn(SendSpawner, Board<Hardware>)) -> ! {
    let mut executor = Executor::new();
    // SAFETY: `run` never returns, so its frame, and the executor in it, lives for good.
    let executor: &'static mut Executor = unsafe { &mut *core::ptr::addr_of_mut!(executor) };
    executor.run(|spawner| {
        let (spawner, board) = setup::init(spawner.make_send());
        app(spawner, board)
    })
}

/// After every feed of the watchdog by the monitor: the fault drill built in, once it is due.
pub fn after_feed() {
    drill::provoke_when_due();
}

/// Logs the image's output stage.
pub fn announce() {
    defmt::info!("feeder firmware up: output {=str}, stopped", Stage::NAME);
}

/// After a panic or HardFault, whose handler has made the safe state: interrupts off, so that no
/// handler (the control loop) runs again and undoes it, the safe state once more (the segment
/// timer stopped, its update interrupt off), then no more feeds: the independent watchdog
/// resets the board within its timeout, and the enable keeper drops the enable.
pub fn after_fault() -> ! {
    cortex_m::interrupt::disable();
    ports::write_all(&SAFE_STATE_WRITES);
    loop {
        cortex_m::asm::wfi();
    }
}
