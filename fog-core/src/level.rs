//! The motion estimator's model-free core ([`LevelCore`]): the stillness detector, the
//! level (with its optional second state), its checkpoints and rollback, and the safety
//! net, fed per sample with the model's inputs `x` and model term `m(x)` computed by the
//! caller.
//!
//! [`crate::motion::MotionEstimator`] is a [`MotionModel`](crate::motion::MotionModel), its
//! input map and one core; the product's dual ([`crate::preset::PresetEstimator`]) gives
//! its window estimator, a core alone, the per-sample estimator's inputs and model term.
//! The formulas and the update rules are the motion module's ([`crate::motion`],
//! [`LevelUpdate`]).
//!
//! Inside, configuration and state are apart: the settings (the [`MotionConfig`], how
//! the level learns, the second state's prior, and the constants derived from them) change
//! only at construction and through the setters; the state changes with every sample and
//! goes back to power-on with [`LevelCore::restart`].

use crate::features::TEMP_RATE_BINS;
use crate::motion::{LevelUpdate, MotionConfig, MotionError, MotionOutput, MotionStats};
use crate::motion::{FAST_GATE_K, MOTION_N};
use crate::still::Stillness;

/// The model-free core of a motion estimator (module docs): per sample it takes the rate,
/// the temperature, the external still flag, the model inputs `x` and the model term
/// `m(x)`, and returns the estimator's output.
#[derive(Debug, Clone)]
pub struct LevelCore {
    cfg: LevelConfig,
    state: LevelState,
}

/// The settings and the constants derived from them.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LevelConfig {
    motion: MotionConfig,
    update: LevelUpdate,
    // Whether there is a second state, and its prior variance ((deg/s per deg C)^2; 0 when
    // off). Apart from the enum: two one-byte fields side by side, no padding.
    second: Second,
    thermal_sigma2: f32,
    // The level's random-walk variance per window and per sample, deg^2/s^2.
    window_q: f32,
    sample_q: f32,
    // `stale_s` in samples.
    stale_n: u32,
}

/// What changes with the samples.
#[derive(Debug, Clone)]
struct LevelState {
    still: Stillness,
    // Level Kalman state.
    level: f32,
    level_var: f32,
    // Model term held for the current window, and for the previous one (the one the
    // detector may release).
    model_now: f32,
    model_prev: f32,
    // Per-sample mode: the random-walk variance per sample at a still sample (the unit's
    // wander at rest, [`crate::rest_q`]); `sample_q` unless set.
    rest_q: f32,
    // Per-sample mode: one sample's noise variance (the detector's reference).
    sample_r: f32,
    // Checkpoints: [level, level_var, coef, cov(level, coef), coef_var].
    checkpoint_now: [f32; 5],
    checkpoint_prev: [f32; 5],
    // The second state (the thermal coefficient, deg/s per deg C; 0 with variance 0 when
    // off), its variance and its covariance with the level.
    coef: f32,
    coef_var: f32,
    coef_cov: f32,
    // Per-sample mode: samples since the previous checkpoint and since the current one.
    since_prev: u32,
    since_now: u32,
    // Per-sample mode: a sample of this window was beyond the fast gate.
    halted: bool,
    // The verdict of the detector window the last push ended (`Some(passed)`), if any.
    last_window: Option<bool>,
    // The window mean the last push released, minus its model term (deg/s).
    released_z: Option<f32>,
    // Safety net: a still sample since power-on, samples since the last one (saturating),
    // the model term then.
    rest_verified: bool,
    since_still: u32,
    model_verified: f32,
    // Thermal second state: the first window's measured temperature (deg C), and
    // `T - T0` of the current and previous windows.
    temp0: Option<f32>,
    u_now: f32,
    u_prev: f32,
    stats: MotionStats,
}

/// What sits beside the level.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Second {
    /// Nothing: the level alone (the coefficient stays 0 with variance 0, so the two-state
    /// arithmetic gives the one-state filter's bits).
    Off,
    /// The unit's own temperature link: a constant coefficient `c` (deg/s per deg C, prior
    /// `N(0, thermal_sigma2)`) observed with coefficient `T - T0` (the window's temperature
    /// minus the first window's), so that the drift follows the unit's temperature in
    /// motion; 0 without a temperature channel.
    Thermal,
}

