//! `host-sim identify`: trains the on-line identifier on training records and scores it,
//! still running on line, on validation records, beside causal baselines.
//!
//! # Protocol (assumptions named)
//! - Training: the records are fed in order through one identifier; the weights and the
//!   trainer's state carry from record to record; at each record start the identifier is
//!   restarted (time 0, empty denoiser and input ring), as at a power-on.
//! - Validation: the identifier goes on from where training left it, on line, record after
//!   record, restarted at each record start. `y(k)` is its output for sample `k` before
//!   it trained on `k` (it trains on `k` at sample `k + B`).
//! - `d` is the denoised measurement: the record denoised in blocks of `B` from its start
//!   (the identifier's own blocks), the tail by the tail rule of `host-sim denoise`.
//! - Every estimator is scored on the same samples: from sample `2B` of each validation
//!   record on (before, the identifier has had no target of that record).
//! - Baselines, all causal with zero output latency (they output at `k` from samples up to
//!   `k`, like the identifier): moving average of the raw rate (10 s, and the window best on
//!   the training records), random-walk Kalman filter (q/r best on the training records),
//!   and a moving average of the denoised target over one block as the identifier sees it,
//!   `B` samples late (the identifier's own information latency).
//! - Input scaling "from measured data": each network input's 1st and 99th percentiles over
//!   the training records map to -1 and 1 (every 10th sample is kept for the percentiles).

pub mod metrics;
pub mod repro;
pub mod series;
pub mod thermal;

use crate::denoise_cmd;
use anyhow::{anyhow, bail, Result};
use fog_core::baseline::RandomWalkKalman;
use fog_core::denoise::DenoiseConfig;
use fog_core::features::{FeatureMap, LevelTrendTime, MultiScaleLevels, RateTime, TimeTemp};
use fog_core::identify::{presets, Identifier};
use fog_core::train::{
    Drls, DrlsConfig, DrlsForm, DrlsMode, Nlms, NlmsConfig, Rls, RlsConfig, Trainer,
};
use fog_core::wnn::{Activation, InputScaling};
use metrics::{ErrorAcc, Figures};
use serde::Serialize;
use series::{Records, Series};
use std::collections::VecDeque;
use std::time::Instant;

/// Network layout and inputs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// The paper: inputs X and T, wavelet neurons, no bias.
    Paper,
    /// Inputs 10-s level, trend, T; bias + linear link + Gaussians.
    LevelTrend,
    /// Inputs T, temperature, temperature rate (known inputs, none from the gyro): a
    /// per-power-on bias and warm-up neuron, shared links and Gaussians (needs `temp_c`).
    TimeTemp,
    /// Levels of the rate at 3..1000 s (as differences) and T, temperature, its rate: a
    /// learned mixture of causal filters plus what known inputs predict.
    LevelBank,
    /// Motion-safe: drift = clamp(level + m(t, temp, dtemp/dt)), the level a stillness-gated
    /// random-walk Kalman filter, `m` trained across static records (`--save-identifier`;
    /// [`crate::motion`]).
    Motion,
}

/// Output-weight trainer.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum TrainerKind {
    /// DRLS, eq. (15) as written (one a-priori error for all weights).
    DrlsParallel,
    /// DRLS with the error refreshed after each weight.
    DrlsSequential,
    /// Full exponentially weighted RLS, O(L^2).
    Rls,
    /// Normalised LMS.
    Nlms,
}

/// DRLS gain recursion (`fog_core::train::DrlsForm`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum DrlsFormArg {
    /// Eq. (15): `U` kept.
    Gain,
    /// Eqs. (10)-(11): the energy `S = 1/U` kept (the level-trend preset's, as the firmware).
    Energy,
}

/// Wavelet neuron.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Act {
    /// exp(-t^2/2).
    Gaussian,
    /// (1 - t^2) exp(-t^2/2).
    MexicanHat,
}

/// Everything that defines one identification run.
#[derive(Clone, Debug, Serialize)]
pub struct Options {
    /// Layout and inputs.
    pub preset: Preset,
    /// Trainer.
    pub trainer: TrainerKind,
    /// Hidden neurons (10, 20, 30, 40 or 60).
    pub hidden: usize,
    /// Forgetting factor.
    pub lambda: f32,
    /// DRLS guard: `U <= u_max`, `|w| <= w_max` (off = eq. 15 exactly).
    pub guard: bool,
    /// DRLS gain recursion.
    pub drls_form: DrlsFormArg,
    /// `U(0)` of DRLS (bias neuron of level-trend excepted: 1).
    pub u0: f32,
    /// Denoising levels.
    pub levels: u32,
    /// Denoising block (256, 512 or 1024).
    pub block: usize,
    /// Wavelet neuron (the level-trend preset uses Gaussians).
    pub activation: Act,
    /// Scale inputs by the training records' percentiles (else the presets' defaults).
    pub scale_from_training: bool,
    /// Level input of the level-trend preset.
    pub level: LevelInput,
    /// time-temp preset: memory of the per-power-on bias neuron, s.
    pub bias_memory_s: f32,
    /// time-temp preset: `U(0)` of the per-power-on warm-up neuron.
    pub warmup_u0: f32,
    /// level-bank preset: index of the level (memory 3, 10, 30, 100, 300, 1000 s) the
    /// network starts as.
    pub bank_from: usize,
    /// level-bank preset: train the neurons on T, temperature and its rate (false: they
    /// stay at 0, the network is a learned mixture of levels only).
    pub known_inputs: bool,
    /// level-bank preset: output from undelayed levels (training inputs stay delayed).
    pub undelayed_output: bool,
}

