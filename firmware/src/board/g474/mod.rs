//! NUCLEO-G474RE: clocks, pins, the two output stages, the edge counter, the watchdog and the
//! safe state.
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
//! virtual COM port. Recipes live in the last 2 KiB page of flash (bank 2 in the factory-default
//! dual-bank mode), which the top-level `memory.x` leaves out of the program: erasing and writing
//! it never stalls the code running from bank 1.
//!
//! Both output stages time every edge in hardware. DAC: TIM2 (32 bits, 170 MHz) counts one
//! segment; its update event loads the preloaded auto-reload (the next length) and, through TRGO,
//! makes the DAC latch the preloaded holding register (the next code). PWM: TIM1 runs the carrier
//! and its repetition counter counts the segment in carrier periods; the update event at the end
//! of the repetitions loads the preloaded compare values (duty and direction) and repetition count.
//!
//! The segment timer's TRGO (its update event) also clocks TIM3, which so counts the edges in
//! hardware: the control loop decides from that count whether exactly one edge has passed, so an
//! edge is never lost to a late interrupt or to two updates that collapse into one pending
//! interrupt. The update interrupt only wakes the control loop.
//!
//! The safe state is [`SAFE_STATE_WRITES`]. On a debugger halt the timers freeze (TIM1's outputs
//! then go inactive) and the independent watchdog, left running, resets the board; a core lockup
//! breaks TIM1. Every feed of the watchdog also toggles PB5, for an external retriggerable
//! monostable that keeps the driver enabled only while the feeds go on (`firmware/README.md`).

use core::future::poll_fn;
use core::sync::atomic::{AtomicU16, Ordering};
use core::task::Poll;

use defmt_rtt as _;
use embassy_executor::{InterruptExecutor, SendSpawner};
use embassy_stm32::dac::{ChannelTrigger, DacChannel, Value};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::{self, Level, OutputType, Pull, Speed};
use embassy_stm32::interrupt::typelevel::{self, Handler};
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::mode::{Async, Blocking};
use embassy_stm32::pac::timer::regs::{BdtrAdv, Cr1Gp16, EgrGp16};
use embassy_stm32::pac::timer::vals::{Bkp, Ossi, Urs};
use embassy_stm32::pac::timer::TimCore;
use embassy_stm32::peripherals::{DAC1, IWDG, PA4, PA8, PA9, TIM1, TIM2, TIM3};
use embassy_stm32::timer::low_level::{
    MasterMode, OutputCompareMode, SlaveMode, Timer, TriggerSource,
};
use embassy_stm32::timer::simple_pwm::PwmPin;
use embassy_stm32::timer::{Ch1, Ch2, Channel};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, pac, rcc, triggers, Config, Peri};
use embassy_sync::waitqueue::AtomicWaker;
use feeder_shared::{DacLevels, Direction, DriveError, PwmLevels, Segment, TickClock};

use crate::app;
use crate::config::{self, OutputStage};
use crate::fault::RegisterWrite;
use crate::output::{EdgeMissed, SegmentOutput, SegmentStart};

pub type Output = G474Output;
pub type DriverEnable = gpio::Output<'static>;
pub type Led = gpio::Output<'static>;
pub type Button = ExtiInput<'static, Async>;
pub type Watchdog = OutputWatchdog;

/// Core clock (`clocks`).
const CORE_HZ: f64 = 170e6;

/// Cycles per instruction assumed for the edge work: Cortex-M4 code from flash at 4 wait states
/// behind the ART accelerator, loads and taken branches included. The firmware logs the measured
/// cycles per edge (DWT) every second; that figure replaces this assumption on a real board.
const CYCLES_PER_INSTRUCTION: f64 = 1.5;

/// The shortest segment either output stage takes: the worst work per edge measured in
/// instructions, at this core's speed, times the margin (about 285 µs).
const MIN_SEGMENT_S: f64 =
    config::EDGE_WORK_MARGIN * config::EDGE_WORK_INSTRUCTIONS * CYCLES_PER_INSTRUCTION / CORE_HZ;

/// Pin number of the driver enable on GPIOA (PA10).
const DRIVER_ENABLE_PIN: usize = 10;

