//! The firmware's release ELF as the board's flash holds it: its loadable segments, its
//! functions (to name a program counter) and the instructions the twin handles itself.

use std::collections::BTreeMap;
use std::path::Path;

use object::elf::PT_LOAD;
use object::read::elf::{ElfFile32, ProgramHeader};
use object::{Endianness, Object, ObjectSymbol, SymbolKind};

use crate::TwinError;

/// `WFI`, `WFE` and `SEV` (Thumb, 16 bits): the core sleeps, or signals an event.
const WFI: u16 = 0xBF30;
const WFE: u16 = 0xBF20;
const SEV: u16 = 0xBF40;

/// What the twin does at a halfword of the program that is one of its own instructions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hint {
    WaitForInterrupt,
    WaitForEvent,
    SendEvent,
}

/// A 16-bit instruction the twin watches for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Watched {
    /// One the twin carries out itself.
    Hint(Hint),
    /// `IT` with the number of instructions its block makes conditional (1 to 4).
    IfThen { instructions: u8 },
}

/// The `IT` instruction's encoding: 0xBF, then firstcond and a mask that is not zero.
fn if_then(halfword: u16) -> Option<Watched> {
    let mask = halfword & 0xF;
    (halfword & 0xFF00 == 0xBF00 && mask != 0).then(|| Watched::IfThen {
        instructions: 4 - mask.trailing_zeros() as u8,
    })
}

/// A loaded image.
pub struct Image {
    /// `(address, bytes)` of every loadable segment with file contents.
    pub segments: Vec<(u32, Vec<u8>)>,
    /// Function start addresses (Thumb bit clear) and their names.
    functions: BTreeMap<u32, String>,
    /// Data symbols by name: the RTT control block among them.
    symbols: BTreeMap<String, u32>,
    /// The watched instruction at each halfword from `hints_from` on, if one is there: one lookup
    /// per 16-bit instruction executed.
    hints: Vec<Option<Watched>>,
    hints_from: u32,
}

/// The symbols of the stack's lowest address and of its top (cortex-m-rt's initial SP).
const STACK_BOTTOM: &str = "_stack_end";
const STACK_TOP: &str = "_stack_start";

impl Image {
    pub fn load(path: &Path) -> Result<Self, TwinError> {
        let bytes = std::fs::read(path).map_err(|error| TwinError::Image {
            path: path.display().to_string(),
            problem: error.to_string(),
        })?;
        let problem = |error: &dyn std::fmt::Display| TwinError::Image {
            path: path.display().to_string(),
            problem: error.to_string(),
        };
        let file = ElfFile32::<Endianness>::parse(&*bytes).map_err(|error| problem(&error))?;
        let endian = file.endian();
        let mut segments = Vec::new();
        let mut hints: Vec<(u32, Watched)> = Vec::new();
        // Each loadable segment goes where the flash holds it: its physical (load) address,
        // from which the start-up code copies `.data` to RAM.
        for header in file.elf_program_headers() {
            if header.p_type(endian) != PT_LOAD {
                continue;
            }
            let data = header
                .data(endian, &*bytes)
                .map_err(|()| problem(&"a segment lies outside the file"))?;
            if data.is_empty() {
                continue;
            }
            let load_address = header.p_paddr(endian);
            for (index, pair) in data.chunks_exact(2).enumerate() {
                let halfword = u16::from_le_bytes([pair[0], pair[1]]);
                let hint = match halfword {
                    WFI => Watched::Hint(Hint::WaitForInterrupt),
                    WFE => Watched::Hint(Hint::WaitForEvent),
                    SEV => Watched::Hint(Hint::SendEvent),
                    _ => match if_then(halfword) {
                        Some(watched) => watched,
                        None => continue,
                    },
                };
                hints.push((load_address + 2 * index as u32, hint));
            }
            segments.push((load_address, data.to_vec()));
        }
        let hints_from = hints.iter().map(|&(address, _)| address).min().unwrap_or(0);
        let hints_to = hints.iter().map(|&(address, _)| address).max().unwrap_or(0);
        let mut table = vec![None; ((hints_to - hints_from) / 2 + 1) as usize];
        for (address, hint) in hints {
            table[((address - hints_from) / 2) as usize] = Some(hint);
        }
        let mut functions = BTreeMap::new();
        let mut symbols = BTreeMap::new();
        for symbol in file.symbols() {
            let Ok(name) = symbol.name() else { continue };
            match symbol.kind() {
                SymbolKind::Text if symbol.address() != 0 => {
                    functions.insert(symbol.address() as u32 & !1, name.to_string());
                }
                SymbolKind::Data => {
                    symbols.insert(name.to_string(), symbol.address() as u32);
                }
                // The linker's bounds of the stack (flip-link's below the data).
                _ if name == STACK_BOTTOM || name == STACK_TOP => {
                    symbols.insert(name.to_string(), symbol.address() as u32);
                }
                _ => {}
            }
        }
        Ok(Image {
            segments,
            functions,
            symbols,
            hints: table,
            hints_from,
        })
    }

    /// The watched instruction at `address`, where the instruction there is 16 bits long.
    pub fn watched(&self, address: u32) -> Option<Watched> {
        let index = address.checked_sub(self.hints_from)? / 2;
        self.hints.get(index as usize).copied().flatten()
    }

    /// The function that holds `pc`, by its symbol.
    pub fn function(&self, pc: u32) -> &str {
        self.functions
            .range(..=pc & !1)
            .next_back()
            .map_or("?", |(_, name)| name.as_str())
    }

    /// The stack's bounds, bottom and top, where the image names them.
    pub fn stack(&self) -> Option<(u32, u32)> {
        let bottom = self.symbol(STACK_BOTTOM)?;
        let top = self.symbol(STACK_TOP)?;
        (bottom < top).then_some((bottom, top))
    }

    /// A data symbol's address.
    pub fn symbol(&self, name: &str) -> Option<u32> {
        self.symbols.get(name).copied()
    }

    /// The data symbols whose (mangled) names hold `part`, with their addresses.
    pub fn symbols_containing(&self, part: &str) -> Vec<(&str, u32)> {
        self.symbols
            .iter()
            .filter(|(name, _)| name.contains(part))
            .map(|(name, &address)| (name.as_str(), address))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// IT's mask: its trailing one ends the block, after 1 to 4 instructions (ARMv7-M ARM,
    /// A7.7.38); a mask of zero is a hint (NOP, YIELD, WFE, WFI, SEV), no IT.
    #[test]
    fn an_if_then_block_is_as_long_as_its_mask_says() {
        let length = |halfword| match if_then(halfword) {
            Some(Watched::IfThen { instructions }) => Some(instructions),
            _ => None,
        };
        assert_eq!(length(0xBF48), Some(1), "IT MI");
        assert_eq!(length(0xBF4C), Some(2), "ITE MI");
        assert_eq!(length(0xBF1A), Some(3), "ITTE NE");
        assert_eq!(length(0xBF01), Some(4), "ITTTT EQ");
        for hint in [0xBF00, 0xBF10, WFE, WFI, SEV] {
            assert_eq!(length(hint), None, "{hint:#06x}");
        }
        assert_eq!(length(0x4C48), None, "no IT at all");
    }
}
