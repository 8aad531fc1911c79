//! The reply lines: `OK …` with the parameters, state and recipes, or `ERR <code> <explanation>`.

use core::fmt::{self, Write};

use heapless::String;

use super::grammar::Param;
use super::limits::REPLY_CAPACITY;
use super::refusal::ReplyError;
use crate::closed_loop::{LoopReport, TrackReport};
use crate::configuration::{Configuration, Key, KeyValue, ValueKind};
use crate::number::{Fixed, Significant};
use crate::recipe::{RecipeSlot, RecordError, RECIPE_SLOTS};
use crate::scheduler::Phase;
use crate::settings::{Applied, Settings};
use crate::waveform::{Drive, Waveform};

/// A snapshot of the controller for `status` and `get`.
#[derive(Debug, Clone, Copy)]
pub struct Status<F> {
    pub phase: Phase,
    /// The latched fault's cause, if any; a latched fault is reported as `state=fault`.
    pub fault: Option<F>,
    /// The waveform in force.
    pub waveform: Waveform,
    pub ramp_cycles: u16,
    /// Predicted steady-state feed rate of `waveform` ([`crate::Machine::feed_rate_mps`]).
    pub feed_rate_mps: f64,
    pub uptime_ms: u64,
    /// Cycles (including idle periods) begun since power-up.
    pub cycles: u64,
    /// The closed loop, on a board that runs one.
    pub closed_loop: Option<LoopReport>,
    /// Track control, on a board with a part sensor.
    pub track: Option<TrackReport>,
}

/// The reportable parameters.
struct Params {
    waveform: Waveform,
    ramp_cycles: u16,
    feed_rate_mps: f64,
}

impl Params {
    fn of_status<F>(status: &Status<F>) -> Self {
        Params {
            waveform: status.waveform,
            ramp_cycles: status.ramp_cycles,
            feed_rate_mps: status.feed_rate_mps,
        }
    }

    fn of_applied(applied: &Applied) -> Self {
        Params {
            waveform: applied.plan.waveform,
            ramp_cycles: applied.settings.ramp_cycles,
            feed_rate_mps: applied.feed_rate_mps,
        }
    }

    fn value(&self, param: Param) -> f64 {
        match param {
            Param::Frequency => self.waveform.frequency_hz(),
            Param::Duty => self.waveform.duty,
            Param::Stroke => self.waveform.stroke_m * 1000.0,
            Param::Accel => self.waveform.accel_mps2,
            Param::Feed => self.feed_rate_mps * 1000.0,
            Param::Ramp => f64::from(self.ramp_cycles),
        }
    }

    fn write(&self, out: &mut Reply, param: Param) {
        let _ = write!(
            out,
            " {}={}",
            param.reply_key(),
            fixed(param, self.value(param))
        );
    }

    fn write_all(&self, out: &mut Reply) {
        for param in Param::ALL {
            self.write(out, param);
        }
    }
}

/// `value` of `param` with the decimal places shown in replies.
const fn fixed(param: Param, value: f64) -> Fixed {
    let decimals = match param {
        Param::Frequency | Param::Feed => 3,
        Param::Duty | Param::Stroke => 4,
        Param::Accel => 2,
        Param::Ramp => 0,
    };
    Fixed { value, decimals }
}

const HELP: &str = "commands: start | stop | status | get freq|duty|stroke|accel|feed|ramp | \
    set freq <Hz> | set duty <0.5..1> | set stroke <mm> | set accel <m/s2> | set feed <mm/s> | \
    set ramp <cycles> | recipe save <0-7> | recipe load <0-7> | recipe list | reset | \
    config list | config get <key> | config set <key> <value> | config save | config defaults | \
    restart | telemetry on|off | help";

/// One reply line: `OK …` or `ERR <code> <explanation>`, printable ASCII, no terminator.
///
/// Writing to it (through [`fmt::Write`]) transliterates non-ASCII (`²` → `2`, `μ` → `mu`),
/// turns control characters into spaces and truncates at [`REPLY_CAPACITY`] instead of failing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    text: String<REPLY_CAPACITY>,
}

impl Reply {
    fn start(head: &str) -> Self {
        let mut reply = Reply {
            text: String::new(),
        };
        let _ = reply.write_str(head);
        reply
    }

