//! The motion-safe identifier on the host ([`fog_core::motion`]): training on static
//! records into an identifier image, reading and writing the image, and running it over a
//! record (`host-sim identify --preset motion`, `host-sim replay --identifier`).
//!
//! Assumptions, stated once:
//! - every record starts at the gyro's power-on (`t_s` of the first row is time 0 of the
//!   model's time input);
//! - the record's rate (mean step of `t_s`) is the sensor's within
//!   [`fog_core::image::RATE_TOLERANCE`]; otherwise the command refuses it;
//! - training records are static (the true rate is zero, or constant and then removed with
//!   the per-record intercept).

pub mod calibration;
pub mod show;
pub mod tune;

use crate::firmware_fit::{self, FirmwareFit};
use crate::identify::series::{Records, Series};
use crate::record;
use anyhow::{anyhow, bail, Context, Result};
use fog_core::image::{Image, IMAGE_LEN};
use fog_core::motion::{
    MotionConfig, MotionModel, MotionOutput, MotionTrainer, RecordFit, MOTION_DRLS,
};
use fog_core::motion_fit::{cross_validate, NormalEquations, RIDGE_GRID};
use fog_core::preset::{Arrangement, PresetEstimator, SecondState};
use fog_core::still::SensorConfig;
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// Default level noise of a saved image, (deg/h)^2 per hour: 85.7, the grid point that
/// minimised the mean test heading RMS of the dual on 16 host-sim and 16 second-generator
/// test vehicles and on 32 demo-family vehicles (ASSUMED for the dual-thermal; a
/// calibration with `--tune-on` scans q). fog-core's `MotionConfig::DEFAULT_LEVEL_Q` (4)
/// is the level of a static record; in motion it is too small by these figures.
pub const DEFAULT_LEVEL_Q_DPH2_PER_H: f32 = 85.7;

/// The bank arrangements: the bank's bias instability `B`, deg/h (ASSUMED: the E-Core
/// class's 1.5 deg/h, `host-sim/presets/ecore2000.toml`).
pub const BANK_B_DPH: f32 = 1.5;
/// The bank arrangements: the bank's longest correlation time, s (states at 1, 10, ...,
/// 10^4 s).
pub const BANK_TAU_MAX_S: f32 = 10_000.0;
/// The bank a saved image carries by default in a bank arrangement ([`BANK_B_DPH`],
/// [`BANK_TAU_MAX_S`] in the image's second-state fields).
pub const DEFAULT_BANK: SecondState = SecondState {
    sigma: BANK_B_DPH / 3600.0,
    tau_s: BANK_TAU_MAX_S,
};

/// How the saved image's level learns (`--level-update`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum LevelUpdateArg {
    /// The level as the sensor's Allan noise model (random walk + one Gauss-Markov state
    /// per decade of correlation time, fog_core::bank) protected as the dual: rolled back
    /// when a window fails, and in motion a second bank that only released windows reached.
    BankDual,
    /// The bank with a failed window's samples rolled back (the windows before it kept),
    /// the output at rest and in motion.
    BankGuarded,
    /// Per-sample level at rest, window level in motion, each with the unit's own
    /// temperature link `c (T - T0)` learned at rest as second state (fog_core::preset).
    /// The default.
    #[default]
    DualThermal,
}

impl LevelUpdateArg {
    /// The image's arrangement.
    pub fn arrangement(self) -> Arrangement {
        match self {
            Self::BankDual => Arrangement::BankDual,
            Self::BankGuarded => Arrangement::BankGuarded,
            Self::DualThermal => Arrangement::DualThermal,
        }
    }

    /// The argument that gives `arrangement` (the inverse of [`Self::arrangement`]).
    pub fn of(arrangement: Arrangement) -> Self {
        match arrangement {
            Arrangement::BankDual => Self::BankDual,
            Arrangement::BankGuarded => Self::BankGuarded,
            Arrangement::DualThermal => Self::DualThermal,
        }
    }

