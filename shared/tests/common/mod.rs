//! Helpers shared by the protocol, control and recipe tests.

use feeder_shared::RecipeSlot;

pub fn slot(number: u8) -> RecipeSlot {
    RecipeSlot::new(number).unwrap()
}
