//! USART1 and LPUART1 (RM0440, "Universal synchronous/asynchronous receiver transmitter" and
//! "Low-power universal asynchronous receiver transmitter"), as embassy's buffered driver drives
//! them with their FIFOs enabled: one model of the registers they share, CR1, CR2, CR3, BRR,
//! RQR, ISR, ICR, RDR, TDR and PRESC (and the USART's GTPR and RTOR, as storage), the two
//! kinds apart only in their baud rate: the USART's `f_ck / BRR` (OVER8 = 0, or `2 · f_ck /
//! USARTDIV` with OVER8), the LPUART's `256 · f_ck / BRR`, `f_ck` the core's clock through
//! PRESC. A character is a start bit, the word CR1's M1:M0 sets (7, 8 or 9 bits, the parity bit
//! among them with PCE) and CR2's stop bits. A byte written to TDR waits in the 8-byte transmit
//! FIFO and leaves the shifter a character later; bytes from outside arrive in the 8-byte
//! receive FIFO a character apart, and RDR takes them (with PCE, the parity bit where the word
//! ends, as the hardware leaves it). ISR's TXFNF, TC, RXFNE and IDLE follow, and the interrupt
//! line is up where one of them is enabled in CR1. With CR3's DEM the driver enable is the
//! UART's: asserted DEAT before the first start bit and released DEDT after the last stop bit
//! (DEP sets its polarity).

use std::cell::RefCell;
use std::collections::VecDeque;

use super::{Access, Cycles};

const CR1: u32 = 0x00;
const CR2: u32 = 0x04;
const CR3: u32 = 0x08;
const BRR: u32 = 0x0C;
const GTPR: u32 = 0x10;
const RTOR: u32 = 0x14;
const RQR: u32 = 0x18;
const ISR: u32 = 0x1C;
const ICR: u32 = 0x20;
const RDR: u32 = 0x24;
const TDR: u32 = 0x28;
const PRESC: u32 = 0x2C;

const CR1_UE: u32 = 1;
const CR1_RE: u32 = 1 << 2;
const CR1_TE: u32 = 1 << 3;
/// CR1's parity: PCE, and PS (odd).
const CR1_PS: u32 = 1 << 9;
const CR1_PCE: u32 = 1 << 10;
/// CR1's word length: M0 and M1 (00: 8 bits, 01: 9 bits, 10: 7 bits).
const CR1_M0: u32 = 1 << 12;
const CR1_M1: u32 = 1 << 28;
/// CR1's OVER8: oversampling by 8 (the USART's alone).
const CR1_OVER8: u32 = 1 << 15;
/// CR1's driver-enable deassertion (DEDT, 20:16) and assertion (DEAT, 25:21) times, in 16ths
/// of a bit (8ths with OVER8).
const CR1_DEDT_SHIFT: u32 = 16;
const CR1_DEAT_SHIFT: u32 = 21;
/// CR2's STOP (13:12): 00 one stop bit, 01 half, 10 two, 11 one and a half.
const CR2_STOP_SHIFT: u32 = 12;
/// CR3's driver-enable mode and its polarity (set: active low).
const CR3_DEM: u32 = 1 << 14;
const CR3_DEP: u32 = 1 << 15;
const IDLE: u32 = 1 << 4;
const RXFNE: u32 = 1 << 5;
const TC: u32 = 1 << 6;
const TXFNF: u32 = 1 << 7;
/// ISR's TEACK and REACK: the transmitter and the receiver enabled.
const TEACK: u32 = 1 << 21;
const REACK: u32 = 1 << 22;

/// Each FIFO's depth.
const FIFO_BYTES: usize = 8;
/// PRESC's dividers (RM0440, "USART prescaler register", "LPUART prescaler register").
const DIVIDERS: [u64; 12] = [1, 2, 4, 6, 8, 10, 12, 16, 32, 64, 128, 256];

/// Which of the two a block is: they differ in how BRR sets the baud rate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// USART1–3, UART4–5: `f_ck / USARTDIV`.
    Usart,
    /// LPUART1: `256 · f_ck / BRR`.
    Lpuart,
}

/// A character on its way out: its byte and when its last stop bit ends.
#[derive(Debug, Clone, Copy)]
struct Outgoing {
    done: Cycles,
    byte: u8,
}

