//! Arbitrary records through decode and load: nothing panics, a record is used only when it is
//! intact and valid, and an intact record re-encodes to the same bytes.
#![no_main]

use feeder_shared::recipe::{self, RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{Friction, Limits, Machine, RecipeSlot, TickClock};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let Some((&number, rest)) = input.split_first() else {
        return;
    };
    let Ok(record) = <[u8; RECORD_LEN]>::try_from(rest) else {
        return;
    };
    let slot = RecipeSlot::new(number % RECIPE_SLOTS as u8).expect("slot below RECIPE_SLOTS");
    let machine = Machine {
        limits: Limits::NONE,
        friction: Friction::new(0.5, 9.81).expect("valid friction"),
        clock: TickClock::new(1_000_000),
        loop_linear_mps2: None,
    };
    let decoded = recipe::decode(&record, slot);
    if let Ok(settings) = decoded {
        assert_eq!(recipe::encode(slot, &settings), record);
    }
    let loaded = recipe::load(&record, slot, &machine);
    assert_eq!(
        loaded.is_ok(),
        decoded.is_ok_and(|s| s.validate(&machine).is_ok())
    );
});
