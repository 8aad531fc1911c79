//! The PWM + direction output stage (`--features output-pwm`): PWM magnitude on PA8 and direction
//! on PA9 (high = forward), for H-bridge drivers; segments counted in carrier periods by TIM1's
//! repetition counter.

use embassy_stm32::gpio::OutputType;
use embassy_stm32::pac::timer::regs::BdtrAdv;
use embassy_stm32::pac::timer::vals::{Bkp, Ossi};
use embassy_stm32::peripherals::{DAC1, PA4, PA8, PA9, TIM1, TIM2, TIM3};
use embassy_stm32::timer::low_level::{OutputCompareMode, Timer, TriggerSource};
use embassy_stm32::timer::simple_pwm::PwmPin;
use embassy_stm32::timer::{Ch1, Ch2, Channel};
use embassy_stm32::{bind_interrupts, pac, Peri};
use feeder_shared::configuration::Configuration;
use feeder_shared::{
    Direction, DriveError, PwmCalibration, PwmCommand, PwmLevels, Segment, TickClock,
};

use super::pins::DRIVER_DISABLE;
use super::segment_timer::{SegmentTimer, UpdateInterrupt, CR1_STOPPED, MIN_SEGMENT_S};
use crate::config;
use crate::output::{EdgeMissed, SegmentOutput, SegmentStart, TrimmedCycle, TrimmedLevels};
use crate::ports::RegisterWrite;

/// TIM1's control register 1, interrupt enable and break and dead-time registers.
const TIM1_CR1: u32 = 0x4001_2C00;
const TIM1_DIER: u32 = 0x4001_2C0C;
const TIM1_BDTR: u32 = 0x4001_2C44;

/// TIM1's BDTR with the main output off: BKP (bit 13, break active high), BKE (bit 12, break
/// enabled: a core lockup clears MOE) and OSSI (bit 10: with MOE clear the outputs are driven to
/// their idle level, low); MOE (bit 15) clear (RM0440, TIM1/TIM8/TIM20, "TIMx break and dead-time
/// register").
const BDTR_OUTPUT_OFF: u32 = 1 << 13 | 1 << 12 | 1 << 10;

// The raw value above means what its comment says, as the PAC decodes it.
const _: () = {
    let bdtr = BdtrAdv(BDTR_OUTPUT_OFF);
    assert!(bdtr.bke(0) && !bdtr.moe() && !bdtr.aoe());
    assert!(bdtr.bkp(0).to_bits() == Bkp::ACTIVE_HIGH.to_bits());
    assert!(bdtr.ossi().to_bits() == Ossi::IDLE_LEVEL.to_bits());
};

bind_interrupts!(struct Irqs {
    TIM1_UP_TIM16 => UpdateInterrupt<TIM1>;
});

/// PWM magnitude on PA8 and direction on PA9 (high = forward), segments counted in carrier
/// periods by TIM1's repetition counter and in segments by TIM3.
pub struct PwmStage {
    timer: SegmentTimer<TIM1>,
    _magnitude: PwmPin<'static, TIM1, Ch1>,
    _direction: PwmPin<'static, TIM1, Ch2>,
    /// Timer counts per carrier period (100 % duty).
    period_counts: u16,
    clock: TickClock,
    /// The driver input's calibration.
    calibration: PwmCalibration,
    levels: Option<PwmLevels>,
    /// The closed loop's levels of the cycle it trimmed last.
    trimmed: Option<TrimmedLevels<PwmCommand>>,
}

impl PwmStage {
    /// The stage's name in the log.
    pub const NAME: &str = "PwmDir";

