//! DMA1 and DMAMUX1 (RM0440, "Direct memory access controller", "DMA request multiplexer"):
//! a request line routed through the multiplexer's channel to the DMA channel of the same index,
//! which moves one item per request (peripheral to memory or back, with its sizes, increments,
//! circular mode), counts down, and raises its half and complete flags and interrupts. The
//! machine carries out the move, which reads and writes the bus.

use super::registers::{plain, Register, RegisterFile};
use super::Access;

/// DMA1's channels on the STM32G474.
pub const CHANNELS: usize = 8;

const ISR: u32 = 0x00;
const IFCR: u32 = 0x04;

const CCR_EN: u32 = 1 << 0;
const CCR_TCIE: u32 = 1 << 1;
const CCR_HTIE: u32 = 1 << 2;
const CCR_TEIE: u32 = 1 << 3;
const CCR_DIR: u32 = 1 << 4;
const CCR_CIRC: u32 = 1 << 5;
const CCR_PINC: u32 = 1 << 6;
const CCR_MINC: u32 = 1 << 7;
const CCR_MEM2MEM: u32 = 1 << 14;

const FLAG_GIF: u32 = 1;
const FLAG_TCIF: u32 = 2;
const FLAG_HTIF: u32 = 4;
const FLAG_TEIF: u32 = 8;

/// DMAMUX request lines the twin's timers raise (RM0440, "DMAMUX: assignment of multiplexer
/// inputs to resources").
pub const REQUEST_TIM6_UP: u32 = 8;
pub const REQUEST_TIM1_UP: u32 = 42;
pub const REQUEST_TIM2_UP: u32 = 60;

/// One item to move: read `size` bytes at `from`, write them at `to`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Move {
    pub channel: usize,
    pub from: u32,
    pub to: u32,
    pub size: u32,
}

#[derive(Debug, Clone, Copy, Default)]
struct Channel {
    ccr: u32,
    cndtr: u32,
    cpar: u32,
    cmar: u32,
    /// The count and addresses loaded when the channel was enabled (circular mode reloads).
    loaded_count: u32,
    /// Items moved since the last reload.
    moved: u32,
}

impl Channel {
    fn size(bits: u32) -> u32 {
        1 << bits.min(2)
    }
}

#[derive(Debug, Clone)]
pub struct Dma {
    channels: [Channel; CHANNELS],
    flags: u32,
}

impl Dma {
    pub fn new() -> Self {
        Dma {
            channels: [Channel::default(); CHANNELS],
            flags: 0,
        }
    }

    pub fn read(&self, offset: u32) -> Access {
        match offset {
            ISR => Access::Value(self.flags),
            IFCR => Access::Value(0),
            0x08..=0xA4 => {
                let (index, register) = ((offset - 0x08) / 0x14, (offset - 0x08) % 0x14);
                let Some(channel) = self.channels.get(index as usize) else {
                    return Access::Unmodelled;
                };
                match register {
                    0x00 => Access::Value(channel.ccr),
                    0x04 => Access::Value(channel.cndtr),
                    0x08 => Access::Value(channel.cpar),
                    0x0C => Access::Value(channel.cmar),
                    _ => Access::Unmodelled,
                }
            }
            _ => Access::Unmodelled,
        }
    }

    pub fn write(&mut self, offset: u32, value: u32) -> bool {
        match offset {
            ISR => true,
            IFCR => {
                let mut clear = value;
                for index in 0..CHANNELS {
                    if value & (FLAG_GIF << (4 * index)) != 0 {
                        clear |= 0xF << (4 * index);
                    }
                }
                self.flags &= !clear;
                true
            }
            0x08..=0xA4 => {
                let (index, register) = ((offset - 0x08) / 0x14, (offset - 0x08) % 0x14);
                let Some(channel) = self.channels.get_mut(index as usize) else {
                    return false;
                };
                let enabled = channel.ccr & CCR_EN != 0;
                match register {
                    0x00 => {
                        channel.ccr = value & 0x7FFF;
                        if !enabled && value & CCR_EN != 0 {
                            channel.loaded_count = channel.cndtr;
                            channel.moved = 0;
                        }
                    }
                    // Count and addresses are read-only while the channel is enabled.
                    0x04 if !enabled => channel.cndtr = value & 0xFFFF,
                    0x08 if !enabled => channel.cpar = value,
                    0x0C if !enabled => channel.cmar = value,
                    0x04 | 0x08 | 0x0C => {}
                    _ => return false,
                }
                true
            }
            _ => false,
        }
    }