/// GPIOA_BSRR: a 1 in bit 16 + n drives PAn low (RM0440, GPIO, "GPIO port bit set/reset register").
const GPIOA_BSRR: u32 = 0x4800_0018;
/// DAC1_DHR12R1: channel 1's 12-bit right-aligned holding register.
#[cfg(not(feature = "output-pwm"))]
const DAC1_DHR12R1: u32 = 0x5000_0808;
/// TIM2's control register 1, interrupt enable and event generation registers.
#[cfg(not(feature = "output-pwm"))]
const TIM2_CR1: u32 = 0x4000_0000;
#[cfg(not(feature = "output-pwm"))]
const TIM2_DIER: u32 = 0x4000_000C;
#[cfg(not(feature = "output-pwm"))]
const TIM2_EGR: u32 = 0x4000_0014;
/// TIM1's control register 1, interrupt enable and break and dead-time registers.
#[cfg(feature = "output-pwm")]
const TIM1_CR1: u32 = 0x4001_2C00;
#[cfg(feature = "output-pwm")]
const TIM1_DIER: u32 = 0x4001_2C0C;
#[cfg(feature = "output-pwm")]
const TIM1_BDTR: u32 = 0x4001_2C44;

/// CR1 of a segment timer, stopped: ARPE (bit 7, the auto-reload is preloaded) and URS (bit 2,
/// only counter overflows raise the update interrupt), CEN (bit 0) clear.
const SEGMENT_TIMER_CR1_STOPPED: u32 = 1 << 7 | 1 << 2;
/// EGR with UG (bit 0): a forced update event.
const EGR_UPDATE: u32 = 1;
/// TIM1's BDTR with the main output off: BKP (bit 13, break active high), BKE (bit 12, break
/// enabled: a core lockup clears MOE) and OSSI (bit 10: with MOE clear the outputs are driven to
/// their idle level, low); MOE (bit 15) clear (RM0440, TIM1/TIM8/TIM20, "TIMx break and dead-time
/// register").
const TIM1_BDTR_OUTPUT_OFF: u32 = 1 << 13 | 1 << 12 | 1 << 10;

// The raw values above mean what their comments say, as the PAC decodes them.
const _: () = {
    let cr1 = Cr1Gp16(SEGMENT_TIMER_CR1_STOPPED);
    assert!(cr1.arpe() && !cr1.cen() && cr1.urs().to_bits() == Urs::COUNTER_ONLY.to_bits());
    assert!(EgrGp16(EGR_UPDATE).ug());
    let bdtr = BdtrAdv(TIM1_BDTR_OUTPUT_OFF);
    assert!(bdtr.bke(0) && !bdtr.moe() && !bdtr.aoe());
    assert!(bdtr.bkp(0).to_bits() == Bkp::ACTIVE_HIGH.to_bits());
    assert!(bdtr.ossi().to_bits() == Ossi::IDLE_LEVEL.to_bits());
    assert!(pac::gpio::regs::Bsrr(1 << (16 + DRIVER_ENABLE_PIN)).br(DRIVER_ENABLE_PIN));
};

/// The stores that make the output safe, in order, made by the HardFault entry before it
/// touches the stack.
///
/// The driver enable goes low first, then the command goes to zero: the zero code into the
/// holding register, then a forced update of TIM2, whose TRGO is the DAC's trigger (TEN set), so
/// the code reaches the output three bus clock cycles later (RM0440, DAC, "DAC conversion"); an
/// update of TIM2's own between the two stores latches the zero code as well. The trigger stays
/// on: clearing TEN with a plain store would have to repeat every other bit of DAC_CR. Then TIM2
/// stops, with its update interrupt off. Only the stage this image drives is stored to: the other
/// one's peripherals are not clocked.
#[cfg(not(feature = "output-pwm"))]
pub static SAFE_STATE_WRITES: [RegisterWrite; 5] = [
    RegisterWrite {
        address: GPIOA_BSRR,
        value: 1 << (16 + DRIVER_ENABLE_PIN),
    },
    RegisterWrite {
        address: DAC1_DHR12R1,
        value: config::DAC.zero_code as u32,
    },
    RegisterWrite {
        address: TIM2_EGR,
        value: EGR_UPDATE,
    },
    RegisterWrite {
        address: TIM2_CR1,
        value: SEGMENT_TIMER_CR1_STOPPED,
    },
    RegisterWrite {
        address: TIM2_DIER,
        value: 0,
    },
];

/// The stores that make the output safe, in order, made by the HardFault entry before it
/// touches the stack.
///
/// The driver enable goes low first, then TIM1's main output goes off, which drives PA8 and PA9
/// low at once; then TIM1 stops, with its update interrupt off. Only the stage this image drives
/// is stored to: the other one's peripherals are not clocked.
#[cfg(feature = "output-pwm")]
pub static SAFE_STATE_WRITES: [RegisterWrite; 4] = [
    RegisterWrite {
        address: GPIOA_BSRR,
        value: 1 << (16 + DRIVER_ENABLE_PIN),
    },
    RegisterWrite {
        address: TIM1_BDTR,
        value: TIM1_BDTR_OUTPUT_OFF,
    },
    RegisterWrite {
        address: TIM1_CR1,
        value: SEGMENT_TIMER_CR1_STOPPED,
    },
    RegisterWrite {
        address: TIM1_DIER,
        value: 0,
    },
];

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