    /// The stores that make the output safe, in order, made by the HardFault entry before it
    /// touches the stack.
    ///
    /// The driver enable goes low first, then TIM1's main output goes off, which drives PA8 and
    /// PA9 low at once; then TIM1 stops, with its update interrupt off. TIM2 and the DAC, which
    /// this image does not clock, are not stored to.
    #[allow(
        clippy::declare_interior_mutable_const,
        reason = "copied once into the board's static table"
    )]
    pub const SAFE_STATE_WRITES: [RegisterWrite; 4] = [
        DRIVER_DISABLE,
        RegisterWrite::new(TIM1_BDTR, BDTR_OUTPUT_OFF),
        RegisterWrite::new(TIM1_CR1, CR1_STOPPED),
        RegisterWrite::new(TIM1_DIER, 0),
    ];

    /// Whether the power-up self-test saw the edge counter count (`SegmentTimer`).
    pub fn counts_edges(&self) -> bool {
        self.timer.counts_edges()
    }

    /// Takes the peripherals of both stages, so that the board builds either the same way; this
    /// one leaves DAC1, PA4 and TIM2 in their reset state.
    pub fn new(
        _dac: Peri<'static, DAC1>,
        _dac_pin: Peri<'static, PA4>,
        _dac_timer: Peri<'static, TIM2>,
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
        registers.bdtr().write_value(BdtrAdv(BDTR_OUTPUT_OFF));
        Self {
            timer: SegmentTimer::new(timer, edge_counter, TriggerSource::ITR0, Irqs),
            _magnitude: magnitude,
            _direction: direction,
            period_counts,
            // The repetition counter has 16 bits.
            clock: TickClock::new(carrier_hz)
                .with_max_segment_ticks(1 << 16)
                .with_min_segment_s(MIN_SEGMENT_S),
            calibration: config::CONFIGURATION.pwm,
            levels: None,
            trimmed: None,
        }
    }

    /// What `segment` sets: zero while the levels are refused.
    fn compares(&self, segment: &Segment) -> Compares {
        let trimmed = self.trimmed.and_then(|trimmed| trimmed.of(segment));
        let (duty, direction) = match (trimmed, self.levels) {
            (Some(command), Some(_)) => (command.duty_counts, command.direction),
            (None, Some(levels)) => {
                let command = levels.command(segment.level, segment.amplitude);
                (command.duty_counts, command.direction)
            }
            (_, None) => (0, Direction::Forward),
        };
        Compares {
            duty,
            direction: match direction {
                Direction::Forward => self.period_counts,
                Direction::Reverse => 0,
            },
            repetitions: segment.ticks.saturating_sub(1).min(u32::from(u16::MAX)) as u16,
        }
    }
}

/// One segment in TIM1's preloaded registers.
struct Compares {
    /// CH1's compare: the magnitude's duty in timer counts.
    duty: u16,
    /// CH2's compare: a whole period (high) forward, zero (low) in reverse.
    direction: u16,
    /// Carrier periods after the first.
    repetitions: u16,
}

impl Compares {
    fn write(&self, timer: &Timer<'static, TIM1>) {
        timer.set_compare_value(Channel::Ch1, self.duty);
        timer.set_compare_value(Channel::Ch2, self.direction);
        timer.set_repetition_counter(self.repetitions);
    }
}

impl SegmentOutput for PwmStage {
    fn clock(&self) -> TickClock {
        self.clock
    }

    fn level_step_mps2(&self) -> f64 {
        self.calibration.full_duty_accel_mps2 / f64::from(self.period_counts)
    }

    /// The PWM output's zero is no duty: only the calibration's scale changes.
    fn calibrate(&mut self, configuration: &Configuration) {
        self.calibration = configuration.pwm;
        self.levels = None;
        self.trimmed = None;
    }

    fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError> {
        self.levels = None;
        self.levels = Some(
            self.calibration
                .levels(peak_accel_mps2, self.period_counts)?,
        );
        Ok(())
    }

    fn trim(&mut self, trimmed: &TrimmedCycle) -> Result<(), DriveError> {
        let (period_counts, calibration) = (self.period_counts, self.calibration);
        self.trimmed = Some(TrimmedLevels::convert(trimmed, |accel_mps2| {
            calibration.command(accel_mps2, period_counts)
        })?);
        Ok(())
    }

    fn restart(&mut self, segment: &Segment) {
        let compares = self.compares(segment);
        self.timer.stop_and_load(|timer| compares.write(timer));
        self.timer.timer().set_moe(true);
        self.timer.start(segment.start_tick);
    }

    /// Writes the next duty, direction and length.
    fn preload(&mut self, segment: &Segment) -> Result<(), EdgeMissed> {
        self.timer.prepare_capture(segment);
        self.compares(segment).write(self.timer.timer());
        self.timer.confirm_preload()
    }

    async fn wait_edge(&mut self) -> Result<(), EdgeMissed> {
        self.timer.wait_edge().await
    }

    fn halt(&mut self) {
        self.timer.timer().set_moe(false);
        self.timer.stop();
    }

    fn started(&self, segment: &Segment) -> SegmentStart {
        SegmentStart {
            // The timer's update event starts every segment exactly on its planned tick.
            tick: segment.start_tick,
            // TIM1's repetition counter cannot be read: this stage has no slack to report.
            slack_ticks: None,
        }
    }
}
