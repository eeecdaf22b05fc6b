//! Wavelet denoising of one block (paper section 3), a sample-by-sample block buffer, and
//! the same denoising spread over the samples ([`ResumableDenoiser`]).

use crate::db4::{self, TransformError};
use crate::threshold::{self, Sigma, ThresholdRule, ZERO_REL};

mod resumable;
pub use resumable::{Refused, ResumableDenoiser};

/// Largest sample magnitude accepted: far above any rate a gyro reports, far enough below
/// `f32::MAX` that no intermediate value of the transform (at most a few hundred times the
/// peak) can overflow.
pub const MAX_ABS_INPUT: f32 = 1.0e30;

/// Most levels any configuration may ask for (a 2^16-sample block at 13 levels).
pub const MAX_LEVELS: u32 = 16;

/// Fixed denoiser configuration, kept apart from any per-sample state.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DenoiseConfig {
    /// Decomposition depth; the paper uses 3.
    pub levels: u32,
    /// Shrinkage rule; the paper uses soft (eq. 1).
    pub rule: ThresholdRule,
    /// Noise estimate; see [`Sigma`].
    pub sigma: Sigma,
}

impl DenoiseConfig {
    /// The paper's configuration: 3 levels, soft threshold, sigma from the finest details.
    ///
    /// The paper does not say how sigma is obtained. The finest-level MAD is the standard
    /// estimate for the universal threshold and the right one for the white rate noise
    /// (angle random walk) that dominates a FOG at the sample rate: an orthonormal transform
    /// keeps white noise at the same sigma on every level, and the finest level holds the
    /// least drift, so its estimate is the least biased. [`Sigma::PerLevelMad`] is offered
    /// for coloured noise.
    pub const PAPER: Self = Self {
        levels: 3,
        rule: ThresholdRule::Soft,
        sigma: Sigma::FinestMad,
    };
}

impl Default for DenoiseConfig {
    fn default() -> Self {
        Self::PAPER
    }
}

/// Why a block could not be denoised. The block is left unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DenoiseError {
    /// Length, levels or scratch size refused by the transform.
    Transform(TransformError),
    /// A sample is NaN or infinite.
    NonFinite,
    /// A sample's magnitude exceeds [`MAX_ABS_INPUT`].
    OutOfRange,
    /// `Sigma::Fixed` holds a negative or non-finite value.
    BadSigma,
}

impl From<TransformError> for DenoiseError {
    fn from(e: TransformError) -> Self {
        Self::Transform(e)
    }
}

impl core::fmt::Display for DenoiseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Transform(e) => write!(f, "{e}"),
            Self::NonFinite => f.write_str("sample is NaN or infinite"),
            Self::OutOfRange => f.write_str("sample magnitude exceeds 1e30"),
            Self::BadSigma => f.write_str("fixed sigma must be finite and >= 0"),
        }
    }
}

impl core::error::Error for DenoiseError {}

/// What a denoising pass used, per level (index 0 = finest, `cD_1`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Thresholds {
    /// Number of valid entries in `sigma` and `mu`.
    pub levels: u32,
    /// Noise sigma used on each level, signal unit.
    pub sigma: [f32; MAX_LEVELS as usize],
    /// Threshold applied on each level, signal unit.
    pub mu: [f32; MAX_LEVELS as usize],
}

/// Partial sums kept by [`peak_and_mean`]: lane `k` sums the samples `k, k + 8, k + 16, ...`.
const SUM_LANES: usize = 8;

