//! The on-line drift identifier: what the firmware runs per sample.
//!
//! Per sample `k` (rate `X(k)` in deg/s):
//! 1. inputs `x(k)` = the feature map of the stream (scaled by an [`InputScaling`]);
//! 2. **output** `y(k) = w . h(x(k))` with the current weights: the identified drift for
//!    this sample, available at once, computed *before* any training on sample `k`;
//! 3. **training** on sample `k - B`: its inputs were kept in a ring of `B` entries and its
//!    target `d(k - B)` (the denoised rate) came out of the block denoiser when its block
//!    completed; the trainer makes one step with `h(x(k - B))` and `d(k - B)`. So targets
//!    are used exactly `B` samples after their measurement, one per incoming sample (no
//!    burst of `B` updates when a block completes);
//! 4. `X(k)` goes into the [`BlockDenoiser`](crate::denoise::BlockDenoiser); when it completes a block, the block's
//!    denoised values become the targets of the next `B` training steps.
//!
//! Memory, fixed at compile time: denoising block and its scratch `8 B` bytes, input ring
//! `4 N B`, network `4 L (N + 3)`, the hidden values of the output and of the training step
//! kept from the previous sample (`2 (4 L + 16)`: [`HiddenCache`]), plus the trainer and
//! the feature map. The block buffer
//! doubles as the store of targets: slot `k mod B` holds `d(k - B)` until sample `k` is
//! trained on it and then stored in its place (the same as
//! [`crate::denoise::BlockDenoiser`] plus a copy of each denoised block, without the copy).

use crate::denoise::{check_config, denoise_in_place, DenoiseConfig, DenoiseError};
use crate::features::FeatureMap;
use crate::train::Trainer;
use crate::wnn::{dot, HiddenCache, InputScaling, WnnShape};

/// Why an identifier could not be built or a sample was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum IdentifyError {
    /// The denoiser refused the configuration or the sample.
    Denoise(DenoiseError),
    /// The sample period is not a positive finite number.
    BadSamplePeriod,
    /// The trainer's configuration is invalid.
    BadTrainer,
    /// The network layout does not fit its sizes.
    Shape(crate::wnn::ShapeError),
}

impl From<DenoiseError> for IdentifyError {
    fn from(e: DenoiseError) -> Self {
        Self::Denoise(e)
    }
}

impl core::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Denoise(e) => write!(f, "{e}"),
            Self::BadSamplePeriod => {
                f.write_str("sample period must be a positive finite number of seconds")
            }
            Self::BadTrainer => f.write_str("invalid trainer configuration"),
            Self::Shape(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for IdentifyError {}

/// What the identifier says about one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// Identified drift `y(k)`, deg/s, from the weights before any training on this sample.
    pub drift_dps: f32,
    /// `X(k) - y(k)`, deg/s.
    pub compensated_dps: f32,
    /// A-priori error of the training step made at this sample (`d(k-B) - y(k-B)` with the
    /// weights before the step), deg/s; NaN when no step was made (the first `2B` samples).
    pub train_error_dps: f32,
    /// This sample completed a denoising block.
    pub block_done: bool,
}

/// Counters of everything the identifier saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IdentifierStats {
    /// Samples accepted.
    pub samples: u32,
    /// Samples refused (non-finite or out of range); they change nothing.
    pub rejected: u32,
    /// Training steps made.
    pub trained: u32,
    /// Denoising blocks completed.
    pub blocks: u32,
}

/// The on-line identifier: feature map `F` (`N` inputs), network of `L` neurons, trainer
/// `T`, denoising blocks of `B` samples.
pub struct Identifier<F, T, const N: usize, const L: usize, const B: usize> {
    features: F,
    scaling: InputScaling<N>,
    shape: WnnShape<N, L>,
    w: [f32; L],
    trainer: T,
    denoise: DenoiseConfig,
    /// Samples `0..k mod B` of the current block, then the denoised values of the last
    /// completed block (the targets of the next training steps).
    block: [f32; B],
    scratch: [f32; B],
    ring: [[f32; N]; B],
    /// Hidden values of the output and of the training step, each kept for the next
    /// sample (runs whose input did not change are not evaluated again).
    out_h: HiddenCache<L>,
    train_h: HiddenCache<L>,
    have_targets: bool,
    block_time: bool,
    sample_period_s: f32,
    stats: IdentifierStats,
}

