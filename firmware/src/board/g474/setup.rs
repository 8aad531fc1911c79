//! Bring-up: clocks, pins, the output stage, the watchdog, the interrupt priorities and the
//! control executor.

use embassy_executor::{InterruptExecutor, SendSpawner};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::{self, Level, Pull, Speed};
use embassy_stm32::interrupt::typelevel::{self, Handler};
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::{bind_interrupts, pac};
use feeder_shared::Fault;

use super::light_barrier::LightBarrier;
use super::pins::{clocks, LinePins};
use super::watchdog::OutputWatchdog;
use super::{operator, Hardware, Stage};
use crate::output::SegmentOutput;
use crate::ports::{Board, Operator};

static CONTROL_EXECUTOR: InterruptExecutor = InterruptExecutor::new();

#[cfg(not(feature = "encoder"))]
bind_interrupts!(struct Irqs {
    EXTI15_10 => exti::InterruptHandler<typelevel::EXTI15_10>;
    UART4 => ControlExecutor;
});

/// With a sensor the application's tasks run on an interrupt executor at the lowest priority,
/// so that thread mode is free for the background (the drive's identification), and the closed
/// loop's course on one just above them.
#[cfg(feature = "encoder")]
static TASK_EXECUTOR: InterruptExecutor = InterruptExecutor::new();
#[cfg(feature = "encoder")]
static LOOP_EXECUTOR: InterruptExecutor = InterruptExecutor::new();

#[cfg(feature = "encoder")]
bind_interrupts!(struct Irqs {
    EXTI15_10 => exti::InterruptHandler<typelevel::EXTI15_10>;
    UART4 => ControlExecutor;
    UART5 => TaskExecutor;
    CORDIC => LoopExecutor;
});

/// UART5 is unused on this board; its vector runs the task executor.
#[cfg(feature = "encoder")]
struct TaskExecutor;

#[cfg(feature = "encoder")]
impl Handler<typelevel::UART5> for TaskExecutor {
    unsafe fn on_interrupt() {
        // SAFETY: the executor was started on this interrupt in `init`.
        unsafe { TASK_EXECUTOR.on_interrupt() }
    }
}

/// The CORDIC unit is unused on this board; its vector runs the loop executor.
#[cfg(feature = "encoder")]
struct LoopExecutor;

#[cfg(feature = "encoder")]
impl Handler<typelevel::CORDIC> for LoopExecutor {
    unsafe fn on_interrupt() {
        // SAFETY: the executor was started on this interrupt in `init`.
        unsafe { LOOP_EXECUTOR.on_interrupt() }
    }
}

/// UART4 is unused on this board; its vector runs the control executor.
struct ControlExecutor;

impl Handler<typelevel::UART4> for ControlExecutor {
    unsafe fn on_interrupt() {
        // SAFETY: the executor was started on this interrupt in `init`.
        unsafe { CONTROL_EXECUTOR.on_interrupt() }
    }
}

