//! Arbitrary configuration records through decode and load: nothing panics, a record is used
//! only when it is intact and valid as a whole, and an intact record re-encodes to the same
//! bytes.
#![no_main]

use feeder_shared::configuration::record::{self, RECORD_LEN};
use feeder_shared::configuration::{BoardFacts, OutputKind};
use feeder_shared::TickClock;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let Some((&facts, rest)) = input.split_first() else {
        return;
    };
    let Ok(bytes) = <[u8; RECORD_LEN]>::try_from(rest) else {
        return;
    };
    let board = BoardFacts {
        clock: TickClock::new(1_000_000),
        output: if facts & 1 == 0 {
            OutputKind::Dac
        } else {
            OutputKind::Pwm
        },
        encoder: facts & 2 != 0,
    };
    let decoded = record::decode(&bytes);
    if let Ok(configuration) = decoded {
        assert_eq!(record::encode(&configuration), bytes);
    }
    let loaded = record::load(&bytes, &board);
    assert_eq!(
        loaded.is_ok(),
        decoded.is_ok_and(|configuration| configuration.check(&board).is_ok())
    );
});