impl<F: FeatureMap<N>, T: Trainer<L>, const N: usize, const L: usize, const B: usize>
    Identifier<F, T, N, L, B>
{
    /// An identifier with initial weights `w0`.
    pub fn new(
        features: F,
        scaling: InputScaling<N>,
        shape: WnnShape<N, L>,
        w0: [f32; L],
        trainer: T,
        denoise: DenoiseConfig,
        sample_period_s: f32,
    ) -> Result<Self, IdentifyError> {
        if !(sample_period_s > 0.0 && sample_period_s.is_finite()) {
            return Err(IdentifyError::BadSamplePeriod);
        }
        // The configuration against `B`, once (as `BlockDenoiser::new` does).
        check_config(B, B, &denoise)?;
        Ok(Self {
            features,
            scaling,
            shape,
            w: w0,
            trainer,
            denoise,
            block: [0.0; B],
            scratch: [0.0; B],
            ring: [[0.0; N]; B],
            out_h: HiddenCache::new(),
            train_h: HiddenCache::new(),
            have_targets: false,
            block_time: false,
            sample_period_s,
            stats: IdentifierStats::default(),
        })
    }

    /// The time handed to the feature map becomes that of the first sample of the current
    /// denoising block, `(k - k mod B) dt`, instead of `k dt`: the time input steps by
    /// `B dt` (5.12 s for `B` = 512 at 100 Hz) and is the same for the `B` samples of a
    /// block, both when the output is computed and when those samples are trained on.
    ///
    /// Why: a network whose neurons along `T` are far wider than a block (the level-trend
    /// network's are 138 s apart over 1800 s) barely changes within a block, and with a
    /// held `T` its Gaussians along `T` are evaluated once per block instead of twice per
    /// sample ([`HiddenCache`]). It is a change of the model's input (a step function of
    /// time), not an approximation of the evaluation: the output and the training see the
    /// same held value. Effect on the identification error: `docs/identify.md`.
    pub fn with_block_time(mut self) -> Self {
        self.block_time = true;
        self
    }

    /// Processes one sample (see the module docs). A refused sample (non-finite, or above
    /// the denoiser's range) returns an error, is counted, and changes nothing.
    pub fn push(&mut self, rate_dps: f32) -> Result<Estimate, IdentifyError> {
        self.push_with_temp(rate_dps, f32::NAN)
    }

    /// [`Identifier::push`] with the sensor temperature of the sample, deg C (NaN: none),
    /// for feature maps that use it (e.g. [`crate::features::TimeTemp`]); the others ignore
    /// it. A non-finite temperature is not a refusal: the feature map holds its last value.
    pub fn push_with_temp(
        &mut self,
        rate_dps: f32,
        temp_c: f32,
    ) -> Result<Estimate, IdentifyError> {
        if !rate_dps.is_finite() || libm::fabsf(rate_dps) > crate::denoise::MAX_ABS_INPUT {
            self.stats.rejected = self.stats.rejected.wrapping_add(1);
            return Err(if rate_dps.is_finite() {
                DenoiseError::OutOfRange
            } else {
                DenoiseError::NonFinite
            }
            .into());
        }
        let k = self.stats.samples;
        let slot = k as usize % B;
        let t_index = if self.block_time { k - slot as u32 } else { k };
        let t_s = t_index as f32 * self.sample_period_s;
        let x = self
            .scaling
            .apply(&self.features.next_with_temp(rate_dps, t_s, temp_c));
        let y = dot(&self.w, self.out_h.eval(&self.shape, &x));

        let mut train_error_dps = f32::NAN;
        if self.have_targets {
            let h = self.train_h.eval(&self.shape, &self.ring[slot]);
            train_error_dps = self.trainer.step(&mut self.w, h, self.block[slot]);
            self.stats.trained = self.stats.trained.wrapping_add(1);
        }
        self.ring[slot] = match self.features.train_inputs() {
            None => x,
            Some(t) => self.scaling.apply(&t),
        };
        // The target d(k - B) has been used: the slot takes this sample.
        self.block[slot] = rate_dps;

        let mut block_done = false;
        if slot + 1 == B {
            denoise_in_place(&mut self.block, &mut self.scratch, &self.denoise)?;
            self.have_targets = true;
            block_done = true;
            self.stats.blocks = self.stats.blocks.wrapping_add(1);
        }
        self.stats.samples = k.wrapping_add(1);
        Ok(Estimate {
            drift_dps: y,
            compensated_dps: rate_dps - y,
            train_error_dps,
            block_done,
        })
    }

    /// Starts a new record (a new power-on): forgets the features' history, the denoiser's
    /// partial block, the stored inputs and targets, and restarts time at 0; keeps the
    /// weights and the trainer's state (what was learned). `features` is the feature map for
    /// the new record (e.g. made for its sample rate).
    pub fn restart(&mut self, features: F, sample_period_s: f32) -> Result<(), IdentifyError> {
        if !(sample_period_s > 0.0 && sample_period_s.is_finite()) {
            return Err(IdentifyError::BadSamplePeriod);
        }
        self.features = features;
        self.sample_period_s = sample_period_s;
        self.have_targets = false;
        self.stats.samples = 0;
        Ok(())
    }

    /// The denoised values of the block the last push completed (oldest first): read it
    /// right after a push whose [`Estimate::block_done`] is true. The buffer is shared with
    /// the next block, so each later push replaces one value (the oldest, once it has
    /// served as a target) with its raw sample. All zero before the first sample.
    pub fn last_denoised_block(&self) -> &[f32; B] {
        &self.block
    }

    /// Current output weights.
    pub fn weights(&self) -> &[f32; L] {
        &self.w
    }

    /// Replaces the output weights (e.g. with weights pretrained on the host).
    pub fn set_weights(&mut self, w: [f32; L]) {
        self.w = w;
    }

    /// The trainer (for diagnostics such as DRLS's `U`).
    pub fn trainer(&self) -> &T {
        &self.trainer
    }

    /// Mutable access to the trainer (e.g. per-neuron DRLS settings).
    pub fn trainer_mut(&mut self) -> &mut T {
        &mut self.trainer
    }

    /// The network's shape.
    pub fn shape(&self) -> &WnnShape<N, L> {
        &self.shape
    }

    /// The input scaling.
    pub fn scaling(&self) -> &InputScaling<N> {
        &self.scaling
    }

    /// Counters.
    pub fn stats(&self) -> &IdentifierStats {
        &self.stats
    }
}

