//! Batch least-squares training of the motion model's output weights, with the ridge
//! picked by leave-one-record-out cross-validation: the bench trainer of
//! `host-sim identify --preset motion` (the default; the paper's DRLS,
//! [`crate::motion::MotionTrainer`], is kept as the reference trainer).
//!
//! Why not DRLS on the bench: training happens once, on the host, over every static record
//! of the family. DRLS is diagonal (each weight sees the others as fixed), and with the
//! forgetting factor it needs to converge at all (0.9998, a memory of about 3 records of
//! 1800 s) its weights are those of the last few records, not of the family. Least squares
//! over all records gives every record the same weight and takes the neurons' overlap into
//! account exactly (a 16 x 16 system).
//!
//! The problem solved (per record `r`, its full detector windows `j`, `h_rj` the network's
//! hidden values at the window's first sample, `d_rj` the window mean of the denoised rate,
//! exactly the targets of [`crate::motion::MotionTrainer`]):
//!
//! ```text
//! min_w  sum_r sum_j ( (d_rj - mean_j d_rj) - w . (h_rj - mean_j h_rj) )^2  +  rho s |w|^2
//! ```
//!
//! Centring inputs and targets per record (the "within" estimator) removes each unit's
//! turn-on bias without a per-record intercept weight: the model learns what changes within
//! a power-on, which is what the level cannot know in motion; the constant left is the
//! level's. `s = trace(G) / L` makes `rho` dimensionless. The normal equations are held in
//! f64 (sums over 10^4..10^5 windows of values near 1e-3 deg/s) and solved by Cholesky.
//! Fixed sizes, no heap: [`NormalEquations`] is 2.2 KiB.

// Dense 16 x 16 linear algebra: index loops read as the formulas they implement.
#![allow(clippy::needless_range_loop)]

use crate::motion::{for_each_window, MotionError, MotionModel, MOTION_L};

/// Ridge values (`rho`, relative to the mean diagonal of the Gram matrix) tried by
/// [`cross_validate`]: 1e-8 .. 10, one per decade. Beside them the cross-validation always
/// considers the empty model (`w = 0`).
pub const RIDGE_GRID: [f64; 10] = [1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0];

/// Within-record normal equations of one or more static records (sums over their full
/// detector windows; see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalEquations {
    /// `sum (h - mean h)(h - mean h)^T`, per record then summed.
    gram: [[f64; MOTION_L]; MOTION_L],
    /// `sum (h - mean h)(d - mean d)`, (deg/s).
    cross: [f64; MOTION_L],
    /// `sum (d - mean d)^2`, (deg/s)^2: the squared error of the empty model.
    target_ss: f64,
    /// Windows summed.
    windows: u64,
    /// Records summed (negative counts never arise: [`Self::without`] checks).
    records: u32,
}

impl Default for NormalEquations {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl NormalEquations {
    /// No record.
    pub const EMPTY: Self = Self {
        gram: [[0.0; MOTION_L]; MOTION_L],
        cross: [0.0; MOTION_L],
        target_ss: 0.0,
        windows: 0,
        records: 0,
    };

