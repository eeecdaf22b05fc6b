//! The drift filter on the host ([`fog_core::drift_filter`]): fitting the gyro model on
//! static calibration runs into an image (`host-sim identify --preset motion`), reading and
//! writing the image, and running it over a record (`host-sim replay --identifier`).
//!
//! Assumptions, stated once:
//! - every record starts at the gyro's power-on (`t_s` of the first row is the filter's
//!   time 0: the warm-up's clock);
//! - the record's rate (mean step of `t_s`) is the sensor's within
//!   [`fog_core::image::RATE_TOLERANCE`]; otherwise the command refuses it;
//! - calibration runs are static (the true rate is zero: Earth's rate is within the turn-on
//!   bias's spread).

pub mod calibration;
pub mod show;
pub mod tune;

use crate::firmware_fit::{self, FirmwareFit};
use crate::gyro_fit::{self, GyroFitReport};
use crate::identify::series::{Records, Series};
use crate::record;
use anyhow::{anyhow, bail, Context, Result};
use fog_core::drift_filter::{DriftFilter, DriftFilterConfig, DriftOutput};
use fog_core::gyro_model::{GyroModel, MarkovTerm, MAX_MARKOV};
use fog_core::image::{Image, IMAGE_LEN};
use fog_core::sensor::SensorConfig;
use std::io::Write;
use std::path::Path;

/// How to fit.
#[derive(Debug, Clone, Copy)]
pub struct TrainOptions {
    /// The gyro file's sensor (rate, full scale, quantum; its noise and bound are checked against
    /// the runs').
    pub sensor: SensorConfig,
    /// The filter's settings stored in the image.
    pub config: DriftFilterConfig,
}

impl TrainOptions {
    /// Defaults for `sensor`: the filter's default settings.
    pub fn new(sensor: SensorConfig) -> Self {
        Self {
            sensor,
            config: DriftFilterConfig::default(),
        }
    }
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
            "{}: sample {k} (t_s = {} s): rate {} deg/s beyond the sensor's full scale {fs} deg/s (a glitch, or give the right --gyro); calibration runs are static records",
            s.name,
            s.t_s[k],
            s.rate_dps[k]
        );
    }
    Ok(())
}

/// Every record of `records` read and checked as a static calibration run of `sensor`
/// (its rate, nothing beyond its full scale).
fn static_runs(records: &dyn Records, sensor: &SensorConfig) -> Result<Vec<Series>> {
    (0..records.len())
        .map(|i| {
            let s = records.get(i)?;
            check_rate(&s, sensor)?;
            check_full_scale(&s, sensor)?;
            Ok(s)
        })
        .collect()
}

/// What [`train`] returns.
#[derive(Debug, Clone)]
pub struct Trained {
    /// The image.
    pub image: Image,
    /// What the fit found ([`gyro_fit`]).
    pub fit: GyroFitReport,
    /// What the calibration runs showed ([`calibration`]).
    pub calibration: calibration::Calibration,
    /// Where the runs and the gyro file disagree.
    pub calibration_warnings: Vec<String>,
}

/// Fits the gyro model on `records` (each static, from power-on) and returns its image. The
/// records are read once and held in memory.
pub fn train(records: &dyn Records, o: &TrainOptions) -> Result<Trained> {
    let all = static_runs(records, &o.sensor)?;
    // The unit is never the datasheet: what the runs show is what the model holds.
    let cal = calibration::measure(&all)?;
    let calibration_warnings = calibration::warnings(&o.sensor, &cal)?;
    let (mut model, fit) = gyro_fit::fit(&all, &cal, f64::from(o.sensor.drift_bound_dps))?;
    // The gyro file fixes what the stream is: its rate and output quantum (the runs'
    // measured ones are checked against them: the warnings above).
    model.sample_rate_hz = o.sensor.sample_rate_hz;
    model.quantum_dps = o.sensor.quantum_dps;
    let image = Image {
        model,
        config: o.config,
        full_scale_dps: o.sensor.full_scale_dps,
        trained_runs: all.len() as u32,
    };
    Ok(Trained {
        image,
        fit,
        calibration: cal,
        calibration_warnings,
    })
}

/// What [`personalize`] returns: the unit's image and what its runs showed.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Personal {
    /// The unit's image (the family's configuration, the unit's model).
    #[serde(skip)]
    pub image: Image,
    /// The unit's runs.
    pub runs: Vec<String>,
    /// Their fit with the links held at the unit's ([`gyro_fit::fit_unit`]).
    pub fit: GyroFitReport,
    /// What they showed.
    pub calibration: calibration::Calibration,
    /// The unit's model (deg/h and s, as `model` in the report).
    pub model: show::ImageInfo,
}

