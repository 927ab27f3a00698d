//! Cost of one estimator step on the host, fixed point against the f32 (micromath) and f64
//! (libm) references of the same equations (issue 3 item 8), side by side in one run:
//! `cargo bench -p liftfw --bench estimator`. Results and the machine they came from:
//! BENCHMARKS.md. The on-target counterpart (Cortex-M4 instruction counts) is scripts/qemu-test.
//!
//! Each iteration is a whole lift motion of 256 ticks (the same motion for all three), so the
//! filter sees realistic inputs and the branch predictor cannot learn a single point; criterion
//! reports the time per motion (and elements/s), divided by 256 in BENCHMARKS.md. The filter is
//! reset before each motion; configuration (`new`) is measured on its own.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use liftfw::estimator::{Estimator, EstimatorConfig, Measurements};
use liftfw::units::{Amperes, Instant, Kilograms};
use liftfw_ref_float::{EstimatorF32, EstimatorF64, FloatMeasurements};
use std::hint::black_box;

const TICKS: usize = 256;

/// From α ≈ 16° up: 60 ms ramp to 3 rad/s, then cruise; 800 kg, 10 A (qemu/src/main.rs: same).
fn motion() -> Vec<(Instant, Measurements)> {
    (0..TICKS)
        .map(|k| {
            let t = k as i64;
            let milli_counts = if t < 60 {
                1375 * t * t / 120
            } else {
                1375 * 30 + 1375 * (t - 60)
            };
            (
                Instant(1000 * k as u32),
                Measurements {
                    position_counts: 20_000 + (milli_counts / 1000) as i32,
                    motor_current: Amperes::lit("10"),
                    load: Kilograms::lit("800"),
                    commanded_dir: 1,
                },
            )
        })
        .collect()
}

fn estimator_step(c: &mut Criterion) {
    let cfg = EstimatorConfig::DEFAULT;
    let motion = motion();
    let m32: Vec<_> = motion
        .iter()
        .map(|(t, m)| (t.0, FloatMeasurements::<f32>::from_fixed(m)))
        .collect();
    let m64: Vec<_> = motion
        .iter()
        .map(|(t, m)| (t.0, FloatMeasurements::<f64>::from_fixed(m)))
        .collect();

    let mut g = c.benchmark_group("estimator_step_256_ticks");
    g.throughput(Throughput::Elements(TICKS as u64));
    g.bench_function("fixed", |b| {
        let mut e = Estimator::new(&cfg).unwrap();
        b.iter(|| {
            e.reset(motion[0].1.position_counts);
            for (now, m) in &motion {
                black_box(e.step(*now, black_box(m)));
            }
        })
    });
    g.bench_function("f32_micromath", |b| {
        let mut e = EstimatorF32::new(&cfg).unwrap();
        b.iter(|| {
            e.reset(m32[0].1.position_counts);
            for (now, m) in &m32 {
                black_box(e.step(*now, black_box(m)));
            }
        })
    });
    g.bench_function("f64_libm", |b| {
        let mut e = EstimatorF64::new(&cfg).unwrap();
        b.iter(|| {
            e.reset(m64[0].1.position_counts);
            for (now, m) in &m64 {
                black_box(e.step(*now, black_box(m)));
            }
        })
    });
    g.finish();

    // Configuration cost, for scale (it is paid once, not per tick).
    let mut g = c.benchmark_group("estimator_new");
    g.bench_function("fixed", |b| b.iter(|| Estimator::new(black_box(&cfg))));
    g.bench_function("f32_micromath", |b| {
        b.iter(|| EstimatorF32::new(black_box(&cfg)))
    });
    g.bench_function("f64_libm", |b| {
        b.iter(|| EstimatorF64::new(black_box(&cfg)))
    });
    g.finish();
}

criterion_group!(benches, estimator_step);
criterion_main!(benches);