#[derive(Debug, Clone)]
pub struct Usart {
    kind: Kind,
    cr1: u32,
    cr2: u32,
    cr3: u32,
    brr: u32,
    gtpr: u32,
    rtor: u32,
    presc: u32,
    /// Characters written to TDR, until their last stop bit has ended.
    transmitting: VecDeque<Outgoing>,
    /// Bytes whose character has ended, with that time, until taken.
    sent: Vec<(Cycles, u8)>,
    /// Bytes on their way in, each with the time its character ends, until RDR takes them.
    receiving: RefCell<VecDeque<(Cycles, u8)>>,
    /// The end of the last character received, for IDLE.
    last_received: Option<Cycles>,
    /// IDLE cleared (ICR) for the idle line after this character.
    idle_cleared_for: Option<Cycles>,
    /// TC cleared (ICR) since the last character sent.
    tc_cleared: bool,
    /// The driver enable's assertion: from when, until when (DEDT after the last stop bit).
    driver_enabled: Option<(Cycles, Cycles)>,
}

impl Usart {
    /// The block at its reset values.
    pub fn new(kind: Kind) -> Self {
        Usart {
            kind,
            cr1: 0,
            cr2: 0,
            cr3: 0,
            brr: 0,
            gtpr: 0,
            rtor: 0,
            presc: 0,
            transmitting: VecDeque::new(),
            sent: Vec::new(),
            receiving: RefCell::new(VecDeque::new()),
            last_received: None,
            idle_cleared_for: None,
            tc_cleared: false,
            driver_enabled: None,
        }
    }

    /// The bits of a character's word: 7, 8 or 9, the parity bit among them.
    fn word_bits(&self) -> u64 {
        match (self.cr1 & CR1_M1 != 0, self.cr1 & CR1_M0 != 0) {
            (false, false) => 8,
            (false, true) => 9,
            _ => 7,
        }
    }

    /// Core cycles a bit takes, times 512: the kernel clock's cycles per bit through PRESC.
    fn bit_cycles_x512(&self) -> u64 {
        let divider = DIVIDERS
            .get(self.presc as usize & 0xF)
            .copied()
            .unwrap_or(256);
        match self.kind {
            Kind::Lpuart => 2 * u64::from(self.brr.max(0x300)) * divider,
            Kind::Usart if self.cr1 & CR1_OVER8 != 0 => {
                // USARTDIV[15:4] = BRR[15:4], USARTDIV[3:1] = BRR[2:0]; a bit is USARTDIV / 2.
                let usartdiv = (self.brr & 0xFFF0) | ((self.brr & 0x7) << 1);
                256 * u64::from(usartdiv.max(16)) * divider
            }
            Kind::Usart => 512 * u64::from(self.brr.max(16)) * divider,
        }
    }

    /// Core cycles a character takes: its start bit, word and stop bits.
    fn frame_cycles(&self) -> Cycles {
        let stop_half_bits = match (self.cr2 >> CR2_STOP_SHIFT) & 3 {
            0 => 2,
            1 => 1,
            2 => 4,
            _ => 3,
        };
        let half_bits = 2 * (1 + self.word_bits()) + stop_half_bits;
        (half_bits * self.bit_cycles_x512()).div_ceil(2 * 512)
    }

    /// Core cycles of the driver-enable time in CR1's field at `shift` (DEAT or DEDT), 16ths of
    /// a bit (8ths with OVER8).
    fn driver_enable_time(&self, shift: u32) -> Cycles {
        let sixteenths = u64::from((self.cr1 >> shift) & 0x1F);
        let per_bit = if self.cr1 & CR1_OVER8 != 0 { 8 } else { 16 };
        (sixteenths * self.bit_cycles_x512()).div_ceil(512 * per_bit)
    }

    fn enabled(&self, bit: u32) -> bool {
        self.cr1 & CR1_UE != 0 && self.cr1 & bit != 0
    }

    /// The receive FIFO's bytes that have arrived by `now`.
    fn arrived(&self, now: Cycles) -> usize {
        self.receiving
            .borrow()
            .iter()
            .take_while(|(at, _)| *at <= now)
            .count()
            .min(FIFO_BYTES)
    }

