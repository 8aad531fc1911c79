//! A whole session through a minimal controller: every line gets exactly one well-formed reply.

use feeder_shared::protocol::{MAX_LINE_BYTES, REPLY_CAPACITY};
use feeder_shared::recipe::{self, RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::testing::machine;
use feeder_shared::{
    Applied, Command, LineAssembler, Machine, Phase, RecipeSlot, Reply, ReplyError, Settings,
    Status,
};
use proptest::prelude::*;

/// A minimal controller over the shared API, standing in for the firmware's.
struct Controller {
    machine: Machine,
    settings: Settings,
    applied: Applied,
    running: bool,
    fault: Option<&'static str>,
    flash: [[u8; RECORD_LEN]; RECIPE_SLOTS],
}

impl Controller {
    fn new() -> Self {
        let machine = machine();
        Controller {
            machine,
            settings: Settings::DEFAULT,
            applied: Settings::DEFAULT.validate(&machine).unwrap(),
            running: false,
            fault: None,
            flash: [[0xff; RECORD_LEN]; RECIPE_SLOTS],
        }
    }

    fn execute(&mut self, request: Result<Command, ReplyError>) -> Reply {
        let command = match request {
            Ok(command) => command,
            Err(error) => return Reply::error(&error),
        };
        match command {
            Command::Start if self.fault.is_some() => Reply::error(&ReplyError::FaultLatched),
            Command::Start => {
                self.running = true;
                Reply::ok(format_args!("starting"))
            }
            Command::Stop => {
                self.running = false;
                Reply::ok(format_args!("stopping"))
            }
            Command::Status => Reply::status(&self.status()),
            Command::Get(param) => Reply::get(param, &self.status()),
            Command::Set(setting) => match self.settings.apply(setting, &self.machine) {
                Ok(applied) => {
                    self.settings = applied.settings;
                    self.applied = applied;
                    Reply::applied(&applied)
                }
                Err(error) => Reply::error(&error.into()),
            },
            Command::RecipeSave(_) if self.running => Reply::error(&ReplyError::NotStopped),
            Command::RecipeSave(slot) => {
                self.flash[slot.index()] = recipe::encode(slot, &self.settings);
                Reply::recipe_saved(slot)
            }
            Command::RecipeLoad(slot) => {
                match recipe::load(&self.flash[slot.index()], slot, &self.machine) {
                    Ok(applied) => {
                        self.settings = applied.settings;
                        self.applied = applied;
                        Reply::recipe_loaded(slot, &applied)
                    }
                    Err(issue) => Reply::error(&ReplyError::RecipeUnusable { slot, issue }),
                }
            }
            Command::Config(_) | Command::Restart => Reply::error(&ReplyError::NoConfiguration),
            Command::Telemetry(on) => {
                Reply::ok(format_args!("telemetry {}", if on { "on" } else { "off" }))
            }
            Command::RecipeList => {
                let entries: [_; RECIPE_SLOTS] = std::array::from_fn(|index| {
                    recipe::decode(&self.flash[index], RecipeSlot::new(index as u8).unwrap())
                });
                Reply::recipe_list(&entries)
            }
            Command::Reset => {
                self.fault = None;
                Reply::ok(format_args!("fault cleared"))
            }
            Command::Help => Reply::help(),
        }
    }

    fn status(&self) -> Status<&'static str> {
        Status {
            phase: if self.running {
                Phase::Running
            } else {
                Phase::Stopped
            },
            fault: self.fault,
            waveform: self.applied.plan.waveform,
            ramp_cycles: self.settings.ramp_cycles,
            feed_rate_mps: self.applied.feed_rate_mps,
            uptime_ms: 0,
            cycles: 0,
            closed_loop: None,
            track: None,
        }
    }

    fn session(&mut self, input: &[u8]) -> Vec<Reply> {
        let mut assembler = LineAssembler::new();
        input
            .iter()
            .filter_map(|&byte| assembler.push(byte))
            .map(|r| self.execute(r))
            .collect()
    }
}

