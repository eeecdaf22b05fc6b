//! Numeric soak of the on-line identifier with lambda = 0.63 on adversarial inputs.
//!
//! Two identifiers, both with the paper's forgetting factor lambda = 0.63 and the guarded
//! sequential DRLS (`U <= u_max`, `|w| <= w_max`; the unguarded eq. (15) diverges by design,
//! see `docs/identify.md`):
//! - `paper`: the paper's network, inputs `[X, T]`, Mexican-hat neurons,
//!   `DrlsConfig::PAPER_GUARDED`, B = 512;
//! - `level-trend@0.63`: the firmware's improved network (bias, link, Gaussians), every
//!   neuron at lambda = 0.63, `U(0) = 1`, B = 512.
//!
//! The input cycles through phases, each `n / 40` samples, 100 Hz time stamps: constant bias
//! 0.012 deg/s; constant +60 deg/s (full scale, stuck at the rail); alternating +-60 deg/s
//! every sample; silence (exact 0.0); a +-60 deg/s square wave of 256-sample half periods;
//! E-Core-like noise (bias + 0.015 deg/s white, quantised); constant -60 deg/s; tiny values
//! (+-1e-30). Time runs on for the whole soak (T leaves its scaled range after 1800 s:
//! adversarial too).
//!
//! Checked at every sample: outputs and the training error finite, every weight finite with
//! `|w| <= w_max`, every `U_a` finite in `[0, u_max]`. The extremes reached are printed.
//!
//! CI runs 10^6 samples per identifier (`soak_short`). The 10^8-sample soak is ignored by
//! default:
//! `cargo test --release -p fog-core --test identifier_soak -- --ignored --nocapture`
//! (figures in docs/reliability.md).

use fog_core::denoise::DenoiseConfig;
use fog_core::identify::presets;
use fog_core::train::{Drls, DrlsConfig, DrlsMode};
use fog_core::wnn::Activation;

const PERIOD_S: f32 = 0.01;
const FULL_SCALE_DPS: f32 = 60.0;
const LSB_DPS: f32 = FULL_SCALE_DPS / 32768.0;
const PHASES: usize = 8;