    fn isr(&self, now: Cycles) -> u32 {
        let mut isr = 0;
        let waiting = self
            .transmitting
            .iter()
            .filter(|outgoing| outgoing.done > now)
            .count();
        // The shifter holds one byte, the FIFO eight more.
        if waiting <= FIFO_BYTES {
            isr |= TXFNF;
        }
        if waiting == 0 && !self.tc_cleared {
            isr |= TC;
        }
        if self.arrived(now) > 0 {
            isr |= RXFNE;
        }
        if let Some(last) = self.last_received {
            let idle_at = last + self.frame_cycles();
            if now >= idle_at && self.idle_cleared_for != Some(last) && self.arrived(now) == 0 {
                isr |= IDLE;
            }
        }
        if self.enabled(CR1_TE) {
            isr |= TEACK;
        }
        if self.enabled(CR1_RE) {
            isr |= REACK;
        }
        isr
    }

    /// What RDR gives for `byte`: with PCE, the parity bit in the word's last bit.
    fn received_word(&self, byte: u8) -> u32 {
        let word = self.word_bits() as u32;
        if self.cr1 & CR1_PCE == 0 {
            return u32::from(byte) & ((1 << word) - 1);
        }
        let data = u32::from(byte) & ((1 << (word - 1)) - 1);
        let odd = self.cr1 & CR1_PS != 0;
        let parity = (data.count_ones() % 2 == 1) != odd;
        data | u32::from(parity) << (word - 1)
    }

    pub fn read(&self, offset: u32, now: Cycles) -> Access {
        Access::Value(match offset {
            CR1 => self.cr1,
            CR2 => self.cr2,
            CR3 => self.cr3,
            BRR => self.brr,
            GTPR if self.kind == Kind::Usart => self.gtpr,
            RTOR if self.kind == Kind::Usart => self.rtor,
            PRESC => self.presc,
            ISR => self.isr(now),
            RQR | ICR | TDR => 0,
            RDR => {
                if self.arrived(now) == 0 {
                    0
                } else {
                    let byte = self.receiving.borrow_mut().pop_front();
                    byte.map_or(0, |(_, byte)| self.received_word(byte))
                }
            }
            _ => return Access::Unmodelled,
        })
    }

    /// A write at `now`; false where no register is.
    pub fn write(&mut self, offset: u32, value: u32, now: Cycles) -> bool {
        self.settle(now);
        match offset {
            CR1 => self.cr1 = value,
            CR2 => self.cr2 = value,
            CR3 => self.cr3 = value,
            BRR if self.kind == Kind::Lpuart => self.brr = value & 0xF_FFFF,
            BRR => self.brr = value & 0xFFFF,
            GTPR if self.kind == Kind::Usart => self.gtpr = value & 0xFFFF,
            RTOR if self.kind == Kind::Usart => self.rtor = value,
            PRESC => self.presc = value & 0xF,
            RQR => {}
            ICR => {
                if value & TC != 0 {
                    self.tc_cleared = true;
                }
                if value & IDLE != 0 {
                    self.idle_cleared_for = self.last_received;
                }
            }
            TDR if self.enabled(CR1_TE) => self.transmit(value, now),
            TDR => {}
            _ => return false,
        }
        true
    }

    /// A character for `value` after those still going out; from an idle line, with the driver
    /// enable, DEAT after `now`.
    fn transmit(&mut self, value: u32, now: Cycles) {
        let data_bits = self.word_bits() - u64::from(self.cr1 & CR1_PCE != 0);
        let byte = (value & ((1 << data_bits) - 1)) as u8;
        let driving = self.cr3 & CR3_DEM != 0;
        let start = match self.transmitting.back() {
            Some(last) => last.done.max(now),
            None if driving => now + self.driver_enable_time(CR1_DEAT_SHIFT),
            None => now,
        };
        let done = start + self.frame_cycles();
        self.transmitting.push_back(Outgoing { done, byte });
        self.tc_cleared = false;
        if driving {
            let release = done + self.driver_enable_time(CR1_DEDT_SHIFT);
            self.driver_enabled = match self.driver_enabled {
                Some((from, until)) if until >= now => Some((from, release)),
                _ => Some((now, release)),
            };
        }
    }

    /// The driver enable's level at `now` (DE; CR3's DEP inverts it): asserted from the write
    /// that began a transmission until DEDT after its last stop bit.
    pub fn driver_enable(&self, now: Cycles) -> bool {
        let asserted = self.cr1 & CR1_UE != 0
            && self.cr3 & CR3_DEM != 0
            && self
                .driver_enabled
                .is_some_and(|(from, until)| from <= now && now < until);
        asserted != (self.cr3 & CR3_DEP != 0)
    }

