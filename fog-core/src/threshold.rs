//! Wavelet-coefficient thresholding: noise estimate, universal threshold, soft and hard rules.

/// How detail coefficients are shrunk (paper eq. 1 is [`ThresholdRule::Soft`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ThresholdRule {
    /// `sign(x) * max(|x| - mu, 0)`: PyWavelets `pywt.threshold(x, mu, 'soft')`.
    Soft,
    /// `x` if `|x| >= mu`, else 0: PyWavelets `pywt.threshold(x, mu, 'hard')`.
    Hard,
}

/// Where the noise standard deviation `sigma` comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Sigma {
    /// Given by the caller, in the signal's unit (e.g. deg/s). Must be finite and >= 0.
    Fixed(f32),
    /// `median(|cD_1|) / 0.6745` over the finest details, numerical zeros ignored
    /// (Donoho-Johnstone); one threshold for every level. **The default.**
    FinestMad,
    /// The same estimate made separately on each level's details, each level thresholded
    /// with its own sigma: for coloured noise (flicker, Gauss-Markov), whose level
    /// variances differ.
    PerLevelMad,
}

/// The 0.75 quantile of the standard normal distribution: `MAD / 0.6745` estimates sigma.
pub const MAD_TO_SIGMA: f32 = 0.6745;

/// A detail coefficient is "numerically zero" when `|x| <= ZERO_REL * scale`, with `scale`
/// the peak magnitude of the transformed block times `sqrt(2)^level`.
///
/// A block that is constant (or a quantized signal that does not change within a filter's
/// span) gives details that are exactly zero in exact arithmetic but a few f32 rounding
/// errors (about `1e-7` of the peak) after the lifting steps; quantized gyro data has many.
/// Counting them would drive the median, hence sigma, to nearly zero. The margin `1e-5`
/// lies well above that rounding and well below one rate count of any 16-bit gyro at a
/// plausible peak (one count is at least `3e-5` of full scale).
pub const ZERO_REL: f32 = 1.0e-5;

/// `mu = sigma * sqrt(2 ln U)` (paper section 3), `U` the block length in samples.
///
/// Returns 0 for `U <= 1`.
pub fn universal_threshold(sigma: f32, block_len: usize) -> f32 {
    if block_len <= 1 {
        return 0.0;
    }
    sigma * libm::sqrtf(2.0 * libm::logf(block_len as f32))
}

/// Shrinks one coefficient.
#[inline]
pub fn shrink(x: f32, mu: f32, rule: ThresholdRule) -> f32 {
    match rule {
        ThresholdRule::Soft => {
            let m = libm::fabsf(x) - mu;
            if m > 0.0 {
                // copysign(m, x) for m > 0, written out so that it inlines (and vectorises).
                f32::from_bits(m.to_bits() | (x.to_bits() & 0x8000_0000))
            } else {
                0.0
            }
        }
        ThresholdRule::Hard => {
            if libm::fabsf(x) >= mu {
                x
            } else {
                0.0
            }
        }
    }
}

/// Shrinks every coefficient of `coeffs` in place.
///
/// The rule is chosen once, outside the loop, so that each loop is branch-free and
/// vectorised; the values are exactly those of [`shrink`].
pub fn shrink_all(coeffs: &mut [f32], mu: f32, rule: ThresholdRule) {
    match rule {
        ThresholdRule::Soft => {
            for c in coeffs {
                *c = shrink(*c, mu, ThresholdRule::Soft);
            }
        }
        ThresholdRule::Hard => {
            for c in coeffs {
                *c = shrink(*c, mu, ThresholdRule::Hard);
            }
        }
    }
}

/// Robust sigma estimate `median(|x| : |x| > zero_tol) / 0.6745`.
///
/// `work` must be at least as long as `x` (it is overwritten). Returns 0 when every value
/// is numerically zero. The median of an even count is the mean of the two middle values
/// (as `numpy.median`). Cost: O(len) on average (quickselect), no allocation.
///
/// From [`BRACKET_MIN_LEN`] values on, the median is first looked for with
/// [`median_abs_bracketed`] (the same value, found faster); below it, or when the bracket
/// misses, all the magnitudes are copied to `work` and selected from.
pub fn mad_sigma(x: &[f32], work: &mut [f32], zero_tol: f32) -> f32 {
    if x.len() >= BRACKET_MIN_LEN {
        if let Some(m) = median_abs_bracketed(x, work, zero_tol) {
            return m / MAD_TO_SIGMA;
        }
    }
    median_abs_direct(x, work, zero_tol) / MAD_TO_SIGMA
}

