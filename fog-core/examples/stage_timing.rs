//! Rough per-stage timing of the denoiser on 2^20 samples (development aid; the numbers
//! that count come from `cargo bench -p fog-core --bench denoise`).
use fog_core::db4;
use fog_core::denoise::{denoise_in_place, DenoiseConfig};
use fog_core::threshold;
use std::time::Instant;

fn main() {
    let n = 1usize << 20;
    let mut state = 1u32;
    let x0: Vec<f32> = (0..n)
        .map(|i| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            0.05 * (i as f32 * 1e-3).sin() + 0.02 * ((state >> 8) as f32 / 16_777_216.0 - 0.5)
        })
        .collect();
    let mut x = x0.clone();
    let mut s = vec![0.0f32; n];
    let reps = 20;
    let time = |name: &str, f: &mut dyn FnMut()| {
        let t = Instant::now();
        for _ in 0..reps {
            f();
        }
        println!(
            "{name:>10}: {:8.3} ms",
            t.elapsed().as_secs_f64() * 1e3 / reps as f64
        );
    };
    time("copy", &mut || x.copy_from_slice(&x0));
    time("forward", &mut || {
        x.copy_from_slice(&x0);
        db4::forward(&mut x, &mut s, 3).expect("valid");
    });
    time("fwd+inv", &mut || {
        x.copy_from_slice(&x0);
        db4::forward(&mut x, &mut s, 3).expect("valid");
        db4::inverse(&mut x, &mut s, 3).expect("valid");
    });
    x.copy_from_slice(&x0);
    db4::forward(&mut x, &mut s, 3).expect("valid");
    let d1 = x[n / 2..].to_vec();
    time("mad", &mut || {
        std::hint::black_box(threshold::mad_sigma(&d1, &mut s, 1e-7));
    });
    time("denoise", &mut || {
        x.copy_from_slice(&x0);
        denoise_in_place(&mut x, &mut s, &DenoiseConfig::PAPER).expect("valid");
    });
}