/// Where the level-trend preset's level input comes from.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
#[serde(rename_all = "kebab-case")]
pub enum LevelInput {
    /// Mean of the last 10 s (bias and link neurons trained).
    Mean10s,
    /// Random-walk Kalman estimate with this q/r per sample; bias and link neurons frozen at
    /// the identity, so the network is this filter plus what its wavelet neurons learn.
    Kalman {
        /// Process-to-measurement noise variance ratio per sample.
        q_over_r: f32,
    },
    /// As `Kalman`, with q/r chosen on the training records exactly as the Kalman baseline's.
    KalmanTuned,
}

impl Options {
    /// The paper's configuration exactly.
    pub fn paper() -> Self {
        Self {
            preset: Preset::Paper,
            trainer: TrainerKind::DrlsParallel,
            hidden: 30,
            lambda: 0.63,
            guard: false,
            drls_form: DrlsFormArg::Gain,
            u0: 1.0,
            levels: 3,
            block: 512,
            activation: Act::MexicanHat,
            scale_from_training: true,
            level: LevelInput::Mean10s,
            bias_memory_s: presets::TT_BIAS_MEMORY_S,
            warmup_u0: presets::TT_WARMUP_U0,
            bank_from: 2,
            known_inputs: true,
            undelayed_output: false,
        }
    }

    /// The drift model on known inputs (T, temperature, its rate).
    pub fn time_temp() -> Self {
        Self {
            preset: Preset::TimeTemp,
            lambda: presets::TIME_TEMP_DRLS.lambda,
            u0: presets::TIME_TEMP_DRLS.u0,
            drls_form: DrlsFormArg::Gain,
            ..Self::level_trend()
        }
    }

    /// The multi-scale configuration (levels at 3..1000 s, T, temperature, its rate).
    pub fn level_bank() -> Self {
        Self {
            preset: Preset::LevelBank,
            lambda: 1.0,
            u0: 1.0e-4,
            drls_form: DrlsFormArg::Gain,
            ..Self::level_trend()
        }
    }

    /// The improved configuration.
    pub fn level_trend() -> Self {
        Self {
            preset: Preset::LevelTrend,
            trainer: TrainerKind::DrlsSequential,
            hidden: 30,
            lambda: presets::LEVEL_TREND_DRLS.lambda,
            guard: true,
            drls_form: DrlsFormArg::Energy,
            u0: presets::LEVEL_TREND_DRLS.u0,
            levels: 3,
            block: 512,
            activation: Act::Gaussian,
            scale_from_training: true,
            level: LevelInput::Mean10s,
            bias_memory_s: presets::TT_BIAS_MEMORY_S,
            warmup_u0: presets::TT_WARMUP_U0,
            bank_from: 2,
            known_inputs: true,
            undelayed_output: false,
        }
    }
}

/// Figures of a baseline, with its tuned parameter.
#[derive(Debug, Clone, Serialize)]
pub struct Baseline {
    /// What it is.
    pub name: &'static str,
    /// Its parameter (window in s, or q/r), tuned on the training records where stated.
    pub parameter: f64,
    /// Error figures on the validation samples.
    #[serde(flatten)]
    pub figures: Figures,
}

/// The JSON report of `host-sim identify`.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The configuration.
    pub config: Options,
    /// RMS(y - d)/RMS(d).
    pub e_rel: Option<f64>,
    /// RMS(y - d)/(max d - min d).
    pub e_range: Option<f64>,
    /// max |y - d|/(max d - min d).
    pub e_max: Option<f64>,
    /// RMS(y - drift)/RMS(drift).
    pub e_truth: Option<f64>,
    /// RMS(y - drift) in deg/h.
    pub rms_err_truth_dph: Option<f64>,
    /// All figures of the identifier.
    pub identifier: Figures,
    /// The baselines.
    pub baselines: Vec<Baseline>,
    /// Identifier samples per second on this host (training and validation, one core).
    pub samples_per_s: f64,
    /// Training samples until the RMS a-priori training error over one block fell to
    /// `goal` times the RMS of that block's targets; null if it never did.
    pub samples_to_goal: Option<u64>,
    /// The same with an absolute goal of 0.001 deg/s (3.6 deg/h).
    pub samples_to_goal_abs: Option<u64>,
    /// The paper's training error goal.
    pub goal: f64,
    /// Training records and samples.
    pub train_records: usize,
    /// Training samples.
    pub train_samples: u64,
    /// Validation records.
    pub validate_records: usize,
    /// Validation samples scored.
    pub scored_samples: u64,
    /// Validation samples at which the identifier's output was first not finite, if ever.
    pub diverged_at_sample: Option<u64>,
    /// The output weights at the end of the validation records (network units).
    pub final_weights: Vec<f32>,
    /// Records with a temperature channel: the share of the drift explained by known
    /// inputs (batch least squares, against the truth; simulated records only).
    pub drift_decomposition: Option<thermal::DriftDecomposition>,
    /// Records with a temperature channel: the regressions of the rate on known inputs
    /// behind the temperature-aware baselines.
    pub temperature_regressions: Vec<thermal::RateRegression>,
    /// Definitions of the figures, in words.
    pub definitions: &'static str,
}

