//! The plate's position sensor (`--features encoder`): an incremental quadrature encoder on
//! TIM4 (A on PB6, B on PB7), sampled by DMA at instants of the output's clock.
//!
//! Assumed encoder: a linear scale with A/B square-wave outputs (3.3 V, or 5 V through a level
//! shifter: PB6 and PB7 are 5 V tolerant) and a 4 µm signal period, counted on all four edges:
//! 1 µm per count, the configuration's default (`encoder_um`, and `encoder_dir` for an encoder
//! that counts down when the plate moves forward). The count is zero where the plate rests at power-up. TIM4's
//! 16-bit count is extended to `i32` by unwrapping, which holds as long as two readings in a row
//! are less than 32 768 counts (32.8 mm, far beyond the plate's stroke) apart.
//!
//! Sampling, all in hardware on the 170 MHz timer clock that also clocks the segment timer:
//! - **Samples every 250 µs.** TIM6 overflows every [`SAMPLE_PERIOD_S`]; its update DMA request
//!   moves TIM4's count into a circular buffer (DMA1 channel 1). When the output restarts,
//!   TIM6 is preset and started together with the segment timer so that it overflows at every
//!   multiple of 250 µs of the output's timeline, where each sample's tick follows from its index.
//! - **A capture at every cycle start.** Each time the output stage preloads a segment that
//!   starts a cycle, the segment timer's update DMA request is enabled for that one update and
//!   DMA1 channel 2 is armed for one transfer: the update event that begins the cycle moves TIM4's
//!   count into memory. At a restart, whose forced update raises no DMA request, the count is
//!   read right after the segment timer is started instead.
//!
//! Timing error: each DMA transfer reads the count a few bus cycles after its event (about
//! 0.05 µs); TIM6 is started one register store before the segment timer (a few core cycles,
//! under 0.1 µs), which stamps every sample that much early; the restart capture is read a few
//! core cycles after the start. At the plate's speeds (under 1 m/s) each is below a tenth of a
//! count. With `output-pwm` the output's tick is a carrier period: sample ticks are rounded to
//! the nearest tick when 250 µs is not a whole number of them.
//!
//! Built but not yet verified on hardware.

use core::cell::{RefCell, UnsafeCell};
use core::sync::atomic::{AtomicBool, Ordering};

use embassy_stm32::pac;
use embassy_stm32::pac::bdma::vals::{Dir, Pl, Size};
use embassy_stm32::pac::timer::vals::FilterValue;
use embassy_stm32::peripherals::{DMA1_CH1, DMA1_CH2, PB6, PB7, TIM4, TIM6};
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::timer::qei::{Config as QeiConfig, Qei, QeiMode};
use embassy_stm32::timer::{BasicInstance, UpDma};
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use feeder_shared::closed_loop::PositionSample;
use feeder_shared::configuration::EncoderSetup;
use feeder_shared::{Segment, TickClock};

use crate::ports::PositionSensor;

/// The interval between two samples.
pub const SAMPLE_PERIOD_S: f64 = 250e-6;

/// Slots of the samples' circular buffer: 64 ms, three cycles at the lowest frequency.
const SAMPLE_SLOTS: usize = 256;
/// Cycle-start captures kept until taken.
const CAPTURE_SLOTS: usize = 4;

/// DMA1 channel 1 (index 0, on DMAMUX1 channel 0): the samples.
const SAMPLE_DMA: usize = 0;
/// DMA1 channel 2 (index 1, on DMAMUX1 channel 1): the cycle-start captures.
const CAPTURE_DMA: usize = 1;

/// Memory that DMA writes and the CPU reads.
struct DmaBuffer<const N: usize>(UnsafeCell<[u16; N]>);

// SAFETY: the CPU only reads it, with volatile reads; DMA writes it.
unsafe impl<const N: usize> Sync for DmaBuffer<N> {}

impl<const N: usize> DmaBuffer<N> {
    const fn new() -> Self {
        Self(UnsafeCell::new([0; N]))
    }

    fn address(&self, index: usize) -> u32 {
        self.0.get().cast::<u16>().wrapping_add(index % N) as u32
    }

    fn read(&self, index: usize) -> u16 {
        // SAFETY: in bounds; DMA writes whole half-words.
        unsafe { core::ptr::read_volatile(self.0.get().cast::<u16>().add(index % N)) }
    }
}

static SAMPLES: DmaBuffer<SAMPLE_SLOTS> = DmaBuffer::new();
static CAPTURES: DmaBuffer<CAPTURE_SLOTS> = DmaBuffer::new();

