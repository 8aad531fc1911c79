//! The events inside other defmt frames (feature `defmt`): `defmt::info!("{}", event)` writes the
//! text of [`event_text!`](crate::event_text) with defmt's typed parameters, nested in that frame.

use super::Event;

impl defmt::Format for Event {
    fn format(&self, f: defmt::Formatter<'_>) {
        encode!(self, defmt::write(f))
    }
}