    /// The command-line value (`bank-dual`, ...), as `--level-update` takes it.
    pub fn cli_name(self) -> String {
        clap::ValueEnum::to_possible_value(&self)
            .map(|v| v.get_name().to_owned())
            .unwrap_or_default()
    }
}

/// The bench trainer of the model's output weights (`identify --motion-trainer`,
/// `demo --trainer`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum TrainerArg {
    /// The paper's DRLS (sequential, lambda 0.9998, `epochs` passes), kept only when the
    /// family shares a shape: least squares with leave-one-record-out
    /// ([`fog_core::motion_fit::cross_validate`]) must find a ridge that predicts held-out
    /// records better than `m = 0`; otherwise the empty model (the default). Why DRLS's
    /// weights and not least squares': on 16 host-sim and 32 demo-family test vehicles
    /// DRLS's model gives the lower heading error in motion (docs/motion.md).
    #[default]
    DrlsChecked,
    /// The paper's DRLS alone (the reference).
    Drls,
    /// Least squares over every record at once, inputs and targets centred per record,
    /// ridge picked by leave-one-record-out ([`fog_core::motion_fit`]); the empty model
    /// when nothing transfers between units.
    LeastSquares,
}

/// How to train.
#[derive(Debug, Clone, Copy)]
pub struct TrainOptions {
    /// The bench trainer (default [`TrainerArg::DrlsChecked`]).
    pub trainer: TrainerArg,
    /// Estimator configuration stored in the image.
    pub config: MotionConfig,
    /// Passes over the training records with DRLS (0: an untrained model, i.e. the gated
    /// random-walk Kalman filter alone, with either trainer; least squares makes one pass
    /// for any other value).
    pub epochs: u32,
    /// Time range of the model, s.
    pub time_max_s: f32,
    /// How the image's level learns (default [`Arrangement::DualThermal`]).
    pub arrangement: Arrangement,
    /// The image's second-state parameters (default [`SecondState::THERMAL`]).
    pub second_state: SecondState,
}

impl TrainOptions {
    /// Defaults for `sensor`: 3 passes, 1800 s, the dual-thermal with the
    /// default prior [`SecondState::THERMAL`], level noise [`DEFAULT_LEVEL_Q_DPH2_PER_H`].
    pub fn new(sensor: SensorConfig) -> Self {
        let mut config = MotionConfig::for_sensor(sensor);
        config.level_q_dps2_per_s = DEFAULT_LEVEL_Q_DPH2_PER_H / (3600.0 * 3600.0 * 3600.0);
        Self {
            trainer: TrainerArg::DrlsChecked,
            config,
            epochs: 3,
            time_max_s: 1800.0,
            arrangement: Arrangement::DualThermal,
            second_state: SecondState::THERMAL,
        }
    }

    /// The same options with `arrangement` and its default second state
    /// ([`default_second_state`]).
    pub fn with_arrangement(mut self, arrangement: Arrangement) -> Self {
        self.arrangement = arrangement;
        self.second_state = default_second_state(arrangement);
        self
    }
}

/// The image's default second-state fields for `arrangement`: [`DEFAULT_BANK`] for a bank
/// arrangement, else the thermal prior [`SecondState::THERMAL`].
pub fn default_second_state(arrangement: Arrangement) -> SecondState {
    if arrangement.is_bank() {
        DEFAULT_BANK
    } else {
        SecondState::THERMAL
    }
}

/// What training did, per record of the last pass.
#[derive(Debug, Clone, Serialize)]
pub struct TrainedRecord {
    /// The record.
    pub name: String,
    /// Training steps (windows).
    pub steps: u32,
    /// Intercept removed, deg/h.
    pub intercept_dph: f64,
    /// RMS a-priori error of the steps, deg/h.
    pub rms_error_dph: f64,
}

