//! Block denoising spread over the samples: [`ResumableDenoiser`].
//!
//! The same computation as [`denoise_in_place`](super::denoise_in_place) (mean removed,
//! `levels` db4 lifting levels, MAD sigma, universal threshold, shrink, inverse, mean added
//! back), bit for bit, but cut into bounded slices: while block `j + 1` fills, each push
//! performs a fixed number of *work units* of block `j`'s transform.
//!
//! # Why the bits are the same
//! Every value goes through the same f32 operations, in the same order, as in
//! `denoise_in_place`; only the memory layout and the order *between independent values*
//! differ:
//! - the block mean and peak are accumulated as the samples arrive, in the same eight lanes
//!   (lane `i mod 8` sums `x[i] * (1 / B)` in sample order), added pairwise at the end;
//! - each level's lifting runs step by step (the multi-pass form `db4`'s fused sweep is
//!   tested against) on de-interleaved channels `s = scratch[..H]`, `d = scratch[H..2H]`
//!   with periodic (masked) indices, where the fused sweep uses ghost cells: the ghost cells
//!   hold the same values computed by the same operations. Each step reads one channel and
//!   writes the other, so a step can stop and resume at any index;
//! - the median of the detail magnitudes is the same radix selection as
//!   [`threshold::median`], its histogram and compaction loops resumable at any index (the
//!   compaction writes at `m <= i`);
//! - shrinking is element-wise.
//!
//! The tests in `tests/resumable_denoise.rs` compare every output bit with
//! [`BlockDenoiser`](super::BlockDenoiser) on random and adversarial blocks.

use super::{check_config, DenoiseConfig, DenoiseError, Thresholds, MAX_ABS_INPUT, MAX_LEVELS};
use crate::db4::{add, ld, st, sub, three, two, K_D, K_S, P0, P2, P4, U1, U3};
use crate::threshold::{
    self, from_total_key, total_key, Sigma, ThresholdRule, MAD_TO_SIGMA, ZERO_REL,
};

/// Work units charged for computing one level's threshold (`sqrtf(2 logf(B))`, about 150
/// instructions on a Cortex-M4F, against about 10 per unit of the loops).
const THRESHOLD_UNITS: usize = 16;

/// Work units charged for choosing a radix pass's digit (a scan of the 16 counts).
const DIGIT_UNITS: usize = 6;

/// Radix passes of the median selection (4 bits of a 32-bit key each).
const RADIX_PASSES: u32 = 8;

/// Where the transform of the pending block stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// Nothing pending.
    Idle,
    /// Forward level: de-interleave `w[..2H]` (minus the offset) into `s | d`.
    FwdSplit,
    /// Forward level: lifting step `step` (0..5 = steps 1..5) over `n = i..H`.
    FwdLift,
    /// Forward level: scale and rotate `s | d` into `w[..H] = cA`, `w[H..2H] = cD`.
    FwdMerge,
    /// Magnitudes above the zero tolerance of `cD_level` copied to `scratch`.
    MadCopy,
    /// Radix selection: digit histogram of the remaining candidates.
    RadixHist,
    /// Radix selection: candidates with the selected digit compacted to the front.
    RadixCompact,
    /// `cD_level` shrunk in place.
    Shrink,
    /// Inverse level: `cA`, `cD` rescaled and rotated into `s | d`.
    InvSplit,
    /// Inverse level: lifting step undone (`step` 0..5 = steps 5..1).
    InvLift,
    /// Inverse level: `s | d` interleaved back into `w[..2H]` (plus the offset).
    InvMerge,
}

