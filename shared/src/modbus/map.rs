//! The register map: the one definition of every register a Modbus master reads and writes,
//! with its address, name, unit and scale. `docs/modbus.md` shows it as a table
//! ([`write_table`] writes that table; a test holds the page to it).
//!
//! Addresses are the protocol's, from 0 (a PLC that counts from 1 adds one: holding register 0
//! is its 40001, input register 0 its 30001). Every value is one unsigned 16-bit register, a
//! physical value times its scale, rounded; `offset_mps2` is two's complement; the 32-bit counts
//! take two registers, the high word first. A value beyond its register reads as 65535.

use core::fmt;

use crate::closed_loop::Stage;
use crate::control::Snapshot;
use crate::protocol::{Command, Param, ReplyError, Status};
use crate::recipe::{RecipeSlot, RECIPE_SLOTS};
use crate::scheduler::Phase;
use crate::settings::Setting;
use crate::supervisor::{Fault, RunState};

/// A register that reads 65535: a value beyond the register, or none.
pub const NONE: u16 = u16::MAX;

/// The holding registers (function codes 3, 6 and 16): what a master changes. A write is the
/// console's command with the same value, checked by the same rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Holding {
    /// 1 starts (soft start), 0 stops (soft stop): `start`, `stop`.
    Run,
    /// A recipe slot to load: `recipe load N`; reads the recipe loaded last, 65535 once a
    /// setting has changed since.
    Recipe,
    Duty,
    Frequency,
    Stroke,
    Accel,
    /// The feed rate the inverse model chooses the duty for (`set feed`); the closed loop,
    /// where it runs, holds the plate to the waveform that gives it.
    Feed,
    Ramp,
    /// 1 acknowledges a latched fault: `reset`. Reads 0.
    Acknowledge,
}

/// The input registers (function code 4): what a master watches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Input {
    /// 0 stopped, 1 running, 2 stopping, 3 faulted.
    State,
    /// The latched fault's code ([`Fault::code`]), 0 for none.
    Fault,
    /// The console's `ERR` code of this link's last refused write, 0 after an accepted one.
    Refusal,
    /// The holding register that write was refused at, 65535 for none.
    RefusedRegister,
    CyclesHigh,
    CyclesLow,
    /// 0 stopped, 1 starting, 2 running, 3 stopping.
    Phase,
    /// The closed loop's stage, 1 and up in the course's order ([`Stage::ALL`]); 0 without a
    /// closed loop.
    LoopStage,
    GainPositive,
    GainNegative,
    Offset,
    Lag,
    PartsPerMinute,
    /// The feed rate the waveform in force is predicted to give.
    FeedPredicted,
    UptimeHigh,
    UptimeLow,
}

/// Where a register is documented: its name, unit and what one count is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spec {
    pub address: u16,
    pub name: &'static str,
    /// The physical unit, or what the values mean.
    pub unit: &'static str,
    /// Register counts per unit.
    pub scale: f64,
}

const fn spec(address: u16, name: &'static str, unit: &'static str, scale: f64) -> Spec {
    Spec {
        address,
        name,
        unit,
        scale,
    }
}

impl Holding {
    /// Every holding register, at addresses 0 and up.
    pub const ALL: [Holding; 9] = [
        Holding::Run,
        Holding::Recipe,
        Holding::Duty,
        Holding::Frequency,
        Holding::Stroke,
        Holding::Accel,
        Holding::Feed,
        Holding::Ramp,
        Holding::Acknowledge,
    ];

    pub const fn spec(self) -> Spec {
        match self {
            Holding::Run => spec(0, "run", "0 stop, 1 start", 1.0),
            Holding::Recipe => spec(1, "recipe", "slot 0-7", 1.0),
            Holding::Duty => spec(2, "duty", "0.0001", 10_000.0),
            Holding::Frequency => spec(3, "freq", "0.01 Hz", 100.0),
            Holding::Stroke => spec(4, "stroke", "1 um", 1_000.0),
            Holding::Accel => spec(5, "accel", "0.1 m/s2", 10.0),
            Holding::Feed => spec(6, "feed", "0.1 mm/s", 10.0),
            Holding::Ramp => spec(7, "ramp", "cycles", 1.0),
            Holding::Acknowledge => spec(8, "acknowledge", "1 acknowledges", 1.0),
        }
    }

    /// The register at `address`.
    pub fn at(address: u16) -> Option<Holding> {
        Holding::ALL.get(usize::from(address)).copied()
    }

