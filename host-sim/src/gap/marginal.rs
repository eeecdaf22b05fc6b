//! The record's own value distribution where it is platykurtic: a monotone map of the fitted
//! baseline's white-noise term, fitted on the record's fit blocks and applied in every
//! simulation of the baseline and its candidates (issue 43: "a baseline that reproduces the
//! record ... its tails").
//!
//! The ADIS16405's z axes carry a near-constant-amplitude oscillation at about 19.7 Hz: their
//! values less the local mean have an excess kurtosis of -0.27 (run 4) and -0.29 (run 5),
//! 18 and 26 standard errors below 0. [`super::colour`] reproduces its PSD, but the shaped
//! white noise is Gaussian (excess kurtosis 0), so the `dist` group stayed at a held-out gap
//! of 28-51 (null 95 % 1.5-2.9) in every round, above every other group: a warm-up or
//! Gauss-Markov candidate that lowered the `time` and `drift` groups could not lower the gap.
//!
//! # Family
//! `F`: a random-phase sinusoid of variance share `rho` plus a Gaussian of share `1 - rho`
//! (unit variance, symmetric, excess kurtosis `-1.5 rho^2`). The white term `w` (sd `s`) is
//! mapped sample by sample to `s F^{-1}(Phi(w / s))`: its marginal becomes `s F`, its
//! variance stays `s^2`, and being monotone and close to linear the map keeps its PSD (a
//! `rho` of 0.4 moves under 2 % of the power into other frequencies). `F^{-1}(Phi(z))` is a
//! table on a uniform `z` grid to [`Z_MAX`], built once per fit: `F` on an `x` grid (Phi
//! averaged over [`PHASES`] phases of the sinusoid), its normal score `Phi^{-1}(F(x))`, and
//! the table by interpolation; beyond [`Z_MAX`] the map goes on with the Gaussian's slope
//! `sqrt(1 - rho)`.
//!
//! # Fit and gate
//! On the fit blocks only (the held-out blocks stay honest), with the `dist` features' own
//! definition (values less their mean over [`super::features::DIST_WINDOWS`] windows per block): the record's
//! excess kurtosis `k` (pooled) and its standard error, the spread of the windows' own
//! kurtoses over the square root of their number (robust to colour, where `24 / n` is not).
//! The map is used only when all hold:
//! - `k` is below 0 by more than [`GATE_SDS`] standard errors and by more than
//!   [`MIN_PLATYKURTOSIS`] (a practical size: the simulations' own spread is about 0.02);
//! - the output quantum (the lattice step of the fit blocks' values; 0 off a lattice) is at
//!   most [`MAX_QUANTUM_OF_SD`] of the residual's sd (the dithered regime, where rounding
//!   adds only `-1.2 (q^2 / 12 / var)^2` to the kurtosis: 5e-4 at the limit);
//! - the baseline's white term carries at least [`MIN_WHITE_SHARE`] of the residual's
//!   variance (the map can only shape the white term).
//!
//! Then `k` less the quantum's part, over the white share squared, is the white term's own
//! excess kurtosis, and `rho = sqrt(-k_white / 1.5)` (at most [`MAX_RHO`]).
//!
//! **Heavy tails are never absorbed**: a positive excess kurtosis (spikes, outliers, a
//! mixture) leaves the white term Gaussian, so that `spikes` and the count features stay
//! findable. Nor is a vocabulary effect's platykurtosis: a line strong enough to pass this
//! gate (amplitude above 0.6 of the noise's sd) is plainly visible in the PSD, and the
//! simulated benchmarks' lines, ramps and warm-ups are far below the gate.
//!
//! # Without a colour
//! When the colour's gate fails but this one passes, the baseline's white term is drawn on
//! the same own stream, unshaped (a flat gain of 1), and mapped: the white level stays the
//! baseline's (its ARW from the short-tau Allan variance).

use super::colour::Colour;
use super::features::{dist_windows, excess_kurtosis};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use statrs::function::erf::{erfc, erfc_inv};

/// The record's excess kurtosis must be below 0 by more than this many standard errors.
pub const GATE_SDS: f64 = 5.0;

/// ... and below `-MIN_PLATYKURTOSIS`.
pub const MIN_PLATYKURTOSIS: f64 = 0.05;

