//! QEMU `-machine mps2-an386` (Cortex-M4F at 25 MHz): the same application as on the board, with
//! an output stage that reports every level change instead of driving a DAC.
//!
//! * Time: an embassy-time driver on the CMSDK APB timers ([`time_driver`]), 1 µs ticks, which
//!   the scheduler plans in. The output stage ([`ReportingOutput`]) keeps TIM2's semantics on
//!   that clock: every level takes effect on its planned tick, whatever the software's latency,
//!   and a segment preloaded after its deadline is a missed edge, as on the board. It reports each
//!   segment's preload slack and measures the work per edge on the 25 MHz timer (40 ns, which
//!   `-icount shift=4` makes 2.5 instructions).
//! * Operator: a script read from the semihosting command line (`script`) instead of B1; with
//!   the `console` feature, the serial console on UART0 (`uart`, QEMU's `-serial`) instead, with
//!   recipes kept in RAM: the feeder waits, stopped, for commands and the emulation runs until
//!   QEMU is ended. The script's image contains no console, so its run (and its `EVT` stream)
//!   does not depend on the console's code.
//! * Executors: all tasks run on two interrupt executors and thread mode spins ([`idle`], where a
//!   script also provokes its thread-mode faults). QEMU executes `wfe` as a no-op, so embassy's
//!   thread executor would spin instead of letting `-icount` skip idle time.
//! * Output registers: the stage's model keeps its state in three words of the machine's FPGA
//!   block RAM ([`OUTPUT_CODE`], [`OUTPUT_RUN`], [`DRIVER_ENABLE`]), which the image links nothing
//!   into: fixed addresses, as a peripheral's are, so that the fault stores
//!   ([`SAFE_STATE_WRITES`]) can name them, and the model honours what they hold.
//! * Logs: defmt over semihosting; the run ends with a semihosting exit code, non-zero after a
//!   panic or fault, which first reports the output's state from those registers.

#[cfg(not(feature = "console"))]
mod script;
mod time_driver;
#[cfg(feature = "console")]
mod uart;