impl Report {
    /// The line `identify` (network presets) and `reproduce` print after the report: the
    /// identifier's figures over every validation sample (the JSON's `e_rel`, `e_truth`,
    /// `rms_err_truth_dph`), the records, and on e_truth the verdict against the best
    /// baseline (the least `e_truth` of `baselines`): `fog wins` / `fog loses` / `fog ties`
    /// ([`crate::replay::pooled`]'s words), the difference in %, the baseline's name.
    pub fn headline(&self) -> String {
        use crate::replay::pooled::{pct, verdict};
        let f = |v: Option<f64>| v.map_or("null".to_string(), |x| format!("{x:.4}"));
        let best = self
            .baselines
            .iter()
            .filter_map(|b| b.figures.e_truth.map(|e| (e, b.name)))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let verdict = match (self.e_truth, best) {
            (Some(id), Some((e, name))) => format!(
                "{}: e_truth {id:.4} against {e:.4} for the best baseline ({:+.1} %), {name}",
                verdict(id, e),
                pct(id, e)
            ),
            (None, _) => {
                "no verdict: the identifier's e_truth is null (no truth, or it diverged)".into()
            }
            (Some(_), None) => "no verdict: no baseline has an e_truth".into(),
        };
        format!(
            "{verdict}; e_rel {} e_truth {} rms_err_truth {} deg/h over {} training / {} validation records",
            f(self.e_rel),
            f(self.e_truth),
            f(self.rms_err_truth_dph),
            self.train_records,
            self.validate_records,
        )
    }
}

const DEFINITIONS: &str = "y = identifier output for a sample before it trained on that sample; d = the record denoised in blocks of B from its start (db4, soft universal threshold); drift = the simulator's true drift_dps; scored from sample 2B of every validation record, the same samples for every estimator; e_rel = RMS(y-d)/RMS(d) (RMS(d) includes any constant bias, so e_rel falls as the bias grows); e_range = RMS(y-d)/(max d - min d); e_max = max|y-d|/(max d - min d); e_truth = RMS(y-drift)/RMS(drift); figures are null when an estimate was NaN or infinite (divergence).";

/// Causal moving average of the last `w` samples (host-side baseline).
struct MovingAverage {
    w: usize,
    buf: VecDeque<f64>,
    sum: f64,
}

impl MovingAverage {
    fn new(w: usize) -> Self {
        Self {
            w: w.max(1),
            buf: VecDeque::new(),
            sum: 0.0,
        }
    }
    fn push(&mut self, x: f64) -> f64 {
        self.buf.push_back(x);
        self.sum += x;
        if self.buf.len() > self.w {
            self.sum -= self.buf.pop_front().unwrap_or(0.0);
        }
        self.sum / self.buf.len() as f64
    }
}

const MA_WINDOWS_S: [f64; 8] = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0];
const KALMAN_Q_OVER_R: [f64; 11] = [
    1e-9, 3e-9, 1e-8, 3e-8, 1e-7, 3e-7, 1e-6, 3e-6, 1e-5, 3e-5, 1e-4,
];
/// Training records used to tune the baselines (enough for a stable choice).
const TUNE_RECORDS: usize = 20;

fn denoised(s: &Series, block: usize, levels: u32) -> Result<Vec<f32>> {
    let plan = denoise_cmd::plan(s.rate_dps.len(), Some(block), levels)?;
    let cfg = DenoiseConfig {
        levels,
        ..DenoiseConfig::PAPER
    };
    denoise_cmd::denoise_blocks(&s.rate_dps, &plan, &cfg)
        .map(|(d, _)| d)
        .map_err(|(i, e)| anyhow!("{}: sample {i}: {e}", s.name))
}

/// The sample's temperature, deg C, or NaN when the record has none.
fn temp_at(s: &Series, k: usize) -> f32 {
    s.temp_c
        .as_ref()
        .and_then(|t| t.get(k).copied())
        .unwrap_or(f32::NAN)
}

/// 1st/99th percentile scaling of the feature map's outputs over the training records.
fn training_scaling<F: FeatureMap<N>, const N: usize>(
    train: &dyn Records,
    make: &dyn Fn(f32) -> F,
) -> Result<InputScaling<N>> {
    let mut vals: [Vec<f32>; N] = std::array::from_fn(|_| Vec::new());
    for i in 0..train.len() {
        let s = train.get(i)?;
        let dt = s.sample_period_s() as f32;
        let mut f = make(dt);
        for (k, &x) in s.rate_dps.iter().enumerate() {
            let v = f.next_with_temp(x, k as f32 * dt, temp_at(&s, k));
            if k % 10 == 0 {
                for j in 0..N {
                    vals[j].push(v[j]);
                }
            }
        }
    }
    let mut lo = [0.0; N];
    let mut hi = [0.0; N];
    for j in 0..N {
        let v = &mut vals[j];
        if v.is_empty() {
            bail!("no training samples");
        }
        v.sort_by(f32::total_cmp);
        lo[j] = v[v.len() / 100];
        hi[j] = v[(v.len() * 99 / 100).min(v.len() - 1)];
    }
    Ok(InputScaling::from_ranges(lo, hi))
}