    /// `OK`, followed by the text of `args` if it is not empty.
    pub fn ok(args: fmt::Arguments<'_>) -> Self {
        let mut reply = Self::start("OK ");
        let _ = reply.write_fmt(args);
        if reply.text.ends_with(' ') {
            reply.text.pop();
        }
        reply
    }

    /// `ERR <code> <explanation>`.
    pub fn error(error: &ReplyError) -> Self {
        let mut reply = Self::start("ERR");
        let _ = write!(reply, " {} {}", error.code(), error);
        reply
    }

    /// The reply to `help`.
    pub fn help() -> Self {
        Self::ok(format_args!("{}", HELP))
    }

    /// The reply to `status`: `OK state=… freq_hz=… … uptime_s=… cycles=… [loop=… [loop_error=…] [gain_pos=…
    /// gain_neg=… offset_mps2=… lag_ms=…]] [track=… parts_per_min=…] fault=…`, the closed loop's and the
    /// track's fields on a board that has them.
    pub fn status<F: fmt::Display>(status: &Status<F>) -> Self {
        let state = match &status.fault {
            Some(_) => "fault",
            None => status.phase.name(),
        };
        let mut reply = Self::start("OK state=");
        let _ = reply.write_str(state);
        Params::of_status(status).write_all(&mut reply);
        let _ = write!(
            reply,
            " uptime_s={}.{:03} cycles={}",
            status.uptime_ms / 1000,
            status.uptime_ms % 1000,
            status.cycles
        );
        if let Some(report) = &status.closed_loop {
            let _ = write!(reply, " loop={}", report.stage.name());
            if let Some(failure) = &report.failure {
                let _ = write!(reply, " loop_error={}", failure.name());
            }
            if let Some(drive) = &report.drive {
                let gain = |value| Fixed { value, decimals: 5 };
                let _ = write!(
                    reply,
                    " gain_pos={} gain_neg={} offset_mps2={} lag_ms={}",
                    gain(drive.gain_positive),
                    gain(drive.gain_negative),
                    Fixed {
                        value: drive.offset_mps2,
                        decimals: 3
                    },
                    Fixed {
                        value: drive.lag_s * 1e3,
                        decimals: 3
                    }
                );
            }
            if let Some(feed) = &report.feed {
                let _ = write!(
                    reply,
                    " feed_amplitude={}",
                    Fixed {
                        value: feed.amplitude,
                        decimals: 4
                    }
                );
                if feed.limited {
                    let _ = write!(
                        reply,
                        " feed_limited_mmps={}",
                        Fixed {
                            value: feed.feed_mps * 1e3,
                            decimals: 3
                        }
                    );
                }
            }
        }
        if let Some(track) = &status.track {
            let _ = write!(
                reply,
                " track={} parts_per_min={}",
                track.state.name(),
                Fixed {
                    value: track.parts_per_minute,
                    decimals: 1
                }
            );
        }
        let _ = write!(reply, " fault=");
        let _ = match &status.fault {
            Some(cause) => write!(reply, "{}", cause),
            None => reply.write_str("none"),
        };
        reply
    }

    /// The reply to `get <param>`: `OK <key>=<value>`.
    pub fn get<F>(param: Param, status: &Status<F>) -> Self {
        let mut reply = Self::start("OK");
        Params::of_status(status).write(&mut reply, param);
        reply
    }

    /// The reply to an accepted `set`: every parameter the candidate will run with.
    pub fn applied(applied: &Applied) -> Self {
        let mut reply = Self::start("OK");
        Params::of_applied(applied).write_all(&mut reply);
        reply
    }

    /// The reply to a successful `recipe save`.
    pub fn recipe_saved(slot: RecipeSlot) -> Self {
        Self::ok(format_args!("recipe {} saved", slot))
    }

    /// The reply to a successful `recipe load`: every parameter the recipe will run with.
    pub fn recipe_loaded(slot: RecipeSlot, applied: &Applied) -> Self {
        let mut reply = Self::ok(format_args!("recipe {} loaded", slot));
        Params::of_applied(applied).write_all(&mut reply);
        reply
    }

