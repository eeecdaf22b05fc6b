//! First-order Gauss-Markov processes and the flicker (bias instability) bank built of them.
//!
//! # Bias instability construction
//! Flicker rate noise (one-sided PSD `B^2 / (2 pi f)`, IEEE Std 952) has the flat Allan
//! deviation `sqrt(2 ln 2 / pi) B = 0.664 B`. It is approximated by the sum of
//! [`FLICKER_PER_DECADE`] = 2 independent first-order Gauss-Markov processes per decade of
//! correlation time, `T_i = tau_min 10^(i/2)` for `i = 0..M` up to `tau_max`, all with the
//! same variance `c B^2`: equal-variance Lorentzians spread evenly in `log T` add up to
//! `1/f` between `1/(2 pi tau_max)` and `1/(2 pi tau_min)`. `c` is not the continuum value
//! `ln(r) / (2 pi)` (it leaves the floor about 6 % high) but calibrated from the exact Allan
//! variance of the bank ([`gm_avar`]): the mean Allan variance over 20 log-spaced taus in
//! `[20 tau_min, tau_max / 10]` equals `(2 ln 2 / pi) B^2`. Over that band the floor stays
//! within 2 % of `0.664 B` (unit test `flicker_floor_is_flat`); below `10 tau_min` it
//! rolls off like rate random walk, above `tau_max / 5` like white noise.
//! Each process starts from its stationary distribution, so the record is stationary.

use rand::Rng;
use rand_distr::StandardNormal;

/// Gauss-Markov processes per decade of correlation time in the flicker bank.
pub const FLICKER_PER_DECADE: f64 = 2.0;

/// `sqrt(2 ln 2 / pi)`: Allan deviation floor of flicker noise per unit B.
pub const FLICKER_FLOOR: f64 = 0.664_282_597_612_5;

/// Exact Allan variance, (deg/s)^2, of a first-order Gauss-Markov process of variance
/// `var` (deg/s)^2 and correlation time `t_s`, averaged over `tau_s`:
/// `2 var T / tau [1 - T / (2 tau) (3 - 4 e^(-tau/T) + e^(-2 tau/T))]`.
pub fn gm_avar(var: f64, t_s: f64, tau_s: f64) -> f64 {
    let x = tau_s / t_s;
    if x < 1.0 {
        // The closed form cancels for small x; its Taylor series instead:
        // sum_{k>=3} (-1)^k (4 - 2^k) x^(k-2) / k! = 2x/3 - x^2/2 + 7x^3/30 - ...
        let mut sum = 0.0;
        let mut xp = x; // x^(k-2)
        let mut fact = 6.0; // k!
        for k in 3..=30 {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            sum += sign * (4.0 - 2f64.powi(k)) * xp / fact;
            xp *= x;
            fact *= f64::from(k + 1);
        }
        return var * sum;
    }
    let bracket = 1.0 - (3.0 - 4.0 * (-x).exp() + (-2.0 * x).exp()) / (2.0 * x);
    2.0 * var / x * bracket
}

/// One first-order Gauss-Markov process sampled every `dt` (exact discretisation).
#[derive(Debug, Clone)]
pub struct GaussMarkov {
    /// Current value, deg/s.
    pub x_dps: f64,
    phi: f64,
    drive_dps: f64,
}

impl GaussMarkov {
    /// Process of standard deviation `sigma_dps`, correlation time `t_s`, step `dt_s`,
    /// started from its stationary distribution.
    pub fn new(sigma_dps: f64, t_s: f64, dt_s: f64, rng: &mut impl Rng) -> Self {
        let phi = (-dt_s / t_s).exp();
        let z: f64 = rng.sample(StandardNormal);
        Self {
            x_dps: sigma_dps * z,
            phi,
            drive_dps: sigma_dps * (1.0 - phi * phi).max(0.0).sqrt(),
        }
    }

    /// Advances one step.
    pub fn step(&mut self, rng: &mut impl Rng) {
        let z: f64 = rng.sample(StandardNormal);
        self.x_dps = self.phi * self.x_dps + self.drive_dps * z;
    }
}

/// Correlation times of the flicker bank between `tau_min_s` and `tau_max_s`.
pub fn flicker_times_s(tau_min_s: f64, tau_max_s: f64) -> Vec<f64> {
    let decades = (tau_max_s / tau_min_s).log10();
    let m = (FLICKER_PER_DECADE * decades - 1e-9).ceil().max(1.0) as usize + 1;
    (0..m)
        .map(|i| tau_min_s * 10f64.powf(i as f64 / FLICKER_PER_DECADE))
        .collect()
}