    /// The equations of one static record from power-on: `rate_dps` at `sample_rate_hz`,
    /// `temp_c` the same length or `None` (the model's reference temperature), windows of
    /// `window_s` (the detector's), the targets and inputs of
    /// [`crate::motion::MotionTrainer::train_record`] (windows holding a non-finite rate are
    /// skipped). Only `model`'s layout and scaling are used, not its weights. Also returns
    /// the record's intercept (the mean rate of its full windows, deg/s), which the
    /// trainer's targets are taken relative to.
    pub fn from_record(
        model: &MotionModel,
        rate_dps: &[f32],
        temp_c: Option<&[f32]>,
        sample_rate_hz: f32,
        window_s: f32,
    ) -> Result<(Self, f32), MotionError> {
        if !(window_s > 0.0 && window_s.is_finite()) {
            return Err(MotionError::BadStillConfig);
        }
        let mut raw_hh = [[0.0f64; MOTION_L]; MOTION_L];
        let mut raw_hd = [0.0f64; MOTION_L];
        let mut sum_h = [0.0f64; MOTION_L];
        let (mut sum_d, mut sum_dd, mut n) = (0.0f64, 0.0f64, 0u64);
        let mut h = [0.0f32; MOTION_L];
        let intercept = for_each_window(
            rate_dps,
            temp_c,
            sample_rate_hz,
            window_s,
            model.scaling.offset[1],
            |_, x, d| {
                model.hidden(x, &mut h);
                let d = f64::from(d);
                for i in 0..MOTION_L {
                    let hi = f64::from(h[i]);
                    sum_h[i] += hi;
                    raw_hd[i] += hi * d;
                    for j in 0..=i {
                        raw_hh[i][j] += hi * f64::from(h[j]);
                    }
                }
                sum_d += d;
                sum_dd += d * d;
                n += 1;
            },
        )?;
        let mut out = Self::EMPTY;
        if n == 0 {
            out.records = 1;
            return Ok((out, intercept));
        }
        let nf = n as f64;
        let mean_d = sum_d / nf;
        for i in 0..MOTION_L {
            let mi = sum_h[i] / nf;
            out.cross[i] = raw_hd[i] - nf * mi * mean_d;
            for j in 0..=i {
                let g = raw_hh[i][j] - nf * mi * (sum_h[j] / nf);
                out.gram[i][j] = g;
                out.gram[j][i] = g;
            }
        }
        out.target_ss = (sum_dd - nf * mean_d * mean_d).max(0.0);
        out.windows = n;
        out.records = 1;
        Ok((out, intercept))
    }

    /// Adds another record's (or set's) equations.
    pub fn add(&mut self, other: &Self) {
        for i in 0..MOTION_L {
            for j in 0..MOTION_L {
                self.gram[i][j] += other.gram[i][j];
            }
            self.cross[i] += other.cross[i];
        }
        self.target_ss += other.target_ss;
        self.windows += other.windows;
        self.records += other.records;
    }

    /// The equations of the model restricted to the neurons `keep`: the others' rows,
    /// columns and cross terms are zeroed, so that [`Self::solve`] (any ridge > 0) gives them
    /// weight 0 and [`Self::sse`] scores the restricted model. For the host's comparison of
    /// the whole model with its linear links alone (`host-sim identify`).
    pub fn keep_only(&self, keep: &[bool; MOTION_L]) -> Self {
        let mut out = *self;
        for i in 0..MOTION_L {
            for j in 0..MOTION_L {
                if !(keep[i] && keep[j]) {
                    out.gram[i][j] = 0.0;
                }
            }
            if !keep[i] {
                out.cross[i] = 0.0;
            }
        }
        out
    }

    /// These equations less `part` (a record that was added): the training set of a
    /// leave-one-out fold. `None` when `part` holds more records or windows than `self`.
    pub fn without(&self, part: &Self) -> Option<Self> {
        if part.records > self.records || part.windows > self.windows {
            return None;
        }
        let mut out = *self;
        for i in 0..MOTION_L {
            for j in 0..MOTION_L {
                out.gram[i][j] -= part.gram[i][j];
            }
            out.cross[i] -= part.cross[i];
        }
        out.target_ss = (out.target_ss - part.target_ss).max(0.0);
        out.windows -= part.windows;
        out.records -= part.records;
        Some(out)
    }

    /// Windows summed.
    pub fn windows(&self) -> u64 {
        self.windows
    }

    /// Records summed.
    pub fn records(&self) -> u32 {
        self.records
    }

    /// Squared error of the empty model (`w = 0`), (deg/s)^2 summed over the windows.
    pub fn target_ss(&self) -> f64 {
        self.target_ss
    }

    /// Squared error of weights `w` on these records, (deg/s)^2 summed over the windows:
    /// `target_ss - 2 w.c + w^T G w` (exact, up to rounding).
    pub fn sse(&self, w: &[f32; MOTION_L]) -> f64 {
        let mut quad = 0.0;
        let mut lin = 0.0;
        for i in 0..MOTION_L {
            let wi = f64::from(w[i]);
            lin += wi * self.cross[i];
            let mut row = 0.0;
            for j in 0..MOTION_L {
                row += self.gram[i][j] * f64::from(w[j]);
            }
            quad += wi * row;
        }
        (self.target_ss - 2.0 * lin + quad).max(0.0)
    }

