//! Throughput of the exact simulator (cycle table and scheduler stream), of the fixed-step
//! reference at `dt = T/20000`, and of the full Fig. 9 sweep.
//!
//! Before measuring, the steady feed rates of the exact and the fixed-step runs are printed with
//! their relative errors against the closed forms (Eq. 15 sliding, Eq. 18 sticking).

mod paper;

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use feeder_shared::model::STANDARD_GRAVITY_MPS2;
use host_sim::figures;
use host_sim::ideal::fixed_step::run_fixed_step;
use host_sim::ideal::simulator::CycleTable;
use host_sim::segments::{exact_cycle, scheduler_segments};
use host_sim::{run_segments, run_table, Contact, OperatingPoint, RunOptions, Timing};
use paper::{point, CASES, FREQ_HZ, MASS_KG, MU};

/// Timer clock of the tick-plan stream (the CLI's default).
const CLOCK_HZ: u32 = 1_000_000;
/// Cycles per iteration of the exact paths.
const EXACT_CYCLES: u64 = 100_000;
/// Steps per cycle of the fixed-step reference: `dt = T/20000`.
const FIXED_STEPS_PER_CYCLE: u64 = 20_000;
/// Cycles per iteration of the fixed-step reference.
const FIXED_CYCLES: u64 = 10;
/// Cycles the fixed-step reference runs from rest for its accuracy (the exact run converges in
/// under 100).
const FIXED_ACCURACY_CYCLES: u64 = 150;

fn fixed(point: &OperatingPoint, cycles: u64) -> RunOptions {
    RunOptions {
        fixed_cycles: Some(cycles),
        ..RunOptions::converge(point.default_criteria())
    }
}

fn relative(actual: f64, expected: f64) -> f64 {
    ((actual - expected) / expected).abs()
}

/// Feed rates and errors of both integrators against the closed form, with the fixed-step
/// reference's slowdown per simulated cycle.
fn print_accuracy() {
    for (name, duty) in CASES {
        let point = point(duty, None);
        let closed_form = point.model().feed_rate_mps.unwrap();
        let exact = point.steady();
        let segments = exact_cycle(&point.waveform);
        let started = Instant::now();
        let reference = run_fixed_step(
            &segments,
            &point.contact,
            FIXED_STEPS_PER_CYCLE,
            FIXED_ACCURACY_CYCLES,
        );
        let fixed_s_per_cycle = started.elapsed().as_secs_f64() / FIXED_ACCURACY_CYCLES as f64;
        let table = CycleTable::exact(&point.waveform, &point.contact);
        let started = Instant::now();
        black_box(run_table(&table, &fixed(&point, EXACT_CYCLES)));
        let exact_s_per_cycle = started.elapsed().as_secs_f64() / EXACT_CYCLES as f64;
        eprintln!(
            "{name}: closed form {closed_form:.15e} m/s; exact {:.15e} m/s ({} cycles, \
             error {:.1e}); fixed step T/{FIXED_STEPS_PER_CYCLE} {:.15e} m/s \
             ({FIXED_ACCURACY_CYCLES} cycles, error {:.1e}); fixed step {:.0}x slower per cycle",
            exact.feed_rate_mps,
            exact.cycles,
            relative(exact.feed_rate_mps, closed_form),
            reference.feed_rate_mps,
            relative(reference.feed_rate_mps, closed_form),
            fixed_s_per_cycle / exact_s_per_cycle,
        );
    }
}

fn exact(c: &mut Criterion) {
    print_accuracy();
    let mut group = c.benchmark_group("exact");
    group.throughput(Throughput::Elements(EXACT_CYCLES));
    for (name, duty) in CASES {
        let point = point(duty, None);
        let table = CycleTable::exact(&point.waveform, &point.contact);
        let options = fixed(&point, EXACT_CYCLES);
        group.bench_function(BenchmarkId::new("table", name), |b| {
            b.iter(|| run_table(black_box(&table), &options))
        });
        let ticked = self::point(duty, Some(CLOCK_HZ));
        let Timing::Ticks(plan) = ticked.timing else {
            unreachable!("a clock gives a tick plan")
        };
        let options = fixed(&ticked, EXACT_CYCLES);
        group.bench_function(BenchmarkId::new("ticks_1MHz", name), |b| {
            b.iter(|| {
                run_segments(
                    scheduler_segments(black_box(plan)),
                    &ticked.contact,
                    &options,
                )
            })
        });
    }
    group.finish();
}

fn fixed_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("fixed_step_T_over_20000");
    group.throughput(Throughput::Elements(FIXED_CYCLES));
    group.sample_size(10);
    for (name, duty) in CASES {
        let point = point(duty, None);
        let segments = exact_cycle(&point.waveform);
        group.bench_function(name, |b| {
            b.iter(|| {
                run_fixed_step(
                    black_box(&segments),
                    &point.contact,
                    FIXED_STEPS_PER_CYCLE,
                    FIXED_CYCLES,
                )
            })
        });
    }
    group.finish();
}

/// Fig. 9: a_max = 100, 150, 200 m/s² × 50 duties in (0.5, 0.98), each to steady state, on rayon's
/// pool (one thread per core).
fn sweep(c: &mut Criterion) {
    let mut group = c.benchmark_group("fig9_sweep");
    group.sample_size(10);
    let contact = Contact::new(MU, MU, STANDARD_GRAVITY_MPS2, MASS_KG, 0.0).unwrap();
    let duties = figures::duty_grid(0.5, 0.98, 50);
    for (name, clock_hz) in [("exact", None), ("ticks_1MHz", Some(CLOCK_HZ))] {
        group.bench_function(name, |b| {
            b.iter(|| {
                figures::sweep(
                    1.0 / FREQ_HZ,
                    &[100.0, 150.0, 200.0],
                    black_box(&duties),
                    &contact,
                    clock_hz,
                    &|| {},
                )
                .unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, exact, fixed_step, sweep);
criterion_main!(benches);