use core::cell::Cell;
use core::convert::Infallible;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::NVIC;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE};
use critical_section::Mutex;
use defmt_semihosting as _;
use embassy_executor::{InterruptExecutor, SendSpawner};
use embassy_time::{Instant, Timer};
use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
use embedded_hal_async::digital::Wait;
#[cfg(feature = "console")]
use feeder_shared::recipe::{RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{DacLevels, DriveError, Segment, TickClock};
#[cfg(feature = "console")]
use feeder_shared::{RecipeSlot, RecipeStore};

use crate::app;
use crate::config;
use crate::fault::{self, RegisterWrite};
use crate::output::{EdgeMissed, SegmentOutput, SegmentStart};
use crate::trace;
use time_driver::CYCLES_PER_TICK;

#[cfg(not(feature = "console"))]
pub use script::{idle, spawn_operator};

/// With the console the operator is on the serial port: there is no script to spawn.
#[cfg(feature = "console")]
pub fn spawn_operator(_: SendSpawner, _: TickClock) {}

/// Thread mode with the console: nothing to do.
#[cfg(feature = "console")]
pub fn idle() -> ! {
    sleep_forever()
}

/// Virtual time per instruction under `-icount shift=4`: 2⁴ ns.
const INSTRUCTION_S: f64 = 16e-9;

/// The shortest segment this board's output stage takes: the worst work per edge, at QEMU's
/// speed, times the margin (about 516 µs).
const MIN_SEGMENT_S: f64 =
    config::EDGE_WORK_MARGIN * config::EDGE_WORK_INSTRUCTIONS * INSTRUCTION_S;

pub type Output = ReportingOutput;
pub type DriverEnable = EnableRegister;
pub type Led = EmulatedPin;
pub type Button = NoButton;
pub type Watchdog = NoWatchdog;

/// Everything the application needs from the board.
pub struct Board {
    pub output: Output,
    pub driver_enable: DriverEnable,
    pub led: Led,
    pub button: Button,
    pub watchdog: Watchdog,
    /// QEMU starts fresh every run.
    pub after_watchdog_reset: bool,
    /// Spawner of the executor that runs the control loop above the other tasks.
    pub control_spawner: SendSpawner,
    /// UART0, for the console.
    #[cfg(feature = "console")]
    pub console: uart::Uart,
}

/// External interrupts of mps2-an386 used here. 30 and 31 belong to GPIO pins nobody enables.
#[derive(Clone, Copy)]
#[repr(u16)]
pub enum Irq {
    #[cfg(feature = "console")]
    Uart0Rx = 0,
    #[cfg(feature = "console")]
    Uart0Tx = 1,
    Timer0 = 8,
    Timer1 = 9,
    ControlExecutor = 30,
    TaskExecutor = 31,
}

// SAFETY: the numbers are valid external interrupts of the machine (it has 32).
unsafe impl InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

/// Priority of the executor that runs every task but the control loop.
const TASK_PRIORITY: u8 = 0x80;

static CONTROL_EXECUTOR: InterruptExecutor = InterruptExecutor::new();
static TASK_EXECUTOR: InterruptExecutor = InterruptExecutor::new();

/// The DAC code on the emulated output (the G474's DAC1 output), written by the stage's model at
/// every edge it plays.
const OUTPUT_CODE: u32 = 0x0100_0000;
/// 1 while the stage's timer runs; while it is 0 the model plays no further edge.
const OUTPUT_RUN: u32 = 0x0100_0004;
/// The driver enable: 1 enabled, 0 disabled.
const DRIVER_ENABLE: u32 = 0x0100_0008;

/// The fault stores (see `crate::fault`): the zero code on the output, the stage's timer
/// stopped, the driver disabled.
pub static SAFE_STATE_WRITES: [RegisterWrite; 3] = [
    RegisterWrite {
        address: OUTPUT_CODE,
        value: config::DAC.zero_code as u32,
    },
    RegisterWrite {
        address: OUTPUT_RUN,
        value: 0,
    },
    RegisterWrite {
        address: DRIVER_ENABLE,
        value: 0,
    },
];

/// Every external interrupt lands here (there is no device crate for this machine).
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn {
        #[cfg(feature = "console")]
        0 => uart::on_receive(),
        #[cfg(feature = "console")]
        1 => uart::on_transmit(),
        8 => time_driver::on_alarm(),
        9 => time_driver::on_clock_wrap(),
        // SAFETY: each executor was started on its interrupt in `init`.
        30 => unsafe { CONTROL_EXECUTOR.on_interrupt() },
        31 => unsafe { TASK_EXECUTOR.on_interrupt() },
        _ => {
            cortex_m::interrupt::disable();
            fault::make_safe();
            defmt::error!("unexpected interrupt {=i16}", irqn);
            after_fault()
        }
    }
}