    /// The register's value now.
    pub fn read(self, status: &Status<Fault>, recipe: Option<RecipeSlot>, running: bool) -> u16 {
        let waveform = &status.waveform;
        let scaled = |value: f64| scaled(value, self.spec().scale);
        match self {
            Holding::Run => u16::from(running),
            Holding::Recipe => recipe.map_or(NONE, |slot| slot.index() as u16),
            Holding::Duty => scaled(waveform.duty),
            Holding::Frequency => scaled(1.0 / waveform.period_s),
            // The stroke in mm, the acceleration in m/s², the feed in mm/s.
            Holding::Stroke => scaled(waveform.stroke_m * 1e3),
            Holding::Accel => scaled(waveform.accel_mps2),
            Holding::Feed => scaled(status.feed_rate_mps * 1e3),
            Holding::Ramp => status.ramp_cycles,
            Holding::Acknowledge => 0,
        }
    }

    /// The console's command a write of `value` makes, or why the value means none.
    pub fn command(self, value: u16) -> Result<Command, ReplyError> {
        let number = f64::from(value) / self.spec().scale;
        let out_of_range = |what, min: u32, max: u32| ReplyError::OutOfRange { what, min, max };
        Ok(match self {
            Holding::Run => match value {
                0 => Command::Stop,
                1 => Command::Start,
                _ => return Err(out_of_range("0 (stop) or 1 (start)", 0, 1)),
            },
            Holding::Recipe => u8::try_from(value)
                .ok()
                .and_then(RecipeSlot::new)
                .map(Command::RecipeLoad)
                .ok_or(out_of_range(
                    "a recipe slot number from 0 to 7",
                    0,
                    RECIPE_SLOTS as u32 - 1,
                ))?,
            Holding::Duty => Command::Set(Setting::Duty(number)),
            Holding::Frequency => Command::Set(Setting::FrequencyHz(number)),
            Holding::Stroke => Command::Set(Setting::StrokeMm(number)),
            Holding::Accel => Command::Set(Setting::AccelMps2(number)),
            Holding::Feed => Command::Set(Setting::FeedMmps(number)),
            Holding::Ramp => Command::Set(Setting::RampCycles(value)),
            Holding::Acknowledge => match value {
                1 => Command::Reset,
                _ => return Err(out_of_range("1 (acknowledge)", 1, 1)),
            },
        })
    }

    /// The console's command a write stands for.
    pub const fn console(self) -> &'static str {
        match self {
            Holding::Run => "start / stop",
            Holding::Recipe => "recipe load N",
            Holding::Duty => "set duty",
            Holding::Frequency => "set freq",
            Holding::Stroke => "set stroke",
            Holding::Accel => "set accel",
            Holding::Feed => "set feed",
            Holding::Ramp => "set ramp",
            Holding::Acknowledge => "reset",
        }
    }

    /// The console's parameter this register reads and writes, where it is one.
    pub const fn param(self) -> Option<Param> {
        match self {
            Holding::Duty => Some(Param::Duty),
            Holding::Frequency => Some(Param::Frequency),
            Holding::Stroke => Some(Param::Stroke),
            Holding::Accel => Some(Param::Accel),
            Holding::Feed => Some(Param::Feed),
            Holding::Ramp => Some(Param::Ramp),
            Holding::Run | Holding::Recipe | Holding::Acknowledge => None,
        }
    }
}

/// What the input registers report besides the controller's status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkState {
    /// This link's last refused write: its `ERR` code and register.
    pub refusal: Option<(u16, u16)>,
}

impl Input {
    /// Every input register, at addresses 0 and up.
    pub const ALL: [Input; 16] = [
        Input::State,
        Input::Fault,
        Input::Refusal,
        Input::RefusedRegister,
        Input::CyclesHigh,
        Input::CyclesLow,
        Input::Phase,
        Input::LoopStage,
        Input::GainPositive,
        Input::GainNegative,
        Input::Offset,
        Input::Lag,
        Input::PartsPerMinute,
        Input::FeedPredicted,
        Input::UptimeHigh,
        Input::UptimeLow,
    ];

    pub const fn spec(self) -> Spec {
        match self {
            Input::State => spec(
                0,
                "state",
                "0 stopped, 1 running, 2 stopping, 3 faulted",
                1.0,
            ),
            Input::Fault => spec(1, "fault", "fault code, 0 none", 1.0),
            Input::Refusal => spec(2, "refusal", "console ERR code, 0 none", 1.0),
            Input::RefusedRegister => spec(3, "refused_register", "holding address", 1.0),
            Input::CyclesHigh => spec(4, "cycles_high", "cycles / 65536", 1.0),
            Input::CyclesLow => spec(5, "cycles_low", "cycles mod 65536", 1.0),
            Input::Phase => spec(
                6,
                "phase",
                "0 stopped, 1 starting, 2 running, 3 stopping",
                1.0,
            ),
            Input::LoopStage => spec(7, "loop_stage", "stage, 0 no loop", 1.0),
            Input::GainPositive => spec(8, "gain_pos", "0.0001", 10_000.0),
            Input::GainNegative => spec(9, "gain_neg", "0.0001", 10_000.0),
            Input::Offset => spec(10, "offset", "0.001 m/s2, signed", 1_000.0),
            Input::Lag => spec(11, "lag", "1 us", 1e6),
            Input::PartsPerMinute => spec(12, "parts_per_min", "0.1 /min", 10.0),
            Input::FeedPredicted => spec(13, "feed_predicted", "0.1 mm/s", 10.0),
            Input::UptimeHigh => spec(14, "uptime_high", "s / 65536", 1.0),
            Input::UptimeLow => spec(15, "uptime_low", "s mod 65536", 1.0),
        }
    }

