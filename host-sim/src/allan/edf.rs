//! Equivalent degrees of freedom of the overlapping Allan variance and chi-square bounds.
//!
//! EDF: the simple approximations of NIST SP 1065 (Riley 2008) Table 5, after Howe, Allan &
//! Barnes (1981) / Stein (1985), for the power-law noise types alpha = 2 (white PM), 1
//! (flicker PM), 0 (white FM), -1 (flicker FM), -2 (random-walk FM); identical to
//! `allantools.edf_simple`. Not Greenhall's exact algorithm. The caller picks alpha per tau
//! from the dominant fitted term; a rate ramp uses the random-walk FM formula. The result is
//! clipped to at least 1.
//!
//! Bounds: `AVAR edf / chi2_{(1+c)/2}(edf) <= sigma^2 <= AVAR edf / chi2_{(1-c)/2}(edf)`,
//! chi-square quantiles from `statrs` (inverse CDF of the chi-square distribution) for
//! `edf < 100`; above that, the Wilson-Hilferty approximation
//! `k (1 - 2/(9k) + z sqrt(2/(9k)))^3` (relative error below 1e-4 there), because statrs'
//! inverse CDF does not converge for millions of degrees of freedom.

use anyhow::{anyhow, Result};
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};

/// Above this many degrees of freedom, chi-square quantiles come from Wilson-Hilferty.
pub const WILSON_HILFERTY_FROM: f64 = 100.0;

/// The `p` quantile of the chi-square distribution with `k` degrees of freedom.
pub fn chi2_quantile(k: f64, p: f64) -> Result<f64> {
    if k >= WILSON_HILFERTY_FROM {
        let z = Normal::standard().inverse_cdf(p);
        let a = 2.0 / (9.0 * k);
        return Ok(k * (1.0 - a + z * a.sqrt()).powi(3));
    }
    let chi = ChiSquared::new(k).map_err(|e| anyhow!("chi-square with {k} dof: {e}"))?;
    Ok(chi.inverse_cdf(p))
}

/// One-sigma confidence (the default): 0.6827.
pub const ONE_SIGMA: f64 = 0.682_689_492_137_086;

/// EDF of the overlapping ADEV at `m` for `n_phase` phase points (= rate samples + 1).
pub fn edf_simple(n_phase: usize, m: usize, alpha: i32) -> f64 {
    let n = n_phase as f64;
    let m = m as f64;
    let edf = match alpha {
        2 => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        1 => {
            let a = (n - 1.0) / (2.0 * m);
            let b = (2.0 * m + 1.0) * (n - 1.0) / 4.0;
            (a.max(1.0).ln() * b.max(1.0).ln()).sqrt().exp()
        }
        0 => {
            (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * (4.0 * m * m)
                / (4.0 * m * m + 5.0)
        }
        -1 if m < 2.0 => 2.0 * (n - 2.0) / (2.3 * n - 4.9),
        -1 => 5.0 * n * n / (4.0 * m * (n + 3.0 * m)),
        _ => {
            let a = (n - 2.0) / (m * (n - 3.0).powi(2));
            a * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m)
        }
    };
    if edf.is_finite() {
        edf.max(1.0)
    } else {
        1.0
    }
}

/// Lower and upper bound of an Allan deviation with `edf` degrees of freedom.
pub fn adev_bounds(adev: f64, edf: f64, confidence: f64) -> Result<(f64, f64)> {
    let hi_q = chi2_quantile(edf, 0.5 * (1.0 + confidence))?;
    let lo_q = chi2_quantile(edf, 0.5 * (1.0 - confidence))?;
    if !(hi_q > lo_q && lo_q > 0.0 && hi_q.is_finite()) {
        return Err(anyhow!("chi-square quantiles failed for {edf} dof"));
    }
    let var = adev * adev;
    Ok(((var * edf / hi_q).sqrt(), (var * edf / lo_q).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_bracket_and_shrink() {
        let (lo, hi) = adev_bounds(1.0, 10.0, ONE_SIGMA).expect("ok");
        assert!(lo < 1.0 && hi > 1.0);
        let (lo2, hi2) = adev_bounds(1.0, 1000.0, ONE_SIGMA).expect("ok");
        let (lo3, hi3) = adev_bounds(1.0, 6.7e6, ONE_SIGMA).expect("ok");
        assert!(lo3 < 1.0 && hi3 > 1.0 && hi3 - lo3 < 1e-3, "{lo3} {hi3}");
        assert!(lo2 > lo && hi2 < hi);
        // Large edf: sigma of ADEV ~ 1/sqrt(2 edf).
        assert!((hi2 - 1.0 - 1.0 / (2000f64).sqrt()).abs() < 2e-3, "{hi2}");
    }

    #[test]
    fn quantiles_are_right_for_small_and_huge_dof() {
        // Known values: chi2_{0.975}(1) = 5.0239, chi2_{0.025}(10) = 3.2470.
        assert!((chi2_quantile(1.0, 0.975).expect("q") - 5.023_886).abs() < 1e-4);
        assert!((chi2_quantile(10.0, 0.025).expect("q") - 3.246_973).abs() < 1e-4);
        for k in [1.0, 2.5, 10.0, 99.0, 100.0, 1e3, 1e5, 6.7e6] {
            for p in [0.158_655_25, 0.841_344_75] {
                let q = chi2_quantile(k, p).expect("q");
                let cdf = ChiSquared::new(k).expect("k").cdf(q);
                assert!((cdf - p).abs() < 2e-4, "k {k} p {p}: q {q} cdf {cdf}");
            }
        }
        // Both sides of the switch agree.
        let a = chi2_quantile(99.999, 0.84).expect("q");
        let b = chi2_quantile(100.0, 0.84).expect("q");
        assert!((a / b - 1.0).abs() < 1e-4, "{a} {b}");
    }

    #[test]
    fn white_fm_edf_large_for_small_m() {
        let e = edf_simple(10_001, 1, 0);
        assert!(e > 5000.0 && e < 15_000.0, "{e}");
        assert!(edf_simple(10_001, 5000, -2) >= 1.0);
    }
}