/// Runs one configuration. `make_features(dt)` builds the feature map for a record of
/// sample period `dt`; `make_id(scaling, dt)` the identifier.
fn run_generic<F, T, const N: usize, const L: usize, const B: usize>(
    opts: &Options,
    train: &dyn Records,
    validate: &dyn Records,
    default_scaling: InputScaling<N>,
    make_features: &dyn Fn(f32) -> F,
    make_id: &dyn Fn(
        InputScaling<N>,
        f32,
    ) -> Result<Identifier<F, T, N, L, B>, fog_core::identify::IdentifyError>,
    power_on: &dyn Fn(&mut Identifier<F, T, N, L, B>, f32),
) -> Result<Report>
where
    F: FeatureMap<N>,
    T: Trainer<L>,
{
    let scaling = if opts.scale_from_training {
        training_scaling::<F, N>(train, make_features)?
    } else {
        default_scaling
    };
    let first_dt = train.get(0)?.sample_period_s() as f32;
    let mut run = OnLineRun {
        id: make_id(scaling, first_dt).map_err(|e| anyhow!("{e}"))?,
        make_features,
        power_on,
        busy_s: 0.0,
        pushed: 0,
    };
    let training = run.train(train, opts.levels)?;
    let best_ma_s = MA_WINDOWS_S[index_of_least(&training.ma_sq)];
    let best_q = tune_kalman(train, B, opts.levels)?;
    let temp = TempBaselines::new(train, validate, B, opts.levels)?;
    let mut scores = Scores::new(best_ma_s, best_q, temp.as_ref().map_or(0, |t| t.regs.len()));
    run.validate(validate, opts.levels, temp.as_ref(), &mut scores)?;
    let fig = scores.id.figures();
    let (baselines, decomposition, regressions) = scores.baselines(B, temp);
    Ok(Report {
        config: opts.clone(),
        e_rel: fig.e_rel,
        e_range: fig.e_range,
        e_max: fig.e_max,
        e_truth: fig.e_truth,
        rms_err_truth_dph: fig.rms_err_truth_dph,
        identifier: fig,
        baselines,
        samples_per_s: run.pushed as f64 / run.busy_s.max(1e-9),
        samples_to_goal: training.convergence.goal_at,
        samples_to_goal_abs: training.convergence.goal_abs_at,
        goal: 0.001,
        train_records: train.len(),
        train_samples: training.samples,
        validate_records: validate.len(),
        scored_samples: scores.scored,
        diverged_at_sample: scores.diverged_at,
        final_weights: run.id.weights().to_vec(),
        drift_decomposition: decomposition,
        temperature_regressions: regressions,
        definitions: DEFINITIONS,
    })
}

/// Index of the least value (the first of equal ones; 0 when `v` is empty).
fn index_of_least(v: &[f64]) -> usize {
    v.iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i)
}

/// The identifier under test, run on line over records, and the time it took.
struct OnLineRun<'a, F, T, const N: usize, const L: usize, const B: usize> {
    /// The identifier; its weights and trainer state carry from record to record.
    id: Identifier<F, T, N, L, B>,
    /// The feature map for a record of sample period `dt`, s.
    make_features: &'a dyn Fn(f32) -> F,
    /// What the preset does to the identifier at a power-on (sample period `dt`, s).
    power_on: &'a dyn Fn(&mut Identifier<F, T, N, L, B>, f32),
    /// Wall time spent pushing samples through the identifier, s.
    busy_s: f64,
    /// Samples pushed through the identifier.
    pushed: u64,
}

/// What training leaves for the report and the baselines.
struct Training {
    /// Training samples.
    samples: u64,
    /// When the training error reached the goals.
    convergence: Convergence,
    /// Squared error, (deg/s)^2, of each moving average of [`MA_WINDOWS_S`], summed over the
    /// first [`TUNE_RECORDS`] training records from sample `2B` of each.
    ma_sq: [f64; MA_WINDOWS_S.len()],
}

impl<F, T, const N: usize, const L: usize, const B: usize> OnLineRun<'_, F, T, N, L, B>
where
    F: FeatureMap<N>,
    T: Trainer<L>,
{
    /// Restarts the identifier for record `s`, as at a power-on.
    fn restart(&mut self, s: &Series) -> Result<()> {
        let dt = s.sample_period_s() as f32;
        self.id
            .restart((self.make_features)(dt), dt)
            .map_err(|e| anyhow!("{}: {e}", s.name))?;
        (self.power_on)(&mut self.id, dt);
        Ok(())
    }

    /// Pushes every sample of `s` through the identifier (timed); returns `pick` of each
    /// sample's estimate.
    fn push_record(
        &mut self,
        s: &Series,
        pick: impl Fn(&fog_core::identify::Estimate) -> f32,
    ) -> Result<Vec<f32>> {
        let t0 = Instant::now();
        let mut out = Vec::with_capacity(s.rate_dps.len());
        for (k, &x) in s.rate_dps.iter().enumerate() {
            let e = self
                .id
                .push_with_temp(x, temp_at(s, k))
                .map_err(|e| anyhow!("{}: {e}", s.name))?;
            out.push(pick(&e));
        }
        self.busy_s += t0.elapsed().as_secs_f64();
        self.pushed += s.rate_dps.len() as u64;
        Ok(out)
    }

    /// Trains on the records in order, restarted at each record start (targets denoised
    /// `levels` deep), measuring convergence and the moving-average baselines on the way.
    fn train(&mut self, train: &dyn Records, levels: u32) -> Result<Training> {
        let mut training = Training {
            samples: 0,
            convergence: Convergence::default(),
            ma_sq: [0.0; MA_WINDOWS_S.len()],
        };
        for i in 0..train.len() {
            let s = train.get(i)?;
            self.restart(&s)?;
            let train_err = self.push_record(&s, |e| e.train_error_dps)?;
            let d = denoised(&s, B, levels)?;
            training
                .convergence
                .add_record(&train_err, &d, B, training.samples);
            if i < TUNE_RECORDS {
                add_moving_average_sq_errors(&mut training.ma_sq, &s, &d, B);
            }
            training.samples += s.rate_dps.len() as u64;
        }
        Ok(training)
    }

    /// Runs on over the validation records, still on line, restarted at each record start
    /// (targets denoised `levels` deep), scoring the identifier and the baselines into
    /// `scores`.
    fn validate(
        &mut self,
        validate: &dyn Records,
        levels: u32,
        temp: Option<&TempBaselines>,
        scores: &mut Scores,
    ) -> Result<()> {
        let mut first_sample = 0u64;
        for i in 0..validate.len() {
            let s = validate.get(i)?;
            self.restart(&s)?;
            let d = denoised(&s, B, levels)?;
            let temp_ys = temp.map(|t| t.track(&s)).transpose()?;
            let ys = self.push_record(&s, |e| e.drift_dps)?;
            scores.add_record(&s, &d, &ys, temp_ys.as_deref(), B, first_sample);
            first_sample += s.rate_dps.len() as u64;
        }
        Ok(())
    }
}