/// Refuses a record whose rate is not the sensor's.
pub fn check_rate(s: &Series, sensor: &SensorConfig) -> Result<f32> {
    let hz = (1.0 / s.sample_period_s()) as f32;
    let want = sensor.sample_rate_hz;
    if (hz - want).abs() > fog_core::image::RATE_TOLERANCE * want {
        bail!(
            "{}: sample rate {hz:.3} Hz, the sensor configuration says {want} Hz",
            s.name
        );
    }
    Ok(hz)
}

/// Refuses a calibration run with a sample beyond the sensor's full scale (a glitch or
/// another unit: one such sample decides the whole fit), naming the run, the sample and its
/// time.
pub fn check_full_scale(s: &Series, sensor: &SensorConfig) -> Result<()> {
    let fs = sensor.full_scale_dps;
    if let Some(k) = s.rate_dps.iter().position(|r| r.abs() > fs) {
        bail!(
            "{}: sample {k} (t_s = {} s): rate {} deg/s beyond the sensor's full scale {fs} deg/s (a glitch, or give the right --sensor); calibration runs are static records",
            s.name,
            s.t_s[k],
            s.rate_dps[k]
        );
    }
    Ok(())
}

/// What the least-squares trainer found ([`fog_core::motion_fit`]).
#[derive(Debug, Clone, Serialize)]
pub struct LeastSquaresFit {
    /// The ridge picked by leave-one-record-out (relative to the Gram matrix's mean
    /// diagonal); `None`: the empty model (nothing transfers between the records' units),
    /// or fewer than 2 records (then [`FALLBACK_RIDGE`] is used and this is `Some`).
    pub rho: Option<f64>,
    /// Pooled held-out gain of the pick over the empty model, `1 - SSE / SSE(m = 0)` on the
    /// records' centred 1-s window means (NaN without cross-validation).
    pub heldout_gain: f64,
    /// The same for the grid's smallest ridge.
    pub heldout_gain_least_ridge: f64,
    /// Windows (training equations) over all records.
    pub windows: u64,
    /// Whether the ridge was cross-validated (2 records or more).
    pub cross_validated: bool,
    /// The model is its linear links to temperature and its rate alone (the time neurons at
    /// 0): they predicted the held-out records better than the whole model.
    pub links_only: bool,
    /// Pooled held-out gain of the whole model (its best ridge; 0: none beats `m = 0`).
    pub heldout_gain_whole: f64,
    /// Pooled held-out gain of the linear links alone (0: none beats `m = 0`).
    pub heldout_gain_links: f64,
}

/// Ridge used without cross-validation (a single record): 1e-3 of the Gram matrix's mean
/// diagonal (ASSUMED: the middle of [`RIDGE_GRID`]).
pub const FALLBACK_RIDGE: f64 = 1e-3;

/// One line on what the least-squares trainer found.
pub fn describe_least_squares(ls: &LeastSquaresFit) -> String {
    let pick = match (ls.rho, ls.cross_validated) {
        (Some(r), true) => format!("ridge {r:.0e} picked by leave-one-record-out"),
        (Some(r), false) => format!("ridge {r:.0e} (one record: not cross-validated)"),
        (None, _) => "EMPTY MODEL: no ridge predicted held-out records better than m = 0 (nothing transfers between units)".to_string(),
    };
    format!(
        "least squares over {} windows: {pick}; held-out gain over m = 0 {:.2} % (smallest ridge {:.2} %); whole model {:.2} %, linear temperature links alone {:.2} % -> {}",
        ls.windows,
        100.0 * ls.heldout_gain,
        100.0 * ls.heldout_gain_least_ridge,
        100.0 * ls.heldout_gain_whole,
        100.0 * ls.heldout_gain_links,
        if ls.links_only { "the links alone (least squares)" } else { "the whole model" }
    )
}

/// What [`train`] returns.
#[derive(Debug, Clone)]
pub struct Trained {
    /// The identifier image.
    pub image: Image,
    /// Per record (the last DRLS pass, or the least-squares fit).
    pub records: Vec<TrainedRecord>,
    /// The least-squares fit or check (`None` with `drls` or 0 epochs).
    pub least_squares: Option<LeastSquaresFit>,
    /// What the calibration runs showed ([`calibration`]), folded into the image's sensor.
    pub calibration: calibration::Calibration,
    /// Where the runs and the sensor file disagree.
    pub calibration_warnings: Vec<String>,
}