impl LevelCore {
    /// A core at power-on for `cfg`, its level learning per released window
    /// ([`LevelUpdate::Window`]) without a second state. Always inlined: built in its
    /// caller's slot (a call would return it through a stack temporary).
    #[inline(always)]
    pub fn new(cfg: MotionConfig) -> Result<Self, MotionError> {
        cfg.check()?;
        let still = Stillness::new(&cfg.sensor, &cfg.still).ok_or(MotionError::BadStillConfig)?;
        let window_s = still.window_samples() as f32 / cfg.sensor.sample_rate_hz;
        let sample_q = cfg.level_q_dps2_per_s / cfg.sensor.sample_rate_hz;
        let mut c = Self {
            cfg: LevelConfig {
                motion: cfg,
                update: LevelUpdate::default(),
                second: Second::Off,
                thermal_sigma2: 0.0,
                window_q: cfg.level_q_dps2_per_s * window_s,
                sample_q,
                stale_n: {
                    let n = libm::roundf(cfg.stale_s * cfg.sensor.sample_rate_hz);
                    if n < 4.0e9 {
                        n as u32
                    } else {
                        u32::MAX
                    }
                },
            },
            state: LevelState {
                still,
                level: 0.0,
                level_var: 0.0,
                model_now: 0.0,
                model_prev: 0.0,
                rest_q: sample_q,
                sample_r: cfg.sensor.sample_var_dps2() * cfg.still.noise_scale,
                checkpoint_now: [0.0; 5],
                checkpoint_prev: [0.0; 5],
                coef: 0.0,
                coef_var: 0.0,
                coef_cov: 0.0,
                since_prev: 0,
                since_now: 0,
                halted: false,
                last_window: None,
                released_z: None,
                rest_verified: false,
                since_still: 0,
                model_verified: 0.0,
                temp0: None,
                u_now: 0.0,
                u_prev: 0.0,
                stats: MotionStats::default(),
            },
        };
        c.restart();
        Ok(c)
    }

    /// Back to power-on: sample count 0, level 0 with the variance of the whole bound,
    /// detector presumed still ([`crate::still`]), nothing verified. Keeps the settings.
    pub fn restart(&mut self) {
        self.cfg.restart(&mut self.state);
    }

    /// [`crate::motion::MotionEstimator::set_level_update`].
    pub fn set_level_update(&mut self, update: LevelUpdate) {
        self.cfg.update = update;
    }

    /// How the level learns.
    pub fn level_update(&self) -> LevelUpdate {
        self.cfg.update
    }

    /// [`crate::motion::MotionEstimator::set_thermal`] (restarts the core).
    pub fn set_thermal(&mut self, sigma_dps_per_c: f32) {
        (self.cfg.second, self.cfg.thermal_sigma2) =
            if sigma_dps_per_c.is_finite() && sigma_dps_per_c > 0.0 {
                (Second::Thermal, sigma_dps_per_c * sigma_dps_per_c)
            } else {
                (Second::Off, 0.0)
            };
        self.restart();
    }

    /// The second state is the unit's temperature link
    /// ([`crate::motion::MotionEstimator::with_thermal`]).
    pub fn has_thermal(&self) -> bool {
        matches!(self.cfg.second, Second::Thermal)
    }

    /// The unit's temperature coefficient and its variance (0, 0 without the second
    /// state), deg/s per deg C and (deg/s per deg C)^2.
    pub fn thermal(&self) -> (f32, f32) {
        match self.cfg.second {
            Second::Thermal => (self.state.coef, self.state.coef_var),
            Second::Off => (0.0, 0.0),
        }
    }

    /// The next accepted sample is a detector window's first: the one whose model term
    /// [`LevelCore::push`] takes (and holds over the window).
    pub fn next_starts_window(&self) -> bool {
        self.state
            .stats
            .samples
            .is_multiple_of(self.state.still.window_samples())
    }

