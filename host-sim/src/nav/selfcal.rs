//! A stillness-gated random-walk Kalman filter (ZARU) with its OWN detector, whose noise
//! reference is measured on the unit itself during its alignment instead of taken from a
//! specification: a baseline for units whose white noise is far from the nominal one (a
//! detector with the specification's noise calls a unit 3x noisier than nominal moving for
//! ever, and lets mild motion of a unit 2x quieter through as still).
//!
//! - **Noise reference**: the rate is cut into consecutive windows of `W` samples
//!   ([`SelfCalConfig::window_s`], `W` = the samples in the record's first `window_s`
//!   seconds, at least [`MIN_WINDOW_SAMPLES`]). Over the first
//!   `round(align_s / window_s)` windows (the alignment, ASSUMED still) the reference
//!   `sigma^2` is the MEDIAN of the windows' sample variances (each about its own window
//!   mean, so a slow drift does not inflate it), divided by the median of
//!   `chi^2_(W-1) / (W-1)` (Wilson-Hilferty, `(1 - 2 / (9 (W-1)))^3`) to make it an unbiased
//!   estimate of the per-sample variance. The median, not the mean: a few windows of motion
//!   inside the alignment (a violated assumption) do not move it. It is a running median
//!   over the alignment windows so far (causal), then frozen.
//! - **Window tests** (in f64): a window passes when its sample
//!   variance is at most `sigma^2 (1 + var_z sqrt(2 / (W - 1)))` and
//!   `|window mean - b| <= mean_k sqrt(sigma^2 / W + P)` (`b`, `P`: the filter's estimate and
//!   variance; no mean test before the first update). The state is still after
//!   `min_still_windows` passing windows and leaves still at the first failing one; it
//!   starts still (ASSUMED: power-on is the alignment, still).
//! - **Release** (as the identifier's level): a window reaches the filter one window late,
//!   only when it passed, the next window passed too and the state was still for both, so no
//!   sample at the onset of motion reaches it.
//! - **Filter**: `b` random-walks by `q_dps2` per sample, predicted at EVERY sample; a
//!   released window updates it with its mean and variance `sigma^2 / W`, which is exactly
//!   `W` scalar updates with its samples (no prediction between them: the window's
//!   predictions were already made, sample by sample, as it arrived).
//!
//! Causal: the estimate returned for sample `k` is the state after the windows released
//! before `k`. The still flag passed to [`DriftEstimator::push`] is ignored.

use super::{run, DriftEstimator, NavRecord, Tuning};
use fog_core::kalman::{DiagonalModel, Kalman};

/// Length of the alignment at power-on, s. ASSUMED: a vehicle's 120-s alignment, still.
pub const ALIGN_S: f64 = 120.0;
/// Detector window, s.
pub const WINDOW_S: f64 = 1.0;
/// Fewest samples in a window (as fog-core's detector).
pub const MIN_WINDOW_SAMPLES: usize = 8;
/// Passing windows before the state is still (3 s of 1-s windows, as fog-core's default).
pub const MIN_STILL_WINDOWS: u32 = 3;
/// Variance test, standard deviations of `s^2 / sigma^2` above 1. ASSUMED 4 (fog-core's).
pub const VAR_Z: f64 = 4.0;
/// Mean test, standard deviations of the window mean. ASSUMED 4 (fog-core's).
pub const MEAN_K: f64 = 4.0;

/// Settings of [`SelfCalKalman`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SelfCalConfig {
    /// Random walk of the bias per sample, (deg/s)^2 (>= 0).
    pub q_dps2: f64,
    /// Alignment at power-on on which the noise is measured, s ([`ALIGN_S`]).
    pub align_s: f64,
    /// Window, s ([`WINDOW_S`]).
    pub window_s: f64,
    /// Passing windows before still ([`MIN_STILL_WINDOWS`]).
    pub min_still_windows: u32,
    /// Variance test z ([`VAR_Z`]).
    pub var_z: f64,
    /// Mean test k ([`MEAN_K`]).
    pub mean_k: f64,
}

impl SelfCalConfig {
    /// The default detector with the random walk `q_dps2` per sample.
    pub fn with_q(q_dps2: f64) -> Self {
        Self {
            q_dps2,
            align_s: ALIGN_S,
            window_s: WINDOW_S,
            min_still_windows: MIN_STILL_WINDOWS,
            var_z: VAR_Z,
            mean_k: MEAN_K,
        }
    }
}

