//! Navigation scores and causal baselines for drift compensation on a MOVING gyro.
//!
//! - [`NavRecord`]: a record with its truth (`true_rate_dps`, `drift_dps`, `moving`).
//! - [`HeadingAcc`] / [`NavScores`]: heading error `integral (compensated - true rate) dt`
//!   (trapezoid, deg), its RMS and final value, e_truth (deg/h RMS of estimated - true
//!   drift) split still / moving. [`DetectorAcc`] / [`DetectorScores`]: false-still and
//!   missed-still rates of a stillness detector against the `moving` truth.
//! - [`DriftEstimator`] baselines: [`NoCompensation`], [`AlignmentBias`], [`GatedKalman`]
//!   (ZARU), [`ThermalKalman`] (ZARU + temperature regression, on-line RLS or coefficients
//!   from [`fit_thermal`] on training records); [`SelfCalKalman`] (ZARU with its OWN detector, the noise
//!   reference measured on the unit's alignment; it ignores the still flags it is given).
//! - [`compare`] / [`table`]: an identifier's drift beside the five baselines (the first
//!   four with the identifier's still flags), as scores and as the text table of `replay` /
//!   `identify`.
//! - [`run`]: one estimator over one record; [`tune_gated_q`]: the gated Kalman's `q` on a
//!   log grid, picked by mean heading-error RMS on validation records ([`tune_selfcal_q`]:
//!   the same for [`SelfCalKalman`]).

mod baselines;
mod compare;
mod record;
mod score;
pub mod selfcal;
mod tune;

pub use baselines::{
    fit_thermal, AlignmentBias, DriftEstimator, GatedKalman, NoCompensation, TempRate, ThermalFit,
    ThermalKalman, ThermalKalmanConfig,
};
pub use compare::{
    compare, table, BaselineConfig, Compared, Comparer, Comparison, Row, TruthSample,
    NO_COMPENSATION, ROWS, SELFCAL_LABEL,
};
pub use record::NavRecord;
pub use score::{DetectorAcc, DetectorScores, HeadingAcc, NavScores, DPH_PER_DPS};
pub use selfcal::{tune_selfcal_q, SelfCalConfig, SelfCalKalman};
pub use tune::{least_mean, log_grid, tune_gated_q, Tuning};

/// One estimator's run over one record.
#[derive(Debug, Clone)]
pub struct Run {
    /// Scores over the record.
    pub scores: NavScores,
    /// Heading error at each sample, deg.
    pub heading_deg: Vec<f64>,
    /// Drift estimate at each sample, deg/s.
    pub drift_est_dps: Vec<f64>,
}

/// Runs `est` over `rec` with the still flags `still` (one per sample; e.g. the truth
/// `!moving`, a detector's calls or an external flag): compensated = rate - estimate.
/// Samples beyond `still.len()` are treated as moving.
pub fn run(rec: &NavRecord, est: &mut dyn DriftEstimator, still: &[bool]) -> Run {
    let mut acc = HeadingAcc::new();
    let n = rec.len();
    let mut heading_deg = Vec::with_capacity(n);
    let mut drift_est_dps = Vec::with_capacity(n);
    for k in 0..n {
        let temp = rec.temp_c.as_ref().and_then(|t| t.get(k).copied());
        let s = still.get(k).copied().unwrap_or(false);
        let d = est.push(rec.t_s[k], rec.rate_dps[k], temp, s);
        let h = acc.push(
            rec.t_s[k],
            rec.rate_dps[k] - d,
            rec.true_rate_dps[k],
            d,
            rec.drift_dps[k],
            rec.moving[k],
        );
        heading_deg.push(h);
        drift_est_dps.push(d);
    }
    Run {
        scores: acc.scores(),
        heading_deg,
        drift_est_dps,
    }
}

/// The scores on `rec` of a drift estimate computed beforehand (`drift_dps`, deg/s, one per
/// sample; 0 beyond it).
pub fn score_drift(rec: &NavRecord, drift_dps: &[f64]) -> NavScores {
    let mut acc = HeadingAcc::new();
    for k in 0..rec.len() {
        let d = drift_dps.get(k).copied().unwrap_or(0.0);
        acc.push(
            rec.t_s[k],
            rec.rate_dps[k] - d,
            rec.true_rate_dps[k],
            d,
            rec.drift_dps[k],
            rec.moving[k],
        );
    }
    acc.scores()
}

#[cfg(test)]
mod tests;