    /// The model term held over the current window, deg/s (0 before the first sample).
    pub fn model_dps(&self) -> f32 {
        self.state.model_now
    }

    /// One sample: `rate_dps`, `temp_c` (NaN: none), `external_still` (overrides the
    /// detector when `Some`), the model's inputs `x` at this sample
    /// (`[t_s, temp_c, dtemp_c_per_s]`, [`crate::features::TimeTemp`]) and the model term
    /// `m_dps` = `m(x)`, deg/s. `m_dps` is read only when the sample starts a detector
    /// window ([`LevelCore::next_starts_window`]; a non-finite one is taken as 0) and held
    /// until the next start; `x` is read there too (the temperature of the second state).
    /// A non-finite rate is refused and counted.
    pub fn push(
        &mut self,
        rate_dps: f32,
        temp_c: f32,
        external_still: Option<bool>,
        x: &[f32; MOTION_N],
        m_dps: f32,
    ) -> Result<MotionOutput, MotionError> {
        if !rate_dps.is_finite() {
            return Err(self.refuse());
        }
        Ok(self.push_finite(rate_dps, temp_c, external_still, x, m_dps))
    }

    /// Counts a refused (non-finite) rate; the error to return.
    pub(crate) fn refuse(&mut self) -> MotionError {
        self.state.stats.rejected = self.state.stats.rejected.wrapping_add(1);
        MotionError::NonFinite
    }

    /// [`LevelCore::push`] of a finite `rate_dps` (the caller checked it).
    pub(crate) fn push_finite(
        &mut self,
        rate_dps: f32,
        temp_c: f32,
        external_still: Option<bool>,
        x: &[f32; MOTION_N],
        m_dps: f32,
    ) -> MotionOutput {
        self.cfg
            .step(&mut self.state, rate_dps, temp_c, external_still, x, m_dps)
    }

    /// The configuration.
    pub fn config(&self) -> &MotionConfig {
        &self.cfg.motion
    }

    /// The stillness detector.
    pub fn detector(&self) -> &Stillness {
        &self.state.still
    }

    /// The detector's noise reference: one sample's variance at rest, deg^2/s^2, learned
    /// on line ([`crate::still`], "Noise reference"); the per-sample level's `r`.
    pub fn noise_var_dps2(&self) -> f32 {
        self.state.still.noise_var_dps2()
    }

    /// Level estimate and its variance (deg/s, deg^2/s^2).
    pub fn level(&self) -> (f32, f32) {
        (self.state.level, self.state.level_var)
    }

    /// Counters.
    pub fn stats(&self) -> &MotionStats {
        &self.state.stats
    }

    /// The last [`LevelCore::push`] ended a detector window that failed.
    pub fn window_failed(&self) -> bool {
        self.state.last_window == Some(false)
    }

    /// The last accepted [`LevelCore::push`] was a detector window's first sample (where
    /// the level is checkpointed); false before the first. Derived from the sample count
    /// (no per-sample cost); the count wraps after 2^32 samples (497 days at 100 Hz).
    pub fn window_started(&self) -> bool {
        let pushed = self.state.stats.samples;
        pushed != 0 && (pushed - 1).is_multiple_of(self.state.still.window_samples())
    }

    /// Samples per detector window.
    pub fn window_samples(&self) -> u32 {
        self.state.still.window_samples()
    }

    /// The last [`LevelCore::push`] ended a detector window.
    pub fn window_ended(&self) -> bool {
        self.state.last_window.is_some()
    }

    /// [`crate::motion::MotionEstimator::set_rest_q`]: the per-sample level's random-walk
    /// density at still samples, deg^2/s^3 (`q` finite and >= 0, else the
    /// configuration's); [`LevelCore::restart`] sets it back to the configuration's.
    pub fn set_rest_q(&mut self, q_dps2_per_s: f32) {
        let m = &self.cfg.motion;
        let q = if q_dps2_per_s.is_finite() && q_dps2_per_s >= 0.0 {
            q_dps2_per_s
        } else {
            m.level_q_dps2_per_s
        };
        self.state.rest_q = q / m.sensor.sample_rate_hz;
    }