/// The two standard configurations, for any number of neurons `L` (the paper's is 30).
pub mod presets {
    use super::IdentifyError;
    use crate::denoise::DenoiseConfig;
    use crate::features::{
        LevelTrendTime, MultiScaleLevels, RateTime, TimeTemp, BANK_INPUTS, BANK_MEMORIES_S, BANK_T,
    };
    use crate::train::{Drls, DrlsConfig, DrlsForm, DrlsMode, Trainer};
    use crate::wnn::{Activation, Group, InputScaling, ShapeError, WnnShape};

    /// The paper's number of hidden neurons.
    pub const L: usize = 30;

    /// The paper's identifier: inputs `[X, T]`, wavelet neurons, DRLS.
    pub type Paper<const B: usize, const NL: usize = L> =
        super::Identifier<RateTime, Drls<NL>, 2, NL, B>;

    /// The improved identifier: inputs `[level, trend, T]` (the trend held for
    /// [`TREND_HOLD_S`], [`level_trend_features`]; `T` held per denoising block,
    /// [`super::Identifier::with_block_time`]), bias + linear link + Gaussians, sequential
    /// guarded DRLS.
    pub type LevelTrend<const B: usize, const NL: usize = L> =
        super::Identifier<LevelTrendTime, Drls<NL>, 3, NL, B>;

    /// Default scaling of `[X, T]` for an E-Core-like static gyro over an 1800-s record
    /// (assumed, not measured: X in +-0.05 deg/s, T in 0..1800 s); `host-sim identify`
    /// replaces it with percentiles of the training records.
    pub const PAPER_SCALING: InputScaling<2> = InputScaling {
        offset: [0.0, 900.0],
        gain: [1.0 / 0.05, 1.0 / 900.0],
    };

    /// How long the level-trend preset holds its trend input, s ([`level_trend_features`]).
    pub const TREND_HOLD_S: f32 = 0.05;