/// Convergence: RMS of the a-priori training error per block of `B` training steps (the
/// error at sample `k` is for target `d(k - B)`), blocks running on across records.
#[derive(Default)]
struct Convergence {
    /// Sum of squared errors of the block so far, deg^2/s^2.
    e2: f64,
    /// Sum of squared targets of the block so far, deg^2/s^2.
    d2: f64,
    /// Errors in the block so far.
    n: usize,
    /// Training samples until the block RMS error fell to 0.001 times the block RMS target.
    goal_at: Option<u64>,
    /// Training samples until the block RMS error fell to 0.001 deg/s.
    goal_abs_at: Option<u64>,
}

impl Convergence {
    /// Adds one record's training errors `train_err` (deg/s) against its denoised targets
    /// `d` (deg/s); `samples_before` training samples preceded the record.
    fn add_record(&mut self, train_err: &[f32], d: &[f32], block: usize, samples_before: u64) {
        for (k, e) in train_err.iter().enumerate() {
            if !e.is_finite() || k < block {
                continue;
            }
            self.e2 += f64::from(*e).powi(2);
            self.d2 += f64::from(d[k - block]).powi(2);
            self.n += 1;
            if self.n == block {
                let rms_e = (self.e2 / block as f64).sqrt();
                let rms_d = (self.d2 / block as f64).sqrt();
                let at = samples_before + k as u64 + 1;
                if self.goal_at.is_none() && rms_e <= 0.001 * rms_d {
                    self.goal_at = Some(at);
                }
                if self.goal_abs_at.is_none() && rms_e <= 0.001 {
                    self.goal_abs_at = Some(at);
                }
                (self.e2, self.d2, self.n) = (0.0, 0.0, 0);
            }
        }
    }
}

/// Adds to `ma_sq[i]` the squared error, deg^2/s^2, of a moving average of the raw rate over
/// `MA_WINDOWS_S[i]` seconds on record `s`, from sample `2 * block` on, against the truth
/// (or, without one, the denoised record `d`).
fn add_moving_average_sq_errors(
    ma_sq: &mut [f64; MA_WINDOWS_S.len()],
    s: &Series,
    d: &[f32],
    block: usize,
) {
    let dt = s.sample_period_s() as f32;
    let reference: Vec<f64> = match &s.drift_dps {
        Some(t) => t.iter().map(|&v| f64::from(v)).collect(),
        None => d.iter().map(|&v| f64::from(v)).collect(),
    };
    for (wi, w_s) in MA_WINDOWS_S.iter().enumerate() {
        let mut ma = MovingAverage::new((w_s / f64::from(dt)).round() as usize);
        for (k, &x) in s.rate_dps.iter().enumerate() {
            let y = ma.push(f64::from(x));
            if k >= 2 * block {
                ma_sq[wi] += (y - reference[k]).powi(2);
            }
        }
    }
}

/// Errors of the identifier and of every causal baseline on the validation samples.
struct Scores {
    /// Window of the best moving average on the training records, s.
    best_ma_s: f64,
    /// q/r of the best random-walk Kalman filter on the training records.
    best_q: f64,
    /// The identifier.
    id: ErrorAcc,
    /// Moving average of the raw rate over 10 s.
    ma10: ErrorAcc,
    /// Moving average of the raw rate over `best_ma_s`.
    ma_best: ErrorAcc,
    /// Random-walk Kalman filter with q/r `best_q`.
    kf: ErrorAcc,
    /// Moving average of the target over one block, one block late.
    lag: ErrorAcc,
    /// One per temperature-aware baseline ([`TempBaselines::regs`]).
    temp: Vec<ErrorAcc>,
    /// Validation sample at which the identifier's output was first not finite, if ever.
    diverged_at: Option<u64>,
    /// Samples scored.
    scored: u64,
}

impl Scores {
    fn new(best_ma_s: f64, best_q: f64, temp_baselines: usize) -> Self {
        Self {
            best_ma_s,
            best_q,
            id: ErrorAcc::default(),
            ma10: ErrorAcc::default(),
            ma_best: ErrorAcc::default(),
            kf: ErrorAcc::default(),
            lag: ErrorAcc::default(),
            temp: vec![ErrorAcc::default(); temp_baselines],
            diverged_at: None,
            scored: 0,
        }
    }