/// `median(|x| : |x| > zero_tol)` by copying those magnitudes to `work` and selecting; 0
/// when there are none.
fn median_abs_direct(x: &[f32], work: &mut [f32], zero_tol: f32) -> f32 {
    let mut n = 0;
    for &v in x {
        let a = libm::fabsf(v);
        if a > zero_tol {
            if let Some(w) = work.get_mut(n) {
                *w = a;
                n += 1;
            }
        }
    }
    // `get_mut`, not `[..n]`: n <= work.len() by construction; no range check in the firmware.
    median(work.get_mut(..n).unwrap_or_default())
}

/// Shortest input for which [`mad_sigma`] tries [`median_abs_bracketed`] first. Shorter
/// inputs (the firmware's: 256 finest details per 512-sample block) take the direct path.
pub const BRACKET_MIN_LEN: usize = 4096;

/// Values sampled by [`median_abs_bracketed`] to place its bracket (about).
const BRACKET_SAMPLE: usize = 1024;

/// Fewest sampled values [`median_abs_bracketed`] places a bracket with (a block whose
/// finest details are 95 % numerical zeros still has about 50).
const BRACKET_MIN_SAMPLE: usize = 48;

/// Bit pattern of `+inf`; above it lie the NaNs.
const INF_BITS: u32 = 0x7f80_0000;

/// Exact `median(|x| : |x| > zero_tol)` by bracketing: `None` when the bracket misses the
/// median (or there is too little to sample), and then the caller selects from everything.
///
/// 1. Every `len / 1024`-th magnitude above `zero_tol` is copied to `work` and the sample's
///    ranks `s/2 -+ 2 sqrt(s) + 2` are selected: a bracket `[lo, hi]` that holds the median
///    of the whole set unless the sample is unrepresentative (4 standard deviations of the
///    sample median's rank; a periodic pattern in `x` aligned with the stride could do it).
/// 2. One vectorised pass over `x` counts the magnitudes above `zero_tol` and those below
///    `lo`; one branch-free pass compacts those in `[lo, hi]` (about 1/8 of them) into
///    `work`.
/// 3. If the middle rank(s) fall in the bracket, they are selected from the compacted
///    values; the result is bit for bit the direct path's.
///
/// Magnitudes are compared as IEEE bit patterns (`bits & 0x7fff_ffff`), which for
/// non-negative floats sort like the values; NaNs are skipped as the direct path skips
/// them (`NaN > zero_tol` is false); a negative, infinite or NaN `zero_tol` returns `None`.
#[inline(never)]
pub fn median_abs_bracketed(x: &[f32], work: &mut [f32], zero_tol: f32) -> Option<f32> {
    let tol_bits = if zero_tol > 0.0 && zero_tol < f32::INFINITY {
        zero_tol.to_bits()
    } else if zero_tol == 0.0 {
        0
    } else {
        return None;
    };
    let counted = |k: u32| k > tol_bits && k <= INF_BITS;
    let stride = (x.len() / BRACKET_SAMPLE).max(1);
    let mut s = 0;
    for v in x.iter().step_by(stride) {
        let k = v.to_bits() & 0x7fff_ffff;
        if counted(k) {
            *work.get_mut(s)? = f32::from_bits(k);
            s += 1;
        }
    }
    if s < BRACKET_MIN_SAMPLE {
        return None;
    }
    // Integer square root of s (s <= 2048 here, so a short search is exact and cheap).
    let mut root = 0usize;
    while (root + 1) * (root + 1) <= s {
        root += 1;
    }
    let margin = 2 * root + 2;
    let lo_rank = (s / 2).saturating_sub(margin);
    let hi_rank = (s / 2 + margin).min(s - 1);
    let sample = work.get_mut(..s)?;
    let (_, lo_v, upper) = sample.select_nth_unstable_by_key(lo_rank, |v| v.to_bits());
    let lo = lo_v.to_bits();
    let hi = if hi_rank > lo_rank {
        let (_, hi_v, _) = upper.select_nth_unstable_by_key(hi_rank - lo_rank - 1, |v| v.to_bits());
        hi_v.to_bits()
    } else {
        lo
    };
    // Pass 1 (vectorised): total = counted values, below = counted values < lo. With
    // c = k - (tol + 1) (wrapping), "counted" is c <= INF - tol - 1 and "counted and < lo" is
    // c < lo - tol - 1: one unsigned comparison each (lo > tol, as the sample's values are).
    let first = tol_bits + 1;
    let (span_counted, span_below) = (INF_BITS - first, lo - first);
    let (mut below, mut total) = (0usize, 0usize);
    for v in x {
        let c = (v.to_bits() & 0x7fff_ffff).wrapping_sub(first);
        total += usize::from(c <= span_counted);
        below += usize::from(c < span_below);
    }
    // Pass 2 (branch-free compaction): values in [lo, hi] (all counted: tol < lo, hi <= INF)
    // are stored at work[m] unconditionally and kept by advancing m. m never exceeds the
    // index of the value being stored, so work[m] exists.
    let span = hi - lo;
    let mut m = 0usize;
    for v in x {
        let k = v.to_bits() & 0x7fff_ffff;
        if let Some(w) = work.get_mut(m) {
            *w = f32::from_bits(k);
        }
        m += usize::from(k.wrapping_sub(lo) <= span);
    }
    if total == 0 {
        return None;
    }
    // Middle ranks (0-based) among the counted values: upper = total / 2, lower = upper - 1
    // when total is even.
    let upper_rank = total / 2;
    let lower_rank = (total - 1) / 2;
    if lower_rank < below || upper_rank >= below + m {
        return None;
    }
    let (left, mid, _) = work
        .get_mut(..m)?
        .select_nth_unstable_by_key(upper_rank - below, |v| v.to_bits());
    let upper = *mid;
    if lower_rank == upper_rank {
        return Some(upper);
    }
    // lower_rank >= below, so the lower middle value is in the bracket, left of `upper`.
    let lower = left.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    Some(0.5 * (lower + upper))
}

