//! The plate's encoder on the host as the board's position sensor (feature `cosim-encoder`): the
//! plant samples it at every multiple of [`ENCODER_SAMPLE_TICKS`] and at every capture the
//! output asks for, and the closed loop takes those samples once a cycle over the plant link
//! (`plant_link`'s wire format, with the two kinds defined here).

use feeder_shared::closed_loop::PositionSample;

use super::plant_link::{self, LinkError, Message, PlantLink};
use crate::ports::PositionSensor;

/// [`Message::kind`]: the encoder is sampled every `tick` ticks and counts `value` nanometres.
const KIND_CONFIG: u32 = 3;
/// [`Message::kind`]: the firmware takes the samples up to `tick`.
const KIND_STREAM: u32 = 4;

/// The encoder is sampled at every multiple of this many output ticks (0.25 ms).
pub const ENCODER_SAMPLE_TICKS: u64 = 250;

/// The encoder's resolution: the plant file's encoder must count the same (the host refuses
/// another).
pub const ENCODER_RESOLUTION_M: f64 = 1e-6;

/// The plate's encoder on the host, read through the link.
pub struct PlantEncoder;

impl PlantEncoder {
    /// Tells the host how the encoder is sampled; the link must be open.
    pub fn attach() -> Self {
        plant_link::with(|link| {
            link.send(
                &Message {
                    tick: ENCODER_SAMPLE_TICKS,
                    kind: KIND_CONFIG,
                    value: (ENCODER_RESOLUTION_M * 1e9) as i32,
                }
                .encode(),
            )
        });
        PlantEncoder
    }
}

impl PositionSensor for PlantEncoder {
    const PRESENT: bool = true;
    const RESOLUTION_M: f64 = ENCODER_RESOLUTION_M;

    fn take_until(&mut self, tick: u64, out: &mut [PositionSample]) -> usize {
        plant_link::with(|link| stream(link, tick, out))
    }
}

/// Takes the samples up to `tick` into `out` (see [`PositionSensor::take_until`]).
fn stream(link: &mut PlantLink, tick: u64, out: &mut [PositionSample]) -> Result<usize, LinkError> {
    link.send(
        &Message {
            tick,
            kind: KIND_STREAM,
            value: 0,
        }
        .encode(),
    )?;
    let header = link.receive_sample()?;
    if header.tick != tick || header.count < 0 {
        return Err(LinkError::OutOfStep {
            asked: tick,
            answered: header.tick,
        });
    }
    let total = header.count as usize;
    let mut kept = 0;
    for index in 0..total {
        let sample = link.receive_sample()?;
        // The oldest are dropped: the last `out.len()` are kept.
        if index + out.len() >= total {
            out[kept] = PositionSample {
                tick: sample.tick,
                position_m: position_m(sample.count),
            };
            kept += 1;
        }
    }
    Ok(kept)
}

/// The position of a count: the middle of it.
fn position_m(count: i32) -> f64 {
    (f64::from(count) + 0.5) * ENCODER_RESOLUTION_M
}
