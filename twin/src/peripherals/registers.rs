//! A peripheral's plain registers: the offsets it has, each with its reset value, stored as
//! written. A model keeps its behaviour in its own code and its storage here.

use super::Access;

/// One register: offset, reset value, and the bits a write may change.
#[derive(Debug, Clone, Copy)]
pub struct Register {
    pub offset: u32,
    pub reset: u32,
    pub writable: u32,
}

/// A register that stores every bit written.
pub const fn plain(offset: u32, reset: u32) -> Register {
    Register {
        offset,
        reset,
        writable: u32::MAX,
    }
}

/// A register whose writes change only `writable`.
pub const fn masked(offset: u32, reset: u32, writable: u32) -> Register {
    Register {
        offset,
        reset,
        writable,
    }
}

/// The registers of one peripheral, from its table.
#[derive(Debug, Clone)]
pub struct RegisterFile {
    table: &'static [Register],
    values: Vec<u32>,
}

impl RegisterFile {
    pub fn new(table: &'static [Register]) -> Self {
        RegisterFile {
            table,
            values: table.iter().map(|register| register.reset).collect(),
        }
    }

    fn index(&self, offset: u32) -> Option<usize> {
        self.table
            .iter()
            .position(|register| register.offset == offset)
    }

    pub fn read(&self, offset: u32) -> Access {
        self.index(offset).map_or(Access::Unmodelled, |index| {
            Access::Value(self.values[index])
        })
    }

    /// Stores `value` (its writable bits); `false` for an offset the table has not.
    pub fn write(&mut self, offset: u32, value: u32) -> bool {
        let Some(index) = self.index(offset) else {
            return false;
        };
        let writable = self.table[index].writable;
        self.values[index] = (self.values[index] & !writable) | (value & writable);
        true
    }

    /// The stored value of a register the table has.
    pub fn get(&self, offset: u32) -> u32 {
        self.index(offset).map_or(0, |index| self.values[index])
    }

    /// Sets a register whatever its writable bits (the hardware's side).
    pub fn set(&mut self, offset: u32, value: u32) {
        if let Some(index) = self.index(offset) {
            self.values[index] = value;
        }
    }
}
