//! The events as text: the format strings of [`event_text!`](crate::event_text), each `{=type}`
//! parameter written as defmt's decoder prints it, so that [`Event`]'s `Display` is the line a
//! decoded log holds. The format string is walked char by char (see [`super`] on the generic
//! string code the firmware also uses).

use core::fmt::{self, Write};

use super::Event;

/// Writes a defmt format string with its parameters in place of its `{=…}` placeholders.
macro_rules! template {
    ($f:expr, $format:literal $(, $parameter:expr)*) => {
        write_template($f, $format, &[$(&$parameter as &dyn Parameter),*])
    };
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        encode!(self, template(f))
    }
}

fn write_template(
    f: &mut fmt::Formatter<'_>,
    format: &str,
    parameters: &[&dyn Parameter],
) -> fmt::Result {
    let mut parameters = parameters.iter();
    let mut in_placeholder = false;
    for c in format.chars() {
        match c {
            '{' => {
                in_placeholder = true;
                if let Some(parameter) = parameters.next() {
                    parameter.write(f)?;
                }
            }
            '}' if in_placeholder => in_placeholder = false,
            _ if in_placeholder => {}
            _ => f.write_char(c)?,
        }
    }
    Ok(())
}

/// A value in the text defmt's decoder gives its `{=type}`.
trait Parameter {
    fn write(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result;
}

macro_rules! integer_parameters {
    ($($integer:ty),*) => {$(
        impl Parameter for $integer {
            fn write(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{self}")
            }
        }
    )*};
}

integer_parameters!(u16, u32, u64, i8, i64);

impl Parameter for &str {
    fn write(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self)
    }
}

impl Parameter for f64 {
    fn write(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        super::float::write(f, *self)
    }
}
