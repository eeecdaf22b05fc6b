//! The motion-safe identifier (preset `motion`): learn at rest, compensate in motion.
//!
//! ```text
//! drift(k)       = clamp( level(k) + m(x(k)), +-drift_bound_dps )
//! compensated(k) = rate(k) - drift(k)
//! ```
//! - `x = [t_s since power-on, temp_c, dtemp_c_per_s]` ([`TimeTemp`]): inputs that need no
//!   stillness. Without a temperature channel (NaN until a first value) the temperature is
//!   held at the model's reference (`scaling.offset[1]`) and its rate at 0: the model then
//!   uses time alone.
//! - `m` = a wavelet network ([`MotionModel`]) whose output weights were trained on the
//!   bench over many static records of the gyro family ([`MotionTrainer`]); it predicts
//!   the drift's *shape* (warm-up, thermal bias, Shupe term), not its per-unit offset. The
//!   inputs move slowly: `m` is evaluated once per detector window (1 s by default) and
//!   held in between (a change of the model's input, the same in training).
//! - `level` = a scalar random-walk Kalman state on the residual `rate - m`. By default
//!   ([`LevelUpdate::Window`]) updated only with window means the detector released
//!   (still, and the next window still too). Alternative ([`LevelUpdate::Sample`]):
//!   updated at every sample the stillness detector ([`crate::still`]) flags still,
//!   checkpointed at every window start and rolled back to the checkpoint before the
//!   previous window when a window fails (no sample of a failed window, nor of the one
//!   before it, stays in the level), with a per-sample fast gate ([`FAST_GATE_K`]) that
//!   stops the updates at the first sample of a drive. In motion the level is frozen while
//!   its variance keeps growing, so it re-converges at the next stop. Optional (off by
//!   default), a second state beside the level: the unit's own temperature coefficient
//!   ([`MotionEstimator::with_thermal`], `c (T - T0)`), learned with the level (per sample
//!   with rollback, or per released window as a two-state Kalman step). The product runs
//!   one of these estimators ([`LevelUpdate::Sample`]) beside a second level fed the same
//!   model term (by default a [`LevelUpdate::Window`] core; [`crate::preset`],
//!   [`crate::preset::Arrangement`]).
//! - The clamp to the sensor's drift bound ([`SensorConfig::drift_bound_dps`]) means that
//!   no state can subtract more than the bound from the rate.
//!
//! Per sample: the feature map (a sum and a count; once per second a 30-bin loop), the
//! detector (3 additions, 1 multiplication), a clamp and a subtraction, and in
//! [`LevelUpdate::Sample`] the level step (1 division, about 14 multiply/add/subtract with
//! the second state, 2 compares); once per window the network (`L` Gaussians), a scalar
//! Kalman step (`Window`) or a 5-float checkpoint copy (`Sample`).
//!
//! [`MotionEstimator`] is the model and its input map around a model-free core
//! ([`crate::level::LevelCore`]: the detector, the level and its second state, the safety
//! net), which takes each sample's inputs `x` and model term `m(x)` from it.

use crate::denoise::{denoise_in_place, DenoiseConfig};
use crate::features::{FeatureMap, TimeTemp};
use crate::level::LevelCore;
use crate::still::{SensorConfig, StillConfig};
use crate::train::{Drls, DrlsConfig, DrlsForm, DrlsMode, Trainer};
use crate::wnn::{dot, Activation, Group, InputScaling, ShapeError, WnnShape};

/// Inputs of the motion network: `t_s`, `temp_c`, `dtemp_c_per_s`.
pub const MOTION_N: usize = 3;
/// Neurons of the motion network ([`MotionModel::standard`]).
pub const MOTION_L: usize = 16;
/// Gaussians along time in [`MotionModel::standard`] (the rest: linear links to the
/// temperature and its rate).
pub const TIME_NEURONS: usize = MOTION_L - 2;

/// Why the motion identifier could not be built, trained or fed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MotionError {
    /// The sensor configuration is invalid ([`SensorConfig::is_valid`]).
    BadSensor,
    /// The detector configuration is invalid ([`StillConfig::is_valid`]).
    BadStillConfig,
    /// The level's process noise is not finite and >= 0.
    BadLevelNoise,
    /// The model's time range is not finite and > 0.
    BadTimeRange,
    /// The trainer's configuration is invalid.
    BadTrainer,
    /// The network layout does not fit.
    Shape(ShapeError),
    /// A non-finite rate: refused, counted, nothing changed.
    NonFinite,
    /// A training record shorter than two detector windows.
    RecordTooShort,
    /// The bank level's noise model is invalid ([`crate::bank::BankConfig::is_valid`]).
    BadBank,
}

impl core::fmt::Display for MotionError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BadSensor => f.write_str("invalid sensor configuration"),
            Self::BadStillConfig => f.write_str("invalid stillness detector configuration"),
            Self::BadLevelNoise => f.write_str("level process noise must be finite and >= 0"),
            Self::BadTimeRange => f.write_str("model time range must be finite and > 0"),
            Self::BadTrainer => f.write_str("invalid trainer configuration"),
            Self::Shape(e) => write!(f, "{e}"),
            Self::NonFinite => f.write_str("non-finite rate sample"),
            Self::RecordTooShort => f.write_str("training record shorter than two windows"),
            Self::BadBank => f.write_str("invalid bank level (B > 0, longest tau 1 to 10^4 s)"),
        }
    }
}

impl core::error::Error for MotionError {}