    /// [`LevelCore::released_window`] less the second state's term at that window
    /// (`c (T - T0)`, exact 0 without it): what the level alone observed, deg/s, and the
    /// window mean's variance, (deg/s)^2.
    pub fn released_level_obs(&self) -> Option<(f32, f32)> {
        let s = &self.state;
        let h = match self.cfg.second {
            Second::Thermal => s.u_prev,
            Second::Off => 0.0,
        };
        self.released_window().map(|(z, r)| (z - h * s.coef, r))
    }

    /// The window mean the last [`LevelCore::push`] released (still, and the window after
    /// it still too) minus that window's model term, deg/s, with its variance (white
    /// noise over a window), (deg/s)^2.
    pub fn released_window(&self) -> Option<(f32, f32)> {
        self.state
            .released_z
            .map(|z| (z, self.state.still.window_mean_var_dps2()))
    }
}

impl LevelConfig {
    /// `s` back to power-on.
    fn restart(&self, s: &mut LevelState) {
        s.still.reset();
        s.level = 0.0;
        let b = self.motion.sensor.drift_bound_dps;
        s.level_var = b * b;
        s.model_now = 0.0;
        s.model_prev = 0.0;
        s.coef = 0.0;
        s.coef_var = match self.second {
            Second::Off => 0.0,
            Second::Thermal => self.thermal_sigma2,
        };
        s.coef_cov = 0.0;
        s.checkpoint_now = s.level_state();
        s.checkpoint_prev = s.checkpoint_now;
        s.since_prev = 0;
        s.since_now = 0;
        s.halted = false;
        s.last_window = None;
        s.released_z = None;
        s.rest_verified = false;
        s.since_still = 0;
        s.model_verified = 0.0;
        s.temp0 = None;
        s.u_now = 0.0;
        s.u_prev = 0.0;
        s.sample_r = s.still.noise_var_dps2();
        s.rest_q = self.sample_q;
        s.stats = MotionStats::default();
    }

    /// The second state's observation coefficient: the window's `T - T0` (thermal), 0 when
    /// off (so `coef * 0` adds exact zeros and the level alone decides).
    fn second_coef(&self, s: &LevelState) -> f32 {
        match self.second {
            Second::Off => 0.0,
            Second::Thermal => s.u_now,
        }
    }

    /// Variance of `level + h coef` (what the detector's mean test uses).
    fn drift_var(&self, s: &LevelState) -> f32 {
        match self.second {
            Second::Thermal => {
                let h = self.second_coef(s);
                s.level_var + 2.0 * h * s.coef_cov + h * h * s.coef_var
            }
            Second::Off => s.level_var,
        }
    }