/// The output's timeline as the sampling sees it, written by the output stage.
struct Timeline {
    /// Timer clocks per output tick.
    clocks_per_tick: u64,
    /// Timer clocks per sample.
    clocks_per_sample: u64,
    /// Counts up at every restart of the output.
    epoch: u32,
    /// The tick of the last restart and the count read at it.
    start_tick: u64,
    start_count: u16,
    /// Sample `k` (from 1) is taken at timer clock `(first_sample + k - 1) · clocks_per_sample`
    /// of the output's timeline (tick · clocks per tick) and lands in slot `(k - 1) % SLOTS`.
    first_sample: u64,
    /// Cycle-start captures: the tick each slot of [`CAPTURES`] was armed for, and the slot
    /// armed last (`None`: none since the restart).
    capture_ticks: [Option<u64>; CAPTURE_SLOTS],
    armed: Option<usize>,
}

static TIMELINE: Mutex<CriticalSectionRawMutex, RefCell<Timeline>> =
    Mutex::new(RefCell::new(Timeline {
        clocks_per_tick: 1,
        clocks_per_sample: 1,
        epoch: 0,
        start_tick: 0,
        start_count: 0,
        first_sample: 0,
        capture_ticks: [None; CAPTURE_SLOTS],
        armed: None,
    }));

/// TIM4's count.
fn count() -> u16 {
    pac::TIM4.cnt().read().cnt()
}

/// Points DMA1 channel `index` at TIM4's count and `memory`, for `transfers` half-words, and
/// enables it.
fn start_dma(index: usize, memory: u32, transfers: u16, circular: bool) {
    let channel = pac::DMA1.ch(index);
    channel.cr().write(|w| w.set_en(false));
    channel.par().write_value(pac::TIM4.cnt().as_ptr() as u32);
    channel.mar().write_value(memory);
    channel.ndtr().write(|w| w.set_ndt(transfers));
    channel.cr().write(|w| {
        w.set_dir(Dir::FROM_PERIPHERAL);
        w.set_psize(Size::BITS16);
        w.set_msize(Size::BITS16);
        w.set_minc(true);
        w.set_circ(circular);
        w.set_pl(Pl::VERY_HIGH);
        w.set_en(true);
    });
}

/// At a restart of the output at `start_tick`, with the segment timer loaded and stopped and its
/// update DMA request off: restarts the samples in phase with the output's timeline, then
/// `start` starts the segment timer right after TIM6, and the count is captured.
pub fn restart(start_tick: u64, start: impl FnOnce()) {
    TIMELINE.lock(|timeline| {
        let mut timeline = timeline.borrow_mut();
        let timer = pac::TIM6;
        timer.cr1().write(|w| w.set_cen(false));
        timer.dier().write(|w| w.set_ude(false));
        let clock = start_tick.wrapping_mul(timeline.clocks_per_tick);
        let phase = clock % timeline.clocks_per_sample;
        timer.cnt().write(|w| w.set_cnt(phase as u16));
        start_dma(SAMPLE_DMA, SAMPLES.address(0), SAMPLE_SLOTS as u16, true);
        timer.dier().write(|w| w.set_ude(true));
        // Nothing runs between the two starts: this runs in a critical section.
        timer.cr1().write(|w| w.set_cen(true));
        start();
        timeline.start_count = count();
        timeline.start_tick = start_tick;
        timeline.first_sample = clock / timeline.clocks_per_sample + 1;
        timeline.epoch = timeline.epoch.wrapping_add(1);
        timeline.capture_ticks = [None; CAPTURE_SLOTS];
        timeline.armed = None;
    });
}

/// When the output stage preloads `segment`, before the update event that begins it:
/// `update_dma` sets the segment timer's update DMA request, on for a segment that starts a
/// cycle (with DMA1 channel 2 armed for one capture), off for any other.
pub fn prepare_capture(segment: &Segment, update_dma: impl Fn(bool)) {
    // Off first: a request left pending is dropped, not served when the channel is armed.
    update_dma(false);
    if !segment.starts_cycle() {
        return;
    }
    TIMELINE.lock(|timeline| {
        let mut timeline = timeline.borrow_mut();
        let slot = timeline.armed.map_or(0, |slot| (slot + 1) % CAPTURE_SLOTS);
        if let Some(last) = timeline.armed {
            // The capture armed last has been made unless its update never came.
            if pac::DMA1.ch(CAPTURE_DMA).ndtr().read().ndt() != 0 {
                timeline.capture_ticks[last] = None;
            }
        }
        start_dma(CAPTURE_DMA, CAPTURES.address(slot), 1, false);
        timeline.capture_ticks[slot] = Some(segment.start_tick);
        timeline.armed = Some(slot);
    });
    update_dma(true);
}

