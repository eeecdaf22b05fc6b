//! The `markov` test: the baseline (white N, flicker B, random walk K) against the baseline
//! plus a first-order Gauss-Markov term (sigma, T), both fitted on the whole record and
//! compared by Whittle likelihood.
//!
//! # Data
//! The periodogram of the record's first differences (the constant bias drops out and the
//! random walk becomes white), tapered at both ends ([`TAPER_SHARE`]), two-sided, (deg/s)^2/Hz, from `3 / record length` to the
//! Nyquist frequency, averaged in bins of [`BINS_PER_DECADE`] per decade: a bin's mean of
//! `m` independent ordinates is `S m^-1 Gamma(m, 1)` distributed.
//!
//! # Models (two-sided PSD of the differenced series, `w = 4 sin^2(pi f dt)`)
//! - white: `N^2 w`; flicker: `B^2 w / (2 pi f)` (Allan floor 0.664 B); random walk:
//!   `K^2 dt^2` (the increments are white);
//! - Gauss-Markov, the sampled AR(1) of variance `sigma^2` and `phi = exp(-dt / T)`:
//!   `sigma^2 w (1 - phi^2) dt / |1 - phi e^(-i 2 pi f dt)|^2`.
//!
//! Each term's share is averaged over the bin. Ordinates next to a line that the sinusoid
//! test found are left out ([`LINE_ORDINATES`]). The likelihood is maximised over the
//! non-negative term variances by projected Fisher scoring; `T` on a grid of
//! [`TAUS_PER_DECADE`] per decade from 2 samples to a tenth of the record.
//!
//! # Statistic and p-value
//! `LR = 2 (l_1 - l_0)`, the largest over the `T` grid. Its null distribution (a variance on
//! its boundary, `T` undefined under the null) comes from a parametric bootstrap of the
//! fitted null: [`BOOT_DRAWS`] binned periodograms drawn from the Gamma law above and fitted
//! again; the tail is a chi-square whose degrees of freedom match the bootstrap's 95th
//! percentile.

use rand::SeedableRng;
use rand_distr::{Distribution, Gamma};
use rustfft::num_complex::Complex;
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Periodogram bins per decade.
pub const BINS_PER_DECADE: f64 = 20.0;

/// Share of the record tapered at each end before the periodogram.
pub const TAPER_SHARE: f64 = 0.05;

/// Periodogram ordinates left out on each side of a detected line.
pub const LINE_ORDINATES: f64 = 3.0;

/// Gauss-Markov correlation times per decade.
pub const TAUS_PER_DECADE: f64 = 8.0;

/// Bootstrap draws of the null.
pub const BOOT_DRAWS: usize = 200;

/// The binned periodogram and each term's shape per bin.
struct Binned {
    m: Vec<f64>,
    i: Vec<f64>,
    /// Baseline shapes: white, flicker, random walk.
    base: [Vec<f64>; 3],
    /// Gauss-Markov shapes per `T`.
    gm: Vec<Vec<f64>>,
}

/// A fit: term variances (N^2, B^2, K^2[, sigma^2]) and the log-likelihood.
#[derive(Debug, Clone, Serialize)]
pub struct Fit {
    /// Log-likelihood (up to a constant).
    pub loglik: f64,
    /// Term variances, in the order of the shapes.
    pub c: Vec<f64>,
}

/// The Whittle log-likelihood of the bins' means `i` under the PSD `fixed + sum c_j col_j`
/// (`fixed` empty: none).
fn loglik(b: &Binned, cols: &[&[f64]], fixed: &[f64], c: &[f64], i: &[f64]) -> f64 {
    let mut l = 0.0;
    for k in 0..b.m.len() {
        let s: f64 = fixed.get(k).copied().unwrap_or(0.0)
            + cols.iter().zip(c).map(|(col, c)| col[k] * c).sum::<f64>();
        if s <= 0.0 || !s.is_finite() {
            return f64::NEG_INFINITY;
        }
        l -= b.m[k] * (s.ln() + i[k] / s);
    }
    l
}

