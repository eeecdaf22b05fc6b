//! How much of the drift is a function of known inputs (time since switch-on `T`, the
//! temperature channel and its rate), and the temperature-aware baselines a demanding user
//! would ask for.
//!
//! Everything here is batch least squares on the training records with a **separate
//! intercept per record** (the turn-on bias is not a function of any input): the rows of a
//! record are centred on the record's mean before they enter the normal equations. Every
//! 10th sample is used (the inputs are smooth; the figures do not change in the third digit).
//!
//! - `explained`: the share of the variance of the *time-varying* true drift (drift minus
//!   its record mean) that a basis explains, fitted against the truth on the training
//!   records, and the same coefficients applied to the validation records (with their own
//!   oracle intercepts): an upper bound of what any model of these inputs can predict.
//! - baselines: the regression fitted against the **measured rate** on the training records
//!   (what a user has, no truth needed); at run time `y = r(k) + K(X - r)(k)` with `K` the
//!   random-walk Kalman filter (q/r tuned on the training records like the plain one) run on
//!   the rate minus the regression: the filter then only tracks what the regression leaves.

use super::series::{Records, Series};
use anyhow::{anyhow, bail, Result};
use fog_core::baseline::RandomWalkKalman;
use fog_core::features::{FeatureMap, TimeTemp};
use serde::Serialize;

/// A basis of known inputs: scaled-free raw inputs `[t_s, temp_c, dtemp_c_per_s]` in, the
/// regressors out (no intercept: the per-record intercept is separate).
pub type Basis<'a> = &'a dyn Fn(&[f32; 3]) -> Vec<f64>;

/// The raw known inputs of every sample of a record (the [`TimeTemp`] feature map).
pub fn known_inputs(s: &Series) -> Result<Vec<[f32; 3]>> {
    let Some(temp) = s.temp_c.as_ref() else {
        bail!(
            "{}: no temp_c column (needed for the temperature inputs)",
            s.name
        );
    };
    let dt = s.sample_period_s() as f32;
    let mut f = TimeTemp::new(1.0 / dt);
    Ok(temp
        .iter()
        .enumerate()
        .map(|(k, &c)| f.next_with_temp(0.0, k as f32 * dt, c))
        .collect())
}

/// Normal equations of a per-record-centred regression.
struct Normal {
    p: usize,
    xtx: Vec<f64>,
    xty: Vec<f64>,
}

const STRIDE: usize = 10;

impl Normal {
    fn new(p: usize) -> Self {
        Self {
            p,
            xtx: vec![0.0; p * p],
            xty: vec![0.0; p],
        }
    }

    /// Adds one record: rows `x` (every sample), targets `y`.
    fn add_record(&mut self, rows: &[Vec<f64>], y: &[f64]) {
        let p = self.p;
        let n = rows.len().div_ceil(STRIDE).max(1) as f64;
        let mut mx = vec![0.0; p];
        let mut my = 0.0;
        for (r, &v) in rows.iter().zip(y).step_by(STRIDE) {
            for j in 0..p {
                mx[j] += r[j] / n;
            }
            my += v / n;
        }
        let mut c = vec![0.0; p];
        for (r, &v) in rows.iter().zip(y).step_by(STRIDE) {
            for j in 0..p {
                c[j] = r[j] - mx[j];
            }
            let cy = v - my;
            for i in 0..p {
                self.xty[i] += c[i] * cy;
                for j in 0..=i {
                    self.xtx[i * p + j] += c[i] * c[j];
                }
            }
        }
    }

    /// Solves with a tiny ridge (1e-9 of the mean diagonal) by Cholesky.
    fn solve(&self) -> Result<Vec<f64>> {
        let p = self.p;
        let mut a = self.xtx.clone();
        for i in 0..p {
            for j in 0..i {
                a[j * p + i] = a[i * p + j];
            }
        }
        let mean_diag = (0..p).map(|i| a[i * p + i]).sum::<f64>() / p.max(1) as f64;
        let ridge = 1e-9 * mean_diag.max(1e-300);
        for i in 0..p {
            a[i * p + i] += ridge;
        }
        // Cholesky: a = L L^T, in place (lower triangle).
        for j in 0..p {
            let mut d = a[j * p + j];
            for k in 0..j {
                d -= a[j * p + k] * a[j * p + k];
            }
            if d <= 0.0 || !d.is_finite() {
                bail!("least squares: the basis is singular on the training records");
            }
            let d = d.sqrt();
            a[j * p + j] = d;
            for i in j + 1..p {
                let mut s = a[i * p + j];
                for k in 0..j {
                    s -= a[i * p + k] * a[j * p + k];
                }
                a[i * p + j] = s / d;
            }
        }
        let mut z = self.xty.clone();
        for i in 0..p {
            for k in 0..i {
                z[i] -= a[i * p + k] * z[k];
            }
            z[i] /= a[i * p + i];
        }
        for i in (0..p).rev() {
            for k in i + 1..p {
                z[i] -= a[k * p + i] * z[k];
            }
            z[i] /= a[i * p + i];
        }
        Ok(z)
    }
}