#[test]
fn a_session_answers_every_line_once() {
    let mut controller = Controller::new();
    let script = "set freq 60\r\nset duty 0.3\r\nstart\r\nrecipe save 1\r\nstop\r\n\
                  recipe save 1\r\n\x00\x01\x02\r\nset feed 30\r\nrecipe load 1\r\nget freq\r\n\
                  get duty\r\nrecipe load 2\r\n";
    let replies: Vec<String> = controller
        .session(script.as_bytes())
        .iter()
        .map(|r| r.to_string())
        .collect();
    let heads: Vec<&str> = replies
        .iter()
        .map(|r| r.split(' ').take(2).last().unwrap())
        .collect();
    assert_eq!(replies.len(), 12, "{replies:#?}");
    assert!(replies[0].starts_with("OK freq_hz=60 "));
    assert!(replies[1].starts_with("ERR 42 duty cycle 0.3 must be above 0.5"));
    assert_eq!(replies[2], "OK starting");
    assert!(replies[3].starts_with("ERR 60 "));
    assert_eq!(replies[5], "OK recipe 1 saved");
    assert!(replies[6].starts_with("ERR 11 "));
    assert!(replies[7].starts_with("OK freq_hz=60 duty=0.5"));
    assert!(
        replies[8].starts_with("OK recipe 1 loaded freq_hz=60 duty=0.586 "),
        "{}",
        replies[8]
    );
    assert_eq!(replies[9], "OK freq_hz=60");
    assert_eq!(replies[10], "OK duty=0.586");
    assert!(replies[11].starts_with("ERR 63 recipe 2 not loaded: no recipe saved in this slot"));
    assert_eq!(heads[4], "stopping");
}

/// Independent check of a reply line's shape.
fn well_formed(reply: &str) -> bool {
    let printable = reply.bytes().all(|b| (b' '..=b'~').contains(&b));
    let shape = reply == "OK"
        || reply.starts_with("OK ")
        || reply.strip_prefix("ERR ").is_some_and(|rest| {
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            !digits.is_empty() && rest[digits.len()..].starts_with(' ')
        });
    printable && shape && reply.len() <= REPLY_CAPACITY
}

/// Command words, numbers and units to build plausible lines from.
fn word() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "start", "STOP", "status", "get", "set", "recipe", "save", "load", "list", "reset",
            "help", "freq", "duty", "stroke", "accel", "feed", "ramp", "hz", "mm", "m/s2", "mm/s",
            "cycles", "inf", "nan", "-", "1e999", "0", "7", "8",
        ])
        .prop_map(str::to_string),
        any::<f64>().prop_map(|x| x.to_string()),
        (0.0f64..300.0).prop_map(|x| format!("{x:.3}")),
        "[ -~]{0,12}",
    ]
}

fn line_text() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        3 => prop::collection::vec(word(), 0..6).prop_map(|words| words.join(" ").into_bytes()),
        1 => prop::collection::vec(
            any::<u8>().prop_filter("no terminator", |b| !matches!(b, b'\r' | b'\n' | 0x08 | 0x7f)),
            0..90,
        ),
    ]
}

fn terminator() -> impl Strategy<Value = &'static [u8]> {
    prop::sample::select(vec![&b"\r"[..], b"\n", b"\r\n"])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Any bytes: no panic, never more replies than terminators, every reply well formed.
    #[test]
    fn arbitrary_bytes_never_break_the_session(
        input in prop::collection::vec(any::<u8>(), 0..600),
    ) {
        let mut controller = Controller::new();
        let replies = controller.session(&input);
        let terminators = input.iter().filter(|&&b| b == b'\r' || b == b'\n').count();
        prop_assert!(replies.len() <= terminators);
        for reply in &replies {
            prop_assert!(well_formed(reply.as_str()), "{:?}", reply.as_str());
        }
    }

    /// Every complete non-blank line gets exactly one reply, in order, of the expected kind.
    #[test]
    fn every_line_gets_exactly_one_reply(
        lines in prop::collection::vec((line_text(), terminator()), 0..12),
        tail in line_text(),
    ) {
        let mut input = Vec::new();
        let mut expected = Vec::new();
        for (text, end) in &lines {
            input.extend_from_slice(text);
            input.extend_from_slice(end);
            let blanks = text.iter().take_while(|b| matches!(b, b' ' | b'\t')).count();
            let content = &text[blanks..];
            if content.is_empty() {
                continue;
            }
            expected.push(if content.len() > MAX_LINE_BYTES {
                Some(10)
            } else {
                match std::str::from_utf8(content) {
                    Ok(s) if !s.chars().any(|c| c.is_control() && c != '\t') => None,
                    _ => Some(11),
                }
            });
        }
        // An unterminated tail gets no reply.
        input.extend_from_slice(&tail);
        let mut controller = Controller::new();
        let replies = controller.session(&input);
        prop_assert_eq!(replies.len(), expected.len());
        for (reply, expected_code) in replies.iter().zip(expected) {
            prop_assert!(well_formed(reply.as_str()), "{:?}", reply.as_str());
            if let Some(code) = expected_code {
                let head = format!("ERR {code} ");
                prop_assert!(reply.as_str().starts_with(&head), "{:?}", reply.as_str());
            }
        }
    }
}
