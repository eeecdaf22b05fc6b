//! The drift filter per sample (`cargo bench -p fog-core --bench drift_filter`): host time
//! per sample, for ratios; the on-target figure is instructions per sample under QEMU
//! (`bash scripts/fw-budget.sh`).
//!
//! Input: 60 s at 100 Hz of an E-Core-like rate (3 deg/h bias, the sensor's white noise),
//! still for 30 s, then a 12 deg/s turn of 10 s and a slow 0.05 deg/s^2 ramp: the test calls
//! still, fails windows and undoes updates, so every path runs; the temperature rises 1 deg C
//! per minute. The filter restarts at each pass (a pass is the same work).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use fog_core::drift_filter::{DriftFilter, DriftFilterConfig};
use fog_core::gyro_model::GyroModel;
use fog_core::sensor::SensorConfig;
use std::hint::black_box;

const S: SensorConfig = SensorConfig::ECORE_2000;

fn rate() -> Vec<f32> {
    let mut s = 11u32;
    let sigma = S.sample_var_dps2().sqrt();
    (0..6000)
        .map(|k| {
            // Sum of 12 uniforms - 6: unit variance.
            let mut z = -6.0f32;
            for _ in 0..12 {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                z += (s >> 8) as f32 / 16_777_216.0;
            }
            let t = k as f32 * 0.01;
            let turn = match k {
                3000..4000 => 12.0,
                4500.. => 0.05 * (t - 45.0),
                _ => 0.0,
            };
            3.0 / 3600.0 + turn + sigma * z
        })
        .collect()
}

fn per_sample(c: &mut Criterion) {
    let x = rate();
    let model = GyroModel::for_sensor(&S);
    let mut g = c.benchmark_group("drift_filter");
    g.throughput(Throughput::Elements(x.len() as u64));
    g.bench_function("60 s at 100 Hz", |b| {
        b.iter(|| {
            let mut f = DriftFilter::new(model, DriftFilterConfig::default()).expect("valid");
            let mut acc = 0.0f32;
            for (k, &r) in x.iter().enumerate() {
                let temp = 25.0 + k as f32 / 6000.0;
                if let Ok(o) = f.push(black_box(r), temp, None) {
                    acc += o.drift_dps;
                }
            }
            black_box(acc)
        })
    });
    g.finish();
}

criterion_group!(benches, per_sample);
criterion_main!(benches);