/// The quadrature encoder on TIM4, sampled on the output's clock.
pub struct Encoder {
    _qei: Qei<'static, TIM4>,
    _sample_timer: Timer<'static, TIM6>,
    _sample_dma: Peri<'static, DMA1_CH1>,
    _capture_dma: Peri<'static, DMA1_CH2>,
    /// The epoch of the last take and the index of the last sample it took.
    epoch: u32,
    last_sample: u64,
    /// The last count read and its unwrapped value.
    last_count: u16,
    position_counts: i32,
    /// How the counts become positions.
    setup: EncoderSetup,
}

impl Encoder {
    /// Starts the encoder count and sets up the sampling for an output whose segment timer is
    /// `S` and whose clock is `clock`; the samples start at the output's first restart, and
    /// count as `setup` says.
    #[allow(clippy::too_many_arguments)]
    pub fn new<S: BasicInstance>(
        tim: Peri<'static, TIM4>,
        a: Peri<'static, PB6>,
        b: Peri<'static, PB7>,
        sample_timer: Peri<'static, TIM6>,
        sample_dma: Peri<'static, DMA1_CH1>,
        capture_dma: Peri<'static, DMA1_CH2>,
        clock: TickClock,
        setup: EncoderSetup,
    ) -> Self
    where
        DMA1_CH2: UpDma<S>,
    {
        let qei = Qei::new(
            tim,
            a,
            b,
            QeiConfig {
                mode: QeiMode::Mode3,
                ..QeiConfig::default()
            },
        );
        // A pulse on A or B shorter than eight timer clocks (47 ns) is no edge: IC1F and IC2F =
        // 0011, fSAMPLING = fCK_INT, N = 8 (RM0440, TIM2/TIM3/TIM4/TIM5, "TIMx_CCMR1"). At
        // 1 µm a count and 1 m/s a channel's edges come every 2 µs.
        pac::TIM4.ccmr_input(0).modify(|w| {
            w.set_icf(0, FilterValue::FCK_INT_N8);
            w.set_icf(1, FilterValue::FCK_INT_N8);
        });
        let sample_request = <DMA1_CH1 as UpDma<TIM6>>::request(&sample_dma);
        let capture_request = <DMA1_CH2 as UpDma<S>>::request(&capture_dma);
        let timer = Timer::new(sample_timer);
        let timer_hz = u64::from(timer.get_clock_frequency().0);
        let clocks_per_sample = (timer_hz as f64 * SAMPLE_PERIOD_S) as u64;
        let clocks_per_tick = (timer_hz / u64::from(clock.hz.max(1))).max(1);
        if clocks_per_tick * u64::from(clock.hz) != timer_hz {
            defmt::warn!("encoder: the output's clock does not divide the timer clock");
        }
        let registers = timer.regs_basic();
        registers.psc().write_value(0);
        registers
            .arr()
            .write(|w| w.set_arr((clocks_per_sample - 1) as u16));
        // Stopped with the segment timer on a debugger halt, so that it stays in step.
        pac::DBGMCU.apb1lfzr().modify(|w| w.set_tim6(true));
        pac::RCC.ahb1enr().modify(|w| {
            w.set_dma1en(true);
            w.set_dmamux1en(true);
        });
        pac::DMAMUX1
            .ccr(SAMPLE_DMA)
            .write(|w| w.set_dmareq_id(sample_request));
        pac::DMAMUX1
            .ccr(CAPTURE_DMA)
            .write(|w| w.set_dmareq_id(capture_request));
        TIMELINE.lock(|timeline| {
            let mut timeline = timeline.borrow_mut();
            timeline.clocks_per_tick = clocks_per_tick;
            timeline.clocks_per_sample = clocks_per_sample;
        });
        let last_count = count();
        Self {
            _qei: qei,
            _sample_timer: timer,
            _sample_dma: sample_dma,
            _capture_dma: capture_dma,
            epoch: 0,
            last_sample: 0,
            last_count,
            position_counts: 0,
            setup,
        }
    }

    /// The position of `count`, unwrapped from the last count read: the middle of the count.
    fn position_m(&mut self, count: u16) -> f64 {
        self.position_counts = self
            .position_counts
            .wrapping_add(i32::from(count.wrapping_sub(self.last_count) as i16));
        self.last_count = count;
        self.setup.position_m(self.position_counts)
    }
}