    /// The reply to `recipe list`, one entry per slot: `<n>=<freq>Hz/<duty>/<stroke>mm` (or
    /// `…/<accel>m/s2`) and `/r<ramp>`, or why the slot holds no recipe.
    pub fn recipe_list(entries: &[Result<Settings, RecordError>; RECIPE_SLOTS]) -> Self {
        let mut reply = Self::start("OK recipes");
        for (index, entry) in entries.iter().enumerate() {
            let _ = write!(reply, " {}=", index);
            let _ = match entry {
                Ok(settings) => {
                    let _ = write!(
                        reply,
                        "{}Hz/{}/",
                        fixed(Param::Frequency, settings.frequency_hz),
                        fixed(Param::Duty, settings.duty)
                    );
                    let _ = match settings.drive {
                        Drive::Stroke { stroke_m } => {
                            write!(reply, "{}mm", fixed(Param::Stroke, stroke_m * 1000.0))
                        }
                        Drive::Accel { accel_mps2 } => {
                            write!(reply, "{}m/s2", fixed(Param::Accel, accel_mps2))
                        }
                    };
                    write!(reply, "/r{}", settings.ramp_cycles)
                }
                Err(error) => reply.write_str(error.short_name()),
            };
        }
        reply
    }

    /// The reply to `config list`: `OK config <key>=<value> …`, every key the configuration
    /// holds, in [`Key::ALL`]'s order.
    pub fn config_list(configuration: &Configuration) -> Self {
        let mut reply = Self::start("OK config");
        for key in Key::ALL {
            write_key(&mut reply, key, configuration);
        }
        reply
    }

    /// The reply to `config get <key>`: `OK <key>=<value>` (`none` for the start-up drive's key
    /// the start-up settings do not hold).
    pub fn config_value(key: Key, configuration: &Configuration) -> Self {
        let mut reply = Self::start("OK");
        if key.get(configuration).is_none() {
            let _ = write!(reply, " {}=none", key.keyword());
        }
        write_key(&mut reply, key, configuration);
        reply
    }

    /// The reply to an accepted `config set`: the key's new value, not saved yet.
    pub fn config_set(key: Key, configuration: &Configuration) -> Self {
        let mut reply = Self::config_value(key, configuration);
        let _ = reply.write_str(" (not saved)");
        reply
    }

    /// The reply to `config save`; `restart_applies` when the board runs another configuration.
    pub fn config_saved(restart_applies: bool) -> Self {
        Self::ok(format_args!(
            "config saved{}",
            if restart_applies {
                "; restart to run it"
            } else {
                ""
            }
        ))
    }

    /// The reply to `config defaults`.
    pub fn config_defaults() -> Self {
        Self::ok(format_args!("config defaults (not saved)"))
    }

    pub fn as_str(&self) -> &str {
        self.text.as_str()
    }

    /// True for `OK` replies.
    pub fn is_ok(&self) -> bool {
        self.text.starts_with("OK")
    }
}

/// ` <key>=<value>` if `configuration` holds the key.
fn write_key(reply: &mut Reply, key: Key, configuration: &Configuration) {
    let _ = match (key.get(configuration), key.kind()) {
        (Some(KeyValue::Number(value)), _) => {
            write!(reply, " {}={}", key.keyword(), Significant(value))
        }
        (
            Some(KeyValue::Switch(on)),
            ValueKind::Switch {
                off: off_word,
                on: on_word,
            },
        ) => write!(
            reply,
            " {}={}",
            key.keyword(),
            if on { on_word } else { off_word }
        ),
        _ => Ok(()),
    };
}

impl fmt::Write for Reply {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        for c in text.chars() {
            let ascii = match c {
                ' '..='~' => {
                    let _ = self.text.push(c);
                    continue;
                }
                'μ' | 'µ' => "mu",
                '²' => "2",
                '³' => "3",
                '·' | '×' => "*",
                '−' | '–' | '—' => "-",
                '≤' => "<=",
                '≥' => ">=",
                '…' => "...",
                c if c.is_control() => " ",
                _ => "?",
            };
            let _ = self.text.push_str(ascii);
        }
        Ok(())
    }
}

impl fmt::Display for Reply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