    /// The ridge solution for `rho` (relative to the mean diagonal of the Gram matrix;
    /// `rho > 0` keeps the system positive definite although the time Gaussians' sum is
    /// nearly constant and so nearly removed by the centring). Errors: `rho` not finite and
    /// `>= 0`, no windows, or a system that is not positive definite (`rho = 0` on
    /// collinear inputs) ([`MotionError::BadTrainer`]).
    pub fn solve(&self, rho: f64) -> Result<[f32; MOTION_L], MotionError> {
        if !(rho >= 0.0 && rho.is_finite()) || self.windows == 0 {
            return Err(MotionError::BadTrainer);
        }
        let trace: f64 = (0..MOTION_L).map(|i| self.gram[i][i]).sum();
        if !(trace > 0.0 && trace.is_finite()) {
            return Err(MotionError::BadTrainer);
        }
        let mut a = self.gram;
        let add = rho * trace / MOTION_L as f64;
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += add;
        }
        // Cholesky A = L L^T, in place in the lower triangle.
        for j in 0..MOTION_L {
            let mut diag = a[j][j];
            for k in 0..j {
                diag -= a[j][k] * a[j][k];
            }
            if diag.is_nan() || diag <= 1e-14 * trace {
                return Err(MotionError::BadTrainer);
            }
            let l = libm::sqrt(diag);
            a[j][j] = l;
            for i in j + 1..MOTION_L {
                let mut v = a[i][j];
                for k in 0..j {
                    v -= a[i][k] * a[j][k];
                }
                a[i][j] = v / l;
            }
        }
        // L y = c, then L^T w = y.
        let mut y = self.cross;
        for i in 0..MOTION_L {
            for k in 0..i {
                y[i] -= a[i][k] * y[k];
            }
            y[i] /= a[i][i];
        }
        for i in (0..MOTION_L).rev() {
            for k in i + 1..MOTION_L {
                y[i] -= a[k][i] * y[k];
            }
            y[i] /= a[i][i];
        }
        let mut w = [0.0f32; MOTION_L];
        for (wi, yi) in w.iter_mut().zip(y) {
            if !yi.is_finite() {
                return Err(MotionError::BadTrainer);
            }
            *wi = yi as f32;
        }
        Ok(w)
    }
}

/// What [`cross_validate`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossValidation {
    /// The ridge with the smallest pooled held-out error; `None`: the empty model (`w = 0`)
    /// predicted the held-out records better than every ridge (the model does not transfer
    /// between units).
    pub rho: Option<f64>,
    /// Pooled held-out gain of the pick: `1 - SSE / SSE(w = 0)` (0 for the empty model).
    pub heldout_gain: f64,
    /// Pooled held-out gain of the smallest ridge of the grid (the least-shrunk model),
    /// for comparison.
    pub heldout_gain_least_ridge: f64,
}

