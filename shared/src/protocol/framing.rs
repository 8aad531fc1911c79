//! Bytes into command lines: terminators, blanks, erasing, and lines too long or not text.

use core::str;

use heapless::Vec;

use super::grammar::{parse, Command};
use super::limits::MAX_LINE_BYTES;
use super::refusal::ReplyError;

const BACKSPACE: u8 = 0x08;
const DELETE: u8 = 0x7f;

/// Assembles bytes into command lines.
///
/// A line ends at CR, LF or CRLF. Leading blanks are skipped and blank lines are ignored;
/// backspace and DEL erase the last character. A line longer than [`MAX_LINE_BYTES`] is
/// discarded and answered with one [`ReplyError::LineTooLong`] when it ends; a line that is not
/// UTF-8 or holds control characters with [`ReplyError::NotText`].
#[derive(Debug, Clone, Default)]
pub struct LineAssembler {
    line: Vec<u8, MAX_LINE_BYTES>,
    overlong: bool,
    after_cr: bool,
}

impl LineAssembler {
    pub const fn new() -> Self {
        LineAssembler {
            line: Vec::new(),
            overlong: false,
            after_cr: false,
        }
    }

    /// Takes one received byte; at the end of a non-blank line returns what it asks for.
    pub fn push(&mut self, byte: u8) -> Option<Result<Command, ReplyError>> {
        let after_cr = core::mem::replace(&mut self.after_cr, byte == b'\r');
        match byte {
            b'\n' if after_cr => None,
            b'\r' | b'\n' => self.finish(),
            BACKSPACE | DELETE => {
                self.erase();
                None
            }
            b' ' | b'\t' if self.line.is_empty() => None,
            _ => {
                if self.line.push(byte).is_err() {
                    self.overlong = true;
                }
                None
            }
        }
    }

    /// Drops a partial line, for example after a transport error.
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    fn finish(&mut self) -> Option<Result<Command, ReplyError>> {
        let overlong = core::mem::take(&mut self.overlong);
        let result = if overlong {
            Some(Err(ReplyError::LineTooLong))
        } else if self.line.is_empty() {
            None
        } else {
            Some(match str::from_utf8(&self.line) {
                Ok(text) if !text.chars().any(|c| c.is_control() && c != '\t') => parse(text),
                _ => Err(ReplyError::NotText),
            })
        };
        self.line.clear();
        result
    }

    /// Removes the last character (all bytes of a UTF-8 sequence) unless the line overflowed.
    fn erase(&mut self) {
        if self.overlong {
            return;
        }
        while let Some(byte) = self.line.pop() {
            if byte & 0xc0 != 0x80 {
                break;
            }
        }
    }
}