/// Peak magnitude and mean of a block, in one read-only pass; refuses a non-finite sample
/// or one above [`MAX_ABS_INPUT`].
///
/// The peak is the largest `|x|` bit pattern (for non-negative floats the IEEE bit order is
/// the value order, and every NaN or infinity sorts above every finite value, so one integer
/// maximum also finds them). The mean is the sum of `x / n` (which cannot overflow whatever
/// the block length) over [`SUM_LANES`] partial sums added at the end: independent chains
/// the compiler vectorises, and a rounding error that grows with `n / 8` instead of `n`.
fn peak_and_mean(x: &[f32]) -> Result<(f32, f32), DenoiseError> {
    let inv_n = 1.0 / x.len() as f32;
    let mut peak_bits = 0u32;
    let mut lanes = [0.0f32; SUM_LANES];
    let chunks = x.chunks_exact(SUM_LANES);
    let rest = chunks.remainder();
    for c in chunks {
        for (acc, &v) in lanes.iter_mut().zip(c) {
            peak_bits = peak_bits.max(v.to_bits() & 0x7fff_ffff);
            *acc += v * inv_n;
        }
    }
    for (acc, &v) in lanes.iter_mut().zip(rest) {
        peak_bits = peak_bits.max(v.to_bits() & 0x7fff_ffff);
        *acc += v * inv_n;
    }
    let peak = f32::from_bits(peak_bits);
    if !peak.is_finite() {
        return Err(DenoiseError::NonFinite);
    }
    if peak > MAX_ABS_INPUT {
        return Err(DenoiseError::OutOfRange);
    }
    // Pairwise: ((0 + 1) + (2 + 3)) + ((4 + 5) + (6 + 7)).
    let [a, b, c, d, e, f, g, h] = lanes;
    Ok((peak, ((a + b) + (c + d)) + ((e + f) + (g + h))))
}

/// Whether `cfg` fits blocks of `len` samples with `scratch_len` of scratch: the checks
/// [`denoise_in_place`] makes on every call, for owners of a block buffer (such as
/// [`BlockDenoiser`] and the identifier) to make once, at construction.
pub fn check_config(
    len: usize,
    scratch_len: usize,
    cfg: &DenoiseConfig,
) -> Result<(), DenoiseError> {
    db4::check(len, scratch_len, cfg.levels)?;
    if cfg.levels > MAX_LEVELS {
        return Err(TransformError::BadLevels.into());
    }
    if let Sigma::Fixed(s) = cfg.sigma {
        if !(s.is_finite() && s >= 0.0) {
            return Err(DenoiseError::BadSigma);
        }
    }
    Ok(())
}

/// Denoises `x` in place: forward db4 transform, shrink every detail coefficient, inverse.
///
/// `scratch` must be at least `x.len()` long. The approximation coefficients are kept as
/// they are (paper section 3, step 2). On error `x` is unchanged.
///
/// The block mean is subtracted before the transform and added back after it. A constant
/// lives only in the approximation coefficients, which are never thresholded, so this
/// changes nothing mathematically; numerically it makes the f32 rounding of the lifting
/// steps relative to the signal's range instead of to its offset (a gyro's bias can be
/// hundreds of times its noise).
pub fn denoise_in_place(
    x: &mut [f32],
    scratch: &mut [f32],
    cfg: &DenoiseConfig,
) -> Result<Thresholds, DenoiseError> {
    check_config(x.len(), scratch.len(), cfg)?;
    let n = x.len();
    let (peak, mean) = peak_and_mean(x)?;
    db4::forward_offset(x, scratch, cfg.levels, mean)?;

    let mut out = Thresholds {
        levels: cfg.levels,
        sigma: [0.0; MAX_LEVELS as usize],
        mu: [0.0; MAX_LEVELS as usize],
    };
    let finest_sigma = match cfg.sigma {
        Sigma::Fixed(s) => s,
        // `get`, not indexing: detail ranges lie inside `x` (len >> level .. 2 (len >> level)),
        // so the empty fallback is never taken; it keeps the firmware free of range checks.
        Sigma::FinestMad | Sigma::PerLevelMad => threshold::mad_sigma(
            x.get(db4::detail_range(n, 1)).unwrap_or(&[]),
            scratch,
            ZERO_REL * peak * core::f32::consts::SQRT_2,
        ),
    };
    let mut level_scale = peak;
    for level in 1..=cfg.levels {
        level_scale *= core::f32::consts::SQRT_2;
        let range = db4::detail_range(n, level);
        let sigma = match cfg.sigma {
            Sigma::PerLevelMad if level > 1 => {
                let detail = x.get(range.clone()).unwrap_or(&[]);
                threshold::mad_sigma(detail, scratch, ZERO_REL * level_scale)
            }
            _ => finest_sigma,
        };
        let mu = threshold::universal_threshold(sigma, n);
        let i = (level - 1) as usize;
        if let (Some(s), Some(m)) = (out.sigma.get_mut(i), out.mu.get_mut(i)) {
            (*s, *m) = (sigma, mu);
        }
        if let Some(detail) = x.get_mut(range) {
            threshold::shrink_all(detail, mu, cfg.rule);
        }
    }
    db4::inverse_offset(x, scratch, cfg.levels, mean)?;
    Ok(out)
}

