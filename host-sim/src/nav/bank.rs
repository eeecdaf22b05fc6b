//! Stillness-gated Kalman filter whose drift model is the sensor's Allan specification:
//! a random walk (rate random walk `K`) plus a bank of first-order Gauss-Markov states that
//! approximates flicker (bias instability `B`), white noise `N` per sample. The parameters
//! are the noise specification's, or tuned by the caller. The f64 counterpart of
//! `fog_core::bank`, the ablation row of `nav_baselines --flags --bank`.

// Matrix code: `p[i * n + j]` with the same `i`, `j` in several arrays reads as the algebra.
#![allow(clippy::needless_range_loop)]

use super::baselines::Gated;
use super::DriftEstimator;

/// Flicker of two-sided PSD `B^2 / (2 pi f)` as a sum of Gauss-Markov states, one per
/// `spacing` factor of correlation time: a continuum of GM states with weight `w` per unit
/// of `ln tau` has PSD `w / (2 f)`, so `w = B^2 / pi` and each state of the bank gets
/// `sigma^2 = B^2 ln(spacing) / pi` (0.733 B^2 per decade).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BankConfig {
    /// Rate random walk, (deg/s)^2 variance growth per second (`K^2`).
    pub q_rw_dps2_per_s: f64,
    /// Bias instability `B`, deg/s (flicker PSD `B^2 / (2 pi f)`, two-sided).
    pub b_dps: f64,
    /// Shortest and longest correlation time of the bank, s.
    pub tau_min_s: f64,
    /// Longest correlation time of the bank, s.
    pub tau_max_s: f64,
    /// Correlation times per decade.
    pub per_decade: f64,
    /// White noise variance per sample, (deg/s)^2.
    pub r_dps2: f64,
    /// Prior variance of the random walk at power-on (turn-on bias), (deg/s)^2.
    pub p0_dps2: f64,
}

impl BankConfig {
    /// The correlation times and stationary variances of the bank.
    pub fn states(&self) -> Vec<(f64, f64)> {
        let spacing = 10f64.powf(1.0 / self.per_decade.max(0.1));
        let var = self.b_dps * self.b_dps * spacing.ln() / std::f64::consts::PI;
        let mut v = Vec::new();
        let mut tau = self.tau_min_s.max(1e-3);
        while tau <= self.tau_max_s * (1.0 + 1e-9) {
            v.push((tau, var));
            tau *= spacing;
        }
        v
    }
}

/// The filter: state `[b, g_1 .. g_M]`, drift `b + sum g`, full covariance; predicted at
/// every sample (in motion the GM states decay toward 0), updated only when still.
#[derive(Debug, Clone)]
pub struct GatedBank {
    cfg: BankConfig,
    taus: Vec<f64>,
    vars: Vec<f64>,
    x: Vec<f64>,
    p: Vec<f64>,
    n: usize,
    last_t_s: Option<f64>,
    dt: f64,
    a: Vec<f64>,
}

impl GatedBank {
    /// A filter at power-on.
    pub fn new(cfg: BankConfig) -> Self {
        let st = cfg.states();
        let n = st.len() + 1;
        let mut p = vec![0.0; n * n];
        p[0] = cfg.p0_dps2;
        for (i, (_, v)) in st.iter().enumerate() {
            p[(i + 1) * n + i + 1] = *v;
        }
        Self {
            cfg,
            taus: st.iter().map(|s| s.0).collect(),
            vars: st.iter().map(|s| s.1).collect(),
            x: vec![0.0; n],
            p,
            n,
            last_t_s: None,
            dt: f64::NAN,
            a: vec![1.0; n],
        }
    }

    fn predict(&mut self, dt: f64) {
        if dt.is_nan() || dt <= 0.0 {
            return;
        }
        let n = self.n;
        if dt != self.dt {
            self.dt = dt;
            for i in 1..n {
                self.a[i] = (-dt / self.taus[i - 1]).exp();
            }
        }
        for i in 1..n {
            self.x[i] *= self.a[i];
        }
        for i in 0..n {
            for j in 0..n {
                self.p[i * n + j] *= self.a[i] * self.a[j];
            }
        }
        self.p[0] += self.cfg.q_rw_dps2_per_s * dt;
        for i in 1..n {
            let a = self.a[i];
            self.p[i * n + i] += self.vars[i - 1] * (1.0 - a * a);
        }
    }

    fn update(&mut self, y: f64) {
        let n = self.n;
        // h = P 1 (H = all ones), s = 1' P 1 + r.
        let h: Vec<f64> = (0..n)
            .map(|i| self.p[i * n..(i + 1) * n].iter().sum())
            .collect();
        let s: f64 = h.iter().sum::<f64>() + self.cfg.r_dps2;
        if s.is_nan() || s <= 0.0 || !y.is_finite() {
            return;
        }
        let innov = y - self.estimate();
        for i in 0..n {
            self.x[i] += h[i] / s * innov;
        }
        for i in 0..n {
            for j in 0..n {
                self.p[i * n + j] -= h[i] * h[j] / s;
            }
        }
    }

    /// Drift estimate, deg/s.
    pub fn estimate(&self) -> f64 {
        self.x.iter().sum()
    }
}

impl DriftEstimator for GatedBank {
    fn name(&self) -> String {
        format!("gated RW+flicker bank ({} GM)", self.n - 1)
    }
    fn push(&mut self, t_s: f64, rate_dps: f64, _: Option<f64>, still: bool) -> f64 {
        self.gated_push(t_s, rate_dps, still)
    }
}

impl Gated for GatedBank {
    fn last_t_s(&mut self) -> &mut Option<f64> {
        &mut self.last_t_s
    }
    fn predict_s(&mut self, dt_s: f64) {
        self.predict(dt_s);
    }
    fn update_still(&mut self, rate_dps: f64) {
        self.update(rate_dps);
    }
    fn drift_dps(&self) -> f64 {
        self.estimate()
    }
}
