//! Exceptions as the core takes them, which the engine leaves to the harness on an M-profile
//! core (ARMv7-M ARM, B1.5): the NVIC's choice against the execution priority, the stack frame
//! with the FPU's extended part, EXC_RETURN, the return, and the faults the core raises itself
//! (escalated to HardFault, or a lockup).

use unicorn_engine::RegisterARM;

use super::{engine_error, Machine, ENTRY_CYCLES, RETURN_CYCLES, XPSR_IT};
use crate::peripherals::scs::HARD_FAULT;
use crate::TwinError;

/// A fault the core raises on an instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum CoreFault {
    /// An undefined instruction (UDF among them): a UsageFault.
    Undefined,
    /// An access the memory map refuses: a BusFault, at `address` where known.
    Bus { address: Option<u32> },
}

/// CFSR bits (ARMv7-M ARM, B3.2.15): UNDEFINSTR, PRECISERR with BFARVALID, STKERR.
const CFSR_UNDEFINSTR: u32 = 1 << 16;
const CFSR_PRECISERR: u32 = 1 << 9;
const CFSR_BFARVALID: u32 = 1 << 15;
const CFSR_STKERR: u32 = 1 << 12;

/// The core registers of an exception frame, in their order on the stack (xPSR follows).
const FRAME_REGISTERS: [RegisterARM; 7] = [
    RegisterARM::R0,
    RegisterARM::R1,
    RegisterARM::R2,
    RegisterARM::R3,
    RegisterARM::R12,
    RegisterARM::LR,
    RegisterARM::PC,
];

/// The IT block an xPSR is in: its instructions left, counting the first after it (the hook's
/// count), 0 outside one. IT[3:0]'s lowest set bit moves up one an instruction, so it is at bit
/// `4 - n` with `n` instructions left (ARMv7-M ARM, A7.3.3).
fn if_then_left(xpsr: u32) -> u8 {
    let low = ((xpsr >> 25) & 3) | (((xpsr >> 10) & 3) << 2);
    if low == 0 {
        0
    } else {
        5 - low.trailing_zeros() as u8
    }
}

