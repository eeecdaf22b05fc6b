//! Causal drift baselines for a moving gyro: each takes one sample at a time (rate, optional
//! temperature, still flag) and gives its drift estimate for that sample, computed from the
//! samples BEFORE it only (a prediction; the first sample gets 0 or the prior).
//!
//! None of them learns from a sample whose still flag is false, so none can take rotation
//! for drift unless the flag lies (a false-still call). The Kalman ones run on
//! [`fog_core::kalman`].

use fog_core::kalman::{DiagonalModel, Kalman};

/// A causal drift estimator.
pub trait DriftEstimator {
    /// Short name for tables and plots.
    fn name(&self) -> String;
    /// Drift estimate for this sample (from earlier samples), deg/s; then learns from the
    /// sample when `still`. `t_s` is time since power-on, `temp_c` the sensor temperature.
    fn push(&mut self, t_s: f64, rate_dps: f64, temp_c: Option<f64>, still: bool) -> f64;
}

/// No compensation: the estimate is always 0.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoCompensation;

impl DriftEstimator for NoCompensation {
    fn name(&self) -> String {
        "none".into()
    }
    fn push(&mut self, _: f64, _: f64, _: Option<f64>, _: bool) -> f64 {
        0.0
    }
}

/// Alignment bias: the mean rate of the initial still period (from the first sample
/// flagged still up to the first non-still one after it; a detector's first seconds of
/// "not yet still" at power-on are skipped), held for ever after.
#[derive(Debug, Clone, Copy, Default)]
pub struct AlignmentBias {
    sum_dps: f64,
    n: u64,
    done: bool,
}

impl DriftEstimator for AlignmentBias {
    fn name(&self) -> String {
        "alignment".into()
    }
    fn push(&mut self, _: f64, rate_dps: f64, _: Option<f64>, still: bool) -> f64 {
        let est = if self.n > 0 {
            self.sum_dps / self.n as f64
        } else {
            0.0
        };
        if !still {
            self.done |= self.n > 0;
        } else if !self.done && rate_dps.is_finite() {
            self.sum_dps += rate_dps;
            self.n += 1;
        }
        est
    }
}

/// Stillness-gated random-walk Kalman filter (zero-angular-rate update, ZARU):
/// `b(k) = b(k-1) + w`, `var w = q_dps2` per sample, ALWAYS (so the variance grows in
/// motion and the filter re-converges quickly at the next stop); measurement
/// `rate = b + v`, `var v = r_dps2`, used ONLY when the sample is flagged still.
#[derive(Debug, Clone, Copy)]
pub struct GatedKalman {
    q_dps2: f64,
    r_dps2: f64,
    /// The bias and its variance (a one-state [`Kalman`]; None before the first still sample).
    level: Option<Kalman<1, f64>>,
}

impl GatedKalman {
    /// A filter; `q_dps2` >= 0 per sample, `r_dps2` > 0 (the white noise variance per
    /// sample: `arw_dps_per_rthz^2 * rate_hz`).
    pub fn new(q_dps2: f64, r_dps2: f64) -> Self {
        Self {
            q_dps2: q_dps2.max(0.0),
            r_dps2: if r_dps2 > 0.0 { r_dps2 } else { 1.0 },
            level: None,
        }
    }

    /// Process noise per sample, (deg/s)^2.
    pub fn q_dps2(&self) -> f64 {
        self.q_dps2
    }

    /// Current variance of the bias, (deg/s)^2.
    pub fn variance_dps2(&self) -> f64 {
        self.level.as_ref().map_or(0.0, |k| k.p()[0][0])
    }
}

impl DriftEstimator for GatedKalman {
    fn name(&self) -> String {
        format!("gated-kalman q={:.3e}", self.q_dps2)
    }
    fn push(&mut self, _: f64, rate_dps: f64, _: Option<f64>, still: bool) -> f64 {
        let walk = DiagonalModel {
            phi: [1.0],
            q: [self.q_dps2],
        };
        let est = self.level.as_ref().map_or(0.0, |k| k.x()[0]);
        if let Some(k) = self.level.as_mut() {
            k.predict(&walk);
        }
        if still && rate_dps.is_finite() {
            match self.level.as_mut() {
                Some(k) => {
                    k.update(&[1.0], rate_dps, self.r_dps2);
                }
                None => self.level = Some(Kalman::new([rate_dps], [self.r_dps2])),
            }
        }
        est
    }
}

