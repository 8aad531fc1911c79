//! The engine's hooks and the bus behind them: every instruction (time, hints, the slice's
//! budget, the work per edge), the peripherals' registers, flash reads, refused accesses and
//! CPU exceptions; the DMA's moves, and memory as the RTT reader sees it.

use unicorn_engine::{HookType, RegisterARM, Unicorn};

use super::{
    engine_error, SliceEnd, State, FLASH, FLASH_BYTES, PERIPHERALS, PERIPHERALS_BYTES, PRIVATE,
    PRIVATE_BYTES, TIM2_ARR, XPSR_IT,
};
use crate::image::Watched;
use crate::peripherals::scs::Request;
use crate::peripherals::{Board, Cycles};
use crate::rtt::Memory;
use crate::TwinError;

/// The engine's memory, for the RTT reader.
pub(super) struct EngineMemory<'e, 'a>(pub(super) &'e mut Unicorn<'a, State>);

impl Memory for EngineMemory<'_, '_> {
    fn read_word(&self, address: u32) -> Option<u32> {
        let mut bytes = [0; 4];
        self.0.mem_read(u64::from(address), &mut bytes).ok()?;
        Some(u32::from_le_bytes(bytes))
    }

    fn read_bytes(&self, address: u32, bytes: &mut [u8]) -> Option<()> {
        self.0.mem_read(u64::from(address), bytes).ok()
    }

    fn write_word(&mut self, address: u32, value: u32) -> Option<()> {
        self.0
            .mem_write(u64::from(address), &value.to_le_bytes())
            .ok()
    }
}

/// Carries out the DMA's requested moves: each item read from its source (a register or
/// memory) and written to its destination; an address that answers neither is a transfer
/// error.
pub(super) fn move_items(engine: &mut Unicorn<'_, State>) {
    loop {
        let items = engine.get_data_mut().board.take_moves();
        if items.is_empty() {
            return;
        }
        for item in items {
            let now = engine.get_data().now();
            let broken = engine.get_data().board.dma_channel_broken == Some(item.channel);
            let value = read_any(engine, item.from, item.size, now).filter(|_| !broken);
            let written = value.and_then(|value| write_any(engine, item.to, item.size, value, now));
            engine.get_data_mut().board.moved(&item, written.is_none());
        }
    }
}

fn is_register(address: u32) -> bool {
    (PERIPHERALS..PERIPHERALS + PERIPHERALS_BYTES).contains(&u64::from(address))
        || (PRIVATE..PRIVATE + PRIVATE_BYTES).contains(&u64::from(address))
}

fn read_any(engine: &mut Unicorn<'_, State>, address: u32, size: u32, now: Cycles) -> Option<u32> {
    if is_register(address) {
        let state = engine.get_data_mut();
        state.before_read(address, now);
        let word = state.board.read(address & !3, now).ok()?;
        return Some(narrow(word, address, size));
    }
    let mut bytes = [0u8; 4];
    engine
        .mem_read(u64::from(address), &mut bytes[..size as usize])
        .ok()?;
    Some(u32::from_le_bytes(bytes))
}

fn write_any(
    engine: &mut Unicorn<'_, State>,
    address: u32,
    size: u32,
    value: u32,
    now: Cycles,
) -> Option<()> {
    if is_register(address) {
        let board = &mut engine.get_data_mut().board;
        let word = widen(board, address, size, value, now)?;
        board.write(address & !3, word, now).ok()?;
        return Some(());
    }
    engine
        .mem_write(u64::from(address), &value.to_le_bytes()[..size as usize])
        .ok()
}

/// The `size` bytes at `address` out of the word that holds them.
fn narrow(word: u32, address: u32, size: u32) -> u32 {
    let shifted = word >> (8 * (address & 3));
    match size {
        1 => shifted & 0xFF,
        2 => shifted & 0xFFFF,
        _ => shifted,
    }
}

/// A write of `size` bytes at `address` as a word: the other bytes as the register reads.
fn widen(board: &mut Board, address: u32, size: u32, value: u32, now: Cycles) -> Option<u32> {
    if size >= 4 {
        return Some(value);
    }
    let shift = 8 * (address & 3);
    let mask = if size == 1 { 0xFF } else { 0xFFFF } << shift;
    let current = board.read(address & !3, now).unwrap_or(0);
    Some((current & !mask) | ((value << shift) & mask))
}