/// The largest output quantum, as a share of the residual's sd, for which the map is fitted.
pub const MAX_QUANTUM_OF_SD: f64 = 0.5;

/// The smallest share of the residual's variance the white term must carry.
pub const MIN_WHITE_SHARE: f64 = 0.5;

/// The largest variance share of the sinusoid in the family.
pub const MAX_RHO: f64 = 0.95;

/// Phases of the sinusoid averaged over to compute the family's CDF.
pub const PHASES: usize = 512;

/// The map's table reaches this normal score; beyond it the slope is `sqrt(1 - rho)`.
pub const Z_MAX: f64 = 8.0;

/// Step of the map's table in normal score.
const Z_STEP: f64 = 0.005;

/// Points of the `x` grid the family's CDF is computed on (one half: it is symmetric).
const X_POINTS: usize = 6000;

/// The map of the white term's marginal.
#[derive(Debug, Clone, Serialize)]
pub struct Marginal {
    /// Variance share of the random-phase sinusoid in the family.
    pub rho: f64,
    /// The family's excess kurtosis, `-1.5 rho^2`: the white term's.
    pub white_excess_kurtosis: f64,
    /// The record's excess kurtosis (fit blocks, `dist` definition).
    pub excess_kurtosis: f64,
    /// Its standard error.
    pub se: f64,
    /// The gate's figure: `-excess_kurtosis / se`.
    pub gate_sds: f64,
    /// The white term's share of the residual's variance.
    pub white_share: f64,
    /// The output quantum over the residual's sd (0 off a lattice).
    pub quantum_of_sd: f64,
    /// `F^{-1}(Phi(z))` at `z = k Z_STEP`, `k = 0 ..` (odd: the negative half by symmetry).
    #[serde(skip)]
    table: Vec<f64>,
}

/// The fit's outcome: the map when the gate passed, and the gate's figures either way.
#[derive(Debug, Clone, Serialize)]
pub struct MarginalFit {
    /// The map (None: the white term stays Gaussian).
    pub marginal: Option<Marginal>,
    /// The record's excess kurtosis (fit blocks, `dist` definition).
    pub excess_kurtosis: f64,
    /// Its standard error from the spread of the windows' kurtoses.
    pub se: f64,
    /// `-excess_kurtosis / se`.
    pub gate_sds: f64,
    /// The output quantum over the residual's sd (0 off a lattice).
    pub quantum_of_sd: f64,
    /// The white term's share of the residual's variance.
    pub white_share: f64,
    /// Why no map (empty when there is one).
    pub detail: String,
}

/// The pooled excess kurtosis of `dist_windows` and its standard error from the spread of
/// the windows' own kurtoses.
pub fn kurtosis_and_se(windows: &[Vec<f64>]) -> (f64, f64) {
    let all: Vec<f64> = windows.iter().flatten().copied().collect();
    let k = excess_kurtosis(&all);
    let ks: Vec<f64> = windows
        .iter()
        .filter(|w| w.len() > 3)
        .map(|w| excess_kurtosis(w))
        .collect();
    let n = ks.len() as f64;
    if ks.len() < 2 {
        return (k, f64::NAN);
    }
    let mu = ks.iter().sum::<f64>() / n;
    let var = ks.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / (n - 1.0);
    (k, (var / n).sqrt())
}