/// Wakes the control loop at every update event of the segment timer.
static EDGE_WAKER: AtomicWaker = AtomicWaker::new();
/// TIM3's count (see [`edges`]) when the playing segment began: the edges the control loop has
/// taken. Written by the control loop only.
static EDGES_TAKEN: AtomicU16 = AtomicU16::new(0);
static CONTROL_EXECUTOR: InterruptExecutor = InterruptExecutor::new();

bind_interrupts!(struct Irqs {
    EXTI15_10 => exti::InterruptHandler<typelevel::EXTI15_10>;
    TIM2 => SegmentEdge;
    TIM1_UP_TIM16 => SegmentEdge;
    UART4 => ControlExecutor;
});

/// Update interrupt of the segment timer: wakes the control loop, which counts on TIM3.
struct SegmentEdge;

impl Handler<typelevel::TIM2> for SegmentEdge {
    unsafe fn on_interrupt() {
        let status = pac::TIM2.sr();
        if status.read().uif() {
            // The flags are rc_w0: a 1 leaves a flag as it is, so only UIF clears (a
            // read-modify-write would also clear a flag set between its read and its write).
            status.write(|w| {
                w.0 = !0;
                w.set_uif(false)
            });
            EDGE_WAKER.wake();
        }
    }
}

impl Handler<typelevel::TIM1_UP_TIM16> for SegmentEdge {
    unsafe fn on_interrupt() {
        let status = pac::TIM1.sr();
        if status.read().uif() {
            // As for TIM2: only UIF clears.
            status.write(|w| {
                w.0 = !0;
                w.set_uif(false)
            });
            EDGE_WAKER.wake();
        }
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

/// The operator's console: LPUART1 and the recipe page in flash.
#[cfg(feature = "console")]
mod console {
    use defmt::{error, warn};
    use embassy_stm32::flash::{self, Flash};
    use embassy_stm32::interrupt::{self, InterruptExt, Priority};
    use embassy_stm32::peripherals::{FLASH, LPUART1, PA2, PA3};
    use embassy_stm32::usart::{self, BufferedUart};
    use embassy_stm32::{bind_interrupts, Peri};
    use feeder_shared::recipe::{RECIPE_SLOTS, RECORD_LEN};
    use feeder_shared::{RecipeSlot, RecipeStore, TickClock};

    bind_interrupts!(struct ConsoleIrqs {
        LPUART1 => usart::BufferedInterruptHandler<LPUART1>;
    });

    /// The console's peripherals, handed to [`console_task`].
    pub struct Console {
        pub(super) lpuart: Peri<'static, LPUART1>,
        pub(super) tx: Peri<'static, PA2>,
        pub(super) rx: Peri<'static, PA3>,
        pub(super) flash: Peri<'static, FLASH>,
    }

    /// Bytes the console's transmitter buffers: a whole reply line.
    const CONSOLE_TX_BUFFER_BYTES: usize = 336;
    /// Bytes the console's receiver buffers while a reply is being composed.
    const CONSOLE_RX_BUFFER_BYTES: usize = 128;

    /// The operator's console on LPUART1 (ST-LINK virtual COM port, 115200 8N1), recipes in flash.
    /// Runs in thread mode, below every interrupt.
    #[embassy_executor::task]
    pub async fn console_task(console: Console, clock: TickClock) {
        let mut tx_buffer = [0u8; CONSOLE_TX_BUFFER_BYTES];
        let mut rx_buffer = [0u8; CONSOLE_RX_BUFFER_BYTES];
        // Below the edges and the control executor.
        interrupt::LPUART1.set_priority(Priority::P3);
        let port = match BufferedUart::new(
            console.lpuart,
            console.rx,
            console.tx,
            &mut tx_buffer,
            &mut rx_buffer,
            ConsoleIrqs,
            usart::Config::default(),
        ) {
            Ok(port) => port,
            Err(err) => {
                error!(
                    "console disabled: LPUART1 refused its configuration: {}",
                    err
                );
                return;
            }
        };
        let recipes = FlashRecipes {
            flash: Flash::new_blocking(console.flash),
        };
        crate::console::serve(port, recipes, clock).await
    }

    /// Offset from the start of flash of the recipe page: the last 2 KiB page of the 512 KiB.
    const RECIPE_PAGE_OFFSET: u32 = 512 * 1024 - RECIPE_PAGE_BYTES;
    /// One flash page in dual-bank mode.
    const RECIPE_PAGE_BYTES: u32 = 2 * 1024;
    /// The records of all slots, one after the other from the start of the page.
    const RECIPE_BYTES: usize = RECORD_LEN * RECIPE_SLOTS;

    /// The recipe records in the reserved flash page. A write rewrites the whole page (about 20 ms
    /// of erase time, spent in the console task).
    struct FlashRecipes {
        flash: Flash<'static, flash::Blocking>,
    }

    impl FlashRecipes {
        fn offset(slot: RecipeSlot) -> u32 {
            RECIPE_PAGE_OFFSET + (slot.index() * RECORD_LEN) as u32
        }
    }

    impl RecipeStore for FlashRecipes {
        type Error = flash::Error;

        fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN] {
            let mut record = [0xff; RECORD_LEN];
            if let Err(err) = self.flash.blocking_read(Self::offset(slot), &mut record) {
                warn!("recipe {} unreadable: {}", slot, err);
                record = [0xff; RECORD_LEN];
            }
            record
        }

        fn write(
            &mut self,
            slot: RecipeSlot,
            record: &[u8; RECORD_LEN],
        ) -> Result<(), flash::Error> {
            let mut page = [0xff; RECIPE_BYTES];
            self.flash.blocking_read(RECIPE_PAGE_OFFSET, &mut page)?;
            let start = slot.index() * RECORD_LEN;
            if let Some(stored) = page.get_mut(start..start + RECORD_LEN) {
                stored.copy_from_slice(record);
            }
            let result = self
                .flash
                .blocking_erase(RECIPE_PAGE_OFFSET, RECIPE_PAGE_OFFSET + RECIPE_PAGE_BYTES)
                .and_then(|()| self.flash.blocking_write(RECIPE_PAGE_OFFSET, &page));
            if let Err(err) = result {
                warn!("recipe {} not written: {}", slot, err);
            }
            result
        }
    }
}

#[cfg(feature = "console")]
pub use console::{console_task, Console};

/// Brings the board up with the output at zero and the driver disabled.
pub fn init() -> Board {
    let after_watchdog_reset = pac::RCC.csr().read().iwdgrstf();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));

    let p = embassy_stm32::init(clocks());
    let driver_enable = gpio::Output::new(p.PA10, Level::Low, Speed::Low);
    let led = gpio::Output::new(p.PA5, Level::Low, Speed::Low);
    let button = ExtiInput::new(p.PC13, p.EXTI13, Pull::Down, Irqs);
    let output = match config::OUTPUT_STAGE {
        OutputStage::Dac => G474Output::Dac(DacStage::new(p.DAC1, p.PA4, p.TIM2, p.TIM3)),
        OutputStage::PwmDir => G474Output::Pwm(PwmStage::new(p.TIM1, p.PA8, p.PA9, p.TIM3)),
    };
    freeze_on_halt();
    // The first period after the start counts down from the reset value 0xFFF (512 ms at LSI/4,
    // RM0440, IWDG, "Independent watchdog functional description"), which covers the rest of the
    // start-up; every feed then reloads the configured timeout.
    let mut watchdog = OutputWatchdog {
        iwdg: IndependentWatchdog::new(p.IWDG, config::WATCHDOG_TIMEOUT_US),
        feed_pulses: gpio::Output::new(p.PB5, Level::Low, Speed::Low),
    };
    watchdog.iwdg.unleash();

    // Edges above the control executor, which is above the thread-mode tasks.
    for edge_irq in [interrupt::TIM2, interrupt::TIM1_UP_TIM16] {
        edge_irq.set_priority(Priority::P0);
        edge_irq.unpend();
        // SAFETY: both handlers are bound above and touch only their timer's flag and the waker.
        unsafe { edge_irq.enable() };
    }
    interrupt::UART4.set_priority(Priority::P1);
    let control_spawner = CONTROL_EXECUTOR.start(interrupt::UART4);

    Board {
        output,
        driver_enable,
        led,
        button,
        watchdog,
        after_watchdog_reset,
        control_spawner,
        #[cfg(feature = "console")]
        console: Console {
            lpuart: p.LPUART1,
            tx: p.PA2,
            rx: p.PA3,
            flash: p.FLASH,
        },
    }
}

