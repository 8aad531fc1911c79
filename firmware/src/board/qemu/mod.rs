//! QEMU `-machine mps2-an386` (Cortex-M4F at 25 MHz): the same application as on the board, with
//! an output stage that reports every level change instead of driving a DAC.
//!
//! * Time: an embassy-time driver on the CMSDK APB timers ([`time_driver`]), 1 µs ticks, which
//!   the scheduler plans in. The output stage ([`output`]) keeps TIM2's semantics on that clock:
//!   every level takes effect on its planned tick, whatever the software's latency, and a segment
//!   preloaded after its deadline is a missed edge, as on the board. It reports each segment's
//!   preload slack and measures the work per edge on the 25 MHz timer ([`edge_work`]: 40 ns,
//!   which `-icount shift=4` makes 2.5 instructions).
//! * Operator: a script read from the semihosting command line (`script`) instead of B1; with
//!   the `console` feature, the serial console on UART0 and the Modbus port on UART1
//!   (`console`, `uart`, QEMU's first and second `-serial`) instead, with recipes kept in RAM: the feeder waits, stopped, for commands and the emulation
//!   runs until QEMU is ended. The script's image contains no console, so its run (and its `EVT`
//!   stream) does not depend on the console's code.
//! * Executors: all tasks run on four interrupt executors (the control loop above the closed
//!   loop's course above the other tasks above the background's long computations) and thread
//!   mode spins (the operator's `idle`, where a script also provokes its thread-mode faults).
//!   QEMU executes `wfe` as a no-op, so embassy's thread executor would spin instead of letting
//!   `-icount` skip idle time.
//! * Output registers: the stage's model keeps its state in three words of the machine's FPGA
//!   block RAM ([`OUTPUT_CODE`], [`OUTPUT_RUN`], [`DRIVER_ENABLE`]), which the image links nothing
//!   into: fixed addresses, as a peripheral's are, so that the fault stores
//!   ([`SAFE_STATE_WRITES`]) can name them, and the model honours what they hold.
//! * Logs: defmt over semihosting; the run ends with a semihosting exit code, non-zero after a
//!   panic or fault, which first reports the output's state from those registers ([`exit`]).
//! * Plant link (feature `cosim`): `plant_link` opens two FIFOs in QEMU's working directory
//!   with semihosting file calls; the output stage sends a plant simulated on the host every
//!   level it applies (tick and DAC code) and, at every cycle start, waits for the plant's
//!   sample (an encoder count) and logs it (`plant: cycle … tick=… count=…`). QEMU executes no
//!   instruction while the call waits, so under `-icount` the firmware's time stands still while
//!   the host computes and a run is byte-identical however long the plant takes
//!   (`tests/tests/cosim.rs`). A host that goes away ends the run like a fault: the output at
//!   zero, the driver disabled, the error logged, a failure exit code.
//!   `feeder_emulator::plant_link` is the host's end.

mod edge_work;
#[cfg(feature = "encoder")]
mod encoder;
mod exit;
#[cfg(feature = "console")]
mod file_store;
#[cfg(not(feature = "console"))]
#[path = "script/mod.rs"]
mod operator;
#[cfg(feature = "console")]
#[path = "console.rs"]
mod operator;
mod output;
mod pins;
#[cfg(feature = "cosim")]
mod plant_link;
mod setup;
mod time_driver;
#[cfg(feature = "console")]
mod uart;

use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::NVIC;
use defmt_semihosting as _;
use embassy_executor::SendSpawner;

use crate::config;
use crate::ports::{self, Board, Parts, RegisterWrite};

pub use exit::after_fault;

/// The emulated machine's parts.
pub enum Hardware {}

impl Parts for Hardware {
    type Output = output::ReportingOutput;
    type DriverEnable = pins::EnableRegister;
    type Led = pins::EmulatedPin;
    type Button = pins::NoButton;
    type Watchdog = pins::NoWatchdog;
    type Operator = operator::Operator;
    type Sensor = Sensor;
    type PartSensor = operator::PartSensor;
}

/// The plate's encoder: the plant's on the host (feature `cosim-encoder`), none otherwise.
#[cfg(feature = "encoder")]
type Sensor = encoder::PlantEncoder;
#[cfg(not(feature = "encoder"))]
type Sensor = ports::NoSensor;

/// The sensor, attached once the board is up (and the plant link open).
#[cfg(feature = "encoder")]
fn attach_sensor() -> Sensor {
    encoder::PlantEncoder::attach(crate::configured::get().encoder)
}
#[cfg(not(feature = "encoder"))]
fn attach_sensor() -> Sensor {
    ports::NoSensor
}

