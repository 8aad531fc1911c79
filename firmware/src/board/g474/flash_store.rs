//! The board's settings in flash: the last two 2 KiB pages (bank 2 in the factory-default
//! dual-bank mode), which the top-level `memory.x` leaves out of the program, so that erasing and
//! writing them never stalls the code running from bank 1. The configuration's record lives at
//! the start of the first page, the recipe records one after the other from the start of the
//! second; a write rewrites its whole page (about 20 ms of erase time, spent in the console
//! task), never the other.

use defmt::warn;
use embassy_stm32::flash::{self, Flash};
use feeder_shared::configuration::record as config_record;
use feeder_shared::recipe::{RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{ConfigurationStore, RecipeSlot, RecipeStore};

/// One flash page in dual-bank mode.
const PAGE_BYTES: u32 = 2 * 1024;
/// Offset from the start of flash of the configuration's page: the last but one of the 512 KiB.
const CONFIGURATION_PAGE_OFFSET: u32 = 512 * 1024 - 2 * PAGE_BYTES;
/// Offset from the start of flash of the recipe page: the last 2 KiB page.
const RECIPE_PAGE_OFFSET: u32 = 512 * 1024 - PAGE_BYTES;
/// The records of all slots, one after the other from the start of the page.
const RECIPE_BYTES: usize = RECORD_LEN * RECIPE_SLOTS;

/// The configuration and the recipe records in the reserved flash pages.
pub struct FlashStore {
    flash: Flash<'static, flash::Blocking>,
}

impl FlashStore {
    pub fn new(flash: Flash<'static, flash::Blocking>) -> Self {
        Self { flash }
    }

    fn offset(slot: RecipeSlot) -> u32 {
        RECIPE_PAGE_OFFSET + (slot.index() * RECORD_LEN) as u32
    }

    /// Erases the page at `page_offset` and writes `bytes` from its start.
    fn rewrite(&mut self, page_offset: u32, bytes: &[u8]) -> Result<(), flash::Error> {
        self.flash
            .blocking_erase(page_offset, page_offset + PAGE_BYTES)
            .and_then(|()| self.flash.blocking_write(page_offset, bytes))
    }
}

impl RecipeStore for FlashStore {
    type Error = flash::Error;

    fn read(&mut self, slot: RecipeSlot) -> [u8; RECORD_LEN] {
        let mut record = [0xff; RECORD_LEN];
        if let Err(err) = self.flash.blocking_read(Self::offset(slot), &mut record) {
            warn!("recipe {} unreadable: {}", slot, err);
            record = [0xff; RECORD_LEN];
        }
        record
    }

    fn write(&mut self, slot: RecipeSlot, record: &[u8; RECORD_LEN]) -> Result<(), flash::Error> {
        let mut page = [0xff; RECIPE_BYTES];
        self.flash.blocking_read(RECIPE_PAGE_OFFSET, &mut page)?;
        let start = slot.index() * RECORD_LEN;
        if let Some(stored) = page.get_mut(start..start + RECORD_LEN) {
            stored.copy_from_slice(record);
        }
        let result = self.rewrite(RECIPE_PAGE_OFFSET, &page);
        if let Err(err) = result {
            warn!("recipe {} not written: {}", slot, err);
        }
        result
    }
}

impl ConfigurationStore for FlashStore {
    type WriteError = flash::Error;

    fn read_configuration(&mut self) -> [u8; config_record::RECORD_LEN] {
        let mut record = [0xff; config_record::RECORD_LEN];
        if let Err(err) = self
            .flash
            .blocking_read(CONFIGURATION_PAGE_OFFSET, &mut record)
        {
            warn!("configuration unreadable: {}", err);
            record = [0xff; config_record::RECORD_LEN];
        }
        record
    }

    fn write_configuration(
        &mut self,
        record: &[u8; config_record::RECORD_LEN],
    ) -> Result<(), flash::Error> {
        let result = self.rewrite(CONFIGURATION_PAGE_OFFSET, record);
        if let Err(err) = result {
            warn!("configuration not written: {}", err);
        }
        result
    }
}
