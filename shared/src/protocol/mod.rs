//! The operator's command protocol: one ASCII command per line, exactly one reply line each.
//!
//! Bytes from the serial port go into a [`LineAssembler`], which yields one
//! `Result<`[`Command`]`, `[`ReplyError`]`>` per non-blank line. The controller executes the
//! command and answers with a [`Reply`] (`OK …` or `ERR <code> <explanation>`), which the
//! transport writes out followed by `\r\n`. A `set` is validated by [`crate::settings`] before
//! anything changes. The reference is `shared/PROTOCOL.md`.
//!
//! One job per submodule, each using only those before it: `limits` (line and reply sizes),
//! `refusal` (why a line is refused, with its code), `grammar` (what a line means), `framing`
//! (bytes into lines), `reply` (the reply lines).

mod framing;
mod grammar;
mod limits;
mod refusal;
mod reply;

pub use framing::LineAssembler;
pub use grammar::{parse, Command, ConfigCommand, Param};
pub use limits::{MAX_LINE_BYTES, REPLY_CAPACITY};
pub use refusal::ReplyError;
pub use reply::{Reply, Status};