/// Maximum Whittle likelihood over non-negative variances (projected Fisher scoring with
/// step halving), columns scaled to the data; `fixed` (empty: none) a PSD term held as it
/// is.
fn fit_cols(b: &Binned, cols: &[&[f64]], fixed: &[f64], i: &[f64]) -> Fit {
    let p = cols.len();
    let nb = b.m.len();
    // Start: every term explains an equal share of the mean level.
    let mean_i = i.iter().zip(&b.m).map(|(v, m)| v * m).sum::<f64>() / b.m.iter().sum::<f64>();
    let mut c: Vec<f64> = cols
        .iter()
        .map(|col| {
            let mc = col.iter().sum::<f64>() / nb as f64;
            if mc > 0.0 {
                mean_i / mc / p as f64
            } else {
                0.0
            }
        })
        .collect();
    let scale = c.clone();
    let mut l = loglik(b, cols, fixed, &c, i);
    for _ in 0..60 {
        let mut g = vec![0.0; p];
        let mut f = vec![vec![0.0; p + 1]; p];
        for k in 0..nb {
            let s: f64 = fixed.get(k).copied().unwrap_or(0.0)
                + cols.iter().zip(&c).map(|(col, c)| col[k] * c).sum::<f64>();
            let r = b.m[k] * (i[k] - s) / (s * s);
            for a in 0..p {
                let xa = cols[a][k] * scale[a];
                g[a] += xa * r;
                for bb in 0..p {
                    f[a][bb] += b.m[k] * xa * cols[bb][k] * scale[bb] / (s * s);
                }
            }
        }
        for a in 0..p {
            f[a][p] = g[a];
            f[a][a] *= 1.0 + 1e-9;
        }
        let Some(step) = super::evidence::solve(f) else {
            break;
        };
        let mut t = 1.0;
        let mut improved = false;
        for _ in 0..30 {
            let cand: Vec<f64> = (0..p)
                .map(|a| (c[a] + t * step[a] * scale[a]).max(0.0))
                .collect();
            let lc = loglik(b, cols, fixed, &cand, i);
            if lc > l {
                improved = lc - l > 1e-9 * l.abs().max(1.0);
                c = cand;
                l = lc;
                break;
            }
            t *= 0.5;
        }
        if !improved {
            break;
        }
    }
    Fit { loglik: l, c }
}

impl Binned {
    fn new(
        d: &[f64],
        dt_s: f64,
        t_total_s: f64,
        line_hz: Option<f64>,
        colour: Option<&super::colour::Colour>,
    ) -> Option<Self> {
        let n = d.len();
        if n < 64 {
            return None;
        }
        let mean = d.iter().sum::<f64>() / n as f64;
        // A split-cosine taper (TAPER_SHARE at each end): without it the series' end values
        // (the sample-scale white noise, far above the low-frequency power of a differenced
        // series) leak into every ordinate alike.
        let edge = ((TAPER_SHARE * n as f64) as usize).max(1);
        let taper = |i: usize| {
            let j = i.min(n - 1 - i);
            if j >= edge {
                1.0
            } else {
                0.5 * (1.0 - (std::f64::consts::PI * (j as f64 + 0.5) / edge as f64).cos())
            }
        };
        let u: f64 = (0..n).map(|i| taper(i).powi(2)).sum::<f64>() / n as f64;
        let mut buf: Vec<Complex<f64>> = d
            .iter()
            .enumerate()
            .map(|(i, &v)| Complex::new((v - mean) * taper(i), 0.0))
            .collect();
        rustfft::FftPlanner::<f64>::new()
            .plan_fft_forward(n)
            .process(&mut buf);
        let df = 1.0 / (n as f64 * dt_s);
        let f_lo = 3.0 / t_total_s;
        let k_lo = ((f_lo / df).ceil() as usize).max(1);
        let k_hi = (n - 1) / 2;
        if k_hi <= k_lo + 8 {
            return None;
        }
        let taus: Vec<f64> = tau_grid(dt_s, t_total_s);
        let step = 10f64.powf(1.0 / BINS_PER_DECADE);
        let mut edges = vec![k_lo];
        let mut f = k_lo as f64 * df;
        loop {
            f *= step;
            let k = ((f / df).ceil() as usize).max(edges[edges.len() - 1] + 1);
            if k > k_hi {
                break;
            }
            edges.push(k);
        }
        edges.push(k_hi + 1);
        let mut out = Binned {
            m: Vec::new(),
            i: Vec::new(),
            base: [Vec::new(), Vec::new(), Vec::new()],
            gm: vec![Vec::new(); taus.len()],
        };
        let phis: Vec<f64> = taus.iter().map(|t| (-dt_s / t).exp()).collect();
        for w in edges.windows(2) {
            let (a, z) = (w[0], w[1]);
            let mut acc = [0.0; 4];
            let mut gm = vec![0.0; taus.len()];
            let near_line =
                |k: usize| line_hz.is_some_and(|f0| (k as f64 - f0 / df).abs() <= LINE_ORDINATES);
            let m = (a..z).filter(|&k| !near_line(k)).count() as f64;
            if m == 0.0 {
                continue;
            }
            for k in (a..z).filter(|&k| !near_line(k)) {
                let fk = k as f64 * df;
                let wk = 4.0 * (std::f64::consts::PI * fk * dt_s).sin().powi(2);
                acc[0] += buf[k].norm_sqr() * dt_s / (n as f64 * u);
                acc[1] += wk * colour.map_or(1.0, |c| c.gain_at(fk));
                acc[2] += wk / (std::f64::consts::TAU * fk);
                acc[3] += dt_s * dt_s;
                let om = std::f64::consts::TAU * fk * dt_s;
                for (g, &ph) in gm.iter_mut().zip(&phis) {
                    let den = 1.0 - 2.0 * ph * om.cos() + ph * ph;
                    *g += wk * (1.0 - ph * ph) * dt_s / den;
                }
            }
            out.m.push(m);
            out.i.push(acc[0] / m);
            for j in 0..3 {
                out.base[j].push(acc[j + 1] / m);
            }
            for (o, g) in out.gm.iter_mut().zip(gm) {
                o.push(g / m);
            }
        }
        Some(out)
    }