/// Outcome of [`BlockDenoiser::push`].
#[derive(Debug, PartialEq)]
pub enum Push<'a, const N: usize> {
    /// The sample was stored; `filled` samples of the current block are in.
    Pending {
        /// Samples stored in the current block.
        filled: usize,
    },
    /// The sample completed a block: here it is, denoised, oldest sample first.
    Block(&'a [f32; N], Thresholds),
}

/// Collects samples one at a time into a static block of `N` samples and denoises the block
/// when it is full.
///
/// # Latency
/// Sample `i` of a block (0-based) comes out, denoised, when sample `N - 1` of that block is
/// pushed: a delay of `N - 1 - i` samples (`N - 1` for the first sample of a block, 0 for the
/// last), plus the time of one [`denoise_in_place`] call, which that last push pays in full.
///
/// # Memory
/// `2 * N * 4` bytes (block + scratch), nothing else.
pub struct BlockDenoiser<const N: usize> {
    cfg: DenoiseConfig,
    block: [f32; N],
    scratch: [f32; N],
    filled: usize,
}

impl<const N: usize> BlockDenoiser<N> {
    const SIZE_OK: () = assert!(
        N.is_power_of_two() && N >= 16 && N <= 1 << 16,
        "block length must be a power of two in 16..=65536"
    );