/// Variance of each bank process per unit `B^2` (see the module docs).
pub fn flicker_unit_var(times_s: &[f64], tau_min_s: f64, tau_max_s: f64) -> f64 {
    let (lo, hi) = ((20.0 * tau_min_s).ln(), (tau_max_s / 10.0).ln());
    let (lo, hi) = if hi > lo { (lo, hi) } else { (hi, lo) };
    let k = 20;
    let mean: f64 = (0..k)
        .map(|j| {
            let tau = (lo + (hi - lo) * j as f64 / (k - 1) as f64).exp();
            times_s.iter().map(|&t| gm_avar(1.0, t, tau)).sum::<f64>()
        })
        .sum::<f64>()
        / k as f64;
    FLICKER_FLOOR * FLICKER_FLOOR / mean
}

/// Analytic Allan deviation, deg/s, of the flicker bank for `b_dps` at `tau_s`.
pub fn flicker_adev(b_dps: f64, tau_min_s: f64, tau_max_s: f64, tau_s: f64) -> f64 {
    let times = flicker_times_s(tau_min_s, tau_max_s);
    let var = flicker_unit_var(&times, tau_min_s, tau_max_s) * b_dps * b_dps;
    times
        .iter()
        .map(|&t| gm_avar(var, t, tau_s))
        .sum::<f64>()
        .sqrt()
}

/// The flicker bank: bias instability as a sum of Gauss-Markov processes.
#[derive(Debug, Clone)]
pub struct Flicker {
    procs: Vec<GaussMarkov>,
}

impl Flicker {
    /// Bank for bias instability `b_dps` over `[tau_min_s, tau_max_s]`, step `dt_s`.
    pub fn new(b_dps: f64, tau_min_s: f64, tau_max_s: f64, dt_s: f64, rng: &mut impl Rng) -> Self {
        if b_dps == 0.0 {
            return Self { procs: Vec::new() };
        }
        let times = flicker_times_s(tau_min_s, tau_max_s);
        let sigma = (flicker_unit_var(&times, tau_min_s, tau_max_s)).sqrt() * b_dps;
        Self {
            procs: times
                .iter()
                .map(|&t| GaussMarkov::new(sigma, t, dt_s, rng))
                .collect(),
        }
    }

    /// Current value, deg/s.
    pub fn value_dps(&self) -> f64 {
        self.procs.iter().map(|p| p.x_dps).sum()
    }

    /// Advances every process one step.
    pub fn step(&mut self, rng: &mut impl Rng) {
        for p in &mut self.procs {
            p.step(rng);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flicker_floor_is_flat() {
        for (lo, hi) in [(1.0, 1e5), (0.5, 1e6), (0.1, 1e3)] {
            for (a, b, limit) in [(20.0f64, 10.0f64, 0.02), (10.0, 5.0, 0.04)] {
                let (a, b) = ((a * lo).ln(), (hi / b).ln());
                let mut worst = 0.0f64;
                for j in 0..=40 {
                    let tau = (a + (b - a) * f64::from(j) / 40.0).exp();
                    let r = flicker_adev(1.0, lo, hi, tau) / FLICKER_FLOOR;
                    worst = worst.max((r - 1.0).abs());
                }
                assert!(worst < limit, "[{lo}, {hi}]: ripple {worst}");
            }
        }
    }

    #[test]
    fn gm_avar_limits() {
        // tau >> T: white noise 2 var T / tau; tau << T: RRW 2 var tau / (3 T).
        let w = gm_avar(1.0, 1.0, 1e4);
        assert!((w / (2.0 / 1e4) - 1.0).abs() < 1e-3);
        let r = gm_avar(1.0, 1e4, 1.0);
        assert!((r / (2.0 / 3e4) - 1.0).abs() < 1e-3);
        // The series and the closed form meet at x = 1.
        let (a, b) = (gm_avar(1.0, 1.0, 1.0 - 1e-13), gm_avar(1.0, 1.0, 1.0));
        assert!((a / b - 1.0).abs() < 1e-12, "{a} {b}");
        // mpmath, 50 digits: x = 1e-3 gives 6.6616689991669126e-4.
        assert!((gm_avar(1.0, 1.0, 1e-3) / 6.661_668_999_166_913e-4 - 1.0).abs() < 1e-14);
    }
}
