//! The drives and run options the real plate's tests share.

// Each test file uses its own part of these helpers.
#![allow(dead_code)]

use feeder_shared::{Drive, Limits, Waveform, WaveformSpec};
use host_sim::plate::PlateRunOptions;
use host_sim::segments::{exact_cycle, PlateSegment};

/// The exact cycle at 50 Hz, a_max 146 m/s² and `duty`, repeated without end.
pub fn cycles(duty: f64) -> impl Iterator<Item = PlateSegment> + Clone {
    let spec = WaveformSpec::from_frequency(50.0, duty, Drive::Accel { accel_mps2: 146.0 });
    let waveform = Waveform::new(spec, &Limits::NONE).unwrap();
    exact_cycle(&waveform).into_iter().cycle()
}

/// A command of `accel_mps2` for 1 ms, starting a cycle.
pub fn millisecond(accel_mps2: f64) -> PlateSegment {
    PlateSegment {
        duration_s: 1e-3,
        accel_mps2,
        starts_cycle: true,
    }
}

/// `cycles` cycles, the feed rate and mean position averaged over the last one.
pub fn options(cycles: u64) -> PlateRunOptions {
    PlateRunOptions {
        cycles,
        average_cycles: 1,
    }
}
