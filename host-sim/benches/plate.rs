//! Throughput of the real plate's exact solver, in simulated cycles per second, for the ideal
//! plate (the piecewise-linear simulator's limit), a plate with current-loop lag and centring
//! spring, and the full set of non-idealities without end stops; and of the RK4 reference at
//! `dt = T/4000`, where it agrees with the exact solver to about 1e-12.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use feeder_shared::{Drive, Limits, Waveform, WaveformSpec};
use host_sim::contact::Contact;
use host_sim::plate::reference::run_fixed_step;
use host_sim::plate::{self, PlateParams, PlateRunOptions};
use host_sim::segments::{exact_cycle, PlateSegment};

const CYCLES: u64 = 200;
const OPTIONS: PlateRunOptions = PlateRunOptions {
    cycles: CYCLES,
    average_cycles: 1,
};

fn cycle() -> [PlateSegment; 4] {
    let spec = WaveformSpec::from_frequency(50.0, 0.586, Drive::Accel { accel_mps2: 146.0 });
    exact_cycle(&Waveform::new(spec, &Limits::NONE).unwrap())
}

fn lag_and_spring() -> PlateParams {
    PlateParams {
        mass_kg: 1.5,
        current_bandwidth_hz: Some(1000.0),
        spring_npm: 2.0e4,
        spring_damping_nspm: 20.0,
        ..PlateParams::default()
    }
}

fn everything() -> PlateParams {
    PlateParams {
        zero_offset_fraction: 0.005,
        gain_positive: 1.02,
        gain_negative: 0.98,
        force_limit_n: Some(300.0),
        coulomb_friction_n: 2.0,
        viscous_friction_nspm: 5.0,
        ..lag_and_spring()
    }
}

fn bench(c: &mut Criterion) {
    let contact = Contact::kinetic(0.3, 1e-4).unwrap();
    let segments = cycle();
    let mut group = c.benchmark_group("plate");
    group.throughput(Throughput::Elements(CYCLES));
    group.sample_size(10);
    for (name, params) in [
        ("ideal", PlateParams::default()),
        ("lag_spring", lag_and_spring()),
        ("everything", everything()),
    ] {
        group.bench_with_input(BenchmarkId::new("exact", name), &params, |b, params| {
            b.iter(|| plate::run(params, &contact, segments.into_iter().cycle(), &OPTIONS).unwrap())
        });
    }
    let params = lag_and_spring();
    group.bench_function("rk4_T/4000/lag_spring", |b| {
        b.iter(|| {
            let segments = segments.into_iter().cycle();
            run_fixed_step(
                &params,
                &contact,
                segments,
                &OPTIONS,
                black_box(0.02 / 4000.0),
            )
            .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