    fn null(&self, i: &[f64]) -> Fit {
        let cols: Vec<&[f64]> = self.base.iter().map(|v| v.as_slice()).collect();
        fit_cols(self, &cols, &[], i)
    }

    /// The baseline plus the Gauss-Markov term of correlation time index `t`, fitted.
    fn alt_at(&self, t: usize, i: &[f64]) -> Fit {
        let cols: Vec<&[f64]> = self
            .base
            .iter()
            .map(|v| v.as_slice())
            .chain(std::iter::once(self.gm[t].as_slice()))
            .collect();
        fit_cols(self, &cols, &[], i)
    }

    /// The baseline plus each Gauss-Markov term of the grid, fitted (in the grid's order).
    fn alts(&self, i: &[f64]) -> Vec<Fit> {
        (0..self.gm.len()).map(|t| self.alt_at(t, i)).collect()
    }

    /// The best Gauss-Markov alternative: (index of T, fit).
    fn alt(&self, i: &[f64]) -> Option<(usize, Fit)> {
        let mut fits = self.alts(i);
        let t = best_alt(&fits)?;
        Some((t, fits.swap_remove(t)))
    }

    /// The baseline refitted with the Gauss-Markov term of correlation time index `t` held
    /// at variance `s2`: its log-likelihood.
    fn held(&self, t: usize, s2: f64, i: &[f64]) -> f64 {
        let fixed: Vec<f64> = self.gm[t].iter().map(|g| g * s2).collect();
        let cols: Vec<&[f64]> = self.base.iter().map(|v| v.as_slice()).collect();
        fit_cols(self, &cols, &fixed, i).loglik
    }

    /// The projections of the joint 95 % likelihood-ratio region of (sigma, T) (drop
    /// [`super::drift::profile_drop_95`]`(2)` from the best fit `best`): T's interval the
    /// hull of the grid cells whose best fit passes (half a grid step either side; open, 0
    /// or infinite, on a side where the grid's end cell passes), sigma's the hull over those
    /// cells of the variances whose held fit passes (from the cell's fit: below, geometric
    /// bisection towards `s2 1e-6`, 0 when even no term passes; above, x4 steps, then
    /// bisection). Cells whose best fit has no Gauss-Markov term are left out (for a named
    /// term, p < 0.006, the null is outside the region). Sigma in deg/s, T in s.
    /// `alts`: [`Binned::alts`] of the same data `i`.
    fn intervals(
        &self,
        best: f64,
        taus: &[f64],
        alts: &[Fit],
        i: &[f64],
    ) -> Option<([f64; 2], [f64; 2])> {
        let target = best - super::drift::profile_drop_95(2);
        let (mut sig, mut tau) = (
            [f64::INFINITY, f64::NEG_INFINITY],
            [f64::INFINITY, f64::NEG_INFINITY],
        );
        for ((t, &tau_s), f) in taus.iter().enumerate().zip(alts) {
            let Some(&s2) = f.c.get(3) else { continue };
            if f.loglik < target || s2 <= 0.0 {
                continue;
            }
            tau = [tau[0].min(tau_s), tau[1].max(tau_s)];
            let lo = if self.held(t, 0.0, i) >= target {
                0.0
            } else {
                let (mut inside, mut outside) = (s2, 0.0_f64);
                for _ in 0..SIGMA_SEARCH_STEPS {
                    let mid = (inside * outside.max(s2 * 1e-6)).sqrt();
                    if self.held(t, mid, i) >= target {
                        inside = mid;
                    } else {
                        outside = mid;
                    }
                }
                outside
            };
            let (mut inside, mut outside) = (s2, None);
            for _ in 0..SIGMA_SEARCH_STEPS {
                match outside {
                    None if self.held(t, inside * 4.0, i) >= target => inside *= 4.0,
                    None => outside = Some(inside * 4.0),
                    Some(o) => {
                        let mid = (inside * o).sqrt();
                        if self.held(t, mid, i) >= target {
                            inside = mid;
                        } else {
                            outside = Some(mid);
                        }
                    }
                }
            }
            let hi = outside.unwrap_or(f64::INFINITY);
            sig = [sig[0].min(lo.sqrt()), sig[1].max(hi.sqrt())];
        }
        let half_step = 10f64.powf(0.5 / TAUS_PER_DECADE);
        let (first, last) = (taus.first().copied(), taus.last().copied());
        let t_lo = if Some(tau[0]) == first {
            0.0
        } else {
            tau[0] / half_step
        };
        let t_hi = if Some(tau[1]) == last {
            f64::INFINITY
        } else {
            tau[1] * half_step
        };
        (sig[0] <= sig[1]).then_some((sig, [t_lo, t_hi]))
    }
}