/// The estimator's settings (apart from the trained model).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionConfig {
    /// The gyro: noise model for the detector, drift bound, sample rate.
    pub sensor: SensorConfig,
    /// The stillness detector.
    pub still: StillConfig,
    /// Random-walk density of the level, deg^2/s^2 per s (>= 0): how fast the residual
    /// drift may wander. Its variance grows by `q * window` every window (the window
    /// level) or `q / rate` every sample (the per-sample level, whose still samples take
    /// the unit's own density instead: [`crate::rest_q`]), and in the first 60 s by the
    /// square of the model term's change at each window start (up to the bound squared).
    pub level_q_dps2_per_s: f32,
    /// The safety net's time, s (> 0): after this long without a still sample the output
    /// holds the drift last verified at rest ([`MotionOutput::verified`]).
    pub stale_s: f32,
}

impl MotionConfig {
    /// Default level random walk: 2 deg/h per sqrt(h) = (2/3600)^2 / 3600 deg^2/s^3,
    /// ASSUMED (four times the simulator's rate random walk, to follow what the model
    /// misses); `host-sim` tunes it on validation records (docs/motion.md).
    pub const DEFAULT_LEVEL_Q: f32 = (2.0 / 3600.0) * (2.0 / 3600.0) / 3600.0;

    /// Default [`MotionConfig::stale_s`]: 600 s, ASSUMED (the longest drive of the
    /// vehicle families without a stop is 20 min; the model's shape is trusted for half).
    pub const DEFAULT_STALE_S: f32 = 600.0;

    /// `sensor` with the default detector and level.
    pub const fn for_sensor(sensor: SensorConfig) -> Self {
        Self {
            sensor,
            still: StillConfig::DEFAULT,
            level_q_dps2_per_s: Self::DEFAULT_LEVEL_Q,
            stale_s: Self::DEFAULT_STALE_S,
        }
    }

    /// Every part valid.
    pub fn check(&self) -> Result<(), MotionError> {
        if !self.sensor.is_valid() {
            return Err(MotionError::BadSensor);
        }
        if !self.still.is_valid() {
            return Err(MotionError::BadStillConfig);
        }
        if !(self.level_q_dps2_per_s >= 0.0 && self.level_q_dps2_per_s.is_finite()) {
            return Err(MotionError::BadLevelNoise);
        }
        if !(self.stale_s > 0.0 && self.stale_s.is_finite()) {
            return Err(MotionError::BadStillConfig);
        }
        Ok(())
    }
}

/// The drift-shape network `m(x)`: layout, input scaling, output weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionModel {
    /// Layout (dilations, translations, kinds, activation).
    pub shape: WnnShape<MOTION_N, MOTION_L>,
    /// Raw inputs to the network's units.
    pub scaling: InputScaling<MOTION_N>,
    /// Time since power-on is clamped to `0..=time_max_s` before scaling (after it the
    /// warm-up is over and the model holds its last value instead of fading out), s.
    pub time_max_s: f32,
    /// Output weights, deg/s.
    pub weights: [f32; MOTION_L],
}

/// Reference temperature of [`MotionModel::standard`], deg C (the simulator's and the
/// lab's; ASSUMED).
pub const REFERENCE_TEMP_C: f32 = 25.0;

impl MotionModel {
    /// The standard layout: [`TIME_NEURONS`] Gaussians along time over `0..time_max_s`,
    /// one sigma apart, then linear links to `(temp - 25 C) / 10 C` and to
    /// `dtemp / (0.005 C/s)`; no bias (the level carries the offset); zero weights.
    pub fn standard(time_max_s: f32) -> Result<Self, MotionError> {
        if !(time_max_s > 0.0 && time_max_s.is_finite()) {
            return Err(MotionError::BadTimeRange);
        }
        let shape = WnnShape::from_groups(
            &[
                Group::Along {
                    input: 0,
                    count: TIME_NEURONS,
                    overlap: 1.0,
                },
                Group::Linear(1),
                Group::Linear(2),
            ],
            Activation::Gaussian,
        )
        .map_err(MotionError::Shape)?;
        Ok(Self {
            shape,
            scaling: InputScaling {
                offset: [0.5 * time_max_s, REFERENCE_TEMP_C, 0.0],
                gain: [2.0 / time_max_s, 1.0 / 10.0, 1.0 / 0.005],
            },
            time_max_s,
            weights: [0.0; MOTION_L],
        })
    }

    /// Hidden values for raw inputs `x` (time clamped, then scaled).
    pub fn hidden(&self, x: &[f32; MOTION_N], h: &mut [f32; MOTION_L]) {
        let mut raw = *x;
        raw[0] = if raw[0] > 0.0 {
            raw[0].min(self.time_max_s)
        } else {
            0.0
        };
        self.shape.hidden(&self.scaling.apply(&raw), h);
    }

    /// `m(x)`, deg/s.
    pub fn eval(&self, x: &[f32; MOTION_N]) -> f32 {
        let mut h = [0.0; MOTION_L];
        self.hidden(x, &mut h);
        dot(&self.weights, &h)
    }
}

/// The feature map with the "no temperature channel: hold the reference" rule.
#[derive(Debug, Clone, PartialEq)]
struct Inputs {
    map: TimeTemp,
    samples_per_s: f32,
    reference_c: f32,
    seen_temp: bool,
}

impl Inputs {
    fn new(samples_per_s: f32, reference_c: f32) -> Self {
        Self {
            map: TimeTemp::new(samples_per_s),
            samples_per_s,
            reference_c,
            seen_temp: false,
        }
    }

