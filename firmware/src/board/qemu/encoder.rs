//! The plate's encoder on the host as the board's position sensor (feature `cosim-encoder`): the
//! plant samples it at every multiple of [`ENCODER_SAMPLE_TICKS`] and at every capture the
//! output asks for, and the closed loop takes those samples once a cycle over the plant link
//! (`plant_link`'s wire format, with the two kinds defined here).

use feeder_shared::closed_loop::PositionSample;
use feeder_shared::configuration::EncoderSetup;

use super::plant_link::{self, LinkError, Message, PlantLink};
use crate::ports::PositionSensor;

/// [`Message::kind`]: the encoder is sampled every `tick` ticks and counts `value` nanometres.
const KIND_CONFIG: u32 = 3;
/// [`Message::kind`]: the firmware takes the samples up to `tick`.
const KIND_STREAM: u32 = 4;

/// The encoder is sampled at every multiple of this many output ticks (0.25 ms).
pub const ENCODER_SAMPLE_TICKS: u64 = 250;

/// The plate's encoder on the host, read through the link, counting as the configuration says
/// (the plant file's encoder must have the configured resolution: the host refuses another).
pub struct PlantEncoder {
    setup: EncoderSetup,
}

impl PlantEncoder {
    /// Tells the host how the encoder is sampled; the link must be open.
    pub fn attach(setup: EncoderSetup) -> Self {
        plant_link::with(|link| {
            link.send(
                &Message {
                    tick: ENCODER_SAMPLE_TICKS,
                    kind: KIND_CONFIG,
                    value: (setup.resolution_m * 1e9 + 0.5) as i32,
                }
                .encode(),
            )
        });
        PlantEncoder { setup }
    }
}

impl PositionSensor for PlantEncoder {
    const PRESENT: bool = true;

    fn take_until(&mut self, tick: u64, out: &mut [PositionSample]) -> usize {
        let setup = self.setup;
        plant_link::with(|link| stream(link, tick, out, &setup))
    }
}

/// Takes the samples up to `tick` into `out` (see [`PositionSensor::take_until`]).
fn stream(
    link: &mut PlantLink,
    tick: u64,
    out: &mut [PositionSample],
    setup: &EncoderSetup,
) -> Result<usize, LinkError> {
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
                position_m: setup.position_m(sample.count),
            };
            kept += 1;
        }
    }
    Ok(kept)
}