/// Share of the time-varying true drift explained by one basis.
#[derive(Debug, Clone, Serialize)]
pub struct Explained {
    /// What the basis is.
    pub basis: &'static str,
    /// Regressors (without the per-record intercept).
    pub regressors: usize,
    /// 1 - SSE/SST of the per-record-centred truth, training records (fitted there).
    pub r2_train: f64,
    /// The same with the training coefficients on the validation records.
    pub r2_validate: f64,
    /// RMS of what the basis leaves of the time-varying drift on the validation records,
    /// deg/h.
    pub rms_left_validate_dph: f64,
}

/// The variance decomposition on which the temperature inputs rest.
#[derive(Debug, Clone, Serialize)]
pub struct DriftDecomposition {
    /// RMS of the true drift, deg/h (validation records).
    pub rms_drift_dph: f64,
    /// RMS of the per-record mean of the true drift (the turn-on bias and the record's
    /// average of everything else), deg/h (validation records).
    pub rms_record_mean_dph: f64,
    /// RMS of the true drift minus its record mean, deg/h (validation records).
    pub rms_time_varying_dph: f64,
    /// Per basis.
    pub explained: Vec<Explained>,
}

fn truth_rows(s: &Series) -> Result<Vec<f64>> {
    s.drift_dps
        .as_ref()
        .map(|d| d.iter().map(|&v| f64::from(v)).collect())
        .ok_or_else(|| anyhow!("{}: no drift_dps column", s.name))
}

/// Per basis (SSE, SST) of the centred truth; RMS of the drift and of its record means,
/// deg/h; samples.
type R2Sums = (Vec<(f64, f64)>, f64, f64, f64);

fn r2_on(
    records: &dyn Records,
    bases: &[(&'static str, Basis<'_>)],
    coefs: &[Vec<f64>],
) -> Result<R2Sums> {
    // (SSE, SST) per basis; and sums for the RMS figures.
    let mut out = vec![(0.0, 0.0); bases.len()];
    let (mut sum_d2, mut sum_m2, mut n_all) = (0.0, 0.0, 0.0);
    for i in 0..records.len() {
        let s = records.get(i)?;
        let x = known_inputs(&s)?;
        let d = truth_rows(&s)?;
        let n = d.len() as f64;
        let md = d.iter().sum::<f64>() / n;
        sum_d2 += d.iter().map(|v| v * v).sum::<f64>();
        sum_m2 += md * md * n;
        n_all += n;
        for (bi, (_, basis)) in bases.iter().enumerate() {
            let pred: Vec<f64> = x
                .iter()
                .map(|r| basis(r).iter().zip(&coefs[bi]).map(|(a, b)| a * b).sum())
                .collect();
            let mp = pred.iter().sum::<f64>() / n;
            for (p, v) in pred.iter().zip(&d) {
                let e = (v - md) - (p - mp);
                out[bi].0 += e * e;
                out[bi].1 += (v - md) * (v - md);
            }
        }
    }
    Ok((
        out,
        (sum_d2 / n_all).sqrt() * 3600.0,
        (sum_m2 / n_all).sqrt() * 3600.0,
        n_all,
    ))
}

/// Fits each basis against the true drift on `train` and scores it on `validate`.
pub fn decompose(
    train: &dyn Records,
    validate: &dyn Records,
    bases: &[(&'static str, Basis<'_>)],
) -> Result<DriftDecomposition> {
    let mut normals: Vec<Normal> = Vec::new();
    for i in 0..train.len() {
        let s = train.get(i)?;
        let x = known_inputs(&s)?;
        let d = truth_rows(&s)?;
        for (bi, (_, basis)) in bases.iter().enumerate() {
            let rows: Vec<Vec<f64>> = x.iter().map(basis).collect();
            if normals.len() <= bi {
                normals.push(Normal::new(rows.first().map_or(0, Vec::len)));
            }
            normals[bi].add_record(&rows, &d);
        }
    }
    let coefs = normals
        .iter()
        .map(Normal::solve)
        .collect::<Result<Vec<_>>>()?;
    let (tr, _, _, _) = r2_on(train, bases, &coefs)?;
    let (va, rms_d, rms_m, n) = r2_on(validate, bases, &coefs)?;
    let rms_tv = (va.first().map_or(0.0, |v| v.1) / n).sqrt() * 3600.0;
    Ok(DriftDecomposition {
        rms_drift_dph: rms_d,
        rms_record_mean_dph: rms_m,
        rms_time_varying_dph: rms_tv,
        explained: bases
            .iter()
            .enumerate()
            .map(|(bi, (name, _))| Explained {
                basis: name,
                regressors: coefs[bi].len(),
                r2_train: 1.0 - tr[bi].0 / tr[bi].1,
                r2_validate: 1.0 - va[bi].0 / va[bi].1,
                rms_left_validate_dph: (va[bi].0 / n).sqrt() * 3600.0,
            })
            .collect(),
    })
}

