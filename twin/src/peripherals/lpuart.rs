//! LPUART1 (RM0440, "Low-power universal asynchronous receiver transmitter"), as the console
//! drives it with its FIFOs enabled (embassy's buffered driver): 8N1 at `256 · f_ck / BRR`
//! baud, `f_ck` the core's clock through PRESC; a byte written to TDR waits in the 8-byte
//! transmit FIFO and leaves the shifter a frame (10 bits) later; bytes from outside arrive in
//! the 8-byte receive FIFO one frame apart, and RDR takes them. ISR's TXFNF, TC, RXFNE and IDLE
//! follow, and the interrupt line is up where one of them is enabled in CR1.

use std::cell::RefCell;
use std::collections::VecDeque;

use super::{Access, Cycles};

const CR1: u32 = 0x00;
const CR2: u32 = 0x04;
const CR3: u32 = 0x08;
const BRR: u32 = 0x0C;
const RQR: u32 = 0x18;
const ISR: u32 = 0x1C;
const ICR: u32 = 0x20;
const RDR: u32 = 0x24;
const TDR: u32 = 0x28;
const PRESC: u32 = 0x2C;

const CR1_UE: u32 = 1;
const CR1_RE: u32 = 1 << 2;
const CR1_TE: u32 = 1 << 3;
const IDLE: u32 = 1 << 4;
const RXFNE: u32 = 1 << 5;
const TC: u32 = 1 << 6;
const TXFNF: u32 = 1 << 7;
/// ISR's TEACK and REACK: the transmitter and the receiver enabled.
const TEACK: u32 = 1 << 21;
const REACK: u32 = 1 << 22;

/// Each FIFO's depth.
const FIFO_BYTES: usize = 8;
/// Bits of an 8N1 frame.
const FRAME_BITS: u64 = 10;
/// PRESC's dividers (RM0440, "LPUART prescaler register").
const DIVIDERS: [u64; 12] = [1, 2, 4, 6, 8, 10, 12, 16, 32, 64, 128, 256];

#[derive(Debug, Clone, Default)]
pub struct Lpuart {
    cr1: u32,
    cr2: u32,
    cr3: u32,
    brr: u32,
    presc: u32,
    /// Bytes written to TDR, each with the time its frame ends on the line.
    transmitting: VecDeque<(Cycles, u8)>,
    /// Bytes whose frame has ended, with that time, until taken.
    sent: Vec<(Cycles, u8)>,
    /// Bytes on their way in, each with the time its frame ends, until RDR takes them.
    receiving: RefCell<VecDeque<(Cycles, u8)>>,
    /// The end of the last frame received, for IDLE.
    last_received: Option<Cycles>,
    /// IDLE cleared (ICR) for the idle line after this frame.
    idle_cleared_for: Option<Cycles>,
    /// TC cleared (ICR) since the last frame sent.
    tc_cleared: bool,
}

impl Lpuart {
    /// Core cycles a frame takes: `10 · BRR / 256` cycles of the kernel clock.
    fn frame_cycles(&self) -> Cycles {
        let divider = DIVIDERS
            .get(self.presc as usize & 0xF)
            .copied()
            .unwrap_or(256);
        (FRAME_BITS * u64::from(self.brr.max(0x300)) * divider).div_ceil(256)
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
            .filter(|(done, _)| *done > now)
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

    pub fn read(&self, offset: u32, now: Cycles) -> Access {
        Access::Value(match offset {
            CR1 => self.cr1,
            CR2 => self.cr2,
            CR3 => self.cr3,
            BRR => self.brr,
            PRESC => self.presc,
            ISR => self.isr(now),
            RQR | ICR | TDR => 0,
            RDR => {
                if self.arrived(now) == 0 {
                    0
                } else {
                    self.receiving
                        .borrow_mut()
                        .pop_front()
                        .map_or(0, |(_, byte)| u32::from(byte))
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
            BRR => self.brr = value & 0xF_FFFF,
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
            TDR if self.enabled(CR1_TE) => {
                let start = self
                    .transmitting
                    .back()
                    .map_or(now, |&(done, _)| done.max(now));
                self.transmitting
                    .push_back((start + self.frame_cycles(), value as u8));
                self.tc_cleared = false;
            }
            TDR => {}
            _ => return false,
        }
        true
    }

    /// Moves the frames that have ended by `now` to the bytes sent.
    fn settle(&mut self, now: Cycles) {
        while let Some(&(done, byte)) = self.transmitting.front() {
            if done > now {
                break;
            }
            self.transmitting.pop_front();
            self.sent.push((done, byte));
        }
    }

    /// `bytes` arrive from outside from `at` on, a frame each, after any still on their way.
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

    /// The bytes whose frames have ended by `now`, with those times, since last taken.
    pub fn take_sent(&mut self, now: Cycles) -> Vec<(Cycles, u8)> {
        self.settle(now);
        std::mem::take(&mut self.sent)
    }

    /// The interrupt line at `now`: a flag up whose interrupt CR1 enables (TXFNFIE, TCIE,
    /// RXFNEIE, IDLEIE sit at the flags' own bit positions).
    pub fn interrupt_line(&self, now: Cycles) -> bool {
        self.cr1 & CR1_UE != 0 && self.isr(now) & self.cr1 & (TXFNF | TC | RXFNE | IDLE) != 0
    }

    /// The next time a flag changes on its own: a frame ends, in or out, or the line goes idle.
    pub fn next_event(&self, now: Cycles) -> Option<Cycles> {
        let out = self
            .transmitting
            .iter()
            .map(|&(done, _)| done)
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
        [out, into, idle].into_iter().flatten().min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 115200 baud from the 170 MHz clock: BRR = 256 · 170e6 / 115200.
    const BRR_115200: u32 = 377_778;

    fn port() -> Lpuart {
        let mut port = Lpuart::default();
        port.write(BRR, BRR_115200, 0);
        port.write(CR1, CR1_UE | CR1_RE | CR1_TE | RXFNE | IDLE, 0);
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
}