    /// Scores record `s` from sample `2 * block` on: the identifier's outputs `ys`, the
    /// baselines run here and the temperature-aware ones' `temp_ys`, all deg/s, against the
    /// denoised record `d`; `first_sample` is the record's first validation sample.
    fn add_record(
        &mut self,
        s: &Series,
        d: &[f32],
        ys: &[f32],
        temp_ys: Option<&[Vec<f64>]>,
        block: usize,
        first_sample: u64,
    ) {
        let dt = s.sample_period_s() as f32;
        let mut ma10 = MovingAverage::new((10.0 / f64::from(dt)).round() as usize);
        let mut ma_best = MovingAverage::new((self.best_ma_s / f64::from(dt)).round() as usize);
        let mut kf = RandomWalkKalman::new(self.best_q as f32, 1.0);
        let mut lag = MovingAverage::new(block);
        for (k, &x) in s.rate_dps.iter().enumerate() {
            let xf = f64::from(x);
            let (y10, yb, yk) = (ma10.push(xf), ma_best.push(xf), f64::from(kf.push(x)));
            // The target d(k - B) becomes known at sample k (block-aligned: at the end of its
            // block; averaging over the last B of them is the same as their block mean then).
            let ylag = if k >= block {
                lag.push(f64::from(d[k - block]))
            } else {
                f64::NAN
            };
            if k < 2 * block {
                continue;
            }
            let dk = f64::from(d[k]);
            let truth = s.drift_dps.as_ref().map(|t| f64::from(t[k]));
            let y = f64::from(ys[k]);
            if !y.is_finite() && self.diverged_at.is_none() {
                self.diverged_at = Some(first_sample + k as u64);
            }
            self.id.add(y, dk, truth);
            self.ma10.add(y10, dk, truth);
            self.ma_best.add(yb, dk, truth);
            self.kf.add(yk, dk, truth);
            self.lag.add(ylag, dk, truth);
            if let Some(tys) = temp_ys {
                for (acc, y) in self.temp.iter_mut().zip(tys) {
                    acc.add(y[k], dk, truth);
                }
            }
            self.scored += 1;
        }
    }

    /// The baselines' rows (those of `temp` last), the drift decomposition and the
    /// temperature regressions; `block` is the lagged baseline's window, samples.
    fn baselines(
        &self,
        block: usize,
        temp: Option<TempBaselines>,
    ) -> (
        Vec<Baseline>,
        Option<thermal::DriftDecomposition>,
        Vec<thermal::RateRegression>,
    ) {
        let mut baselines = vec![
            Baseline {
                name: "moving_average_10s",
                parameter: 10.0,
                figures: self.ma10.figures(),
            },
            Baseline {
                name: "moving_average_best_window_s",
                parameter: self.best_ma_s,
                figures: self.ma_best.figures(),
            },
            Baseline {
                name: "kalman_random_walk_q_over_r",
                parameter: self.best_q,
                figures: self.kf.figures(),
            },
            Baseline {
                name: "moving_average_of_target_lagged_one_block",
                parameter: block as f64,
                figures: self.lag.figures(),
            },
        ];
        let (mut decomposition, mut regressions) = (None, Vec::new());
        if let Some(t) = temp {
            for ((reg, q), acc) in t.regs.iter().zip(&t.q).zip(&self.temp) {
                baselines.push(Baseline {
                    name: reg.0,
                    parameter: *q,
                    figures: acc.figures(),
                });
            }
            regressions = t.regs.into_iter().map(|r| r.1).collect();
            decomposition = t.decomposition;
        }
        (baselines, decomposition, regressions)
    }
}

/// The temperature-aware baselines and the drift decomposition (records with `temp_c`).
struct TempBaselines {
    scaling: InputScaling<3>,
    shape: fog_core::wnn::WnnShape<3, { presets::L }>,
    /// (baseline name, regression); basis `i` of [`TempBaselines::basis`] for entry `i`.
    regs: Vec<(&'static str, thermal::RateRegression)>,
    /// Tuned q/r of each regression's Kalman filter.
    q: Vec<f64>,
    decomposition: Option<thermal::DriftDecomposition>,
}

/// Bases of known inputs: 0 = linear temperature and rate; 1 = the time-temp network's
/// neurons (all but the bias); 2 = its neurons on `T` alone.
const BASIS_NAMES: [&str; 3] = [
    "linear in temp_c and dtemp_c_per_s",
    "time-temp network neurons (T, temp_c, dtemp_c_per_s; no bias)",
    "time-temp network neurons on T alone (warm-up shape)",
];

impl TempBaselines {
    fn new(
        train: &dyn Records,
        validate: &dyn Records,
        block: usize,
        levels: u32,
    ) -> Result<Option<Self>> {
        if train.get(0)?.temp_c.is_none() || validate.get(0)?.temp_c.is_none() {
            return Ok(None);
        }
        let scaling = training_scaling::<TimeTemp, 3>(train, &|dt| TimeTemp::new(1.0 / dt))?;
        let shape = presets::time_temp_shape::<{ presets::L }>().map_err(|e| anyhow!("{e}"))?;
        let mut me = Self {
            scaling,
            shape,
            regs: Vec::new(),
            q: Vec::new(),
            decomposition: None,
        };
        let reference = |s: &Series| -> Result<Vec<f64>> {
            Ok(denoised(s, block, levels)?
                .iter()
                .map(|&v| f64::from(v))
                .collect())
        };
        for (i, name) in [
            "kalman_on_rate_minus_temperature_regression",
            "kalman_on_rate_minus_batch_ls_of_network_basis",
        ]
        .into_iter()
        .enumerate()
        {
            let basis = |x: &[f32; 3]| me.basis(i, x);
            let reg = thermal::fit_rate(train, BASIS_NAMES[i], &basis)?;
            let q = thermal::tune_q(
                train,
                TUNE_RECORDS,
                &KALMAN_Q_OVER_R,
                &reg,
                &basis,
                2 * block,
                &reference,
            )?;
            me.regs.push((name, reg));
            me.q.push(q);
        }
        if train.get(0)?.drift_dps.is_some() && validate.get(0)?.drift_dps.is_some() {
            let b0 = |x: &[f32; 3]| me.basis(0, x);
            let b2 = |x: &[f32; 3]| me.basis(2, x);
            let b1 = |x: &[f32; 3]| me.basis(1, x);
            me.decomposition = Some(thermal::decompose(
                train,
                validate,
                &[
                    (BASIS_NAMES[0], &b0),
                    (BASIS_NAMES[2], &b2),
                    (BASIS_NAMES[1], &b1),
                ],
            )?);
        }
        Ok(Some(me))
    }

