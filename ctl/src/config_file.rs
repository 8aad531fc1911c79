//! `feeder-ctl export` and `import`: the board's configuration as a text file, one `key=value`
//! per line in the units `config list` shows, `#` comments and blank lines ignored.
//!
//! Export writes what `config list` answers: the board's configuration with any change not yet
//! saved. Import sends every line as `config set` and, with `--save`, `config save`; the board
//! checks every value (and, at the save, the whole). A refusal stops the import, says which line
//! the board refused and why, and sets every key back to what it was before the import, so that
//! a refused import changes nothing.

use std::fmt;
use std::io;
use std::path::Path;

use crate::console::Console;

/// Why an export or an import did not complete.
#[derive(Debug)]
pub enum TransferError {
    /// The link failed.
    Link(io::Error),
    /// The file could not be read or written.
    File(io::Error),
    /// A line of the file is not `key=value`.
    Syntax { line: usize, text: String },
    /// The board refused a command; the keys are back where they were (`restored`), or not.
    Refused {
        what: String,
        reply: String,
        restored: bool,
    },
}

impl fmt::Display for TransferError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TransferError::Link(error) => write!(f, "{error}"),
            TransferError::File(error) => write!(f, "{error}"),
            TransferError::Syntax { line, text } => {
                write!(f, "line {line} is not key=value: {text:?}")
            }
            TransferError::Refused {
                what,
                reply,
                restored,
            } => {
                write!(f, "the board refused {what}: {reply}")?;
                if *restored {
                    f.write_str("; every key is back as it was")
                } else {
                    f.write_str("; the keys could not all be set back, check `config list`")
                }
            }
        }
    }
}

/// The `key=value` pairs of a `config list` reply, in its order.
pub fn pairs_of_list(reply: &str) -> Option<Vec<(String, String)>> {
    let rest = reply.strip_prefix("OK config")?;
    rest.split_whitespace()
        .map(|pair| {
            let (key, value) = pair.split_once('=')?;
            Some((key.to_string(), value.to_string()))
        })
        .collect()
}

/// The file's text for the pairs of a `config list` reply, read from `source`.
pub fn file_text(pairs: &[(String, String)], source: &str) -> String {
    let mut text = format!(
        "# feeder configuration from {source}\n\
         # key=value in the units `config list` shows; `feeder-ctl import` sends each line as\n\
         # `config set` (`--save` also saves it on the board)\n"
    );
    for (key, value) in pairs {
        text.push_str(&format!("{key}={value}\n"));
    }
    text
}

/// The `key=value` pairs of a configuration file's text.
pub fn pairs_of_file(text: &str) -> Result<Vec<(String, String)>, TransferError> {
    let mut pairs = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let syntax = || TransferError::Syntax {
            line: index + 1,
            text: line.to_string(),
        };
        let (key, value) = line.split_once('=').ok_or_else(syntax)?;
        let (key, value) = (key.trim(), value.trim());
        if key.is_empty() || value.is_empty() || key.contains(char::is_whitespace) {
            return Err(syntax());
        }
        pairs.push((key.to_string(), value.to_string()));
    }
    Ok(pairs)
}

/// The board's configuration as `config list` answers it.
fn current(console: &mut Console) -> Result<Vec<(String, String)>, TransferError> {
    let reply = console
        .command("config list")
        .map_err(TransferError::Link)?;
    pairs_of_list(&reply).ok_or(TransferError::Refused {
        what: "config list".into(),
        reply,
        restored: true,
    })
}

/// Writes the board's configuration to `file`; the number of keys written.
pub fn export(console: &mut Console, file: &Path, source: &str) -> Result<usize, TransferError> {
    let pairs = current(console)?;
    std::fs::write(file, file_text(&pairs, source)).map_err(TransferError::File)?;
    Ok(pairs.len())
}

/// Sends every pair of `file` as `config set`, then `config save` if `save`; the last reply.
pub fn import(console: &mut Console, file: &Path, save: bool) -> Result<String, TransferError> {
    let text = std::fs::read_to_string(file).map_err(TransferError::File)?;
    let pairs = pairs_of_file(&text)?;
    let before = current(console)?;
    let mut commands: Vec<String> = pairs
        .iter()
        .map(|(key, value)| format!("config set {key} {value}"))
        .collect();
    if save {
        commands.push("config save".into());
    }
    let mut last = String::new();
    for command in commands {
        let reply = console.command(&command).map_err(TransferError::Link)?;
        if !reply.starts_with("OK") {
            let restored = restore(console, &before);
            return Err(TransferError::Refused {
                what: command,
                reply,
                restored,
            });
        }
        last = reply;
    }
    Ok(last)
}

/// Sets every key back to `before`; true if the board took every one.
fn restore(console: &mut Console, before: &[(String, String)]) -> bool {
    before.iter().all(|(key, value)| {
        console
            .command(&format!("config set {key} {value}"))
            .is_ok_and(|reply| reply.starts_with("OK"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_list_reply_round_trips_through_the_file() {
        let reply = "OK config dac_zero=2048 encoder_dir=forward start_duty=0.586";
        let pairs = pairs_of_list(reply).unwrap();
        assert_eq!(pairs.len(), 3);
        let text = file_text(&pairs, "TCP 127.0.0.1:4444");
        assert!(text.starts_with("# feeder configuration from TCP 127.0.0.1:4444\n"));
        assert!(text.ends_with("dac_zero=2048\nencoder_dir=forward\nstart_duty=0.586\n"));
        assert_eq!(pairs_of_file(&text).unwrap(), pairs);
    }

    #[test]
    fn blanks_around_the_equals_sign_and_comments_are_fine() {
        let pairs = pairs_of_file("  # a note\n\n dac_zero = 2050 \n").unwrap();
        assert_eq!(pairs, [("dac_zero".to_string(), "2050".to_string())]);
    }

    #[test]
    fn a_line_that_is_not_key_value_is_refused_with_its_number() {
        for text in ["dac_zero 2050", "=2050", "dac_zero=", "dac zero=1"] {
            let error = pairs_of_file(&format!("# ok\n{text}\n")).unwrap_err();
            assert!(
                matches!(error, TransferError::Syntax { line: 2, .. }),
                "{text}: {error}"
            );
        }
    }

    #[test]
    fn an_error_reply_is_no_list() {
        assert_eq!(
            pairs_of_list("ERR 66 this board keeps no configuration"),
            None
        );
    }
}
