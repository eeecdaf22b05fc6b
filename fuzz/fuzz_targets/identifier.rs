//! Fuzz target: the on-line identifier (`fog_core::identify`) fed arbitrary f32 sequences.
//!
//! Input: byte 0 picks the configuration, byte 1 the sample encoding, the rest are samples of
//! 4 bytes: raw f32 bits (NaN, infinities, subnormals, 1e38 all reachable) or, for encoding 1,
//! an i16 of E-Core counts times 60/32768 deg/s (realistic rates) with the other two bytes
//! as a repeat count (1..=256), so that long constant runs (stuck values) are cheap to reach.
//!
//! Configurations: 0 = the firmware's improved identifier (`presets::level_trend`, B = 512);
//! 1 = the same with B = 64 (more blocks per input); 2 = the paper's identifier, lambda =
//! 0.63, sequential guarded DRLS (`DrlsConfig::PAPER_GUARDED`), B = 64. The paper's unguarded
//! eq. (15) (`DrlsConfig::PAPER`) diverges by design (docs/identify.md) and is not fuzzed.
//!
//! Invariants checked after every sample:
//! - a refused sample (non-finite or |x| > `MAX_ABS_INPUT`) returns an error, is counted in
//!   `rejected` and changes neither the weights nor `U`; accepted + refused = samples given;
//! - an accepted sample gives a finite drift and compensated rate, and a finite training
//!   error whenever a training step was made (no NaN or infinity out of finite input);
//! - state bounded: every weight finite with `|w| <= w_max`; every `U_a` finite in
//!   `[0, u_max]`.
#![no_main]

use fog_core::denoise::MAX_ABS_INPUT;
use fog_core::features::FeatureMap;
use fog_core::identify::{presets, Identifier, IdentifyError};
use fog_core::train::{Drls, DrlsConfig};
use fog_core::wnn::Activation;
use libfuzzer_sys::fuzz_target;

const SAMPLE_PERIOD_S: f32 = 0.01;
const LSB_DPS: f32 = 60.0 / 32768.0;

fn samples(encoding: u8, data: &[u8]) -> Vec<f32> {
    let mut out = Vec::new();
    for c in data.chunks_exact(4) {
        let b = [c[0], c[1], c[2], c[3]];
        if encoding.is_multiple_of(2) {
            out.push(f32::from_le_bytes(b));
        } else {
            let x = f32::from(i16::from_le_bytes([b[0], b[1]])) * LSB_DPS;
            let repeat = usize::from(u16::from_le_bytes([b[2], b[3]]) % 256) + 1;
            out.extend(std::iter::repeat_n(x, repeat));
        }
    }
    out
}

fn run<F: FeatureMap<N>, const N: usize, const L: usize, const B: usize>(
    mut id: Identifier<F, Drls<L>, N, L, B>,
    xs: &[f32],
) {
    let cfg = *id.trainer().config();
    for (k, &x) in xs.iter().enumerate() {
        let w_before = *id.weights();
        let u_before = id.trainer().u();
        let stats_before = *id.stats();
        let r = id.push(x);
        let st = *id.stats();
        let acceptable = x.is_finite() && x.abs() <= MAX_ABS_INPUT;
        match r {
            Ok(est) => {
                assert!(acceptable, "sample {k} = {x:e} accepted");
                assert!(
                    est.drift_dps.is_finite(),
                    "sample {k} = {x:e}: drift {est:?}"
                );
                assert!(
                    est.compensated_dps.is_finite(),
                    "sample {k} = {x:e}: {est:?}"
                );
                if st.trained != stats_before.trained {
                    assert!(
                        est.train_error_dps.is_finite(),
                        "sample {k} = {x:e}: training error {est:?}"
                    );
                }
                assert_eq!(st.samples, stats_before.samples.wrapping_add(1));
            }
            Err(e) => {
                assert!(!acceptable, "sample {k} = {x:e} refused: {e:?}");
                assert!(matches!(e, IdentifyError::Denoise(_)), "{e:?}");
                assert_eq!(st.rejected, stats_before.rejected + 1);
                assert_eq!(st.samples, stats_before.samples);
                assert_eq!(
                    id.weights(),
                    &w_before,
                    "refused sample changed the weights"
                );
                assert_eq!(id.trainer().u(), u_before, "refused sample changed U");
            }
        }
        for (a, w) in id.weights().iter().enumerate() {
            assert!(
                w.is_finite() && w.abs() <= cfg.w_max,
                "sample {k}: w[{a}] = {w:e}"
            );
        }
        for (a, u) in id.trainer().u().iter().enumerate() {
            assert!(
                u.is_finite() && *u >= 0.0 && *u <= cfg.u_max,
                "sample {k}: U[{a}] = {u:e}"
            );
        }
    }
    let st = id.stats();
    assert_eq!(st.samples as usize + st.rejected as usize, xs.len());
}

fuzz_target!(|data: &[u8]| {
    let [config, encoding, rest @ ..] = data else {
        return;
    };
    let xs = samples(*encoding, rest);
    match config % 3 {
        0 => match presets::level_trend::<512>(presets::LEVEL_TREND_SCALING, SAMPLE_PERIOD_S) {
            Ok(id) => run(id, &xs),
            Err(e) => panic!("{e}"),
        },
        1 => match presets::level_trend::<64>(presets::LEVEL_TREND_SCALING, SAMPLE_PERIOD_S) {
            Ok(id) => run(id, &xs),
            Err(e) => panic!("{e}"),
        },
        _ => {
            let Some(t) = Drls::<{ presets::L }>::new(DrlsConfig::PAPER_GUARDED) else {
                panic!("PAPER_GUARDED refused");
            };
            match presets::paper_with::<_, 64, { presets::L }>(
                Activation::MexicanHat,
                presets::PAPER_SCALING,
                t,
                fog_core::denoise::DenoiseConfig::PAPER,
                SAMPLE_PERIOD_S,
            ) {
                Ok(id) => run(id, &xs),
                Err(e) => panic!("{e}"),
            }
        }
    }
});
