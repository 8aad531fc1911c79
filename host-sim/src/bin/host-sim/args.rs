//! The argument groups several commands share, and the checks of counts and grids they make
//! before anything is computed.

use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use clap::Args;
use feeder_shared::drive::MACHINE_LIMITS;
use feeder_shared::model::STANDARD_GRAVITY_MPS2;
use feeder_shared::number::{parse_length, LengthUnit, Significant};
use feeder_shared::{DacCalibration, Drive, Waveform, WaveformSpec};
use host_sim::contact::PAPER_PART_MASS_KG;
use host_sim::plate::{PlateParams, PlateRunOptions};
use host_sim::{Contact, OperatingPoint, SimError};

/// Timer clock of the tick plan when neither `--clock-hz` nor `--exact-times` is given.
const DEFAULT_CLOCK_HZ: u32 = 1_000_000;
/// Peak-to-peak stroke when neither `--stroke-m` nor `--accel-mps2` is given.
const DEFAULT_STROKE_M: f64 = 0.0025;
/// Cycles a real plate runs when a command is not told (it has no steady-state detection).
pub const PLATE_CYCLES: u64 = 100;
/// The last cycles over which a real plate's feed rate and mean position are averaged.
pub const PLATE_AVERAGE_CYCLES: u64 = 10;
/// Most operating points one command simulates to steady state: a_max values × duties for
/// `sweep`, forces for `viscosity`, a_max values × μ values for `saturation` (40 runs each).
pub const MAX_POINTS: usize = 10_000;

/// The vibration frequency.
#[derive(Args, Clone)]
pub struct FrequencyArgs {
    /// Vibration frequency 1/T.
    #[arg(long, default_value_t = 50.0, allow_hyphen_values = true)]
    pub freq_hz: f64,
}

impl FrequencyArgs {
    /// The period `T`; the frequency must be finite and above zero.
    pub fn period_s(&self) -> Result<f64, SimError> {
        let frequency_hz = self.freq_hz;
        if frequency_hz.is_finite() && frequency_hz > 0.0 {
            Ok(1.0 / frequency_hz)
        } else {
            Err(SimError::BadFrequency { frequency_hz })
        }
    }
}

/// The plate's waveform (Eq. 1–5).
#[derive(Args, Clone)]
pub struct WaveArgs {
    #[command(flatten)]
    pub frequency: FrequencyArgs,
    /// Duty cycle d = F/T of the plate's velocity profile, in (0.5, 1).
    #[arg(long, default_value_t = 0.586, allow_hyphen_values = true)]
    pub duty: f64,
    /// Peak-to-peak plate stroke x_max in metres, or with its unit (2.5mm, 2500um); a_max follows
    /// from Eq. 5. Default 2.5 mm.
    #[arg(
        long,
        conflicts_with = "accel_mps2",
        allow_hyphen_values = true,
        value_parser = metres
    )]
    pub stroke_m: Option<f64>,
    /// Peak plate acceleration a_max (the stroke follows from Eq. 5).
    #[arg(long, allow_hyphen_values = true)]
    pub accel_mps2: Option<f64>,
}

impl WaveArgs {
    pub fn spec(&self) -> Result<WaveformSpec, SimError> {
        let drive = match (self.accel_mps2, self.stroke_m) {
            (Some(accel_mps2), _) => Drive::Accel { accel_mps2 },
            (None, stroke_m) => Drive::Stroke {
                stroke_m: stroke_m.unwrap_or(DEFAULT_STROKE_M),
            },
        };
        Ok(WaveformSpec {
            period_s: self.frequency.period_s()?,
            duty: self.duty,
            drive,
        })
    }
}

/// A length typed in metres or with its unit, as metres.
fn metres(text: &str) -> Result<f64, String> {
    parse_length(text, LengthUnit::Metre, LengthUnit::Metre).map_err(|error| error.to_string())
}

/// Whether a waveform is held to the machine's drive limits.
#[derive(Args, Clone)]
pub struct DriveLimitArgs {
    /// Run a waveform beyond the machine's drive limits (its frequencies, peak acceleration and
    /// stroke, as the firmware checks them, and the DAC's linear range): a paper study.
    #[arg(long)]
    pub no_drive_limits: bool,
}

impl DriveLimitArgs {
    /// Refuses `spec` beyond the machine's limits unless `--no-drive-limits` lifts them; with them
    /// lifted, why it is beyond them (`None` within them), for the report.
    pub fn check(&self, spec: WaveformSpec) -> Result<Option<String>, SimError> {
        if self.no_drive_limits {
            return Ok(beyond_drive_limits(spec));
        }
        check_drive_limits(spec, " (--no-drive-limits runs it as a paper study)").map(|()| None)
    }
}

