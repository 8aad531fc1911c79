//! The board's peripherals behind one bus: each access goes to the model of the block at its
//! address, an access no model covers is refused (the machine stops the run naming it), and the
//! signals between blocks (a timer's update to the DAC, the edge counter and the DMA, every
//! block's interrupt line to the NVIC) are routed here.

mod dac;
mod dma;
mod exti;
mod gpio;
mod iwdg;
mod rcc;
mod registers;
pub mod scs;
mod system;
mod timer;
mod usart;

use dac::{Dac, TSEL_TIM2_TRGO};
use dma::{Dma, Dmamux, Move, REQUEST_TIM1_UP, REQUEST_TIM2_UP, REQUEST_TIM6_UP};
use exti::Exti;
use gpio::Port;
use iwdg::Iwdg;
use rcc::Rcc;
use registers::RegisterFile;
use scs::{Request, Scs};
use system::FlashInterface;
use timer::{Kind, Timer, Update};
use usart::Usart;

/// The core's clock: every bus and timer here runs at it (RM0440, 170 MHz with boost).
pub const CORE_HZ: u64 = 170_000_000;

/// Time in core clock cycles since power-up.
pub type Cycles = u64;

/// What a register read gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    Value(u32),
    /// No model covers this register.
    Unmodelled,
}

/// Interrupt lines (RM0440, "STM32G4 Series vector table"), as the image's vector table binds
/// them.
pub mod irq {
    pub const DMA1_CHANNEL1: usize = 11;
    pub const DMA1_CHANNEL2: usize = 12;
    pub const EXTI15_10: usize = 40;
    pub const TIM1_BRK_TIM15: usize = 24;
    pub const TIM1_UP_TIM16: usize = 25;
    pub const TIM2: usize = 28;
    pub const TIM3: usize = 29;
    pub const TIM4: usize = 30;
    pub const TIM6_DAC: usize = 54;
    pub const USART1: usize = 37;
    pub const LPUART1: usize = 91;
}

/// Something the outside world sees change: a pin or the analog output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// DAC1 channel 1's code from `at` on.
    Dac { at: Cycles, code: u32 },
    /// The driver enable (PA10) from `at` on.
    Enable { at: Cycles, on: bool },
    /// TIM1's PWM from `at` on: the magnitude's duty on CH1 (0 with the main output off) and the
    /// direction on CH2 (high: forward).
    Pwm {
        at: Cycles,
        duty_counts: u32,
        forward: bool,
    },
    /// A reset at `at`: every pin back to its reset state (PA10 an input, its external
    /// pull-down holding the driver off; the DAC off, PA4 at high impedance) until the firmware
    /// drives them again.
    Reset { at: Cycles },
}

/// Where a peripheral access went wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Refused {
    pub address: u32,
}

/// Every peripheral of the board the firmware touches.
pub struct Board {
    pub scs: Scs,
    rcc: Rcc,
    pwr: RegisterFile,
    flash: FlashInterface,
    syscfg: RegisterFile,
    dbgmcu: RegisterFile,
    exti: Exti,
    ports: [Port; 4],
    dac: Dac,
    dma: Dma,
    dmamux: Dmamux,
    iwdg: Iwdg,
    lpuart1: Usart,
    usart1: Usart,
    tim1: Timer,
    tim2: Timer,
    tim3: Timer,
    tim4: Timer,
    tim6: Timer,
    tim15: Timer,
    /// The latest time the board was brought to (an access, an event): the time of the
    /// interrupt lines raised without one given.
    now: Cycles,
    /// The driver enable's level as last reported.
    enable_on: bool,
    /// Changes on the outputs, in time order, until taken.
    outputs: Vec<Output>,
    /// DMA items to move, until the machine moves them.
    moves: Vec<Move>,
    /// The independent watchdog expired: the machine resets the board.
    pub watchdog_expired: bool,
    /// TIM2's counter overflowed (an edge of the DAC stage) since last asked.
    edge_came: bool,
    /// A fault put in on purpose: TIM3 ignores its trigger (a dead edge counter).
    pub edge_counter_dead: bool,
    /// A fault put in on purpose: every move of this DMA1 channel (0-based) is a transfer
    /// error.
    pub dma_channel_broken: Option<usize>,
}

