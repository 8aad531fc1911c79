//! The STM32G4's timers as RM0440 describes them, as far as the firmware uses them: an up-counter
//! on the timer clock through its prescaler, or on a master's trigger (external clock mode 1),
//! or in encoder mode fed from outside; the auto-reload and prescaler with their preload, the
//! repetition counter (advanced timers), the update event with its flag, interrupt, DMA
//! request and TRGO, and the capture/compare registers as plain storage.
//!
//! Time is the core's clock; every timer here runs on the 170 MHz timer clock.

use super::{Access, Cycles};

/// Register offsets (RM0440, TIMx register map).
const CR1: u32 = 0x00;
const CR2: u32 = 0x04;
const SMCR: u32 = 0x08;
const DIER: u32 = 0x0C;
const SR: u32 = 0x10;
const EGR: u32 = 0x14;
const CCMR1: u32 = 0x18;
const CCMR2: u32 = 0x1C;
const CCER: u32 = 0x20;
const CNT: u32 = 0x24;
const PSC: u32 = 0x28;
const ARR: u32 = 0x2C;
const RCR: u32 = 0x30;
const CCR1: u32 = 0x34;
const CCR4: u32 = 0x40;
const BDTR: u32 = 0x44;
const CCR5: u32 = 0x48;
const CCR6: u32 = 0x4C;
const CCMR3: u32 = 0x50;
const DTR2: u32 = 0x54;
const ECR: u32 = 0x58;
const TISEL: u32 = 0x5C;
const AF1: u32 = 0x60;
const AF2: u32 = 0x64;
const DCR: u32 = 0x3DC;

const CR1_CEN: u32 = 1 << 0;
const CR1_URS: u32 = 1 << 2;
const CR1_OPM: u32 = 1 << 3;
const CR1_DIR: u32 = 1 << 4;
const CR1_ARPE: u32 = 1 << 7;
const DIER_UIE: u32 = 1 << 0;
const DIER_UDE: u32 = 1 << 8;
const SR_UIF: u32 = 1 << 0;
const EGR_UG: u32 = 1 << 0;

/// What a timer is built as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// TIM6/TIM7: counter, prescaler, auto-reload, update only.
    Basic,
    /// TIM2–TIM5, TIM15–TIM17 as far as used: four channels, slave mode.
    General,
    /// TIM1/TIM8/TIM20: repetition counter, break and dead time.
    Advanced,
}

/// What an update event did beyond the timer itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Update {
    /// The update interrupt is pending (UIF set with UIE).
    pub interrupt: bool,
    /// A DMA request (UDE).
    pub dma: bool,
    /// TRGO went out (MMS = update).
    pub trigger: bool,
}

/// One timer.
#[derive(Debug, Clone)]
pub struct Timer {
    kind: Kind,
    /// The counter wraps past this (16 or 32 bits).
    counter_max: u32,
    cr1: u32,
    cr2: u32,
    smcr: u32,
    dier: u32,
    sr: u32,
    ccmr: [u32; 3],
    ccer: u32,
    ccr: [u32; 6],
    bdtr: u32,
    af: [u32; 2],
    tisel: u32,
    dtr2: u32,
    ecr: u32,
    /// Preload and active auto-reload, prescaler and repetition count.
    arr: u32,
    arr_active: u32,
    psc: u32,
    psc_active: u32,
    rcr: u32,
    rcr_left: u32,
    /// The counter's value at `since`, counting on the timer clock.
    count_at_since: u32,
    since: Cycles,
    /// An externally set count (encoder mode, external clock): the counter does not run on the
    /// clock.
    external_count: u32,
    /// The last compare match taken, by channel.
    compared_at: [Option<Cycles>; 4],
    /// When the counter was first enabled: the origin of an output's timeline.
    first_started_at: Option<Cycles>,
}

impl Timer {
    pub fn new(kind: Kind, bits: u32) -> Self {
        Timer {
            kind,
            counter_max: if bits == 32 { u32::MAX } else { 0xFFFF },
            cr1: 0,
            cr2: 0,
            smcr: 0,
            dier: 0,
            sr: 0,
            ccmr: [0; 3],
            ccer: 0,
            ccr: [0; 6],
            bdtr: 0,
            af: [if kind == Kind::Advanced { 1 } else { 0 }, 0],
            tisel: 0,
            dtr2: 0,
            ecr: 0,
            arr: if bits == 32 { u32::MAX } else { 0xFFFF },
            arr_active: if bits == 32 { u32::MAX } else { 0xFFFF },
            psc: 0,
            psc_active: 0,
            rcr: 0,
            rcr_left: 0,
            count_at_since: 0,
            since: 0,
            external_count: 0,
            compared_at: [None; 4],
            first_started_at: None,
        }
    }