/// The engine's hooks: every instruction (time, hints, the slice's budget), the peripherals'
/// bus, CPU exceptions.
pub(super) fn install_hooks(engine: &mut Unicorn<'_, State>) -> Result<(), TwinError> {
    let hook = engine_error("install its hooks");
    engine
        .add_code_hook(0, u64::MAX, |uc, address, size| {
            let sp = uc.reg_read(RegisterARM::SP).unwrap_or(u64::MAX) as u32;
            // The engine keeps a finished IT block's state in its register file, where the
            // next indirect branch (or the next slice's start) looks its target's translation
            // up with it: the target's first instructions then run as if the block went on (a
            // function's push skipped). At the first instruction after the block it goes,
            // before anything can stop the slice here.
            if uc.get_data().if_then_left == 1 {
                let xpsr = uc.reg_read(RegisterARM::XPSR).unwrap_or(0);
                if xpsr & u64::from(XPSR_IT) != 0 {
                    let _ = uc.reg_write(RegisterARM::XPSR, xpsr & !u64::from(XPSR_IT));
                }
            }
            let state = uc.get_data_mut();
            state.lowest_sp = state.lowest_sp.min(sp);
            let address = address as u32;
            if state.executed >= state.budget {
                state.end = Some(SliceEnd::Budget);
                let _ = uc.emu_stop();
                return;
            }
            // A register write that asks for the machine stops the core here, at the next
            // instruction, where its state is whole.
            if let Some(end) = state.requested.take() {
                state.end = Some(end);
                let _ = uc.emu_stop();
                return;
            }
            match (size, state.image.watched(address)) {
                (2, Some(Watched::Hint(hint))) => {
                    state.end = Some(SliceEnd::Hint(hint, address));
                    let _ = uc.emu_stop();
                    return;
                }
                (2, Some(Watched::IfThen { instructions })) => {
                    state.if_then_left = instructions + 1;
                }
                _ => state.if_then_left = state.if_then_left.saturating_sub(1),
            }
            state.pc = address;
            state.executed += 1;
            if let Some(work) = state.edge.as_mut() {
                work.instructions += 1;
                work.code_bytes += u64::from(size);
            }
        })
        .map_err(&hook)?;
    for (base, bytes) in [(PERIPHERALS, PERIPHERALS_BYTES), (PRIVATE, PRIVATE_BYTES)] {
        engine
            .mmio_map(
                base,
                bytes,
                Some(
                    move |uc: &mut Unicorn<'_, State>, offset: u64, size: usize| {
                        let address = (base + offset) as u32;
                        let state = uc.get_data_mut();
                        let now = state.now();
                        state.before_read(address, now);
                        match state.board.read(address & !3, now) {
                            Ok(word) => u64::from(narrow(word, address, size as u32)),
                            Err(refused) => {
                                state.end = Some(SliceEnd::Refused {
                                    address: refused.address,
                                    pc: state.pc,
                                    write: false,
                                });
                                let _ = uc.emu_stop();
                                0
                            }
                        }
                    },
                ),
                Some(
                    move |uc: &mut Unicorn<'_, State>, offset: u64, size: usize, value: u64| {
                        let address = (base + offset) as u32;
                        let state = uc.get_data_mut();
                        let now = state.now();
                        if let Some(writes) = state.writes.as_mut() {
                            writes.push((address, value as u32));
                        }
                        if address == TIM2_ARR {
                            if let Some(work) = state.edge.take() {
                                if work.instructions > state.worst_edge.instructions {
                                    state.worst_edge = work;
                                }
                                state.edges_measured += 1;
                            }
                        }
                        let result =
                            widen(&mut state.board, address, size as u32, value as u32, now)
                                .ok_or(())
                                .and_then(|word| {
                                    state.board.write(address & !3, word, now).map_err(|_| ())
                                });
                        match result {
                            Err(()) => {
                                state.end = Some(SliceEnd::Refused {
                                    address: address & !3,
                                    pc: state.pc,
                                    write: true,
                                });
                                let _ = uc.emu_stop();
                            }
                            Ok(Request::Reset) => state.requested = Some(SliceEnd::SystemReset),
                            Ok(Request::Evaluate) => {
                                move_items(uc);
                                let state = uc.get_data_mut();
                                state.deliver_outputs();
                                if state.board.scs.highest_pending().is_some()
                                    && state.requested.is_none()
                                {
                                    state.requested = Some(SliceEnd::Evaluate);
                                }
                            }
                            Ok(Request::None) => {}
                        }
                    },
                ),
            )
            .map_err(&hook)?;
    }
    engine
        .add_mem_hook(
            HookType::MEM_READ,
            FLASH,
            FLASH + FLASH_BYTES - 1,
            |uc, _kind, _address, _size, _value| {
                if let Some(work) = uc.get_data_mut().edge.as_mut() {
                    work.flash_reads += 1;
                }
                true
            },
        )
        .map_err(&hook)?;
    engine
        .add_mem_hook(
            HookType::MEM_INVALID,
            0,
            u64::MAX,
            |uc, _kind, address, _size, _value| {
                uc.get_data_mut().bad_access = Some(address as u32);
                false
            },
        )
        .map_err(&hook)?;
    engine
        .add_intr_hook(|uc, number| {
            let state = uc.get_data_mut();
            state.end = Some(SliceEnd::CpuException(number));
            let _ = uc.emu_stop();
        })
        .map_err(&hook)?;
    Ok(())
}