/// The filter and its self-calibrated detector (see the module docs).
#[derive(Debug, Clone)]
pub struct SelfCalKalman {
    cfg: SelfCalConfig,
    // Window in progress: sums of `x - x0` (against cancellation), samples, finite samples.
    x0: f64,
    sum: f64,
    sum2: f64,
    n: usize,
    n_finite: usize,
    first_t_s: Option<f64>,
    last_t_s: Option<f64>,
    /// Samples per window, known at the end of the first window.
    window_n: Option<usize>,
    windows_done: u64,
    align_windows: u64,
    align_vars_dps2: Vec<f64>,
    /// Per-sample noise variance, (deg/s)^2 (None before the first window).
    sigma2_dps2: Option<f64>,
    passing: u32,
    still: bool,
    /// The previous window's mean, deg/s, and whether it may be released.
    prev: Option<(f64, bool)>,
    /// The bias `b`, deg/s, and its variance, (deg/s)^2: a one-state filter on
    /// [`fog_core::kalman`] (None before the first update).
    level: Option<Kalman<1, f64>>,
    samples: u64,
    still_samples: u64,
    updates: u64,
}

impl SelfCalKalman {
    /// A filter at power-on.
    pub fn new(cfg: SelfCalConfig) -> Self {
        let align_windows = if cfg.window_s > 0.0 && cfg.align_s.is_finite() {
            (cfg.align_s / cfg.window_s).round().max(1.0) as u64
        } else {
            1
        };
        Self {
            cfg,
            x0: 0.0,
            sum: 0.0,
            sum2: 0.0,
            n: 0,
            n_finite: 0,
            first_t_s: None,
            last_t_s: None,
            window_n: None,
            windows_done: 0,
            align_windows,
            align_vars_dps2: Vec::new(),
            sigma2_dps2: None,
            passing: cfg.min_still_windows,
            still: true,
            prev: None,
            level: None,
            samples: 0,
            still_samples: 0,
            updates: 0,
        }
    }

    /// The per-sample noise variance measured so far (frozen after the alignment),
    /// (deg/s)^2; None before the first window.
    pub fn noise_var_dps2(&self) -> Option<f64> {
        self.sigma2_dps2
    }

    /// Samples per window (None before the first window ends).
    pub fn window_samples(&self) -> Option<usize> {
        self.window_n
    }

    /// The detector's state: the next sample is flagged still.
    pub fn is_still(&self) -> bool {
        self.still
    }

    /// Samples pushed so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Samples flagged still so far (the state when each arrived).
    pub fn still_samples(&self) -> u64 {
        self.still_samples
    }

    /// Windows released to the filter so far.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// The bias estimate, deg/s, and its variance, (deg/s)^2 (None before the first update).
    pub fn state(&self) -> (f64, Option<f64>) {
        match &self.level {
            Some(k) => (k.x()[0], Some(k.p()[0][0])),
            None => (0.0, None),
        }
    }

    fn window_ends(&self, t_s: f64) -> bool {
        match self.window_n {
            Some(w) => self.n >= w,
            // The first window: the samples in the first `window_s` seconds (this one is
            // the last when the next, one step later, would be past `window_s` less half a
            // step: the step's rounding in the CSV does not add a sample).
            None => match (self.first_t_s, self.last_t_s) {
                (Some(t0), Some(prev)) => {
                    let dt = t_s - prev;
                    self.n >= MIN_WINDOW_SAMPLES && t_s + 1.5 * dt - t0 >= self.cfg.window_s
                }
                _ => false,
            },
        }
    }

    fn end_window(&mut self) {
        let w = *self.window_n.get_or_insert(self.n);
        self.windows_done += 1;
        let nf = self.n_finite as f64;
        let ok = self.n_finite == self.n && self.n_finite >= 2;
        let mean_d = if self.n_finite > 0 {
            self.sum / nf
        } else {
            0.0
        };
        let mean_dps = self.x0 + mean_d;
        let var_dps2 = if self.n_finite >= 2 {
            ((self.sum2 - self.sum * mean_d) / (nf - 1.0)).max(0.0)
        } else {
            f64::NAN
        };
        if ok && self.windows_done <= self.align_windows {
            self.align_vars_dps2.push(var_dps2);
            let mut v = self.align_vars_dps2.clone();
            v.sort_by(f64::total_cmp);
            let m = v.len() / 2;
            let median = if v.len() % 2 == 1 {
                v[m]
            } else {
                0.5 * (v[m - 1] + v[m])
            };
            let dof = (w.max(2) - 1) as f64;
            let median_of_ratio = (1.0 - 2.0 / (9.0 * dof)).powi(3);
            self.sigma2_dps2 = Some(median / median_of_ratio);
        }
        let passed = match self.sigma2_dps2 {
            Some(s2) if ok => {
                let dof = (w.max(2) - 1) as f64;
                let var_ok = var_dps2 <= s2 * (1.0 + self.cfg.var_z * (2.0 / dof).sqrt());
                let mean_ok = match &self.level {
                    None => true,
                    Some(k) => {
                        let dm = mean_dps - k.x()[0];
                        dm * dm <= self.cfg.mean_k * self.cfg.mean_k * (s2 / w as f64 + k.p()[0][0])
                    }
                };
                var_ok && mean_ok
            }
            _ => false,
        };
        let was_still = self.still;
        if passed {
            self.passing = self.passing.saturating_add(1);
            if self.passing >= self.cfg.min_still_windows {
                self.still = true;
            }
        } else {
            self.passing = 0;
            self.still = false;
        }
        if let (Some((m, true)), Some(s2)) = (self.prev, self.sigma2_dps2) {
            if passed && was_still && self.still {
                self.update(m, s2 / w as f64);
            }
        }
        self.prev = Some((mean_dps, passed && self.still));
        self.sum = 0.0;
        self.sum2 = 0.0;
        self.n = 0;
        self.n_finite = 0;
    }