    /// One accepted (finite) sample: [`LevelCore::push`].
    #[inline]
    fn step(
        &self,
        s: &mut LevelState,
        rate_dps: f32,
        temp_c: f32,
        external_still: Option<bool>,
        x: &[f32; MOTION_N],
        m_dps: f32,
    ) -> MotionOutput {
        let k = s.stats.samples;
        if k.is_multiple_of(s.still.window_samples()) {
            s.checkpoint_prev = s.checkpoint_now;
            s.checkpoint_now = s.level_state();
            // Samples since the new previous checkpoint: the last window's.
            s.since_prev = s.since_now;
            s.since_now = 0;
            s.halted = false;
            s.model_prev = s.model_now;
            if s.temp0.is_none() && temp_c.is_finite() {
                s.temp0 = Some(x[1]);
            }
            s.u_prev = s.u_now;
            let u = s.temp0.map_or(0.0, |t0| x[1] - t0);
            s.u_now = if u.is_finite() { u } else { 0.0 };
            s.model_now = if m_dps.is_finite() { m_dps } else { 0.0 };
            // While the temperature-rate input settles (its first TEMP_RATE_BINS seconds),
            // the model term can step by tens of deg/h from one window to the next; the
            // level, seconds old, would unlearn such a step slowly. So in that time its
            // variance grows by the step squared (ASSUMED: the step is uncertain by its
            // size), never beyond the power-on prior (the bound squared): a temperature
            // glitch then costs what power-on costs, and later not at all. A rollback
            // restores its checkpoint's variance.
            let sensor = &self.motion.sensor;
            let settling = (k as f32) < TEMP_RATE_BINS as f32 * sensor.sample_rate_hz;
            if settling {
                let dm = s.model_now - s.model_prev;
                let b = sensor.drift_bound_dps;
                s.level_var = (s.level_var + dm * dm).min(b * b).max(s.level_var);
            }
        }
        let sensor = &self.motion.sensor;
        let second = self.second_coef(s) * s.coef;
        let reference = sensor.clamp_drift(s.level + s.model_now + second);
        // The safety net (MotionOutput::verified): decided on the state before this sample.
        let verified = s.rest_verified && s.since_still <= self.stale_n;
        // Tentative: nothing verified yet, the sample flagged still (presumed at power-on),
        // a per-sample level that learns from it and is rolled back if its window fails.
        let tentative = !s.rest_verified
            && self.update == LevelUpdate::Sample
            && external_still.unwrap_or(s.still.is_still());
        let drift = if verified || tentative {
            reference
        } else if s.rest_verified {
            sensor.clamp_drift(s.level + s.model_verified + second)
        } else {
            0.0
        };
        let drift_var = self.drift_var(s);
        let d = s.still.push(rate_dps, reference, drift_var, external_still);
        let mut still = d.still;
        s.last_window = d.window.map(|w| w.passed);
        s.released_z = None;
        if d.window.is_some() {
            s.sample_r = s.still.noise_var_dps2();
        }
        if self.update == LevelUpdate::Sample {
            still = self.sample_step(s, rate_dps, still, external_still.is_none());
        }
        if still {
            // An external still flag is trusted: verified at once.
            s.rest_verified |= external_still == Some(true);
            s.since_still = 0;
            s.model_verified = s.model_now;
        } else {
            s.since_still = s.since_still.saturating_add(1);
        }
        if let Some(w) = d.window {
            if self.update == LevelUpdate::Sample {
                if !w.passed {
                    // Rollback: no sample of this window or of the one before reaches the level.
                    s.set_level_state(s.checkpoint_prev);
                    s.level_var += self.sample_q * s.since_prev as f32;
                    s.checkpoint_now = s.level_state();
                    s.checkpoint_prev = s.checkpoint_now;
                    s.since_prev = 0;
                    s.since_now = 0;
                }
            } else {
                s.level_var += self.window_q;
            }
            if let Some(mean) = w.confirmed_mean_dps {
                // Released: its window and the next passed in the still state.
                s.rest_verified = true;
                s.released_z = Some(mean - s.model_prev);
                if self.update == LevelUpdate::Window {
                    // The released window is the previous one: its model term is
                    // model_prev (windows and evaluations coincide).
                    let z = mean - s.model_prev;
                    let r = s.still.window_mean_var_dps2();
                    let h = match self.second {
                        // The released window is the previous one: its `T - T0`.
                        Second::Thermal => Some(s.u_prev),
                        Second::Off => None,
                    };
                    if let Some(h) = h {
                        s.window_step_two(z, r, h);
                    } else {
                        let gain = s.level_var / (s.level_var + r);
                        let level = s.level + gain * (z - s.level);
                        if level.is_finite() {
                            s.level = level;
                            s.level_var *= 1.0 - gain;
                        }
                    }
                    s.stats.level_updates = s.stats.level_updates.wrapping_add(1);
                }
            }
        }
        s.stats.samples = k.wrapping_add(1);
        if still {
            s.stats.still_samples = s.stats.still_samples.wrapping_add(1);
        }
        if !verified {
            s.stats.unverified_samples = s.stats.unverified_samples.wrapping_add(1);
        }
        MotionOutput {
            drift_dps: drift,
            compensated_dps: rate_dps - drift,
            still,
            level_dps: s.level,
            model_dps: s.model_now,
            verified,
        }
    }

