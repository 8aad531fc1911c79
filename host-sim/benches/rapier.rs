//! The same feeder in a general rigid-body engine: a 1 cm × 1 mm box of 0.1 g (the paper's part,
//! Section IV, seen from the side) on a kinematic plate whose velocity follows the waveform's exact
//! segments, friction μ = 1 on both colliders, rotation locked as for a point mass.
//!
//! Prints the steady feed rate at each timestep beside the exact simulator and the closed form,
//! then lets criterion time one simulated cycle. Rapier's default step (1/60 s) is longer than the
//! 20 ms period, so only steps of 1e-4 s and 1e-5 s are run.

mod paper;

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use feeder_shared::model::STANDARD_GRAVITY_MPS2;
use host_sim::segments::exact_cycle;
use host_sim::{OperatingPoint, PlateSegment};
use paper::{point, CASES, FREQ_HZ, MASS_KG, MU};
use rapier2d::prelude::*;

const PART_HALF_LENGTH_M: f32 = 0.005;
const PART_HALF_HEIGHT_M: f32 = 0.0005;
const PLATE_HALF_LENGTH_M: f32 = 1.0;
const PLATE_HALF_HEIGHT_M: f32 = 0.005;
/// Cycles from rest before the feed rate is measured (the exact run settles in about 100).
const SETTLE_CYCLES: u32 = 150;
const MEASURE_CYCLES: u32 = 50;
const STEPS_S: [f64; 2] = [1e-4, 1e-5];

/// Plate position, integrated exactly from one cycle's segments.
struct PlatePath {
    /// Start time, velocity and position of every segment, with its acceleration.
    starts: Vec<(f64, f64, f64, f64)>,
    period_s: f64,
    /// Travel over one cycle (0 up to rounding).
    cycle_travel_m: f64,
}

impl PlatePath {
    fn new(cycle: &[PlateSegment]) -> Self {
        let (mut time_s, mut velocity_mps, mut position_m) = (0.0, 0.0, 0.0);
        let mut starts = Vec::with_capacity(cycle.len());
        for segment in cycle {
            starts.push((time_s, velocity_mps, position_m, segment.accel_mps2));
            let end_velocity_mps = velocity_mps + segment.accel_mps2 * segment.duration_s;
            position_m += 0.5 * (velocity_mps + end_velocity_mps) * segment.duration_s;
            velocity_mps = end_velocity_mps;
            time_s += segment.duration_s;
        }
        PlatePath {
            starts,
            period_s: time_s,
            cycle_travel_m: position_m,
        }
    }

    fn position_m(&self, time_s: f64) -> f64 {
        let cycles = (time_s / self.period_s).floor();
        let phase_s = time_s - cycles * self.period_s;
        let &(start_s, velocity_mps, position_m, accel_mps2) = self
            .starts
            .iter()
            .rev()
            .find(|start| start.0 <= phase_s)
            .unwrap_or(&self.starts[0]);
        let offset_s = phase_s - start_s;
        cycles * self.cycle_travel_m
            + position_m
            + velocity_mps * offset_s
            + 0.5 * accel_mps2 * offset_s * offset_s
    }
}

/// Plate and part in a rapier world, stepped at a fixed `dt`.
struct Bench {
    world: PhysicsWorld,
    plate: RigidBodyHandle,
    part: RigidBodyHandle,
    path: PlatePath,
    dt_s: f64,
    steps_per_cycle: u64,
    step: u64,
}

impl Bench {
    fn new(point: &OperatingPoint, dt_s: f64) -> Self {
        let mut world = PhysicsWorld {
            gravity: Vector::new(0.0, -STANDARD_GRAVITY_MPS2 as f32),
            ..PhysicsWorld::default()
        };
        world.integration_parameters.dt = dt_s as f32;
        // Contact tolerances scale with the length unit: centimetres for a millimetre-thin part.
        world.integration_parameters.length_unit = 0.01;
        let plate = world.bodies.insert(
            RigidBodyBuilder::kinematic_velocity_based()
                .translation(Vector::new(0.0, -PLATE_HALF_HEIGHT_M))
                .build(),
        );
        let plate_collider = ColliderBuilder::cuboid(PLATE_HALF_LENGTH_M, PLATE_HALF_HEIGHT_M)
            .friction(MU as f32)
            .build();
        world
            .colliders
            .insert_with_parent(plate_collider, plate, &mut world.bodies);
        let part = world.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(Vector::new(0.0, PART_HALF_HEIGHT_M))
                .lock_rotations()
                .build(),
        );
        let part_collider = ColliderBuilder::cuboid(PART_HALF_LENGTH_M, PART_HALF_HEIGHT_M)
            .friction(MU as f32)
            .mass(MASS_KG as f32)
            .build();
        world
            .colliders
            .insert_with_parent(part_collider, part, &mut world.bodies);
        let path = PlatePath::new(&exact_cycle(&point.waveform));
        let steps_per_cycle = (path.period_s / dt_s).round() as u64;
        Bench {
            world,
            plate,
            part,
            path,
            dt_s,
            steps_per_cycle,
            step: 0,
        }
    }

    /// One step with the plate moving at its exact mean velocity over the step.
    fn step(&mut self) {
        let from_s = self.step as f64 * self.dt_s;
        let to_s = from_s + self.dt_s;
        let travel_m = self.path.position_m(to_s) - self.path.position_m(from_s);
        let velocity_mps = travel_m / self.dt_s;
        self.world.bodies[self.plate].set_linvel(Vector::new(velocity_mps as f32, 0.0), true);
        self.world.step();
        self.step += 1;
    }

    fn cycle(&mut self) {
        for _ in 0..self.steps_per_cycle {
            self.step();
        }
    }

    fn part_x_m(&self) -> f64 {
        f64::from(self.world.bodies[self.part].translation().x)
    }
}

fn relative(actual: f64, expected: f64) -> f64 {
    ((actual - expected) / expected).abs()
}

fn print_feed_rates() {
    for (name, duty) in CASES {
        let point = point(duty, None);
        let exact = point.steady().feed_rate_mps;
        let closed_form = point.model().feed_rate_mps.unwrap();
        for dt_s in STEPS_S {
            let mut bench = Bench::new(&point, dt_s);
            for _ in 0..SETTLE_CYCLES {
                bench.cycle();
            }
            let start_m = bench.part_x_m();
            let started = std::time::Instant::now();
            for _ in 0..MEASURE_CYCLES {
                bench.cycle();
            }
            let wall_s_per_cycle = started.elapsed().as_secs_f64() / f64::from(MEASURE_CYCLES);
            let feed = (bench.part_x_m() - start_m) / (f64::from(MEASURE_CYCLES) / FREQ_HZ);
            eprintln!(
                "{name} dt {dt_s:e} s: rapier {feed:.6e} m/s, exact {exact:.6e} m/s \
                 (error {:.2e}), closed form {closed_form:.6e} m/s (error {:.2e}), \
                 {:.3} ms per cycle",
                relative(feed, exact),
                relative(feed, closed_form),
                wall_s_per_cycle * 1e3,
            );
        }
    }
}

fn rapier(c: &mut Criterion) {
    print_feed_rates();
    let mut group = c.benchmark_group("rapier");
    group.throughput(Throughput::Elements(1));
    group.sample_size(10);
    for (name, duty) in CASES {
        for dt_s in STEPS_S {
            let mut bench = Bench::new(&point(duty, None), dt_s);
            group.bench_function(BenchmarkId::new(format!("dt_{dt_s:e}"), name), |b| {
                b.iter(|| black_box(&mut bench).cycle())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, rapier);
criterion_main!(benches);