/// 170 MHz from HSI16: /4 × 85 /2, range 1 boost.
fn clocks() -> Config {
    let mut config = Config::default();
    config.rcc.pll = Some(rcc::Pll {
        source: rcc::PllSource::HSI,
        prediv: rcc::PllPreDiv::DIV4,
        mul: rcc::PllMul::MUL85,
        divp: None,
        divq: None,
        divr: Some(rcc::PllRDiv::DIV2),
    });
    config.rcc.sys = rcc::Sysclk::PLL1_R;
    config.rcc.boost = true;
    config
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

/// After a panic or HardFault, whose handler has made the safe state: interrupts off, so that no
/// handler (the control loop) runs again and undoes it, the safe state once more (the segment
/// timers stopped, their update interrupts off), then no more feeds: the independent watchdog
/// resets the board within its timeout, and the enable keeper drops the enable.
pub fn after_fault() -> ! {
    cortex_m::interrupt::disable();
    crate::fault::make_safe();
    loop {
        cortex_m::asm::wfi();
    }
}

/// The independent watchdog, fed only while the output plays what the control loop preloaded,
/// and the feed pulses on PB5: every feed toggles it, for an external retriggerable monostable
/// that keeps the driver enabled only while the pulses go on (`firmware/README.md`).
pub struct OutputWatchdog {
    iwdg: IndependentWatchdog<'static, IWDG>,
    feed_pulses: gpio::Output<'static>,
}

impl app::Watchdog for OutputWatchdog {
    /// Feeds unless the output replays a segment: two or more edges past the ones the control
    /// loop has taken mean that the segment timer has started the playing segment again.
    fn feed(&mut self) {
        if edges().wrapping_sub(EDGES_TAKEN.load(Ordering::Relaxed)) >= 2 {
            return;
        }
        self.iwdg.pet();
        self.feed_pulses.toggle();
        drill::provoke_when_due();
    }
}

/// TIM3's count of the segment timer's update events (wrapping at 16 bits).
fn edges() -> u16 {
    pac::TIM3.cnt().read().cnt()
}

/// Starts TIM3 counting the update events of a segment timer: external clock mode 1 (SMS = 0111)
/// clocked by the internal trigger `segment_timer_trgo`, TIM3's ITR0 = TIM1_TRGO or
/// ITR1 = TIM2_TRGO (RM0440, TIM2/TIM3/TIM4/TIM5, "TIMx internal trigger connection"; "Using one
/// timer as prescaler for another timer"), whose TRGO is set to its update event.
fn start_edge_counter(
    tim: Peri<'static, TIM3>,
    segment_timer_trgo: TriggerSource,
) -> Timer<'static, TIM3> {
    let counter = Timer::new(tim);
    counter.set_trigger_source(segment_timer_trgo);
    counter.set_slave_mode(SlaveMode::EXT_CLOCK_MODE);
    counter.start();
    EDGES_TAKEN.store(edges(), Ordering::Relaxed);
    counter
}