    /// The level-trend preset's inputs for `samples_per_s` samples per second: the 10-s
    /// level every sample, the trend computed every [`TREND_HOLD_S`] (rounded to samples,
    /// at least 1) and held in between ([`LevelTrendTime::with_trend_every`]).
    pub fn level_trend_features(samples_per_s: f32) -> LevelTrendTime {
        LevelTrendTime::new(samples_per_s).with_trend_every(trend_hold_samples(samples_per_s))
    }

    /// [`TREND_HOLD_S`] in samples at `samples_per_s` (rounded, at least 1).
    pub fn trend_hold_samples(samples_per_s: f32) -> u32 {
        let m = libm::roundf(samples_per_s * TREND_HOLD_S);
        if (1.0..1.0e6).contains(&m) {
            m as u32
        } else {
            1
        }
    }

    /// Default scaling of `[level, trend, T]` (assumed: level +-0.02 deg/s, trend
    /// +-0.003 deg/s, T 0..1800 s).
    pub const LEVEL_TREND_SCALING: InputScaling<3> = InputScaling {
        offset: [0.0, 0.0, 900.0],
        gain: [1.0 / 0.02, 1.0 / 0.003, 1.0 / 900.0],
    };

    /// The paper's network: `NL/2` wavelet neurons along `X`, the rest along `T` (eq. 5 is a
    /// ridge function, so each neuron looks along one direction; the paper does not say
    /// which), centres evenly over the scaled range [-1, 1], neighbours one sigma apart.
    pub fn paper_shape<const NL: usize>(
        activation: Activation,
    ) -> Result<WnnShape<2, NL>, ShapeError> {
        WnnShape::from_groups(
            &[
                Group::Along {
                    input: 0,
                    count: NL / 2,
                    overlap: 1.0,
                },
                Group::Along {
                    input: 1,
                    count: NL - NL / 2,
                    overlap: 1.0,
                },
            ],
            activation,
        )
    }

    /// The improved network: bias, linear link to `level`, `(NL-2)/2` Gaussians along
    /// `trend`, the rest along `T`. Needs `NL >= 4`. Its two Gaussian groups are evaluated
    /// by the recurrence of [`WnnShape::with_recurrence`] (2 `expf` per group instead of one
    /// per neuron; accuracy documented there); the paper's network ([`paper_shape`]) keeps
    /// the direct evaluation of eq. (5).
    pub fn level_trend_shape<const NL: usize>() -> Result<WnnShape<3, NL>, ShapeError> {
        let k = NL.saturating_sub(2);
        WnnShape::from_groups(
            &[
                Group::Bias,
                Group::Linear(0),
                Group::Along {
                    input: 1,
                    count: k / 2,
                    overlap: 1.0,
                },
                Group::Along {
                    input: 2,
                    count: k - k / 2,
                    overlap: 1.0,
                },
            ],
            Activation::Gaussian,
        )
        .map(WnnShape::with_recurrence)
    }

    /// The paper's identifier with any trainer, zero initial weights.
    pub fn paper_with<T: Trainer<NL>, const B: usize, const NL: usize>(
        activation: Activation,
        scaling: InputScaling<2>,
        trainer: T,
        denoise: DenoiseConfig,
        sample_period_s: f32,
    ) -> Result<super::Identifier<RateTime, T, 2, NL, B>, IdentifyError> {
        let shape = paper_shape::<NL>(activation).map_err(IdentifyError::Shape)?;
        super::Identifier::new(
            RateTime,
            scaling,
            shape,
            [0.0; NL],
            trainer,
            denoise,
            sample_period_s,
        )
    }

    /// The paper's identifier with DRLS `trainer` (e.g. [`DrlsConfig::PAPER`]), zero initial
    /// weights, the paper's denoiser.
    pub fn paper<const B: usize>(
        activation: Activation,
        scaling: InputScaling<2>,
        trainer: DrlsConfig,
        sample_period_s: f32,
    ) -> Result<Paper<B>, IdentifyError> {
        let t = Drls::new(trainer).ok_or(IdentifyError::BadTrainer)?;
        paper_with(
            activation,
            scaling,
            t,
            DenoiseConfig::PAPER,
            sample_period_s,
        )
    }

    /// Trainer of the improved identifier: sequential DRLS, `U` in `(0, 1]`, lambda 0.99999
    /// (memory 10^5 samples, 1000 s at 100 Hz); [`level_trend_drls`] gives the bias neuron
    /// lambda 0.9999 (10^4 samples) and `U(0) = 1` so it follows the turn-on bias within a
    /// few blocks.
    pub const LEVEL_TREND_DRLS: DrlsConfig = DrlsConfig {
        lambda: 0.99999,
        u0: 1.0e-4,
        u_max: 1.0,
        w_max: 1.0e4,
        mode: DrlsMode::Sequential,
        form: DrlsForm::Energy,
    };