impl Personal {
    /// One line: the unit's turn-on centre and scatter, warm-up, links.
    pub fn describe(&self) -> String {
        let m = &self.image.model;
        let dph = 3600.0;
        format!(
            "turn-on {:+.2} +- {:.2} deg/h, warm-up {:+.2} +- {:.2} deg/h over {:.0}-{:.0} s, link {:+.4} +- {:.4} deg/h/C, rate link {:+.3} +- {:.3} deg/h per C/min",
            m.turn_on_dps.mean * dph,
            m.turn_on_dps.sigma * dph,
            m.warmup_dps.mean * dph,
            m.warmup_dps.sigma * dph,
            m.warmup_tau_min_s,
            m.warmup_tau_max_s,
            m.temp_dps_per_c.mean * dph,
            m.temp_dps_per_c.sigma * dph,
            m.temp_rate_dps_per_c_per_s.mean * dph / 60.0,
            m.temp_rate_dps_per_c_per_s.sigma * dph / 60.0,
        )
    }
}

/// The `family` image made ONE unit's on that unit's own static `records` (each from
/// power-on; [`gyro_fit::fit_unit`]); the runs are checked as [`train`]'s. The unit keeps
/// the family's Gauss-Markov terms as fitted (`fitted_markov`, the trained image's), not
/// as `--tune-on` scaled them: the tuning picks them for the family image on other units'
/// vehicles, where they also carry the errors of the family's constants, which the unit's
/// own runs remove (measured: docs/drift-filter.md "The unit's own runs").
pub fn personalize(
    family: &Image,
    fitted_markov: &[MarkovTerm; MAX_MARKOV],
    records: &dyn Records,
    sensor: &SensorConfig,
) -> Result<Personal> {
    let runs = static_runs(records, sensor)?;
    if runs.len() < 2 {
        bail!(
            "--unit-runs: {} run(s) of the unit; at least 2 (each from power-on)",
            runs.len()
        );
    }
    let cal = calibration::measure(&runs)?;
    let family_model = GyroModel {
        markov: *fitted_markov,
        ..family.model
    };
    let (mut model, fit) = gyro_fit::fit_unit(
        &runs,
        &cal,
        f64::from(sensor.drift_bound_dps),
        &family_model,
    )?;
    model.sample_rate_hz = sensor.sample_rate_hz;
    model.quantum_dps = sensor.quantum_dps;
    let image = Image {
        model,
        trained_runs: family.trained_runs.saturating_add(runs.len() as u32),
        ..*family
    };
    let bytes = image_bytes(&image)?;
    Ok(Personal {
        model: show::describe(&image, &bytes),
        image,
        runs: runs.iter().map(|s| s.name.clone()).collect(),
        fit,
        calibration: cal,
    })
}

/// The image of the sensor's specification alone ([`GyroModel::for_sensor`]): the built-in
/// default of `host-sim replay` without an image.
pub fn untrained(sensor: &SensorConfig) -> Image {
    Image {
        model: GyroModel::for_sensor(sensor),
        config: DriftFilterConfig::default(),
        full_scale_dps: sensor.full_scale_dps,
        trained_runs: 0,
    }
}

/// `image` as the bytes of its file.
pub fn image_bytes(image: &Image) -> Result<Vec<u8>> {
    let mut buf = [0u8; IMAGE_LEN];
    let n = image.to_bytes(&mut buf).map_err(|e| anyhow!("{e}"))?;
    Ok(buf[..n].to_vec())
}

/// Writes `image` to `path` atomically, unless it does not fit the firmware and `force` is
/// off ([`crate::firmware_fit`]: then an error naming `path` and the verdict, and nothing is
/// written). Returns what the firmware does with it, for the caller to print and report.
pub fn write_image(path: &Path, image: &Image, force: bool) -> Result<FirmwareFit> {
    let bytes = image_bytes(image).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let fit = firmware_fit::check(image, &bytes);
    fit.refuse(path, force)?;
    record::write_atomic(path, |w| {
        w.write_all(&bytes)
            .with_context(|| format!("{}: write failed", path.display()))
    })?;
    Ok(fit)
}

/// Reads an image; any problem is one line naming the file.
pub fn read_image(path: &Path) -> Result<Image> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    Image::parse(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// The sensor an image stands for (rate, full scale, quantum, white noise, drift bound), as
/// the stream readers and the baselines take it.
pub fn sensor_of(image: &Image) -> SensorConfig {
    let m = &image.model;
    SensorConfig {
        full_scale_dps: image.full_scale_dps,
        quantum_dps: m.quantum_dps,
        sample_rate_hz: m.sample_rate_hz,
        noise_density_dps_rthz: m.white_dps_rthz,
        drift_bound_dps: m.drift_bound_dps,
    }
}

/// The level's process noise per sample of `model`, (deg/s)^2: the rate random walk's
/// `K^2 dt` plus each Gauss-Markov term's short-time increment `2 sigma^2 dt / tau` (what a
/// one-state random-walk baseline would take from the model).
pub fn level_q_dps2_per_sample(model: &GyroModel) -> f64 {
    let dt = f64::from(model.sample_period_s());
    let k = f64::from(model.rrw_dps_per_s_rthz);
    let gm: f64 = model
        .markov
        .iter()
        .filter(|t| t.sigma_dps > 0.0)
        .map(|t| 2.0 * f64::from(t.sigma_dps).powi(2) * dt / f64::from(t.tau_s))
        .sum();
    k * k * dt + gm
}

/// The image's filter at power-on; an error naming `name` if it cannot be built.
pub fn filter(image: &Image, name: &str) -> Result<DriftFilter> {
    image
        .filter()
        .map_err(|e| anyhow!("{name}: {}", filter_error_words(&e)))
}

/// Why a drift filter cannot be built, in words (never the enum's internal name).
pub fn filter_error_words(e: &fog_core::drift_filter::DriftFilterError) -> &'static str {
    use fog_core::drift_filter::DriftFilterError as E;
    match e {
        E::BadModel => "the gyro model is not valid (a term not finite, or out of its range)",
        E::BadConfig => {
            "the drift filter's settings are not valid (its window holds fewer than 2 samples)"
        }
        E::NonFiniteRate => "a rate that is not finite",
    }
}