/// Causal temperature rate: first-order low-pass (time constant `tau_s`) of the sample to
/// sample difference quotient, deg C/s.
#[derive(Debug, Clone, Copy)]
pub struct TempRate {
    tau_s: f64,
    prev: Option<(f64, f64)>,
    dtemp_c_per_s: f64,
}

impl TempRate {
    /// A filter of time constant `tau_s` (> 0).
    pub fn new(tau_s: f64) -> Self {
        Self {
            tau_s: tau_s.max(1e-9),
            prev: None,
            dtemp_c_per_s: 0.0,
        }
    }

    /// Adds a temperature; returns the smoothed rate, deg C/s.
    pub fn push(&mut self, t_s: f64, temp_c: f64) -> f64 {
        if let Some((t0, c0)) = self.prev {
            let dt = t_s - t0;
            if dt > 0.0 {
                let a = (dt / self.tau_s).min(1.0);
                self.dtemp_c_per_s += a * ((temp_c - c0) / dt - self.dtemp_c_per_s);
            }
        }
        self.prev = Some((t_s, temp_c));
        self.dtemp_c_per_s
    }
}

/// Thermal coefficients of the bias model `b + c1 (T - T0) + c2 dT/dt`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ThermalFit {
    /// deg/s per deg C.
    pub c1_dps_per_c: f64,
    /// deg/s per (deg C/s).
    pub c2_dps_per_c_per_s: f64,
}

/// Configuration of [`ThermalKalman`].
#[derive(Debug, Clone, Copy)]
pub struct ThermalKalmanConfig {
    /// Random walk of `b` per sample, (deg/s)^2.
    pub q_dps2: f64,
    /// White noise variance per sample, (deg/s)^2.
    pub r_dps2: f64,
    /// Prior 1-sigma of `c1`, deg/s per deg C (0 = held at its initial value).
    pub c1_sigma_dps_per_c: f64,
    /// Prior 1-sigma of `c2`, deg/s per (deg C/s) (0 = held).
    pub c2_sigma_dps_per_c_per_s: f64,
    /// Time constant of the temperature-rate filter, s.
    pub dtemp_tau_s: f64,
}

impl Default for ThermalKalmanConfig {
    /// ASSUMED priors for an E-Core-class FOG: c1 1-sigma 1 deg/h per deg C, c2 1-sigma
    /// 60 deg/h per (deg C/s); dT/dt filter 30 s; q 1e-12, r 1.2e-4 (E-Core preset at 100 Hz).
    fn default() -> Self {
        Self {
            q_dps2: 1e-12,
            r_dps2: 1.2e-4,
            c1_sigma_dps_per_c: 1.0 / DPH,
            c2_sigma_dps_per_c_per_s: 60.0 / DPH,
            dtemp_tau_s: 30.0,
        }
    }
}

const DPH: f64 = 3600.0;

/// Stillness-gated Kalman filter with a temperature regression: state
/// `x = [b, c1, c2]`, drift `= b + c1 (T - T0) + c2 dT/dt` (`T0` = the first temperature,
/// `dT/dt` from [`TempRate`]). `b` random-walks (`q_dps2` per sample, always); `c1, c2`
/// are constants. The update (recursive least squares with the random walk on `b`) runs
/// ONLY on still samples. Two ways to get the coefficients: learned on line from the stops
/// ([`ThermalKalman::new`], priors from the config), or fitted on training records with
/// [`fit_thermal`] and held ([`ThermalKalman::with_fit`]). Without a temperature the
/// regressors are 0 and it is the gated Kalman filter.
#[derive(Debug, Clone, Copy)]
pub struct ThermalKalman {
    cfg: ThermalKalmanConfig,
    fitted: bool,
    /// `[b, c1, c2]` and their covariance ([`Kalman`]).
    kf: Kalman<3, f64>,
    t0_c: Option<f64>,
    rate: TempRate,
    started: bool,
}

