//! The recipe store in flash: the last 2 KiB page (bank 2 in the factory-default dual-bank mode),
//! which the top-level `memory.x` leaves out of the program, so that erasing and writing it never
//! stalls the code running from bank 1.

use defmt::warn;
use embassy_stm32::flash::{self, Flash};
use feeder_shared::recipe::{RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{RecipeSlot, RecipeStore};

/// Offset from the start of flash of the recipe page: the last 2 KiB page of the 512 KiB.
const RECIPE_PAGE_OFFSET: u32 = 512 * 1024 - RECIPE_PAGE_BYTES;
/// One flash page in dual-bank mode.
const RECIPE_PAGE_BYTES: u32 = 2 * 1024;
/// The records of all slots, one after the other from the start of the page.
const RECIPE_BYTES: usize = RECORD_LEN * RECIPE_SLOTS;

/// The recipe records in the reserved flash page. A write rewrites the whole page (about 20 ms
/// of erase time, spent in the console task).
pub struct FlashRecipes {
    flash: Flash<'static, flash::Blocking>,
}

impl FlashRecipes {
    pub fn new(flash: Flash<'static, flash::Blocking>) -> Self {
        Self { flash }
    }

    fn offset(slot: RecipeSlot) -> u32 {
        RECIPE_PAGE_OFFSET + (slot.index() * RECORD_LEN) as u32
    }
}

impl RecipeStore for FlashRecipes {
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
        let result = self
            .flash
            .blocking_erase(RECIPE_PAGE_OFFSET, RECIPE_PAGE_OFFSET + RECIPE_PAGE_BYTES)
            .and_then(|()| self.flash.blocking_write(RECIPE_PAGE_OFFSET, &page));
        if let Err(err) = result {
            warn!("recipe {} not written: {}", slot, err);
        }
        result
    }
}