    /// The register at `address`.
    pub fn at(address: u16) -> Option<Input> {
        Input::ALL.get(usize::from(address)).copied()
    }

    /// The register's value in `snapshot`, with the controller's `status` and the `link`'s.
    pub fn read(self, snapshot: &Snapshot, status: &Status<Fault>, link: &LinkState) -> u16 {
        let scale = self.spec().scale;
        let drive = snapshot.closed_loop.and_then(|report| report.drive);
        let identified = |value: fn(&crate::closed_loop::Identified) -> f64| {
            drive.map_or(0, |drive| scaled(value(&drive), scale))
        };
        let uptime_s = snapshot.uptime_ms / 1000;
        match self {
            Input::State => match snapshot.state {
                RunState::Stopped => 0,
                RunState::Running => 1,
                RunState::Stopping => 2,
                RunState::Faulted(_) => 3,
            },
            Input::Fault => match snapshot.state {
                RunState::Faulted(fault) => fault.code(),
                _ => 0,
            },
            Input::Refusal => link.refusal.map_or(0, |(code, _)| code),
            Input::RefusedRegister => link.refusal.map_or(NONE, |(_, register)| register),
            Input::CyclesHigh => high(snapshot.cycles),
            Input::CyclesLow => snapshot.cycles as u16,
            Input::Phase => match snapshot.phase {
                Phase::Stopped => 0,
                Phase::Starting => 1,
                Phase::Running => 2,
                Phase::Stopping => 3,
            },
            Input::LoopStage => snapshot.closed_loop.map_or(0, |report| {
                Stage::ALL
                    .iter()
                    .position(|&stage| stage == report.stage)
                    .map_or(NONE, |index| index as u16 + 1)
            }),
            Input::GainPositive => identified(|drive| drive.gain_positive),
            Input::GainNegative => identified(|drive| drive.gain_negative),
            Input::Offset => drive.map_or(0, |drive| signed(drive.offset_mps2 * scale)),
            Input::Lag => identified(|drive| drive.lag_s),
            Input::PartsPerMinute => snapshot
                .track
                .map_or(0, |track| scaled(track.parts_per_minute, scale)),
            Input::FeedPredicted => scaled(status.feed_rate_mps * 1e3, scale),
            Input::UptimeHigh => high(uptime_s),
            Input::UptimeLow => uptime_s as u16,
        }
    }
}

/// `value · scale` rounded to a register, [`NONE`] where it does not fit (or is not finite).
fn scaled(value: f64, scale: f64) -> u16 {
    let count = libm::round(value * scale);
    if (0.0..f64::from(NONE)).contains(&count) {
        count as u16
    } else {
        NONE
    }
}

/// A signed value rounded to a two's-complement register, [`i16::MIN`] where it does not fit.
fn signed(value: f64) -> u16 {
    let count = libm::round(value);
    let fits = (f64::from(i16::MIN) < count) && (count <= f64::from(i16::MAX));
    (if fits { count as i16 } else { i16::MIN }) as u16
}

/// The high word of a 32-bit count, 65535 beyond 32 bits.
fn high(value: u64) -> u16 {
    match u32::try_from(value) {
        Ok(value) => (value >> 16) as u16,
        Err(_) => NONE,
    }
}

/// The register tables as `docs/modbus.md` shows them: one Markdown table each.
pub fn write_table(out: &mut impl fmt::Write) -> fmt::Result {
    writeln!(out, "| holding | PLC | name | unit | console |")?;
    writeln!(out, "|---:|---:|---|---|---|")?;
    for register in Holding::ALL {
        let spec = register.spec();
        writeln!(
            out,
            "| {} | 4{:04} | `{}` | {} | `{}` |",
            spec.address,
            spec.address + 1,
            spec.name,
            spec.unit,
            register.console()
        )?;
    }
    writeln!(out)?;
    writeln!(out, "| input | PLC | name | unit |")?;
    writeln!(out, "|---:|---:|---|---|")?;
    for register in Input::ALL {
        let spec = register.spec();
        writeln!(
            out,
            "| {} | 3{:04} | `{}` | {} |",
            spec.address,
            spec.address + 1,
            spec.name,
            spec.unit
        )?;
    }
    Ok(())
}