/// Forces an update event of a stopped segment timer: its preloaded registers load and its TRGO
/// fires, which TIM3 counts as one edge, taken here as the control loop's own (URS keeps the
/// update interrupt quiet).
fn forced_update(timer: TimCore) {
    EDGES_TAKEN.store(edges().wrapping_add(1), Ordering::Relaxed);
    timer.egr().write(|w| w.set_ug(true));
}

/// Clears a pending update flag by a write (the flags are rc_w0, see [`SegmentEdge`]).
fn clear_update_flag(timer: TimCore) {
    timer.sr().write(|w| {
        w.0 = !0;
        w.set_uif(false)
    });
}

/// The output stage chosen by [`config::OUTPUT_STAGE`].
pub enum G474Output {
    Dac(DacStage),
    Pwm(PwmStage),
}

impl SegmentOutput for G474Output {
    fn clock(&self) -> TickClock {
        match self {
            G474Output::Dac(stage) => stage.clock(),
            G474Output::Pwm(stage) => stage.clock,
        }
    }

    fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError> {
        match self {
            G474Output::Dac(stage) => {
                stage.levels = None;
                stage.levels = Some(config::DAC.levels(peak_accel_mps2)?);
            }
            G474Output::Pwm(stage) => {
                stage.levels = None;
                stage.levels = Some(config::PWM.levels(peak_accel_mps2, stage.period_counts)?);
            }
        }
        Ok(())
    }

    fn restart(&mut self, segment: &Segment) {
        match self {
            G474Output::Dac(stage) => stage.restart(segment),
            G474Output::Pwm(stage) => stage.restart(segment),
        }
    }

    fn preload(&mut self, segment: &Segment) -> Result<(), EdgeMissed> {
        let update_pending = match self {
            G474Output::Dac(stage) => stage.preload(segment)?,
            G474Output::Pwm(stage) => stage.preload(segment),
        };
        // An edge before the writes completed may have split the preload across two segments.
        // TIM3 counts it a few timer cycles after the update event; UIF shows it at once, until
        // the update interrupt, which preempts this code, clears it.
        if update_pending || edges() != EDGES_TAKEN.load(Ordering::Relaxed) {
            return Err(EdgeMissed);
        }
        Ok(())
    }