/// The DAC code on the emulated output (the G474's DAC1 output), written by the stage's model at
/// every edge it plays.
const OUTPUT_CODE: u32 = 0x0100_0000;
/// 1 while the stage's timer runs; while it is 0 the model plays no further edge.
const OUTPUT_RUN: u32 = 0x0100_0004;
/// The driver enable: 1 enabled, 0 disabled.
const DRIVER_ENABLE: u32 = 0x0100_0008;

/// The fault stores (see `crate::fault`): the zero code on the output (the configured one from
/// power-up, [`ZERO_CODE_WRITE`]), the stage's timer stopped, the driver disabled.
pub static SAFE_STATE_WRITES: [RegisterWrite; 3] = [
    RegisterWrite::new(OUTPUT_CODE, config::CONFIGURATION.dac.zero_code as u32),
    RegisterWrite::new(OUTPUT_RUN, 0),
    RegisterWrite::new(DRIVER_ENABLE, 0),
];

/// The store of [`SAFE_STATE_WRITES`] that writes the zero code.
const ZERO_CODE_WRITE: usize = 0;

/// Brings the emulated board up with the output at zero and the driver disabled, hands it to
/// `app`, which spawns its tasks on the executors, and leaves thread mode to the operator.
pub fn run(app: fn(SendSpawner, Board<Hardware>)) -> ! {
    let (spawner, board) = setup::init();
    app(spawner, board);
    operator::idle()
}

/// After every feed of the watchdog by the monitor: nothing, this machine has no fault drill.
pub fn after_feed() {}

/// Logs what the firmware came up on.
pub fn announce() {
    defmt::info!("feeder firmware up on QEMU mps2-an386: output reported as events, stopped");
}

/// External interrupts of mps2-an386 used here. 28 to 31 belong to GPIO pins nobody enables.
#[derive(Clone, Copy)]
#[repr(u16)]
enum Irq {
    #[cfg(feature = "console")]
    Uart0Rx = 0,
    #[cfg(feature = "console")]
    Uart0Tx = 1,
    #[cfg(feature = "console")]
    Uart1Rx = 2,
    #[cfg(feature = "console")]
    Uart1Tx = 3,
    Timer0 = 8,
    Timer1 = 9,
    LoopExecutor = 28,
    BackgroundExecutor = 29,
    ControlExecutor = 30,
    TaskExecutor = 31,
}

// SAFETY: the numbers are valid external interrupts of the machine (it has 32).
unsafe impl InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

/// Every external interrupt lands here (there is no device crate for this machine).
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn {
        #[cfg(feature = "console")]
        0 => uart::on_receive(uart::Port::Console),
        #[cfg(feature = "console")]
        1 => uart::on_transmit(uart::Port::Console),
        #[cfg(feature = "console")]
        2 => uart::on_receive(uart::Port::Modbus),
        #[cfg(feature = "console")]
        3 => uart::on_transmit(uart::Port::Modbus),
        8 => time_driver::on_alarm(),
        9 => time_driver::on_clock_wrap(),
        // SAFETY: each executor was started on its interrupt in `setup::init`.
        28 => unsafe { setup::LOOP_EXECUTOR.on_interrupt() },
        29 => unsafe { setup::BACKGROUND_EXECUTOR.on_interrupt() },
        30 => unsafe { setup::CONTROL_EXECUTOR.on_interrupt() },
        31 => unsafe { setup::TASK_EXECUTOR.on_interrupt() },
        _ => {
            cortex_m::interrupt::disable();
            ports::write_all(&SAFE_STATE_WRITES);
            defmt::error!("unexpected interrupt {=i16}", irqn);
            after_fault()
        }
    }
}

/// Reads the 32-bit register at `address`, one of this machine's CMSDK APB peripherals or the
/// output stage's registers.
fn register_read(address: usize) -> u32 {
    // SAFETY: callers pass aligned word registers that only this board module uses.
    unsafe { core::ptr::read_volatile(address as *const u32) }
}

/// Writes the 32-bit register at `address` (see [`register_read`]).
fn register_write(address: usize, value: u32) {
    // SAFETY: as in `register_read`.
    unsafe { core::ptr::write_volatile(address as *mut u32, value) }
}

/// Sets an interrupt's priority (lower is more urgent) without taking the core peripherals,
/// which the application's cycle counter needs.
fn set_priority(irq: Irq, priority: u8) {
    // SAFETY: a byte write to this interrupt's priority register before it is enabled; no
    // priority-based critical section is in use.
    unsafe { (*NVIC::PTR).ipr[usize::from(irq.number())].write(priority) }
}