    fn next(&mut self, t_s: f32, temp_c: f32) -> [f32; MOTION_N] {
        self.seen_temp |= temp_c.is_finite();
        let temp = if self.seen_temp {
            temp_c
        } else {
            self.reference_c
        };
        self.map.next_with_temp(0.0, t_s, temp)
    }

    fn reset(&mut self) {
        *self = Self::new(self.samples_per_s, self.reference_c);
    }
}

/// What the estimator says about one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionOutput {
    /// Drift estimate, deg/s, within the sensor's bound.
    pub drift_dps: f32,
    /// `rate - drift`, deg/s.
    pub compensated_dps: f32,
    /// The sample was taken as still (detector or external flag).
    pub still: bool,
    /// The level (residual drift the model does not explain), deg/s.
    pub level_dps: f32,
    /// The model term `m(x)`, deg/s.
    pub model_dps: f32,
    /// The safety net ([`MotionConfig::stale_s`]): `true` when the output is the whole
    /// estimate; `false` when nothing has been verified on this unit since power-on or no
    /// still sample came for `stale_s`. Verified means a still window confirmed by the
    /// next (the detector released its mean: no rollback reaches it) or an external still
    /// flag. Before that, the per-sample level ([`LevelUpdate::Sample`]) gives a tentative
    /// drift while the detector flags the sample still (presumed at power-on,
    /// [`crate::still`]), undone if its window fails; otherwise the drift is 0, no
    /// compensation. After `stale_s` without a still sample, the drift is the level plus
    /// the model term as they were at the last still sample (what was verified at rest),
    /// until the next rest.
    pub verified: bool,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionStats {
    /// Samples accepted.
    pub samples: u32,
    /// Samples refused (non-finite).
    pub rejected: u32,
    /// Samples flagged still.
    pub still_samples: u32,
    /// Level updates: released still windows ([`LevelUpdate::Window`]) or still samples
    /// ([`LevelUpdate::Sample`]).
    pub level_updates: u32,
    /// Samples whose output was not verified ([`MotionOutput::verified`] false).
    pub unverified_samples: u32,
}

/// The per-sample estimator (see the module docs): the model, its input map and a
/// model-free [`LevelCore`] (detector, level, second state, safety net). Build it from a
/// trained model and a configuration, or from an identifier image ([`crate::image`]).
#[derive(Debug, Clone)]
pub struct MotionEstimator {
    model: MotionModel,
    inputs: Inputs,
    core: LevelCore,
}

/// Fast gate of [`LevelUpdate::Sample`], in sigma of the innovation (ASSUMED: 5 sigma,
/// a white-noise false alarm every 1.7 million samples).
pub const FAST_GATE_K: f32 = 5.0;

/// How the level learns from still samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LevelUpdate {
    /// One Kalman step per released window mean (still, and the next window still too):
    /// the onset of motion never reaches the level, at the cost of a 2-window delay. The
    /// product's window estimator ([`crate::preset`]: the output in motion).
    #[default]
    Window,
    /// One Kalman step per sample flagged still, on `rate - m` (variance `sigma^2`), with
    /// rollback: the level is checkpointed at every window start and, when a window fails
    /// the detector, restored to the checkpoint taken before the PREVIOUS window (so every
    /// sample of the failed window and of the window before it leaves the level; its
    /// variance is the checkpoint's plus the random walk since). The output uses the
    /// tentative level; a fast gate ([`FAST_GATE_K`]) stops the updates of a window at its
    /// first sample beyond the gate. Adds per sample: 1 division, 8 multiply/add/subtract,
    /// 2 compares (and a 5-float copy per window). The product's per-sample estimator
    /// ([`crate::preset`]: the output at rest).
    Sample,
}

impl MotionEstimator {
    /// An estimator at power-on. Always inlined: built in its caller's slot (the dual
    /// builds it beside its window core; a call would return it through a stack
    /// temporary).
    #[inline(always)]
    pub fn new(model: MotionModel, cfg: MotionConfig) -> Result<Self, MotionError> {
        Ok(Self {
            core: LevelCore::new(cfg)?,
            inputs: Inputs::new(cfg.sensor.sample_rate_hz, model.scaling.offset[1]),
            model,
        })
    }

    /// Back to power-on: time 0, level 0 with the variance of the whole bound, detector
    /// presumed still ([`crate::still`]), nothing verified. Keeps the model.
    pub fn restart(&mut self) {
        self.inputs.reset();
        self.core.restart();
    }

    /// Chooses how the level learns ([`LevelUpdate`]; default [`LevelUpdate::Window`]).
    pub fn with_level_update(mut self, update: LevelUpdate) -> Self {
        self.set_level_update(update);
        self
    }

    /// [`MotionEstimator::with_level_update`] in place.
    pub fn set_level_update(&mut self, update: LevelUpdate) {
        self.core.set_level_update(update);
    }

    /// How the level learns.
    pub fn level_update(&self) -> LevelUpdate {
        self.core.level_update()
    }

    /// The unit's own temperature link as the second state:
    /// `drift = level + m(x) + c (T - T0)`, `c` constant with prior standard deviation
    /// `sigma_dps_per_c` (deg/s per deg C, > 0), learned from still samples or released
    /// windows like the level (and rolled back with it). `sigma_dps_per_c` not finite or
    /// <= 0 turns it off. Restarts the estimator.
    pub fn with_thermal(mut self, sigma_dps_per_c: f32) -> Self {
        self.set_thermal(sigma_dps_per_c);
        self
    }

