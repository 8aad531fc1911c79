//! The output stage as the application sees it: a timer that starts each segment in hardware,
//! with the next segment preloaded by software while the current one plays.

use feeder_shared::configuration::Configuration;
#[cfg(any(feature = "board-qemu", not(feature = "output-pwm")))]
use feeder_shared::{DacCalibration, DacLevels};
use feeder_shared::{DriveError, Segment, TickClock};

/// A segment could not be prepared before its edge: the output timing is lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct EdgeMissed;

/// How a segment began on the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentStart {
    /// The tick at which it took effect.
    pub tick: u64,
    /// Its deadline (its start) minus the moment software preloaded it, in ticks; `None` for a
    /// segment applied at once by [`SegmentOutput::restart`] or where the stage cannot read it.
    pub slack_ticks: Option<u32>,
}

/// The levels of one cycle as the closed loop trims them: what each of its segments commands
/// instead of the plan's level, by its place in the cycle (`SegmentKind::place`).
#[derive(Debug, Clone, Copy, PartialEq, defmt::Format)]
pub struct TrimmedCycle {
    pub cycle: u64,
    pub levels_mps2: [f64; 4],
}

/// A trimmed cycle's levels in a stage's own units (DAC codes, PWM commands), converted once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrimmedLevels<T> {
    cycle: u64,
    levels: [T; 4],
}

impl<T: Copy> TrimmedLevels<T> {
    /// `trimmed`'s levels converted by `convert`, or its first refusal.
    pub fn convert(
        trimmed: &TrimmedCycle,
        convert: impl Fn(f64) -> Result<T, DriveError>,
    ) -> Result<Self, DriveError> {
        let [a, b, c, d] = trimmed.levels_mps2;
        Ok(TrimmedLevels {
            cycle: trimmed.cycle,
            levels: [convert(a)?, convert(b)?, convert(c)?, convert(d)?],
        })
    }

    /// What `segment` outputs if it belongs to the trimmed cycle.
    pub fn of(&self, segment: &Segment) -> Option<T> {
        (segment.cycle == self.cycle).then_some(self.levels[segment.kind.place()])
    }
}

/// The DAC codes of a stage that drives a DAC: the plan's levels at the peak acceleration set
/// last and the closed loop's trimmed cycle, for the DAC stage and the emulated one alike.
#[cfg(any(feature = "board-qemu", not(feature = "output-pwm")))]
pub struct DacCodes {
    /// The driver input's calibration.
    calibration: DacCalibration,
    /// The codes of the plan's levels; `None` (a refused acceleration): zero.
    levels: Option<DacLevels>,
    /// The codes of the cycle the closed loop trimmed last.
    trimmed: Option<TrimmedLevels<u16>>,
}

#[cfg(any(feature = "board-qemu", not(feature = "output-pwm")))]
impl DacCodes {
    /// No levels yet: zero until [`DacCodes::set_peak_accel`].
    pub const fn new(calibration: DacCalibration) -> Self {
        Self {
            calibration,
            levels: None,
            trimmed: None,
        }
    }

    /// One DAC count, in m/s² (see [`SegmentOutput::level_step_mps2`]).
    pub fn level_step_mps2(&self) -> f64 {
        1.0 / self.calibration.counts_per_mps2
    }

    /// The code of zero acceleration.
    pub const fn zero_code(&self) -> u16 {
        self.calibration.zero_code
    }

    /// See [`SegmentOutput::calibrate`]: no levels until the next
    /// [`DacCodes::set_peak_accel`].
    pub fn calibrate(&mut self, calibration: DacCalibration) {
        *self = Self::new(calibration);
    }

    /// See [`SegmentOutput::set_peak_accel`].
    pub fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError> {
        self.levels = None;
        self.levels = Some(self.calibration.levels(peak_accel_mps2)?);
        Ok(())
    }

    /// See [`SegmentOutput::trim`].
    pub fn trim(&mut self, trimmed: &TrimmedCycle) -> Result<(), DriveError> {
        let calibration = self.calibration;
        self.trimmed = Some(TrimmedLevels::convert(trimmed, |accel_mps2| {
            calibration.code(accel_mps2)
        })?);
        Ok(())
    }

    /// The code of `segment`: its trimmed cycle's, or the plan's, at the zero code while the
    /// plan's levels are refused.
    pub fn code(&self, segment: &Segment) -> u16 {
        match (&self.trimmed, &self.levels) {
            (Some(trimmed), Some(levels)) => trimmed
                .of(segment)
                .unwrap_or_else(|| levels.code(segment.level, segment.amplitude)),
            (None, Some(levels)) => levels.code(segment.level, segment.amplitude),
            (_, None) => self.calibration.zero_code,
        }
    }
}

/// A hardware-timed output of segments.
///
/// The stage holds two segments: the one playing and the one preloaded. At the end of the
/// playing segment the timer starts the preloaded one without software; the application then
/// preloads the next. Segment lengths are in ticks of [`SegmentOutput::clock`].
pub trait SegmentOutput {
    /// The clock that times the segments; the scheduler plans in its ticks.
    fn clock(&self) -> TickClock;

    /// The smallest step of a level (one DAC count, one PWM count), in m/s².
    fn level_step_mps2(&self) -> f64;

    /// Takes the driver input's calibration from `configuration`, once at power-up before
    /// anything plays: the output goes to its zero, and the safe state's store of the command
    /// writes that zero from now on.
    fn calibrate(&mut self, configuration: &Configuration);

    /// Recomputes the output levels for plans with this peak acceleration. Segments already
    /// playing or preloaded keep their values. On error the stage outputs zero until a valid
    /// acceleration is set.
    fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError>;

    /// Outputs `trimmed`'s levels for the segments of its cycle preloaded from now on, instead of
    /// the plan's; every other cycle keeps the plan's. Converts the four levels at once, before
    /// the cycle's first preload; on error the cycle keeps the plan's levels.
    fn trim(&mut self, trimmed: &TrimmedCycle) -> Result<(), DriveError>;

    /// Applies `segment` at once and restarts the timer with its length; nothing is preloaded.
    fn restart(&mut self, segment: &Segment);

    /// Preloads `segment` to begin when the playing one ends. Fails if an edge has passed since
    /// [`SegmentOutput::wait_edge`] returned, or if the segment is too short to be timed.
    fn preload(&mut self, segment: &Segment) -> Result<(), EdgeMissed>;

    /// Waits until the preloaded segment has begun. Fails if more than one edge has passed.
    async fn wait_edge(&mut self) -> Result<(), EdgeMissed>;

    /// Outputs zero at once and stops the timer.
    fn halt(&mut self);

    /// How `segment`, the one just begun, started. The timer starts every segment on its
    /// planned tick: the tick is that start, on the stage's own timeline (which a restart after
    /// a halt may shift against the plan).
    fn started(&self, segment: &Segment) -> SegmentStart;
}