/// Base addresses (RM0440, "Memory map and register boundary addresses").
const TIM2: u32 = 0x4000_0000;
const TIM3: u32 = 0x4000_0400;
const TIM4: u32 = 0x4000_0800;
const TIM6: u32 = 0x4000_1000;
const IWDG: u32 = 0x4000_3000;
const PWR: u32 = 0x4000_7000;
const LPUART1: u32 = 0x4000_8000;
const SYSCFG: u32 = 0x4001_0000;
const EXTI: u32 = 0x4001_0400;
const TIM1: u32 = 0x4001_2C00;
const USART1: u32 = 0x4001_3800;
const TIM15: u32 = 0x4001_4000;
const DMA1: u32 = 0x4002_0000;
const DMAMUX1: u32 = 0x4002_0800;
const RCC: u32 = 0x4002_1000;
const FLASH: u32 = 0x4002_2000;
const GPIOA: u32 = 0x4800_0000;
const DAC1: u32 = 0x5000_0800;
const SCS: u32 = 0xE000_0000;
const DBGMCU: u32 = 0xE004_2000;
/// A block's address range.
const BLOCK: u32 = 0x400;

/// The driver enable: PA10.
const ENABLE_PORT: usize = 0;
const ENABLE_PIN: u32 = 10;

impl Default for Board {
    fn default() -> Self {
        Self::new()
    }
}

impl Board {
    /// The board at power-up.
    pub fn new() -> Self {
        Board {
            scs: Scs::new(),
            rcc: Rcc::new(),
            pwr: system::pwr(),
            flash: FlashInterface::new(),
            syscfg: system::syscfg(),
            dbgmcu: system::dbgmcu(),
            exti: Exti::new(),
            ports: [
                Port::new('A'),
                Port::new('B'),
                Port::new('C'),
                Port::new('D'),
            ],
            dac: Dac::new(),
            dma: Dma::new(),
            dmamux: Dmamux::new(),
            iwdg: Iwdg::new(),
            lpuart1: Usart::new(usart::Kind::Lpuart),
            usart1: Usart::new(usart::Kind::Usart),
            tim1: Timer::new(Kind::Advanced, 16),
            tim2: Timer::new(Kind::General, 32),
            tim3: Timer::new(Kind::General, 16),
            tim4: Timer::new(Kind::General, 16),
            tim6: Timer::new(Kind::Basic, 16),
            tim15: Timer::new(Kind::General, 16),
            now: 0,
            enable_on: false,
            outputs: Vec::new(),
            moves: Vec::new(),
            watchdog_expired: false,
            edge_came: false,
            edge_counter_dead: false,
            dma_channel_broken: None,
        }
    }

    /// The board after a system or watchdog reset: every peripheral at its reset values, the
    /// reset's cause in RCC_CSR; the outputs go to their reset state at `at`.
    pub fn reset(&self, at: Cycles, by_watchdog: bool) -> Self {
        let mut board = Board::new();
        board.edge_counter_dead = self.edge_counter_dead;
        if by_watchdog {
            board.rcc = self.rcc.after_watchdog_reset();
        }
        board.outputs.push(Output::Reset { at });
        board
    }