    /// The improved identifier's DRLS trainer for `NL` neurons.
    pub fn level_trend_drls<const NL: usize>() -> Option<Drls<NL>> {
        let mut t = Drls::new(LEVEL_TREND_DRLS)?;
        t.set_neuron(0, 0.9999, 1.0);
        Some(t)
    }

    /// Initial weights "from measured data" without a host: the output starts as the 10-s
    /// level itself (`w_link = 1/gain`, `w_bias = offset`), i.e. a 10-s moving average, and
    /// training moves it from there.
    pub fn level_identity_weights<const NL: usize>(scaling: &InputScaling<3>) -> [f32; NL] {
        let mut w0 = [0.0; NL];
        if NL >= 2 {
            w0[0] = scaling.offset[0];
            w0[1] = if scaling.gain[0] != 0.0 {
                1.0 / scaling.gain[0]
            } else {
                1.0
            };
        }
        w0
    }

    /// The improved identifier with any trainer.
    pub fn level_trend_with<T: Trainer<NL>, const B: usize, const NL: usize>(
        scaling: InputScaling<3>,
        trainer: T,
        denoise: DenoiseConfig,
        sample_period_s: f32,
    ) -> Result<super::Identifier<LevelTrendTime, T, 3, NL, B>, IdentifyError> {
        let shape = level_trend_shape::<NL>().map_err(IdentifyError::Shape)?;
        let w0 = level_identity_weights::<NL>(&scaling);
        let f = level_trend_features(1.0 / sample_period_s);
        super::Identifier::new(f, scaling, shape, w0, trainer, denoise, sample_period_s)
            .map(super::Identifier::with_block_time)
    }

    /// The drift model on known inputs: inputs `[T, temp_c, dtemp_c_per_s]`
    /// ([`TimeTemp`]), a per-power-on bias and warm-up neuron, shared links and Gaussians,
    /// sequential DRLS (see [`time_temp_shape`]).
    pub type TimeTempNet<const B: usize, const NL: usize = L> =
        super::Identifier<TimeTemp, Drls<NL>, 3, NL, B>;

    /// Default scaling of `[T, temp_c, dtemp_c_per_s]` (assumed: T 0..1800 s, temperature
    /// 15..35 C, rate +-0.005 C/s); `host-sim identify` replaces it with percentiles of the
    /// training records.
    pub const TIME_TEMP_SCALING: InputScaling<3> = InputScaling {
        offset: [900.0, 25.0, 0.0],
        gain: [1.0 / 900.0, 1.0 / 10.0, 1.0 / 0.005],
    };

    /// Index of the per-power-on bias neuron of [`time_temp_shape`].
    pub const TT_BIAS: usize = 0;
    /// Index of the per-power-on warm-up neuron of [`time_temp_shape`].
    pub const TT_WARMUP: usize = 1;
    /// Width of the warm-up neuron in units of the scaled `T` range: a Gaussian centred at
    /// switch-on (scaled `T` = -1) with sigma = 2/3 of the half range (600 s for records
    /// scaled over 0..1800 s).
    pub const TT_WARMUP_DILATION: f32 = 1.5;