    /// Counts on the timer clock: enabled, and no slave mode that clocks it from elsewhere.
    fn runs_on_clock(&self) -> bool {
        self.cr1 & CR1_CEN != 0 && self.slave_mode() == 0
    }

    /// SMS (bits 16 and 2:0).
    pub fn slave_mode(&self) -> u32 {
        (self.smcr & 0x7) | ((self.smcr >> 16) & 1) << 3
    }

    /// TS (bits 21:20 and 6:4): the trigger input.
    pub fn trigger_source(&self) -> u32 {
        ((self.smcr >> 4) & 0x7) | ((self.smcr >> 20) & 0x3) << 3
    }

    /// MMS (bits 25 and 6:4): what TRGO carries.
    fn master_mode(&self) -> u32 {
        ((self.cr2 >> 4) & 0x7) | ((self.cr2 >> 25) & 1) << 3
    }

    /// Any enabled interrupt flag is up: the timer's interrupt line.
    pub fn interrupt_line(&self) -> bool {
        self.sr & self.dier & 0xFF != 0
    }

    /// The counter at `now`.
    pub fn count(&self, now: Cycles) -> u32 {
        if !self.runs_on_clock() {
            return if self.slave_mode() == 0 {
                self.count_at_since
            } else {
                self.external_count
            };
        }
        let ticks = (now - self.since) / u64::from(self.psc_active + 1);
        (u64::from(self.count_at_since) + ticks) as u32
    }

    /// When the counter next overflows, if it runs on the clock.
    pub fn next_update(&self) -> Option<Cycles> {
        if !self.runs_on_clock() || self.cr1 & CR1_DIR != 0 {
            return None;
        }
        let top = if self.count_at_since > self.arr_active {
            self.counter_max
        } else {
            self.arr_active
        };
        let ticks = u64::from(top - self.count_at_since) + 1;
        Some(self.since + ticks * u64::from(self.psc_active + 1))
    }

    /// The next compare match of a channel whose interrupt is enabled (CCxIE), with its
    /// channel: the counter reaching CCRx in this period, or else in the next one.
    fn next_compare(&self) -> Option<(Cycles, usize)> {
        if !self.runs_on_clock() || self.kind == Kind::Basic {
            return None;
        }
        let next_update = self.next_update()?;
        let tick = u64::from(self.psc_active + 1);
        (0..4)
            .filter(|&channel| self.dier & (1 << (channel + 1)) != 0)
            .filter_map(|channel| {
                let ccr = self.ccr[channel];
                let not_done =
                    |at: &Cycles| self.compared_at[channel].is_none_or(|done| *at > done);
                let this_period = (ccr > self.count_at_since && ccr <= self.arr_active)
                    .then(|| self.since + u64::from(ccr - self.count_at_since) * tick)
                    .filter(not_done);
                // A CCR of 0 matches as the counter restarts, at the update itself: once.
                let at = this_period.or_else(|| {
                    (ccr <= self.arr_active)
                        .then(|| next_update + u64::from(ccr) * tick)
                        .filter(not_done)
                })?;
                Some((at, channel))
            })
            .min()
    }

    /// The next time this timer does something on its own: an update or a compare match.
    pub fn next_event(&self) -> Option<Cycles> {
        let update = self.next_update();
        let compare = self.next_compare().map(|(at, _)| at);
        update.into_iter().chain(compare).min()
    }

    /// Runs this timer's events at `at` (from [`Timer::next_event`]): the compare matches set
    /// their flags, an overflow makes its update.
    pub fn event(&mut self, at: Cycles) -> Update {
        while let Some((when, channel)) = self.next_compare().filter(|&(when, _)| when == at) {
            self.sr |= 1 << (channel + 1);
            self.compared_at[channel] = Some(when);
        }
        if self.next_update() == Some(at) {
            return self.overflow(at);
        }
        Update::default()
    }

    /// The counter overflow at `at` (from [`Timer::next_update`]).
    fn overflow(&mut self, at: Cycles) -> Update {
        self.count_at_since = 0;
        self.since = at;
        if self.kind == Kind::Advanced && self.rcr_left > 0 {
            self.rcr_left -= 1;
            return Update::default();
        }
        self.update_event(false)
    }

    /// A trigger from the master on the slave's TS input: one count in external clock mode 1.
    pub fn trigger_in(&mut self) -> Update {
        if self.cr1 & CR1_CEN == 0 || self.slave_mode() != 7 {
            return Update::default();
        }
        if self.external_count >= self.arr_active {
            self.external_count = 0;
            self.update_event(false)
        } else {
            self.external_count += 1;
            Update::default()
        }
    }