    /// Moves the characters that have ended by `now` to the bytes sent.
    fn settle(&mut self, now: Cycles) {
        while let Some(&outgoing) = self.transmitting.front() {
            if outgoing.done > now {
                break;
            }
            self.transmitting.pop_front();
            self.sent.push((outgoing.done, outgoing.byte));
        }
    }

    /// `bytes` arrive from outside from `at` on, a character each, after any still on their way.
    pub fn receive(&mut self, bytes: &[u8], at: Cycles) {
        let frame = self.frame_cycles();
        let mut receiving = self.receiving.borrow_mut();
        let mut end = receiving.back().map_or(at, |&(done, _)| done.max(at));
        for &byte in bytes {
            end += frame;
            receiving.push_back((end, byte));
            self.last_received = Some(end);
        }
    }

    /// The bytes whose characters have ended by `now`, with those times, since last taken.
    pub fn take_sent(&mut self, now: Cycles) -> Vec<(Cycles, u8)> {
        self.settle(now);
        std::mem::take(&mut self.sent)
    }

    /// The interrupt line at `now`: a flag up whose interrupt CR1 enables (TXFNFIE, TCIE,
    /// RXFNEIE, IDLEIE sit at the flags' own bit positions).
    pub fn interrupt_line(&self, now: Cycles) -> bool {
        self.cr1 & CR1_UE != 0 && self.isr(now) & self.cr1 & (TXFNF | TC | RXFNE | IDLE) != 0
    }