    /// Regressors of basis `which` (see [`BASIS_NAMES`]) for raw known inputs `x`.
    fn basis(&self, which: usize, x: &[f32; 3]) -> Vec<f64> {
        if which == 0 {
            return vec![f64::from(x[1]), f64::from(x[2])];
        }
        let mut h = [0.0f32; presets::L];
        self.shape.hidden(&self.scaling.apply(x), &mut h);
        h.iter()
            .enumerate()
            .filter(|(l, _)| *l != presets::TT_BIAS && (which == 1 || self.shape.a[*l][0] != 0.0))
            .map(|(_, &v)| f64::from(v))
            .collect()
    }

    /// Each baseline's estimates for record `s`.
    fn track(&self, s: &Series) -> Result<Vec<Vec<f64>>> {
        self.regs
            .iter()
            .zip(&self.q)
            .enumerate()
            .map(|(i, ((_, reg), q))| reg.track(&|x: &[f32; 3]| self.basis(i, x), s, *q))
            .collect()
    }
}

/// The guard's ceiling on every DRLS `U_a`: 1, the largest `U(0)` of the presets (the
/// level-trend bias neuron's), so a silent neuron's `U` never exceeds what it started with.
const GUARD_U_MAX: f32 = 1.0;

/// `U(0)` that keeps a neuron's weight where it starts (with lambda = 1 it only shrinks).
const FROZEN_U: f32 = 1.0e-20;

fn drls_config(o: &Options) -> DrlsConfig {
    DrlsConfig {
        lambda: o.lambda,
        u0: o.u0,
        u_max: if o.guard { GUARD_U_MAX } else { f32::INFINITY },
        w_max: if o.guard { 1.0e4 } else { f32::INFINITY },
        mode: if o.trainer == TrainerKind::DrlsParallel {
            DrlsMode::Parallel
        } else {
            DrlsMode::Sequential
        },
        form: match o.drls_form {
            DrlsFormArg::Gain => DrlsForm::Gain,
            DrlsFormArg::Energy => DrlsForm::Energy,
        },
    }
}

fn activation(a: Act) -> Activation {
    match a {
        Act::Gaussian => Activation::Gaussian,
        Act::MexicanHat => Activation::MexicanHat,
    }
}

fn with_trainer<const L: usize, const B: usize>(
    o: &Options,
    train: &dyn Records,
    validate: &dyn Records,
) -> Result<Report> {
    let den = DenoiseConfig {
        levels: o.levels,
        ..DenoiseConfig::PAPER
    };
    let act = activation(o.activation);
    let rls = RlsConfig {
        lambda: o.lambda,
        delta: 1.0,
        trace_max: 1.0e6,
        w_max: 1.0e4,
    };
    let nlms = NlmsConfig {
        mu: (1.0 - o.lambda).clamp(1e-4, 1.0),
        eps: 1e-3,
        w_max: 1.0e4,
    };
    let bad = || anyhow!("invalid trainer configuration: {o:?}");
    macro_rules! go {
        ($features:expr, $default:expr, $mk:expr) => {
            match o.trainer {
                TrainerKind::DrlsParallel | TrainerKind::DrlsSequential => {
                    let mut t = Drls::<L>::new(drls_config(o)).ok_or_else(bad)?;
                    if o.preset == Preset::LevelTrend {
                        if matches!(o.level, LevelInput::Kalman { .. }) {
                            // The linear part (bias + link) is the Kalman filter itself:
                            // frozen, the wavelet neurons learn only what it misses.
                            t.set_neuron(0, 1.0, FROZEN_U);
                            t.set_neuron(1, 1.0, FROZEN_U);
                        } else {
                            t.set_neuron(0, 0.9999, 1.0);
                        }
                    }
                    if o.preset == Preset::LevelBank {
                        // The 1000-s level's link stays the identity.
                        t.set_neuron(presets::LB_LEVEL, 1.0, FROZEN_U);
                        if !o.known_inputs {
                            for a in presets::LB_KNOWN..L {
                                t.set_neuron(a, 1.0, FROZEN_U);
                            }
                        }
                    }
                    run_generic::<_, _, _, L, B>(
                        o,
                        train,
                        validate,
                        $default,
                        &$features,
                        &|s, dt| $mk(s, t.clone(), dt),
                        &|id, dt| {
                            if o.preset == Preset::TimeTemp {
                                let mut w = *id.weights();
                                presets::time_temp_power_on(
                                    &mut w,
                                    id.trainer_mut(),
                                    dt,
                                    o.bias_memory_s,
                                    o.warmup_u0,
                                );
                                id.set_weights(w);
                            }
                        },
                    )
                }
                TrainerKind::Rls => {
                    let t = Rls::<L>::new(rls).ok_or_else(bad)?;
                    run_generic::<_, _, _, L, B>(
                        o,
                        train,
                        validate,
                        $default,
                        &$features,
                        &|s, dt| $mk(s, t.clone(), dt),
                        &|_, _| {},
                    )
                }
                TrainerKind::Nlms => {
                    let t = Nlms::new(nlms).ok_or_else(bad)?;
                    run_generic::<_, _, _, L, B>(
                        o,
                        train,
                        validate,
                        $default,
                        &$features,
                        &|s, dt| $mk(s, t.clone(), dt),
                        &|_, _| {},
                    )
                }
            }
        };
    }
    match o.preset {
        Preset::Paper => go!(|_dt: f32| RateTime, presets::PAPER_SCALING, |s, t, dt| {
            presets::paper_with::<_, B, L>(act, s, t, den, dt)
        }),
        Preset::LevelTrend => go!(
            |dt: f32| match o.level {
                // As `presets::level_trend_with` makes them: the trend held for a while.
                LevelInput::Kalman { q_over_r } => {
                    LevelTrendTime::with_kalman(1.0 / dt, q_over_r)
                        .with_trend_every(presets::trend_hold_samples(1.0 / dt))
                }
                LevelInput::Mean10s | LevelInput::KalmanTuned => {
                    presets::level_trend_features(1.0 / dt)
                }
            },
            presets::LEVEL_TREND_SCALING,
            |s, t, dt| presets::level_trend_with::<_, B, L>(s, t, den, dt)
        ),
        Preset::LevelBank => go!(
            |dt: f32| if o.undelayed_output {
                MultiScaleLevels::new(1.0 / dt).undelayed_output()
            } else {
                MultiScaleLevels::new(1.0 / dt)
            },
            InputScaling::IDENTITY,
            |s, t, dt| presets::level_bank_with::<_, B, L>(s, t, den, dt, o.bank_from)
        ),
        Preset::Motion => bail!(
            "preset motion is trained with --save-identifier and scored by replay --identifier"
        ),
        Preset::TimeTemp => {
            if train.get(0)?.temp_c.is_none() {
                bail!(
                    "{}: preset time-temp needs a temp_c column",
                    train.get(0)?.name
                );
            }
            go!(
                |dt: f32| TimeTemp::new(1.0 / dt),
                presets::TIME_TEMP_SCALING,
                |s, t, dt| presets::time_temp_with::<_, B, L>(s, t, den, dt)
            )
        }
    }
}

/// The Kalman baseline's q/r: the grid value with the least squared error on the first
/// training records, against the true drift when the records carry it, else against the
/// denoised measurement; samples from `2 * block` on, as everywhere.
pub fn tune_kalman(train: &dyn Records, block: usize, levels: u32) -> Result<f64> {
    let mut sq = [0.0f64; KALMAN_Q_OVER_R.len()];
    for i in 0..train.len().min(TUNE_RECORDS) {
        let s = train.get(i)?;
        let reference: Vec<f64> = match &s.drift_dps {
            Some(t) => t.iter().map(|&v| f64::from(v)).collect(),
            None => denoised(&s, block, levels)?
                .iter()
                .map(|&v| f64::from(v))
                .collect(),
        };
        for (qi, q) in KALMAN_Q_OVER_R.iter().enumerate() {
            let mut kf = RandomWalkKalman::new(*q as f32, 1.0);
            for (k, &x) in s.rate_dps.iter().enumerate() {
                let y = f64::from(kf.push(x));
                if k >= 2 * block {
                    sq[qi] += (y - reference[k]).powi(2);
                }
            }
        }
    }
    let best = sq
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    Ok(KALMAN_Q_OVER_R[best])
}

/// Runs one identification experiment.
pub fn run(o: &Options, train: &dyn Records, validate: &dyn Records) -> Result<Report> {
    if train.is_empty() || validate.is_empty() {
        bail!("need at least one training and one validation record");
    }
    let mut tuned;
    let o = if o.level == LevelInput::KalmanTuned {
        tuned = o.clone();
        tuned.level = LevelInput::Kalman {
            q_over_r: tune_kalman(train, o.block, o.levels)? as f32,
        };
        &tuned
    } else {
        o
    };
    match (o.hidden, o.block) {
        (10, 512) => with_trainer::<10, 512>(o, train, validate),
        (20, 512) => with_trainer::<20, 512>(o, train, validate),
        (30, 512) => with_trainer::<30, 512>(o, train, validate),
        (40, 512) => with_trainer::<40, 512>(o, train, validate),
        (60, 512) => with_trainer::<60, 512>(o, train, validate),
        (30, 256) => with_trainer::<30, 256>(o, train, validate),
        (30, 1024) => with_trainer::<30, 1024>(o, train, validate),
        (h, b) => bail!("--hidden {h} with --block {b} is not built in: hidden 10, 20, 30, 40 or 60 with block 512, or hidden 30 with block 256 or 1024"),
    }
}