    /// Per-sample level step ([`LevelUpdate::Sample`]): the random walk always; when the
    /// sample is flagged still, the fast gate, then the Kalman update on `rate - m`.
    /// Returns the still flag after the fast gate. The gate is off for a sample with an
    /// external still flag (the flag overrides the detector, as documented).
    ///
    /// Fast gate: a still-flagged sample whose innovation exceeds [`FAST_GATE_K`] sigma
    /// (the sample noise and the level's variance) marks the rest of its window as moving
    /// at once: no update, flag false, until the detector's verdict at the window end (a
    /// failed window rolls back; a passing one, a false alarm of 1 in 1.7 million samples
    /// of white noise, resumes). This closes the detector's one-window lag at the start of
    /// a drive for any motion above the gate (0.06 deg/s for the E-Core).
    fn sample_step(&self, s: &mut LevelState, rate_dps: f32, still: bool, gate: bool) -> bool {
        s.since_prev = s.since_prev.saturating_add(1);
        s.since_now = s.since_now.saturating_add(1);
        if !still || s.halted {
            s.level_var += self.sample_q;
            return false;
        }
        // At a still sample the unit's own wander (rest q); a sample the gate stops is
        // moving: the configuration's.
        let level_var = s.level_var + s.rest_q;
        // Observation rate - m = level + h c: H = [1, h], h = the window's T - T0 (0: off).
        let h = self.second_coef(s);
        let innovation = rate_dps - s.model_now - s.level - s.coef * h;
        let (ph0, ph1, sk) = s.gain_terms(level_var, h, s.sample_r);
        if gate && innovation * innovation > FAST_GATE_K * FAST_GATE_K * sk {
            s.level_var += self.sample_q;
            s.halted = true;
            return false;
        }
        s.level_var = level_var;
        s.update_two(innovation, ph0, ph1, sk);
        s.stats.level_updates = s.stats.level_updates.wrapping_add(1);
        true
    }
}

impl LevelState {
    /// [`LevelUpdate::Window`] with a second state: one two-state Kalman step on a
    /// released window mean `z` (= `rate - m`, variance `r`), observation `level + h c`
    /// (`h` = the released window's `T - T0`).
    fn window_step_two(&mut self, z: f32, r: f32, h: f32) {
        let innovation = z - self.level - h * self.coef;
        let (ph0, ph1, s) = self.gain_terms(self.level_var, h, r);
        self.update_two(innovation, ph0, ph1, s);
    }

    /// Observation `level + h c` with noise variance `r`, the level's variance taken as
    /// `level_var`: `P H^T = (ph0, ph1)` and the innovation variance `s`.
    #[inline(always)]
    fn gain_terms(&self, level_var: f32, h: f32, r: f32) -> (f32, f32, f32) {
        let ph0 = level_var + h * self.coef_cov;
        let ph1 = self.coef_cov + h * self.coef_var;
        (ph0, ph1, ph0 + h * ph1 + r)
    }

    /// The two-state Kalman update with [`LevelState::gain_terms`]'s `(ph0, ph1, s)`; a
    /// non-finite result leaves the state as it was.
    #[inline(always)]
    fn update_two(&mut self, innovation: f32, ph0: f32, ph1: f32, s: f32) {
        let k0 = ph0 / s;
        let k1 = ph1 / s;
        let level = self.level + k0 * innovation;
        let c = self.coef + k1 * innovation;
        if level.is_finite() && c.is_finite() {
            self.level = level;
            self.coef = c;
            self.level_var -= k0 * ph0;
            self.coef_cov -= k0 * ph1;
            self.coef_var -= k1 * ph1;
        }
    }

    fn level_state(&self) -> [f32; 5] {
        [
            self.level,
            self.level_var,
            self.coef,
            self.coef_cov,
            self.coef_var,
        ]
    }

    fn set_level_state(&mut self, v: [f32; 5]) {
        [
            self.level,
            self.level_var,
            self.coef,
            self.coef_cov,
            self.coef_var,
        ] = v;
    }
}