    fn update(&mut self, mean_dps: f64, r_mean_dps2: f64) {
        self.updates += 1;
        match self.level.as_mut() {
            None => self.level = Some(Kalman::new([mean_dps], [r_mean_dps2])),
            Some(k) => {
                k.update(&[1.0], mean_dps, r_mean_dps2);
            }
        }
    }
}

impl DriftEstimator for SelfCalKalman {
    fn name(&self) -> String {
        format!("selfcal-gated-kalman q={:.3e}", self.cfg.q_dps2)
    }

    fn push(&mut self, t_s: f64, rate_dps: f64, _: Option<f64>, _: bool) -> f64 {
        let est = self.level.as_ref().map_or(0.0, |k| k.x()[0]);
        let walk = DiagonalModel {
            phi: [1.0],
            q: [self.cfg.q_dps2.max(0.0)],
        };
        if let Some(k) = self.level.as_mut() {
            k.predict(&walk);
        }
        self.samples += 1;
        self.still_samples += u64::from(self.still);
        if self.first_t_s.is_none() {
            self.first_t_s = Some(t_s);
        }
        if self.n == 0 {
            self.x0 = if rate_dps.is_finite() { rate_dps } else { 0.0 };
        }
        if rate_dps.is_finite() {
            let d = rate_dps - self.x0;
            self.sum += d;
            self.sum2 += d * d;
            self.n_finite += 1;
        }
        self.n += 1;
        let ends = self.window_ends(t_s);
        self.last_t_s = Some(t_s);
        if ends {
            self.end_window();
        }
        est
    }
}

