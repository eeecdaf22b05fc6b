//! `ResumableDenoiser` against `BlockDenoiser`: every output bit, every threshold, every
//! refusal, on random and adversarial blocks, several configurations and block lengths
//! 16..=4096; the work bound (no block ever finished late) and the delays.

use fog_core::denoise::{
    BlockDenoiser, DenoiseConfig, DenoiseError, Push, ResumableDenoiser, Thresholds, MAX_ABS_INPUT,
};
use fog_core::{Sigma, ThresholdRule};
use proptest::prelude::*;

/// Deterministic LCG in [-0.5, 0.5).
struct Lcg(u32);

impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (self.0 >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    }
}

/// Blocks of every kind, back to back: each kind fills whole blocks of `b` samples.
fn adversarial_stream(b: usize, seed: u32) -> Vec<f32> {
    let mut r = Lcg(seed);
    let mut out = Vec::new();
    let kinds = 12;
    for kind in 0..kinds {
        for i in 0..b {
            let u = r.next();
            out.push(match kind {
                // Noise on a slow sine with a bias (a gyro).
                0 => 15.0 + (i as f32 * 0.02).sin() + 0.3 * u,
                1 => 0.0,
                2 => 0.25,
                3 => -123.456,
                // Huge values, alternating signs, at the accepted limit.
                4 => {
                    if i % 2 == 0 {
                        MAX_ABS_INPUT
                    } else {
                        -MAX_ABS_INPUT
                    }
                }
                5 => MAX_ABS_INPUT * u,
                6 => {
                    if i % 2 == 0 {
                        1.0
                    } else {
                        -1.0
                    }
                }
                // Quantized (many ties at the median), a spike, tiny values, signed zeros.
                7 => (u * 8.0).round() * 0.125,
                8 => {
                    if i == b / 3 {
                        1.0e6
                    } else {
                        0.001 * u
                    }
                }
                9 => 1.0e-30 * u,
                10 => {
                    if u < 0.0 {
                        -0.0
                    } else {
                        0.0
                    }
                }
                // A step in the middle of white noise.
                _ => u + if i < b / 2 { 0.0 } else { 50.0 },
            });
        }
    }
    out
}

/// The configurations tested for a block length `b` (levels up to the length's maximum).
fn configs(b: usize) -> Vec<DenoiseConfig> {
    let max = fog_core::db4::max_levels(b).min(5);
    let mut v = Vec::new();
    for levels in 1..=max {
        for rule in [ThresholdRule::Soft, ThresholdRule::Hard] {
            for sigma in [Sigma::FinestMad, Sigma::PerLevelMad, Sigma::Fixed(0.2)] {
                v.push(DenoiseConfig {
                    levels,
                    rule,
                    sigma,
                });
            }
        }
    }
    v
}

fn same_thresholds(a: &Thresholds, b: &Thresholds) -> bool {
    a.levels == b.levels
        && a.sigma
            .iter()
            .zip(&b.sigma)
            .all(|(x, y)| x.to_bits() == y.to_bits())
        && a.mu
            .iter()
            .zip(&b.mu)
            .all(|(x, y)| x.to_bits() == y.to_bits())
}

/// Pushes `stream` into both denoisers and checks every output bit: the per-sample output
/// (`2B` later), the whole blocks (one block later), the thresholds, the refusals.
fn compare<const B: usize>(cfg: DenoiseConfig, stream: &[f32]) {
    let mut block = BlockDenoiser::<B>::new(cfg).expect("valid config");
    let mut res = ResumableDenoiser::<B>::new(cfg).expect("valid config");
    let mut want: Vec<f32> = Vec::new();
    let mut want_thr: Vec<Thresholds> = Vec::new();
    let mut got: Vec<f32> = Vec::new();
    let mut got_blocks: Vec<f32> = Vec::new();
    let mut accepted = 0usize;
    for &x in stream {
        let a = block.push(x);
        let r = res.push(x);
        match (a, r) {
            (Err(e1), Err(e2)) => assert_eq!(e1, e2),
            (Ok(p), Ok(out)) => {
                accepted += 1;
                if let Push::Block(b, t) = p {
                    want.extend_from_slice(b);
                    want_thr.push(t);
                }
                if accepted > 2 * B {
                    got.push(out.expect("an output from sample 2B on"));
                } else {
                    assert_eq!(out, None, "no output before 2B samples");
                }
                if let Some((b, t)) = res.denoised_block() {
                    let j = got_blocks.len() / B;
                    assert!(same_thresholds(t, &want_thr[j]), "{cfg:?} block {j}");
                    got_blocks.extend_from_slice(b);
                }
            }
            (a, r) => panic!("refusals differ: {a:?} vs {r:?}"),
        }
    }
    assert_eq!(
        res.late_finishes(),
        0,
        "{cfg:?} B {B}: a block finished late"
    );
    assert_eq!(got_blocks.len(), want.len().saturating_sub(B));
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(
            g.to_bits(),
            w.to_bits(),
            "{cfg:?} B {B} sample {i}: {g} vs {w}"
        );
    }
    for (i, (g, w)) in got_blocks.iter().zip(&want).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "{cfg:?} B {B} block sample {i}");
    }
    assert_eq!(got.len(), accepted.saturating_sub(2 * B));
}

fn all_configs<const B: usize>(seed: u32) {
    let stream = adversarial_stream(B, seed);
    for cfg in configs(B) {
        compare::<B>(cfg, &stream);
    }
}