    async fn wait_edge(&mut self) -> Result<(), EdgeMissed> {
        let taken = EDGES_TAKEN.load(Ordering::Relaxed);
        let now = poll_fn(|cx| {
            EDGE_WAKER.register(cx.waker());
            let now = edges();
            if now == taken {
                Poll::Pending
            } else {
                Poll::Ready(now)
            }
        })
        .await;
        EDGES_TAKEN.store(now, Ordering::Relaxed);
        if let G474Output::Dac(stage) = self {
            stage.playing_slack_ticks = stage.queued_slack_ticks.take();
        }
        if now.wrapping_sub(taken) == 1 {
            Ok(())
        } else {
            Err(EdgeMissed)
        }
    }

    fn halt(&mut self) {
        match self {
            G474Output::Dac(stage) => stage.halt(),
            G474Output::Pwm(stage) => stage.halt(),
        }
    }

    fn started(&self, segment: &Segment) -> SegmentStart {
        SegmentStart {
            // The timer's update event starts every segment exactly on its planned tick.
            tick: segment.start_tick,
            // TIM1's repetition counter cannot be read: the PWM stage has no slack to report.
            slack_ticks: match self {
                G474Output::Dac(stage) => stage.playing_slack_ticks,
                G474Output::Pwm(_) => None,
            },
        }
    }
}

/// Analog command on PA4, edges timed by TIM2 and counted by TIM3.
pub struct DacStage {
    dac: DacChannel<'static, Blocking>,
    timer: Timer<'static, TIM2>,
    _edge_counter: Timer<'static, TIM3>,
    levels: Option<DacLevels>,
    /// Preload slack of the preloaded segment and of the playing one (`None`: restarted).
    queued_slack_ticks: Option<u32>,
    playing_slack_ticks: Option<u32>,
}

impl DacStage {
    fn new(
        dac: Peri<'static, DAC1>,
        pin: Peri<'static, PA4>,
        tim: Peri<'static, TIM2>,
        edge_counter: Peri<'static, TIM3>,
    ) -> Self {
        let mut dac = DacChannel::new_blocking(dac, pin);
        // Untriggered, the zero code reaches the pin at once.
        dac.set(Value::Bit12Right(config::DAC.zero_code));
        let trigger = <triggers::TIM2_TRGO as ChannelTrigger<DAC1>>::signal(&triggers::TIM2_TRGO);
        // The trigger selection can change only while the channel is disabled; the HAL has no
        // call for it on a blocking channel.
        pac::DAC1.cr().modify(|w| w.set_en(0, false));
        pac::DAC1.cr().modify(|w| {
            w.set_tsel(0, trigger);
            w.set_ten(0, true);
        });
        pac::DAC1.cr().modify(|w| w.set_en(0, true));

        let timer = Timer::new(tim);
        timer.set_autoreload_preload(true);
        timer.set_master_mode(MasterMode::UPDATE);
        // Only counter overflows (segment ends) raise the interrupt, not forced updates.
        timer
            .regs_core()
            .cr1()
            .modify(|w| w.set_urs(Urs::COUNTER_ONLY));
        timer.enable_update_interrupt(true);
        Self {
            dac,
            timer,
            _edge_counter: start_edge_counter(edge_counter, TriggerSource::ITR1),
            levels: None,
            queued_slack_ticks: None,
            playing_slack_ticks: None,
        }
    }

    fn clock(&self) -> TickClock {
        TickClock::new(self.timer.get_clock_frequency().0).with_min_segment_s(MIN_SEGMENT_S)
    }

    fn code(&self, segment: &Segment) -> u16 {
        match self.levels {
            Some(levels) => levels.code(segment.level, segment.amplitude),
            None => config::DAC.zero_code,
        }
    }

    fn restart(&mut self, segment: &Segment) {
        self.timer.stop();
        self.timer.reset();
        self.dac.set(Value::Bit12Right(self.code(segment)));
        self.timer
            .regs_gp32()
            .arr()
            .write_value(segment.ticks.saturating_sub(1));
        // Loads the length and, through TRGO, the code.
        forced_update(self.timer.regs_core());
        clear_update_flag(self.timer.regs_core());
        self.queued_slack_ticks = None;
        self.playing_slack_ticks = None;
        self.timer.start();
    }