/// A regression of the measured rate on known inputs, fitted on the training records.
#[derive(Debug, Clone, Serialize)]
pub struct RateRegression {
    /// What the basis is.
    pub basis: &'static str,
    /// Coefficients, deg/s per regressor.
    pub coefficients: Vec<f64>,
}

/// Fits `basis` against the measured rate (per-record intercepts) on `train`.
pub fn fit_rate(
    train: &dyn Records,
    name: &'static str,
    basis: Basis<'_>,
) -> Result<RateRegression> {
    let mut normal: Option<Normal> = None;
    for i in 0..train.len() {
        let s = train.get(i)?;
        let x = known_inputs(&s)?;
        let rows: Vec<Vec<f64>> = x.iter().map(basis).collect();
        let y: Vec<f64> = s.rate_dps.iter().map(|&v| f64::from(v)).collect();
        normal
            .get_or_insert_with(|| Normal::new(rows.first().map_or(0, Vec::len)))
            .add_record(&rows, &y);
    }
    let normal = normal.ok_or_else(|| anyhow!("no training record"))?;
    Ok(RateRegression {
        basis: name,
        coefficients: normal.solve()?,
    })
}

impl RateRegression {
    /// The regression's value for one sample's known inputs, deg/s.
    pub fn value(&self, basis: Basis<'_>, x: &[f32; 3]) -> f64 {
        basis(x)
            .iter()
            .zip(&self.coefficients)
            .map(|(a, b)| a * b)
            .sum()
    }

    /// The baseline's estimates for a record: `r(k) + K(X - r)(k)`.
    pub fn track(&self, basis: Basis<'_>, s: &Series, q_over_r: f64) -> Result<Vec<f64>> {
        let x = known_inputs(s)?;
        let mut kf = RandomWalkKalman::new(q_over_r as f32, 1.0);
        Ok(s.rate_dps
            .iter()
            .zip(&x)
            .map(|(&z, xi)| {
                let r = self.value(basis, xi);
                r + f64::from(kf.push((f64::from(z) - r) as f32))
            })
            .collect())
    }
}

/// The q/r of the Kalman filter on the rate minus `reg`: the grid value with the least
/// squared error on the first `records` training records, against the truth when known,
/// else against `reference(s)` (the denoised rate).
pub fn tune_q(
    train: &dyn Records,
    records: usize,
    grid: &[f64],
    reg: &RateRegression,
    basis: Basis<'_>,
    skip: usize,
    reference: &dyn Fn(&Series) -> Result<Vec<f64>>,
) -> Result<f64> {
    let mut sq = vec![0.0f64; grid.len()];
    for i in 0..train.len().min(records) {
        let s = train.get(i)?;
        let refv = match &s.drift_dps {
            Some(t) => t.iter().map(|&v| f64::from(v)).collect(),
            None => reference(&s)?,
        };
        for (qi, q) in grid.iter().enumerate() {
            let y = reg.track(basis, &s, *q)?;
            for (k, (a, b)) in y.iter().zip(&refv).enumerate() {
                if k >= skip {
                    sq[qi] += (a - b).powi(2);
                }
            }
        }
    }
    let best = sq
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    Ok(grid[best])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_record_intercepts_and_slope() {
        // y = 3 + 2 x on record 1, -5 + 2 x on record 2: slope 2 whatever the intercepts.
        let mut n = Normal::new(1);
        for c in [3.0, -5.0] {
            let rows: Vec<Vec<f64>> = (0..100).map(|k| vec![k as f64]).collect();
            let y: Vec<f64> = (0..100).map(|k| c + 2.0 * k as f64).collect();
            n.add_record(&rows, &y);
        }
        let w = n.solve().expect("regular");
        // The solver adds a ridge of 1e-9 x the mean diagonal, which shrinks the slope by
        // about 1e-9 relative: the tolerance allows ten times that, no more.
        assert!((w[0] - 2.0).abs() < 2e-8, "{w:?}");
    }
}