/// Why the firmware would refuse `spec`: the shared refusal of a waveform beyond
/// [`MACHINE_LIMITS`] or, with the default DAC, beyond its linear range; `None` within them.
pub fn beyond_drive_limits(spec: WaveformSpec) -> Option<String> {
    let waveform = match Waveform::new(spec, &MACHINE_LIMITS) {
        Ok(waveform) => waveform,
        Err(error) => return Some(error.to_string()),
    };
    DacCalibration::DEFAULT
        .levels(waveform.accel_mps2)
        .err()
        .map(|error| error.to_string())
}

/// Refuses a waveform the firmware would refuse ([`beyond_drive_limits`]): the shared refusal's
/// text, then `remedy`.
pub fn check_drive_limits(spec: WaveformSpec, remedy: &str) -> Result<(), SimError> {
    match beyond_drive_limits(spec) {
        Some(reason) => Err(SimError::Request(format!(
            "{reason}: beyond the machine's drive limits, which the firmware refuses{remedy}"
        ))),
        None => Ok(()),
    }
}

/// The part's friction on the plate, gravity and the part's mass.
#[derive(Args, Clone)]
pub struct FrictionArgs {
    /// Kinetic friction coefficient μ.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub mu: f64,
    /// Static friction coefficient μ_s ≥ μ (default μ).
    #[arg(long, allow_hyphen_values = true)]
    pub mu_static: Option<f64>,
    #[arg(long, default_value_t = STANDARD_GRAVITY_MPS2, allow_hyphen_values = true)]
    pub gravity_mps2: f64,
    /// Part mass (the paper's 0.1 g by default).
    #[arg(long, default_value_t = PAPER_PART_MASS_KG, allow_hyphen_values = true)]
    pub mass_kg: f64,
}

impl FrictionArgs {
    /// The contact under a constant external force `force_n`.
    pub fn contact(&self, force_n: f64) -> Result<Contact, SimError> {
        Contact::new(
            self.mu,
            self.mu_static.unwrap_or(self.mu),
            self.gravity_mps2,
            self.mass_kg,
            force_n,
        )
    }
}

/// The whole contact: friction, gravity, mass and a constant external force.
#[derive(Args, Clone)]
pub struct ContactArgs {
    #[command(flatten)]
    pub friction: FrictionArgs,
    /// Constant external force on the part along the feed direction.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub force_n: f64,
}

impl ContactArgs {
    pub fn contact(&self) -> Result<Contact, SimError> {
        self.friction.contact(self.force_n)
    }
}

/// Where the plate's switching times come from.
#[derive(Args, Clone)]
pub struct TimingArgs {
    /// Drive the plate with the shared scheduler's tick plan at this timer clock (default 1 MHz).
    #[arg(long, conflicts_with = "exact_times", allow_hyphen_values = true)]
    clock_hz: Option<u32>,
    /// Use the waveform's exact real-valued switching times instead of a tick plan.
    #[arg(long)]
    exact_times: bool,
}

impl TimingArgs {
    /// The tick plan's clock, `None` for exact times.
    pub fn clock_hz(&self) -> Option<u32> {
        if self.exact_times {
            None
        } else {
            Some(self.clock_hz.unwrap_or(DEFAULT_CLOCK_HZ))
        }
    }
}

/// The plate a command drives, with the open-loop command: the command exactly as planned, with
/// no correction (`closed-loop` and `cosim` run the closed loop).
#[derive(Args, Clone)]
pub struct PlantArgs {
    /// The plate as a TOML plant file (host-sim/plants/), driven open loop; without it, the ideal
    /// plate. A plate with any non-ideality runs until its command ends or it hits an end stop.
    #[arg(long, value_name = "FILE")]
    pub plant: Option<PathBuf>,
}

impl PlantArgs {
    /// The plant file and its plate, read and checked; `None` without `--plant`.
    pub fn plate(&self) -> Result<Option<(&Path, PlateParams)>, SimError> {
        self.plant
            .as_deref()
            .map(|path| Ok((path, PlateParams::from_path(path)?)))
            .transpose()
    }
}

/// An operating point: the plate's waveform, the part's contact, the drive limits' flag `L`
/// ([`DriveLimitArgs`], or [`NoLimitFlag`] where a command has none) and where the switching
/// times come from, in that order.
#[derive(Args, Clone)]
pub struct PointArgs<L: Args = NoLimitFlag> {
    #[command(flatten)]
    pub wave: WaveArgs,
    #[command(flatten)]
    pub contact: ContactArgs,
    #[command(flatten)]
    pub drive_limits: L,
    #[command(flatten)]
    pub timing: TimingArgs,
}

