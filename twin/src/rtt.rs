//! The firmware's RTT up channel (defmt-rtt's `_SEGGER_RTT` control block), read as a debug
//! probe reads it: the bytes between the read and the write offset, then the read offset
//! moved on.

/// Offsets in the control block: the 16-byte id, the channel counts, then up channel 0's name,
/// buffer, size, write and read offsets and flags, 4 bytes each.
const UP_BUFFER: u32 = 28;
const UP_SIZE: u32 = 32;
const UP_WRITE: u32 = 36;
const UP_READ: u32 = 40;

/// Memory as the probe sees it.
pub trait Memory {
    fn read_word(&self, address: u32) -> Option<u32>;
    fn read_bytes(&self, address: u32, bytes: &mut [u8]) -> Option<()>;
    fn write_word(&mut self, address: u32, value: u32) -> Option<()>;
}

/// Takes the bytes waiting in the up channel of the control block at `block`.
pub fn drain(memory: &mut impl Memory, block: u32) -> Vec<u8> {
    let read_all = || -> Option<(u32, u32, u32, u32)> {
        Some((
            memory.read_word(block + UP_BUFFER)?,
            memory.read_word(block + UP_SIZE)?,
            memory.read_word(block + UP_WRITE)?,
            memory.read_word(block + UP_READ)?,
        ))
    };
    let Some((buffer, size, write, read)) = read_all() else {
        return Vec::new();
    };
    if size == 0 || write >= size || read >= size || write == read {
        return Vec::new();
    }
    let mut bytes = Vec::new();
    let mut take = |from: u32, to: u32| {
        let mut chunk = vec![0; (to - from) as usize];
        if memory.read_bytes(buffer + from, &mut chunk).is_some() {
            bytes.extend_from_slice(&chunk);
        }
    };
    if write > read {
        take(read, write);
    } else {
        take(read, size);
        take(0, write);
    }
    let _ = memory.write_word(block + UP_READ, write);
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Ram(Vec<u8>);

    impl Memory for Ram {
        fn read_word(&self, address: u32) -> Option<u32> {
            let at = address as usize;
            Some(u32::from_le_bytes(self.0.get(at..at + 4)?.try_into().ok()?))
        }
        fn read_bytes(&self, address: u32, bytes: &mut [u8]) -> Option<()> {
            let at = address as usize;
            bytes.copy_from_slice(self.0.get(at..at + bytes.len())?);
            Some(())
        }
        fn write_word(&mut self, address: u32, value: u32) -> Option<()> {
            let at = address as usize;
            self.0
                .get_mut(at..at + 4)?
                .copy_from_slice(&value.to_le_bytes());
            Some(())
        }
    }

    #[test]
    fn a_wrapped_buffer_is_read_in_order_and_marked_read() {
        let mut ram = Ram(vec![0; 256]);
        for (offset, value) in [(UP_BUFFER, 100), (UP_SIZE, 8), (UP_WRITE, 2), (UP_READ, 6)] {
            ram.write_word(offset, value);
        }
        ram.0[100..108].copy_from_slice(b"cdxxxxab");
        assert_eq!(drain(&mut ram, 0), b"abcd");
        assert_eq!(ram.read_word(UP_READ), Some(2));
        assert!(drain(&mut ram, 0).is_empty());
    }
}