/// Brings the emulated board up: time driver, executors (timers above the control loop above
/// the other tasks). Returns the spawner for the application's other tasks.
pub fn init() -> (SendSpawner, Board) {
    guard_below_ram();
    register_write(OUTPUT_CODE as usize, u32::from(config::DAC.zero_code));
    register_write(OUTPUT_RUN as usize, 0);
    register_write(DRIVER_ENABLE as usize, 0);
    time_driver::init();
    for irq in time_driver::IRQS {
        set_priority(irq, 0x00);
        // SAFETY: the time driver's handlers are ready (`time_driver::init` ran).
        unsafe { NVIC::unmask(irq) };
    }
    set_priority(Irq::ControlExecutor, 0x40);
    set_priority(Irq::TaskExecutor, TASK_PRIORITY);
    let control_spawner = CONTROL_EXECUTOR.start(Irq::ControlExecutor);
    let task_spawner = TASK_EXECUTOR.start(Irq::TaskExecutor);
    let board = Board {
        output: ReportingOutput::new(),
        driver_enable: EnableRegister,
        led: EmulatedPin,
        button: NoButton,
        watchdog: NoWatchdog,
        after_watchdog_reset: false,
        control_spawner,
        #[cfg(feature = "console")]
        console: uart::Uart::new(),
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

/// Thread mode has nothing to do: every task runs in an interrupt. It spins instead of sleeping
/// so that, under `-icount`, virtual time is exactly the instruction count: QEMU advances an idle
/// (`wfi`) CPU by host time, which would make runs differ.
pub fn sleep_forever() -> ! {
    loop {
        cortex_m::asm::nop();
    }
}

/// Set once the run ends with a failure, so that a fault while reporting only exits.
static ENDING: AtomicBool = AtomicBool::new(false);

/// Ends the emulation with a failure code, so a panic or fault fails the run: interrupts off,
/// then the output's state as its registers hold it (`EVT zero` if it holds the zero code,
/// `EVT enable`), then the exit.
pub fn after_fault() -> ! {
    cortex_m::interrupt::disable();
    if !ENDING.swap(true, Ordering::Relaxed) {
        let actual_tick = Instant::now()
            .as_ticks()
            .saturating_sub(critical_section::with(|cs| TIMELINE_TICKS.borrow(cs).get()));
        let code = register_read(OUTPUT_CODE as usize);
        if code == u32::from(config::DAC.zero_code) {
            trace::zero(actual_tick);
        } else {
            defmt::error!("the output holds code {=u32} at the end", code);
        }
        trace::enable(actual_tick, register_read(DRIVER_ENABLE as usize) != 0);
    }
    debug::exit(EXIT_FAILURE);
    sleep_forever()
}

/// Cycle whose first segment the output stage preloads late, once (`u32::MAX`: none).
static LATE_PRELOAD_CYCLE: AtomicU32 = AtomicU32::new(u32::MAX);
/// How far past its deadline the provoked late preload comes.
const LATE_PRELOAD_TICKS: u64 = 50;
/// Clock tick of actual tick 0 (the first restart), for the report at the end of a failed run.
static TIMELINE_TICKS: Mutex<Cell<u64>> = Mutex::new(Cell::new(u64::MAX));
/// The work per edge so far.
static EDGE_WORK: Mutex<Cell<EdgeWork>> = Mutex::new(Cell::new(EdgeWork {
    edges: 0,
    max_cycles: 0,
    total_cycles: 0,
}));

/// Work per edge: timer cycles from an edge (when the output switched) to the preload of the
/// next segment, wake-up included, over the edges whose next segment was preloaded in time.
#[derive(Clone, Copy)]
pub struct EdgeWork {
    pub edges: u32,
    pub max_cycles: u32,
    pub total_cycles: u64,
}

/// Makes the software preload the first segment of `cycle` after its deadline, as an overrun
/// would: the missed edge of a scripted run.
#[cfg(not(feature = "console"))]
fn provoke_late_preload(cycle: u32) {
    LATE_PRELOAD_CYCLE.store(cycle, Ordering::Relaxed);
}

/// The work per edge of the run so far.
#[cfg(not(feature = "console"))]
fn edge_work() -> EdgeWork {
    critical_section::with(|cs| EDGE_WORK.borrow(cs).get())
}

/// Holds the software up past `deadline_cycles` if `segment` is the one whose late preload the
/// scenario provoked: an overrun of the control loop.
fn overrun_if_provoked(segment: &Segment, deadline_cycles: u64) {
    let provoked = segment.starts_cycle()
        && LATE_PRELOAD_CYCLE
            .compare_exchange(
                segment.cycle as u32,
                u32::MAX,
                Ordering::Relaxed,
                Ordering::Relaxed,
            )
            .is_ok();
    if provoked {
        let late_cycles = deadline_cycles + LATE_PRELOAD_TICKS * CYCLES_PER_TICK;
        while time_driver::now_cycles() < late_cycles {}
    }
}

/// Adds one edge's work, in timer cycles, to the run's.
fn record_edge_work(cycles: u64) {
    let cycles = u32::try_from(cycles).unwrap_or(u32::MAX);
    critical_section::with(|cs| {
        let work = EDGE_WORK.borrow(cs);
        let mut sums = work.get();
        sums.edges += 1;
        sums.max_cycles = sums.max_cycles.max(cycles);
        sums.total_cycles += u64::from(cycles);
        work.set(sums);
    })
}

/// The output stage: TIM2's semantics on the emulated clock. Each segment takes effect on its
/// planned tick whatever the software does, which only preloads the next segment while the
/// current one plays. At each edge the model writes the segment's DAC code to [`OUTPUT_CODE`],
/// unless [`OUTPUT_RUN`] says the timer was stopped: then it plays no edge at all. A preload
/// after its deadline (the start of the segment it preloads) is too late: at the deadline the
/// update event found nothing new and the timer played the playing segment again, level and
/// length. The stage returns [`EdgeMissed`] and reports the replay (`EVT replay`) at the halt
/// that follows, with the output's zero (`EVT zero`), so that the report does not delay the
/// halt.
///
/// `actual` ticks count from the first restart on one timeline: the planned ticks until a halt,
/// after which the restart shifts the plan against it.
pub struct ReportingOutput {
    /// Clock tick of scheduler tick 0, set by each restart (wrapping).
    origin_ticks: u64,
    /// Clock tick of actual tick 0: the first restart.
    timeline_ticks: u64,
    /// The segment playing and its preload slack (`None`: restarted), until a halt.
    playing: Option<(Segment, Option<u32>)>,
    /// The preloaded segment, its slack and its DAC code.
    queued: Option<(Segment, u32, u32)>,
    /// The codes of the plan's levels; `None` (a refused acceleration): zero.
    levels: Option<DacLevels>,
    /// Timer cycle of the edge that began the playing segment, until the next preload.
    edge_cycles: Option<u64>,
    /// The missed edge's replay, until the halt reports it.
    replay: Option<Replay>,
}

/// At a missed edge the timer played `segment` again from `actual_tick`; `slack_ticks` is the
/// late preload's slack, `None` if software had not tried yet.
#[derive(Clone, Copy)]
struct Replay {
    segment: Segment,
    actual_tick: u64,
    slack_ticks: Option<i64>,
}

impl ReportingOutput {
    fn new() -> Self {
        Self {
            origin_ticks: 0,
            timeline_ticks: u64::MAX,
            playing: None,
            queued: None,
            levels: None,
            edge_cycles: None,
            replay: None,
        }
    }

    /// The DAC code of `segment`, at the zero code while the levels are refused.
    fn code(&self, segment: &Segment) -> u32 {
        let code = match &self.levels {
            Some(levels) => levels.code(segment.level, segment.amplitude),
            None => config::DAC.zero_code,
        };
        u32::from(code)
    }

    /// The clock tick of scheduler tick `tick`.
    fn clock_tick(&self, tick: u64) -> u64 {
        self.origin_ticks.wrapping_add(tick)
    }

    /// The actual tick of clock tick `clock_tick`.
    fn actual(&self, clock_tick: u64) -> u64 {
        clock_tick.saturating_sub(self.timeline_ticks)
    }
}

/// The operator's console on UART0, with recipes in RAM.
#[cfg(feature = "console")]
#[embassy_executor::task]
pub async fn console_task(port: uart::Uart, clock: TickClock) {
    crate::console::serve(port, RamRecipes::new(), clock).await
}

/// Recipe records in RAM: erased at every start of the emulation.
#[cfg(feature = "console")]
struct RamRecipes {
    records: [[u8; RECORD_LEN]; RECIPE_SLOTS],
}

#[cfg(feature = "console")]
impl RamRecipes {
    fn new() -> Self {
        Self {
            records: [[0xff; RECORD_LEN]; RECIPE_SLOTS],
        }
    }
}

#[cfg(feature = "console")]
impl RecipeStore for RamRecipes {
    type Error = Infallible;

    fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN] {
        self.records
            .get(slot.index())
            .copied()
            .unwrap_or([0xff; RECORD_LEN])
    }

    fn write(&mut self, slot: RecipeSlot, record: &[u8; RECORD_LEN]) -> Result<(), Infallible> {
        if let Some(stored) = self.records.get_mut(slot.index()) {
            *stored = *record;
        }
        Ok(())
    }
}

impl SegmentOutput for ReportingOutput {
    fn clock(&self) -> TickClock {
        TickClock::new(embassy_time::TICK_HZ as u32).with_min_segment_s(MIN_SEGMENT_S)
    }

    fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError> {
        // The same levels the board's DAC stage computes.
        self.levels = None;
        self.levels = Some(config::DAC.levels(peak_accel_mps2)?);
        Ok(())
    }

    fn restart(&mut self, segment: &Segment) {
        let now_ticks = Instant::now().as_ticks();
        self.origin_ticks = now_ticks.wrapping_sub(segment.start_tick);
        if now_ticks < self.timeline_ticks {
            self.timeline_ticks = now_ticks;
            critical_section::with(|cs| TIMELINE_TICKS.borrow(cs).set(now_ticks));
        }
        register_write(OUTPUT_CODE as usize, self.code(segment));
        register_write(OUTPUT_RUN as usize, 1);
        self.playing = Some((*segment, None));
        self.queued = None;
        self.edge_cycles = None;
    }

    fn preload(&mut self, segment: &Segment) -> Result<(), EdgeMissed> {
        let deadline_cycles = self.clock_tick(segment.start_tick) * CYCLES_PER_TICK;
        overrun_if_provoked(segment, deadline_cycles);
        let now_cycles = time_driver::now_cycles();
        if now_cycles >= deadline_cycles {
            self.replay = self.playing.map(|(playing, _)| Replay {
                segment: playing,
                actual_tick: self.actual(self.clock_tick(segment.start_tick)),
                slack_ticks: Some(
                    (deadline_cycles as i64 - now_cycles as i64).div_euclid(CYCLES_PER_TICK as i64),
                ),
            });
            return Err(EdgeMissed);
        }
        if let Some(edge_cycles) = self.edge_cycles.take() {
            record_edge_work(now_cycles - edge_cycles);
        }
        let slack_ticks = (deadline_cycles - now_cycles) / CYCLES_PER_TICK;
        self.queued = Some((*segment, slack_ticks as u32, self.code(segment)));
        Ok(())
    }

    async fn wait_edge(&mut self) -> Result<(), EdgeMissed> {
        let (segment, slack_ticks, code) = self.queued.take().ok_or(EdgeMissed)?;
        let edge_ticks = self.clock_tick(segment.start_tick);
        Timer::at(Instant::from_ticks(edge_ticks)).await;
        if register_read(OUTPUT_RUN as usize) == 0 {
            // A stopped timer has no further edge.
            core::future::pending::<()>().await;
        }
        register_write(OUTPUT_CODE as usize, code);
        self.playing = Some((segment, Some(slack_ticks)));
        let end_ticks = self.clock_tick(segment.end_tick());
        if Instant::now().as_ticks() >= end_ticks {
            // More than one edge has passed: the segment played, then the timer played it again.
            trace::segment(&segment, self.started(&segment));
            self.replay = Some(Replay {
                segment,
                actual_tick: self.actual(end_ticks),
                slack_ticks: None,
            });
            return Err(EdgeMissed);
        }
        self.edge_cycles = Some(edge_ticks * CYCLES_PER_TICK);
        Ok(())
    }

    fn halt(&mut self) {
        register_write(OUTPUT_CODE as usize, u32::from(config::DAC.zero_code));
        register_write(OUTPUT_RUN as usize, 0);
        let now_ticks = Instant::now().as_ticks();
        self.queued = None;
        self.edge_cycles = None;
        if let Some(replay) = self.replay.take() {
            trace::replay(&replay.segment, replay.actual_tick, replay.slack_ticks);
        }
        if self.playing.take().is_some() {
            trace::zero(self.actual(now_ticks));
        }
    }

    fn started(&self, segment: &Segment) -> SegmentStart {
        SegmentStart {
            tick: self.actual(self.clock_tick(segment.start_tick)),
            slack_ticks: self.playing.and_then(|(_, slack_ticks)| slack_ticks),
        }
    }
}

/// The driver enable, in [`DRIVER_ENABLE`].
pub struct EnableRegister;

impl ErrorType for EnableRegister {
    type Error = Infallible;
}

impl OutputPin for EnableRegister {
    fn set_low(&mut self) -> Result<(), Infallible> {
        register_write(DRIVER_ENABLE as usize, 0);
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        register_write(DRIVER_ENABLE as usize, 1);
        Ok(())
    }
}

/// The LED: no pin on this machine; its state shows in the log.
pub struct EmulatedPin;

impl ErrorType for EmulatedPin {
    type Error = Infallible;
}

impl OutputPin for EmulatedPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// The scenario presses no button.
pub struct NoButton;

impl ErrorType for NoButton {
    type Error = Infallible;
}

impl InputPin for NoButton {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(false)
    }

    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(true)
    }
}

impl Wait for NoButton {
    async fn wait_for_high(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }

    async fn wait_for_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }

    async fn wait_for_rising_edge(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }

    async fn wait_for_falling_edge(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }

    async fn wait_for_any_edge(&mut self) -> Result<(), Infallible> {
        core::future::pending().await
    }
}

/// QEMU models no independent watchdog for this machine; the monitor's feeding is a no-op.
pub struct NoWatchdog;

impl app::Watchdog for NoWatchdog {
    fn feed(&mut self) {}
}
