//! The drift filter: the Kalman filter of a [`GyroModel`], run at the window rate, with the
//! model's own stillness test.
//!
//! States (`x`, [`STATES`] of them): the level `b` (a random walk of the model's rate random
//! walk), the Gauss-Markov terms `g_1..g_3` (absent terms have zero variance and stay 0),
//! the warm-up's coefficients `a_1..a_3` on its basis of exponentials
//! ([`crate::warmup_basis`]: the warm-up of a time constant known only within a range;
//! absent terms stay 0) and the temperature and temperature-rate links `c`, `c'`
//! (constants). Prior: the model's family means and spreads (the warm-up's a joint one). Process noise: the model's, never chosen on line. The observation of one window
//! is its mean rate `ybar` with the row
//! `hbar = [1, 1, 1, 1, mean e^(-t/tau_1), .., mean e^(-t/tau_3), mean (T - T0), dT/dt]`,
//! `T0` the model's reference temperature.
//!
//! Per window of `W` samples ([`DriftFilterConfig::window_s`]):
//! 1. predict `W` steps of the model;
//! 2. **stillness test** (a likelihood-ratio test on the window mean, as zero-velocity
//!    detectors do): the window is still when its normalized innovation
//!    `e^2 / (hbar P hbar' + R_W)` and the normalized squared difference of its two halves'
//!    means are both below one chi-square(1) threshold ([`DriftFilterConfig::nis_limit`]).
//!    The first test catches a rate that stays (the slow start of a drive), the second one
//!    that changes within the window (a turn). `R_W` is the variance of a window mean at
//!    rest, learned on the unit from the half-window differences of its still windows
//!    (fast vibration averages out in a window mean: an idling engine makes a still window
//!    worth less, it does not widen the test beyond what it must resolve). `R_W` lies
//!    between the model's white-noise floor and a cap set by the rate the test must resolve
//!    ([`DriftFilterConfig::resolve_dps`]). The first [`DriftFilterConfig::learn_windows`]
//!    windows after power-on (the unit is presumed still when switched on) learn `R_W`
//!    without the half-difference test; the first window is presumed still (power-on: a
//!    turn-on bias beyond the model's spread is learned there), the mean test applies
//!    from the second;
//! 3. a still window updates the filter; the update is held back one window (but the
//!    power-on window's, below): the output uses the state before it until the next window
//!    passes (or while the next window's samples so far pass the test, below), and when
//!    the next window fails
//!    the filter returns to that state (one checkpoint, written once per window). Nothing is
//!    learned from a window that failed. A window an external flag calls still is trusted:
//!    its update is not held back.
//!
//! **The window so far.** The output does not wait for a window's end when the window
//! before it was still (and at power-on, whose window is presumed still): while it fills,
//! each sample's drift is the filter's own `h x` (the last window's update included, which
//! step 3 holds back) updated by the mean of the window's samples so far
//! (`h P h' / (h P h' + v / n_eff)` times the mean `m` of `rate - h x` over its `n`
//! samples, `v` the larger of the model's per-sample variance and the samples' own (a
//! noisier unit, an idling engine), the samples counted as `n_eff = min(n, (pi f t)^2)`
//! after `t` seconds (a vibration of `f` >= 5 Hz, ASSUMED as for the window length, is no
//! white noise: a partial cycle's mean keeps more of it), `h P h'` the filter's at the
//! window's second sample; from the 8th sample on; before it the held-back state's `h x`).
//! After power-on both apply only while the mean passes the stillness test of the samples
//! so far, `m^2 < nis_limit (h P h' + v / n_eff)`: the output is then at most the held-back update
//! plus `sqrt(nis_limit h P h')` (3 sigma of the filter's own drift) from the held-back
//! state, whatever the vehicle does; the start of a turn fails the test and returns the
//! output to the held-back state, and the held-back update is still undone when the window
//! fails. The power-on window's own update is shown at once (it stays undoable: when the
//! second window fails the output returns to the prior). Without it the output held the
//! prior for two windows, the largest part of e_truth on a static record whose turn-on is
//! far from the family's mean, and lagged two windows behind at every stop
//! (`drift_filter_eval` on `scripts/gen_unit_family.py` families, `docs/drift-filter.md`).
//! An external flag calling the window moving turns it off.
//!
//! Output per sample: `drift = h(t, T) x`, clamped to the model's drift bound, and the
//! compensated rate `rate - drift`. Cost per sample: a few additions and multiplications;
//! per window one predict and one update of a 9-state filter (`O(81)` each), split over
//! two samples: the push that ends a window predicts and tests, the next push applies the
//! decision (the update, or the return to the checkpoint) before it computes its own
//! output, so every output is the same as if both happened at once ([`DriftFilter::kalman`]
//! between the two shows the state before the decision).
//!
//! An external still flag (a vehicle's zero-speed signal) overrides the test for the
//! window it is given in (the window is still when every sample with a flag says still, and
//! moving when one says moving).

