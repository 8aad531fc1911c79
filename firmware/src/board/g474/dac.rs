//! The DAC output stage: the analog command on PA4 (DAC1 channel 1), edges timed by TIM2.

use embassy_stm32::dac::{ChannelTrigger, DacChannel, Value};
use embassy_stm32::mode::Blocking;
use embassy_stm32::peripherals::{DAC1, PA4, PA8, PA9, TIM1, TIM2, TIM3};
use embassy_stm32::timer::low_level::{Timer, TriggerSource};
use embassy_stm32::{bind_interrupts, pac, triggers, Peri};
use feeder_shared::configuration::Configuration;
use feeder_shared::{DriveError, Segment, TickClock};

use super::pins::DRIVER_DISABLE;
use super::segment_timer::{SegmentTimer, UpdateInterrupt, CR1_STOPPED, EGR_UPDATE, MIN_SEGMENT_S};
use crate::config;
use crate::output::{DacCodes, EdgeMissed, SegmentOutput, SegmentStart, TrimmedCycle};
use crate::ports::RegisterWrite;

/// DAC1_DHR12R1: channel 1's 12-bit right-aligned holding register.
const DAC1_DHR12R1: u32 = 0x5000_0808;
/// TIM2's control register 1, interrupt enable and event generation registers.
const TIM2_CR1: u32 = 0x4000_0000;
const TIM2_DIER: u32 = 0x4000_000C;
const TIM2_EGR: u32 = 0x4000_0014;

bind_interrupts!(struct Irqs {
    TIM2 => UpdateInterrupt<TIM2>;
});

/// Analog command on PA4, edges timed by TIM2 and counted by TIM3.
pub struct DacStage {
    dac: DacChannel<'static, Blocking>,
    timer: SegmentTimer<TIM2>,
    codes: DacCodes,
    /// Preload slack of the preloaded segment and of the playing one (`None`: restarted).
    queued_slack_ticks: Option<u32>,
    playing_slack_ticks: Option<u32>,
}

impl DacStage {
    /// The stage's name in the log.
    pub const NAME: &str = "Dac";

    /// The stores that make the output safe, in order, made by the HardFault entry before it
    /// touches the stack.
    ///
    /// The driver enable goes low first, then the command goes to zero: the zero code into the
    /// holding register, then a forced update of TIM2, whose TRGO is the DAC's trigger (TEN set),
    /// so the code reaches the output three bus clock cycles later (RM0440, DAC, "DAC
    /// conversion"); an update of TIM2's own between the two stores latches the zero code as
    /// well. The trigger stays on: clearing TEN with a plain store would have to repeat every
    /// other bit of DAC_CR. Then TIM2 stops, with its update interrupt off. TIM1, which this image
    /// does not clock, is not stored to.
    #[allow(
        clippy::declare_interior_mutable_const,
        reason = "copied once into the board's static table, whose zero code power-up sets"
    )]
    pub const SAFE_STATE_WRITES: [RegisterWrite; 5] = [
        DRIVER_DISABLE,
        RegisterWrite::new(DAC1_DHR12R1, config::CONFIGURATION.dac.zero_code as u32),
        RegisterWrite::new(TIM2_EGR, EGR_UPDATE),
        RegisterWrite::new(TIM2_CR1, CR1_STOPPED),
        RegisterWrite::new(TIM2_DIER, 0),
    ];

    /// The store of [`Self::SAFE_STATE_WRITES`] that writes the zero code.
    const ZERO_CODE_WRITE: usize = 1;

    /// Whether the power-up self-test saw the edge counter count (`SegmentTimer`).
    pub fn counts_edges(&self) -> bool {
        self.timer.counts_edges()
    }

    /// Takes the peripherals of both stages, so that the board builds either the same way; this
    /// one leaves TIM1, PA8 and PA9 in their reset state.
    pub fn new(
        dac: Peri<'static, DAC1>,
        pin: Peri<'static, PA4>,
        tim: Peri<'static, TIM2>,
        _pwm_timer: Peri<'static, TIM1>,
        _magnitude_pin: Peri<'static, PA8>,
        _direction_pin: Peri<'static, PA9>,
        edge_counter: Peri<'static, TIM3>,
    ) -> Self {
        let mut dac = DacChannel::new_blocking(dac, pin);
        // Untriggered, the zero code reaches the pin at once.
        dac.set(Value::Bit12Right(config::CONFIGURATION.dac.zero_code));
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
        Self {
            dac,
            timer: SegmentTimer::new(timer, edge_counter, TriggerSource::ITR1, Irqs),
            codes: DacCodes::new(config::CONFIGURATION.dac),
            queued_slack_ticks: None,
            playing_slack_ticks: None,
        }
    }
}

impl SegmentOutput for DacStage {
    fn clock(&self) -> TickClock {
        TickClock::new(self.timer.timer().get_clock_frequency().0).with_min_segment_s(MIN_SEGMENT_S)
    }

    fn level_step_mps2(&self) -> f64 {
        self.codes.level_step_mps2()
    }

    fn calibrate(&mut self, configuration: &Configuration) {
        self.codes.calibrate(configuration.dac);
        let zero_code = self.codes.zero_code();
        super::SAFE_STATE_WRITES[Self::ZERO_CODE_WRITE].set(u32::from(zero_code));
        self.dac.set(Value::Bit12Right(zero_code));
        self.timer.forced_update();
    }

    fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError> {
        self.codes.set_peak_accel(peak_accel_mps2)
    }

    fn trim(&mut self, trimmed: &TrimmedCycle) -> Result<(), DriveError> {
        self.codes.trim(trimmed)
    }

    fn restart(&mut self, segment: &Segment) {
        let code = self.codes.code(segment);
        let dac = &mut self.dac;
        self.timer.stop_and_load(|timer| {
            dac.set(Value::Bit12Right(code));
            timer
                .regs_gp32()
                .arr()
                .write_value(segment.ticks.saturating_sub(1));
        });
        self.queued_slack_ticks = None;
        self.playing_slack_ticks = None;
        self.timer.start(segment.start_tick);
    }

    /// Writes the next code and length and keeps the slack left when they were written (the
    /// playing segment's auto-reload + 1 − the count).
    fn preload(&mut self, segment: &Segment) -> Result<(), EdgeMissed> {
        // A one-tick segment would stop the counter (auto-reload 0) and cannot be prepared.
        if segment.ticks < 2 {
            return Err(EdgeMissed);
        }
        self.timer.prepare_capture(segment);
        let counter = self.timer.timer().regs_gp32();
        let playing_reload = counter.arr().read();
        self.dac.set(Value::Bit12Right(self.codes.code(segment)));
        counter.arr().write_value(segment.ticks - 1);
        self.queued_slack_ticks = Some(
            playing_reload
                .wrapping_add(1)
                .wrapping_sub(counter.cnt().read()),
        );
        self.timer.confirm_preload()
    }

    async fn wait_edge(&mut self) -> Result<(), EdgeMissed> {
        let edge = self.timer.wait_edge().await;
        self.playing_slack_ticks = self.queued_slack_ticks.take();
        edge
    }

    fn halt(&mut self) {
        self.timer.stop();
        self.dac.set(Value::Bit12Right(self.codes.zero_code()));
        self.timer.forced_update();
    }

    fn started(&self, segment: &Segment) -> SegmentStart {
        SegmentStart {
            // The timer's update event starts every segment exactly on its planned tick.
            tick: segment.start_tick,
            slack_ticks: self.playing_slack_ticks,
        }
    }
}
