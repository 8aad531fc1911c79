//! Bring-up: the MPU guard below RAM, the output registers at rest, the time driver and the four
//! interrupt executors (timers above the control loop above the closed loop's course above the
//! other tasks above the background).

use cortex_m::peripheral::NVIC;
use embassy_executor::{InterruptExecutor, SendSpawner};

use super::output::ReportingOutput;
use super::pins::{EmulatedPin, EnableRegister, NoButton, NoWatchdog};
use super::{
    operator, register_write, set_priority, time_driver, Hardware, Irq, DRIVER_ENABLE, OUTPUT_CODE,
    OUTPUT_RUN,
};
use crate::config;
use crate::output::SegmentOutput;
use crate::ports::{Board, Operator};

/// Priority of the executor that runs the closed loop's course, above the operator.
const LOOP_PRIORITY: u8 = 0x60;
/// Priority of the executor that runs every task but the control loop and the course.
pub const TASK_PRIORITY: u8 = 0x80;
/// Priority of the background executor, below every task.
const BACKGROUND_PRIORITY: u8 = 0xC0;

pub static CONTROL_EXECUTOR: InterruptExecutor = InterruptExecutor::new();
pub static LOOP_EXECUTOR: InterruptExecutor = InterruptExecutor::new();
pub static TASK_EXECUTOR: InterruptExecutor = InterruptExecutor::new();
pub static BACKGROUND_EXECUTOR: InterruptExecutor = InterruptExecutor::new();

/// Brings the emulated board up. Returns the spawner for the application's tasks but the control
/// loop and the course, and the board.
pub fn init() -> (SendSpawner, Board<Hardware>) {
    guard_below_ram();
    register_write(
        OUTPUT_CODE as usize,
        u32::from(config::CONFIGURATION.dac.zero_code),
    );
    register_write(OUTPUT_RUN as usize, 0);
    register_write(DRIVER_ENABLE as usize, 0);
    time_driver::init();
    for irq in time_driver::IRQS {
        set_priority(irq, 0x00);
        // SAFETY: the time driver's handlers are ready (`time_driver::init` ran).
        unsafe { NVIC::unmask(irq) };
    }
    set_priority(Irq::ControlExecutor, 0x40);
    set_priority(Irq::LoopExecutor, LOOP_PRIORITY);
    set_priority(Irq::TaskExecutor, TASK_PRIORITY);
    set_priority(Irq::BackgroundExecutor, BACKGROUND_PRIORITY);
    let control_spawner = CONTROL_EXECUTOR.start(Irq::ControlExecutor);
    let loop_spawner = LOOP_EXECUTOR.start(Irq::LoopExecutor);
    let task_spawner = TASK_EXECUTOR.start(Irq::TaskExecutor);
    let background_spawner = BACKGROUND_EXECUTOR.start(Irq::BackgroundExecutor);
    #[cfg(feature = "cosim")]
    super::plant_link::open_or_end();
    let mut output = ReportingOutput::new();
    let mut operator = operator::Operator::new();
    let configuration = operator.load_configuration(output.clock());
    output.calibrate(&configuration);
    let board = Board {
        output,
        driver_enable: EnableRegister::new(),
        led: EmulatedPin,
        button: NoButton,
        watchdog: NoWatchdog,
        operator,
        sensor: super::attach_sensor(),
        part_sensor: operator::part_sensor(),
        // QEMU starts fresh every run.
        latched_at_power_up: None,
        control_spawner,
        loop_spawner,
        background_spawner,
    };
    (task_spawner, board)
}

/// Makes accesses below SRAM fault, as they do on the G474, where nothing lies below RAM. This
/// machine answers 0x1001_0000..0x2000_0000 as reserved memory that reads as zero and ignores
/// writes, so a stack that crosses the bottom of RAM (where flip-link puts it) would run on
/// unnoticed; a no-access MPU region over 0x1000_0000..0x2000_0000 turns that into a fault.
fn guard_below_ram() {
    const BASE: u32 = 0x1000_0000;
    /// RASR: execute never, no access, 2^(27 + 1) bytes (256 MiB), enabled.
    const NO_ACCESS_256_MIB: u32 = 1 << 28 | 27 << 1 | 1;
    /// CTRL: the default memory map elsewhere (privileged code), MPU enabled.
    const DEFAULT_MAP_ENABLED: u32 = 1 << 2 | 1;
    // SAFETY: region 0 is this board's only MPU region and is set before anything runs that
    // could touch it; everything runs privileged, so the default map covers the rest.
    unsafe {
        let mpu = &*cortex_m::peripheral::MPU::PTR;
        mpu.rnr.write(0);
        mpu.rbar.write(BASE);
        mpu.rasr.write(NO_ACCESS_256_MIB);
        mpu.ctrl.write(DEFAULT_MAP_ENABLED);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}
