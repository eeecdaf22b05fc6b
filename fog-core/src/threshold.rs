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
                libm::copysignf(m, x)
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
pub fn shrink_all(coeffs: &mut [f32], mu: f32, rule: ThresholdRule) {
    for c in coeffs {
        *c = shrink(*c, mu, rule);
    }
}

/// Robust sigma estimate `median(|x| : |x| > zero_tol) / 0.6745`.
///
/// `work` must be at least as long as `x` (it is overwritten). Returns 0 when every value
/// is numerically zero. The median of an even count is the mean of the two middle values
/// (as `numpy.median`). Cost: O(len) on average (quickselect), no allocation.
pub fn mad_sigma(x: &[f32], work: &mut [f32], zero_tol: f32) -> f32 {
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
    median(work.get_mut(..n).unwrap_or_default()) / MAD_TO_SIGMA
}

/// Median of `v` (reordered in place); 0 for an empty slice.
pub fn median(v: &mut [f32]) -> f32 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    // For non-negative floats the IEEE bit patterns sort like the values, and comparing
    // integers is cheaper than `total_cmp`; negative values keep the general order.
    let all_non_negative = v.iter().all(|x| x.is_sign_positive());
    let (lower, upper_mid, _) = if all_non_negative {
        v.select_nth_unstable_by_key(n / 2, |x| x.to_bits())
    } else {
        v.select_nth_unstable_by(n / 2, f32::total_cmp)
    };
    let upper = *upper_mid;
    if n % 2 == 1 {
        return upper;
    }
    // The lower middle value is the largest of the elements left of the upper one.
    let lower_mid = lower.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    0.5 * (lower_mid + upper)
}

#[cfg(test)]
mod tests {
    use super::*;

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