/// Steps of each side's search for sigma in [`Binned::intervals`] (x4 steps and
/// bisections together on the upper side).
const SIGMA_SEARCH_STEPS: usize = 14;

/// The index of the fit of largest likelihood among `fits`.
fn best_alt(fits: &[Fit]) -> Option<usize> {
    fits.iter()
        .enumerate()
        .max_by(|a, b| a.1.loglik.total_cmp(&b.1.loglik))
        .map(|(t, _)| t)
}

fn tau_grid(dt_s: f64, t_total_s: f64) -> Vec<f64> {
    let mut v = Vec::new();
    let mut t = 2.0 * dt_s;
    while t <= 0.1 * t_total_s {
        v.push(t);
        t *= 10f64.powf(1.0 / TAUS_PER_DECADE);
    }
    v
}

/// The test's result.
#[derive(Debug, Clone, Serialize)]
pub struct MarkovTest {
    /// `2 (l_1 - l_0)`.
    pub lr: f64,
    /// p-value (bootstrap-matched chi-square tail).
    pub p_value: f64,
    /// Degrees of freedom of that tail.
    pub tail_dof: f64,
    /// Fitted correlation time, s.
    pub gm_tau_s: f64,
    /// Fitted standard deviation, deg/s.
    pub gm_sigma_dps: f64,
    /// The null fit: N, deg/s/sqrt(Hz); B, deg/s; K, deg/s/sqrt(s).
    pub null_arw_bi_rrw: [f64; 3],
    /// Bins used.
    pub bins: usize,
    /// The projections of the joint 95 % region of (sigma deg/s, T s) (`Binned::intervals`);
    /// computed only where the test's p-value is below [`INTERVALS_BELOW_P`].
    pub ci95: Option<([f64; 2], [f64; 2])>,
}

/// The p-value below which the test's intervals are computed (a term that is named needs
/// p < 0.006; the profile costs a few hundred refits).
pub const INTERVALS_BELOW_P: f64 = 0.05;

