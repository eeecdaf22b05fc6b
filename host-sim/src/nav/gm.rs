//! Stillness-gated two-state Kalman filter: a slow random walk plus a first-order
//! Gauss-Markov state (bias instability), the reference model for the level of the motion
//! preset, in f64.

use super::baselines::Gated;
use super::DriftEstimator;

/// Parameters of [`GatedRwGm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RwGmConfig {
    /// Random-walk variance growth of the slow state per SECOND, (deg/s)^2 / s (>= 0).
    pub q_rw_dps2_per_s: f64,
    /// Stationary standard deviation of the Gauss-Markov state, deg/s (>= 0).
    pub sigma_gm_dps: f64,
    /// Correlation time of the Gauss-Markov state, s (> 0).
    pub tau_s: f64,
    /// White noise variance per sample, (deg/s)^2 (> 0).
    pub r_dps2: f64,
    /// Prior variance of the slow state at power-on, (deg/s)^2.
    pub p0_dps2: f64,
}

/// Drift `b + g`: `b` a random walk (`var += q dt`), `g` a first-order Gauss-Markov state
/// (`g <- a g + w`, `a = exp(-dt / tau)`, `var w = sigma^2 (1 - a^2)`). Both are predicted
/// at every sample, still or not (so in motion `g` decays toward 0 and the estimate tends
/// to the slow part `b`); the measurement `rate = b + g + v` (`var v = r`) is used ONLY
/// when the sample is flagged still. The estimate of a sample comes from earlier samples.
#[derive(Debug, Clone, Copy)]
pub struct GatedRwGm {
    cfg: RwGmConfig,
    x: [f64; 2],
    // Covariance [p00, p01, p11].
    p: [f64; 3],
    last_t_s: Option<f64>,
    // Cached `(dt, a)`.
    dt_a: (f64, f64),
}

impl GatedRwGm {
    /// A filter at power-on: state 0, variances `p0` and `sigma^2`.
    pub fn new(cfg: RwGmConfig) -> Self {
        let cfg = RwGmConfig {
            q_rw_dps2_per_s: cfg.q_rw_dps2_per_s.max(0.0),
            sigma_gm_dps: cfg.sigma_gm_dps.abs(),
            tau_s: if cfg.tau_s > 0.0 { cfg.tau_s } else { 1.0 },
            r_dps2: if cfg.r_dps2 > 0.0 { cfg.r_dps2 } else { 1.0 },
            p0_dps2: cfg.p0_dps2.max(0.0),
        };
        Self {
            x: [0.0; 2],
            p: [cfg.p0_dps2, 0.0, cfg.sigma_gm_dps * cfg.sigma_gm_dps],
            cfg,
            last_t_s: None,
            dt_a: (f64::NAN, 1.0),
        }
    }

    /// The states `[b, g]`, deg/s.
    pub fn state(&self) -> [f64; 2] {
        self.x
    }

    /// The covariance `[p00, p01, p11]`, (deg/s)^2.
    pub fn covariance(&self) -> [f64; 3] {
        self.p
    }

    /// Prediction over `dt_s` seconds.
    pub fn predict(&mut self, dt_s: f64) {
        if dt_s.is_nan() || dt_s <= 0.0 {
            return;
        }
        if dt_s != self.dt_a.0 {
            self.dt_a = (dt_s, (-dt_s / self.cfg.tau_s).exp());
        }
        let a = self.dt_a.1;
        let s2 = self.cfg.sigma_gm_dps * self.cfg.sigma_gm_dps;
        self.x[1] *= a;
        self.p[0] += self.cfg.q_rw_dps2_per_s * dt_s;
        self.p[1] *= a;
        self.p[2] = a * a * self.p[2] + s2 * (1.0 - a * a);
    }

    /// Measurement update with `y = b + g + v`, `var v = r_dps2`.
    pub fn update(&mut self, y_dps: f64, r_dps2: f64) {
        let [p00, p01, p11] = self.p;
        let h0 = p00 + p01;
        let h1 = p01 + p11;
        let s = h0 + h1 + r_dps2;
        if s.is_nan() || s <= 0.0 || !y_dps.is_finite() {
            return;
        }
        let (k0, k1) = (h0 / s, h1 / s);
        let innovation = y_dps - self.x[0] - self.x[1];
        self.x[0] += k0 * innovation;
        self.x[1] += k1 * innovation;
        self.p = [p00 - k0 * h0, p01 - k0 * h1, p11 - k1 * h1];
    }

    /// The drift estimate `b + g`, deg/s.
    pub fn estimate(&self) -> f64 {
        self.x[0] + self.x[1]
    }
}

impl DriftEstimator for GatedRwGm {
    fn name(&self) -> String {
        format!(
            "gated RW+GM q={:.2e} sigma={:.2e} tau={}",
            self.cfg.q_rw_dps2_per_s, self.cfg.sigma_gm_dps, self.cfg.tau_s
        )
    }
    fn push(&mut self, t_s: f64, rate_dps: f64, _: Option<f64>, still: bool) -> f64 {
        self.gated_push(t_s, rate_dps, still)
    }
}

impl Gated for GatedRwGm {
    fn last_t_s(&mut self) -> &mut Option<f64> {
        &mut self.last_t_s
    }
    fn predict_s(&mut self, dt_s: f64) {
        self.predict(dt_s);
    }
    fn update_still(&mut self, rate_dps: f64) {
        self.update(rate_dps, self.cfg.r_dps2);
    }
    fn drift_dps(&self) -> f64 {
        self.estimate()
    }
}