/// Trains a model on `records` (each static, from power-on) with `o.trainer` and returns
/// its image, the per-record figures and the least-squares cross-validation. The records
/// are read once and held in memory.
pub fn train(records: &dyn Records, o: &TrainOptions) -> Result<Trained> {
    let all: Vec<Series> = (0..records.len())
        .map(|i| {
            let s = records.get(i)?;
            check_rate(&s, &o.config.sensor)?;
            check_full_scale(&s, &o.config.sensor)?;
            Ok(s)
        })
        .collect::<Result<_>>()?;
    // The unit is never the datasheet: what the runs show goes into the image's sensor.
    let cal = calibration::measure(&all)?;
    let (sensor, still, calibration_warnings) =
        calibration::learned_sensor(&o.config.sensor, &o.config.still, &cal)?;
    let mut learned = *o;
    learned.config.sensor = sensor;
    learned.config.still = still;
    let o = &learned;
    let base = trainer(o)?;
    let (model, drls, rows, ls) = if o.epochs == 0 {
        let rows = all
            .iter()
            .map(|s| TrainedRecord::untrained(&s.name))
            .collect();
        (*base.model(), base.drls().clone(), rows, None)
    } else {
        match o.trainer {
            TrainerArg::Drls | TrainerArg::DrlsChecked => {
                let (tr, fits) = train_on(&all, o)?;
                let rows = all
                    .iter()
                    .zip(fits)
                    .map(|(s, fit)| TrainedRecord {
                        name: s.name.clone(),
                        steps: fit.steps,
                        intercept_dph: f64::from(fit.intercept_dps) * 3600.0,
                        rms_error_dph: f64::from(fit.rms_error_dps) * 3600.0,
                    })
                    .collect();
                let mut model = *tr.model();
                let mut check = None;
                if o.trainer == TrainerArg::DrlsChecked {
                    let (ls, fit) = least_squares(&equations(&all, o)?, o)?;
                    model = drls_checked(model, &fit, &ls);
                    check = Some(fit);
                }
                (model, tr.drls().clone(), rows, check)
            }
            TrainerArg::LeastSquares => {
                let eqs = equations(&all, o)?;
                let (model, fit) = least_squares(&eqs, o)?;
                let rows = all
                    .iter()
                    .zip(&eqs)
                    .map(|(s, (e, intercept))| TrainedRecord {
                        name: s.name.clone(),
                        steps: e.windows() as u32,
                        intercept_dph: f64::from(*intercept) * 3600.0,
                        rms_error_dph: (e.sse(&model.weights) / e.windows().max(1) as f64).sqrt()
                            * 3600.0,
                    })
                    .collect();
                (model, base.drls().clone(), rows, Some(fit))
            }
        }
    };
    let records_trained = match o.trainer {
        TrainerArg::Drls | TrainerArg::DrlsChecked => o.epochs.saturating_mul(all.len() as u32),
        TrainerArg::LeastSquares if o.epochs > 0 => all.len() as u32,
        TrainerArg::LeastSquares => 0,
    };
    Ok(Trained {
        image: Image::new(o.config, model, &drls, records_trained)
            .with_arrangement(o.arrangement, o.second_state),
        records: rows,
        least_squares: ls,
        calibration: cal,
        calibration_warnings,
    })
}

impl TrainedRecord {
    fn untrained(name: &str) -> Self {
        Self {
            name: name.to_string(),
            steps: 0,
            intercept_dph: f64::NAN,
            rms_error_dph: f64::NAN,
        }
    }
}

