//! Property tests: reconstruction and "no panic on any input" for the denoiser.

use fog_core::db4;
use fog_core::denoise::{denoise_in_place, DenoiseConfig};
use fog_core::{BlockDenoiser, Push, Sigma, ThresholdRule};
use proptest::prelude::*;

/// A power-of-two length in 16..=4096 and a valid level count for it.
fn len_and_levels() -> impl Strategy<Value = (usize, u32)> {
    (4u32..=12).prop_flat_map(|m| {
        let n = 1usize << m;
        (Just(n), 1..=db4::max_levels(n))
    })
}

fn signal(n: usize, magnitude: f32) -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(-magnitude..=magnitude, n)
}

fn any_rule() -> impl Strategy<Value = ThresholdRule> {
    prop_oneof![Just(ThresholdRule::Soft), Just(ThresholdRule::Hard)]
}

fn any_sigma() -> impl Strategy<Value = Sigma> {
    prop_oneof![
        Just(Sigma::FinestMad),
        Just(Sigma::PerLevelMad),
        (0.0f32..1e3).prop_map(Sigma::Fixed),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn forward_inverse_reconstructs((n, levels) in len_and_levels(), seed in signal(4096, 1e3)) {
        let x0 = &seed[..n];
        let mut x = x0.to_vec();
        let mut scratch = vec![0.0; n];
        db4::forward(&mut x, &mut scratch, levels).expect("valid");
        db4::inverse(&mut x, &mut scratch, levels).expect("valid");
        let peak = x0.iter().fold(0.0f32, |a, v| a.max(v.abs())).max(f32::MIN_POSITIVE);
        for (a, b) in x.iter().zip(x0) {
            prop_assert!((a - b).abs() <= 2e-6 * peak, "{a} vs {b}, peak {peak}");
        }
    }

    #[test]
    fn transform_preserves_energy((n, levels) in len_and_levels(), seed in signal(4096, 10.0)) {
        // db4 is orthonormal: sum of squares is kept (Parseval).
        let x0 = &seed[..n];
        let mut x = x0.to_vec();
        let mut scratch = vec![0.0; n];
        db4::forward(&mut x, &mut scratch, levels).expect("valid");
        let e0: f64 = x0.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
        let e1: f64 = x.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
        prop_assert!((e0 - e1).abs() <= 1e-5 * e0.max(1e-30));
    }

    #[test]
    fn denoise_never_panics_and_stays_finite(
        (n, levels) in len_and_levels(),
        seed in prop::collection::vec(prop::num::f32::NORMAL | prop::num::f32::ZERO | prop::num::f32::SUBNORMAL, 4096),
        rule in any_rule(),
        sigma in any_sigma(),
    ) {
        // Any finite input: either a finite result or OutOfRange (|x| > 1e30), never NaN.
        let mut x: Vec<f32> = seed[..n].to_vec();
        let mut scratch = vec![0.0; n];
        let cfg = DenoiseConfig { levels, rule, sigma };
        let big = x.iter().any(|v| v.abs() > fog_core::denoise::MAX_ABS_INPUT);
        match denoise_in_place(&mut x, &mut scratch, &cfg) {
            Ok(t) => {
                prop_assert!(!big);
                prop_assert!(x.iter().all(|v| v.is_finite()));
                prop_assert!(t.mu.iter().all(|v| v.is_finite() && *v >= 0.0));
            }
            Err(e) => prop_assert!(big && e == fog_core::DenoiseError::OutOfRange, "{e:?}"),
        }
        // The same data scaled into range always denoises to finite values.
        let mut y: Vec<f32> = seed[..n].iter().map(|v| v * 1e-9).collect();
        let ok = y.iter().all(|v| v.abs() <= fog_core::denoise::MAX_ABS_INPUT);
        if ok {
            denoise_in_place(&mut y, &mut scratch, &cfg).expect("in range");
            prop_assert!(y.iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn denoise_rejects_or_survives_any_bits(bits in prop::collection::vec(any::<u32>(), 64), levels in 0u32..8, s in any::<f32>()) {
        // Arbitrary bit patterns (NaN, infinities, huge) and arbitrary configuration: an error
        // or a result, never a panic.
        let mut x: Vec<f32> = bits.iter().map(|&b| f32::from_bits(b)).collect();
        let mut scratch = vec![0.0; 64];
        for sigma in [Sigma::Fixed(s), Sigma::FinestMad, Sigma::PerLevelMad] {
            let cfg = DenoiseConfig { levels, rule: ThresholdRule::Soft, sigma };
            let _ = denoise_in_place(&mut x, &mut scratch, &cfg);
        }
        let _ = db4::forward(&mut x, &mut scratch[..3], levels);
    }

    #[test]
    fn block_denoiser_equals_one_shot(seed in signal(512, 5.0)) {
        let cfg = DenoiseConfig::PAPER;
        let mut bd = BlockDenoiser::<256>::new(cfg).expect("valid");
        let mut got = Vec::new();
        for &v in &seed {
            if let Push::Block(b, _) = bd.push(v).expect("finite") {
                got.extend_from_slice(b);
            }
        }
        let mut want = seed.clone();
        let mut scratch = vec![0.0; 256];
        for chunk in want.chunks_mut(256) {
            denoise_in_place(chunk, &mut scratch, &cfg).expect("valid");
        }
        prop_assert_eq!(got, want);
    }
}

/// Mixed magnitudes: continuous noise, exact zeros, and quantized values (many ties).
fn mixed_values(len: std::ops::Range<usize>) -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(
        prop_oneof![
            4 => -1.0f32..1.0,
            1 => Just(0.0f32),
            2 => (-8i32..=8).prop_map(|k| k as f32 / 8.0),
        ],
        len,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The bracketed median (inputs of 4096 values or more) gives the bits of a plain sort.
    #[test]
    fn mad_sigma_equals_sorted_median(x in mixed_values(4096..6000), tol in prop_oneof![Just(0.0f32), Just(1e-6), Just(0.1)]) {
        let mut kept: Vec<f32> = x.iter().map(|v| v.abs()).filter(|a| *a > tol).collect();
        kept.sort_by(f32::total_cmp);
        let n = kept.len();
        let median = if n == 0 {
            0.0
        } else if n % 2 == 1 {
            kept[n / 2]
        } else {
            0.5 * (kept[n / 2 - 1] + kept[n / 2])
        };
        let mut work = vec![0.0f32; x.len()];
        if let Some(b) = fog_core::threshold::median_abs_bracketed(&x, &mut work, tol) {
            prop_assert_eq!(b.to_bits(), median.to_bits());
        }
        let sigma = fog_core::threshold::mad_sigma(&x, &mut work, tol);
        prop_assert_eq!(sigma.to_bits(), (median / fog_core::threshold::MAD_TO_SIGMA).to_bits());
    }
}