    /// Reads the 32-bit register at `address` at `now`.
    pub fn read(&self, address: u32, now: Cycles) -> Result<u32, Refused> {
        let (base, offset) = (address & !(BLOCK - 1), address & (BLOCK - 1));
        let access = match base {
            TIM1 => self.tim1.read(offset, now),
            TIM2 => self.tim2.read(offset, now),
            TIM3 => self.tim3.read(offset, now),
            TIM4 => self.tim4.read(offset, now),
            TIM6 => self.tim6.read(offset, now),
            TIM15 => self.tim15.read(offset, now),
            IWDG => self.iwdg.read(offset),
            LPUART1 => self.lpuart1.read(offset, now),
            USART1 => self.usart1.read(offset, now),
            PWR => self.pwr.read(offset),
            SYSCFG => self.syscfg.read(offset),
            EXTI => self.exti.read(offset),
            DMA1 => self.dma.read(offset),
            DMAMUX1 => self.dmamux.read(offset),
            RCC => self.rcc.read(offset),
            FLASH => self.flash.read(offset),
            DAC1 => self.dac.read(offset),
            DBGMCU => self.dbgmcu.read(offset),
            _ if (GPIOA..GPIOA + 4 * BLOCK).contains(&address) => {
                self.ports[((address - GPIOA) / BLOCK) as usize].read(offset)
            }
            _ if (SCS..SCS + 0x10_0000).contains(&address) => self.scs.read(address - SCS, now),
            _ => Access::Unmodelled,
        };
        match access {
            Access::Value(value) => Ok(value),
            Access::Unmodelled => Err(Refused { address }),
        }
    }

    /// Writes the 32-bit register at `address` at `now`; what the system control space asks
    /// of the machine.
    pub fn write(&mut self, address: u32, value: u32, now: Cycles) -> Result<Request, Refused> {
        let refused = Err(Refused { address });
        self.now = self.now.max(now);
        let (base, offset) = (address & !(BLOCK - 1), address & (BLOCK - 1));
        let mut request = Request::Evaluate;
        let written = match base {
            TIM1 | TIM2 | TIM3 | TIM4 | TIM6 | TIM15 => {
                let Some(Ok(update)) = self
                    .timer_mut(base)
                    .map(|timer| timer.write(offset, value, now))
                else {
                    return refused;
                };
                self.route_update(base, update, now);
                true
            }
            IWDG => self.iwdg.write(offset, value, now),
            LPUART1 => self.lpuart1.write(offset, value, now),
            USART1 => self.usart1.write(offset, value, now),
            PWR => self.pwr.write(offset, value),
            SYSCFG => self.syscfg.write(offset, value),
            EXTI => self.exti.write(offset, value),
            DMA1 => self.dma.write(offset, value),
            DMAMUX1 => self.dmamux.write(offset, value),
            RCC => self.rcc.write(offset, value),
            FLASH => self.flash.write(offset, value),
            DAC1 => match self.dac.write(offset, value) {
                Ok(Some(code)) => {
                    self.outputs.push(Output::Dac { at: now, code });
                    true
                }
                Ok(None) => true,
                Err(()) => false,
            },
            DBGMCU => self.dbgmcu.write(offset, value),
            _ if (GPIOA..GPIOA + 4 * BLOCK).contains(&address) => {
                let written = self.ports[((address - GPIOA) / BLOCK) as usize].write(offset, value);
                self.watch_enable(now);
                written
            }
            _ if (SCS..SCS + 0x10_0000).contains(&address) => {
                match self.scs.write(address - SCS, value, now) {
                    Some(scs_request) => {
                        request = scs_request;
                        true
                    }
                    None => false,
                }
            }
            _ => false,
        };
        if !written {
            return refused;
        }
        self.raise_lines();
        Ok(request)
    }

    fn timer_mut(&mut self, base: u32) -> Option<&mut Timer> {
        match base {
            TIM1 => Some(&mut self.tim1),
            TIM2 => Some(&mut self.tim2),
            TIM3 => Some(&mut self.tim3),
            TIM4 => Some(&mut self.tim4),
            TIM6 => Some(&mut self.tim6),
            TIM15 => Some(&mut self.tim15),
            _ => None,
        }
    }

