//! The random operator: what it types, and what the console must answer to each line.
//!
//! Every line carries its [`Expect`]ation, decided when the line is made: a blank line gets no
//! reply, a syntax error its code, a value past the machine's limits an `ERR`, a value inside
//! them an `OK` that echoes it or a validation `ERR` (other settings can make it invalid).

use std::time::Duration;

use feeder_shared::drive::MACHINE_LIMITS;
use feeder_shared::protocol::{Param, MAX_LINE_BYTES, REPLY_CAPACITY};
use feeder_shared::recipe::RECIPE_SLOTS;

/// The machine's limits ([`MACHINE_LIMITS`], which the firmware validates against) in the
/// protocol's units.
const MIN_FREQUENCY_HZ: f64 = MACHINE_LIMITS.min_frequency_hz;
const MAX_FREQUENCY_HZ: f64 = MACHINE_LIMITS.max_frequency_hz;
const MAX_STROKE_MM: f64 = MACHINE_LIMITS.max_stroke_m * 1e3;
const MAX_ACCEL_MPS2: f64 = MACHINE_LIMITS.max_accel_mps2;
const MAX_RAMP_CYCLES: i64 = 65_535;

/// Every error code of `shared/PROTOCOL.md`.
const ERROR_CODES: [std::ops::RangeInclusive<u16>; 4] = [10..=11, 20..=29, 40..=58, 60..=66];
/// The codes of a refused `set` whose value parsed: validation (40–58).
const VALIDATION_CODES: std::ops::RangeInclusive<u16> = 40..=58;
/// The codes of a `recipe load` that loads nothing: an empty slot, an unusable record.
const RECIPE_NOT_LOADED_CODES: [u16; 2] = [63, 64];

