//! The emulated board's flash: `feeder-flash.bin` in QEMU's working directory, read and written
//! with semihosting file calls, so that what the console saves is there after the emulation
//! restarts, as a board's flash is after a reset. Two 2 KiB pages as on the G474: the
//! configuration's record at the start of the first, the recipe records from the start of the
//! second. A new file is filled with `0xFF`, erased flash.

use cortex_m_semihosting::nr::open::{RW_BINARY, RW_TRUNC_BINARY};
use cortex_m_semihosting::syscall;
use defmt::warn;
use feeder_shared::configuration::record as config_record;
use feeder_shared::recipe::{RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{ConfigurationStore, RecipeSlot, RecipeStore};

/// The file's name, with the terminating NUL that `SYS_OPEN` wants.
const FILE_NAME: &str = "feeder-flash.bin\0";
/// One page.
const PAGE_BYTES: usize = 2048;
/// The configuration's page.
const CONFIGURATION_AT: usize = 0;
/// The recipes' page.
const RECIPES_AT: usize = PAGE_BYTES;
/// The whole file.
const FILE_BYTES: usize = 2 * PAGE_BYTES;

const _: () = assert!(config_record::RECORD_LEN <= PAGE_BYTES);
const _: () = assert!(RECORD_LEN * RECIPE_SLOTS <= PAGE_BYTES);

/// A semihosting file call failed.
#[derive(Debug, defmt::Format)]
pub struct FileError;

/// The flash file, open for reading and writing; `None` if it could not be opened (then
/// everything reads erased and no write succeeds).
pub struct FileStore {
    handle: Option<usize>,
}

impl FileStore {
    /// Opens the file, making an erased one where there is none or it is short.
    pub fn open() -> Self {
        let handle = open(RW_BINARY).or_else(|| open(RW_TRUNC_BINARY));
        let mut store = FileStore { handle };
        let Some(handle) = handle else {
            warn!(
                "flash file {=str} cannot be opened: nothing is kept",
                FILE_NAME
            );
            return store;
        };
        // SAFETY: SYS_FLEN takes the open handle.
        let length = unsafe { syscall!(FLEN, handle) } as isize;
        if length >= 0 && (length as usize) < FILE_BYTES {
            let erased = [0xff; 64];
            let mut at = length as usize;
            while at < FILE_BYTES {
                let chunk = (FILE_BYTES - at).min(erased.len());
                if store.write_at(at, &erased[..chunk]).is_err() {
                    warn!("flash file {=str} cannot be extended", FILE_NAME);
                    store.handle = None;
                    break;
                }
                at += chunk;
            }
        }
        store
    }

    /// Fills `buffer` from offset `at`; what cannot be read stays as it was (erased).
    fn read_at(&mut self, at: usize, buffer: &mut [u8]) {
        let Some(handle) = self.handle else {
            return;
        };
        // SAFETY: SYS_SEEK takes the open handle and an offset inside the file.
        if unsafe { syscall!(SEEK, handle, at) } != 0 {
            return;
        }
        // SAFETY: SYS_READ writes at most `buffer.len()` bytes into `buffer`.
        unsafe { syscall!(READ, handle, buffer.as_mut_ptr(), buffer.len()) };
    }

    /// Writes `bytes` at offset `at`.
    fn write_at(&mut self, at: usize, bytes: &[u8]) -> Result<(), FileError> {
        let handle = self.handle.ok_or(FileError)?;
        // SAFETY: SYS_SEEK takes the open handle and an offset inside the file (or its end).
        if unsafe { syscall!(SEEK, handle, at) } != 0 {
            return Err(FileError);
        }
        // SAFETY: SYS_WRITE reads `bytes.len()` bytes from `bytes`.
        match unsafe { syscall!(WRITE, handle, bytes.as_ptr(), bytes.len()) } {
            0 => Ok(()),
            _ => Err(FileError),
        }
    }
}

/// Opens the file with the semihosting open mode `mode`.
fn open(mode: usize) -> Option<usize> {
    // SAFETY: SYS_OPEN reads the name's `len - 1` bytes (without the NUL), which is 'static.
    let handle = unsafe { syscall!(OPEN, FILE_NAME.as_ptr(), mode, FILE_NAME.len() - 1) };
    (handle as isize != -1).then_some(handle)
}

impl RecipeStore for FileStore {
    type Error = FileError;

    fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN] {
        let mut record = [0xff; RECORD_LEN];
        self.read_at(RECIPES_AT + slot.index() * RECORD_LEN, &mut record);
        record
    }

    fn write(&mut self, slot: RecipeSlot, record: &[u8; RECORD_LEN]) -> Result<(), FileError> {
        self.write_at(RECIPES_AT + slot.index() * RECORD_LEN, record)
    }
}

impl ConfigurationStore for FileStore {
    type WriteError = FileError;

    fn read_configuration(&mut self) -> [u8; config_record::RECORD_LEN] {
        let mut record = [0xff; config_record::RECORD_LEN];
        self.read_at(CONFIGURATION_AT, &mut record);
        record
    }

    fn write_configuration(
        &mut self,
        record: &[u8; config_record::RECORD_LEN],
    ) -> Result<(), FileError> {
        self.write_at(CONFIGURATION_AT, record)
    }
}
