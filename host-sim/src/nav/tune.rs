//! Tuning the gated Kalman filter's process noise on validation records.

use super::{run, GatedKalman, NavRecord};

/// Result of [`tune_gated_q`].
#[derive(Debug, Clone, PartialEq)]
pub struct Tuning {
    /// The chosen `q`, (deg/s)^2 per sample.
    pub q_dps2: f64,
    /// Its mean heading-error RMS over the validation records, deg.
    pub heading_rms_deg: f64,
    /// Every grid point: (q, mean heading-error RMS deg).
    pub grid: Vec<(f64, f64)>,
}

/// `per_decade` points per decade from `lo` to `hi` (both > 0, included), log-spaced.
pub fn log_grid(lo: f64, hi: f64, per_decade: usize) -> Vec<f64> {
    if !(lo > 0.0 && hi >= lo && per_decade > 0) {
        return Vec::new();
    }
    let decades = (hi / lo).log10();
    let n = (decades * per_decade as f64).round() as usize;
    (0..=n)
        .map(|i| lo * 10f64.powf(decades * i as f64 / n.max(1) as f64))
        .collect()
}

/// Picks the gated Kalman filter's `q` from `q_grid` by the mean heading-error RMS over
/// `records`, each run with its truth still flags (`!moving`) and the noise variance
/// `r_dps2`. Ties go to the smaller `q`. None when the grid or the record set is empty.
pub fn tune_gated_q(records: &[NavRecord], r_dps2: f64, q_grid: &[f64]) -> Option<Tuning> {
    least_mean(records, q_grid, |q, r| {
        let mut k = GatedKalman::new(q, r_dps2);
        run(r, &mut k, &r.still_truth()).scores.heading_rms_deg
    })
}

/// The grid point of `q_grid` with the least mean `score(q, record)` over `records`; ties
/// go to the smaller `q` (the first). None when the grid or the record set is empty or no
/// grid point scores a finite value.
pub fn least_mean<R>(
    records: &[R],
    q_grid: &[f64],
    score: impl Fn(f64, &R) -> f64,
) -> Option<Tuning> {
    if records.is_empty() {
        return None;
    }
    let grid: Vec<(f64, f64)> = q_grid
        .iter()
        .map(|&q| {
            let sum: f64 = records.iter().map(|r| score(q, r)).sum();
            (q, sum / records.len() as f64)
        })
        .collect();
    let best = grid.iter().copied().filter(|p| p.1.is_finite()).fold(
        None::<(f64, f64)>,
        |b, p| match b {
            Some(b) if b.1 <= p.1 => Some(b),
            _ => Some(p),
        },
    )?;
    Some(Tuning {
        q_dps2: best.0,
        heading_rms_deg: best.1,
        grid,
    })
}
