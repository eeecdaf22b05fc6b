//! Allan variance of a band of rate noise: a hump in the Allan deviation that no IEEE Std
//! 952 term makes (a dither band, a sensor's filter resonance, an angle-count pattern).
//!
//! The band is white rate noise of total variance 1 (deg/s)^2 spread evenly over
//! `[lo_hz, hi_hz]` (one-sided PSD `1 / (hi - lo)` there, 0 elsewhere). Its Allan variance
//! is `2 int S(f) sin^4(pi f tau) / (pi f tau)^2 df` (IEEE Std 952 eq. C.2 with the
//! one-sided PSD), which with `x = pi f tau` is
//! ```text
//! AVAR(tau) = 2 / ((hi - lo) pi tau) int_{pi lo tau}^{pi hi tau} sin^4(x) / x^2 dx
//! ```
//! It rises as `tau^2` below the band (ADEV as tau) and falls as `tau^-2` above it (ADEV as
//! `tau^-1`, like angle quantization), with its peak near `tau = 0.37 / f`. The integral is
//! Simpson's rule (step 0.05) up to `x = 200`, and beyond it the mean of `sin^4` (3/8)
//! over `x^2` (relative error below 1e-3 of the whole). The continuous-time form is used:
//! for a band below the Nyquist frequency the sampled record's Allan variance differs by a
//! factor `(sin(pi f tau0) / (pi f tau0))^2` across the band, absorbed in the fitted size.

/// Band edges of a band term centred (geometrically) on `centre_hz`: one octave wide.
pub fn edges_hz(centre_hz: f64) -> (f64, f64) {
    let half = std::f64::consts::SQRT_2;
    (centre_hz / half, centre_hz * half)
}

/// Allan variance at `tau_s` of a unit-variance band `[lo_hz, hi_hz]` (module docs).
pub fn band_avar(lo_hz: f64, hi_hz: f64, tau_s: f64) -> f64 {
    if !(hi_hz > lo_hz && lo_hz > 0.0 && tau_s > 0.0) {
        return 0.0;
    }
    let pi = std::f64::consts::PI;
    let (x1, x2) = (pi * lo_hz * tau_s, pi * hi_hz * tau_s);
    2.0 / ((hi_hz - lo_hz) * pi * tau_s) * sin4_over_x2(x1, x2)
}

/// Where the integral switches from Simpson's rule to the mean of `sin^4`.
const SIMPSON_UP_TO: f64 = 200.0;
/// Simpson's step on `x`.
const STEP: f64 = 0.05;

/// `int_a^b sin^4(x) / x^2 dx` for `0 <= a < b`.
fn sin4_over_x2(a: f64, b: f64) -> f64 {
    let mid = b.min(SIMPSON_UP_TO);
    let mut sum = 0.0;
    if a < mid {
        let k = (((mid - a) / STEP).ceil() as usize).max(1);
        let k = k + k % 2;
        let h = (mid - a) / k as f64;
        let f = |x: f64| {
            if x < 1e-4 {
                x * x
            } else {
                let s = x.sin();
                let s2 = s * s;
                s2 * s2 / (x * x)
            }
        };
        let mut acc = f(a) + f(mid);
        for i in 1..k {
            let w = if i % 2 == 1 { 4.0 } else { 2.0 };
            acc += w * f(a + i as f64 * h);
        }
        sum += acc * h / 3.0;
    }
    let lo = a.max(SIMPSON_UP_TO);
    if b > lo {
        sum += 0.375 * (1.0 / lo - 1.0 / b);
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integral_matches_its_closed_form_limit() {
        // int_0^inf sin^4(x) / x^2 dx = pi / 4.
        let v = sin4_over_x2(0.0, 1e9);
        assert!((v / (std::f64::consts::PI / 4.0) - 1.0).abs() < 1e-3, "{v}");
    }

    #[test]
    fn a_wide_band_is_white_noise_in_its_middle() {
        // White rate noise of PSD h over [lo, hi]: AVAR = h / (2 tau) for 1/hi << tau << 1/lo.
        let (lo, hi) = (1e-3, 1e3);
        let h = 1.0 / (hi - lo);
        for tau in [0.1, 1.0, 10.0] {
            let v = band_avar(lo, hi, tau);
            assert!((v / (h / (2.0 * tau)) - 1.0).abs() < 0.02, "tau {tau}: {v}");
        }
    }

    #[test]
    fn a_band_is_a_hump() {
        let (lo, hi) = edges_hz(3.0);
        let peak = band_avar(lo, hi, 0.37 / 3.0);
        assert!(band_avar(lo, hi, 0.01) < 0.1 * peak);
        // tau^-2 well above the band.
        let (a, b) = (band_avar(lo, hi, 10.0), band_avar(lo, hi, 20.0));
        assert!((a / b / 4.0 - 1.0).abs() < 0.05, "{a} {b}");
        assert!(a < 0.1 * peak);
    }
}
