//! The motion-safe identifier's estimator per sample, every arrangement side by side in one
//! run (`cargo bench -p fog-core --bench preset`): host time per sample, so the arrangements'
//! costs can be compared as ratios; the on-target figure is instructions per sample under
//! QEMU (`bash scripts/fw-budget.sh`).
//!
//! Input: 60 s at 100 Hz of an E-Core-like rate (3 deg/h bias, the sensor's white noise),
//! still for 30 s, then a 12 deg/s turn of 10 s and a slow 0.05 deg/s^2 ramp: the detector
//! calls still, fails windows and rolls back, so every arrangement's paths run; the
//! temperature rises 1 deg C per minute (the thermal state's path). The estimator restarts
//! at each pass (a pass is the same work).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use fog_core::motion::{MotionConfig, MotionModel};
use fog_core::preset::{Arrangement, PresetEstimator, SecondState};
use fog_core::still::SensorConfig;
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

/// Temperature of sample `k`, deg C: 25 rising 1 deg C per minute.
fn temp_c(k: usize) -> f32 {
    25.0 + k as f32 / 6000.0
}

fn arrangements(c: &mut Criterion) {
    let x = rate();
    let mut model = MotionModel::standard(1800.0).expect("valid");
    for (i, w) in model.weights.iter_mut().enumerate() {
        *w = 1e-4 * (i as f32 - 7.0);
    }
    let cfg = MotionConfig::for_sensor(S);
    let thermal = SecondState::THERMAL;
    let bank = SecondState {
        sigma: 1.5 / 3600.0,
        tau_s: 10_000.0,
    };
    let mut g = c.benchmark_group("preset_push_per_sample");
    g.throughput(Throughput::Elements(x.len() as u64));
    for (name, a, second) in [
        ("dual_thermal", Arrangement::DualThermal, thermal),
        ("bank_dual", Arrangement::BankDual, bank),
        ("bank_guarded", Arrangement::BankGuarded, bank),
    ] {
        let mut est = PresetEstimator::new(model, cfg, a, second).expect("valid");
        // The input exercises both calls: still at rest, moving in the turn.
        let calls: Vec<bool> = x
            .iter()
            .enumerate()
            .map(|(k, &r)| est.push(r, temp_c(k), None).is_ok_and(|o| o.still))
            .collect();
        assert!(
            calls[1000..3000].iter().filter(|c| **c).count() > 1500,
            "{name}: still at rest"
        );
        assert!(
            calls[3100..4000].iter().all(|c| !c),
            "{name}: moving in the turn"
        );
        g.bench_function(name, |b| {
            b.iter(|| {
                est.restart();
                for (k, &r) in x.iter().enumerate() {
                    let _ = black_box(est.push(black_box(r), temp_c(k), None));
                }
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = arrangements
}
criterion_main!(benches);