    /// The next time a flag or the driver enable changes on its own: a character ends, in or
    /// out, the line goes idle, or DE is released.
    pub fn next_event(&self, now: Cycles) -> Option<Cycles> {
        let out = self
            .transmitting
            .iter()
            .map(|outgoing| outgoing.done)
            .find(|&done| done > now);
        let into = self
            .receiving
            .borrow()
            .iter()
            .map(|&(done, _)| done)
            .find(|&done| done > now);
        let idle = self
            .last_received
            .map(|last| last + self.frame_cycles())
            .filter(|&at| at > now);
        let released = self
            .driver_enabled
            .map(|(_, until)| until)
            .filter(|&at| at > now);
        [out, into, idle, released].into_iter().flatten().min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 115200 baud from the 170 MHz clock: BRR = 256 · 170e6 / 115200.
    const BRR_115200: u32 = 377_778;
    /// 19200 baud on the USART: BRR = 170e6 / 19200.
    const BRR_19200: u32 = 8_854;

    fn port() -> Usart {
        let mut port = Usart::new(Kind::Lpuart);
        port.write(BRR, BRR_115200, 0);
        port.write(CR1, CR1_UE | CR1_RE | CR1_TE | RXFNE | IDLE, 0);
        port
    }

    /// USART1 as the Modbus port drives it: 19200 baud, 8E1 (a 9-bit word with parity), the
    /// driver enable in hardware.
    fn rs485() -> Usart {
        let mut port = Usart::new(Kind::Usart);
        port.write(CR3, CR3_DEM, 0);
        port.write(BRR, BRR_19200, 0);
        port.write(
            CR1,
            CR1_UE | CR1_RE | CR1_TE | CR1_M0 | CR1_PCE | RXFNE | IDLE,
            0,
        );
        port
    }

    #[test]
    fn a_byte_takes_a_frame_of_ten_bits_at_the_baud_rate() {
        let mut port = port();
        // 86.8 µs a byte at 115200 baud: 14,757 cycles.
        assert_eq!(port.frame_cycles(), 14_757);
        port.write(TDR, u32::from(b'O'), 1_000);
        port.write(TDR, u32::from(b'K'), 1_000);
        assert_eq!(port.read(ISR, 1_000), Access::Value(TXFNF | TEACK | REACK));
        assert!(port.take_sent(15_756).is_empty());
        assert_eq!(port.take_sent(15_757), [(15_757, b'O')]);
        assert_eq!(port.take_sent(30_514), [(30_514, b'K')]);
        assert_eq!(
            port.read(ISR, 30_514),
            Access::Value(TXFNF | TC | TEACK | REACK)
        );
    }

    #[test]
    fn received_bytes_wait_in_the_fifo_and_the_line_goes_idle_a_frame_after_the_last() {
        let mut port = port();
        port.receive(b"ok", 0);
        assert!(!port.interrupt_line(14_756), "nothing arrived yet");
        assert!(port.interrupt_line(14_757));
        assert_eq!(port.next_event(14_757), Some(2 * 14_757));
        assert_eq!(port.read(RDR, 30_000), Access::Value(u32::from(b'o')));
        assert_eq!(port.read(RDR, 30_000), Access::Value(u32::from(b'k')));
        assert_eq!(
            port.read(ISR, 30_000),
            Access::Value(TXFNF | TC | TEACK | REACK)
        );
        assert_eq!(
            port.read(ISR, 3 * 14_757),
            Access::Value(TXFNF | TC | IDLE | TEACK | REACK)
        );
        port.write(ICR, IDLE, 3 * 14_757);
        assert!(!port.interrupt_line(3 * 14_757));
    }

    #[test]
    fn the_usart_counts_eleven_bits_for_8e1_and_8n2_at_f_ck_over_brr() {
        let mut port = rs485();
        // 11 bits of 8,854 cycles: 572.9 µs a character at 19200 baud.
        assert_eq!(port.frame_cycles(), 11 * 8_854);
        port.write(CR1, CR1_UE | CR1_RE | CR1_TE, 0);
        port.write(CR2, 2 << CR2_STOP_SHIFT, 0);
        assert_eq!(port.frame_cycles(), 11 * 8_854);
        port.write(CR2, 0, 0);
        assert_eq!(port.frame_cycles(), 10 * 8_854);
        // OVER8: BRR 0x1143 is USARTDIV 0x1146 = 4,422, a bit of 2,211 cycles.
        port.write(CR1, CR1_UE | CR1_OVER8, 0);
        port.write(BRR, 0x1143, 0);
        assert_eq!(port.frame_cycles(), 10 * 2_211);
    }

    #[test]
    fn the_parity_bit_ends_the_received_word_and_is_not_sent() {
        let mut port = rs485();
        port.receive(&[0x01, 0x03], 0);
        let frame = port.frame_cycles();
        // 0x01 has one bit set: even parity sets bit 8; 0x03 has two: it stays clear.
        assert_eq!(port.read(RDR, 2 * frame), Access::Value(0x101));
        assert_eq!(port.read(RDR, 2 * frame), Access::Value(0x03));
        port.write(TDR, 0x1FF, 2 * frame);
        assert_eq!(port.take_sent(3 * frame), [(3 * frame, 0xFF)]);
    }

    #[test]
    fn the_driver_enable_covers_the_characters_sent_back_to_back_and_no_more() {
        let mut port = rs485();
        let frame = port.frame_cycles();
        assert!(!port.driver_enable(0));
        port.write(TDR, 0x01, 1_000);
        port.write(TDR, 0x02, 1_000);
        assert!(port.driver_enable(1_000));
        assert!(port.driver_enable(1_000 + 2 * frame - 1));
        assert_eq!(port.next_event(1_000 + frame), Some(1_000 + 2 * frame));
        assert!(!port.driver_enable(1_000 + 2 * frame));
        assert_eq!(
            port.take_sent(1_000 + 2 * frame),
            [(1_000 + frame, 0x01), (1_000 + 2 * frame, 0x02)]
        );
        // DEAT and DEDT of 16 sixteenths: a bit before the start bit and after the stop bit.
        port.write(
            CR1,
            port.cr1 | 16 << CR1_DEAT_SHIFT | 16 << CR1_DEDT_SHIFT,
            10 * frame,
        );
        port.write(TDR, 0x03, 10 * frame);
        assert!(port.driver_enable(10 * frame));
        assert_eq!(port.take_sent(11 * frame + 8_853), []);
        assert_eq!(
            port.take_sent(11 * frame + 8_854),
            [(11 * frame + 8_854, 0x03)]
        );
        assert!(port.driver_enable(11 * frame + 2 * 8_854 - 1));
        assert!(!port.driver_enable(11 * frame + 2 * 8_854));
        // DEP: active low.
        port.write(CR3, CR3_DEM | CR3_DEP, 20 * frame);
        assert!(port.driver_enable(20 * frame));
    }
}