/// SplitMix64: a small, fast generator whose sequence depends on the seed alone.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(seed)
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n` small: the modulo bias is negligible).
    fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn chance(&mut self, probability: f64) -> bool {
        self.unit() < probability
    }

    fn uniform(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.unit()
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len() as u64) as usize]
    }

    /// An index into `weights`, chosen in proportion to them.
    fn weighted(&mut self, weights: &[u32]) -> usize {
        let total: u32 = weights.iter().sum();
        let mut point = self.below(u64::from(total)) as u32;
        for (index, weight) in weights.iter().enumerate() {
            if point < *weight {
                return index;
            }
            point -= weight;
        }
        weights.len() - 1
    }
}

/// What the console must answer to one line.
#[derive(Debug, Clone, PartialEq)]
pub enum Expect {
    /// A blank line: no reply at all.
    Nothing,
    /// `OK` followed by this text.
    Ok(String),
    /// `ERR` with this code, or with any code.
    Err(Option<u16>),
    /// `set <param> <value>`: an `OK` echoing the value is allowed only `in_range` (inside the
    /// machine's limits); otherwise an `ERR` 40–58, which validation may also give in range
    /// (other settings can make the change invalid), except for a ramp length.
    Set {
        param: Param,
        value: f64,
        in_range: bool,
    },
    /// `status`: the state, and no fault.
    Status,
    /// `recipe save <slot>`: saved, or refused because the feeder is not stopped.
    RecipeSave(usize),
    /// `recipe load <slot>`: the slot's settings, or `ERR 63` or `ERR 64` and nothing changed.
    RecipeLoad(usize),
    /// `reset` with no fault latched.
    Reset,
}

/// One line as sent, terminator included, with what it must get back.
#[derive(Debug, Clone)]
pub struct Line {
    pub bytes: Vec<u8>,
    pub expect: Expect,
}

impl Line {
    /// The line as a report shows it: quoted, with its bytes escaped.
    pub fn shown(&self) -> String {
        format!("\"{}\"", self.bytes.escape_ascii())
    }

    /// Whether the console answers this line.
    pub fn replied(&self) -> bool {
        self.expect != Expect::Nothing
    }
}

/// One write to the port: a line, or several pipelined (a PLC's burst), possibly delivered in
/// two pieces.
pub struct Write {
    pub lines: Vec<Line>,
    /// Deliver the first this many bytes, pause, then the rest.
    pub split_at: Option<usize>,
}

impl Write {
    pub fn bytes(&self) -> Vec<u8> {
        self.lines
            .iter()
            .flat_map(|line| line.bytes.clone())
            .collect()
    }
}

/// Parameters an accepted change runs with, as its reply states them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parameters {
    pub freq_hz: f64,
    pub duty: f64,
    pub stroke_mm: f64,
    pub accel_mps2: f64,
    pub ramp_cycles: u16,
}

/// What a correct reply says.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// A reply of the right kind that changes nothing.
    Plain,
    /// The settings changed (`set`, `recipe load`): the control loop must run these.
    Applied(Parameters),
    /// `status`: the state word.
    State(String),
    /// The firmware says a fault is latched (in words).
    Fault(String),
}

impl Expect {
    /// Judges `reply` to a line with this expectation: `Err` says what is wrong with it.
    pub fn judge(&self, reply: &str) -> Result<Verdict, String> {
        let shape = shape(reply)?;
        match (self, shape) {
            (Expect::Nothing, _) => Err("a blank line got a reply".into()),
            (Expect::Ok(head), Shape::Ok(text)) if text.starts_with(head.as_str()) => {
                Ok(Verdict::Plain)
            }
            (Expect::Err(None), Shape::Err(_)) => Ok(Verdict::Plain),
            (Expect::Err(Some(code)), Shape::Err(got)) if *code == got => Ok(Verdict::Plain),
            // Validation never refuses a ramp length the parser took.
            (Expect::Set { param, .. }, Shape::Err(code))
                if *param != Param::Ramp && VALIDATION_CODES.contains(&code) =>
            {
                Ok(Verdict::Plain)
            }
            (
                Expect::Set {
                    param,
                    value,
                    in_range: true,
                },
                Shape::Ok(_),
            ) => {
                let echoed = number(reply, param.reply_key())?;
                if (echoed - value).abs() > echo_tolerance(*param, *value) {
                    return Err(format!(
                        "{} is {echoed}, not the {value} set",
                        param.reply_key()
                    ));
                }
                parameters(reply).map(Verdict::Applied)
            }
            (Expect::Status, Shape::Ok(text)) => status(text),
            (Expect::RecipeSave(slot), Shape::Ok(text))
                if text == format!("recipe {slot} saved") =>
            {
                Ok(Verdict::Plain)
            }
            (Expect::RecipeSave(_), Shape::Err(60)) => Ok(Verdict::Plain),
            (Expect::RecipeLoad(slot), Shape::Ok(text))
                if text.starts_with(&format!("recipe {slot} loaded ")) =>
            {
                parameters(reply).map(Verdict::Applied)
            }
            (Expect::RecipeLoad(_), Shape::Err(code))
                if RECIPE_NOT_LOADED_CODES.contains(&code) =>
            {
                Ok(Verdict::Plain)
            }
            (Expect::Reset, Shape::Ok("no fault latched")) => Ok(Verdict::Plain),
            (Expect::Reset, Shape::Ok("fault cleared")) => {
                Ok(Verdict::Fault("`reset` cleared a latched fault".into()))
            }
            (_, Shape::Err(61)) => Ok(Verdict::Fault("ERR 61: a fault is latched".into())),
            (expect, _) => Err(format!("expected {expect:?}")),
        }
    }
}

/// A reply's kind: `OK` and its text, or `ERR` and its code.
enum Shape<'a> {
    Ok(&'a str),
    Err(u16),
}

/// Checks the format every reply has (printable ASCII, at most [`REPLY_CAPACITY`] bytes, `OK`
/// or `ERR <known code> <explanation>`).
fn shape(reply: &str) -> Result<Shape<'_>, String> {
    if reply.len() > REPLY_CAPACITY {
        return Err(format!("longer than {REPLY_CAPACITY} bytes"));
    }
    if !reply.bytes().all(|byte| (b' '..=b'~').contains(&byte)) {
        return Err("not printable ASCII".into());
    }
    if reply == "OK" {
        return Ok(Shape::Ok(""));
    }
    if let Some(text) = reply.strip_prefix("OK ") {
        return Ok(Shape::Ok(text));
    }
    let mut words = reply
        .strip_prefix("ERR ")
        .ok_or("neither OK nor ERR")?
        .splitn(2, ' ');
    let code: u16 = words
        .next()
        .and_then(|code| code.parse().ok())
        .ok_or("ERR without a numeric code")?;
    if !ERROR_CODES.iter().any(|codes| codes.contains(&code)) {
        return Err(format!("unknown error code {code}"));
    }
    match words.next() {
        Some(explanation) if !explanation.trim().is_empty() => Ok(Shape::Err(code)),
        _ => Err("ERR without an explanation".into()),
    }
}

/// The `status` text: its state, or the fault it reports.
fn status(text: &str) -> Result<Verdict, String> {
    let state = text
        .strip_prefix("state=")
        .and_then(|rest| rest.split(' ').next())
        .ok_or("status without state=")?;
    let (_, fault) = text.rsplit_once(" fault=").ok_or("status without fault=")?;
    if state == "fault" || fault != "none" {
        return Ok(Verdict::Fault(format!(
            "status: state={state} fault={fault}"
        )));
    }
    match state {
        "stopped" | "starting" | "running" | "stopping" => Ok(Verdict::State(state.to_string())),
        other => Err(format!("unknown state {other:?}")),
    }
}

/// The value of `key=` in `reply`.
fn number(reply: &str, key: &str) -> Result<f64, String> {
    reply
        .split(' ')
        .find_map(|word| word.strip_prefix(key)?.strip_prefix('='))
        .and_then(|value| value.parse().ok())
        .ok_or_else(|| format!("no number {key}="))
}

fn parameters(reply: &str) -> Result<Parameters, String> {
    let ramp_cycles = number(reply, Param::Ramp.reply_key())?;
    Ok(Parameters {
        freq_hz: number(reply, Param::Frequency.reply_key())?,
        duty: number(reply, Param::Duty.reply_key())?,
        stroke_mm: number(reply, Param::Stroke.reply_key())?,
        accel_mps2: number(reply, Param::Accel.reply_key())?,
        ramp_cycles: u16::try_from(ramp_cycles as i64)
            .map_err(|_| format!("ramp_cycles={ramp_cycles} is out of range"))?,
    })
}

/// How far a reply's value may lie from the one set: half the last decimal the reply shows, and
/// for the feed rate also the inverse model's tolerance.
pub fn echo_tolerance(param: Param, value: f64) -> f64 {
    let shown = match param {
        Param::Frequency => 5e-4,
        Param::Duty | Param::Stroke => 5e-5,
        Param::Accel => 5e-3,
        Param::Feed => 5e-4 + 1e-3 * value.abs(),
        Param::Ramp => 0.0,
    };
    shown + 1e-12 * value.abs()
}

/// The operator: picks lines at random, more often `start` while it believes the feeder stopped.
pub struct Operator {
    rng: Rng,
    /// Whether the last motion command sent was `start`.
    moving: bool,
}

/// What a line does, for the weighted choice.
#[derive(Clone, Copy)]
enum Kind {
    Set,
    Get,
    Start,
    Stop,
    Status,
    Recipe,
    Reset,
    Help,
    Mistyped,
    Garbage,
    Overlong,
    Blank,
    Config,
}

const KINDS: [Kind; 13] = [
    Kind::Set,
    Kind::Get,
    Kind::Start,
    Kind::Stop,
    Kind::Status,
    Kind::Recipe,
    Kind::Reset,
    Kind::Help,
    Kind::Mistyped,
    Kind::Garbage,
    Kind::Overlong,
    Kind::Blank,
    Kind::Config,
];

/// Weights of [`KINDS`] while moving and while stopped.
const MOVING_WEIGHTS: [u32; 13] = [40, 8, 2, 3, 10, 5, 1, 1, 6, 3, 2, 2, 3];
const STOPPED_WEIGHTS: [u32; 13] = [40, 8, 30, 2, 10, 8, 1, 1, 6, 3, 2, 2, 3];

impl Operator {
    pub fn new(seed: u64) -> Self {
        Operator {
            rng: Rng::new(seed),
            moving: false,
        }
    }

    /// The next write: mostly one line, sometimes a burst of two to eight.
    pub fn next_write(&mut self) -> Write {
        let count = if self.rng.chance(0.15) {
            2 + self.rng.below(7) as usize
        } else {
            1
        };
        let lines: Vec<Line> = (0..count).map(|_| self.line()).collect();
        let length: usize = lines.iter().map(|line| line.bytes.len()).sum();
        let split_at = (length > 1 && self.rng.chance(0.05))
            .then(|| 1 + self.rng.below(length as u64 - 1) as usize);
        Write { lines, split_at }
    }

    /// The pause before the next write: mostly short, sometimes long enough for a ramp to end.
    pub fn think_time(&mut self) -> Duration {
        let millis = match self.rng.below(20) {
            0 => self.rng.uniform(150.0, 600.0),
            1..=5 => self.rng.uniform(20.0, 150.0),
            _ => self.rng.uniform(0.0, 20.0),
        };
        Duration::from_secs_f64(millis / 1000.0)
    }

    /// A pause inside a write delivered in two pieces.
    pub fn split_pause(&mut self) -> Duration {
        Duration::from_millis(1 + self.rng.below(5))
    }

    /// A plain command with CR LF, for the wind-down.
    pub fn plain(text: &str, expect: Expect) -> Line {
        Line {
            bytes: format!("{text}\r\n").into_bytes(),
            expect,
        }
    }

    fn line(&mut self) -> Line {
        let weights = if self.moving {
            &MOVING_WEIGHTS
        } else {
            &STOPPED_WEIGHTS
        };
        match KINDS[self.rng.weighted(weights)] {
            Kind::Set => self.set(),
            Kind::Get => self.get(),
            Kind::Start => {
                self.moving = true;
                self.command(&["start"], Expect::Ok("starting".into()))
            }
            Kind::Stop => {
                self.moving = false;
                self.command(&["stop"], Expect::Ok("stopping".into()))
            }
            Kind::Status => self.command(&["status"], Expect::Status),
            Kind::Recipe => self.recipe(),
            Kind::Reset => self.command(&["reset"], Expect::Reset),
            Kind::Help => {
                let word = *self.rng.pick(&["help", "?"]);
                self.command(&[word], Expect::Ok("commands: ".into()))
            }
            Kind::Mistyped => self.mistyped(),
            Kind::Garbage => self.garbage(),
            Kind::Overlong => self.overlong(),
            Kind::Blank => self.blank(),
            Kind::Config => self.config(),
        }
    }

    /// `config` lines whose answer does not depend on the motion: reads, a start-up key, values
    /// past a key's range, a switch's wrong word, an unknown key.
    fn config(&mut self) -> Line {
        match self.rng.below(6) {
            0 => self.command(&["config", "list"], Expect::Ok("config dac_zero=".into())),
            1 => {
                let key = *self
                    .rng
                    .pick(&["dac_zero", "encoder_dir", "part_mu", "start_freq_hz"]);
                self.command(&["config", "get", key], Expect::Ok(format!("{key}=")))
            }
            2 => {
                let cycles = self.rng.below(u64::from(u16::MAX) + 1).to_string();
                let expect = Expect::Ok(format!("start_ramp={cycles} (not saved)"));
                self.command(&["config", "set", "start_ramp", &cycles], expect)
            }
            3 => {
                // A start-up key: refused for its range whether the plate moves or not.
                let value = *self.rng.pick(&["0", "0.2", "2.5", "1e9", "-1"]);
                self.command(
                    &["config", "set", "start_duty", value],
                    Expect::Err(Some(65)),
                )
            }
            4 => self.command(
                &["config", "set", "closed_loop", "maybe"],
                Expect::Err(Some(29)),
            ),
            _ => self.command(&["config", "get", "gain"], Expect::Err(Some(23))),
        }
    }

    /// `set` with a value across the machine's range and just past it, in any unit spelling.
    fn set(&mut self) -> Line {
        let param = *self.rng.pick(&Param::ALL);
        if self.rng.chance(0.08) {
            return self.set_misspelled(param);
        }
        let number = match param {
            Param::Ramp => self.ramp_cycles().to_string(),
            _ => {
                let value = self.parameter_value(param);
                self.written(value)
            }
        };
        // Judged by the number as written: rounding can move a value onto or past a limit.
        let value: f64 = number
            .parse()
            .expect("the operator writes numbers Rust reads");
        let in_range = in_limits(param, value);
        let expect = if param == Param::Ramp && !in_range {
            Expect::Err(Some(28))
        } else {
            Expect::Set {
                param,
                value,
                in_range,
            }
        };
        let mut words = vec![self.cased("set"), self.cased(param.keyword())];
        match self.correct_unit(param) {
            Some(unit) if self.rng.chance(0.5) => words.push(format!("{number}{unit}")),
            Some(unit) => words.extend([number, unit]),
            None => words.push(number),
        }
        let words: Vec<&str> = words.iter().map(String::as_str).collect();
        self.command(&words, expect)
    }

    /// `set` with a wrong unit, a non-number, a decimal comma, a fraction of a cycle or no value.
    fn set_misspelled(&mut self, param: Param) -> Line {
        let keyword = param.keyword();
        let (words, code): (Vec<String>, u16) = match self.rng.below(6) {
            0 => {
                let unit = wrong_unit(param);
                (
                    vec!["set".into(), keyword.into(), "60".into(), unit.into()],
                    26,
                )
            }
            1 => {
                let word = *self.rng.pick(&["nan", "inf", "-inf", "1e999"]);
                (vec!["set".into(), keyword.into(), word.into()], 25)
            }
            2 => {
                let word = *self.rng.pick(&["fast", "x", "--"]);
                (vec!["set".into(), keyword.into(), word.into()], 24)
            }
            3 => {
                let word = *self.rng.pick(&["0,6", "62,5", ",5"]);
                (vec!["set".into(), keyword.into(), word.into()], 24)
            }
            4 if param == Param::Ramp => (vec!["set".into(), "ramp".into(), "2.5".into()], 27),
            _ => (vec!["set".into(), keyword.into()], 21),
        };
        let words: Vec<&str> = words.iter().map(String::as_str).collect();
        self.command(&words, Expect::Err(Some(code)))
    }

    /// A value for `param` over its range and a margin past it, or one at or just past a limit.
    fn parameter_value(&mut self, param: Param) -> f64 {
        let (low, high, edges): (f64, f64, &[f64]) = match param {
            Param::Frequency => (45.0, 105.0, &[50.0, 100.0, 49.999, 100.001, 0.0, -50.0]),
            Param::Duty => (
                0.45,
                1.05,
                &[0.5, 1.0, 0.5001, 0.9999, 0.999_999, 0.500_000_1],
            ),
            Param::Stroke => (-0.2, 5.5, &[0.0, 5.0, 5.0001, 0.001, 1e-6]),
            Param::Accel => (-5.0, 220.0, &[0.0, 200.0, 200.01, 2.9, 3.0]),
            Param::Feed => (-10.0, 400.0, &[0.0, 0.001, 1000.0]),
            Param::Ramp => unreachable!("ramps are whole numbers"),
        };
        if self.rng.chance(0.15) {
            *self.rng.pick(edges)
        } else {
            self.rng.uniform(low, high)
        }
    }

    /// Mostly short ramps, some long ones, the limits and just past them.
    fn ramp_cycles(&mut self) -> i64 {
        match self.rng.below(20) {
            0 => *self
                .rng
                .pick(&[0, 1, MAX_RAMP_CYCLES, MAX_RAMP_CYCLES + 1, 100_000, -1]),
            1..=4 => 61 + self.rng.below(1940) as i64,
            _ => self.rng.below(61) as i64,
        }
    }

    /// `value` as an operator writes it: fixed decimals, exponent, or a bare leading point.
    fn written(&mut self, value: f64) -> String {
        match self.rng.below(10) {
            0 => format!("{value:e}"),
            1 if value.abs() < 1.0 && value > 0.0 => {
                let fixed = format!("{value:.4}");
                fixed.trim_start_matches('0').to_string()
            }
            _ => {
                let decimals = self.rng.below(7) as usize;
                format!("{value:.decimals$}")
            }
        }
    }

    /// A unit `param` accepts, in any case, or none (half of the time).
    fn correct_unit(&mut self, param: Param) -> Option<String> {
        let units: &[&str] = match param {
            Param::Frequency => &["Hz", "hz", "HZ"],
            Param::Duty => &[],
            Param::Stroke => &["mm", "MM"],
            Param::Accel => &["m/s2", "m/s^2", "m/s²", "M/S2"],
            Param::Feed => &["mm/s", "MM/S"],
            Param::Ramp => &["cycles", "cycle", "Cycles"],
        };
        if units.is_empty() || self.rng.chance(0.5) {
            None
        } else {
            Some(self.rng.pick(units).to_string())
        }
    }

    fn get(&mut self) -> Line {
        match self.rng.below(12) {
            0 => self.command(&["get", "speed"], Expect::Err(Some(23))),
            1 => self.command(&["get"], Expect::Err(Some(21))),
            _ => {
                let param = *self.rng.pick(&Param::ALL);
                let words = [self.cased("get"), self.cased(param.keyword())];
                let expect = Expect::Ok(format!("{}=", param.reply_key()));
                self.command(&[words[0].as_str(), words[1].as_str()], expect)
            }
        }
    }

    fn recipe(&mut self) -> Line {
        let slot = self.rng.below(RECIPE_SLOTS as u64) as usize;
        let slot_word = slot.to_string();
        match self.rng.below(10) {
            0..=2 => self.command(&["recipe", "save", &slot_word], Expect::RecipeSave(slot)),
            3..=5 => self.command(&["recipe", "load", &slot_word], Expect::RecipeLoad(slot)),
            6 | 7 => self.command(&["recipe", "list"], Expect::Ok("recipes 0=".into())),
            8 => {
                let past = RECIPE_SLOTS.to_string();
                let verb = *self.rng.pick(&["save", "load"]);
                self.command(&["recipe", verb, &past], Expect::Err(Some(28)))
            }
            _ => self.command(&["recipe", "load", "1.5"], Expect::Err(Some(27))),
        }
    }

    /// Unknown commands, words too many, and a typo corrected with backspace or DEL.
    fn mistyped(&mut self) -> Line {
        match self.rng.below(4) {
            0 => {
                let word = *self
                    .rng
                    .pick(&["launch", "go", "sett", "STARTT", "recipes"]);
                self.command(&[word, "1"], Expect::Err(Some(20)))
            }
            1 => self.command(&["recipe", "delete", "1"], Expect::Err(Some(20))),
            2 => {
                let word = *self.rng.pick(&["status", "stop", "help"]);
                self.command(&[word, "now"], Expect::Err(Some(22)))
            }
            _ => {
                let erase = *self.rng.pick(&[0x08u8, 0x7f]);
                let mut bytes = b"get dutx".to_vec();
                bytes.push(erase);
                bytes.extend_from_slice(b"y");
                self.terminated(bytes, Expect::Ok("duty=".into()))
            }
        }
    }

    /// Random bytes with at least one control character: `ERR 11`, or `ERR 10` if too long.
    fn garbage(&mut self) -> Line {
        let length = 1 + self.rng.below(90) as usize;
        let mut bytes: Vec<u8> = (0..length)
            .map(|_| loop {
                let byte = self.rng.below(256) as u8;
                // No terminators (they would split the line) and no erasing (it could empty it).
                if !matches!(byte, b'\r' | b'\n' | 0x08 | 0x7f) {
                    break byte;
                }
            })
            .collect();
        let control = *self.rng.pick(&[0x00u8, 0x01, 0x07, 0x0b, 0x1b, 0x1f]);
        let at = self.rng.below(bytes.len() as u64 + 1) as usize;
        bytes.insert(at, control);
        self.terminated(bytes, Expect::Err(Some(11)))
    }

    /// A printable line past [`MAX_LINE_BYTES`]: `ERR 10`.
    fn overlong(&mut self) -> Line {
        let extra = 1 + self.rng.below(200) as usize;
        let text = format!("set duty 0.6{}", "0".repeat(MAX_LINE_BYTES + extra));
        self.terminated(text.into_bytes(), Expect::Err(Some(10)))
    }

    /// Blanks only: no reply.
    fn blank(&mut self) -> Line {
        let blanks = *self.rng.pick(&["", " ", "\t", "  \t "]);
        self.terminated(blanks.as_bytes().to_vec(), Expect::Nothing)
    }

    /// `words` joined by random blanks, sometimes padded to exactly the line limit or one past.
    fn command(&mut self, words: &[&str], expect: Expect) -> Line {
        let mut text = String::new();
        if self.rng.chance(0.1) {
            let indent = *self.rng.pick(&[" ", "\t", "  "]);
            text.push_str(indent);
        }
        for (index, word) in words.iter().enumerate() {
            if index > 0 {
                let blanks = *self.rng.pick(&[" ", " ", " ", "  ", "\t"]);
                text.push_str(blanks);
            }
            text.push_str(word);
        }
        if self.rng.chance(0.05) {
            let blank_start = text.len() - text.trim_start().len();
            let width = blank_start + MAX_LINE_BYTES + self.rng.below(2) as usize;
            while text.len() < width {
                text.push(' ');
            }
        }
        self.terminated(text.into_bytes(), expect)
    }

    /// `bytes` with a random line terminator; a line past the limit must get `ERR 10`.
    fn terminated(&mut self, mut bytes: Vec<u8>, expect: Expect) -> Line {
        let content = bytes
            .iter()
            .skip_while(|byte| matches!(byte, b' ' | b'\t'))
            .count();
        let expect = if content > MAX_LINE_BYTES {
            Expect::Err(Some(10))
        } else {
            expect
        };
        let terminator = *self.rng.pick(&["\r\n", "\r\n", "\n", "\r"]);
        bytes.extend_from_slice(terminator.as_bytes());
        Line { bytes, expect }
    }

    /// `word` in lower, upper or title case.
    fn cased(&mut self, word: &str) -> String {
        match self.rng.below(8) {
            0 => word.to_uppercase(),
            1 => {
                let mut chars = word.chars();
                chars
                    .next()
                    .map(|first| first.to_uppercase().chain(chars).collect())
                    .unwrap_or_default()
            }
            _ => word.to_string(),
        }
    }
}

/// Whether `value` lies inside the machine's limits for `param`.
fn in_limits(param: Param, value: f64) -> bool {
    match param {
        Param::Frequency => (MIN_FREQUENCY_HZ..=MAX_FREQUENCY_HZ).contains(&value),
        Param::Duty => value > 0.5 && value < 1.0,
        Param::Stroke => value > 0.0 && value <= MAX_STROKE_MM,
        Param::Accel => value > 0.0 && value <= MAX_ACCEL_MPS2,
        Param::Feed => value > 0.0,
        Param::Ramp => (0.0..=MAX_RAMP_CYCLES as f64).contains(&value),
    }
}

/// A unit `param` refuses.
fn wrong_unit(param: Param) -> &'static str {
    match param {
        Param::Stroke => "Hz",
        _ => "mm",
    }
}

/// The codes this operator accepts are those `shared/PROTOCOL.md` documents.
#[test]
fn the_error_codes_are_the_documented_ones() {
    let reference = include_str!("../../../shared/PROTOCOL.md");
    let documented: Vec<u16> = reference
        .lines()
        .filter_map(|line| {
            line.strip_prefix('|')?
                .split('|')
                .next()?
                .trim()
                .parse()
                .ok()
        })
        .collect();
    let known: Vec<u16> = ERROR_CODES.iter().cloned().flatten().collect();
    assert_eq!(known, documented);
    assert!(VALIDATION_CODES
        .clone()
        .all(|code| documented.contains(&code)));
    assert!(RECIPE_NOT_LOADED_CODES
        .iter()
        .all(|code| documented.contains(code)));
}
