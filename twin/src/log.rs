//! The firmware's defmt log as text: the frames read from RTT decoded against the image's
//! table (the decoder `defmt-print` is built on), one line a frame, `timestamp LEVEL message`
//! as `defmt-print` writes them.

use defmt_decoder::{DecodeError, StreamDecoder, Table};

use crate::TwinError;

/// The image's defmt table.
pub struct LogTable(Table);

impl LogTable {
    pub fn load(elf: &[u8]) -> Result<Self, TwinError> {
        let table = Table::parse(elf)
            .map_err(|error| TwinError::Image {
                path: "the image".into(),
                problem: format!("its defmt table: {error}"),
            })?
            .ok_or_else(|| TwinError::Image {
                path: "the image".into(),
                problem: "it has no defmt table".into(),
            })?;
        Ok(LogTable(table))
    }

    pub fn decoder(&self) -> LogDecoder<'_> {
        LogDecoder(self.0.new_stream_decoder())
    }
}

/// A stream of frames being decoded.
pub struct LogDecoder<'t>(Box<dyn StreamDecoder + Send + Sync + 't>);

impl LogDecoder<'_> {
    /// Takes `bytes` from RTT; returns the lines of the frames they complete. A malformed frame
    /// is a line that says so.
    pub fn lines(&mut self, bytes: &[u8]) -> Vec<String> {
        self.0.received(bytes);
        let mut lines = Vec::new();
        loop {
            match self.0.decode() {
                Ok(frame) => {
                    let timestamp = frame
                        .display_timestamp()
                        .map_or(String::new(), |t| format!("{t} "));
                    let level = frame.level().map_or(String::new(), |l| {
                        format!("{:<5} ", l.as_str().to_uppercase())
                    });
                    lines.push(format!("{timestamp}{level}{}", frame.display_message()));
                }
                Err(DecodeError::UnexpectedEof) => return lines,
                Err(DecodeError::Malformed) => lines.push("(a malformed defmt frame)".into()),
            }
        }
    }
}