    /// [`MotionEstimator::with_thermal`] in place (restarts the estimator).
    pub fn set_thermal(&mut self, sigma_dps_per_c: f32) {
        self.inputs.reset();
        self.core.set_thermal(sigma_dps_per_c);
    }

    /// The second state is the unit's temperature link ([`MotionEstimator::with_thermal`]).
    pub fn has_thermal(&self) -> bool {
        self.core.has_thermal()
    }

    /// The unit's temperature coefficient and its variance (0, 0 unless
    /// [`MotionEstimator::with_thermal`]), deg/s per deg C.
    pub fn thermal(&self) -> (f32, f32) {
        self.core.thermal()
    }

    /// One sample: `rate_dps`, `temp_c` (NaN: none), `external_still` (overrides the
    /// detector when `Some`). A non-finite rate is refused and counted.
    pub fn push(
        &mut self,
        rate_dps: f32,
        temp_c: f32,
        external_still: Option<bool>,
    ) -> Result<MotionOutput, MotionError> {
        self.push_inputs(rate_dps, temp_c, external_still)
            .map(|(o, _)| o)
    }

    /// [`MotionEstimator::push`], also returning the sample's model inputs `x` (what
    /// [`crate::preset::PresetEstimator`]'s dual gives its window core, with the model
    /// term: the network is evaluated once per window for both).
    pub(crate) fn push_inputs(
        &mut self,
        rate_dps: f32,
        temp_c: f32,
        external_still: Option<bool>,
    ) -> Result<(MotionOutput, [f32; MOTION_N]), MotionError> {
        if !rate_dps.is_finite() {
            return Err(self.core.refuse());
        }
        let t_s = self.core.stats().samples as f32 / self.core.config().sensor.sample_rate_hz;
        let x = self.inputs.next(t_s, temp_c);
        // The network once per detector window (at its first sample); held in between.
        let m = if self.core.next_starts_window() {
            self.model.eval(&x)
        } else {
            self.core.model_dps()
        };
        let o = self
            .core
            .push_finite(rate_dps, temp_c, external_still, &x, m);
        Ok((o, x))
    }

    /// The configuration.
    pub fn config(&self) -> &MotionConfig {
        self.core.config()
    }

    /// The model.
    pub fn model(&self) -> &MotionModel {
        &self.model
    }

    /// The model-free core (detector, level, second state, safety net).
    pub fn core(&self) -> &LevelCore {
        &self.core
    }

    /// The detector's noise reference: one sample's variance at rest, deg^2/s^2, learned
    /// on line ([`crate::still`], "Noise reference"); the per-sample level's `r`.
    pub fn noise_var_dps2(&self) -> f32 {
        self.core.noise_var_dps2()
    }

    /// Level estimate and its variance (deg/s, deg^2/s^2).
    pub fn level(&self) -> (f32, f32) {
        self.core.level()
    }

    /// Counters.
    pub fn stats(&self) -> &MotionStats {
        self.core.stats()
    }

    /// The last [`MotionEstimator::push`] ended a detector window that failed.
    pub fn window_failed(&self) -> bool {
        self.core.window_failed()
    }

    /// The last accepted [`MotionEstimator::push`] was a detector window's first sample
    /// (where the level is checkpointed); false before the first. Derived from the sample
    /// count (no per-sample cost); the count wraps after 2^32 samples (497 days at 100 Hz).
    pub fn window_started(&self) -> bool {
        self.core.window_started()
    }

    /// Samples per detector window.
    pub fn window_samples(&self) -> u32 {
        self.core.window_samples()
    }

    /// The last [`MotionEstimator::push`] ended a detector window.
    pub fn window_ended(&self) -> bool {
        self.core.window_ended()
    }

    /// The per-sample level's random-walk density at still samples, deg^2/s^3
    /// ([`LevelUpdate::Sample`]; [`crate::rest_q`]): `q` finite and >= 0, else the
    /// configuration's [`MotionConfig::level_q_dps2_per_s`]. Moving samples and rolled-back
    /// windows keep the configuration's. [`MotionEstimator::restart`] sets it back to that.
    pub fn set_rest_q(&mut self, q_dps2_per_s: f32) {
        self.core.set_rest_q(q_dps2_per_s);
    }

    /// [`MotionEstimator::released_window`] less the second state's term at that window
    /// (`c (T - T0)`, exact 0 without it): what the level alone observed, deg/s, and the
    /// window mean's variance, (deg/s)^2.
    pub fn released_level_obs(&self) -> Option<(f32, f32)> {
        self.core.released_level_obs()
    }

    /// The window mean the last [`MotionEstimator::push`] released (still, and the window
    /// after it still too) minus that window's model term, deg/s, with its variance
    /// (white noise over a window), (deg/s)^2.
    pub fn released_window(&self) -> Option<(f32, f32)> {
        self.core.released_window()
    }
}

/// Denoising block of the trainer, samples (the firmware's).
pub const TRAIN_BLOCK: usize = 512;

/// The trainer's DRLS: sequential (Gauss-Seidel), energy form, guarded, forgetting factor
/// 0.9998 (a memory of 5000 windows, about 3 records of 1800 s). Why not 1 (no forgetting):
/// with `lambda = 1` every `S_a` grows without bound, the steps shrink as `1/k` and the
/// diagonal sweeps stop before they reach the least-squares weights of overlapping neurons
/// (measured in `trainer_learns_the_shared_shape_not_the_offsets`: 0.70 deg/h error at
/// 1200 s with 1, below 0.41 with 0.9998).
pub const MOTION_DRLS: DrlsConfig = DrlsConfig {
    lambda: 0.9998,
    u0: 1.0,
    u_max: 1.0,
    w_max: 1.0,
    mode: DrlsMode::Sequential,
    form: DrlsForm::Energy,
};