    /// A denoiser for blocks of `N` samples. Fails if `cfg` does not fit `N`.
    pub fn new(cfg: DenoiseConfig) -> Result<Self, DenoiseError> {
        let () = Self::SIZE_OK;
        check_config(N, N, &cfg)?;
        Ok(Self {
            cfg,
            block: [0.0; N],
            scratch: [0.0; N],
            filled: 0,
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &DenoiseConfig {
        &self.cfg
    }

    /// Samples stored in the current, incomplete block.
    pub fn filled(&self) -> usize {
        self.filled
    }

    /// Forgets the incomplete block.
    pub fn reset(&mut self) {
        self.filled = 0;
    }

    /// Stores one sample; denoises and returns the block when it is full.
    ///
    /// A non-finite sample is refused with [`DenoiseError::NonFinite`], one larger than
    /// [`MAX_ABS_INPUT`] with [`DenoiseError::OutOfRange`]; neither is stored.
    pub fn push(&mut self, x: f32) -> Result<Push<'_, N>, DenoiseError> {
        if !x.is_finite() {
            return Err(DenoiseError::NonFinite);
        }
        if libm::fabsf(x) > MAX_ABS_INPUT {
            return Err(DenoiseError::OutOfRange);
        }
        // `filled < N` always holds between calls.
        if let Some(slot) = self.block.get_mut(self.filled) {
            *slot = x;
        }
        self.filled += 1;
        if self.filled < N {
            return Ok(Push::Pending {
                filled: self.filled,
            });
        }
        self.filled = 0;
        let t = denoise_in_place(&mut self.block, &mut self.scratch, &self.cfg)?;
        Ok(Push::Block(&self.block, t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_leave_block_unchanged() {
        let mut x = [1.0f32; 64];
        let mut s = [0.0f32; 64];
        x[5] = f32::NAN;
        let before = x;
        assert_eq!(
            denoise_in_place(&mut x, &mut s, &DenoiseConfig::PAPER),
            Err(DenoiseError::NonFinite)
        );
        assert!(x
            .iter()
            .zip(&before)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        let mut y = [1.0f32; 64];
        let bad = DenoiseConfig {
            levels: 4,
            ..DenoiseConfig::PAPER
        };
        assert_eq!(
            denoise_in_place(&mut y, &mut s, &bad),
            Err(DenoiseError::Transform(TransformError::BadLevels))
        );
        let neg = DenoiseConfig {
            sigma: Sigma::Fixed(-1.0),
            ..DenoiseConfig::PAPER
        };
        assert_eq!(
            denoise_in_place(&mut y, &mut s, &neg),
            Err(DenoiseError::BadSigma)
        );
        assert_eq!(
            denoise_in_place(&mut y[..48], &mut s, &DenoiseConfig::PAPER),
            Err(DenoiseError::Transform(TransformError::LengthNotPowerOfTwo))
        );
        assert_eq!(
            denoise_in_place(&mut y, &mut s[..32], &DenoiseConfig::PAPER),
            Err(DenoiseError::Transform(TransformError::ScratchTooShort))
        );
        assert!(y.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn peak_and_mean_refuses_every_non_finite_and_out_of_range_sample() {
        let mut s = [0.0f32; 64];
        for (bad, want) in [
            (f32::NAN, DenoiseError::NonFinite),
            (-f32::NAN, DenoiseError::NonFinite),
            (f32::INFINITY, DenoiseError::NonFinite),
            (f32::NEG_INFINITY, DenoiseError::NonFinite),
            (2.0e30, DenoiseError::OutOfRange),
            (-2.0e30, DenoiseError::OutOfRange),
        ] {
            // In the 8-sample lanes and in the remainder-free tail position alike.
            for pos in [0, 7, 63] {
                let mut x = [0.25f32; 64];
                x[pos] = bad;
                assert_eq!(
                    denoise_in_place(&mut x, &mut s, &DenoiseConfig::PAPER),
                    Err(want),
                    "{bad} at {pos}"
                );
            }
        }
        let x: [f32; 64] = core::array::from_fn(|i| i as f32 - 40.0);
        let (peak, mean) = peak_and_mean(&x).expect("finite");
        assert_eq!(peak, 40.0);
        assert!((mean - (31.5 - 40.0)).abs() < 1e-5, "{mean}");
    }

    #[test]
    fn block_denoiser_latency_and_rejections() {
        let mut bd = BlockDenoiser::<64>::new(DenoiseConfig::PAPER).expect("valid");
        assert_eq!(bd.push(f32::INFINITY), Err(DenoiseError::NonFinite));
        assert_eq!(bd.push(2e30), Err(DenoiseError::OutOfRange));
        for i in 0..63 {
            assert_eq!(bd.push(0.5), Ok(Push::Pending { filled: i + 1 }));
        }
        match bd.push(0.5) {
            Ok(Push::Block(b, t)) => {
                // A constant block comes back as itself: all details are zero.
                assert!(b.iter().all(|&v| (v - 0.5).abs() < 1e-6));
                assert_eq!(t.sigma[0], 0.0);
            }
            other => panic!("expected a block, got {other:?}"),
        }
        assert_eq!(bd.filled(), 0);
        assert!(BlockDenoiser::<64>::new(DenoiseConfig {
            levels: 4,
            ..DenoiseConfig::PAPER
        })
        .is_err());
    }

    #[test]
    fn denoising_reduces_white_noise() {
        // Deterministic pseudo-random noise (LCG) on a slow sine: the denoised block is closer
        // to the sine than the noisy one.
        let mut state = 12345u32;
        let mut noisy = [0.0f32; 1024];
        let mut clean = [0.0f32; 1024];
        for i in 0..1024 {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let u = (state >> 8) as f32 / (1u32 << 24) as f32 - 0.5;
            clean[i] = libm::sinf(i as f32 * 0.01);
            noisy[i] = clean[i] + 0.3 * u;
        }
        let err = |x: &[f32]| {
            x.iter()
                .zip(&clean)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f32>()
        };
        let before = err(&noisy);
        let mut s = [0.0f32; 1024];
        denoise_in_place(&mut noisy, &mut s, &DenoiseConfig::PAPER).expect("valid");
        assert!(err(&noisy) < 0.3 * before, "{} vs {}", err(&noisy), before);
    }
}