impl Machine<'_> {
    /// A fault of the instruction at the current `pc` (ARMv7-M ARM, B1.5.14): escalated to
    /// HardFault, with its cause in CFSR (and the address in BFAR); where the execution
    /// priority is already −1 or less (FAULTMASK, in HardFault or NMI), the core locks up.
    pub(super) fn fault(&mut self, fault: CoreFault) -> Result<(), TwinError> {
        let pc = self.engine.get_data().pc;
        self.set_reg(RegisterARM::PC, pc)?;
        if self.execution_priority() <= -1 {
            self.engine.get_data_mut().locked = true;
            return Ok(());
        }
        let (cfsr, address) = match fault {
            CoreFault::Undefined => (CFSR_UNDEFINSTR, None),
            CoreFault::Bus { address } => (CFSR_PRECISERR | CFSR_BFARVALID, address),
        };
        self.engine
            .get_data_mut()
            .board
            .scs
            .record_fault(cfsr, address);
        self.enter(HARD_FAULT)
    }

    /// The execution priority: the active exceptions', raised by PRIMASK, FAULTMASK, BASEPRI.
    fn execution_priority(&self) -> i32 {
        let scs = &self.board().scs;
        let mut priority = scs.active_priority();
        let basepri = self.reg(RegisterARM::BASEPRI) & 0xFF;
        if basepri != 0 {
            priority = priority.min(scs.group(basepri as i32));
        }
        if self.reg(RegisterARM::PRIMASK) & 1 != 0 {
            priority = priority.min(0);
        }
        if self.reg(RegisterARM::FAULTMASK) & 1 != 0 {
            priority = priority.min(-1);
        }
        priority
    }

    /// Takes the highest pending exception if it preempts what runs.
    pub(super) fn take_exception(&mut self) -> Result<bool, TwinError> {
        let scs = &self.board().scs;
        let Some((number, priority)) = scs.highest_pending() else {
            return Ok(false);
        };
        if scs.group(priority) >= self.execution_priority() {
            return Ok(false);
        }
        self.enter(number)?;
        Ok(true)
    }

    /// Exception entry (ARMv7-M ARM, B1.5.6): the frame on the main stack (with the
    /// floating-point part where the thread used the FPU), EXC_RETURN in LR, the handler from
    /// the vector table.
    pub(super) fn enter(&mut self, number: u32) -> Result<(), TwinError> {
        let control = self.reg(RegisterARM::CONTROL);
        let in_handler = !self.engine.get_data().active.is_empty();
        let floating = control & 4 != 0;
        if control & 2 != 0 && !in_handler {
            return Err(TwinError::Engine {
                what: "take an exception from the process stack".into(),
                problem: "the twin models the main stack only".into(),
            });
        }
        let mut frame: Vec<u32> = FRAME_REGISTERS.iter().map(|&r| self.reg(r)).collect();
        let ipsr = self.engine.get_data().active.last().copied().unwrap_or(0);
        let xpsr = (self.reg(RegisterARM::XPSR) & !0x1FF) | ipsr | 1 << 24;
        frame.push(xpsr);
        if floating {
            for index in 0..16 {
                frame.push(self.reg_s(index));
            }
            frame.push(self.reg(RegisterARM::FPSCR));
            frame.push(0);
        }
        let sp = self.reg(RegisterARM::SP);
        let mut top = sp - 4 * frame.len() as u32;
        if top & 4 != 0 {
            top -= 4;
            frame[7] |= 1 << 9;
        }
        let state = self.engine.get_data_mut();
        state.lowest_sp = state.lowest_sp.min(top);
        // A frame that cannot be stacked is a bus fault on stacking (STKERR): the handler is
        // entered all the same, the stack pointer moved, the frame not written.
        let stacked = (0..frame.len() as u32).all(|index| {
            self.write_word(top + 4 * index, frame[index as usize])
                .is_some()
        });
        if !stacked {
            self.engine
                .get_data_mut()
                .board
                .scs
                .record_fault(CFSR_STKERR, None);
        }
        let vector_table = self.board().scs.vector_table();
        let handler = self.read_word(vector_table + 4 * number).unwrap_or(0);
        let exc_return = match (floating, in_handler) {
            (false, true) => 0xFFFF_FFF1,
            (false, false) => 0xFFFF_FFF9,
            (true, true) => 0xFFFF_FFE1,
            (true, false) => 0xFFFF_FFE9,
        };
        self.set_reg(RegisterARM::SP, top)?;
        self.set_reg(RegisterARM::LR, exc_return)?;
        // The handler starts outside any IT block (EPSR.IT = 0); the interrupted one's state
        // is in the frame, and its return restores it.
        let live = self.reg(RegisterARM::XPSR);
        self.set_reg(RegisterARM::XPSR, live & !XPSR_IT)?;
        self.engine.get_data_mut().if_then_left = 0;
        self.set_reg(RegisterARM::CONTROL, control & !4)?;
        self.set_reg(RegisterARM::PC, handler & !1)?;
        let state = self.engine.get_data_mut();
        state.board.scs.activate(number);
        state.active.push(number);
        state.extra_cycles += ENTRY_CYCLES;
        state.event = true;
        Ok(())
    }

    /// Exception return on `exc_return` (ARMv7-M ARM, B1.5.8): the frame back off the stack,
    /// the exception no longer active.
    pub(super) fn exception_return(&mut self, exc_return: u32) -> Result<(), TwinError> {
        let state = self.engine.get_data_mut();
        let Some(number) = state.active.pop() else {
            return Err(TwinError::Engine {
                what: format!("return from an exception (EXC_RETURN 0x{exc_return:08x})"),
                problem: "no exception is active".into(),
            });
        };
        state.board.scs.deactivate(number);
        state.extra_cycles += RETURN_CYCLES;
        state.event = true;
        let floating = exc_return & 0x10 == 0;
        let sp = self.reg(RegisterARM::SP);
        let words = if floating { 26 } else { 8 };
        let mut frame = Vec::with_capacity(words);
        for index in 0..words as u32 {
            frame.push(
                self.read_word(sp + 4 * index)
                    .ok_or_else(|| TwinError::Engine {
                        what: format!("unstack at 0x{sp:08x}"),
                        problem: "the stack is outside RAM".into(),
                    })?,
            );
        }
        for (register, value) in FRAME_REGISTERS.iter().zip(&frame) {
            self.set_reg(*register, *value)?;
        }
        let xpsr = frame[7];
        self.set_reg(RegisterARM::XPSR, xpsr & !0x1FF)?;
        self.engine.get_data_mut().if_then_left = if_then_left(xpsr);
        if floating {
            for index in 0..16 {
                self.set_reg_s(index, frame[8 + index as usize])?;
            }
            self.set_reg(RegisterARM::FPSCR, frame[24])?;
        }
        let control = self.reg(RegisterARM::CONTROL);
        let control = if floating { control | 4 } else { control & !4 };
        self.set_reg(RegisterARM::CONTROL, control)?;
        let padding = if xpsr & (1 << 9) != 0 { 4 } else { 0 };
        self.set_reg(RegisterARM::SP, sp + 4 * words as u32 + padding)?;
        Ok(())
    }

    fn reg_s(&self, index: u32) -> u32 {
        self.engine
            .reg_read(RegisterARM::S0 as i32 + index as i32)
            .unwrap_or(0) as u32
    }

    fn set_reg_s(&mut self, index: u32, value: u32) -> Result<(), TwinError> {
        self.engine
            .reg_write(RegisterARM::S0 as i32 + index as i32, u64::from(value))
            .map_err(engine_error("set a floating-point register"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An xPSR with ITSTATE `it` (IT[1:0] at 26:25, IT[7:2] at 15:10).
    fn xpsr(it: u32) -> u32 {
        1 << 24 | (it & 3) << 25 | (it >> 2) << 10
    }

    #[test]
    fn an_interrupted_if_then_block_counts_on_from_where_it_stopped() {
        // ITTE NE (firstcond 0001, mask 1010): three instructions, then one more with
        // each shift of IT[4:0] one fewer.
        assert_eq!(if_then_left(xpsr(0x1A)), 4, "three left, and the one after");
        assert_eq!(if_then_left(xpsr(0x14)), 3);
        assert_eq!(if_then_left(xpsr(0x08)), 2, "the last of the block");
        assert_eq!(if_then_left(xpsr(0)), 0, "outside a block");
    }
}