/// Leave-one-record-out over `records` (each one record's [`NormalEquations`]): for each
/// `rho` of `grid`, the model fitted on all records but one predicts the one left out; the
/// pooled held-out squared error picks `rho`, or the empty model when none beats it.
/// `None` with fewer than 2 records or when no fold can be solved.
pub fn cross_validate(records: &[NormalEquations], grid: &[f64]) -> Option<CrossValidation> {
    if records.len() < 2 || grid.is_empty() {
        return None;
    }
    let mut all = NormalEquations::EMPTY;
    for r in records {
        all.add(r);
    }
    let zero: f64 = records.iter().map(|r| r.target_ss).sum();
    if zero.is_nan() || zero <= 0.0 {
        return None;
    }
    let mut best: Option<(f64, f64)> = None;
    let mut least_ridge = f64::NAN;
    for (g, &rho) in grid.iter().enumerate() {
        let mut sse = 0.0;
        let mut ok = true;
        for r in records {
            match all.without(r).map(|train| train.solve(rho)) {
                Some(Ok(w)) => sse += r.sse(&w),
                _ => {
                    ok = false;
                    break;
                }
            }
        }
        if !ok {
            continue;
        }
        if g == 0 {
            least_ridge = 1.0 - sse / zero;
        }
        if best.is_none_or(|(_, b)| sse < b) {
            best = Some((rho, sse));
        }
    }
    let (rho, sse) = best?;
    Some(if sse < zero {
        CrossValidation {
            rho: Some(rho),
            heldout_gain: 1.0 - sse / zero,
            heldout_gain_least_ridge: least_ridge,
        }
    } else {
        CrossValidation {
            rho: None,
            heldout_gain: 0.0,
            heldout_gain_least_ridge: least_ridge,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::REFERENCE_TEMP_C;
    use crate::still::SensorConfig;
    use crate::test_noise::Noise;
    extern crate std;
    use std::vec::Vec;

    const S: SensorConfig = SensorConfig::ECORE_2000;

    fn record(seed: u64, bias: f32, shape: &dyn Fn(f32) -> f32, n: usize) -> Vec<f32> {
        let mut z = Noise(seed);
        let sigma = S.sample_var_dps2().sqrt();
        (0..n)
            .map(|k| bias + shape(k as f32 * 0.01) + sigma * z.normal())
            .collect()
    }

    fn warmup(t: f32) -> f32 {
        3.0 / 3600.0 * libm::expf(-t / 600.0)
    }

    /// RMS over 25..1775 s of the centred difference between the model and `shape`, deg/h.
    fn centred_rms_dph(m: &MotionModel, shape: &dyn Fn(f32) -> f32) -> f32 {
        let x = |t: f32| [t, REFERENCE_TEMP_C, 0.0];
        let diff: Vec<f32> = (0..36)
            .map(|i| {
                let t = 25.0 + 50.0 * i as f32;
                (m.eval(&x(t)) - shape(t)) * 3600.0
            })
            .collect();
        let c = diff.iter().sum::<f32>() / diff.len() as f32;
        (diff.iter().map(|d| (d - c) * (d - c)).sum::<f32>() / diff.len() as f32).sqrt()
    }

    #[test]
    fn sse_equals_the_direct_sum_and_solve_is_its_minimum() {
        // Float reference: the centred squared error summed window by window in f64.
        let model = MotionModel::standard(600.0).expect("test");
        let rate = record(3, 1e-3, &warmup, 60_000);
        let (ne, _) = NormalEquations::from_record(&model, &rate, None, 100.0, 1.0).expect("test");
        assert_eq!((ne.windows(), ne.records()), (600, 1));
        let w = ne.solve(1e-6).expect("test");
        let mut m = model;
        m.weights = w;
        let (mut xs, mut ds) = (Vec::new(), Vec::new());
        for_each_window(&rate, None, 100.0, 1.0, REFERENCE_TEMP_C, |_, x, d| {
            xs.push(f64::from(m.eval(x)));
            ds.push(f64::from(d));
        })
        .expect("test");
        let md = ds.iter().sum::<f64>() / ds.len() as f64;
        let mm = xs.iter().sum::<f64>() / xs.len() as f64;
        let direct: f64 = ds
            .iter()
            .zip(&xs)
            .map(|(d, x)| ((d - md) - (x - mm)).powi(2))
            .sum();
        let via = ne.sse(&w);
        assert!((via / direct - 1.0).abs() < 1e-4, "{via} vs {direct}");
        let zero: f64 = ds.iter().map(|d| (d - md).powi(2)).sum();
        assert!((ne.target_ss() / zero - 1.0).abs() < 1e-9);
        // The solution beats small perturbations of itself (the ridge term is tiny).
        for k in 0..MOTION_L {
            for s in [-1.0f32, 1.0] {
                let mut p = w;
                p[k] += s * 2e-5;
                assert!(ne.sse(&p) >= via * (1.0 - 1e-9), "weight {k} {s}");
            }
        }
    }

    #[test]
    fn learns_the_shared_shape_from_every_record_not_the_last_ones() {
        // Six units with the same 3 deg/h warm-up and their own offsets, then two more
        // records with a DIFFERENT shape (a 3 deg/h rise): least squares weighs all eight
        // equally, so the shape it learns is the mean (6 x warm-up + 2 x rise) / 8, to
        // within the noise.
        let model = MotionModel::standard(1800.0).expect("test");
        let rise = |t: f32| -warmup(t);
        let mut all = NormalEquations::EMPTY;
        for r in 0..8u64 {
            let bias = (r as f32 - 3.5) * 2.0 / 3600.0;
            let shape: &dyn Fn(f32) -> f32 = if r < 6 { &warmup } else { &rise };
            let rate = record(50 + r, bias, shape, 180_000);
            all.add(
                &NormalEquations::from_record(&model, &rate, None, 100.0, 1.0)
                    .expect("test")
                    .0,
            );
        }
        let mut m = model;
        m.weights = all.solve(1e-4).expect("test");
        let mean = |t: f32| (6.0 * warmup(t) + 2.0 * rise(t)) / 8.0;
        let rms = centred_rms_dph(&m, &mean);
        // Noise floor: 4 deg/h per window mean, 14,400 windows over 14 Gaussians.
        assert!(rms < 0.25, "rms {rms} deg/h");
        // And it is not the last records' shape (the rise): that one is 1.5 deg/h away.
        assert!(centred_rms_dph(&m, &rise) > 1.0);
    }

    #[test]
    fn cross_validation_keeps_a_shared_shape_and_drops_unit_specific_ones() {
        let model = MotionModel::standard(600.0).expect("test");
        let eq = |rate: &[f32]| {
            NormalEquations::from_record(&model, rate, None, 100.0, 1.0)
                .expect("test")
                .0
        };
        // Shared: every unit has the same 10 deg/h warm-up (tau 150 s) plus its offset.
        let shared_shape = |t: f32| 10.0 / 3600.0 * libm::expf(-t / 150.0);
        let shared: Vec<_> = (0..5u64)
            .map(|r| {
                eq(&record(
                    100 + r,
                    (r as f32 - 2.0) * 3.0 / 3600.0,
                    &shared_shape,
                    60_000,
                ))
            })
            .collect();
        let cv = cross_validate(&shared, &RIDGE_GRID).expect("test");
        assert!(cv.rho.is_some() && cv.heldout_gain > 0.1, "{cv:?}");
        // Unit-specific: each unit's warm-up has its own sign and size (mean zero over the
        // family): nothing transfers, the empty model wins.
        let own: Vec<_> = (0..5u64)
            .map(|r| {
                let a = [8.0f32, -10.0, 6.0, -7.0, 3.0][r as usize] / 3600.0;
                eq(&record(
                    200 + r,
                    0.0,
                    &|t| a * libm::expf(-t / 150.0),
                    60_000,
                ))
            })
            .collect();
        let cv = cross_validate(&own, &RIDGE_GRID).expect("test");
        assert!(cv.rho.is_none() && cv.heldout_gain == 0.0, "{cv:?}");
        assert!(cv.heldout_gain_least_ridge < 0.0, "{cv:?}");
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let model = MotionModel::standard(600.0).expect("test");
        assert_eq!(
            NormalEquations::EMPTY.solve(1e-3),
            Err(MotionError::BadTrainer)
        );
        let rate = record(1, 0.0, &warmup, 1000);
        let (ne, _) = NormalEquations::from_record(&model, &rate, None, 100.0, 1.0).expect("test");
        assert_eq!(ne.solve(f64::NAN), Err(MotionError::BadTrainer));
        assert_eq!(ne.solve(-1.0), Err(MotionError::BadTrainer));
        assert!(NormalEquations::from_record(&model, &rate[..150], None, 100.0, 1.0).is_err());
        assert!(NormalEquations::from_record(&model, &rate, None, 100.0, f32::NAN).is_err());
        assert!(NormalEquations::EMPTY.without(&ne).is_none());
        assert!(cross_validate(&[ne], &RIDGE_GRID).is_none());
        // A record of NaN only: no window, no equation, no panic.
        let nan = [f32::NAN; 1000];
        let (e, _) = NormalEquations::from_record(&model, &nan, None, 100.0, 1.0).expect("test");
        assert_eq!(e.windows(), 0);
    }
}