/// The pending block's transform: its stage, position and intermediate values.
#[derive(Debug, Clone, Copy)]
struct Job {
    stage: Stage,
    /// Level of the current stage (1 = finest).
    level: u32,
    /// Lifting step within a level (0..5).
    step: u8,
    /// Next index of the current stage's loop.
    i: usize,
    peak: f32,
    mean: f32,
    /// `peak * sqrt(2)^level`, updated as in `denoise_in_place`.
    level_scale: f32,
    finest_sigma: f32,
    /// `sqrtf(2 logf(B))`, the universal threshold's factor.
    mu_factor: f32,
    zero_tol: f32,
    /// Candidates copied by [`Stage::MadCopy`].
    mad_n: usize,
    /// Radix selection state, as in [`threshold::median`].
    len: usize,
    rank: usize,
    below: usize,
    below_max: u32,
    pass: u32,
    digit: u32,
    m: usize,
    hist: [usize; 16],
    thr: Thresholds,
}

impl Job {
    const IDLE: Self = Self {
        stage: Stage::Idle,
        level: 0,
        step: 0,
        i: 0,
        peak: 0.0,
        mean: 0.0,
        level_scale: 0.0,
        finest_sigma: 0.0,
        mu_factor: 0.0,
        zero_tol: 0.0,
        mad_n: 0,
        len: 0,
        rank: 0,
        below: 0,
        below_max: 0,
        pass: 0,
        digit: 0,
        m: 0,
        hist: [0; 16],
        thr: Thresholds {
            levels: 0,
            sigma: [0.0; MAX_LEVELS as usize],
            mu: [0.0; MAX_LEVELS as usize],
        },
    };
}

/// Refused samples, by reason (saturating counts).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Refused {
    /// NaN or infinite samples ([`DenoiseError::NonFinite`]).
    pub non_finite: u32,
    /// Samples whose magnitude exceeds [`MAX_ABS_INPUT`] ([`DenoiseError::OutOfRange`]).
    pub out_of_range: u32,
}

/// Block denoiser whose transform is spread over the samples of the next block.
///
/// Blocks of `B` samples (a power of two in `16..=65536`), the same
/// [`DenoiseConfig`] and the same results, bit for bit, as
/// [`BlockDenoiser<B>`](super::BlockDenoiser), but no push does more than
/// [`units_per_push`](Self::units_per_push) work units (one unit is one iteration of a
/// transform, selection or shrink loop, about 10 instructions on a Cortex-M4F).
///
/// # Timing and output
/// Block `j` (samples `jB .. jB + B - 1`) is transformed during the pushes of block `j + 1`,
/// starting with the push that completes block `j`. When block `j + 1` completes, the
/// denoised block `j` is available whole through [`denoised_block`](Self::denoised_block)
/// (until the next push), and then the push of sample `k` of block `j + 2` returns the
/// denoised sample `k - 2B` while storing sample `k` in its place. So:
/// - sample by sample: [`push`](Self::push) returns the denoised value of the sample
///   **`2B` pushes earlier** (`None` for the first `2B` accepted samples);
/// - whole blocks: a block comes out **one block later** than from `BlockDenoiser` (at the
///   completion of the next block).
///
/// Refused samples (NaN, infinite, above [`MAX_ABS_INPUT`]) are not stored, do not advance
/// anything and are counted ([`refused`](Self::refused)), as `BlockDenoiser` refuses them.
///
/// # Memory
/// `3 B` floats (`12 B` bytes: the filling block, the block being transformed, the scratch
/// the lifting and the median selection work in) plus about 0.5 KiB of state. The block
/// being filled also holds the previous denoised block, which it hands out one sample per
/// push as it is overwritten.
///
/// # Work per push
/// Computed at construction from the worst case (the radix selection keeping every
/// candidate through its 8 passes): `ceil(worst_units / (B - 1))`. A typical block finishes
/// early (the selection's candidates shrink after the first passes). Should the work of a
/// block not be done when the next block completes, the completing push finishes it and
/// [`late_finishes`](Self::late_finishes) counts it; the bound makes this impossible, and
/// the tests check the count stays 0.
pub struct ResumableDenoiser<const B: usize> {
    cfg: DenoiseConfig,
    /// Two blocks: one filling (and handing out the previous denoised block), one being
    /// transformed in place.
    bufs: [[f32; B]; 2],
    scratch: [f32; B],
    /// Index in `bufs` of the filling block.
    fill: usize,
    filled: usize,
    /// Peak `|x|` bit pattern and mean lanes of the filling block.
    peak_bits: u32,
    lanes: [f32; 8],
    job: Job,
    /// The transformed buffer holds a block (pending or done).
    have_work: bool,
    /// The filling buffer holds a denoised block not yet handed out.
    out_valid: bool,
    out_thr: Thresholds,
    units: usize,
    /// `sqrtf(2 logf(B))`: `universal_threshold(sigma, B) = sigma * mu_factor`, bit for bit.
    mu_factor: f32,
    refused: Refused,
    late: u32,
}