use crate::gyro_model::{GyroModel, MAX_MARKOV};
use crate::kalman::{DiagonalModel, Innovation, Kalman};
use crate::warmup_basis::{WarmupBasis, TERMS as MAX_WARMUP};

/// Number of states: level, three Gauss-Markov terms, three warm-up terms, temperature,
/// temperature rate.
pub const STATES: usize = 3 + MAX_MARKOV + MAX_WARMUP;

const LEVEL: usize = 0;
const WARMUP: usize = 1 + MAX_MARKOV;
const TEMP: usize = WARMUP + MAX_WARMUP;
const TEMP_RATE: usize = TEMP + 1;

/// How the filter runs (apart from the model it runs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriftFilterConfig {
    /// Window length, s (> 0); at least 2 samples. ASSUMED default 2 s: short against the
    /// drift's tens of seconds, long enough for idling vibration (> 5 Hz) to average out.
    pub window_s: f32,
    /// The stillness test's threshold on a normalized squared innovation (chi-square with
    /// one degree of freedom): 10.83 is a false alarm of 1e-3 per window and test.
    pub nis_limit: f32,
    /// The smallest steady rate the test must still tell from rest, deg/s (> 0): caps `R_W`
    /// at `(resolve_dps)^2 / nis_limit`. ASSUMED default 0.01 deg/s (36 deg/h).
    pub resolve_dps: f32,
    /// Windows after power-on whose half-difference learns `R_W` without being tested.
    pub learn_windows: u32,
    /// Time constant of the temperature-rate estimate, s (> 0).
    pub temp_rate_tau_s: f32,
}

impl Default for DriftFilterConfig {
    fn default() -> Self {
        Self {
            window_s: 2.0,
            nis_limit: 10.83,
            resolve_dps: 0.01,
            learn_windows: 8,
            temp_rate_tau_s: 60.0,
        }
    }
}

impl DriftFilterConfig {
    /// Every field finite and > 0 (`learn_windows` may be 0).
    pub fn is_valid(&self) -> bool {
        let pos = |v: f32| v > 0.0 && v.is_finite();
        pos(self.window_s)
            && pos(self.nis_limit)
            && pos(self.resolve_dps)
            && pos(self.temp_rate_tau_s)
    }
}

/// Why a filter cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriftFilterError {
    /// The model is not valid ([`GyroModel::is_valid`]).
    BadModel,
    /// The configuration is not valid or its window holds fewer than 2 samples.
    BadConfig,
    /// A rate that is not finite: refused, counted, nothing changed.
    NonFiniteRate,
}

/// One sample's result.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriftOutput {
    /// Drift estimate, deg/s, within the model's bound.
    pub drift_dps: f32,
    /// `rate - drift`, deg/s.
    pub compensated_dps: f32,
    /// The sample's external flag when it has one, else the last window the test decided
    /// was still (at power-on: presumed still).
    pub still: bool,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriftStats {
    /// Samples accepted.
    pub samples: u32,
    /// Samples refused (non-finite rate).
    pub rejected: u32,
    /// Windows ended.
    pub windows: u32,
    /// Windows found still (updates made).
    pub still_windows: u32,
    /// Updates undone because the next window failed.
    pub undone: u32,
}

/// The model's constants the filter runs with (built once).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Built {
    window: DiagonalModel<STATES>,
    samples_per_window: u32,
    /// `e^(-dt / tau_j)` per warm-up term.
    warmup_step: [f32; MAX_WARMUP],
    /// `e^(-W dt / tau_j)` per warm-up term: one window.
    warmup_window_step: [f32; MAX_WARMUP],
    r_floor: f32,
    r_cap: f32,
}