impl Marginal {
    /// Fits the map on the fit blocks `ranges` of `y` (the rate less its reference); `raw`:
    /// the rate as recorded (for the output quantum); `white_var_dps2`: the variance of the
    /// baseline's white term as simulated (after its colour). See the module docs.
    pub fn fit(
        y: &[f64],
        raw: &[f64],
        ranges: &[(usize, usize)],
        white_var_dps2: f64,
    ) -> MarginalFit {
        let windows = dist_windows(y, ranges);
        let (k, se) = kurtosis_and_se(&windows);
        let all: Vec<f64> = windows.iter().flatten().copied().collect();
        let var = all.iter().map(|x| x * x).sum::<f64>() / all.len().max(1) as f64;
        let vals: Vec<f64> = ranges
            .iter()
            .flat_map(|&(a, b)| raw[a..b].iter().copied())
            .collect();
        let q = super::effects::lattice_step(&vals).unwrap_or(0.0);
        let q_of_sd = if var > 0.0 { q / var.sqrt() } else { f64::NAN };
        let share = (white_var_dps2 / var).min(1.0);
        let gate = -k / se;
        let none = |detail: String| MarginalFit {
            marginal: None,
            excess_kurtosis: k,
            se,
            gate_sds: gate,
            quantum_of_sd: q_of_sd,
            white_share: share,
            detail,
        };
        if !(k.is_finite() && se.is_finite() && se > 0.0 && var > 0.0) {
            return none("too few values to measure the record's kurtosis".into());
        }
        if k > 0.0 {
            return none(format!(
                "excess kurtosis {k:.3} +- {se:.3}: heavy tails are never absorbed"
            ));
        }
        if k >= -MIN_PLATYKURTOSIS || gate <= GATE_SDS {
            return none(format!(
                "excess kurtosis {k:.3} +- {se:.3} ({gate:.1} sd below 0): the map needs more than {GATE_SDS} sd and below -{MIN_PLATYKURTOSIS}"
            ));
        }
        if q_of_sd.is_nan() || q_of_sd > MAX_QUANTUM_OF_SD {
            return none(format!(
                "excess kurtosis {k:.3} +- {se:.3}, but the output quantum is {q_of_sd:.2} of the residual's sd (> {MAX_QUANTUM_OF_SD})"
            ));
        }
        if share.is_nan() || share < MIN_WHITE_SHARE {
            return none(format!(
                "excess kurtosis {k:.3} +- {se:.3}, but the white term carries only {share:.2} of the residual's variance (< {MIN_WHITE_SHARE})"
            ));
        }
        // The quantum's own part (a uniform error of variance q^2 / 12, kurtosis -1.2).
        let k_corr = k + 1.2 * (q * q / 12.0 / var).powi(2);
        let k_white = k_corr / (share * share);
        let rho = (-k_white / 1.5).max(0.0).sqrt().min(MAX_RHO);
        let m = Marginal::with_rho(rho, k, se, share, q_of_sd);
        MarginalFit {
            marginal: Some(m),
            excess_kurtosis: k,
            se,
            gate_sds: gate,
            quantum_of_sd: q_of_sd,
            white_share: share,
            detail: String::new(),
        }
    }

    /// The map for the family with sinusoid share `rho` (the other fields are the fit's
    /// figures, for the report).
    pub fn with_rho(rho: f64, k: f64, se: f64, share: f64, q_of_sd: f64) -> Self {
        let rho = rho.clamp(0.0, MAX_RHO);
        let a = (2.0 * rho).sqrt();
        let s = (1.0 - rho).sqrt();
        // F on x in [x_lo, 0] (F(0) = 1/2 by symmetry), and its normal score.
        let x_lo = -(a + 10.0 * s);
        let phases: Vec<f64> = (0..PHASES)
            .map(|p| a * (std::f64::consts::TAU * (p as f64 + 0.5) / PHASES as f64).sin())
            .collect();
        let mut xs = Vec::with_capacity(X_POINTS + 1);
        let mut zs = Vec::with_capacity(X_POINTS + 1);
        for i in 0..=X_POINTS {
            let x = x_lo * (1.0 - i as f64 / X_POINTS as f64);
            let f = phases
                .iter()
                .map(|c| 0.5 * erfc(-(x - c) / (std::f64::consts::SQRT_2 * s)))
                .sum::<f64>()
                / PHASES as f64;
            if f > 1e-300 && f.is_finite() {
                let z = if i == X_POINTS {
                    0.0
                } else {
                    -std::f64::consts::SQRT_2 * erfc_inv(2.0 * f)
                };
                // Keep the scores strictly increasing (rounding in the far tail).
                if zs.last().is_none_or(|&l: &f64| z > l) {
                    xs.push(x);
                    zs.push(z);
                }
            }
        }
        // The table: x at z = -k Z_STEP by interpolation, stored as its negative (the
        // positive half).
        let nz = (Z_MAX / Z_STEP).round() as usize;
        let mut table = Vec::with_capacity(nz + 1);
        let mut j = zs.len().saturating_sub(1);
        for k in 0..=nz {
            let z = -(k as f64) * Z_STEP;
            while j > 0 && zs[j] > z {
                j -= 1;
            }
            let x = if zs.is_empty() {
                z
            } else if j + 1 >= zs.len() || zs[j] > z {
                // Below the grid (never: the grid reaches about -10): the tail's slope.
                xs[j] + s * (z - zs[j])
            } else {
                let w = (z - zs[j]) / (zs[j + 1] - zs[j]);
                xs[j] + w * (xs[j + 1] - xs[j])
            };
            table.push(-x);
        }
        Self {
            rho,
            white_excess_kurtosis: -1.5 * rho * rho,
            excess_kurtosis: k,
            se,
            gate_sds: -k / se,
            white_share: share,
            quantum_of_sd: q_of_sd,
            table,
        }
    }