    /// The network of the drift model on known inputs, for `NL >= 8` neurons:
    /// - neuron 0: bias, **per power-on** (restarted at each record: the turn-on bias and
    ///   the slow bias instability, an exponentially weighted mean of the targets);
    /// - neuron 1: a Gaussian on `T` centred at switch-on, **per power-on** (restarted at 0
    ///   at each record: this record's deviation of the warm-up from the learned shape);
    /// - neurons 2, 3: linear links to `temp_c` and `dtemp_c_per_s` (temperature
    ///   sensitivity, Shupe effect), **shared** by all records;
    /// - the rest, shared: 3/4 Gaussians along `T` (the warm-up shape as a function of time
    ///   since switch-on), 1/4 along `temp_c` (a non-linear temperature sensitivity);
    ///   centres evenly on [-1, 1], neighbours one sigma apart.
    pub fn time_temp_shape<const NL: usize>() -> Result<WnnShape<3, NL>, ShapeError> {
        let k = NL.saturating_sub(4);
        let k_temp = k / 4;
        let mut s = WnnShape::from_groups(
            &[
                Group::Bias,
                Group::Along {
                    input: 0,
                    count: 1,
                    overlap: TT_WARMUP_DILATION,
                },
                Group::Linear(1),
                Group::Linear(2),
                Group::Along {
                    input: 0,
                    count: k - k_temp,
                    overlap: 1.0,
                },
                Group::Along {
                    input: 1,
                    count: k_temp,
                    overlap: 1.0,
                },
            ],
            Activation::Gaussian,
        )?;
        // The warm-up neuron sits at scaled T = -1 (switch-on): b = a * c with c = -1.
        if let Some(b) = s.b.get_mut(TT_WARMUP) {
            *b = -TT_WARMUP_DILATION;
        }
        Ok(s)
    }

    /// Trainer of the drift model on known inputs: sequential DRLS, lambda 1 for the shared
    /// neurons (their weights are averages over every record seen), `U(0)` 1e-4, guard
    /// `U <= 1`, `|w| <= 1e4`. The per-power-on neurons get their own settings at each
    /// record start from [`time_temp_power_on`].
    pub const TIME_TEMP_DRLS: DrlsConfig = DrlsConfig {
        lambda: 1.0,
        u0: 1.0e-4,
        u_max: 1.0,
        w_max: 1.0e4,
        mode: DrlsMode::Sequential,
        form: DrlsForm::Gain,
    };

    /// Default memory of the per-power-on bias neuron, s (after its growing-window start).
    pub const TT_BIAS_MEMORY_S: f32 = 600.0;
    /// `U(0)` of the per-power-on warm-up neuron: its prior variance over the targets' noise
    /// variance, in scaled units (about (2 deg/h / 60 deg/h)^2).
    pub const TT_WARMUP_U0: f32 = 1.0e-3;

    /// What a power-on does to the drift model on known inputs: the bias neuron restarts as
    /// a growing-window mean (`U = 1`) that turns into an exponential one with memory
    /// `bias_memory_s` (lambda = `1 - dt/memory`), the warm-up neuron restarts at weight 0
    /// with `U = warmup_u0`; the shared neurons keep their weights and `U`.
    pub fn time_temp_power_on<const NL: usize>(
        w: &mut [f32; NL],
        trainer: &mut Drls<NL>,
        sample_period_s: f32,
        bias_memory_s: f32,
        warmup_u0: f32,
    ) {
        let lambda_b = if bias_memory_s > sample_period_s && bias_memory_s.is_finite() {
            1.0 - sample_period_s / bias_memory_s
        } else {
            1.0
        };
        trainer.set_neuron(TT_BIAS, lambda_b, 1.0);
        trainer.set_neuron(TT_WARMUP, 1.0, warmup_u0);
        if let Some(v) = w.get_mut(TT_WARMUP) {
            *v = 0.0;
        }
    }

    /// The drift model on known inputs with any trainer, zero initial weights.
    pub fn time_temp_with<T: Trainer<NL>, const B: usize, const NL: usize>(
        scaling: InputScaling<3>,
        trainer: T,
        denoise: DenoiseConfig,
        sample_period_s: f32,
    ) -> Result<super::Identifier<TimeTemp, T, 3, NL, B>, IdentifyError> {
        let shape = time_temp_shape::<NL>().map_err(IdentifyError::Shape)?;
        let f = TimeTemp::new(1.0 / sample_period_s);
        super::Identifier::new(
            f,
            scaling,
            shape,
            [0.0; NL],
            trainer,
            denoise,
            sample_period_s,
        )
    }

    /// The drift model on known inputs as configured by default (30 neurons, its DRLS, the
    /// first power-on applied).
    pub fn time_temp<const B: usize>(
        scaling: InputScaling<3>,
        sample_period_s: f32,
    ) -> Result<TimeTempNet<B>, IdentifyError> {
        let t = Drls::new(TIME_TEMP_DRLS).ok_or(IdentifyError::BadTrainer)?;
        let mut id = time_temp_with(scaling, t, DenoiseConfig::PAPER, sample_period_s)?;
        let mut w = *id.weights();
        time_temp_power_on(
            &mut w,
            id.trainer_mut(),
            sample_period_s,
            TT_BIAS_MEMORY_S,
            TT_WARMUP_U0,
        );
        id.set_weights(w);
        Ok(id)
    }

