//! The plants the closed loop is designed for: the spread of real linear-motor and flexure
//! feeders (a drive's zero offset and unequal ± gains, a current loop of finite bandwidth, slide
//! friction, a flexure's centring spring, a position sensor's resolution), written down once. The
//! host's plant family draws from it, and a plant outside it is to be refused with the [`Cause`]
//! named.

use crate::error::Error;

/// The envelope of plants and operating points.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Envelope {
    /// The drive's full-scale acceleration, the unit of its zero offset: ±200 m/s² is the
    /// default DAC's ±1600 counts ([`crate::DacCalibration::DEFAULT`]).
    pub full_scale_mps2: f64,
    /// `|zero offset|` as a fraction of the drive's full scale.
    pub zero_offset_fraction_max: f64,
    /// Each direction's gain within `[gain_min, gain_max]`.
    pub gain_min: f64,
    pub gain_max: f64,
    /// The current loop's bandwidth at least this.
    pub current_bandwidth_min_hz: f64,
    /// Moving mass.
    pub mass_min_kg: f64,
    pub mass_max_kg: f64,
    /// The slide's Coulomb and viscous friction at most these.
    pub coulomb_max_n: f64,
    pub viscous_max_nspm: f64,
    /// A centring spring (a flexure mount) at most this stiff.
    pub spring_max_npm: f64,
    /// End stops at least this far from centre.
    pub end_stop_min_m: f64,
    /// The position sensor's count at most this coarse.
    pub resolution_max_m: f64,
    /// Operating frequencies and duties.
    pub frequency_min_hz: f64,
    pub frequency_max_hz: f64,
    pub duty_min: f64,
    pub duty_max: f64,
}

/// The envelope the closed loop is held to.
pub const ENVELOPE: Envelope = Envelope {
    full_scale_mps2: 200.0,
    zero_offset_fraction_max: 0.02,
    gain_min: 0.90,
    gain_max: 1.10,
    current_bandwidth_min_hz: 150.0,
    mass_min_kg: 0.5,
    mass_max_kg: 5.0,
    coulomb_max_n: 15.0,
    viscous_max_nspm: 20.0,
    spring_max_npm: 50e3,
    end_stop_min_m: 3e-3,
    resolution_max_m: 5e-6,
    frequency_min_hz: 50.0,
    frequency_max_hz: 100.0,
    duty_min: 0.52,
    duty_max: 0.62,
};

/// How far beyond the envelope an identified gain or offset may lie before it is refused: the
/// identification's own error on the envelope's plants.
pub const IDENTIFIED_MARGIN: f64 = 0.015;

impl Envelope {
    /// The largest `|offset|` an identification may find, m/s².
    pub fn offset_max_mps2(&self) -> f64 {
        self.zero_offset_fraction_max * self.full_scale_mps2 * (1.0 + 8.0 * IDENTIFIED_MARGIN)
    }

    /// The longest current-loop lag an identification may find, s: the time constant of the
    /// slowest current loop, with the identification's margin.
    pub fn lag_max_s(&self) -> f64 {
        (1.0 + 8.0 * IDENTIFIED_MARGIN)
            / (2.0 * core::f64::consts::PI * self.current_bandwidth_min_hz)
    }

    /// The largest `|offset|` a settle may find ([`Settle::drive`](crate::closed_loop::Settle::drive)
    /// reads it over the drive's mean gain): [`Envelope::offset_max_mps2`] over the weakest
    /// gain, so that no plant of the envelope is refused for it.
    pub fn settled_offset_max_mps2(&self) -> f64 {
        self.offset_max_mps2() / self.gain_min
    }

    /// The highest planned peak acceleration the closed loop takes on an output whose linear
    /// range reaches `linear_mps2`: its `+a` level, divided by the weakest gain, with the
    /// largest offset and the friction of the lightest plate on the stiffest slide fed forward
    /// on top, stays within the range: `a/g_min + |e|_max + (F_c/M)_max ≤ linear`.
    pub const fn loop_accel_max_mps2(&self, linear_mps2: f64) -> f64 {
        let offset_mps2 = self.zero_offset_fraction_max * self.full_scale_mps2;
        let friction_mps2 = self.coulomb_max_n / self.mass_min_kg;
        (linear_mps2 - offset_mps2 - friction_mps2) * self.gain_min
    }

    /// Whether the closed loop takes a waveform of peak acceleration `accel_mps2` on an output
    /// whose linear range reaches `linear_mps2` ([`Envelope::loop_accel_max_mps2`]).
    pub fn check_loop_accel(&self, accel_mps2: f64, linear_mps2: f64) -> Result<(), Error> {
        let limit_mps2 = self.loop_accel_max_mps2(linear_mps2);
        if accel_mps2 > limit_mps2 {
            return Err(Error::AccelAboveLoopRoom {
                accel_mps2,
                limit_mps2,
                linear_mps2,
            });
        }
        Ok(())
    }

    /// The stiffest centring spring an identification may find, as `k/M` (1/s²): the stiffest
    /// spring on the lightest plate, with the identification's margin.
    pub fn spring_max_per_s2(&self) -> f64 {
        self.spring_max_npm / self.mass_min_kg * (1.0 + 8.0 * IDENTIFIED_MARGIN)
    }

    /// The gains an identification may find.
    pub fn identified_gains(&self) -> (f64, f64) {
        (
            self.gain_min * (1.0 - IDENTIFIED_MARGIN),
            self.gain_max * (1.0 + IDENTIFIED_MARGIN),
        )
    }
}

/// The physical cause for which a plant lies outside the envelope.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Cause {
    /// A centring spring stiffer than [`Envelope::spring_max_npm`].
    Spring,
    /// Slide friction beyond [`Envelope::coulomb_max_n`].
    Friction,
    /// A zero offset beyond [`Envelope::zero_offset_fraction_max`].
    Offset,
    /// A gain outside [`Envelope::gain_min`]–[`Envelope::gain_max`].
    Gain,
    /// A current loop slower than [`Envelope::current_bandwidth_min_hz`].
    Lag,
    /// A position sensor coarser than [`Envelope::resolution_max_m`].
    Sensor,
}

impl Cause {
    /// Every cause, in order.
    pub const ALL: [Cause; 6] = [
        Cause::Spring,
        Cause::Friction,
        Cause::Offset,
        Cause::Gain,
        Cause::Lag,
        Cause::Sensor,
    ];

    /// The cause's name in reports.
    pub const fn name(self) -> &'static str {
        match self {
            Cause::Spring => "spring",
            Cause::Friction => "friction",
            Cause::Offset => "offset",
            Cause::Gain => "gain",
            Cause::Lag => "lag",
            Cause::Sensor => "sensor",
        }
    }

    /// What the operator can do about it.
    pub const fn remedy(self) -> &'static str {
        match self {
            Cause::Spring => {
                "mount the plate on a softer suspension, or run the feeder in open loop"
            }
            Cause::Friction => "check the slide's preload, seals and lubrication",
            Cause::Offset => "trim the drive's analog input offset",
            Cause::Gain => "check the drive's scaling and the DAC calibration",
            Cause::Lag => "raise the drive's current-loop bandwidth",
            Cause::Sensor => "fit a finer position sensor",
        }
    }
}