impl<const B: usize> ResumableDenoiser<B> {
    const SIZE_OK: () = assert!(
        B.is_power_of_two() && B >= 16 && B <= 1 << 16,
        "block length must be a power of two in 16..=65536"
    );

    /// A denoiser for blocks of `B` samples. Fails if `cfg` does not fit `B` (the checks of
    /// `BlockDenoiser::new`).
    pub fn new(cfg: DenoiseConfig) -> Result<Self, DenoiseError> {
        let () = Self::SIZE_OK;
        check_config(B, B, &cfg)?;
        let units = worst_units(B, &cfg).div_ceil(B - 1);
        Ok(Self {
            cfg,
            bufs: [[0.0; B]; 2],
            scratch: [0.0; B],
            fill: 0,
            filled: 0,
            peak_bits: 0,
            lanes: [0.0; 8],
            job: Job::IDLE,
            have_work: false,
            out_valid: false,
            out_thr: Job::IDLE.thr,
            units,
            mu_factor: threshold::universal_threshold(1.0, B),
            refused: Refused::default(),
            late: 0,
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &DenoiseConfig {
        &self.cfg
    }

    /// Work units each push may perform (see the type's docs).
    pub fn units_per_push(&self) -> usize {
        self.units
    }

    /// Samples stored in the current, incomplete block.
    pub fn filled(&self) -> usize {
        self.filled
    }

    /// Samples refused so far, by reason.
    pub fn refused(&self) -> Refused {
        self.refused
    }

    /// Blocks whose transform was not done in time and was finished by the push that
    /// completed the next block (0 by construction; see the type's docs).
    pub fn late_finishes(&self) -> u32 {
        self.late
    }

    /// Whether a block's transform is still in progress.
    pub fn busy(&self) -> bool {
        self.job.stage != Stage::Idle
    }

    /// Forgets everything: the incomplete block, the pending transform and the denoised
    /// block not yet handed out (the next output comes `2B` samples after this call). The
    /// refusal counts are kept.
    pub fn reset(&mut self) {
        self.filled = 0;
        self.peak_bits = 0;
        self.lanes = [0.0; 8];
        self.job.stage = Stage::Idle;
        self.have_work = false;
        self.out_valid = false;
    }

    /// The denoised block handed out from now on and its thresholds: `Some` only between
    /// the push that completed a block and the next push.
    pub fn denoised_block(&self) -> Option<(&[f32; B], &Thresholds)> {
        if self.out_valid && self.filled == 0 {
            self.bufs.get(self.fill).map(|b| (b, &self.out_thr))
        } else {
            None
        }
    }

    /// The thresholds of the denoised block being handed out (`None` before the first).
    pub fn thresholds(&self) -> Option<&Thresholds> {
        self.out_valid.then_some(&self.out_thr)
    }

    /// Stores one sample, performs at most [`units_per_push`](Self::units_per_push) units of
    /// the pending block's transform, and returns the denoised value of the sample pushed
    /// `2B` accepted samples before (`None` while there is none).
    ///
    /// A non-finite sample is refused with [`DenoiseError::NonFinite`], one larger than
    /// [`MAX_ABS_INPUT`] with [`DenoiseError::OutOfRange`]; neither is stored nor advances
    /// the transform, and both are counted.
    pub fn push(&mut self, x: f32) -> Result<Option<f32>, DenoiseError> {
        if !x.is_finite() {
            self.refused.non_finite = self.refused.non_finite.saturating_add(1);
            return Err(DenoiseError::NonFinite);
        }
        if libm::fabsf(x) > MAX_ABS_INPUT {
            self.refused.out_of_range = self.refused.out_of_range.saturating_add(1);
            return Err(DenoiseError::OutOfRange);
        }
        let i = self.filled;
        let mut out = None;
        if let Some(slot) = self.bufs.get_mut(self.fill).and_then(|b| b.get_mut(i)) {
            if self.out_valid {
                out = Some(*slot);
            }
            *slot = x;
        }
        // The same lanes and products as `peak_and_mean`, in sample order.
        self.peak_bits = self.peak_bits.max(x.to_bits() & 0x7fff_ffff);
        if let Some(acc) = self.lanes.get_mut(i % 8) {
            *acc += x * (1.0 / B as f32);
        }
        self.filled += 1;
        if self.filled < B {
            self.run(self.units);
        } else {
            self.complete();
        }
        Ok(out)
    }

    /// The filling block is complete: finish the previous block if needed, hand it out, and
    /// start transforming the new one.
    fn complete(&mut self) {
        if self.job.stage != Stage::Idle {
            self.late = self.late.saturating_add(1);
            self.run(usize::MAX);
        }
        self.out_valid = self.have_work;
        self.out_thr = self.job.thr;
        self.fill ^= 1;
        self.have_work = true;
        let [a, b, c, d, e, f, g, h] = self.lanes;
        let mean = ((a + b) + (c + d)) + ((e + f) + (g + h));
        let peak = f32::from_bits(self.peak_bits);
        self.filled = 0;
        self.peak_bits = 0;
        self.lanes = [0.0; 8];
        self.job = Job {
            stage: Stage::FwdSplit,
            level: 1,
            step: 0,
            i: 0,
            peak,
            mean,
            level_scale: peak,
            mu_factor: self.mu_factor,
            thr: Thresholds {
                levels: self.cfg.levels,
                ..Job::IDLE.thr
            },
            ..Job::IDLE
        };
        self.run(self.units);
    }

    /// Performs up to `budget` units of the pending transform.
    fn run(&mut self, mut budget: usize) {
        let Self {
            cfg,
            bufs,
            scratch,
            fill,
            job,
            ..
        } = self;
        let [b0, b1] = bufs;
        let w: &mut [f32] = if *fill == 0 { b1 } else { b0 };
        let s: &mut [f32] = scratch;
        while budget > 0 && job.stage != Stage::Idle {
            let len = job.stage_len(w.len());
            let k = budget.min(len.saturating_sub(job.i));
            job.work(w, s, cfg, k);
            budget -= k;
            if job.i >= len {
                budget = budget.saturating_sub(job.next(w, s, cfg));
            }
        }
    }
}

impl Job {
    /// Iterations of the current stage's loop, for blocks of `bl` samples.
    fn stage_len(&self, bl: usize) -> usize {
        match self.stage {
            Stage::Idle => 0,
            Stage::RadixHist | Stage::RadixCompact => self.len,
            _ => bl >> self.level,
        }
    }

    /// Iterations `i..i + k` of the current stage (`w`: the block, `s`: the scratch).
    fn work(&mut self, w: &mut [f32], s: &mut [f32], cfg: &DenoiseConfig, k: usize) {
        let (lo, hi) = (self.i, self.i + k);
        self.i = hi;
        let h = w.len() >> self.level;
        let offset = if self.level == 1 { self.mean } else { 0.0 };
        match self.stage {
            Stage::Idle => {}
            Stage::FwdSplit => {
                let Some((sv, dv)) = s.split_at_mut_checked(h) else {
                    return;
                };
                let (Some(src), Some(so), Some(dout)) = (
                    w.get(2 * lo..2 * hi),
                    sv.get_mut(lo..hi),
                    dv.get_mut(lo..hi),
                ) else {
                    return;
                };
                for ((pair, e), o) in src.chunks_exact(2).zip(so).zip(dout) {
                    *e = pair[0] - offset;
                    *o = pair[1] - offset;
                }
            }
            Stage::FwdLift => lift(s, h, self.step, false, lo, hi),
            Stage::FwdMerge => {
                let Some((sv, dv)) = s.split_at_checked(h) else {
                    return;
                };
                // cA[n] = K_S s[n - 1], cD[n] = K_D d[n + 1] (PyWavelets' alignment).
                let Some((ca, cd)) = w.split_at_mut_checked(h) else {
                    return;
                };
                scale_rotated(ca, sv, K_S, false, lo, hi);
                scale_rotated(cd, dv.get(..h).unwrap_or(&[]), K_D, true, lo, hi);
            }
            Stage::MadCopy => {
                for n in lo..hi {
                    let a = libm::fabsf(ld(w, h + n));
                    if a > self.zero_tol {
                        st(s, self.mad_n, a);
                        self.mad_n += 1;
                    }
                }
            }
            Stage::RadixHist => {
                let shift = 28 - 4 * self.pass;
                for n in lo..hi {
                    let digit = (total_key(ld(s, n)) >> shift) & 15;
                    if let Some(c) = self.hist.get_mut(digit as usize) {
                        *c += 1;
                    }
                }
            }
            Stage::RadixCompact => {
                let shift = 28 - 4 * self.pass;
                for n in lo..hi {
                    let x = ld(s, n);
                    let q = total_key(x);
                    let dq = (q >> shift) & 15;
                    if dq < self.digit {
                        self.below += 1;
                        self.below_max = self.below_max.max(q);
                    } else if dq == self.digit {
                        st(s, self.m, x);
                        self.m += 1;
                    }
                }
            }
            Stage::Shrink => {
                let i = (self.level - 1) as usize;
                let mu = self.thr.mu.get(i).copied().unwrap_or(0.0);
                let Some(detail) = w.get_mut(h + lo..h + hi) else {
                    return;
                };
                match cfg.rule {
                    ThresholdRule::Soft => threshold::shrink_all(detail, mu, ThresholdRule::Soft),
                    ThresholdRule::Hard => threshold::shrink_all(detail, mu, ThresholdRule::Hard),
                }
            }
            Stage::InvSplit => {
                let Some((sv, dv)) = s.split_at_mut_checked(h) else {
                    return;
                };
                // d[n] = K_S cD[n - 1], s[n] = K_D cA[n + 1]: the inverse of the rotation.
                let Some((ca, cd)) = w.get(..2 * h).and_then(|v| v.split_at_checked(h)) else {
                    return;
                };
                scale_rotated(dv, cd, K_S, false, lo, hi);
                scale_rotated(sv, ca, K_D, true, lo, hi);
            }
            Stage::InvLift => lift(s, h, self.step, true, lo, hi),
            Stage::InvMerge => {
                let Some((sv, dv)) = s.split_at_checked(h) else {
                    return;
                };
                let (Some(dst), Some(se), Some(so)) =
                    (w.get_mut(2 * lo..2 * hi), sv.get(lo..hi), dv.get(lo..hi))
                else {
                    return;
                };
                for ((pair, e), o) in dst.chunks_exact_mut(2).zip(se).zip(so) {
                    pair[0] = e + offset;
                    pair[1] = o + offset;
                }
            }
        }
    }

    /// The current stage's loop is done: moves to the next stage and returns the units
    /// that transition costs (at least 1).
    fn next(&mut self, w: &mut [f32], s: &mut [f32], cfg: &DenoiseConfig) -> usize {
        let bl = w.len();
        let _ = bl;
        self.i = 0;
        match self.stage {
            Stage::Idle => {}
            Stage::FwdSplit => {
                self.stage = Stage::FwdLift;
                self.step = 0;
            }
            Stage::FwdLift | Stage::InvLift if self.step < 4 => self.step += 1,
            Stage::FwdLift => self.stage = Stage::FwdMerge,
            Stage::FwdMerge => {
                if self.level < cfg.levels {
                    self.level += 1;
                    self.stage = Stage::FwdSplit;
                } else {
                    self.level = 0;
                    return self.begin_level_threshold(cfg);
                }
            }
            Stage::MadCopy => {
                if self.mad_n == 0 {
                    return self.set_threshold(0.0);
                }
                self.len = self.mad_n;
                self.rank = self.mad_n / 2;
                self.below = 0;
                self.below_max = 0;
                self.pass = 0;
                self.hist = [0; 16];
                self.stage = Stage::RadixHist;
            }
            Stage::RadixHist => {
                self.digit = 0;
                for (d, &c) in (0u32..).zip(&self.hist) {
                    if self.rank < c {
                        self.digit = d;
                        break;
                    }
                    self.rank -= c;
                }
                self.m = 0;
                self.stage = Stage::RadixCompact;
                return DIGIT_UNITS;
            }
            Stage::RadixCompact => {
                self.len = self.m;
                self.pass += 1;
                // One candidate left: the remaining passes would keep it and count nothing
                // below it (its digit always holds rank 0), so they are skipped.
                if self.pass < RADIX_PASSES && self.len > 1 {
                    self.hist = [0; 16];
                    self.stage = Stage::RadixHist;
                    return 2;
                } else {
                    // As `threshold::median`: every remaining candidate has the middle key.
                    let n = self.mad_n;
                    let upper = s.first().copied().unwrap_or(0.0);
                    let median = if n % 2 == 1 {
                        upper
                    } else {
                        let lower_mid = if self.below < n / 2 {
                            upper
                        } else {
                            from_total_key(self.below_max)
                        };
                        0.5 * (lower_mid + upper)
                    };
                    return self.set_threshold(median / MAD_TO_SIGMA);
                }
            }
            Stage::Shrink => {
                if self.level < cfg.levels {
                    return self.begin_level_threshold(cfg);
                }
                self.stage = Stage::InvSplit;
            }
            Stage::InvSplit => {
                self.stage = Stage::InvLift;
                self.step = 0;
            }
            Stage::InvLift => self.stage = Stage::InvMerge,
            Stage::InvMerge => {
                if self.level > 1 {
                    self.level -= 1;
                    self.stage = Stage::InvSplit;
                } else {
                    self.stage = Stage::Idle;
                }
            }
        }
        1
    }

    /// Starts the next level's threshold: its MAD when the configuration estimates one
    /// there, else the threshold from the finest (or fixed) sigma.
    fn begin_level_threshold(&mut self, cfg: &DenoiseConfig) -> usize {
        self.level += 1;
        self.level_scale *= core::f32::consts::SQRT_2;
        let mad = match cfg.sigma {
            Sigma::Fixed(sigma) => {
                self.finest_sigma = sigma;
                false
            }
            Sigma::FinestMad => self.level == 1,
            Sigma::PerLevelMad => true,
        };
        if !mad {
            return self.set_threshold(self.finest_sigma);
        }
        // The tolerances of `denoise_in_place`, with the same roundings.
        self.zero_tol = if self.level == 1 {
            ZERO_REL * self.peak * core::f32::consts::SQRT_2
        } else {
            ZERO_REL * self.level_scale
        };
        self.mad_n = 0;
        self.stage = Stage::MadCopy;
        1
    }

    /// Records the level's sigma and threshold and starts shrinking.
    fn set_threshold(&mut self, sigma: f32) -> usize {
        if self.level == 1 {
            self.finest_sigma = sigma;
        }
        // `universal_threshold(sigma, bl)` is `sigma * sqrtf(2 logf(bl))`: the same product
        // with the factor computed once (`logf` and `sqrtf` are software on a Cortex-M4F).
        let mu = sigma * self.mu_factor;
        let i = (self.level - 1) as usize;
        if let (Some(sg), Some(m)) = (self.thr.sigma.get_mut(i), self.thr.mu.get_mut(i)) {
            (*sg, *m) = (sigma, mu);
        }
        self.stage = Stage::Shrink;
        self.i = 0;
        THRESHOLD_UNITS
    }
}

/// `dst[n] = k * src[(n + 1) mod H]` (`ahead`) or `k * src[(n - 1) mod H]` for
/// `n = lo..hi`, `H = src.len()` a power of two: the one wrapping index masked, the others
/// on shifted sub-slices.
fn scale_rotated(dst: &mut [f32], src: &[f32], k: f32, ahead: bool, lo: usize, hi: usize) {
    let len = src.len();
    let m = len.wrapping_sub(1);
    let (a, b) = if ahead {
        (lo, hi.min(len.saturating_sub(1)))
    } else {
        (lo.max(1), hi)
    };
    let from = |n: usize| if ahead { (n + 1) & m } else { (n + m) & m };
    if a >= b {
        for n in lo..hi {
            st(dst, n, k * ld(src, from(n)));
        }
        return;
    }
    for n in (lo..a).chain(b..hi) {
        st(dst, n, k * ld(src, from(n)));
    }
    let (sa, sb) = if ahead {
        (a + 1, b + 1)
    } else {
        (a - 1, b - 1)
    };
    let (Some(d), Some(v)) = (dst.get_mut(a..b), src.get(sa..sb)) else {
        return;
    };
    for (o, x) in d.iter_mut().zip(v) {
        *o = k * x;
    }
}

/// Lifting step `step` at `n = lo..hi` on `s = sc[..h]`, `d = sc[h..2h]` with periodic
/// indices: forward (`step` 0..5 = steps 1..5 of the `db4` module's table) or inverse
/// (`step` 0..5 undo steps 5..1). The iterations that reach across the ends (within 2 of
/// them) use masked indices; the others run on shifted sub-slices, with no index to check.
fn lift(sc: &mut [f32], h: usize, step: u8, inverse: bool, lo: usize, hi: usize) {
    let Some((s, rest)) = sc.split_at_mut_checked(h) else {
        return;
    };
    let Some(d) = rest.get_mut(..h) else {
        return;
    };
    let (a, b) = (lo.max(2), hi.min(h.saturating_sub(2)));
    if a >= b {
        lift_masked(s, d, step, inverse, lo, hi);
        return;
    }
    lift_masked(s, d, step, inverse, lo, a);
    lift_interior(s, d, step, inverse, a, b);
    lift_masked(s, d, step, inverse, b, hi);
}

/// [`lift`] at `n = lo..hi`, every index masked (`h = s.len()` a power of two).
fn lift_masked(s: &mut [f32], d: &mut [f32], step: u8, inverse: bool, lo: usize, hi: usize) {
    let m = s.len().wrapping_sub(1);
    let p1 = |n: usize| (n + 1) & m;
    let p2 = |n: usize| (n + 2) & m;
    let m1 = |n: usize| (n + m) & m;
    let m2 = |n: usize| (n + m - 1) & m;
    for n in lo..hi {
        match (inverse, step) {
            (false, 0) => add(d, n, P0[0] * ld(s, p1(n))),
            (false, 1) => add(s, n, two(&U1, ld(d, n), ld(d, m1(n)))),
            (false, 2) => add(d, n, two(&P2, ld(s, p2(n)), ld(s, p1(n)))),
            (false, 3) => add(s, n, two(&U3, ld(d, n), ld(d, m1(n)))),
            (false, _) => add(d, n, three(&P4, ld(s, n), ld(s, m1(n)), ld(s, m2(n)))),
            (true, 0) => sub(d, n, three(&P4, ld(s, n), ld(s, m1(n)), ld(s, m2(n)))),
            (true, 1) => sub(s, n, two(&U3, ld(d, n), ld(d, m1(n)))),
            (true, 2) => sub(d, n, two(&P2, ld(s, p2(n)), ld(s, p1(n)))),
            (true, 3) => sub(s, n, two(&U1, ld(d, n), ld(d, m1(n)))),
            (true, _) => sub(d, n, P0[0] * ld(s, p1(n))),
        }
    }
}

/// `v[a + k .. b + k]` (empty if out of range).
fn shifted(v: &[f32], a: usize, b: usize, k: isize) -> &[f32] {
    v.get(a.wrapping_add_signed(k)..b.wrapping_add_signed(k))
        .unwrap_or(&[])
}

/// [`lift`] at `n = a..b` with `2 <= a < b <= h - 2`: no index wraps, so each step is a
/// zip of sub-slices (the same f32 operations as [`lift_masked`]).
fn lift_interior(s: &mut [f32], d: &mut [f32], step: u8, inverse: bool, a: usize, b: usize) {
    let at = |v, k| shifted(v, a, b, k);
    match (inverse, step) {
        (false, 0) | (true, 4) => {
            let src = at(s, 1);
            let Some(dst) = d.get_mut(a..b) else { return };
            if inverse {
                dst.iter_mut().zip(src).for_each(|(o, v)| *o -= P0[0] * v);
            } else {
                dst.iter_mut().zip(src).for_each(|(o, v)| *o += P0[0] * v);
            }
        }
        (false, 1) | (true, 3) | (false, 3) | (true, 1) => {
            let c = if (step == 1) != inverse { &U1 } else { &U3 };
            let (u, v) = (at(d, 0), at(d, -1));
            let Some(dst) = s.get_mut(a..b) else { return };
            let it = dst.iter_mut().zip(u).zip(v);
            if inverse {
                it.for_each(|((o, u), v)| *o -= two(c, *u, *v));
            } else {
                it.for_each(|((o, u), v)| *o += two(c, *u, *v));
            }
        }
        (false, 2) | (true, 2) => {
            let (u, v) = (at(s, 2), at(s, 1));
            let Some(dst) = d.get_mut(a..b) else { return };
            let it = dst.iter_mut().zip(u).zip(v);
            if inverse {
                it.for_each(|((o, u), v)| *o -= two(&P2, *u, *v));
            } else {
                it.for_each(|((o, u), v)| *o += two(&P2, *u, *v));
            }
        }
        _ => {
            let (u, v, w) = (at(s, 0), at(s, -1), at(s, -2));
            let Some(dst) = d.get_mut(a..b) else { return };
            let it = dst.iter_mut().zip(u).zip(v).zip(w);
            if inverse {
                it.for_each(|(((o, u), v), w)| *o -= three(&P4, *u, *v, *w));
            } else {
                it.for_each(|(((o, u), v), w)| *o += three(&P4, *u, *v, *w));
            }
        }
    }
}

/// Work units of one block's transform in the worst case (the radix selection keeping
/// every candidate through its passes), transitions included.
fn worst_units(bl: usize, cfg: &DenoiseConfig) -> usize {
    let levels = cfg.levels.min(MAX_LEVELS);
    let mut units = 0;
    for level in 1..=levels {
        let h = bl >> level;
        // Forward and inverse: split, 5 steps, merge (h each), 7 transitions each.
        units += 2 * (7 * h + 7);
        // Shrink, its threshold and its transition.
        units += h + THRESHOLD_UNITS + 2;
        let mad = match cfg.sigma {
            Sigma::Fixed(_) => false,
            Sigma::FinestMad => level == 1,
            Sigma::PerLevelMad => true,
        };
        if mad {
            units += h + 2 + RADIX_PASSES as usize * (2 * h + DIGIT_UNITS + 2);
        }
    }
    units + 8
}