/// Each record's within-record normal equations and intercept.
fn equations(all: &[Series], o: &TrainOptions) -> Result<Vec<(NormalEquations, f32)>> {
    let model = MotionModel::standard(o.time_max_s).map_err(|e| anyhow!("model: {e}"))?;
    all.iter()
        .map(|s| {
            NormalEquations::from_record(
                &model,
                &s.rate_dps,
                s.temp_c.as_deref(),
                o.config.sensor.sample_rate_hz,
                o.config.still.window_s,
            )
            .map_err(|e| anyhow!("{}: {e}", s.name))
        })
        .collect()
}

/// The `drls-checked` rule: `model` (DRLS's) unless the least-squares cross-validation
/// `fit` found no shape the records share, then the empty model.
pub fn drls_checked(
    mut model: MotionModel,
    fit: &LeastSquaresFit,
    ls: &MotionModel,
) -> MotionModel {
    if fit.cross_validated && fit.rho.is_none() {
        model.weights = [0.0; fog_core::motion::MOTION_L];
    } else if fit.links_only {
        // The links alone predict held-out units better than the whole model: the
        // least-squares links, not DRLS's whole model.
        model.weights = ls.weights;
    }
    model
}

/// The least-squares model on `eqs`, its ridge picked by leave-one-record-out.
fn least_squares(
    eqs: &[(NormalEquations, f32)],
    o: &TrainOptions,
) -> Result<(MotionModel, LeastSquaresFit)> {
    let used: Vec<NormalEquations> = eqs.iter().map(|e| e.0).collect();
    least_squares_fit(&used, o.time_max_s)
}

/// The least-squares model (standard layout over `0..time_max_s`) on the records `used`
/// (one [`NormalEquations`] each), its ridge picked by leave-one-record-out
/// ([`cross_validate`] over [`RIDGE_GRID`]; the empty model when no ridge beats `m = 0`;
/// [`FALLBACK_RIDGE`] with fewer than 2 records).
pub fn least_squares_fit(
    used: &[NormalEquations],
    time_max_s: f32,
) -> Result<(MotionModel, LeastSquaresFit)> {
    let mut sum = NormalEquations::EMPTY;
    for e in used {
        sum.add(e);
    }
    let mut model = MotionModel::standard(time_max_s).map_err(|e| anyhow!("model: {e}"))?;
    let cv_full = cross_validate(used, &RIDGE_GRID);
    // The model's linear links to temperature and its rate alone (the time neurons at 0):
    // kept when it predicts held-out records better than the whole model.
    let keep = links_only(&model);
    let links: Vec<NormalEquations> = used.iter().map(|e| e.keep_only(&keep)).collect();
    let cv_links = if keep.iter().any(|k| *k) {
        cross_validate(&links, &RIDGE_GRID)
    } else {
        None
    };
    let gain = |c: &Option<fog_core::motion_fit::CrossValidation>| {
        c.as_ref()
            .filter(|c| c.rho.is_some())
            .map(|c| c.heldout_gain)
    };
    let (gain_links, gain_whole) = (gain(&cv_links), gain(&cv_full));
    // The links win when they beat the whole model held out, or when only they beat m = 0.
    let links_win = gain_links.is_some_and(|l| gain_whole.is_none_or(|f| l > f));
    let (cv, sum) = if links_win {
        let mut s = NormalEquations::EMPTY;
        for e in &links {
            s.add(e);
        }
        (cv_links, s)
    } else {
        (cv_full, sum)
    };
    let rho = match cv {
        Some(c) => c.rho,
        None => Some(FALLBACK_RIDGE),
    };
    if let Some(rho) = rho {
        model.weights = sum.solve(rho).map_err(|e| {
            anyhow!(
                "least squares over {} records ({} windows): {e}",
                used.len(),
                sum.windows()
            )
        })?;
    }
    Ok((
        model,
        LeastSquaresFit {
            rho,
            heldout_gain: cv.map_or(f64::NAN, |c| c.heldout_gain),
            heldout_gain_least_ridge: cv.map_or(f64::NAN, |c| c.heldout_gain_least_ridge),
            windows: sum.windows(),
            cross_validated: cv.is_some(),
            links_only: links_win,
            heldout_gain_whole: gain_whole.unwrap_or(0.0),
            heldout_gain_links: gain_links.unwrap_or(0.0),
        },
    ))
}