/// Runs `filter` over a record from power-on: one output per row.
pub fn run(filter: &mut DriftFilter, s: &Series) -> Vec<DriftOutput> {
    run_rows(
        filter,
        s.rate_dps.iter().enumerate().map(|(k, &rate)| {
            let temp = s
                .temp_c
                .as_ref()
                .and_then(|t| t.get(k).copied())
                .unwrap_or(f32::NAN);
            let ext = s.still.as_ref().and_then(|v| v.get(k).copied().flatten());
            (rate, temp, ext)
        }),
    )
}

/// Runs `filter` from power-on over `rows`, each `(rate_dps, temp_c, external_still)` as
/// [`push_row`] takes them: one output per row.
pub fn run_rows(
    filter: &mut DriftFilter,
    rows: impl IntoIterator<Item = (f32, f32, Option<bool>)>,
) -> Vec<DriftOutput> {
    filter.restart();
    rows.into_iter()
        .map(|(rate_dps, temp_c, ext)| push_row(filter, rate_dps, temp_c, ext))
        .collect()
}

/// One row through `filter`: `temp_c` NaN for none, `external_still` the row's flag. Rows
/// are validated finite by the reader, so a refusal cannot happen; if it did, the row gets
/// no drift, the rate uncompensated and not still.
pub fn push_row(
    filter: &mut DriftFilter,
    rate_dps: f32,
    temp_c: f32,
    external_still: Option<bool>,
) -> DriftOutput {
    filter
        .push(rate_dps, temp_c, external_still)
        .unwrap_or(DriftOutput {
            drift_dps: 0.0,
            compensated_dps: rate_dps,
            still: false,
        })
}

/// Header of `replay --identifier` output: the replay columns (`denoised_dps` empty: the
/// drift filter does not denoise at run time), then the still flag (0/1: the last window
/// the filter's test found still, or the external flag's window).
pub const OUTPUT_HEADER: &str = "index,t_s,rate_dps,denoised_dps,drift_dps,compensated_dps,still";

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn a_family_with_a_shared_warm_up_is_fitted_and_its_image_runs() {
        let records = Synthetic(vec![10.0, 12.0, 8.0, 11.0, 9.0]);
        let t = train(&records, &TrainOptions::new(SensorConfig::ECORE_2000)).expect("train");
        assert_eq!(t.image.trained_runs, 5);
        // Every unit warms up by about 10 deg/h: the family's mean says so.
        let warm_dph = t.image.model.warmup_dps.mean * 3600.0;
        assert!((5.0..15.0).contains(&warm_dph), "{warm_dph}");
        let bytes = image_bytes(&t.image).expect("bytes");
        assert_eq!(Image::parse(&bytes), Ok(t.image));
        let mut f = filter(&t.image, "test").expect("filter");
        let s = records.get(0).expect("record");
        let out = run(&mut f, &s);
        // At the end the drift is the bias (1e-3 deg/s) within 2 deg/h.
        let last = out.last().expect("rows").drift_dps;
        assert!((last - 1e-3).abs() < 2.0 / 3600.0, "{}", last * 3600.0);
    }

    #[test]
    fn a_unit_keeps_the_fitted_gauss_markov_terms_not_the_tuned_ones() {
        let family = Synthetic(vec![10.0, 12.0, 8.0, 11.0, 9.0]);
        let t = train(&family, &TrainOptions::new(SensorConfig::ECORE_2000)).expect("train");
        let term = |sigma_dph: f32| MarkovTerm {
            sigma_dps: sigma_dph / 3600.0,
            tau_s: 30.0,
        };
        let fitted = [term(1.0), MarkovTerm::default(), MarkovTerm::default()];
        // As `--tune-on` might leave them: scaled x3.
        let mut tuned = t.image;
        tuned.model.markov = [term(3.0), MarkovTerm::default(), MarkovTerm::default()];
        let unit = Synthetic(vec![20.0, 21.0, 19.0]);
        let p = personalize(&tuned, &fitted, &unit, &SensorConfig::ECORE_2000).expect("unit");
        assert_eq!(p.image.model.markov, fitted);
        assert_eq!(
            p.image.model.rrw_dps_per_s_rthz,
            tuned.model.rrw_dps_per_s_rthz
        );
        assert_eq!(p.runs.len(), 3);
    }
}