    /// The multi-scale identifier: inputs of [`MultiScaleLevels`] (levels at 3..1000 s and
    /// known inputs), see [`level_bank_shape`].
    pub type LevelBankNet<const B: usize, const NL: usize = L> =
        super::Identifier<MultiScaleLevels, Drls<NL>, BANK_INPUTS, NL, B>;

    /// Index of the `K_1000` link of [`level_bank_shape`] (kept at the identity).
    pub const LB_LEVEL: usize = 0;
    /// First neuron of [`level_bank_shape`] on the known inputs (T, temperature, its
    /// rate): the links at 7, 8, then the Gaussians.
    pub const LB_KNOWN: usize = 7;

    /// The multi-scale network, `NL >= 12`: neuron 0 a linear link to the 1000-s level
    /// (the identity: kept, not trained), 1 a bias, 2..=6 linear links to the five level
    /// differences, 7, 8 linear links to `temp_c` and `dtemp_c_per_s`; the rest Gaussians,
    /// 2/3 along `T` (the average warm-up shape the levels lag behind), 1/3 along `temp_c`.
    pub fn level_bank_shape<const NL: usize>() -> Result<WnnShape<BANK_INPUTS, NL>, ShapeError> {
        let k = NL.saturating_sub(9);
        let k_temp = k / 3;
        WnnShape::from_groups(
            &[
                Group::Linear(0),
                Group::Bias,
                Group::Linear(1),
                Group::Linear(2),
                Group::Linear(3),
                Group::Linear(4),
                Group::Linear(5),
                Group::Linear(BANK_T + 1),
                Group::Linear(BANK_T + 2),
                Group::Along {
                    input: BANK_T,
                    count: k - k_temp,
                    overlap: 1.0,
                },
                Group::Along {
                    input: BANK_T + 1,
                    count: k_temp,
                    overlap: 1.0,
                },
            ],
            Activation::Gaussian,
        )
    }

    /// Initial weights "from measured data": the output starts as the level of memory
    /// `BANK_MEMORIES_S[from]` (identity on `K_1000` and on every difference from `from`
    /// up, the offsets into the bias), i.e. as a random-walk Kalman filter of that memory.
    pub fn level_bank_identity_weights<const NL: usize>(
        scaling: &InputScaling<BANK_INPUTS>,
        from: usize,
    ) -> [f32; NL] {
        let mut w0 = [0.0; NL];
        let inv = |g: f32| if g != 0.0 { 1.0 / g } else { 1.0 };
        if NL >= 7 {
            w0[LB_LEVEL] = inv(scaling.gain[0]);
            w0[1] = scaling.offset[0];
            for i in from..BANK_MEMORIES_S.len() - 1 {
                w0[2 + i] = inv(scaling.gain[1 + i]);
                w0[1] += scaling.offset[1 + i];
            }
        }
        w0
    }

    /// The multi-scale identifier with any trainer, starting as the level of memory
    /// `BANK_MEMORIES_S[from]`.
    pub fn level_bank_with<T: Trainer<NL>, const B: usize, const NL: usize>(
        scaling: InputScaling<BANK_INPUTS>,
        trainer: T,
        denoise: DenoiseConfig,
        sample_period_s: f32,
        from: usize,
    ) -> Result<super::Identifier<MultiScaleLevels, T, BANK_INPUTS, NL, B>, IdentifyError> {
        let shape = level_bank_shape::<NL>().map_err(IdentifyError::Shape)?;
        let w0 = level_bank_identity_weights::<NL>(&scaling, from);
        let f = MultiScaleLevels::new(1.0 / sample_period_s);
        super::Identifier::new(f, scaling, shape, w0, trainer, denoise, sample_period_s)
    }

    /// The improved identifier as configured by default (30 neurons, its DRLS).
    pub fn level_trend<const B: usize>(
        scaling: InputScaling<3>,
        sample_period_s: f32,
    ) -> Result<LevelTrend<B>, IdentifyError> {
        let t = level_trend_drls::<L>().ok_or(IdentifyError::BadTrainer)?;
        level_trend_with(scaling, t, DenoiseConfig::PAPER, sample_period_s)
    }
}