    /// A timer's update event's consequences: the DMA request, and TRGO to the DAC and to the
    /// edge counter (TIM3 takes ITR0 from TIM1, ITR1 from TIM2: RM0440, "TIMx internal trigger
    /// connection").
    fn route_update(&mut self, base: u32, update: Update, now: Cycles) {
        if update.dma {
            let request = match base {
                TIM1 => Some(REQUEST_TIM1_UP),
                TIM2 => Some(REQUEST_TIM2_UP),
                TIM6 => Some(REQUEST_TIM6_UP),
                _ => None,
            };
            if let Some(request) = request {
                let channels: Vec<usize> = self.dmamux.routes(request).collect();
                for channel in channels {
                    if let Some(item) = self.dma.request(channel) {
                        self.moves.push(item);
                    }
                }
            }
        }
        if update.trigger {
            let itr = match base {
                TIM1 => Some(0),
                TIM2 => Some(1),
                TIM4 => Some(2),
                _ => None,
            };
            if base == TIM2 {
                if let Some(code) = self.dac.trigger(TSEL_TIM2_TRGO) {
                    self.outputs.push(Output::Dac { at: now, code });
                }
            }
            if base == TIM1 {
                let (duty_counts, forward) = self.tim1.pwm();
                self.outputs.push(Output::Pwm {
                    at: now,
                    duty_counts,
                    forward,
                });
            }
            if itr.is_some() && itr == Some(self.tim3.trigger_source()) && !self.edge_counter_dead {
                let counted = self.tim3.trigger_in();
                self.route_update(TIM3, counted, now);
            }
        }
    }

    /// The PA10 level, reported when it changes.
    fn watch_enable(&mut self, now: Cycles) {
        let on = self.ports[ENABLE_PORT].drives_high(ENABLE_PIN);
        if on != self.enable_on {
            self.enable_on = on;
            self.outputs.push(Output::Enable { at: now, on });
        }
    }

    /// Every peripheral's interrupt line that is up pends its interrupt.
    fn raise_lines(&mut self) {
        let lines = [
            (irq::TIM2, self.tim2.interrupt_line()),
            (irq::TIM3, self.tim3.interrupt_line()),
            (irq::TIM4, self.tim4.interrupt_line()),
            (irq::TIM6_DAC, self.tim6.interrupt_line()),
            (irq::TIM1_BRK_TIM15, self.tim15.interrupt_line()),
            (irq::TIM1_UP_TIM16, self.tim1.interrupt_line()),
            (irq::EXTI15_10, self.exti.interrupts() & 0xFC00 != 0),
            (irq::DMA1_CHANNEL1, self.dma.interrupt_line(0)),
            (irq::DMA1_CHANNEL2, self.dma.interrupt_line(1)),
            (irq::LPUART1, self.lpuart1.interrupt_line(self.now)),
            (irq::USART1, self.usart1.interrupt_line(self.now)),
        ];
        for (line, up) in lines {
            if up {
                self.scs.pend(line);
            }
        }
    }