    /// A request on `channel` (from its multiplexer): the item it moves, if enabled with items
    /// left. Call [`Dma::moved`] once the move is done.
    pub fn request(&self, channel: usize) -> Option<Move> {
        let state = &self.channels[channel];
        if state.ccr & CCR_EN == 0 || state.cndtr == 0 || state.ccr & CCR_MEM2MEM != 0 {
            return None;
        }
        let psize = Channel::size((state.ccr >> 8) & 3);
        let msize = Channel::size((state.ccr >> 10) & 3);
        let peripheral = state.cpar
            + if state.ccr & CCR_PINC != 0 {
                state.moved * psize
            } else {
                0
            };
        let memory = state.cmar
            + if state.ccr & CCR_MINC != 0 {
                state.moved * msize
            } else {
                0
            };
        Some(if state.ccr & CCR_DIR == 0 {
            Move {
                channel,
                from: peripheral,
                to: memory,
                size: msize.min(psize),
            }
        } else {
            Move {
                channel,
                from: memory,
                to: peripheral,
                size: msize.min(psize),
            }
        })
    }

    /// The move of `channel`'s item is done (or failed, `error`): the count, flags, circular
    /// reload; whether the channel's interrupt is now raised.
    pub fn moved(&mut self, channel: usize, error: bool) -> bool {
        let state = &mut self.channels[channel];
        let shift = 4 * channel;
        if error {
            state.ccr &= !CCR_EN;
            self.flags |= (FLAG_TEIF | FLAG_GIF) << shift;
            return state.ccr & CCR_TEIE != 0;
        }
        state.cndtr -= 1;
        state.moved += 1;
        let mut raised = false;
        if state.moved == state.loaded_count.div_ceil(2) {
            self.flags |= (FLAG_HTIF | FLAG_GIF) << shift;
            raised |= state.ccr & CCR_HTIE != 0;
        }
        if state.cndtr == 0 {
            self.flags |= (FLAG_TCIF | FLAG_GIF) << shift;
            raised |= state.ccr & CCR_TCIE != 0;
            if state.ccr & CCR_CIRC != 0 {
                state.cndtr = state.loaded_count;
                state.moved = 0;
            }
        }
        raised
    }

    /// Whether `channel`'s interrupt line is up (an enabled flag set).
    pub fn interrupt_line(&self, channel: usize) -> bool {
        let flags = (self.flags >> (4 * channel)) & 0xE;
        let enabled = self.channels[channel].ccr & (CCR_TCIE | CCR_HTIE | CCR_TEIE);
        flags & enabled != 0
    }
}

const MUX_TABLE: &[Register] = &[
    plain(0x00, 0),
    plain(0x04, 0),
    plain(0x08, 0),
    plain(0x0C, 0),
    plain(0x10, 0),
    plain(0x14, 0),
    plain(0x18, 0),
    plain(0x1C, 0),
    plain(0x20, 0),
    plain(0x24, 0),
    plain(0x28, 0),
    plain(0x2C, 0),
    plain(0x30, 0),
    plain(0x34, 0),
    plain(0x38, 0),
    plain(0x3C, 0),
    plain(0x80, 0),
    plain(0x84, 0),
    plain(0x100, 0),
    plain(0x104, 0),
    plain(0x108, 0),
    plain(0x10C, 0),
    plain(0x140, 0),
    plain(0x144, 0),
];

/// DMAMUX1: channel `c`'s request selection (DMAREQ_ID, bits 6:0) routes to DMA1 channel
/// `c + 1`.
#[derive(Debug, Clone)]
pub struct Dmamux {
    registers: RegisterFile,
}

impl Dmamux {
    pub fn new() -> Self {
        Dmamux {
            registers: RegisterFile::new(MUX_TABLE),
        }
    }

    pub fn read(&self, offset: u32) -> Access {
        self.registers.read(offset)
    }

    pub fn write(&mut self, offset: u32, value: u32) -> bool {
        self.registers.write(offset, value)
    }

    /// The DMA1 channels (0-based) that take request line `request`.
    pub fn routes(&self, request: u32) -> impl Iterator<Item = usize> + '_ {
        (0..CHANNELS).filter(move |&c| self.registers.get(4 * c as u32) & 0x7F == request)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_circular_channel_moves_its_items_and_reloads() {
        let mut dma = Dma::new();
        // CCR as the encoder's channel has it: circular, memory increment, 16-bit both sides.
        dma.write(0x0C, 2);
        dma.write(0x10, 0x4000_0824);
        dma.write(0x14, 0x2000_0000);
        dma.write(0x08, 0x35A1);
        let first = dma.request(0).unwrap();
        assert_eq!(
            (first.from, first.to, first.size),
            (0x4000_0824, 0x2000_0000, 2)
        );
        assert!(!dma.moved(0, false));
        assert_eq!(dma.request(0).unwrap().to, 0x2000_0002);
        dma.moved(0, false);
        assert_eq!(dma.read(ISR), Access::Value(0x7), "half, complete, global");
        assert_eq!(dma.request(0).unwrap().to, 0x2000_0000, "reloaded");
    }

    #[test]
    fn an_error_disables_the_channel_and_flags_it() {
        let mut dma = Dma::new();
        dma.write(0x20, 1);
        dma.write(0x1C, CCR_EN | CCR_TEIE);
        assert!(dma.moved(1, true));
        assert_eq!(dma.read(0x1C), Access::Value(CCR_TEIE));
        assert!(dma.interrupt_line(1));
    }
}
