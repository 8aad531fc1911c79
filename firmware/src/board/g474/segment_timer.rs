//! The segment timer, which starts every segment in hardware, and TIM3, which counts its edges.
//!
//! The segment timer's TRGO (its update event) clocks TIM3, which so counts the edges in hardware:
//! the control loop decides from that count whether exactly one edge has passed, so an edge is
//! never lost to a late interrupt or to two updates that collapse into one pending interrupt. The
//! update interrupt only wakes the control loop.

use core::future::poll_fn;
use core::marker::PhantomData;
use core::sync::atomic::{AtomicU16, Ordering};
use core::task::Poll;

use embassy_stm32::interrupt::typelevel::{Binding, Handler, Interrupt};
use embassy_stm32::interrupt::Priority;
use embassy_stm32::pac;
use embassy_stm32::pac::timer::regs::{Cr1Gp16, EgrGp16};
use embassy_stm32::pac::timer::vals::Urs;
use embassy_stm32::pac::timer::TimCore;
use embassy_stm32::peripherals::TIM3;
use embassy_stm32::timer::low_level::{MasterMode, SlaveMode, Timer, TriggerSource};
use embassy_stm32::timer::{CoreInstance, GeneralInstance4Channel};
use embassy_stm32::Peri;
use embassy_sync::waitqueue::AtomicWaker;
use feeder_shared::plan::{EDGE_WORK_INSTRUCTIONS, EDGE_WORK_MARGIN};
use feeder_shared::Segment;

use super::pins::CORE_HZ;
use crate::output::EdgeMissed;

/// Cycles per instruction the edge work is given: Cortex-M4 code from flash at 4 wait states
/// behind the ART accelerator. The G474 twin bounds it from this image's own code
/// (`twin/tests/g474_image.rs`): the worst edge of a run with a start, a stop and the event
/// trace takes 5,103 instructions (14,070 bytes of code, 140 data reads from flash); with no
/// ART hit at all, every 8-byte line and every read a 5-cycle miss, nothing overlapped and each
/// instruction a cycle, that is at most 14,598 cycles, inside the 16,500 that
/// `EDGE_WORK_INSTRUCTIONS` × 1.5 gives (the 1,902 left over take the instructions of more than
/// a cycle: divisions, multiple loads). The firmware logs the measured cycles per edge (DWT)
/// every second on a real board.
const CYCLES_PER_INSTRUCTION: f64 = 1.5;

/// The shortest segment either output stage takes: the worst work per edge measured in
/// instructions, at this core's speed, times the margin (about 291 µs).
pub const MIN_SEGMENT_S: f64 =
    EDGE_WORK_MARGIN * EDGE_WORK_INSTRUCTIONS * CYCLES_PER_INSTRUCTION / CORE_HZ;

/// CR1 of a segment timer, stopped: ARPE (bit 7, the auto-reload is preloaded) and URS (bit 2,
/// only counter overflows raise the update interrupt), CEN (bit 0) clear.
pub const CR1_STOPPED: u32 = 1 << 7 | 1 << 2;
/// EGR with UG (bit 0): a forced update event.
pub const EGR_UPDATE: u32 = 1;

// The raw values above mean what their comments say, as the PAC decodes them.
const _: () = {
    let cr1 = Cr1Gp16(CR1_STOPPED);
    assert!(cr1.arpe() && !cr1.cen() && cr1.urs().to_bits() == Urs::COUNTER_ONLY.to_bits());
    assert!(EgrGp16(EGR_UPDATE).ug());
};

/// Wakes the control loop at every update event of the segment timer.
static EDGE_WAKER: AtomicWaker = AtomicWaker::new();
/// TIM3's count (see [`edges`]) when the playing segment began: the edges the control loop has
/// taken. Written by the control loop only.
static EDGES_TAKEN: AtomicU16 = AtomicU16::new(0);

/// Update interrupt of the segment timer `T`: wakes the control loop, which counts on TIM3.
pub struct UpdateInterrupt<T: CoreInstance>(PhantomData<T>);