    /// `F^{-1}(Phi(z))`: a standard normal score mapped to the family (odd, increasing).
    pub fn map(&self, z: f64) -> f64 {
        let u = z.abs() / Z_STEP;
        let k = u as usize;
        let t = &self.table;
        let v = if k + 1 < t.len() {
            t[k] + (u - k as f64) * (t[k + 1] - t[k])
        } else {
            t.last().copied().unwrap_or(0.0) + (1.0 - self.rho).sqrt() * (z.abs() - Z_MAX)
        };
        if z < 0.0 {
            -v
        } else {
            v
        }
    }
}

/// The baseline's own white-noise term: `n` samples of sd `sigma_dps` (before the colour's
/// gain), sample period `dt_s`, from `seed`'s own stream; shaped by `colour` (unshaped
/// without one) and, with `marginal`, mapped to its family (standardised by the shaped
/// term's sd, mapped, rescaled).
pub fn white_term(
    colour: Option<&Colour>,
    marginal: Option<&Marginal>,
    sigma_dps: f64,
    n: usize,
    dt_s: f64,
    seed: u64,
) -> Vec<f64> {
    let (mut w, sd) = match colour {
        Some(c) => (
            c.shaped_white(sigma_dps, n, dt_s, seed),
            sigma_dps * c.variance_gain(n, dt_s).sqrt(),
        ),
        None => {
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed ^ 0x3A76_1A1D_43F0_0D5E);
            let w: Vec<f64> = (0..n)
                .map(|_| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    sigma_dps * z
                })
                .collect();
            (w, sigma_dps)
        }
    };
    if let (Some(m), true) = (marginal, sd > 0.0) {
        for v in w.iter_mut() {
            *v = sd * m.map(*v / sd);
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// `n` samples at 100 Hz: white noise of sd 0.3 deg/s plus, with `tone_share > 0`, a
    /// constant-amplitude tone at 19.7 Hz carrying that share of the variance.
    fn record(n: usize, seed: u64, tone_share: f64) -> Vec<f64> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let var_total = 0.09 / (1.0 - tone_share);
        let amp = (2.0 * tone_share * var_total).sqrt();
        (0..n)
            .map(|k| {
                let e: f64 = StandardNormal.sample(&mut rng);
                let t = k as f64 * 0.01;
                0.3 * e + amp * (std::f64::consts::TAU * 19.7 * t + 0.3).sin()
            })
            .collect()
    }

    /// The fit blocks of a record of `n` samples: blocks 0, 2, 4 of 6.
    fn fit_ranges(n: usize) -> Vec<(usize, usize)> {
        (0..6)
            .step_by(2)
            .map(|b| (n * b / 6, n * (b + 1) / 6))
            .collect()
    }

    fn variance(y: &[f64]) -> f64 {
        let m = y.iter().sum::<f64>() / y.len() as f64;
        y.iter().map(|x| (x - m).powi(2)).sum::<f64>() / y.len() as f64
    }

    /// Gaussian records keep a Gaussian white term: the gate does not pass on any of 8, and
    /// their excess kurtosis is within 4 standard errors of 0.
    #[test]
    fn gaussian_noise_keeps_a_gaussian_white_term() {
        for seed in 0..8 {
            let y = record(60_000, 100 + seed, 0.0);
            let r = fit_ranges(y.len());
            let f = Marginal::fit(&y, &y, &r, variance(&y));
            assert!(f.marginal.is_none(), "seed {seed}: {f:?}");
            assert!(f.excess_kurtosis.abs() < 4.0 * f.se, "seed {seed}: {f:?}");
            assert!(!f.detail.is_empty());
        }
    }

    /// Heavy tails are not absorbed: white noise with 1 % of its samples 5 times larger.
    #[test]
    fn heavy_tails_are_not_absorbed() {
        let mut y = record(60_000, 7, 0.0);
        for v in y.iter_mut().step_by(100) {
            *v *= 5.0;
        }
        let f = Marginal::fit(&y, &y, &fit_ranges(60_000), variance(&y));
        assert!(f.excess_kurtosis > 1.0, "{f:?}");
        assert!(f.marginal.is_none(), "{f:?}");
    }

    /// A coarse quantum (0.8 of the residual's sd) keeps the white term Gaussian, whatever
    /// the kurtosis.
    #[test]
    fn a_coarse_quantum_is_not_the_dithered_regime() {
        let y: Vec<f64> = record(60_000, 8, 0.424)
            .iter()
            .map(|v| (v / 0.32).round() * 0.32)
            .collect();
        let f = Marginal::fit(&y, &y, &fit_ranges(60_000), variance(&y));
        assert!(f.quantum_of_sd > MAX_QUANTUM_OF_SD, "{f:?}");
        assert!(f.marginal.is_none(), "{f:?}");
    }

    /// White noise plus a constant-amplitude 19.7-Hz tone (excess kurtosis about -0.27):
    /// the fitted rho is the tone's share within 0.05, and white noise of the record's
    /// variance, mapped, has the record's kurtosis (the `dist` definition, fit blocks)
    /// within 4 combined standard errors, on 3 simulations.
    #[test]
    fn a_tone_s_platykurtosis_is_fitted_and_reproduced() {
        let y = record(60_000, 3, 0.424);
        let r = fit_ranges(y.len());
        let var = variance(&y);
        let f = Marginal::fit(&y, &y, &r, var);
        let m = f.marginal.clone().expect("the gate passes");
        assert!(
            (f.excess_kurtosis + 0.27).abs() < 0.05,
            "{}",
            f.excess_kurtosis
        );
        assert!((m.rho - 0.424).abs() < 0.05, "rho {}", m.rho);
        for seed in 0..3 {
            let sim = white_term(None, Some(&m), var.sqrt(), y.len(), 0.01, 40 + seed);
            let (k, se) = kurtosis_and_se(&dist_windows(&sim, &r));
            let tol = 4.0 * (se * se + f.se * f.se).sqrt();
            assert!(
                (k - f.excess_kurtosis).abs() < tol,
                "seed {seed}: simulated {k} +- {se}, record {} +- {}",
                f.excess_kurtosis,
                f.se
            );
            // The white term's variance is kept.
            assert!((variance(&sim) / var - 1.0).abs() < 0.02);
        }
    }

    /// The map is odd, increasing and of unit variance under the normal law (quadrature),
    /// for several rho; rho 0 is the identity.
    #[test]
    fn the_map_is_monotone_with_unit_variance() {
        for rho in [0.0, 0.2, 0.424, 0.7, 0.95] {
            let m = Marginal::with_rho(rho, 0.0, 1.0, 1.0, 0.0);
            let (mut prev, mut v2, mut v4) = (f64::NEG_INFINITY, 0.0, 0.0);
            let h = 0.001;
            for i in 0..=20_000 {
                let z = -10.0 + i as f64 * h;
                let x = m.map(z);
                assert!(x > prev, "rho {rho}: not increasing at z {z}");
                assert!((x + m.map(-z)).abs() < 1e-12, "rho {rho}: not odd at {z}");
                prev = x;
                let w = h * (-0.5 * z * z).exp() / (std::f64::consts::TAU).sqrt();
                v2 += w * x * x;
                v4 += w * x.powi(4);
            }
            assert!((v2 - 1.0).abs() < 2e-3, "rho {rho}: variance {v2}");
            let k = v4 / (v2 * v2) - 3.0;
            assert!(
                (k + 1.5 * rho * rho).abs() < 0.01,
                "rho {rho}: excess kurtosis {k}"
            );
            if rho == 0.0 {
                assert!((m.map(1.3) - 1.3).abs() < 1e-4);
            }
        }
    }
}
