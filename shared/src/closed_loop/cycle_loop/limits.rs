//! How far the cycle-rate loop may trim ([`LoopLimits`]) and why it gave up ([`LoopError`]).

/// How far the loop may trim before it reports that it cannot hold the plate.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopLimits {
    /// `|δ|` at most this.
    pub correction_max_mps2: f64,
    /// `m` within `1 ± amplitude_max`.
    pub amplitude_max: f64,
    /// `|x − x_set|` at most this at a cycle start.
    pub position_error_max_m: f64,
}

/// Why the loop gave up.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LoopError {
    /// The centring correction needed more than its limit.
    Correction { correction_mps2: f64 },
    /// The amplitude trim left its range.
    Amplitude { amplitude: f64 },
    /// The plate is too far from where it should start a cycle.
    Position { error_m: f64 },
    /// A latched position is not finite.
    Sensor,
    /// A spring that turns the plate about half around in a cycle: one cycle's bias cannot
    /// steer both its position and its velocity.
    Unsteerable { spring_per_s2: f64, period_s: f64 },
    /// The encoder counts backwards: through the settle's dither the plate's acceleration read
    /// against the command (`measured_mps2` where the command swung by `commanded_mps2`).
    Backwards {
        measured_mps2: f64,
        commanded_mps2: f64,
    },
}

impl core::fmt::Display for LoopError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            LoopError::Correction { correction_mps2 } => write!(
                f,
                "centring the plate needs {correction_mps2} m/s², more than the loop may add"
            ),
            LoopError::Amplitude { amplitude } => write!(
                f,
                "holding the stroke needs {amplitude} × the planned level, outside the loop's range"
            ),
            LoopError::Position { error_m } => {
                write!(
                    f,
                    "the plate is {error_m} m from its centre at a cycle start"
                )
            }
            LoopError::Sensor => f.write_str("the position sensor returned no valid value"),
            LoopError::Backwards {
                measured_mps2,
                commanded_mps2,
            } => write!(
                f,
                "the encoder counts backwards: the plate's acceleration swung by {} m/s² where \
                 the command swung by {} m/s²; flip it (config set encoder_dir reversed, config \
                 save, restart)",
                crate::number::Significant(measured_mps2),
                crate::number::Significant(commanded_mps2)
            ),
            LoopError::Unsteerable {
                spring_per_s2,
                period_s,
            } => write!(
                f,
                "the plate's mount (natural frequency {} Hz) turns it about half around in a \
                 cycle of {} ms: the loop cannot steer it at this frequency",
                crate::number::Significant(
                    libm::sqrt(spring_per_s2.max(0.0)) / (2.0 * core::f64::consts::PI)
                ),
                crate::number::Significant(period_s * 1e3)
            ),
        }
    }
}