    /// The next time something happens on its own: a timer's update, the watchdog's expiry.
    pub fn next_event(&self) -> Option<Cycles> {
        [
            self.tim1.next_event(),
            self.tim2.next_event(),
            self.tim3.next_event(),
            self.tim4.next_event(),
            self.tim6.next_event(),
            self.tim15.next_event(),
            self.lpuart1.next_event(self.now),
            self.usart1.next_event(self.now),
            self.iwdg.expiry(),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// Runs every event up to and including `now`, in time order.
    pub fn advance(&mut self, now: Cycles) {
        while let Some(at) = self.next_event().filter(|&at| at <= now) {
            self.now = self.now.max(at);
            if self.iwdg.expiry() == Some(at) {
                self.watchdog_expired = true;
                return;
            }
            for base in [TIM1, TIM2, TIM3, TIM4, TIM6, TIM15] {
                let update = self
                    .timer_mut(base)
                    .filter(|timer| timer.next_event() == Some(at))
                    .map(|timer| timer.event(at));
                if let Some(update) = update {
                    self.edge_came |= base == TIM2 && update.trigger;
                    self.route_update(base, update, at);
                }
            }
            self.raise_lines();
        }
        self.now = self.now.max(now);
    }

    /// Whether an edge (TIM2's overflow) came since last asked.
    pub fn take_edge(&mut self) -> bool {
        std::mem::take(&mut self.edge_came)
    }

    /// The outputs' changes since last taken.
    pub fn take_outputs(&mut self) -> Vec<Output> {
        std::mem::take(&mut self.outputs)
    }

    /// The DMA items requested since last taken.
    pub fn take_moves(&mut self) -> Vec<Move> {
        std::mem::take(&mut self.moves)
    }

    /// The move of `item` is done (or failed).
    pub fn moved(&mut self, item: &Move, error: bool) {
        self.dma.moved(item.channel, error);
        self.raise_lines();
    }

    /// The code on the DAC's output and whether the driver is enabled.
    pub fn output_state(&self) -> (u32, bool) {
        (self.dac.output(), self.enable_on)
    }

    /// Drives input pin `pin` of port `port` (0 for A) from outside, `None` to release it: a
    /// change of level is an edge on its EXTI line where SYSCFG routes that port there.
    pub fn drive_pin(&mut self, port: usize, pin: u32, level: Option<bool>) {
        let before = self.ports[port].level(pin);
        self.ports[port].drive(pin, level);
        let after = self.ports[port].level(pin);
        let exticr = self.syscfg.get(0x08 + 4 * (pin / 4));
        let routed = (exticr >> (4 * (pin % 4))) & 0xF == port as u32;
        if before != after && routed {
            self.exti.edge(pin, after);
            self.raise_lines();
        }
    }

    /// `bytes` arrive on LPUART1's RX (PA3, the ST-LINK's virtual COM port) from `at` on.
    pub fn serial_receive(&mut self, bytes: &[u8], at: Cycles) {
        self.lpuart1.receive(bytes, at);
    }

    /// The bytes LPUART1 has sent on TX (PA2) by `now`, since last taken.
    pub fn serial_take(&mut self, now: Cycles) -> Vec<u8> {
        self.lpuart1
            .take_sent(now)
            .into_iter()
            .map(|(_, byte)| byte)
            .collect()
    }

    /// `bytes` arrive on USART1's RX (PC5, from the RS-485 transceiver) from `at` on.
    pub fn rs485_receive(&mut self, bytes: &[u8], at: Cycles) {
        self.usart1.receive(bytes, at);
    }

    /// The bytes USART1 has sent on TX (PC4, to the RS-485 transceiver) by `now`, each with the
    /// time its last stop bit ended, since last taken.
    pub fn rs485_take(&mut self, now: Cycles) -> Vec<(Cycles, u8)> {
        self.usart1.take_sent(now)
    }

    /// The level on pin `pin` of port `port` (0 for A) at `now`, as the outside sees it: what
    /// an output drives, what a modelled peripheral drives on a pin in its alternate function
    /// (USART1's DE on PA12, AF7), else what drives it from outside or its pull.
    pub fn pin_level(&self, port: usize, pin: u32, now: Cycles) -> bool {
        let gpio = &self.ports[port];
        match (port, pin, gpio.alternate(pin)) {
            (0, 12, Some(7)) => self.usart1.driver_enable(now),
            _ => gpio.level(pin),
        }
    }

    /// The encoder's count, as the plate sets it on TIM4 (encoder mode).
    pub fn set_encoder(&mut self, count: u32) {
        self.tim4.set_external_count(count);
    }

    /// The core time of the output timeline's tick 0: the segment timer's first start (TIM2,
    /// or TIM1 for the PWM stage).
    pub fn output_origin(&self) -> Option<Cycles> {
        self.tim2
            .first_started_at()
            .or(self.tim1.first_started_at())
    }

    /// The independent watchdog's last refresh (a feed).
    pub fn last_feed(&self) -> Option<Cycles> {
        self.iwdg.refreshed_at
    }

    /// The core time from which the firmware's clock (embassy's time driver on TIM15) counts:
    /// its log's timestamps are seconds from here.
    pub fn clock_origin(&self) -> Option<Cycles> {
        self.tim15.first_started_at()
    }

    /// The flash's wait states (FLASH_ACR's LATENCY).
    pub fn flash_wait_states(&self) -> u32 {
        self.flash.latency()
    }

    /// The flash interface, for programming.
    pub fn flash(&mut self) -> &mut FlashInterface {
        &mut self.flash
    }
}
