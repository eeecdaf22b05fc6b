//! Error figures of an estimator over many samples (all fractions: 0.015 is 1.5 %).

use serde::Serialize;

/// Accumulates `y` against the denoised measurement `d` and, when known, the true drift.
#[derive(Debug, Clone, Default)]
pub struct ErrorAcc {
    n: u64,
    non_finite: u64,
    sum_sq_err_d: f64,
    sum_sq_d: f64,
    max_abs_err_d: f64,
    d_min: f64,
    d_max: f64,
    n_truth: u64,
    sum_sq_err_truth: f64,
    sum_sq_truth: f64,
}

impl ErrorAcc {
    /// Adds one sample: estimate `y`, denoised measurement `d`, true drift if known.
    pub fn add(&mut self, y: f64, d: f64, truth: Option<f64>) {
        if self.n == 0 && self.non_finite == 0 {
            self.d_min = f64::INFINITY;
            self.d_max = f64::NEG_INFINITY;
        }
        self.d_min = self.d_min.min(d);
        self.d_max = self.d_max.max(d);
        self.sum_sq_d += d * d;
        if let Some(t) = truth {
            self.sum_sq_truth += t * t;
        }
        if !y.is_finite() {
            self.non_finite += 1;
            return;
        }
        self.n += 1;
        let e = y - d;
        self.sum_sq_err_d += e * e;
        self.max_abs_err_d = self.max_abs_err_d.max(e.abs());
        if let Some(t) = truth {
            self.n_truth += 1;
            self.sum_sq_err_truth += (y - t) * (y - t);
        }
    }

    /// The figures; every one is `None` when some estimate was not finite (it diverged).
    pub fn figures(&self) -> Figures {
        let total = (self.n + self.non_finite).max(1) as f64;
        let ok = self.non_finite == 0 && self.n > 0;
        let rms_err_d = (self.sum_sq_err_d / self.n.max(1) as f64).sqrt();
        let rms_d = (self.sum_sq_d / total).sqrt();
        let range = self.d_max - self.d_min;
        let truth_ok = ok && self.n_truth == self.n;
        let rms_err_t = (self.sum_sq_err_truth / self.n_truth.max(1) as f64).sqrt();
        let rms_t = (self.sum_sq_truth / total).sqrt();
        let some = |c: bool, v: f64| (c && v.is_finite()).then_some(v);
        Figures {
            e_rel: some(ok && rms_d > 0.0, rms_err_d / rms_d),
            e_range: some(ok && range > 0.0, rms_err_d / range),
            e_max: some(ok && range > 0.0, self.max_abs_err_d / range),
            e_truth: some(truth_ok && rms_t > 0.0, rms_err_t / rms_t),
            rms_err_truth_dph: some(truth_ok, rms_err_t * 3600.0),
            rms_err_d_dph: some(ok, rms_err_d * 3600.0),
            rms_d_dph: rms_d * 3600.0,
            rms_truth_dph: (self.n_truth > 0 || self.non_finite > 0).then_some(rms_t * 3600.0),
            samples: self.n + self.non_finite,
            non_finite: self.non_finite,
        }
    }
}

/// The figures of one estimator.
#[derive(Debug, Clone, Serialize)]
pub struct Figures {
    /// RMS(y - d) / RMS(d).
    pub e_rel: Option<f64>,
    /// RMS(y - d) / (max d - min d).
    pub e_range: Option<f64>,
    /// max |y - d| / (max d - min d).
    pub e_max: Option<f64>,
    /// RMS(y - drift) / RMS(drift) (simulated records).
    pub e_truth: Option<f64>,
    /// RMS(y - drift), deg/h.
    pub rms_err_truth_dph: Option<f64>,
    /// RMS(y - d), deg/h.
    pub rms_err_d_dph: Option<f64>,
    /// RMS(d), deg/h: what e_rel is relative to (it includes any constant bias).
    pub rms_d_dph: f64,
    /// RMS(drift), deg/h.
    pub rms_truth_dph: Option<f64>,
    /// Samples scored.
    pub samples: u64,
    /// Estimates that were NaN or infinite (the estimator diverged).
    pub non_finite: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures() {
        let mut a = ErrorAcc::default();
        for (y, d, t) in [(1.0, 2.0, 1.5), (3.0, 2.0, 2.5), (2.0, 4.0, 3.0)] {
            a.add(y, d, Some(t));
        }
        let f = a.figures();
        let rms_err = ((1.0 + 1.0 + 4.0) / 3.0f64).sqrt();
        assert!(
            (f.e_rel.expect("finite") - rms_err / ((4.0 + 4.0 + 16.0) / 3.0f64).sqrt()).abs()
                < 1e-12
        );
        assert!((f.e_range.expect("finite") - rms_err / 2.0).abs() < 1e-12);
        assert!((f.e_max.expect("finite") - 1.0).abs() < 1e-12);
        a.add(f64::NAN, 1.0, None);
        assert!(a.figures().e_rel.is_none());
    }
}
