//! Scores a navigator reads: heading error, drift error split still / moving, detector rates.

use serde::Serialize;

/// deg/s -> deg/h.
pub const DPH_PER_DPS: f64 = 3600.0;

/// Heading error and drift error of one estimator over one record, sample by sample.
///
/// Heading error `h(t) = integral_0^t (compensated - true rate) dt`, deg, by the TRAPEZOID
/// rule on the samples' own `t_s` (gaps are bridged by one trapezoid), `h = 0` at the first
/// sample. Its RMS is over samples (sample-weighted, not time-weighted).
#[derive(Debug, Clone, Default)]
pub struct HeadingAcc {
    n: u64,
    last: Option<(f64, f64)>,
    heading_deg: f64,
    sum_sq_heading: f64,
    max_abs_heading_deg: f64,
    still: Truth,
    moving: Truth,
    non_finite: u64,
}

#[derive(Debug, Clone, Copy, Default)]
struct Truth {
    n: u64,
    sum_sq: f64,
}

impl HeadingAcc {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one sample; returns the heading error at it, deg.
    /// `drift_est_dps` is the estimator's drift, `drift_dps` the true drift, `moving` the
    /// ground truth (from the record's `moving` column).
    pub fn push(
        &mut self,
        t_s: f64,
        compensated_dps: f64,
        true_rate_dps: f64,
        drift_est_dps: f64,
        drift_dps: f64,
        moving: bool,
    ) -> f64 {
        let e = compensated_dps - true_rate_dps;
        if !(e.is_finite() && t_s.is_finite()) {
            self.non_finite += 1;
            return self.heading_deg;
        }
        if let Some((t0, e0)) = self.last {
            self.heading_deg += 0.5 * (e0 + e) * (t_s - t0);
        }
        self.last = Some((t_s, e));
        self.n += 1;
        self.sum_sq_heading += self.heading_deg * self.heading_deg;
        self.max_abs_heading_deg = self.max_abs_heading_deg.max(self.heading_deg.abs());
        let d = (drift_est_dps - drift_dps) * DPH_PER_DPS;
        if d.is_finite() {
            let acc = if moving {
                &mut self.moving
            } else {
                &mut self.still
            };
            acc.n += 1;
            acc.sum_sq += d * d;
        }
        self.heading_deg
    }

    /// The scores so far.
    pub fn scores(&self) -> NavScores {
        let rms = |t: Truth| (t.n > 0).then(|| (t.sum_sq / t.n as f64).sqrt());
        let all = Truth {
            n: self.still.n + self.moving.n,
            sum_sq: self.still.sum_sq + self.moving.sum_sq,
        };
        NavScores {
            samples: self.n,
            non_finite: self.non_finite,
            heading_rms_deg: (self.sum_sq_heading / self.n.max(1) as f64).sqrt(),
            heading_final_deg: self.heading_deg,
            heading_max_abs_deg: self.max_abs_heading_deg,
            e_truth_dph: rms(all),
            e_truth_still_dph: rms(self.still),
            e_truth_moving_dph: rms(self.moving),
        }
    }
}

/// Scores of one estimator on one record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NavScores {
    /// Samples scored.
    pub samples: u64,
    /// Samples skipped because the compensated rate was not finite.
    pub non_finite: u64,
    /// RMS of the heading error over the record, deg.
    pub heading_rms_deg: f64,
    /// Heading error at the last sample, deg.
    pub heading_final_deg: f64,
    /// Largest |heading error|, deg.
    pub heading_max_abs_deg: f64,
    /// RMS of (estimated - true drift) over every sample, deg/h.
    pub e_truth_dph: Option<f64>,
    /// The same over the still samples (None when there are none), deg/h.
    pub e_truth_still_dph: Option<f64>,
    /// The same over the moving samples (None when there are none), deg/h.
    pub e_truth_moving_dph: Option<f64>,
}

/// A stillness detector against the `moving` truth.
#[derive(Debug, Clone, Copy, Default)]
pub struct DetectorAcc {
    moving: u64,
    still: u64,
    false_still: u64,
    missed_still: u64,
}

impl DetectorAcc {
    /// Adds one sample: the truth and the detector's call.
    pub fn push(&mut self, moving: bool, called_still: bool) {
        if moving {
            self.moving += 1;
            self.false_still += u64::from(called_still);
        } else {
            self.still += 1;
            self.missed_still += u64::from(!called_still);
        }
    }

    /// The rates so far.
    pub fn scores(&self) -> DetectorScores {
        let frac = |a: u64, b: u64| (b > 0).then(|| a as f64 / b as f64);
        DetectorScores {
            moving_samples: self.moving,
            still_samples: self.still,
            false_still_rate: frac(self.false_still, self.moving),
            missed_still_rate: frac(self.missed_still, self.still),
        }
    }
}

/// Detector scores (fractions: 0.015 is 1.5 %).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DetectorScores {
    /// Moving samples in the record.
    pub moving_samples: u64,
    /// Still samples in the record.
    pub still_samples: u64,
    /// Moving samples called still / moving samples (None without moving samples): the
    /// dangerous error, it lets rotation into the level.
    pub false_still_rate: Option<f64>,
    /// Still samples called moving / still samples (None without still samples): lost
    /// learning time.
    pub missed_still_rate: Option<f64>,
}