    /// Writes the next code and length and keeps the slack left when they were written (the
    /// playing segment's auto-reload + 1 − the count); returns whether an update is pending.
    fn preload(&mut self, segment: &Segment) -> Result<bool, EdgeMissed> {
        // A one-tick segment would stop the counter (auto-reload 0) and cannot be prepared.
        if segment.ticks < 2 {
            return Err(EdgeMissed);
        }
        let counter = self.timer.regs_gp32();
        let playing_reload = counter.arr().read();
        self.dac.set(Value::Bit12Right(self.code(segment)));
        counter.arr().write_value(segment.ticks - 1);
        self.queued_slack_ticks = Some(
            playing_reload
                .wrapping_add(1)
                .wrapping_sub(counter.cnt().read()),
        );
        // Both writes done (the DAC's is on another bus) before the checks.
        cortex_m::asm::dsb();
        Ok(self.timer.regs_core().sr().read().uif())
    }

    fn halt(&mut self) {
        self.timer.stop();
        self.dac.set(Value::Bit12Right(config::DAC.zero_code));
        forced_update(self.timer.regs_core());
    }
}

/// PWM magnitude on PA8 and direction on PA9 (high = forward), segments counted in carrier
/// periods by TIM1's repetition counter and in segments by TIM3.
pub struct PwmStage {
    timer: Timer<'static, TIM1>,
    _magnitude: PwmPin<'static, TIM1, Ch1>,
    _direction: PwmPin<'static, TIM1, Ch2>,
    _edge_counter: Timer<'static, TIM3>,
    /// Timer counts per carrier period (100 % duty).
    period_counts: u16,
    clock: TickClock,
    levels: Option<PwmLevels>,
}

impl PwmStage {
    fn new(
        tim: Peri<'static, TIM1>,
        pwm: Peri<'static, PA8>,
        dir: Peri<'static, PA9>,
        edge_counter: Peri<'static, TIM3>,
    ) -> Self {
        let magnitude = PwmPin::new(pwm, OutputType::PushPull);
        let direction = PwmPin::new(dir, OutputType::PushPull);
        let timer = Timer::new(tim);
        let timer_hz = timer.get_clock_frequency().0;
        let period_counts =
            (timer_hz / config::PWM_FREQUENCY_HZ).clamp(1, u32::from(u16::MAX)) as u16;
        let carrier_hz = timer_hz / u32::from(period_counts);
        if carrier_hz * u32::from(period_counts) != timer_hz {
            defmt::warn!(
                "PWM carrier {=u32} Hz does not divide the timer clock",
                carrier_hz
            );
        }
        timer
            .regs_core()
            .arr()
            .write(|w| w.set_arr(period_counts - 1));
        timer.set_autoreload_preload(true);
        for channel in [Channel::Ch1, Channel::Ch2] {
            timer.set_output_compare_mode(channel, OutputCompareMode::PwmMode1);
            timer.set_output_compare_preload(channel, true);
            timer.set_compare_value(channel, 0);
            timer.enable_channel(channel, true);
        }
        // Main output off, both pins at their idle level (low); a core lockup breaks the timer
        // (SYSCFG_CFGR2.CLL, RM0440, SYSCFG, "SYSCFG configuration register 2"), which clears
        // MOE at once. The break input pin is not used.
        pac::SYSCFG.cfgr2().modify(|w| w.set_cll(true));
        let registers = timer.regs_advanced();
        registers.af1().modify(|w| w.set_bkine(false));
        registers.bdtr().write_value(BdtrAdv(TIM1_BDTR_OUTPUT_OFF));
        timer.set_master_mode(MasterMode::UPDATE);
        timer
            .regs_core()
            .cr1()
            .modify(|w| w.set_urs(Urs::COUNTER_ONLY));
        timer.enable_update_interrupt(true);
        Self {
            timer,
            _magnitude: magnitude,
            _direction: direction,
            _edge_counter: start_edge_counter(edge_counter, TriggerSource::ITR0),
            period_counts,
            // The repetition counter has 16 bits.
            clock: TickClock::new(carrier_hz)
                .with_max_segment_ticks(1 << 16)
                .with_min_segment_s(MIN_SEGMENT_S),
            levels: None,
        }
    }

    fn write(&self, segment: &Segment) {
        let (duty, direction) = match self.levels {
            Some(levels) => {
                let command = levels.command(segment.level, segment.amplitude);
                (command.duty_counts, command.direction)
            }
            None => (0, Direction::Forward),
        };
        let direction_compare = match direction {
            Direction::Forward => self.period_counts,
            Direction::Reverse => 0,
        };
        self.timer.set_compare_value(Channel::Ch1, duty);
        self.timer
            .set_compare_value(Channel::Ch2, direction_compare);
        let repetitions = segment.ticks.saturating_sub(1).min(u32::from(u16::MAX)) as u16;
        self.timer.set_repetition_counter(repetitions);
    }