/// Picks [`SelfCalKalman`]'s `q` from `q_grid` by the mean heading-error RMS over
/// `records` (its own detector, the rest of `cfg` as given), as [`super::tune_gated_q`]
/// does for the gated Kalman filter. Ties go to the smaller `q`. None when the grid or the
/// record set is empty or no grid point scores a finite value.
pub fn tune_selfcal_q(records: &[NavRecord], cfg: SelfCalConfig, q_grid: &[f64]) -> Option<Tuning> {
    super::tune::least_mean(records, q_grid, |q, r| {
        let mut k = SelfCalKalman::new(SelfCalConfig { q_dps2: q, ..cfg });
        run(r, &mut k, &[]).scores.heading_rms_deg
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic unit normal deviates (the simulator's generator and distribution).
    struct Noise(rand_pcg::Pcg64);
    impl Noise {
        fn normal(&mut self) -> f64 {
            use rand::Rng;
            self.0.sample(rand_distr::StandardNormal)
        }
    }

    const FS_HZ: f64 = 100.0;
    const DPH: f64 = 1.0 / 3600.0;
    /// The E-Core 2000's nominal white noise per sample at 100 Hz, deg/s.
    fn sigma_nominal_dps() -> f64 {
        f64::from(fog_core::sensor::SensorConfig::ECORE_2000.sample_var_dps2()).sqrt()
    }

    /// Runs the filter over `n` samples of `rate(k)`; returns the estimates and the flags.
    fn drive(
        f: &mut SelfCalKalman,
        n: usize,
        rate: impl Fn(usize) -> f64,
    ) -> (Vec<f64>, Vec<bool>) {
        let (mut est, mut flags) = (Vec::new(), Vec::new());
        for k in 0..n {
            flags.push(f.is_still());
            est.push(f.push(k as f64 / FS_HZ, rate(k), None, false));
        }
        (est, flags)
    }

    #[test]
    fn still_record_converges_to_the_bias() {
        let bias = 12.0 * DPH;
        let mut noise = Noise(rand::SeedableRng::seed_from_u64(3));
        let sigma = sigma_nominal_dps();
        let rates: Vec<f64> = (0..60_000).map(|_| bias + sigma * noise.normal()).collect();
        let mut f = SelfCalKalman::new(SelfCalConfig::with_q(1e-14));
        let (est, flags) = drive(&mut f, rates.len(), |k| rates[k]);
        assert_eq!(f.window_samples(), Some(100));
        let s2 = f.noise_var_dps2().expect("measured");
        assert!((s2 / (sigma * sigma) - 1.0).abs() < 0.05, "{s2}");
        let frac = flags.iter().filter(|&&s| s).count() as f64 / flags.len() as f64;
        assert!(frac > 0.95, "still fraction {frac}");
        let last = est.last().copied().expect("estimates");
        assert!((last - bias).abs() < 0.5 * DPH, "{} deg/h", last / DPH);
        // Causal: the first window's estimate is 0 (nothing released yet).
        assert!(est[..200].iter().all(|&e| e == 0.0));
    }

    #[test]
    fn constant_rate_turn_is_never_learnt() {
        // 150.5 s still (alignment and more), a 5-deg/s turn for 100 s, still again.
        let bias = -20.0 * DPH;
        let sigma = sigma_nominal_dps();
        let mut noise = Noise(rand::SeedableRng::seed_from_u64(5));
        let (on, off) = (15_050, 25_050);
        let rates: Vec<f64> = (0..40_000)
            .map(|k| bias + sigma * noise.normal() + if (on..off).contains(&k) { 5.0 } else { 0.0 })
            .collect();
        let mut f = SelfCalKalman::new(SelfCalConfig::with_q(1e-12));
        let (est, flags) = drive(&mut f, rates.len(), |k| rates[k]);
        // From the onset to the end of the turn the estimate never changes.
        let at_onset = est[on];
        assert!(est[on..off].iter().all(|&e| e == at_onset));
        assert!((at_onset - bias).abs() < 2.0 * DPH, "{}", at_onset / DPH);
        // Flags lag one window at the onset, then moving until the turn ends.
        assert!(flags[on + 100..off].iter().all(|&s| !s));
        // Still again after the turn: learning resumes, the estimate stays at the bias.
        assert!(flags[off + 500..].iter().all(|&s| s));
        let last = est.last().copied().expect("estimates");
        assert!((last - bias).abs() < 2.0 * DPH, "{}", last / DPH);
    }

    #[test]
    fn noise_three_times_nominal_is_still() {
        let bias = 30.0 * DPH;
        let sigma = 3.0 * sigma_nominal_dps();
        let mut noise = Noise(rand::SeedableRng::seed_from_u64(11));
        let rates: Vec<f64> = (0..30_000).map(|_| bias + sigma * noise.normal()).collect();
        let mut f = SelfCalKalman::new(SelfCalConfig::with_q(1e-14));
        let (est, flags) = drive(&mut f, rates.len(), |k| rates[k]);
        let frac = flags.iter().filter(|&&s| s).count() as f64 / flags.len() as f64;
        assert!(frac > 0.95, "still fraction {frac}");
        let last = est.last().copied().expect("estimates");
        assert!((last - bias).abs() < 1.5 * DPH, "{} deg/h", last / DPH);
    }

    #[test]
    fn a_turn_inside_the_alignment_does_not_move_the_noise_reference() {
        let sigma = sigma_nominal_dps();
        let mut noise = Noise(rand::SeedableRng::seed_from_u64(13));
        // A 10-deg/s turn from 50 s to 60 s, inside the 120-s alignment.
        let rates: Vec<f64> = (0..20_000)
            .map(|k| {
                sigma * noise.normal()
                    + if (5_000..6_000).contains(&k) {
                        10.0
                    } else {
                        0.0
                    }
            })
            .collect();
        let mut f = SelfCalKalman::new(SelfCalConfig::with_q(1e-12));
        let (est, _) = drive(&mut f, rates.len(), |k| rates[k]);
        let s2 = f.noise_var_dps2().expect("measured");
        assert!((s2 / (sigma * sigma) - 1.0).abs() < 0.1, "{s2}");
        assert!(est.iter().all(|e| e.abs() < 3.0 * DPH));
    }

    #[test]
    fn tuner_scans_the_grid() {
        let sigma = sigma_nominal_dps();
        let mut noise = Noise(rand::SeedableRng::seed_from_u64(17));
        let n = 30_000usize;
        let rec = NavRecord {
            t_s: (0..n).map(|k| k as f64 / FS_HZ).collect(),
            rate_dps: (0..n).map(|_| 5.0 * DPH + sigma * noise.normal()).collect(),
            temp_c: None,
            true_rate_dps: vec![0.0; n],
            drift_dps: vec![5.0 * DPH; n],
            moving: vec![false; n],
        };
        let grid = super::super::log_grid(1e-16, 1e-8, 1);
        let t = tune_selfcal_q(
            std::slice::from_ref(&rec),
            SelfCalConfig::with_q(0.0),
            &grid,
        )
        .expect("tuned");
        assert_eq!(t.grid.len(), grid.len());
        let min = t.grid.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        assert_eq!(t.heading_rms_deg, min);
        assert!(tune_selfcal_q(&[], SelfCalConfig::with_q(0.0), &grid).is_none());
    }
}
