//! Training-step throughput with L = 30 (issue goal: at least 5 million samples per second
//! on one host core), for every trainer, and the whole identifier per sample.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use fog_core::identify::presets;
use fog_core::train::{
    Drls, DrlsConfig, DrlsForm, DrlsMode, Nlms, NlmsConfig, Rls, RlsConfig, Trainer,
};
use std::hint::black_box;

const L: usize = 30;

fn inputs(n: usize) -> Vec<([f32; L], f32)> {
    let mut s = 1u32;
    let mut u = move || {
        s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (s >> 8) as f32 / 16_777_216.0
    };
    (0..n)
        .map(|_| (std::array::from_fn(|_| u()), u() - 0.5))
        .collect()
}

fn bench_step<T: Trainer<L>>(c: &mut Criterion, name: &str, mut t: T) {
    let data = inputs(1024);
    let mut w = [0.0f32; L];
    let mut g = c.benchmark_group("train_step_L30");
    g.throughput(Throughput::Elements(data.len() as u64));
    g.bench_function(name, |b| {
        b.iter(|| {
            for (h, d) in &data {
                black_box(t.step(&mut w, black_box(h), *d));
            }
        })
    });
    g.finish();
}

fn trainers(c: &mut Criterion) {
    let seq = DrlsConfig {
        lambda: 0.9999,
        u0: 1e-4,
        u_max: 1.0,
        w_max: 1e4,
        mode: DrlsMode::Sequential,
        form: DrlsForm::Gain,
    };
    bench_step(
        c,
        "drls_parallel",
        Drls::<L>::new(DrlsConfig {
            mode: DrlsMode::Parallel,
            ..seq
        })
        .expect("valid"),
    );
    bench_step(c, "drls_sequential", Drls::<L>::new(seq).expect("valid"));
    bench_step(
        c,
        "drls_sequential_energy",
        Drls::<L>::new(DrlsConfig {
            form: DrlsForm::Energy,
            ..seq
        })
        .expect("valid"),
    );
    bench_step(
        c,
        "rls",
        Rls::<L>::new(RlsConfig {
            lambda: 0.9999,
            delta: 1.0,
            trace_max: 1e6,
            w_max: 1e4,
        })
        .expect("valid"),
    );
    bench_step(
        c,
        "nlms",
        Nlms::new(NlmsConfig {
            mu: 0.01,
            eps: 1e-3,
            w_max: 1e4,
        })
        .expect("valid"),
    );
}

fn identifier(c: &mut Criterion) {
    let mut s = 7u32;
    let x: Vec<f32> = (0..4096)
        .map(|_| {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            0.01 * ((s >> 8) as f32 / 16_777_216.0 - 0.5)
        })
        .collect();
    let mut id = presets::level_trend::<512>(presets::LEVEL_TREND_SCALING, 0.01).expect("valid");
    let mut g = c.benchmark_group("identifier_level_trend_L30_B512");
    g.throughput(Throughput::Elements(x.len() as u64));
    g.bench_function("push", |b| {
        b.iter(|| {
            for &r in &x {
                let _ = black_box(id.push(black_box(r)));
            }
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = trainers, identifier
}
criterion_main!(benches);