impl ThermalKalman {
    /// Coefficients learned on line (from 0, with the config's prior sigmas).
    pub fn new(cfg: ThermalKalmanConfig) -> Self {
        Self {
            cfg,
            fitted: false,
            kf: Kalman::new(
                [0.0; 3],
                [
                    0.0,
                    cfg.c1_sigma_dps_per_c.powi(2),
                    cfg.c2_sigma_dps_per_c_per_s.powi(2),
                ],
            ),
            t0_c: None,
            rate: TempRate::new(cfg.dtemp_tau_s),
            started: false,
        }
    }

    /// Coefficients fitted on training records and held (only `b` is estimated).
    pub fn with_fit(cfg: ThermalKalmanConfig, fit: ThermalFit) -> Self {
        let mut s = Self::new(cfg);
        s.fitted = true;
        s.kf = Kalman::new([0.0, fit.c1_dps_per_c, fit.c2_dps_per_c_per_s], [0.0; 3]);
        s
    }

    /// Current coefficients.
    pub fn coefficients(&self) -> ThermalFit {
        ThermalFit {
            c1_dps_per_c: self.kf.x()[1],
            c2_dps_per_c_per_s: self.kf.x()[2],
        }
    }
}

impl DriftEstimator for ThermalKalman {
    fn name(&self) -> String {
        let how = if self.fitted { "fitted" } else { "rls" };
        format!("thermal-kalman-{how} q={:.3e}", self.cfg.q_dps2)
    }

    fn push(&mut self, t_s: f64, rate_dps: f64, temp_c: Option<f64>, still: bool) -> f64 {
        let h = match temp_c.filter(|c| c.is_finite()) {
            Some(c) => {
                let t0 = *self.t0_c.get_or_insert(c);
                [1.0, c - t0, self.rate.push(t_s, c)]
            }
            None => [1.0, 0.0, 0.0],
        };
        let est = self.kf.observe(&h);
        if self.started {
            self.kf.predict(&DiagonalModel {
                phi: [1.0; 3],
                q: [self.cfg.q_dps2, 0.0, 0.0],
            });
        }
        if !(still && rate_dps.is_finite()) {
            return est;
        }
        if !self.started {
            // First still sample: b takes the residual with the noise variance (P is
            // diagonal until the first update).
            self.started = true;
            let x = *self.kf.x();
            let p = self.kf.p();
            self.kf = Kalman::new(
                [rate_dps - (est - x[0]), x[1], x[2]],
                [self.cfg.r_dps2, p[1][1], p[2][2]],
            );
            return est;
        }
        self.kf.update(&h, rate_dps, self.cfg.r_dps2);
        est
    }
}

/// Least-squares thermal coefficients from training records, each a slice of
/// `(t_s, rate_dps - true_rate_dps, temp_c, still)`: only still samples, one intercept per
/// record (each power-on has its own turn-on bias), `dT/dt` from [`TempRate`] of
/// `dtemp_tau_s`. None when the temperature does not vary enough to separate the terms.
pub fn fit_thermal(records: &[Vec<(f64, f64, f64, bool)>], dtemp_tau_s: f64) -> Option<ThermalFit> {
    // Normal equations of the per-record demeaned regressors.
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for rec in records {
        let mut tr = TempRate::new(dtemp_tau_s);
        let rows: Vec<[f64; 3]> = rec
            .iter()
            .filter_map(|&(t, z, c, still)| {
                let d = tr.push(t, c);
                (still && z.is_finite() && c.is_finite()).then_some([c, d, z])
            })
            .collect();
        if rows.is_empty() {
            continue;
        }
        let n = rows.len() as f64;
        let m: [f64; 3] = std::array::from_fn(|i| rows.iter().map(|r| r[i]).sum::<f64>() / n);
        for r in &rows {
            let (u1, u2, z) = (r[0] - m[0], r[1] - m[1], r[2] - m[2]);
            a11 += u1 * u1;
            a12 += u1 * u2;
            a22 += u2 * u2;
            b1 += u1 * z;
            b2 += u2 * z;
        }
    }
    let det = a11 * a22 - a12 * a12;
    if !(det.is_finite() && det > 1e-12 * (a11 * a22).max(f64::MIN_POSITIVE)) {
        return None;
    }
    Some(ThermalFit {
        c1_dps_per_c: (b1 * a22 - b2 * a12) / det,
        c2_dps_per_c_per_s: (a11 * b2 - a12 * b1) / det,
    })
}
