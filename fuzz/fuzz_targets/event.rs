//! Arbitrary log lines through the event parser: nothing panics, and an event read from a line
//! writes back to text that reads as the same event (compared as text, so that a NaN field
//! counts as equal to itself).
#![no_main]

use feeder_shared::event::parse_line;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|line: &str| {
    let Ok(Some(event)) = parse_line(line) else {
        return;
    };
    let written = event.to_string();
    let reread = parse_line(&written)
        .expect("written text parses")
        .expect("written text carries the marker");
    assert_eq!(reread.to_string(), written);
});