    /// The PWM of an advanced timer as its outputs drive it: CH1's duty (0 with the main output
    /// off, MOE, or the channel off, CC1E) and whether CH2 is high (its duty the whole period).
    pub fn pwm(&self) -> (u32, bool) {
        let moe = self.bdtr & (1 << 15) != 0;
        let duty = if moe && self.ccer & 1 != 0 {
            self.ccr[0]
        } else {
            0
        };
        let forward = moe && self.ccer & (1 << 4) != 0 && self.ccr[1] > self.arr_active;
        (duty, forward)
    }

    /// When the counter was first enabled.
    pub fn first_started_at(&self) -> Option<Cycles> {
        self.first_started_at
    }

    /// Sets the count an outside source gives (an encoder's position).
    pub fn set_external_count(&mut self, count: u32) {
        self.external_count = count & self.counter_max;
    }

    /// The update event: shadow registers loaded, the flag, interrupt, DMA and TRGO; `forced`
    /// for UG, which URS keeps from the flag and the interrupt.
    fn update_event(&mut self, forced: bool) -> Update {
        self.arr_active = self.arr;
        self.psc_active = self.psc;
        self.rcr_left = self.rcr;
        if self.cr1 & CR1_OPM != 0 && !forced {
            self.cr1 &= !CR1_CEN;
        }
        let flagged = !(forced && self.cr1 & CR1_URS != 0);
        if flagged {
            self.sr |= SR_UIF;
        }
        Update {
            interrupt: flagged && self.dier & DIER_UIE != 0,
            dma: self.dier & DIER_UDE != 0,
            trigger: self.master_mode() == 2,
        }
    }

    /// Reads register `offset` at `now`.
    pub fn read(&self, offset: u32, now: Cycles) -> Access {
        let value = match offset {
            CR1 => self.cr1,
            CR2 => self.cr2,
            SMCR if self.kind != Kind::Basic => self.smcr,
            DIER => self.dier,
            SR => self.sr,
            EGR => 0,
            CCMR1 if self.kind != Kind::Basic => self.ccmr[0],
            CCMR2 if self.kind != Kind::Basic => self.ccmr[1],
            CCER if self.kind != Kind::Basic => self.ccer,
            CNT => self.count(now),
            PSC => self.psc,
            ARR => self.arr,
            RCR if self.kind == Kind::Advanced => self.rcr,
            CCR1..=CCR4 if self.kind != Kind::Basic => self.ccr[((offset - CCR1) / 4) as usize],
            BDTR if self.kind == Kind::Advanced => self.bdtr,
            CCR5 | CCR6 if self.kind == Kind::Advanced => {
                self.ccr[4 + ((offset - CCR5) / 4) as usize]
            }
            CCMR3 if self.kind == Kind::Advanced => self.ccmr[2],
            DTR2 if self.kind == Kind::Advanced => self.dtr2,
            ECR if self.kind != Kind::Basic => self.ecr,
            TISEL if self.kind != Kind::Basic => self.tisel,
            AF1 if self.kind != Kind::Basic => self.af[0],
            AF2 if self.kind != Kind::Basic => self.af[1],
            _ => return Access::Unmodelled,
        };
        Access::Value(value)
    }