#[test]
fn bit_identical_to_block_denoiser_16_to_512() {
    all_configs::<16>(1);
    all_configs::<32>(2);
    all_configs::<64>(3);
    all_configs::<128>(4);
    all_configs::<256>(5);
    all_configs::<512>(6);
}

#[test]
fn bit_identical_to_block_denoiser_1024_to_4096() {
    // The paper's configuration and the per-level one at the longest blocks.
    for b in [1024usize, 2048, 4096] {
        let cfgs = [
            DenoiseConfig::PAPER,
            DenoiseConfig {
                levels: 5,
                rule: ThresholdRule::Hard,
                sigma: Sigma::PerLevelMad,
            },
        ];
        for cfg in cfgs {
            match b {
                1024 => compare::<1024>(cfg, &adversarial_stream(b, 7)),
                2048 => compare::<2048>(cfg, &adversarial_stream(b, 8)),
                _ => compare::<4096>(cfg, &adversarial_stream(b, 9)),
            }
        }
    }
}

#[test]
fn refusals_are_counted_and_change_nothing() {
    let mut stream = adversarial_stream(64, 11);
    for (i, bad) in [f32::NAN, f32::INFINITY, -f32::INFINITY, 2.0e30, -1.5e30]
        .into_iter()
        .enumerate()
    {
        stream.insert(17 + 100 * i, bad);
    }
    compare::<64>(DenoiseConfig::PAPER, &stream);
    let mut res = ResumableDenoiser::<64>::new(DenoiseConfig::PAPER).expect("valid");
    assert_eq!(res.push(f32::NAN), Err(DenoiseError::NonFinite));
    assert_eq!(res.push(f32::NEG_INFINITY), Err(DenoiseError::NonFinite));
    assert_eq!(res.push(1.0e31), Err(DenoiseError::OutOfRange));
    assert_eq!(res.push(MAX_ABS_INPUT), Ok(None));
    let r = res.refused();
    assert_eq!((r.non_finite, r.out_of_range), (2, 1));
    assert_eq!(res.filled(), 1);
}

#[test]
fn bad_configs_are_refused_as_by_block_denoiser() {
    for cfg in [
        DenoiseConfig {
            levels: 4,
            ..DenoiseConfig::PAPER
        },
        DenoiseConfig {
            levels: 0,
            ..DenoiseConfig::PAPER
        },
        DenoiseConfig {
            sigma: Sigma::Fixed(f32::NAN),
            ..DenoiseConfig::PAPER
        },
    ] {
        assert_eq!(
            ResumableDenoiser::<64>::new(cfg).err(),
            BlockDenoiser::<64>::new(cfg).err()
        );
    }
}

#[test]
fn work_is_spread_and_bounded() {
    let mut res = ResumableDenoiser::<512>::new(DenoiseConfig::PAPER).expect("valid");
    // Worst case of the paper's configuration at 512: 11,242 units over 511 pushes.
    assert_eq!(res.units_per_push(), 22);
    let stream = adversarial_stream(512, 3);
    let mut busy_after_completion = 0;
    for (k, &x) in stream.iter().enumerate() {
        res.push(x).expect("accepted");
        if k % 512 == 511 && res.busy() {
            busy_after_completion += 1;
        }
    }
    // The completing push starts the next block's transform and cannot finish it.
    assert_eq!(busy_after_completion, stream.len() / 512);
    assert_eq!(res.late_finishes(), 0);
}

#[test]
fn reset_starts_over() {
    let stream = adversarial_stream(64, 5);
    let mut res = ResumableDenoiser::<64>::new(DenoiseConfig::PAPER).expect("valid");
    for &x in &stream[..150] {
        res.push(x).expect("accepted");
    }
    res.reset();
    assert!(!res.busy());
    assert_eq!(res.filled(), 0);
    let mut fresh = ResumableDenoiser::<64>::new(DenoiseConfig::PAPER).expect("valid");
    for &x in &stream {
        let a = res.push(x).expect("accepted");
        let b = fresh.push(x).expect("accepted");
        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn proptest_bit_identical(
        samples in prop::collection::vec(
            prop_oneof![
                4 => -1.0e3f32..1.0e3,
                1 => Just(0.0f32),
                1 => Just(-0.0f32),
                1 => -1.0e30f32..1.0e30,
                1 => Just(f32::NAN),
                1 => Just(3.0e30f32),
            ],
            64..400,
        ),
        levels in 1u32..=3,
        hard in any::<bool>(),
        sigma_kind in 0u8..3,
    ) {
        let cfg = DenoiseConfig {
            levels,
            rule: if hard { ThresholdRule::Hard } else { ThresholdRule::Soft },
            sigma: match sigma_kind {
                0 => Sigma::FinestMad,
                1 => Sigma::PerLevelMad,
                _ => Sigma::Fixed(1.5),
            },
        };
        compare::<64>(cfg, &samples);
    }
}

#[test]
fn memory_is_three_blocks_plus_state() {
    let size = core::mem::size_of::<ResumableDenoiser<512>>();
    let blocks = 3 * 512 * 4;
    println!("ResumableDenoiser<512>: {size} bytes ({blocks} of blocks)");
    // State beyond the three blocks: the job (radix counts, thresholds) and the output's
    // thresholds; at most 1 KiB on a 64-bit host (less on a 32-bit target).
    assert!(size >= blocks && size - blocks <= 1024, "{size}");
}
