//! The command protocol: every command and every error by table, the line assembler's framing,
//! reply formatting, a whole session over arbitrary input bytes, and the reference document.

#[path = "../common/mod.rs"]
mod common;

mod framing;
mod grammar;
mod reference;
mod refusal;
mod reply;
mod session;