/// The filter at one moment (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftFilter {
    model: GyroModel,
    cfg: DriftFilterConfig,
    built: Built,
    kf: Kalman<STATES>,
    /// The state before the last still window's update (module docs, step 3).
    checkpoint: Kalman<STATES>,
    /// The last still window's update is held back (module docs, step 3).
    pending: bool,
    /// The held-back state: the filter's without the pending update, which the output uses
    /// but while a window so far passes its test (module docs, "The window so far").
    out_x: [f32; STATES],
    /// `sum` of `out_x`'s level and Gauss-Markov terms (the drift's window-constant part).
    out_const: f32,
    /// The decision of the window that ended on the last push, applied on the next one.
    deferred: Deferred,
    /// `R_W` estimate: sum of half-difference variances and their count (capped: an
    /// exponential average over the last `R_MEMORY` windows once full).
    r_sum: f32,
    r_count: f32,
    r_checkpoint: (f32, f32),
    /// Window sums: rate (two halves), warm-up factors, temperature offset.
    sum_first: f32,
    sum_second: f32,
    sum_warm: [f32; MAX_WARMUP],
    sum_temp: f32,
    in_window: u32,
    /// External flags seen in this window: any still, any moving.
    ext_still: bool,
    ext_moving: bool,
    /// The warm-up factors `e^(-t/tau_j)` of the next sample (0 for an absent term).
    warm: [f32; MAX_WARMUP],
    /// The warm-up factors at the start of this window.
    warm_start: [f32; MAX_WARMUP],
    /// The window so far (module docs): the sums of `rate - h x` and of its square over
    /// its samples so far, and `h P h'` of the drift at its second sample.
    so_far_resid: f32,
    so_far_resid_sq: f32,
    so_far_var: f32,
    /// Last valid temperature minus `T0` (0 before any).
    temp_off: f32,
    /// Previous window's mean temperature offset, and the temperature-rate estimate, C/s.
    temp_prev: Option<f32>,
    temp_rate: f32,
    /// The drift's window-constant part `b + sum g` and the coefficients, per sample.
    still: bool,
    stats: DriftStats,
}

/// Samples of a window before its mean so far moves the output (module docs, "The window
/// so far"): their spread is estimated from them. ASSUMED: 8.
const SO_FAR_MIN_SAMPLES: u32 = 8;

/// The slowest vibration a window's mean so far is assumed to average out, Hz (the window
/// length's assumption: idling vibration > 5 Hz, [`DriftFilterConfig::window_s`]).
const SO_FAR_VIBRATION_HZ: f32 = 5.0;

/// Memory of the `R_W` average, windows.
const R_MEMORY: f32 = 64.0;

/// What the window that ended on the last push decided (applied on the next push).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Deferred {
    /// Nothing left to do.
    Nothing,
    /// A still window: the update with this row, mean and `R_W`; its half-difference
    /// sample for `R_W`; trusted (an external flag: not held back).
    Update {
        h: [f32; STATES],
        mean: f32,
        r: f32,
        r_sample: f32,
        trusted: bool,
        /// The output takes the update at once (trusted, or the power-on window: presumed
        /// still); an untrusted one stays undoable.
        show: bool,
    },
    /// The next window failed: back to the checkpoint, predicted one window.
    Undo,
}

impl DriftFilter {
    /// The filter of `model` at power-on.
    pub fn new(model: GyroModel, cfg: DriftFilterConfig) -> Result<Self, DriftFilterError> {
        let samples_per_window = Self::check(&model, &cfg)?;
        let w = samples_per_window as f32;
        let dt = model.sample_period_s();
        let mut step = DiagonalModel {
            phi: [1.0; STATES],
            q: [0.0; STATES],
        };
        step.q[LEVEL] = model.rrw_dps_per_s_rthz * model.rrw_dps_per_s_rthz * dt;
        for (i, m) in model.markov.iter().enumerate() {
            if m.sigma_dps > 0.0 {
                let phi = libm::expf(-dt / m.tau_s);
                step.phi[1 + i] = phi;
                step.q[1 + i] = m.sigma_dps * m.sigma_dps * (1.0 - phi * phi);
            }
        }
        let basis = Self::warmup_basis(&model)?;
        let warmup_tau_s = basis.tau_s;
        // The warm-up factors at power-on: 1 for a present term, 0 for an absent one.
        let warm_at_power_on = warmup_tau_s.map(|t| if t > 0.0 { 1.0 } else { 0.0 });
        let r_floor = model.sample_var_dps2() / w;
        let r_cap = (cfg.resolve_dps * cfg.resolve_dps / cfg.nis_limit).max(r_floor);
        let built = Built {
            window: step.repeated(samples_per_window),
            samples_per_window,
            warmup_step: warmup_tau_s.map(|t| if t > 0.0 { libm::expf(-dt / t) } else { 0.0 }),
            warmup_window_step: warmup_tau_s.map(|t| {
                if t > 0.0 {
                    libm::expf(-(samples_per_window as f32) * dt / t)
                } else {
                    0.0
                }
            }),
            r_floor,
            r_cap,
        };
        let kf = Self::prior(&model, &basis);
        Ok(Self {
            model,
            cfg,
            built,
            kf,
            checkpoint: kf,
            pending: false,
            out_x: *kf.x(),
            out_const: Self::const_part(kf.x()),
            deferred: Deferred::Nothing,
            r_sum: 0.0,
            r_count: 0.0,
            r_checkpoint: (0.0, 0.0),
            sum_first: 0.0,
            sum_second: 0.0,
            sum_warm: [0.0; MAX_WARMUP],
            sum_temp: 0.0,
            in_window: 0,
            ext_still: false,
            ext_moving: false,
            warm: warm_at_power_on,
            warm_start: warm_at_power_on,
            so_far_resid: 0.0,
            so_far_resid_sq: 0.0,
            so_far_var: 0.0,
            temp_off: 0.0,
            temp_prev: None,
            temp_rate: 0.0,
            still: true,
            stats: DriftStats::default(),
        })
    }

