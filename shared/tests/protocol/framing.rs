//! The line assembler: terminators, blanks, erasing, overlong lines and bytes that are not text.

use feeder_shared::protocol::MAX_LINE_BYTES;
use feeder_shared::{Command, LineAssembler, ReplyError};

/// Feeds `input` and collects what each completed line asks for.
fn feed(input: &[u8]) -> Vec<Result<Command, ReplyError>> {
    let mut assembler = LineAssembler::new();
    input
        .iter()
        .filter_map(|&byte| assembler.push(byte))
        .collect()
}

#[test]
fn lines_end_at_cr_lf_or_crlf() {
    let got = feed(b"start\rstop\nstatus\r\nhelp\n\rreset\r\r\n\n");
    assert_eq!(
        got,
        [
            Ok(Command::Start),
            Ok(Command::Stop),
            Ok(Command::Status),
            Ok(Command::Help),
            Ok(Command::Reset)
        ]
    );
    // Nothing until the terminator arrives.
    assert!(feed(b"start").is_empty());
}

#[test]
fn blank_lines_get_no_reply() {
    assert!(feed(b"\r\n\n\r   \t \r\n").is_empty());
    // Backspacing a whole line leaves it blank.
    assert!(feed(b"sta\x08\x08\x08\r").is_empty());
}

#[test]
fn backspace_and_delete_erase_characters() {
    assert_eq!(feed(b"stoq\x08p\r"), [Ok(Command::Stop)]);
    assert_eq!(feed(b"startx\x7f\n"), [Ok(Command::Start)]);
    // A multi-byte character goes in one erase.
    assert_eq!(
        feed("set accel 150 m/s²\x08\x08\x08\x082\n".as_bytes()),
        feed(b"set accel 150 2\n")
    );
    assert_eq!(feed("stop²\x08\n".as_bytes()), [Ok(Command::Stop)]);
    assert_eq!(feed(b"\x08\x08stop\n"), [Ok(Command::Stop)]);
}

#[test]
fn overlong_lines_give_one_error_when_they_end() {
    let long = "x".repeat(MAX_LINE_BYTES + 1);
    let input = format!("{long}{long}{long}\r\nstart\n");
    assert_eq!(
        feed(input.as_bytes()),
        [Err(ReplyError::LineTooLong), Ok(Command::Start)]
    );
    // Erasing cannot rescue a line that already overflowed.
    let input = format!("{long}\x08\x08\n");
    assert_eq!(feed(input.as_bytes()), [Err(ReplyError::LineTooLong)]);
}

#[test]
fn line_length_limit_is_exact_and_ignores_leading_blanks() {
    let padded = |length: usize| format!("status{}", " ".repeat(length - "status".len()));
    assert_eq!(
        feed(format!("{}\n", padded(MAX_LINE_BYTES)).as_bytes()),
        [Ok(Command::Status)]
    );
    assert_eq!(
        feed(format!("{}\n", padded(MAX_LINE_BYTES + 1)).as_bytes()),
        [Err(ReplyError::LineTooLong)]
    );
    let indented = format!("{}status\n", " ".repeat(3 * MAX_LINE_BYTES));
    assert_eq!(feed(indented.as_bytes()), [Ok(Command::Status)]);
}

#[test]
fn garbage_is_refused_as_not_text() {
    for input in [
        &b"st\xffart\n"[..],
        b"\x00\n",
        b"\x1b[A\n",
        b"start\x07\n",
        b"\xc3\n",
        b"\xe2\x82\n",
    ] {
        assert_eq!(feed(input), [Err(ReplyError::NotText)], "{input:?}");
    }
    // UTF-8 text that is no command is an unknown command, not garbage.
    assert_eq!(
        feed("démarrer\n".as_bytes()),
        [Err(ReplyError::UnknownCommand)]
    );
}

#[test]
fn clear_drops_a_partial_line() {
    let mut assembler = LineAssembler::new();
    for &byte in b"garbage" {
        assert_eq!(assembler.push(byte), None);
    }
    assembler.clear();
    let got: Vec<_> = b"stop\n"
        .iter()
        .filter_map(|&b| assembler.push(b))
        .collect();
    assert_eq!(got, [Ok(Command::Stop)]);
}