/// The neurons that are linear links to an input other than time (temperature, its rate).
fn links_only(model: &MotionModel) -> [bool; fog_core::motion::MOTION_L] {
    let mut keep = [false; fog_core::motion::MOTION_L];
    for (k, kind) in keep.iter_mut().zip(model.shape.kind.iter()) {
        *k = matches!(kind, fog_core::wnn::Neuron::Linear(j) if *j > 0);
    }
    keep
}

/// `o.epochs` passes over `all`; the fits of the last pass.
fn train_on(all: &[Series], o: &TrainOptions) -> Result<(MotionTrainer, Vec<RecordFit>)> {
    let mut tr = trainer(o)?;
    let mut fits = Vec::new();
    for pass in 0..o.epochs {
        for s in all {
            let fit: RecordFit = tr
                .train_record(
                    &s.rate_dps,
                    s.temp_c.as_deref(),
                    o.config.sensor.sample_rate_hz,
                )
                .map_err(|e| anyhow!("{}: {e}", s.name))?;
            if pass + 1 == o.epochs {
                fits.push(fit);
            }
        }
    }
    Ok((tr, fits))
}

fn trainer(o: &TrainOptions) -> Result<MotionTrainer> {
    o.config
        .check()
        .map_err(|e| anyhow!("configuration: {e}"))?;
    let model = MotionModel::standard(o.time_max_s).map_err(|e| anyhow!("model: {e}"))?;
    MotionTrainer::new(model, MOTION_DRLS, o.config.still.window_s)
        .map_err(|e| anyhow!("trainer: {e}"))
}

/// The image of an untrained model (weights 0) with `o`'s configuration: the
/// stillness-gated level alone (the built-in default of `host-sim replay`).
pub fn untrained(o: &TrainOptions) -> Result<Image> {
    let tr = trainer(o)?;
    Ok(Image::new(o.config, *tr.model(), tr.drls(), 0)
        .with_arrangement(o.arrangement, o.second_state))
}

/// `image` as the bytes of its file.
pub fn image_bytes(image: &Image) -> Result<Vec<u8>> {
    let mut buf = [0u8; IMAGE_LEN];
    let n = image.to_bytes(&mut buf).map_err(|e| anyhow!("{e}"))?;
    Ok(buf[..n].to_vec())
}

/// Writes `image` to `path` atomically, unless the firmware would refuse it
/// ([`crate::firmware_fit`]: then an error naming `path`, and nothing is written). Returns
/// what the firmware does with it, for the caller to print and report.
pub fn write_image(path: &Path, image: &Image) -> Result<FirmwareFit> {
    let bytes = image_bytes(image).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let fit = firmware_fit::check(image, &bytes);
    fit.refuse(path)?;
    record::write_atomic(path, |w| {
        w.write_all(&bytes)
            .with_context(|| format!("{}: write failed", path.display()))
    })?;
    Ok(fit)
}