    /// Whether [`DriftFilter::new`] builds a filter of `model` and `cfg`, without building
    /// it (a filter is about 1 KiB: on the MCU an image is checked with this). Returns the
    /// samples per window.
    pub fn check(model: &GyroModel, cfg: &DriftFilterConfig) -> Result<u32, DriftFilterError> {
        if !model.is_valid() {
            return Err(DriftFilterError::BadModel);
        }
        if !cfg.is_valid() {
            return Err(DriftFilterError::BadConfig);
        }
        let w = libm::roundf(cfg.window_s * model.sample_rate_hz);
        if !(2.0..=1.0e6).contains(&w) {
            return Err(DriftFilterError::BadConfig);
        }
        Self::warmup_basis(model)?;
        Ok(w as u32)
    }

    fn warmup_basis(model: &GyroModel) -> Result<WarmupBasis, DriftFilterError> {
        WarmupBasis::new(
            model.warmup_dps.mean,
            model.warmup_dps.sigma,
            model.warmup_tau_min_s,
            model.warmup_tau_max_s,
        )
        .ok_or(DriftFilterError::BadModel)
    }

    fn prior(model: &GyroModel, basis: &WarmupBasis) -> Kalman<STATES> {
        let mut x0 = [0.0; STATES];
        let mut p0 = [0.0; STATES];
        x0[LEVEL] = model.turn_on_dps.mean;
        p0[LEVEL] = model.turn_on_dps.sigma * model.turn_on_dps.sigma;
        for (i, m) in model.markov.iter().enumerate() {
            p0[1 + i] = m.sigma_dps * m.sigma_dps;
        }
        for (x, m) in x0[WARMUP..TEMP].iter_mut().zip(&basis.mean_dps) {
            *x = *m;
        }
        x0[TEMP] = model.temp_dps_per_c.mean;
        p0[TEMP] = model.temp_dps_per_c.sigma * model.temp_dps_per_c.sigma;
        x0[TEMP_RATE] = model.temp_rate_dps_per_c_per_s.mean;
        p0[TEMP_RATE] =
            model.temp_rate_dps_per_c_per_s.sigma * model.temp_rate_dps_per_c_per_s.sigma;
        let mut p = [[0.0; STATES]; STATES];
        for (i, row) in p.iter_mut().enumerate() {
            row[i] = p0[i];
        }
        for (i, row) in basis.cov_dps2.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                p[WARMUP + i][WARMUP + j] = *v;
            }
        }
        Kalman::with_covariance(x0, p)
    }

    /// Back to power-on; keeps the model and the configuration.
    pub fn restart(&mut self) {
        if let Ok(f) = Self::new(self.model, self.cfg) {
            *self = f;
        }
    }

    /// The model.
    pub fn model(&self) -> &GyroModel {
        &self.model
    }

    /// The configuration.
    pub fn config(&self) -> &DriftFilterConfig {
        &self.cfg
    }

    /// The filter's state and covariance now.
    pub fn kalman(&self) -> &Kalman<STATES> {
        &self.kf
    }

    /// Samples per window.
    pub fn window_samples(&self) -> u32 {
        self.built.samples_per_window
    }

    /// `R_W`, the variance of a window mean at rest, deg^2/s^2, as learned now.
    pub fn window_var_dps2(&self) -> f32 {
        let r = if self.r_count > 0.0 {
            self.r_sum / self.r_count
        } else {
            self.built.r_floor
        };
        // Comparisons, not clamp (its panic path would be linked) nor max/min (calls to
        // fmaxf/fminf on the target); r_floor <= r_cap by construction.
        if r > self.built.r_cap {
            self.built.r_cap
        } else if r < self.built.r_floor {
            self.built.r_floor
        } else {
            r
        }
    }

    /// Counters.
    pub fn stats(&self) -> &DriftStats {
        &self.stats
    }

    /// The level and Gauss-Markov terms of `x` summed (constant over a window).
    fn const_part(x: &[f32; STATES]) -> f32 {
        let mut d = 0.0;
        for v in x.iter().take(WARMUP) {
            d += v;
        }
        d
    }

    /// Sets the state the output uses.
    fn set_out(&mut self, x: [f32; STATES]) {
        self.out_const = Self::const_part(&x);
        self.out_x = x;
    }

    /// The drift at the next sample (deg/s, unclamped).
    fn drift_now(&self) -> f32 {
        self.drift_at(self.out_const, &self.out_x)
    }

    /// The drift at the next sample of state `x` whose constant part is `x_const`.
    fn drift_at(&self, x_const: f32, x: &[f32; STATES]) -> f32 {
        let mut d = x_const;
        for (a, w) in x[WARMUP..TEMP].iter().zip(&self.warm) {
            d += a * w;
        }
        d + x[TEMP] * self.temp_off + x[TEMP_RATE] * self.temp_rate
    }

    /// The drift at the next sample of state `x` (deg/s, unclamped).
    fn drift_of(&self, x: &[f32; STATES]) -> f32 {
        self.drift_at(Self::const_part(x), x)
    }

    /// Applies the last window's decision (module docs: the second half of its work).
    fn apply_deferred(&mut self) {
        match core::mem::replace(&mut self.deferred, Deferred::Nothing) {
            Deferred::Nothing => {}
            Deferred::Update {
                h,
                mean,
                r,
                r_sample,
                trusted,
                show,
            } => {
                self.checkpoint = self.kf;
                self.r_checkpoint = (self.r_sum, self.r_count);
                self.kf.update(&h, mean, r);
                // Held back one window: the output keeps the state before this update
                // until the next window confirms it; a window the external flag calls
                // still is the flag's (trusted: nothing to confirm or undo).
                self.pending = !trusted;
                if show {
                    self.set_out(*self.kf.x());
                }
                // R_W from the window's half-difference (an average with a fast start).
                if self.r_count >= R_MEMORY {
                    self.r_sum *= (R_MEMORY - 1.0) / R_MEMORY;
                } else {
                    self.r_count += 1.0;
                }
                self.r_sum += r_sample;
            }
            Deferred::Undo => {
                self.kf = self.checkpoint;
                self.kf.predict(&self.built.window);
                (self.r_sum, self.r_count) = self.r_checkpoint;
                self.set_out(*self.kf.x());
            }
        }
    }

    /// One sample: `rate_dps`, `temp_c` (NaN: no reading; the last one is kept),
    /// `external_still` (a trusted still / moving flag, or `None`). A non-finite rate is
    /// refused and counted, nothing else changes.
    pub fn push(
        &mut self,
        rate_dps: f32,
        temp_c: f32,
        external_still: Option<bool>,
    ) -> Result<DriftOutput, DriftFilterError> {
        if !rate_dps.is_finite() {
            self.stats.rejected = self.stats.rejected.saturating_add(1);
            return Err(DriftFilterError::NonFiniteRate);
        }
        self.apply_deferred();
        self.stats.samples = self.stats.samples.saturating_add(1);
        if temp_c.is_finite() {
            self.temp_off = temp_c - self.model.temp_ref_c;
        }
        let predicted = self.drift_now();
        let power_on = self.stats.windows == 0;
        let so_far = power_on || self.still;
        let drift = if so_far {
            // The filter's own state, the held-back update included (module docs, "The
            // window so far").
            let own = if self.pending {
                self.drift_of(self.kf.x())
            } else {
                predicted
            };
            match self.so_far_correction(own - predicted, !power_on) {
                Some(c) => own + c,
                None => predicted,
            }
        } else {
            predicted
        };
        let drift = self.model.clamp_drift(drift);
        // The window's sums (the sample's own h before the warm-up factor moves on).
        let half = self.built.samples_per_window / 2;
        if self.in_window < half {
            self.sum_first += rate_dps;
        } else {
            self.sum_second += rate_dps;
        }
        for (s, w) in self.sum_warm.iter_mut().zip(&self.warm) {
            *s += w;
        }
        self.sum_temp += self.temp_off;
        if so_far {
            let e = rate_dps - predicted;
            self.so_far_resid += e;
            self.so_far_resid_sq += e * e;
        }
        match external_still {
            Some(true) => self.ext_still = true,
            Some(false) => self.ext_moving = true,
            None => {}
        }
        self.in_window += 1;
        for (w, step) in self.warm.iter_mut().zip(&self.built.warmup_step) {
            *w *= step;
        }
        if self.in_window >= self.built.samples_per_window {
            self.end_window(half);
        }
        Ok(DriftOutput {
            drift_dps: drift,
            compensated_dps: rate_dps - drift,
            still: external_still.unwrap_or(self.still),
        })
    }

    /// A window after a still one, or the power-on window (module docs, "The window so
    /// far"): the update of the filter's own drift by the mean `m` of this window's `n`
    /// samples so far, `m` taken against that drift (`shift`: it less the held-back output's
    /// drift, against which `push` sums the samples), `h P h' / (h P h' + v / n_eff) * m`,
    /// `v` the larger of the model's per-sample variance and the samples' own, `n_eff` at
    /// most `(pi f t)^2` ([`SO_FAR_VIBRATION_HZ`]). `None` (the output keeps the held-back
    /// state) for the first [`SO_FAR_MIN_SAMPLES`] (`push` adds each sample's residual after
    /// its output), once an external flag called the window moving, and, when `gated`,
    /// unless `m^2 < nis_limit (h P h' + v / n_eff)`.
    fn so_far_correction(&mut self, shift: f32, gated: bool) -> Option<f32> {
        if self.ext_moving {
            return None;
        }
        let n = self.in_window as f32;
        if self.in_window == 1 {
            // At the second sample: the first one applied the last window's decision (the
            // filter's state does not change again within the window); the update and this
            // `O(81)` product fall on different pushes.
            let mut h = [1.0; STATES];
            h[WARMUP..TEMP].copy_from_slice(&self.warm);
            h[TEMP] = self.temp_off;
            h[TEMP_RATE] = self.temp_rate;
            self.so_far_var = self.kf.observe_var(&h);
        }
        if self.in_window < SO_FAR_MIN_SAMPLES {
            return None;
        }
        // The samples' own variance when above the model's (a noisier unit, vibration).
        let mean_held = self.so_far_resid / n;
        let spread = (self.so_far_resid_sq - n * mean_held * mean_held) / (n - 1.0);
        let v = if spread > self.model.sample_var_dps2() {
            spread
        } else {
            self.model.sample_var_dps2()
        };
        // Vibration is not white: the mean of a sinusoid of frequency f over t seconds keeps
        // up to 1 / (pi f t)^2 of its variance, so the samples count as at most (pi f t)^2
        // with f the slowest vibration the window assumes.
        let t_s = n * self.model.sample_period_s();
        let x = core::f32::consts::PI * SO_FAR_VIBRATION_HZ * t_s;
        let n_eff = if x * x < n { x * x } else { n };
        let s = self.so_far_var;
        let innovation_var = s + v / n_eff;
        let mean = mean_held - shift;
        if gated && mean * mean >= self.cfg.nis_limit * innovation_var {
            return None;
        }
        Some(s / innovation_var * mean)
    }

    fn end_window(&mut self, half: u32) {
        let n = self.in_window as f32;
        let n1 = half as f32;
        let n2 = n - n1;
        let mean = (self.sum_first + self.sum_second) / n;
        let mean_temp = self.sum_temp / n;
        // Temperature rate: a first-order average of the window-to-window slope.
        let window_s = n * self.model.sample_period_s();
        if let Some(prev) = self.temp_prev {
            let slope = (mean_temp - prev) / window_s;
            let a = (window_s / self.cfg.temp_rate_tau_s).min(1.0);
            self.temp_rate += a * (slope - self.temp_rate);
        }
        self.temp_prev = Some(mean_temp);
        let mut h = [1.0; STATES];
        for (hj, s) in h[WARMUP..TEMP].iter_mut().zip(&self.sum_warm) {
            *hj = s / n;
        }
        h[TEMP] = mean_temp;
        h[TEMP_RATE] = self.temp_rate;
        self.kf.predict(&self.built.window);
        let r = self.window_var_dps2();
        let inn: Innovation = self.kf.innovation(&h, mean, r);
        // Half-difference: variance n (1/n1 + 1/n2) R_W at rest, whatever a constant rate.
        let d = self.sum_first / n1 - self.sum_second / n2;
        let d_scale = n * (1.0 / n1 + 1.0 / n2);
        let learning = self.stats.windows < self.cfg.learn_windows;
        let still = if self.ext_moving {
            false
        } else if self.ext_still {
            true
        } else if self.stats.windows == 0 {
            // Power-on: the unit is presumed still (a bias beyond the model's spread is
            // learned here); the next window undoes it if it fails.
            true
        } else {
            inn.nis().is_some_and(|v| v < self.cfg.nis_limit)
                && (learning || d * d / (d_scale * r) < self.cfg.nis_limit)
        };
        self.stats.windows = self.stats.windows.saturating_add(1);
        if still {
            // The output keeps the state before the update (= the predicted state now)
            // unless the flag is trusted; the update itself on the next push.
            if !self.ext_still {
                self.set_out(*self.kf.x());
            }
            self.deferred = Deferred::Update {
                h,
                mean,
                r,
                r_sample: d * d / d_scale,
                trusted: self.ext_still,
                show: self.ext_still || self.stats.windows == 1,
            };
            self.stats.still_windows = self.stats.still_windows.saturating_add(1);
        } else if self.pending {
            self.pending = false;
            self.deferred = Deferred::Undo;
            self.stats.undone = self.stats.undone.saturating_add(1);
        } else {
            self.set_out(*self.kf.x());
        }
        self.still = still;
        // The next window.
        self.sum_first = 0.0;
        self.sum_second = 0.0;
        self.sum_warm = [0.0; MAX_WARMUP];
        self.sum_temp = 0.0;
        self.in_window = 0;
        self.so_far_resid = 0.0;
        self.so_far_resid_sq = 0.0;
        self.ext_still = false;
        self.ext_moving = false;
        // The warm-up factors of the next window: the last window's start times one
        // window's decay (not the product of every sample's step).
        for ((w, s), step) in self
            .warm
            .iter_mut()
            .zip(self.warm_start.iter_mut())
            .zip(&self.built.warmup_window_step)
        {
            *s *= step;
            *w = *s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gyro_model::tests::ecore_like;
    use crate::test_noise::Noise;

    fn sigma(m: &GyroModel) -> f64 {
        (m.sample_var_dps2() as f64).sqrt()
    }

    #[test]
    fn a_still_unit_converges_to_its_bias() {
        let m = ecore_like();
        let mut f = DriftFilter::new(m, DriftFilterConfig::default()).expect("test");
        let mut n = Noise(7);
        let bias = 20.0 / 3600.0;
        let mut last = 0.0;
        for _ in 0..(600.0 * m.sample_rate_hz) as usize {
            last = f
                .push(
                    (bias + sigma(&m) * f64::from(n.normal12())) as f32,
                    25.0,
                    None,
                )
                .expect("test")
                .drift_dps;
        }
        assert!(
            (last as f64 - bias).abs() < 2.0 / 3600.0,
            "{}",
            last * 3600.0
        );
        let s = f.stats();
        assert!(s.still_windows as f32 > 0.95 * s.windows as f32, "{s:?}");
    }

    #[test]
    fn power_on_output_follows_the_first_window_and_is_undone_by_a_turn() {
        // A noise-free unit at 100 deg/h (the prior: 0 +- about 39 deg/h).
        let m = ecore_like();
        let mut f = DriftFilter::new(m, DriftFilterConfig::default()).expect("test");
        let w = f.window_samples() as usize;
        let bias = 100.0 / 3600.0;
        let dph2 = (1.0f64 / 3600.0).powi(2);
        // h P h' at power-on: turn-on, the two Gauss-Markov terms, the warm-up (25 deg/h).
        let s = (30.0f64.powi(2) + 1.0 + 1.5f64.powi(2) + 25.0f64.powi(2)) * dph2;
        let v = f64::from(m.sample_var_dps2());
        let first = f.push(bias as f32, 25.0, None).expect("test").drift_dps;
        assert_eq!(first, 0.0, "no sample yet: the prior");
        for n in 1..w {
            let d = f64::from(f.push(bias as f32, 25.0, None).expect("test").drift_dps);
            // From the 8th sample; the samples count as at most (pi 5 Hz t)^2.
            let x = core::f64::consts::PI * 5.0 * n as f64 / f64::from(m.sample_rate_hz);
            let n_eff = (x * x).min(n as f64);
            let k = if n < 8 { 0.0 } else { s / (s + v / n_eff) };
            assert!((d / bias - k).abs() < 0.01, "n {n}: {} vs {}", d / bias, k);
        }
        // The first window's update is shown at once.
        let d = f.push(bias as f32, 25.0, None).expect("test").drift_dps;
        assert!((f64::from(d) / bias - 1.0).abs() < 0.02, "{}", d * 3600.0);
        // A turn in the second window: the output returns to the prior.
        for _ in 1..w {
            f.push((bias + 0.5) as f32, 25.0, None).expect("test");
        }
        let d = f.push(bias as f32, 25.0, None).expect("test").drift_dps;
        assert!(d.abs() < 1.0 / 3600.0, "{}", d * 3600.0);
        assert_eq!(f.stats().undone, 1);
    }

    #[test]
    fn vibration_at_power_on_does_not_move_the_output() {
        // 1 kHz, an idling engine's 20 Hz at 0.1 deg/s from the first sample, no bias: a
        // partial cycle's mean is no white-noise mean (module docs, "The window so far").
        let mut m = ecore_like();
        m.sample_rate_hz = 1000.0;
        let mut f = DriftFilter::new(m, DriftFilterConfig::default()).expect("test");
        let mut worst: f32 = 0.0;
        for k in 0..f.window_samples() {
            let t = k as f32 / m.sample_rate_hz;
            let rate = 0.1 * libm::sinf(2.0 * core::f32::consts::PI * 20.0 * t);
            let d = f.push(rate, 25.0, None).expect("test").drift_dps;
            worst = worst.max(d.abs());
        }
        // 6.9 deg/h; the samples counted as white (every sample one): 150.
        assert!(worst < 15.0 / 3600.0, "{} deg/h", worst * 3600.0);
    }

    #[test]
    fn a_turn_after_a_stop_fails_the_window_so_far() {
        // Noise-free at 10 deg/h for 60 s (a converged level), then 0.5 deg/s from a
        // window's first sample: the window so far follows the window after a still one,
        // but the turn's mean fails its test from the first samples on (module docs, "The
        // window so far"); without the test the output would take k * 0.5 deg/s.
        let m = ecore_like();
        let mut f = DriftFilter::new(m, DriftFilterConfig::default()).expect("test");
        let w = f.window_samples() as usize;
        let bias = 10.0f32 / 3600.0;
        let mut before = 0.0;
        for _ in 0..(30 * w) {
            before = f.push(bias, 25.0, None).expect("test").drift_dps;
        }
        let mut worst: f32 = 0.0;
        for _ in 0..(10 * w) {
            let o = f.push(bias + 0.5, 25.0, None).expect("test");
            worst = worst.max((o.drift_dps - before).abs());
        }
        assert!(worst < 0.5 / 3600.0, "{} deg/h", worst * 3600.0);
    }

    #[test]
    fn a_turn_is_never_learnt() {
        // 60 s still at a 10 deg/h bias, then a 0.5 deg/s turn for 120 s, then still.
        let m = ecore_like();
        let mut f = DriftFilter::new(m, DriftFilterConfig::default()).expect("test");
        let mut n = Noise(3);
        let bias = 10.0 / 3600.0;
        let fs = m.sample_rate_hz as usize;
        let mut worst: f64 = 0.0;
        for k in 0..(300 * fs) {
            let t = k as f64 / fs as f64;
            // A slow start: the rate ramps over 5 s.
            let turn = if (60.0..180.0).contains(&t) {
                0.5 * ((t - 60.0) / 5.0).min(1.0)
            } else {
                0.0
            };
            let o = f
                .push(
                    (bias + turn + sigma(&m) * f64::from(n.normal12())) as f32,
                    25.0,
                    None,
                )
                .expect("test");
            if t > 30.0 {
                worst = worst.max((o.drift_dps as f64 - bias).abs());
            }
        }
        assert!(
            worst < 5.0 / 3600.0,
            "worst drift error {} deg/h",
            worst * 3600.0
        );
    }

    #[test]
    fn idling_vibration_is_still_and_a_slow_turn_is_not() {
        // Noise 3x, a 23 Hz engine line of 10x the white sigma: window means still resolve a
        // 0.02 deg/s turn.
        let m = ecore_like();
        let mut f = DriftFilter::new(m, DriftFilterConfig::default()).expect("test");
        let mut n = Noise(11);
        let fs = m.sample_rate_hz as f64;
        let s = sigma(&m);
        let mut moving_still = 0;
        let mut still_windows_at_rest = 0;
        let mut windows_at_rest = 0;
        for k in 0..(400.0 * fs) as usize {
            let t = k as f64 / fs;
            let vib = 10.0 * s * (2.0 * core::f64::consts::PI * 23.0 * t).sin();
            let turn = if t >= 300.0 { 0.02 } else { 0.0 };
            let o = f
                .push(
                    (3.0 * s * f64::from(n.normal12()) + vib + turn) as f32,
                    25.0,
                    None,
                )
                .expect("test");
            if k % (2.0 * fs) as usize == (2.0 * fs) as usize - 1 {
                if t > 304.0 && o.still {
                    moving_still += 1;
                }
                if (60.0..300.0).contains(&t) {
                    windows_at_rest += 1;
                    still_windows_at_rest += o.still as i32;
                }
            }
        }
        assert_eq!(moving_still, 0);
        assert!(
            still_windows_at_rest as f64 > 0.9 * windows_at_rest as f64,
            "{still_windows_at_rest} of {windows_at_rest}"
        );
    }

    #[test]
    fn bad_input_is_refused() {
        let m = ecore_like();
        let mut f = DriftFilter::new(m, DriftFilterConfig::default()).expect("test");
        assert_eq!(
            f.push(f32::NAN, 25.0, None),
            Err(DriftFilterError::NonFiniteRate)
        );
        assert_eq!(f.stats().rejected, 1);
        assert_eq!(f.stats().samples, 0);
        let mut bad = m;
        bad.sample_rate_hz = 0.0;
        assert_eq!(
            DriftFilter::new(bad, DriftFilterConfig::default()).err(),
            Some(DriftFilterError::BadModel)
        );
        let cfg = DriftFilterConfig {
            window_s: 0.001,
            ..DriftFilterConfig::default()
        };
        assert_eq!(
            DriftFilter::new(m, cfg).err(),
            Some(DriftFilterError::BadConfig)
        );
    }
}