/// No flag for the drive limits: a paper study, or a command that always holds a waveform to
/// them.
#[derive(Args, Clone)]
pub struct NoLimitFlag {}

impl<L: Args> PointArgs<L> {
    /// The waveform's spec and the operating point; the waveform is checked before the contact.
    fn spec_and_point(&self) -> Result<(WaveformSpec, OperatingPoint), SimError> {
        let spec = self.wave.spec()?;
        let point = OperatingPoint::new(spec, self.contact.contact()?, self.timing.clock_hz())?;
        Ok((spec, point))
    }

    /// The operating point.
    pub fn point(&self) -> Result<OperatingPoint, SimError> {
        self.spec_and_point().map(|(_, point)| point)
    }
}

impl PointArgs<DriveLimitArgs> {
    /// The operating point, refused beyond the machine's drive limits unless
    /// `--no-drive-limits` lifts them; with them lifted, why it is beyond them (`None` within
    /// them), for the report.
    pub fn limited_point(&self) -> Result<(OperatingPoint, Option<String>), SimError> {
        let (spec, point) = self.spec_and_point()?;
        Ok((point, self.drive_limits.check(spec)?))
    }
}

/// `cycles` cycles of a real plate, averaged over the last [`PLATE_AVERAGE_CYCLES`] (all if
/// fewer).
pub fn plate_options(cycles: u64) -> PlateRunOptions {
    PlateRunOptions {
        cycles,
        average_cycles: cycles.min(PLATE_AVERAGE_CYCLES),
    }
}

/// What a command writes besides its report.
#[derive(Args, Clone)]
pub struct OutputArgs {
    /// Print one JSON document instead of the human-readable report.
    #[arg(long)]
    pub json: bool,
    /// Also write the data as CSV to this file.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Also draw a chart to this file (.svg or .png).
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
}

/// A whole-number flag as one clap attribute, `#[arg(long, count_in = (1, MAX))]`.
pub trait CountArg {
    /// Takes a whole number from `min` to `max`, named `N` in the help (a `value_name` after it
    /// renames it); a negative number reaches the bound's refusal instead of reading as a flag.
    fn count_in<T>(self, bounds: (T, T)) -> Self
    where
        T: FromStr + PartialOrd + Display + Copy + Send + Sync + 'static;
}

impl CountArg for clap::Arg {
    fn count_in<T>(self, (min, max): (T, T)) -> Self
    where
        T: FromStr + PartialOrd + Display + Copy + Send + Sync + 'static,
    {
        self.value_name("N")
            .value_parser(count(min, max))
            .allow_hyphen_values(true)
    }
}

/// A clap parser for a count from `min` to `max`; a refusal names the range.
fn count<T>(min: T, max: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static
where
    T: FromStr + PartialOrd + Display + Copy + Send + Sync + 'static,
{
    move |text| {
        text.parse()
            .ok()
            .filter(|count| (min..=max).contains(count))
            .ok_or_else(|| format!("expected a whole number from {min} to {max}"))
    }
}

/// Refuses `rows × columns` operating points beyond [`MAX_POINTS`]; `what` names the two flags.
pub fn check_grid(rows: usize, columns: usize, what: [&str; 2]) -> Result<(), SimError> {
    let points = rows.saturating_mul(columns);
    if points <= MAX_POINTS {
        return Ok(());
    }
    Err(SimError::Request(format!(
        "{rows} {} values × {} {columns} make {points} operating points; a run computes at most \
         {MAX_POINTS}",
        what[0], what[1]
    )))
}

/// `points` values from `low` to `high`, both included; refused unless `points ≥ 2` and
/// `high > low` (NaN bounds included), naming the two `flags` (low's, high's).
pub fn evenly_spaced(
    low: f64,
    high: f64,
    points: usize,
    flags: [&str; 2],
) -> Result<Vec<f64>, SimError> {
    if points < 2 || high.partial_cmp(&low) != Some(std::cmp::Ordering::Greater) {
        return Err(SimError::Request(format!(
            "{} {} must be above {} {}",
            flags[1],
            Significant(high),
            flags[0],
            Significant(low)
        )));
    }
    let span = high - low;
    Ok((0..points)
        .map(|i| low + span * (i as f64 / (points - 1) as f64))
        .collect())
}