/// Reads an identifier image; any problem is one line naming the file.
pub fn read_image(path: &Path) -> Result<Image> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    Image::parse(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// Runs `estimator` over a record from power-on: one output per row.
pub fn run(estimator: &mut PresetEstimator, s: &Series) -> Vec<MotionOutput> {
    estimator.restart();
    (0..s.rate_dps.len())
        .map(|k| {
            let temp = s
                .temp_c
                .as_ref()
                .and_then(|t| t.get(k).copied())
                .unwrap_or(f32::NAN);
            let ext = s.still.as_ref().and_then(|v| v.get(k).copied().flatten());
            push_row(estimator, s.rate_dps[k], temp, ext)
        })
        .collect()
}

/// One row through `estimator`: `temp_c` NaN for none, `external_still` the row's flag.
/// Rows are validated finite by the reader, so a refusal cannot happen; if it did, the row
/// gets no drift, the rate uncompensated, not still and not verified (counted as such by
/// the caller).
pub fn push_row(
    estimator: &mut PresetEstimator,
    rate_dps: f32,
    temp_c: f32,
    external_still: Option<bool>,
) -> MotionOutput {
    estimator
        .push(rate_dps, temp_c, external_still)
        .unwrap_or(MotionOutput {
            drift_dps: 0.0,
            compensated_dps: rate_dps,
            still: false,
            level_dps: 0.0,
            model_dps: 0.0,
            verified: false,
        })
}

/// Header of `replay --identifier` output: the replay columns (`denoised_dps` empty: the
/// motion estimator does not denoise at run time), then the still flag (0/1), the level,
/// the model term and the safety net's flag (1: the whole estimate; 0: nothing verified at
/// rest yet, or no rest for the image's `stale_s`: fog_core::motion::MotionOutput::verified).
pub const OUTPUT_HEADER: &str =
    "index,t_s,rate_dps,denoised_dps,drift_dps,compensated_dps,still,level_dps,model_dps,verified";

#[cfg(test)]
mod tests {
    use super::*;

    /// Every `--level-update` value names its arrangement and back, and the name `replay`
    /// reports is the one `identify` takes (`bank-dual`, not `bankdual`).
    #[test]
    fn level_update_names_round_trip() {
        use clap::ValueEnum;
        for arg in LevelUpdateArg::value_variants() {
            assert_eq!(LevelUpdateArg::of(arg.arrangement()), *arg);
            let name = arg.cli_name();
            assert_eq!(LevelUpdateArg::from_str(&name, false), Ok(*arg), "{name}");
        }
        assert_eq!(LevelUpdateArg::BankDual.cli_name(), "bank-dual");
    }

    /// In-memory static records: 600 s at 100 Hz, each `bias + a_i exp(-t / 150 s)` plus
    /// deterministic noise of the E-Core's sample sigma.
    struct Synthetic(Vec<f64>);

    impl Records for Synthetic {
        fn len(&self) -> usize {
            self.0.len()
        }
        fn get(&self, i: usize) -> Result<Series> {
            let sigma = f64::from(SensorConfig::ECORE_2000.sample_var_dps2()).sqrt();
            let mut x = 0x9e37_79b9_7f4a_7c15u64 ^ (i as u64 + 1);
            let mut unit = move || {
                x = x
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            let a = self.0[i] / 3600.0;
            let n = 60_000;
            let t_s: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
            let rate_dps = t_s
                .iter()
                .map(|t| {
                    let z = (unit() + unit() + unit() + unit()) * 3f64.sqrt();
                    (1e-3 + a * (-t / 150.0).exp() + sigma * z) as f32
                })
                .collect();
            Ok(Series {
                name: format!("synthetic {i}"),
                t_s,
                rate_dps,
                drift_dps: None,
                temp_c: None,
                ..Default::default()
            })
        }
    }

    fn weights(records: &Synthetic, trainer: TrainerArg) -> [f32; fog_core::motion::MOTION_L] {
        let mut o = TrainOptions::new(SensorConfig::ECORE_2000);
        o.time_max_s = 600.0;
        o.trainer = trainer;
        train(records, &o).expect("train").image.model.weights
    }

    #[test]
    fn drls_checked_keeps_a_shared_shape_and_drops_unit_specific_ones() {
        let any = |w: &[f32]| w.iter().any(|v| *v != 0.0);
        // Every unit warms up by 10 deg/h: DRLS's model is kept, the same bits as DRLS.
        let shared = Synthetic(vec![10.0; 5]);
        let checked = weights(&shared, TrainerArg::DrlsChecked);
        assert!(any(&checked));
        assert_eq!(checked, weights(&shared, TrainerArg::Drls));
        // Each unit's own sign and size (mean zero): DRLS still learns something, the
        // check removes it.
        let own = Synthetic(vec![8.0, -10.0, 6.0, -7.0, 3.0]);
        assert!(any(&weights(&own, TrainerArg::Drls)));
        assert!(!any(&weights(&own, TrainerArg::DrlsChecked)));
    }
}