/// Brings the board up with the output at zero and the driver disabled; `thread_spawner` is
/// the thread-mode executor's. Returns the spawner for the application's tasks and the board.
pub fn init(thread_spawner: SendSpawner) -> (SendSpawner, Board<Hardware>) {
    let after_watchdog_reset = pac::RCC.csr().read().iwdgrstf();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));

    let p = embassy_stm32::init(clocks());
    lower_shared_interrupts();
    let driver_enable = gpio::Output::new(p.PA10, Level::Low, Speed::Low);
    let led = gpio::Output::new(p.PA5, Level::Low, Speed::Low);
    let button = ExtiInput::new(p.PC13, p.EXTI13, Pull::Down, Irqs);
    let part_sensor = LightBarrier(ExtiInput::new(p.PB10, p.EXTI10, Pull::Up, Irqs));
    let mut output = Stage::new(p.DAC1, p.PA4, p.TIM2, p.TIM1, p.PA8, p.PA9, p.TIM3);
    let line = LinePins {
        usart: p.USART1,
        tx: p.PC4,
        rx: p.PC5,
        de: p.PA12,
        release: p.PC0,
        select: (p.PC2, p.PC3),
        ready: p.PC6,
        fault: p.PC8,
    };
    let mut operator = operator::Operator::new(p.LPUART1, p.PA2, p.PA3, p.FLASH, line);
    let configuration = operator.load_configuration(output.clock());
    output.calibrate(&configuration);
    freeze_on_halt();
    #[cfg(feature = "encoder")]
    let sensor = super::encoder::Encoder::new::<super::SegmentTimerPeri>(
        p.TIM4,
        p.PB6,
        p.PB7,
        p.TIM6,
        p.DMA1_CH1,
        p.DMA1_CH2,
        output.clock(),
        configuration.encoder,
    );
    #[cfg(not(feature = "encoder"))]
    let sensor = crate::ports::NoSensor;
    let watchdog = OutputWatchdog::start(p.IWDG, p.PB5);

    // The control executor runs below the edges and above the tasks.
    interrupt::UART4.set_priority(Priority::P1);
    let control_spawner = CONTROL_EXECUTOR.start(interrupt::UART4);
    // Thread mode is this board's lowest level: without a sensor it runs the tasks (nothing of
    // the closed loop runs); with one, the drive's identification, below the tasks.
    #[cfg(not(feature = "encoder"))]
    let (task_spawner, loop_spawner) = (thread_spawner, thread_spawner);
    #[cfg(feature = "encoder")]
    let (task_spawner, loop_spawner) = {
        interrupt::UART5.set_priority(Priority::P15);
        interrupt::CORDIC.set_priority(Priority::P14);
        (
            TASK_EXECUTOR.start(interrupt::UART5),
            LOOP_EXECUTOR.start(interrupt::CORDIC),
        )
    };

    // A failed self-test outranks the watchdog's reset: it cannot be acknowledged.
    let latched_at_power_up = if !output.counts_edges() {
        Some(Fault::EdgeCounter)
    } else if after_watchdog_reset {
        Some(Fault::WatchdogReset)
    } else {
        None
    };
    let board = Board {
        output,
        driver_enable,
        led,
        button,
        watchdog,
        operator,
        sensor,
        part_sensor,
        latched_at_power_up,
        control_spawner,
        loop_spawner,
        background_spawner: thread_spawner,
    };
    (task_spawner, board)
}

/// Only the segment timer's update runs at P0, above every other interrupt: the time driver's
/// timer (TIM15, which embassy enables at P0) goes to the control executor's P1, where it waits
/// for the control loop's work at an edge rather than delaying the edge; the EXTI lines (embassy
/// enables them all at P0; the button's and the light barrier's are EXTI15_10's) to P2.
fn lower_shared_interrupts() {
    interrupt::TIM1_BRK_TIM15.set_priority(Priority::P1);
    for line in [
        interrupt::EXTI0,
        interrupt::EXTI1,
        interrupt::EXTI2,
        interrupt::EXTI3,
        interrupt::EXTI4,
        interrupt::EXTI9_5,
        interrupt::EXTI15_10,
    ] {
        line.set_priority(Priority::P2);
    }
}

/// On a debugger halt the segment timers and the edge counter stop (DBGMCU_APB1FZR1, APB2FZR):
/// TIM1's outputs then go inactive, as if MOE were cleared (RM0440, TIM1/TIM8/TIM20, "Debug
/// mode"), while TIM2 stops with the DAC holding its code. The independent watchdog keeps running
/// (DBG_IWDG_STOP cleared, whatever a debugger set before): a halt longer than its timeout resets
/// the board, which leaves PA4 at high impedance and the driver enable low.
fn freeze_on_halt() {
    pac::DBGMCU.apb1lfzr().modify(|w| {
        w.set_tim2(true);
        w.set_tim3(true);
        w.set_iwdg(false);
    });
    pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));
}
