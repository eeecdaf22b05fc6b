//! Speed of one `host-sim gap` diagnosis (issue goal: an 1800-s record at 100 Hz diagnosed
//! in under 30 s on one core). Each iteration runs the real diagnosis (`gap::diagnose`,
//! single-threaded) on a benchmark record (baseline + a Gauss-Markov term, 180 000 samples
//! with `temp_c` and a reference rate), 12 simulations per model, all 12 candidates:
//! - `with_sim_and_task`: the benchmark baseline given as `--sim`, identification task on
//!   (what `host-sim gap --sim MODEL.toml` does);
//! - `fitted_baseline`: no `--sim` (baseline fitted to the record), task off.
//!
//! `cargo bench -p host-sim --bench gap` (10 samples each: minutes, not run in CI).

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::gap::{self, bench, effects::Effect};
use std::hint::black_box;
use std::time::Duration;

fn diagnosis(c: &mut Criterion) {
    let (rec, time, _) =
        bench::make_record(Some(Effect::Markov), 6007, 1800.0, 100.0).expect("record");
    let base = bench::baseline_model(100.0);
    let mut g = c.benchmark_group("gap_diagnosis_1800s_100hz");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(60))
        .warm_up_time(Duration::from_millis(1));
    let o = gap::Options {
        seeds: 12,
        ..gap::Options::default()
    };
    g.bench_function("with_sim_and_task", |b| {
        b.iter(|| black_box(gap::diagnose(&rec, time.clone(), Some(&base), &o).expect("diagnosis")))
    });
    let o = gap::Options {
        seeds: 12,
        task: false,
        ..gap::Options::default()
    };
    g.bench_function("fitted_baseline", |b| {
        b.iter(|| black_box(gap::diagnose(&rec, time.clone(), None, &o).expect("diagnosis")))
    });
    g.finish();
}

criterion_group!(benches, diagnosis);
criterion_main!(benches);