/// What training on one record did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RecordFit {
    /// Training steps (one per full detector window).
    pub steps: u32,
    /// The record's intercept that was removed (mean rate of its full windows), deg/s.
    pub intercept_dps: f32,
    /// RMS of the a-priori errors of this record's steps, deg/s.
    pub rms_error_dps: f32,
}

/// Trains the shared output weights of a [`MotionModel`] on static records, one record at
/// a time, with DRLS.
///
/// Per record (all samples still, from power-on, at the sensor's rate):
/// 1. the rate is denoised in blocks of [`TRAIN_BLOCK`] (the paper's denoiser; a final
///    partial block stays raw);
/// 2. targets are the means of the denoised rate over the detector's windows, inputs the
///    features at each window's first sample (as [`MotionEstimator`] evaluates them);
/// 3. **the per-record intercept is removed by centring the targets**: each target minus
///    the mean rate of the record's windows. Why this and not a per-record bias neuron: each
///    unit's turn-on bias is unknown to the model and is the level's job at run time; a bias
///    neuron reset between records would compete with the Gaussians along time (whose sum
///    is itself nearly constant), and diagonal DRLS splits such a shared direction badly,
///    leaking part of each record's offset into the shared weights. Centring removes the
///    offset exactly; the model then learns the shape up to a constant, which the level
///    absorbs at the first stop. Records of equal length and the same power-on time axis
///    give the same constant; a short record shifts its targets by the mean of its own
///    part of the shape (a small bias the level absorbs too).
///
/// Call [`MotionTrainer::train_record`] for each record, several passes (epochs) if wanted
/// (DRLS is diagonal: a few Gauss-Seidel passes bring the weights closer to least squares).
#[derive(Debug, Clone)]
pub struct MotionTrainer {
    model: MotionModel,
    drls: Drls<MOTION_L>,
    window_s: f32,
    records: u32,
}

impl MotionTrainer {
    /// A trainer starting from `model`'s weights; `window_s` is the detector window of the
    /// estimator the model is for.
    pub fn new(model: MotionModel, drls: DrlsConfig, window_s: f32) -> Result<Self, MotionError> {
        if !(window_s > 0.0 && window_s.is_finite()) {
            return Err(MotionError::BadStillConfig);
        }
        Ok(Self {
            model,
            drls: Drls::new(drls).ok_or(MotionError::BadTrainer)?,
            window_s,
            records: 0,
        })
    }

    /// Trains on one static record: `rate_dps` at `sample_rate_hz`, `temp_c` the same length
    /// or `None` (the model's reference temperature is used). Non-finite rates are replaced
    /// by the previous sample (0 at the start) for denoising, and the windows holding them
    /// are skipped.
    pub fn train_record(
        &mut self,
        rate_dps: &[f32],
        temp_c: Option<&[f32]>,
        sample_rate_hz: f32,
    ) -> Result<RecordFit, MotionError> {
        let (mut steps, mut err2) = (0u32, 0.0f64);
        let ref_temp_c = self.model.scaling.offset[1];
        let mut h = [0.0f32; MOTION_L];
        let model = &mut self.model;
        let drls = &mut self.drls;
        let intercept = for_each_window(
            rate_dps,
            temp_c,
            sample_rate_hz,
            self.window_s,
            ref_temp_c,
            |_, x, d| {
                model.hidden(x, &mut h);
                let e = drls.step(&mut model.weights, &h, d);
                if e.is_finite() {
                    steps += 1;
                    err2 += f64::from(e) * f64::from(e);
                }
            },
        )?;
        self.records = self.records.wrapping_add(1);
        Ok(RecordFit {
            steps,
            intercept_dps: intercept,
            rms_error_dps: if steps > 0 {
                libm::sqrt(err2 / f64::from(steps)) as f32
            } else {
                f32::NAN
            },
        })
    }

    /// The model with the weights trained so far.
    pub fn model(&self) -> &MotionModel {
        &self.model
    }

    /// The DRLS state (saved in the identifier image).
    pub fn drls(&self) -> &Drls<MOTION_L> {
        &self.drls
    }

    /// Records trained on (passes included).
    pub fn records(&self) -> u32 {
        self.records
    }
}

