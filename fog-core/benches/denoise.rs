//! Denoise throughput: 2^20 samples, 3 levels, soft universal threshold (the paper's
//! configuration), through the same `denoise_in_place` the firmware and host-sim call.
//!
//! Compare with PyWavelets on the same data in the same run:
//! `bash scripts/bench-denoise.sh` runs both and prints the ratio.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use fog_core::denoise::{denoise_in_place, DenoiseConfig};
use std::hint::black_box;

/// Same generator as `scripts/bench_pywt.py`: LCG pseudo-noise plus a slow sine.
pub fn signal(n: usize) -> Vec<f32> {
    let mut state = 1u32;
    (0..n)
        .map(|i| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let u = (state >> 8) as f32 / (1u32 << 24) as f32 - 0.5;
            0.05 * libm::sinf(i as f32 * 1e-3) + 0.02 * u
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("denoise_db4_soft_3lvl");
    for &n in &[1usize << 20, 512] {
        let x0 = signal(n);
        let mut x = x0.clone();
        let mut scratch = vec![0.0f32; n];
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                x.copy_from_slice(&x0);
                black_box(denoise_in_place(
                    black_box(&mut x),
                    &mut scratch,
                    &DenoiseConfig::PAPER,
                ))
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);