/// What [`Encoder::take_until`] needs of the timeline, copied out of its lock.
struct View {
    epoch: u32,
    clocks_per_tick: u64,
    clocks_per_sample: u64,
    first_sample: u64,
    /// The count captured at the tick asked for.
    capture: Option<u16>,
}

/// Whether the sampling's DMA has stopped: a transfer error (TEIF) disables its channel, and the
/// buffers would then hand the last counts on as new ones. Logged the first time.
fn sampling_failed() -> bool {
    static REPORTED: AtomicBool = AtomicBool::new(false);
    let status = pac::DMA1.isr().read();
    let failed = status.teif(SAMPLE_DMA)
        || status.teif(CAPTURE_DMA)
        || !pac::DMA1.ch(SAMPLE_DMA).cr().read().en();
    if failed && !REPORTED.swap(true, Ordering::Relaxed) {
        defmt::error!(
            "encoder: the sampling DMA stopped (transfer error or channel off): no position is \
             taken from it"
        );
    }
    failed
}

impl PositionSensor for Encoder {
    const PRESENT: bool = true;

    /// Nothing once the sampling's DMA has stopped ([`sampling_failed`]): the closed loop then
    /// stops on the missing capture.
    fn take_until(&mut self, tick: u64, out: &mut [PositionSample]) -> usize {
        if sampling_failed() {
            return 0;
        }
        let Some(view) = TIMELINE.lock(|timeline| {
            let timeline = timeline.borrow();
            if tick < timeline.start_tick || out.is_empty() {
                return None;
            }
            let capture = if tick == timeline.start_tick {
                Some(timeline.start_count)
            } else {
                let done = |slot: usize| {
                    Some(slot) != timeline.armed
                        || pac::DMA1.ch(CAPTURE_DMA).ndtr().read().ndt() == 0
                };
                (0..CAPTURE_SLOTS)
                    .find(|&slot| timeline.capture_ticks[slot] == Some(tick) && done(slot))
                    .map(|slot| CAPTURES.read(slot))
            };
            Some(View {
                epoch: timeline.epoch,
                clocks_per_tick: timeline.clocks_per_tick,
                clocks_per_sample: timeline.clocks_per_sample,
                first_sample: timeline.first_sample,
                capture,
            })
        }) else {
            return 0;
        };
        let Some(capture) = view.capture else {
            return 0;
        };
        if view.epoch != self.epoch {
            self.epoch = view.epoch;
            self.last_sample = 0;
        }
        // Samples 1..=newest are before `tick`; the ones taken before and those that do not
        // fit (beside the capture) are left out.
        let clock = tick.wrapping_mul(view.clocks_per_tick);
        let newest = (clock.saturating_sub(1) / view.clocks_per_sample + 1)
            .saturating_sub(view.first_sample);
        let room = (out.len() - 1).min(SAMPLE_SLOTS - 1) as u64;
        let first = (self.last_sample + 1).max((newest + 1).saturating_sub(room));
        let mut counts = [0u16; SAMPLE_SLOTS];
        let taken = (newest + 1).saturating_sub(first) as usize;
        for (offset, slot) in counts[..taken].iter_mut().enumerate() {
            *slot = SAMPLES.read((first as usize + offset - 1) % SAMPLE_SLOTS);
        }
        // Samples written by now (at least `newest`): DMA may have overwritten the oldest slots
        // before or while they were read.
        let remaining = usize::from(pac::DMA1.ch(SAMPLE_DMA).ndtr().read().ndt());
        let next_slot = (SAMPLE_SLOTS - remaining) % SAMPLE_SLOTS;
        let behind = (next_slot + SAMPLE_SLOTS - newest as usize % SAMPLE_SLOTS) % SAMPLE_SLOTS;
        let written = newest + behind as u64;
        let valid_from = first.max(written.saturating_sub(SAMPLE_SLOTS as u64 - 1));
        if TIMELINE.lock(|timeline| timeline.borrow().epoch) != view.epoch {
            // The output restarted meanwhile: the buffer was reset.
            return 0;
        }
        let mut kept = 0;
        for index in valid_from..=newest {
            let sample_clock = (view.first_sample + index - 1) * view.clocks_per_sample;
            out[kept] = PositionSample {
                tick: (sample_clock + view.clocks_per_tick / 2) / view.clocks_per_tick,
                position_m: self.position_m(counts[(index - first) as usize]),
            };
            kept += 1;
        }
        self.last_sample = self.last_sample.max(newest);
        out[kept] = PositionSample {
            tick,
            position_m: self.position_m(capture),
        };
        kept + 1
    }
}