impl MarkovTest {
    /// Runs the test on the rate `y` (deg/s, sample period `dt_s`); deterministic (`seed`).
    /// `line_hz`: a spectral line found by the sinusoid test, whose ordinates are left out
    /// (a line is not a Gauss-Markov bump).
    pub fn run(
        y: &[f64],
        dt_s: f64,
        seed: u64,
        line_hz: Option<f64>,
        colour: Option<&super::colour::Colour>,
    ) -> Option<Self> {
        let d: Vec<f64> = y.windows(2).map(|w| w[1] - w[0]).collect();
        let t_total = y.len() as f64 * dt_s;
        let b = Binned::new(&d, dt_s, t_total, line_hz, colour)?;
        if b.gm.is_empty() {
            return None;
        }
        let f0 = b.null(&b.i);
        let alts = b.alts(&b.i);
        let ti = best_alt(&alts)?;
        let f1 = &alts[ti];
        let lr = (2.0 * (f1.loglik - f0.loglik)).max(0.0);
        // Bootstrap of the fitted null.
        let s0: Vec<f64> = (0..b.m.len())
            .map(|k| (0..3).map(|j| b.base[j][k] * f0.c[j]).sum())
            .collect();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut lrs: Vec<f64> = (0..BOOT_DRAWS)
            .map(|_| {
                let i: Vec<f64> = (0..b.m.len())
                    .map(|k| {
                        let g =
                            Gamma::new(b.m[k], 1.0 / b.m[k]).map_or(1.0, |g| g.sample(&mut rng));
                        s0[k] * g
                    })
                    .collect();
                let l0 = b.null(&i).loglik;
                b.alt(&i)
                    .map_or(0.0, |(_, f)| (2.0 * (f.loglik - l0)).max(0.0))
            })
            .collect();
        lrs.sort_by(|a, b| a.total_cmp(b));
        let q95 = lrs[(0.95 * BOOT_DRAWS as f64) as usize];
        // Degrees of freedom whose chi-square 95th percentile is the bootstrap's.
        let q = |k: f64| ChiSquared::new(k).map_or(f64::NAN, |c| c.inverse_cdf(0.95));
        let (mut lo, mut hi) = (0.05, 40.0);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if q(mid) < q95 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let dof = 0.5 * (lo + hi);
        let p_value = ChiSquared::new(dof).map_or(1.0, |c| c.sf(lr));
        let taus = tau_grid(dt_s, t_total);
        let ci95 = if p_value < INTERVALS_BELOW_P {
            b.intervals(f1.loglik, &taus, &alts, &b.i)
        } else {
            None
        };
        Some(MarkovTest {
            lr,
            p_value,
            tail_dof: dof,
            gm_tau_s: taus[ti],
            gm_sigma_dps: f1.c[3].sqrt(),
            null_arw_bi_rrw: [f0.c[0].sqrt(), f0.c[1].sqrt(), f0.c[2].sqrt()],
            bins: b.m.len(),
            ci95,
        })
    }

    /// As a [`super::evidence::Test`] outcome.
    pub fn outcome(&self) -> super::evidence::Test {
        let z = super::drift::z_of_p(self.p_value);
        let threshold = super::evidence::threshold(super::effects::Effect::Markov);
        super::evidence::Test {
            effect: super::effects::Effect::Markov,
            test: format!("whole record, periodogram of the first differences, Whittle likelihood ratio of (N, B, K) + Gauss-Markov against (N, B, K); tail chi-square({:.2}) matched to a {BOOT_DRAWS}-draw parametric bootstrap", self.tail_dof),
            statistic: self.lr,
            null_mean: self.tail_dof,
            null_sd: (2.0 * self.tail_dof).sqrt(),
            null_max: f64::NAN,
            nulls: BOOT_DRAWS,
            z,
            threshold,
            passed: z > threshold,
            detail: format!(
                "T {:.3} s, sigma {:.4} deg/h",
                self.gm_tau_s,
                self.gm_sigma_dps * 3600.0
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_distr::StandardNormal;

    fn record(seed: u64, gm_sigma: f64, gm_tau: f64) -> Vec<f64> {
        let (dt, n) = (0.01, 180_000);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let phi: f64 = (-dt / gm_tau).exp();
        let mut g = 0.0;
        let mut walk = 0.0;
        (0..n)
            .map(|_| {
                let (a, b, c): (f64, f64, f64) = (
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                );
                g = phi * g + gm_sigma * (1.0 - phi * phi).sqrt() * a;
                walk += 1e-5 * dt.sqrt() * b;
                g + walk + 0.003 / dt.sqrt() * c
            })
            .collect()
    }

    /// White noise and a walk: no Gauss-Markov term; with one of sigma 3x the white noise's
    /// 1-T deviation, found with about its T.
    #[test]
    fn finds_a_gauss_markov_term_and_not_a_missing_one() {
        let t = MarkovTest::run(&record(1, 0.0, 1.0), 0.01, 7, None, None).expect("test");
        assert!(t.p_value > 0.01, "{t:?}");
        let sigma = 3.0 * 0.003 / 5f64.sqrt();
        let t = MarkovTest::run(&record(2, sigma, 5.0), 0.01, 7, None, None).expect("test");
        assert!(t.p_value < 1e-4, "{t:?}");
        assert!((2.0..=12.0).contains(&t.gm_tau_s), "{t:?}");
        assert!((t.gm_sigma_dps / sigma - 1.0).abs() < 0.5, "{t:?}");
        // The joint region's projections hold the estimate and the truth.
        let (s_ci, t_ci) = t.ci95.expect("intervals of a passed test");
        assert!(
            s_ci[0] <= t.gm_sigma_dps && t.gm_sigma_dps <= s_ci[1],
            "{t:?}"
        );
        assert!(s_ci[0] <= sigma && sigma <= s_ci[1], "{t:?}");
        assert!(t_ci[0] <= 5.0 && 5.0 <= t_ci[1], "{t:?}");
    }
}
