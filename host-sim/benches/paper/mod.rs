//! The paper's operating point the exact simulator and the rigid-body engine are measured at:
//! 50 Hz, μ = 1, a 0.1 g part, a_max giving a 2.5 mm stroke at d = 0.586.

use feeder_shared::{Drive, WaveformSpec};
use host_sim::{Contact, OperatingPoint};

pub const FREQ_HZ: f64 = 50.0;
pub const ACCEL_MPS2: f64 = 145.86;
pub const MU: f64 = 1.0;
pub const MASS_KG: f64 = 1e-4;

/// Sliding all cycle (paper point) and sticking part of it (saturated, above `d_sat,nqs` ≈ 0.609).
pub const CASES: [(&str, f64); 2] = [("sliding_d0.586", 0.586), ("sticking_d0.7", 0.7)];

/// The paper's point at `duty`, its tick plan on `clock_hz` if given.
pub fn point(duty: f64, clock_hz: Option<u32>) -> OperatingPoint {
    let spec = WaveformSpec::from_frequency(
        FREQ_HZ,
        duty,
        Drive::Accel {
            accel_mps2: ACCEL_MPS2,
        },
    );
    let contact = Contact::kinetic(MU, MASS_KG).unwrap();
    OperatingPoint::new(spec, contact, clock_hz).unwrap()
}