    /// Writes register `offset` at `now`; an update event it forces (UG) is returned.
    pub fn write(&mut self, offset: u32, value: u32, now: Cycles) -> Result<Update, ()> {
        let count = self.count(now);
        let mut update = Update::default();
        match offset {
            CR1 => {
                let was_running = self.runs_on_clock();
                self.cr1 = value & 0xFFF;
                if self.cr1 & CR1_CEN != 0 && self.first_started_at.is_none() {
                    self.first_started_at = Some(now);
                }
                if was_running != self.runs_on_clock() {
                    self.count_at_since = count;
                    self.since = now;
                }
            }
            CR2 => self.cr2 = value,
            SMCR if self.kind != Kind::Basic => {
                self.count_at_since = count;
                self.since = now;
                self.smcr = value;
            }
            DIER => self.dier = value,
            SR => self.sr &= value,
            EGR => {
                if value & EGR_UG != 0 {
                    self.count_at_since = 0;
                    self.external_count = 0;
                    self.since = now;
                    update = self.update_event(true);
                }
            }
            CCMR1 if self.kind != Kind::Basic => self.ccmr[0] = value,
            CCMR2 if self.kind != Kind::Basic => self.ccmr[1] = value,
            CCER if self.kind != Kind::Basic => self.ccer = value,
            CNT => {
                self.count_at_since = value & self.counter_max;
                self.external_count = value & self.counter_max;
                self.since = now;
            }
            PSC => self.psc = value & 0xFFFF,
            ARR => {
                self.arr = value & self.counter_max;
                if self.cr1 & CR1_ARPE == 0 {
                    self.arr_active = self.arr;
                }
            }
            RCR if self.kind == Kind::Advanced => self.rcr = value & 0xFFFF,
            CCR1..=CCR4 if self.kind != Kind::Basic => {
                self.ccr[((offset - CCR1) / 4) as usize] = value
            }
            BDTR if self.kind == Kind::Advanced => self.bdtr = value,
            CCR5 | CCR6 if self.kind == Kind::Advanced => {
                self.ccr[4 + ((offset - CCR5) / 4) as usize] = value
            }
            CCMR3 if self.kind == Kind::Advanced => self.ccmr[2] = value,
            DTR2 if self.kind == Kind::Advanced => self.dtr2 = value,
            ECR if self.kind != Kind::Basic => self.ecr = value,
            TISEL if self.kind != Kind::Basic => self.tisel = value,
            AF1 if self.kind != Kind::Basic => self.af[0] = value,
            AF2 if self.kind != Kind::Basic => self.af[1] = value,
            DCR => return Err(()),
            _ => return Err(()),
        }
        Ok(update)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_preloaded_reload_takes_effect_at_the_next_update() {
        let mut timer = Timer::new(Kind::General, 32);
        timer.write(CR1, CR1_ARPE, 0).unwrap();
        timer.write(ARR, 99, 0).unwrap();
        timer.write(EGR, EGR_UG, 0).unwrap();
        timer.write(DIER, DIER_UIE, 0).unwrap();
        timer.write(CR1, CR1_ARPE | CR1_CEN, 10).unwrap();
        assert_eq!(timer.next_update(), Some(110), "100 counts from 10");
        timer.write(ARR, 49, 50).unwrap();
        assert_eq!(
            timer.next_update(),
            Some(110),
            "the running period keeps its length"
        );
        let update = timer.event(110);
        assert!(update.interrupt && !update.dma);
        assert_eq!(timer.next_update(), Some(160), "then 50 counts");
        assert_eq!(timer.count(135), 25);
    }

    #[test]
    fn a_compare_match_flags_its_channel_once_a_period() {
        let mut timer = Timer::new(Kind::General, 16);
        timer.write(PSC, 169, 0).unwrap();
        timer.write(EGR, EGR_UG, 0).unwrap();
        timer.write(SR, 0, 0).unwrap();
        timer.write(CCR1, 0x8000, 0).unwrap();
        timer.write(DIER, 1 << 1, 0).unwrap();
        timer.write(CR1, CR1_CEN, 0).unwrap();
        // 1 MHz counts: 0x8000 µs after the start.
        let at = 0x8000 * 170;
        assert_eq!(timer.next_event(), Some(at));
        timer.event(at);
        assert_eq!(timer.read(SR, at), Access::Value(1 << 1));
        assert_eq!(timer.next_event(), Some(0x10000 * 170), "then the overflow");
        timer.event(0x10000 * 170);
        assert_eq!(
            timer.next_event(),
            Some(0x18000 * 170),
            "the next period's match"
        );
    }

    /// A CCR of 0 (embassy's time driver sets one for an alarm at a period's start) matches as
    /// the counter restarts: once, at the update, and then at the next one.
    #[test]
    fn a_compare_at_zero_matches_once_at_each_update() {
        let mut timer = Timer::new(Kind::General, 16);
        timer.write(ARR, 99, 0).unwrap();
        timer.write(EGR, EGR_UG, 0).unwrap();
        timer.write(CCR1, 0, 0).unwrap();
        timer.write(DIER, 1 << 1, 0).unwrap();
        timer.write(CR1, CR1_CEN, 0).unwrap();
        assert_eq!(timer.next_event(), Some(100));
        timer.event(100);
        assert_eq!(timer.read(SR, 100), Access::Value(1 << 1 | 1));
        assert_eq!(timer.next_event(), Some(200), "the next update's match");
        timer.write(SR, 0, 150).unwrap();
        timer.event(200);
        assert_eq!(timer.read(SR, 200), Access::Value(1 << 1 | 1));
    }

    #[test]
    fn a_forced_update_with_urs_raises_no_flag_but_a_trigger() {
        let mut timer = Timer::new(Kind::General, 32);
        timer.write(CR2, 2 << 4, 0).unwrap();
        timer.write(CR1, CR1_URS, 0).unwrap();
        timer.write(DIER, DIER_UIE, 0).unwrap();
        let update = timer.write(EGR, EGR_UG, 5).unwrap();
        assert!(update.trigger && !update.interrupt);
        assert_eq!(timer.read(SR, 5), Access::Value(0));
    }

    #[test]
    fn external_clock_mode_counts_triggers_and_wraps_at_the_reload() {
        let mut timer = Timer::new(Kind::General, 16);
        timer.write(SMCR, 0x17, 0).unwrap();
        timer.write(ARR, 2, 0).unwrap();
        timer.write(CR1, CR1_CEN, 0).unwrap();
        for expected in [1, 2, 0, 1] {
            timer.trigger_in();
            assert_eq!(timer.count(1_000), expected);
        }
        assert_eq!(timer.trigger_source(), 1, "ITR1");
    }
}