    fn restart(&mut self, segment: &Segment) {
        self.timer.stop();
        self.timer.reset();
        self.write(segment);
        forced_update(self.timer.regs_core());
        clear_update_flag(self.timer.regs_core());
        self.timer.set_moe(true);
        self.timer.start();
    }

    /// Writes the next duty, direction and length; returns whether an update is pending.
    fn preload(&mut self, segment: &Segment) -> bool {
        self.write(segment);
        cortex_m::asm::dsb();
        self.timer.regs_core().sr().read().uif()
    }

    fn halt(&mut self) {
        self.timer.set_moe(false);
        self.timer.stop();
    }
}

/// Faults provoked on purpose for the bring-up checklist (`firmware/README.md`), chosen when the
/// image is built: `FEEDER_FAULT_DRILL=<drill> cargo run --release`. Without the variable none of
/// it is in the image.
mod drill {
    use core::sync::atomic::{AtomicU32, Ordering};

    use embassy_stm32::pac;
    use embassy_stm32::pac::gpio::vals::Odr;

    use super::DRIVER_ENABLE_PIN;
    use crate::config;

    /// What to provoke.
    #[derive(Clone, Copy)]
    enum Drill {
        /// A panic on the control executor.
        Panic,
        /// Unbounded recursion: flip-link makes it fault at the bottom of RAM.
        StackOverflow,
        /// Interrupts masked for 10 ms: no edge is taken, no feed made.
        CriticalSection,
        /// The control executor spins with interrupts on: edges replay, nothing feeds.
        Hang,
        /// A fault with FAULTMASK set, which the core cannot take: it locks up.
        Lockup,
    }

    /// The drill named by `FEEDER_FAULT_DRILL` at build time; a name not listed here stops the
    /// build.
    const DRILL: Option<Drill> = match option_env!("FEEDER_FAULT_DRILL") {
        None => None,
        Some(name) => Some(named(name)),
    };

    const fn named(name: &str) -> Drill {
        if same(name, "panic") {
            Drill::Panic
        } else if same(name, "stack-overflow") {
            Drill::StackOverflow
        } else if same(name, "critical-section") {
            Drill::CriticalSection
        } else if same(name, "hang") {
            Drill::Hang
        } else if same(name, "lockup") {
            Drill::Lockup
        } else {
            panic!("FEEDER_FAULT_DRILL: panic, stack-overflow, critical-section, hang or lockup")
        }
    }

    const fn same(a: &str, b: &str) -> bool {
        let (a, b) = (a.as_bytes(), b.as_bytes());
        if a.len() != b.len() {
            return false;
        }
        let mut i = 0;
        while i < a.len() {
            if a[i] != b[i] {
                return false;
            }
            i += 1;
        }
        true
    }

    /// Feeds with the driver enabled before the drill: 2 s into a run.
    const DUE_AFTER_FEEDS: u32 = (2_000_000 / config::MONITOR_PERIOD_US) as u32;

    /// Feeds made with the driver enabled so far.
    static ENABLED_FEEDS: AtomicU32 = AtomicU32::new(0);

    /// Called at every feed: provokes the drill once the driver has been enabled long enough.
    pub fn provoke_when_due() {
        let Some(drill) = DRILL else {
            return;
        };
        if pac::GPIOA.odr().read().odr(DRIVER_ENABLE_PIN) != Odr::HIGH {
            return;
        }
        if ENABLED_FEEDS.fetch_add(1, Ordering::Relaxed) < DUE_AFTER_FEEDS {
            return;
        }
        defmt::warn!("fault drill now");
        match drill {
            Drill::Panic => panic!("fault drill"),
            Drill::StackOverflow => {
                recurse(0);
            }
            Drill::CriticalSection => {
                cortex_m::interrupt::free(|_| cortex_m::asm::delay(super::CORE_HZ as u32 / 100))
            }
            Drill::Hang => loop {
                cortex_m::asm::nop();
            },
            Drill::Lockup => {
                // SAFETY: a drill: the core locks up on purpose.
                unsafe { core::arch::asm!("cpsid f", "udf #0", options(noreturn)) }
            }
        }
    }

    /// Uses 256 bytes of stack per call, without end.
    fn recurse(depth: u32) -> u32 {
        let frame = core::hint::black_box([depth; 64]);
        if core::hint::black_box(depth) == u32::MAX {
            return frame[0];
        }
        recurse(depth + 1).wrapping_add(frame[63])
    }
}