/// The training targets of one static record: calls `f(j, x, d)` for every full detector
/// window `j` (0-based) without a non-finite rate, `x` the features at the window's first sample, `d` the
/// window's mean of the denoised rate minus the record's intercept (returned: the mean of
/// the full windows' finite samples). See [`MotionTrainer`] for the steps.
pub(crate) fn for_each_window(
    rate_dps: &[f32],
    temp_c: Option<&[f32]>,
    sample_rate_hz: f32,
    window_s: f32,
    ref_temp_c: f32,
    mut f: impl FnMut(usize, &[f32; MOTION_N], f32),
) -> Result<f32, MotionError> {
    if !(sample_rate_hz > 0.0 && sample_rate_hz.is_finite()) {
        return Err(MotionError::BadSensor);
    }
    let w = libm::roundf(window_s * sample_rate_hz).max(8.0) as usize;
    let windows = rate_dps.len() / w;
    if windows < 2 {
        return Err(MotionError::RecordTooShort);
    }
    // Intercept: mean of the full windows' finite samples (f64 sum: 10^6 samples).
    let (mut sum, mut n) = (0.0f64, 0u32);
    for &x in rate_dps.iter().take(windows * w).filter(|x| x.is_finite()) {
        sum += f64::from(x);
        n += 1;
    }
    let intercept = if n > 0 {
        (sum / f64::from(n)) as f32
    } else {
        0.0
    };

    let mut inputs = Inputs::new(sample_rate_hz, ref_temp_c);
    let mut block = [0.0f32; TRAIN_BLOCK];
    let mut scratch = [0.0f32; TRAIN_BLOCK];
    let mut x_window = [0.0f32; MOTION_N];
    let (mut acc, mut acc_n, mut bad) = (0.0f32, 0usize, false);
    let mut last = 0.0f32;
    let dt = 1.0 / sample_rate_hz;
    let full = windows * w;
    let mut start = 0usize;
    while start < full {
        let end = (start + TRAIN_BLOCK).min(full);
        let len = end - start;
        let mut any_bad = [false; TRAIN_BLOCK];
        for (i, slot) in block.iter_mut().take(len).enumerate() {
            let v = rate_dps.get(start + i).copied().unwrap_or(f32::NAN);
            if v.is_finite() {
                last = v;
            } else {
                any_bad[i] = true;
            }
            *slot = last;
        }
        if len == TRAIN_BLOCK {
            // A refused block (cannot happen with finite values) stays raw.
            let _ = denoise_in_place(&mut block, &mut scratch, &DenoiseConfig::PAPER);
        }
        for i in 0..len {
            let k = start + i;
            let temp = temp_c.and_then(|t| t.get(k).copied()).unwrap_or(f32::NAN);
            let x = inputs.next(k as f32 * dt, temp);
            if k.is_multiple_of(w) {
                x_window = x;
            }
            acc += block[i];
            acc_n += 1;
            bad |= any_bad[i];
            if acc_n == w {
                if !bad {
                    f(k / w, &x_window, acc / w as f32 - intercept);
                }
                acc = 0.0;
                acc_n = 0;
                bad = false;
            }
        }
        start = end;
    }
    Ok(intercept)
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::vec::Vec;

    use crate::test_noise::Noise;

    const S: SensorConfig = SensorConfig::ECORE_2000;

    /// Warm-up shape: 3 deg/h decaying in 600 s.
    fn shape(t: f32) -> f32 {
        3.0 / 3600.0 * (-t / 600.0).exp()
    }

    fn record(seed: u64, bias: f32, n: usize) -> Vec<f32> {
        let mut z = Noise(seed);
        let sigma = S.sample_var_dps2().sqrt();
        (0..n)
            .map(|k| bias + shape(k as f32 * 0.01) + sigma * z.normal())
            .collect()
    }

    #[test]
    fn trainer_learns_the_shared_shape_not_the_offsets() {
        let model = MotionModel::standard(1800.0).expect("test");
        let mut tr = MotionTrainer::new(model, MOTION_DRLS, 1.0).expect("test");
        for epoch in 0..2 {
            for r in 0..6u64 {
                let bias = (r as f32 - 2.5) * 2.0 / 3600.0;
                let fit = tr.train_record(&record(r + 10 * epoch, bias, 180_000), None, 100.0);
                assert!(fit.expect("test").steps == 1800);
            }
        }
        let m = tr.model();
        // Changes of the shape are learned to within 0.6 deg/h (offset removed).
        let x = |t: f32| [t, REFERENCE_TEMP_C, 0.0];
        let diff: Vec<f32> = (0..36)
            .map(|i| (m.eval(&x(25.0 + 50.0 * i as f32)) - shape(25.0 + 50.0 * i as f32)) * 3600.0)
            .collect();
        let c = diff.iter().sum::<f32>() / diff.len() as f32;
        let rms = (diff.iter().map(|d| (d - c) * (d - c)).sum::<f32>() / diff.len() as f32).sqrt();
        // Noise floor: a window mean is 4 deg/h (1 sigma); each neuron sees about 140
        // windows per record, 6 records, and the trainer's memory is about 3 records.
        assert!(rms < 0.3, "rms {rms} deg/h: {diff:?}");
        // The shape itself spans 3 deg/h: it is learned, not ignored.
        assert!((diff[0] - diff[35]).abs() < 1.0, "{diff:?}");
        // An untrained model predicts nothing.
        assert_eq!(
            MotionModel::standard(1800.0).expect("test").eval(&x(10.0)),
            0.0
        );
    }

    #[test]
    fn window_started_marks_each_windows_first_accepted_sample() {
        let model = MotionModel::standard(1800.0).expect("test");
        let mut e = MotionEstimator::new(model, MotionConfig::for_sensor(S)).expect("test");
        let w = e.window_samples() as usize;
        assert!(!e.window_started(), "no push yet");
        let x = record(3, 0.0, 2 * w + 50);
        for (k, &r) in x.iter().enumerate() {
            e.push(r, 25.0, None).expect("test");
            assert_eq!(e.window_started(), k % w == 0, "{k}");
            // A refused sample is not a sample: the answer stays.
            assert!(e.push(f32::NAN, 25.0, None).is_err());
            assert_eq!(e.window_started(), k % w == 0, "{k} after a refused sample");
        }
        e.restart();
        assert!(!e.window_started());
    }

    #[test]
    fn estimator_holds_in_motion_and_is_bounded() {
        let model = MotionModel::standard(1800.0).expect("test");
        let mut e = MotionEstimator::new(model, MotionConfig::for_sensor(S)).expect("test");
        let mut z = Noise(5);
        let sigma = S.sample_var_dps2().sqrt();
        let bias = 4.0 / 3600.0;
        let mut max_drift = 0.0f32;
        for k in 0..60_000usize {
            // Still 60 s, then turns of 10 deg/s for 30 s and stops of 30 s.
            let moving = k >= 6000 && (k / 3000) % 2 == 0;
            let turn = if moving { 10.0 } else { 0.0 };
            let o = e
                .push(bias + turn + sigma * z.normal(), f32::NAN, None)
                .expect("test");
            max_drift = max_drift.max(o.drift_dps.abs());
            if k > 5000 && !moving {
                // Once aligned, the level is the bias within 1 deg/h.
                assert!(
                    (o.level_dps - bias).abs() < 1.0 / 3600.0,
                    "{k}: {}",
                    o.level_dps
                );
            }
        }
        assert!(max_drift <= S.drift_bound_dps);
        assert!(e.stats().level_updates > 100);
        assert!(e.push(f32::NAN, 0.0, None).is_err());
        assert_eq!(e.stats().rejected, 1);
    }

    #[test]
    fn rollback_removes_every_sample_of_the_failed_windows() {
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        let sigma = S.sample_var_dps2().sqrt();
        let bias = 2.0 / 3600.0;
        let mut z = Noise(21);
        // 30 s still: the reference estimator stops at the start of a window.
        let still: Vec<f32> = (0..3000).map(|_| bias + sigma * z.normal()).collect();
        let mut a = MotionEstimator::new(model, cfg)
            .expect("test")
            .with_level_update(LevelUpdate::Sample);
        assert_eq!(a.level_update(), LevelUpdate::Sample);
        for &x in &still {
            a.push(x, f32::NAN, None).expect("test");
        }
        let (level_a, var_a) = a.level();
        // Then a window with a creeping onset the detector passes (0.2 sigma of a sample:
        // 2 sigma of a window mean, below the 4-sigma test), then a 10 deg/s turn.
        let mut b = a.clone();
        let mut passed_creep = false;
        for k in 0..200 {
            let turn = if k < 100 { 0.2 * sigma } else { 10.0 };
            let o = b
                .push(bias + turn + sigma * z.normal(), f32::NAN, None)
                .expect("test");
            if k == 99 {
                // The creep reached the tentative level...
                assert!(b.level().0 != level_a);
            }
            if k == 100 {
                // ... the creeping window passed, but the turn's first sample trips the
                // fast gate: called moving at once.
                passed_creep = b.core.detector().is_still();
                assert!(!o.still);
            }
        }
        assert!(
            passed_creep,
            "the creeping window must pass for this test to mean anything"
        );
        // ... and the failed turn window rolled it back, bit for bit, with the variance of
        // the random walk over the 200 samples.
        let (level_b, var_b) = b.level();
        assert_eq!(level_b, level_a);
        let q = cfg.level_q_dps2_per_s / S.sample_rate_hz;
        assert!(
            (var_b - (var_a + 200.0 * q)).abs() <= 1e-6 * var_b,
            "{var_a} {var_b}"
        );
        // The window update never takes a sample in before the next window passed.
        let mut c = MotionEstimator::new(model, cfg)
            .expect("test")
            .with_level_update(LevelUpdate::Window);
        for &x in &still {
            c.push(x, f32::NAN, None).expect("test");
        }
        assert!((c.level().0 - bias).abs() < 1.0 / 3600.0);
    }

    #[test]
    fn model_term_is_added_and_clamped() {
        let mut model = MotionModel::standard(1800.0).expect("test");
        model.weights = [1.0; MOTION_L];
        let mut e = MotionEstimator::new(model, MotionConfig::for_sensor(S)).expect("test");
        // Nothing verified at power-on: no compensation (the safety net).
        let o = e.push(0.0, 25.0, Some(false)).expect("test");
        assert!(!o.verified);
        assert_eq!(o.drift_dps, 0.0);
        e.push(0.0, 25.0, Some(true)).expect("test");
        let o = e.push(0.0, 25.0, Some(false)).expect("test");
        assert!(o.verified);
        assert!(o.model_dps > S.drift_bound_dps);
        assert_eq!(o.drift_dps, S.drift_bound_dps);
    }

    /// Temperature of window `w` (deg C): constant within each 1-s window (so that the
    /// window's `T - T0` is the record's), a 1-deg sine of period 300 s.
    fn window_temp_c(k: usize) -> f32 {
        let w = (k / 100) as f32;
        25.0 + (w * 2.0 * core::f32::consts::PI / 300.0).sin()
    }

    #[test]
    fn thermal_level_matches_a_float_reference() {
        // Untrained model (m = 0), every sample flagged still by the external flag: the
        // level + thermal coefficient is the two-state Kalman filter with observation
        // `level + (T - T0) c`, checked against an f64 reference written here.
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        let sigma_c = 2.0f32 / 3600.0;
        let mut e = MotionEstimator::new(model, cfg)
            .expect("test")
            .with_level_update(LevelUpdate::Sample)
            .with_thermal(sigma_c);
        let q = f64::from(cfg.level_q_dps2_per_s) / f64::from(S.sample_rate_hz);
        let b = f64::from(S.drift_bound_dps);
        let (mut x, mut p) = ([0.0f64; 2], [b * b, 0.0, f64::from(sigma_c).powi(2)]);
        let mut z = Noise(3);
        let sigma = f64::from(S.sample_var_dps2()).sqrt();
        let t0 = f64::from(window_temp_c(0));
        let mut max_err = 0.0f64;
        for k in 0..30_000 {
            let temp = window_temp_c(k);
            let h = f64::from(temp) - t0;
            let y = 3.0 / 3600.0 + 1.5 / 3600.0 * h + sigma * f64::from(z.normal());
            let o = e.push(y as f32, temp, Some(true)).expect("test");
            // The sample's noise variance: the detector's reference, learned at window ends
            // (crate::still, "Noise reference"; the Kalman step takes it from there).
            let r = f64::from(e.noise_var_dps2());
            // Reference: predict, estimate (from earlier samples), update.
            if k > 0 {
                p[0] += q;
                let err = (f64::from(o.drift_dps) - (x[0] + h * x[1])).abs();
                max_err = max_err.max(err);
            }
            let (h0, h1) = (p[0] + h * p[1], p[1] + h * p[2]);
            let sk = h0 + h * h1 + r;
            let (k0, k1) = (h0 / sk, h1 / sk);
            let inn = y - x[0] - h * x[1];
            x = [x[0] + k0 * inn, x[1] + k1 * inn];
            p = [p[0] - k0 * h0, p[1] - k0 * h1, p[2] - k1 * h1];
        }
        // f32 against f64 over 30,000 steps: within 0.02 deg/h; the coefficient learnt (the
        // reference's, within 0.02 deg/h per deg C; the random-walk level takes part of the
        // true 1.5, so the filter's estimate is lower: 1.01 measured).
        assert!(max_err < 0.02 / 3600.0, "{}", max_err * 3600.0);
        let (c, c_var) = e.thermal();
        assert!(
            (f64::from(c) - x[1]).abs() < 0.02 / 3600.0 && c > 0.5 / 3600.0,
            "{} vs {}",
            c * 3600.0,
            x[1] * 3600.0
        );
        assert!(c_var > 0.0 && c_var < sigma_c * sigma_c);
    }

    /// Two thermal estimators with `update`, fed the same noise `z`, drift and temperature,
    /// one of them turning at 20 deg/s during a 60-s drive: their drifts are bit-identical,
    /// and the coefficient does not move in motion once the drive's first windows failed
    /// (the per-sample update rolls back the two windows before; then nothing is learnt).
    fn assert_rotation_ignored_by_the_thermal_state(update: LevelUpdate, z: &mut Noise) {
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        let make = || {
            MotionEstimator::new(model, cfg)
                .expect("test")
                .with_level_update(update)
                .with_thermal(2.0 / 3600.0)
        };
        let (mut a, mut b) = (make(), make());
        let sigma = S.sample_var_dps2().sqrt();
        let mut c_at_drive_start = 0.0;
        for k in 0..12_000usize {
            let moving = (6000..12_000).contains(&k);
            let temp = window_temp_c(k);
            let n = sigma * z.normal();
            let drift = 4.0 / 3600.0 + 1.0 / 3600.0 * (temp - 25.0);
            // `b` turns at 20 deg/s during the drive; `a` does not.
            let oa = a.push(drift + n, temp, Some(!moving)).expect("test");
            let turn = if moving { 20.0 } else { 0.0 };
            let ob = b.push(drift + n + turn, temp, Some(!moving)).expect("test");
            assert_eq!(oa.drift_dps, ob.drift_dps, "{k}");
            if k == 6200 {
                c_at_drive_start = a.thermal().0;
            }
        }
        assert!(c_at_drive_start != 0.0);
        assert_eq!(a.thermal().0, c_at_drive_start);
    }

    #[test]
    fn thermal_state_ignores_rotation_in_motion() {
        assert_rotation_ignored_by_the_thermal_state(LevelUpdate::Sample, &mut Noise(17));
        assert_rotation_ignored_by_the_thermal_state(LevelUpdate::Window, &mut Noise(19));
    }

    #[test]
    fn window_thermal_follows_the_temperature_at_rest() {
        // At rest, a drift of 3 deg/h plus 2 deg/h per deg C of a 1-deg sine (period 300 s):
        // the window level with the thermal state follows it better than the level alone
        // (same q), and learns the coefficient.
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        let mut plain = MotionEstimator::new(model, cfg).expect("test");
        let mut thermal = plain.clone().with_thermal(4.0 / 3600.0);
        assert_eq!(thermal.level_update(), LevelUpdate::Window);
        let mut z = Noise(23);
        let sigma = S.sample_var_dps2().sqrt();
        let (mut e_plain, mut e_thermal) = (0.0f64, 0.0f64);
        for k in 0..120_000usize {
            let temp = window_temp_c(k);
            let drift = 3.0 / 3600.0 + 2.0 / 3600.0 * (temp - 25.0);
            let y = drift + sigma * z.normal();
            let a = plain.push(y, temp, None).expect("test");
            let b = thermal.push(y, temp, None).expect("test");
            if k >= 10_000 {
                e_plain += f64::from(a.drift_dps - drift).powi(2);
                e_thermal += f64::from(b.drift_dps - drift).powi(2);
            }
        }
        assert!(e_thermal < 0.5 * e_plain, "{e_thermal} vs {e_plain}");
        let (c, c_var) = thermal.thermal();
        assert!((c - 2.0 / 3600.0).abs() < 0.3 / 3600.0, "{}", c * 3600.0);
        assert!(c_var > 0.0);
    }
}