/// Unsigned key that sorts like `f32::total_cmp` (the IEEE bits, with the negative values'
/// magnitude bits flipped and the sign bit inverted).
#[inline(always)]
pub(crate) fn total_key(x: f32) -> u32 {
    let b = x.to_bits();
    let flip = (((b as i32) >> 31) as u32) >> 1;
    (b ^ flip) ^ 0x8000_0000
}

/// The value whose [`total_key`] is `k`.
#[inline(always)]
pub(crate) fn from_total_key(k: u32) -> f32 {
    let b = k ^ 0x8000_0000;
    let flip = (((b as i32) >> 31) as u32) >> 1;
    f32::from_bits(b ^ flip)
}

/// Median of `v` (reordered in place); 0 for an empty slice. The median of an even count is
/// the mean of the two middle values; values are ranked by `f32::total_cmp` (for
/// non-negative values, the order of their bit patterns).
///
/// Radix selection on `total_key`, 4 bits per pass from the top: each pass counts the
/// remaining candidates per digit, keeps (compacted to the front of `v`) those with the
/// digit that holds the middle rank, and records how many fall below it and the largest of
/// them (for the lower middle value). The candidates shrink quickly once the exponent bits
/// are passed (about 2.3 n reads for the denoiser's detail magnitudes). Nothing is indexed
/// out of range (the histogram index is a 4-bit digit; `v` through `get`), so, unlike
/// `select_nth_unstable` (whose median-of-medians fallback links core's bounds checks),
/// this has no panic path. Same result: keys are equal only for identical bit patterns.
pub fn median(v: &mut [f32]) -> f32 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    let k = n / 2;
    let (mut len, mut rank) = (n, k);
    let (mut below, mut below_max) = (0usize, 0u32);
    for pass in 0..8u32 {
        let shift = 28 - 4 * pass;
        let mut hist = [0usize; 16];
        for &x in v.iter().take(len) {
            hist[((total_key(x) >> shift) & 15) as usize] += 1;
        }
        let mut digit = 0u32;
        for (d, &c) in (0u32..).zip(&hist) {
            if rank < c {
                digit = d;
                break;
            }
            rank -= c;
        }
        let mut m = 0;
        for i in 0..len {
            let Some(&x) = v.get(i) else { break };
            let q = total_key(x);
            let dq = (q >> shift) & 15;
            if dq < digit {
                below += 1;
                below_max = below_max.max(q);
            } else if dq == digit {
                if let Some(slot) = v.get_mut(m) {
                    *slot = x;
                }
                m += 1;
            }
        }
        len = m;
    }
    // Every remaining candidate has the middle key: identical bits.
    let upper = v.first().copied().unwrap_or(0.0);
    if n % 2 == 1 {
        return upper;
    }
    // The lower middle value: the largest value ranked below `upper`, or `upper` itself when
    // fewer than n / 2 values rank below it (ties).
    let lower_mid = if below < k {
        upper
    } else {
        from_total_key(below_max)
    };
    0.5 * (lower_mid + upper)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radix_median_equals_sorted_median_bit_for_bit() {
        let mut state = 11u32;
        for case in 0..7 {
            for n in [1usize, 2, 3, 4, 7, 8, 64, 255, 256, 257, 1000] {
                let mut v = [0.0f32; 1000];
                for x in v[..n].iter_mut() {
                    state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    let u = (state >> 8) as f32 / (1u32 << 24) as f32;
                    *x = match case {
                        0 => u,
                        1 => u - 0.5,
                        2 => (u * 8.0).floor() * 0.25,
                        3 => (u * 4.0).floor() - 2.0,
                        4 => u * 1e-30,
                        5 => -u,
                        // Signed zeros: ranked -0 < +0 as total_cmp does.
                        _ => {
                            if u < 0.5 {
                                -0.0
                            } else {
                                0.0
                            }
                        }
                    };
                }
                let mut sorted = v[..n].to_vec();
                sorted.sort_by(f32::total_cmp);
                let want = if n % 2 == 1 {
                    sorted[n / 2]
                } else {
                    0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
                };
                let got = median(&mut v[..n]);
                assert_eq!(got.to_bits(), want.to_bits(), "case {case}, n {n}");
            }
        }
    }

    #[test]
    fn median_odd_even_empty() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut []), 0.0);
    }

    #[test]
    fn mad_sigma_ignores_numerical_zeros() {
        let x = [0.0, 1e-9, -2.0, 0.0, 4.0, -6.0, 0.0];
        let mut w = [0.0; 7];
        // Nonzero magnitudes: 2, 4, 6 -> median 4.
        assert!((mad_sigma(&x, &mut w, 1e-6) - 4.0 / MAD_TO_SIGMA).abs() < 1e-6);
        assert_eq!(mad_sigma(&[0.0; 5], &mut w, 1e-6), 0.0);
    }

    #[test]
    fn bracketed_median_equals_direct_bit_for_bit() {
        const N: usize = 8192;
        let mut state = 7u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        let mut found = 0;
        for case in 0..8 {
            for len in [4096usize, 4097, 5000, N] {
                let x: [f32; N] = core::array::from_fn(|i| match case {
                    // White noise, then noise with most values (numerically) zero.
                    0 => next(),
                    1 => {
                        let u = next();
                        if u.abs() < 0.4 {
                            1e-9 * u
                        } else {
                            u
                        }
                    }
                    // Quantized: few distinct values, many ties at the median.
                    2 => libm::roundf(next() * 8.0) / 8.0,
                    // A pattern aligned with the sampling stride: the sample sees only
                    // large values, so the bracket misses and `None` is expected.
                    3 => {
                        if i % 8 == 0 {
                            100.0 + next()
                        } else {
                            next()
                        }
                    }
                    // Non-finite values among noise: NaN skipped, infinity counted.
                    4 => match i % 97 {
                        0 => f32::NAN,
                        1 => f32::NEG_INFINITY,
                        _ => next(),
                    },
                    // Constant, all zero, and a single counted value.
                    5 => 0.25,
                    6 => 0.0,
                    _ => {
                        if i == 3 {
                            2.0
                        } else {
                            0.0
                        }
                    }
                });
                let mut w1 = [0.0f32; N];
                let mut w2 = [0.0f32; N];
                let x = &x[..len];
                for tol in [0.0, 1e-6, 0.1] {
                    let direct = median_abs_direct(x, &mut w1, tol);
                    if let Some(b) = median_abs_bracketed(x, &mut w2, tol) {
                        assert_eq!(b.to_bits(), direct.to_bits(), "case {case} len {len}");
                        found += 1;
                    }
                    let sigma = mad_sigma(x, &mut w2, tol);
                    assert_eq!(sigma.to_bits(), (direct / MAD_TO_SIGMA).to_bits());
                }
                for bad_tol in [-1.0, f32::INFINITY, f32::NAN] {
                    assert_eq!(median_abs_bracketed(x, &mut w2, bad_tol), None);
                }
            }
        }
        // The bracket must hit in every ordinary case (noise, mostly zeros, ties, constants):
        // all but the stride-aligned pattern, the all-zero and the single-value inputs.
        assert_eq!(found, 60);
    }

    #[test]
    fn shrink_rules_match_paper_eq1() {
        let mu = 1.0;
        assert_eq!(shrink(2.5, mu, ThresholdRule::Soft), 1.5);
        assert_eq!(shrink(-2.5, mu, ThresholdRule::Soft), -1.5);
        assert_eq!(shrink(0.5, mu, ThresholdRule::Soft), 0.0);
        assert_eq!(shrink(1.0, mu, ThresholdRule::Soft), 0.0);
        assert_eq!(shrink(1.0, mu, ThresholdRule::Hard), 1.0);
        assert_eq!(shrink(-0.99, mu, ThresholdRule::Hard), 0.0);
    }

    #[test]
    fn universal_threshold_value() {
        // sqrt(2 ln 512) = 3.5322...
        assert!((universal_threshold(1.0, 512) - 3.532_21).abs() < 1e-4);
        assert_eq!(universal_threshold(1.0, 1), 0.0);
    }
}