impl<T: CoreInstance> Handler<T::UpdateInterrupt> for UpdateInterrupt<T> {
    unsafe fn on_interrupt() {
        // SAFETY: `T::regs` is the timer's register block.
        let status = unsafe { TimCore::from_ptr(T::regs()) }.sr();
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

/// A timer that starts each segment at its update event, with the next segment preloaded, and
/// the edge counter on its TRGO.
pub struct SegmentTimer<T: GeneralInstance4Channel> {
    timer: Timer<'static, T>,
    _edge_counter: Timer<'static, TIM3>,
    /// The power-up self-test saw TIM3 count a forced update.
    counts_edges: bool,
}

impl<T: GeneralInstance4Channel> SegmentTimer<T> {
    /// Makes `timer`, stopped and set up by its stage, the segment timer: TRGO on its update
    /// event, counted by TIM3 through `trgo` (TIM3's internal trigger from this timer), and its
    /// update interrupt raised by counter overflows (segment ends) only, not by forced updates,
    /// above every other interrupt.
    pub fn new(
        timer: Timer<'static, T>,
        edge_counter: Peri<'static, TIM3>,
        trgo: TriggerSource,
        _irq: impl Binding<T::UpdateInterrupt, UpdateInterrupt<T>>,
    ) -> Self {
        timer.set_master_mode(MasterMode::UPDATE);
        timer
            .regs_core()
            .cr1()
            .modify(|w| w.set_urs(Urs::COUNTER_ONLY));
        timer.enable_update_interrupt(true);
        let edge_counter = start_edge_counter(edge_counter, trgo);
        T::UpdateInterrupt::set_priority(Priority::P0);
        T::UpdateInterrupt::unpend();
        // SAFETY: the handler touches only this timer's flag and the waker.
        unsafe { T::UpdateInterrupt::enable() };
        let mut segment_timer = Self {
            timer,
            _edge_counter: edge_counter,
            counts_edges: false,
        };
        segment_timer.counts_edges = segment_timer.self_test();
        segment_timer
    }

    /// The power-up self-test: a forced update of the stopped timer must reach TIM3 through
    /// TRGO as one edge, else edges cannot be counted and the output must not start.
    fn self_test(&mut self) -> bool {
        let before = edges();
        self.forced_update();
        // TIM3 counts the trigger a few timer cycles after the update event.
        cortex_m::asm::delay(16);
        let counted = edges() == before.wrapping_add(1);
        if !counted {
            defmt::error!(
                "self-test: the edge counter (TIM3) did not count the segment timer's forced update"
            );
        }
        counted
    }

    /// Whether the power-up self-test saw the edge counter count.
    pub fn counts_edges(&self) -> bool {
        self.counts_edges
    }

    /// The timer, for its stage's own registers.
    pub fn timer(&self) -> &Timer<'static, T> {
        &self.timer
    }

    /// Stops the timer and loads a first segment: `write` writes it, then a forced update makes
    /// it active. Start the timer with [`SegmentTimer::start`].
    pub fn stop_and_load(&mut self, write: impl FnOnce(&Timer<'static, T>)) {
        self.timer.stop();
        self.timer.reset();
        write(&self.timer);
        self.forced_update();
        // Clears the pending update flag by a write (the flags are rc_w0, see
        // [`UpdateInterrupt`]).
        self.timer.regs_core().sr().write(|w| {
            w.0 = !0;
            w.set_uif(false)
        });
    }

    /// Starts the loaded timer: the output's timeline resumes at `start_tick`, where the
    /// position sensor (with `encoder`) restarts its sampling.
    pub fn start(&mut self, start_tick: u64) {
        self.timer.enable_update_dma(false);
        #[cfg(feature = "encoder")]
        super::encoder::restart(start_tick, || self.timer.start());
        #[cfg(not(feature = "encoder"))]
        {
            let _ = start_tick;
            self.timer.start();
        }
    }

    /// Before `segment` is preloaded: with `encoder`, the update event that begins it captures
    /// the encoder's count if it starts a cycle.
    pub fn prepare_capture(&self, segment: &Segment) {
        #[cfg(feature = "encoder")]
        super::encoder::prepare_capture(segment, |on| self.timer.enable_update_dma(on));
        #[cfg(not(feature = "encoder"))]
        let _ = segment;
    }

    pub fn stop(&mut self) {
        self.timer.stop();
    }

    /// Forces an update event of the stopped timer: its preloaded registers load and its TRGO
    /// fires, which TIM3 counts as one edge, taken here as the control loop's own (URS keeps the
    /// update interrupt quiet).
    pub fn forced_update(&mut self) {
        EDGES_TAKEN.store(edges().wrapping_add(1), Ordering::Relaxed);
        self.timer.regs_core().egr().write(|w| w.set_ug(true));
    }

    /// Ends a preload whose writes have been issued: fails if an edge came before they were
    /// done, which may have split the preload across two segments. TIM3 counts that edge a few
    /// timer cycles after the update event; UIF shows it at once, until the update interrupt,
    /// which preempts this code, clears it.
    pub fn confirm_preload(&self) -> Result<(), EdgeMissed> {
        // The writes done (some on another bus) before the checks.
        cortex_m::asm::dsb();
        let update_pending = self.timer.regs_core().sr().read().uif();
        if update_pending || edges() != EDGES_TAKEN.load(Ordering::Relaxed) {
            return Err(EdgeMissed);
        }
        Ok(())
    }

    /// Waits until the preloaded segment has begun; fails if more than one edge has passed.
    pub async fn wait_edge(&mut self) -> Result<(), EdgeMissed> {
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
        if now.wrapping_sub(taken) == 1 {
            Ok(())
        } else {
            Err(EdgeMissed)
        }
    }
}

/// Whether the segment timer replays a segment: two or more edges past the ones the control loop
/// has taken mean that it has started the playing segment again.
pub fn replaying() -> bool {
    edges().wrapping_sub(EDGES_TAKEN.load(Ordering::Relaxed)) >= 2
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