/// Sample `i` of phase `phase` (see the module docs); `rng` is an xorshift state.
fn input(phase: usize, i: usize, rng: &mut u64) -> f32 {
    match phase {
        0 => 0.012,
        1 => FULL_SCALE_DPS,
        2 => {
            if i.is_multiple_of(2) {
                FULL_SCALE_DPS
            } else {
                -FULL_SCALE_DPS
            }
        }
        3 => 0.0,
        4 => {
            if (i / 256).is_multiple_of(2) {
                FULL_SCALE_DPS
            } else {
                -FULL_SCALE_DPS
            }
        }
        5 => {
            // Sum of 4 uniforms: roughly normal, sigma 0.015 deg/s.
            let mut u = 0.0f32;
            for _ in 0..4 {
                *rng ^= *rng << 13;
                *rng ^= *rng >> 7;
                *rng ^= *rng << 17;
                u += (*rng >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
            }
            let x = 0.012 + 0.015 * u * 3.0f32.sqrt();
            (x / LSB_DPS).round() * LSB_DPS
        }
        6 => -FULL_SCALE_DPS,
        _ => {
            if i.is_multiple_of(2) {
                1e-30
            } else {
                -1e-30
            }
        }
    }
}

/// Extremes reached over a soak.
#[derive(Debug, Default)]
struct Extremes {
    samples: u64,
    max_abs_w: f32,
    max_u: f32,
    min_u: f32,
    zero_u_samples: u64,
    max_abs_drift_dps: f32,
    max_abs_train_error_dps: f32,
    weight_saturations: u32,
}

fn soak_one<F, const N: usize, const B: usize>(
    name: &str,
    mut id: fog_core::identify::Identifier<F, Drls<{ presets::L }>, N, { presets::L }, B>,
    n: usize,
) -> Extremes
where
    F: fog_core::features::FeatureMap<N>,
{
    let cfg = *id.trainer().config();
    let phase_len = (n / (5 * PHASES)).max(1);
    let mut rng = 0x9E37_79B9_7F4A_7C15u64;
    let mut ex = Extremes {
        min_u: f32::INFINITY,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    for k in 0..n {
        let phase = (k / phase_len) % PHASES;
        let x = input(phase, k % phase_len, &mut rng);
        let e = match id.push(x) {
            Ok(e) => e,
            Err(err) => panic!("{name}: sample {k} = {x} refused: {err}"),
        };
        assert!(
            e.drift_dps.is_finite() && e.compensated_dps.is_finite(),
            "{name}: sample {k} (phase {phase}): {e:?}"
        );
        if id.stats().trained > 0 && !e.train_error_dps.is_nan() {
            assert!(e.train_error_dps.is_finite(), "{name}: sample {k}: {e:?}");
            ex.max_abs_train_error_dps = ex.max_abs_train_error_dps.max(e.train_error_dps.abs());
        }
        ex.max_abs_drift_dps = ex.max_abs_drift_dps.max(e.drift_dps.abs());
        for &w in id.weights() {
            assert!(
                w.is_finite() && w.abs() <= cfg.w_max,
                "{name}: sample {k}: w {w:e}"
            );
            ex.max_abs_w = ex.max_abs_w.max(w.abs());
        }
        let mut any_zero = false;
        for u in id.trainer().u() {
            assert!(
                u.is_finite() && (0.0..=cfg.u_max).contains(&u),
                "{name}: sample {k}: U {u:e}"
            );
            ex.max_u = ex.max_u.max(u);
            ex.min_u = ex.min_u.min(u);
            any_zero |= u == 0.0;
        }
        ex.zero_u_samples += u64::from(any_zero);
    }
    ex.samples = n as u64;
    ex.weight_saturations = id.trainer().weight_saturations;
    let secs = t0.elapsed().as_secs_f64();
    eprintln!(
        "soak {name}: {n} samples in {secs:.1} s ({:.0} samples/s); max|w| {:.4e} (w_max {:e}), \
         U in [{:.4e}, {:.4e}] (u_max {:e}), samples with some U = 0: {}, max|drift| {:.4e} deg/s, \
         max|train error| {:.4e} deg/s, weight saturations {}",
        n as f64 / secs,
        ex.max_abs_w,
        cfg.w_max,
        ex.min_u,
        ex.max_u,
        cfg.u_max,
        ex.zero_u_samples,
        ex.max_abs_drift_dps,
        ex.max_abs_train_error_dps,
        ex.weight_saturations
    );
    ex
}

fn soak(n: usize) -> (Extremes, Extremes) {
    let paper = std::thread::spawn(move || {
        let id = presets::paper::<512>(
            Activation::MexicanHat,
            presets::PAPER_SCALING,
            DrlsConfig::PAPER_GUARDED,
            PERIOD_S,
        )
        .expect("valid paper identifier");
        soak_one("paper (PAPER_GUARDED, lambda 0.63)", id, n)
    });
    let lt = std::thread::spawn(move || {
        let cfg = DrlsConfig {
            lambda: 0.63,
            u0: 1.0,
            u_max: 1.0,
            w_max: 1.0e4,
            mode: DrlsMode::Sequential,
            form: presets::LEVEL_TREND_DRLS.form,
        };
        let t = Drls::new(cfg).expect("valid DRLS");
        let id = presets::level_trend_with::<_, 512, { presets::L }>(
            presets::LEVEL_TREND_SCALING,
            t,
            DenoiseConfig::PAPER,
            PERIOD_S,
        )
        .expect("valid level-trend identifier");
        soak_one("level-trend (lambda 0.63)", id, n)
    });
    (
        paper.join().expect("paper soak"),
        lt.join().expect("level-trend soak"),
    )
}

/// 10^6 samples per identifier (every phase 5 times, 25 000 samples each): runs in CI.
#[test]
fn soak_short() {
    let (p, l) = soak(1_000_000);
    assert_eq!(p.samples + l.samples, 2_000_000);
}

/// 10^8 samples per identifier (every phase 5 times, 2.5 million samples each).
#[test]
#[ignore = "about 10 minutes; run with --release -- --ignored (docs/reliability.md)"]
fn soak_1e8() {
    let (p, l) = soak(100_000_000);
    assert_eq!(p.samples + l.samples, 200_000_000);
}
