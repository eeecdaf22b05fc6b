//! `host-sim replay` with the motion preset (the default): a record through the drift
//! filter ([`fog_core::drift_filter`]), per-sample CSV, and when the record carries truth the
//! navigator's scores beside the causal baselines ([`crate::nav::compare`]).
//!
//! The image is a file (`--identifier`, from `identify --preset motion --save-identifier`:
//! the gyro model fitted on the unit family's calibration runs), or the `[identified]` model
//! of a `--gyro` file (`identify --save-gyro`), or, without either, the BUILT-IN default: the
//! model of the sensor's specification alone (`--gyro`, default the built-in whose rate
//! matches the record's; [`fog_core::gyro_model::GyroModel::for_sensor`]). It never subtracts more
//! than the model's drift bound, and learns only from windows its stillness test finds
//! still, so it cannot erase rotation.
//!
//! The replayed record streams ([`replay`]: memory bounded by the rate's look-ahead and the
//! report's decimations, whatever its length); records with truth scored as a set
//! (`identify --preset motion --validate`, [`score_records`]) are read whole.

use super::input::{self, Input};
use super::pooled::{heading_rms, pool, Pooled};
use super::stream::{self, InputFormat};
use super::tally::Tally;
use crate::identify::series::{CsvFiles, Records, Series};
use crate::motion::{self, OUTPUT_HEADER};
use crate::nav::{self, BaselineConfig, Comparer, NavRecord, TruthSample};
use crate::record;
use crate::record::{ReadOptions, Record};
use crate::record_args::HolesSummary;
use crate::report::motion::MotionFigures;
use crate::report::BytesSummary;
use anyhow::{anyhow, bail, Result};
use fog_core::image::Image;
use fog_core::sensor::SensorConfig;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// What a motion replay is asked to do.
#[derive(Debug, Clone)]
pub struct MotionOptions {
    /// The drift image; None: the built-in default for `sensor` (the model of its
    /// specification alone).
    pub identifier: Option<PathBuf>,
    /// `--gyro`: the sensor without an image (with an image, it must agree).
    pub sensor: Option<SensorConfig>,
    /// `--gyro`'s `[identified]` model as an image, and what it is in words: run instead of
    /// the sensor's specification alone when there is no `identifier`.
    pub gyro_image: Option<(Image, String)>,
    /// Format, full scale and rate for decoding captures (and `t_s` without a column).
    pub stream: stream::Options,
    /// The CSV's rate column and scale and the external still flag column (`rate_hz` is
    /// `stream.rate_hz`).
    pub csv: ReadOptions,
    /// The gated Kalman filters' q, (deg/s)^2 per sample, and where it came from (e.g.
    /// `--baseline-q-dps2`).
    pub baseline_q: Option<(f64, String)>,
    /// `--validate`: records with truth on which the q is tuned ([`nav::tune_gated_q`]).
    pub validate: Vec<PathBuf>,
    /// Keep what the report's figures need ([`MotionFigures`]: bounded decimations).
    pub figures: bool,
}

/// The sensor configuration as JSON.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct SensorSummary {
    /// Full scale, deg/s.
    pub full_scale_dps: f32,
    /// One count, deg/s (0: floating point).
    pub quantum_dps: f32,
    /// Sample rate, Hz.
    pub sample_rate_hz: f32,
    /// White noise, deg/s/sqrt(Hz).
    pub noise_density_dps_rthz: f32,
    /// Drift bound, deg/h.
    pub drift_bound_dph: f32,
}

impl From<SensorConfig> for SensorSummary {
    fn from(s: SensorConfig) -> Self {
        Self {
            full_scale_dps: s.full_scale_dps,
            quantum_dps: s.quantum_dps,
            sample_rate_hz: s.sample_rate_hz,
            noise_density_dps_rthz: s.noise_density_dps_rthz,
            drift_bound_dph: s.drift_bound_dps * 3600.0,
        }
    }
}

/// What a motion replay did (`summary.json`, `--json`).
#[derive(Debug, Clone, Serialize)]
pub struct MotionSummary {
    /// Input file.
    pub input: String,
    /// Format read.
    pub format: &'static str,
    /// Output CSV.
    pub output: String,
    /// The identifier image, or the built-in default.
    pub identifier: String,
    /// Calibration runs the image's model was fitted on (0: the sensor's specification).
    pub trained_runs: u32,
    /// The sensor configuration used.
    pub sensor: SensorSummary,
    /// Where `t_s` came from.
    pub t_s_source: &'static str,
    /// Rate column and scale (CSV).
    pub rate_column: Option<String>,
    /// Factor applied to the rate column.
    pub rate_scale: f64,
    /// Rows in and out (one output row per input sample).
    pub rows: usize,
    /// Samples at or beyond the sensor's full scale (possibly saturated input).
    pub at_full_scale: usize,
    /// The record's white noise over the image's, from the median |first difference|
    /// ([`super::tally::DiffMedian::noise_ratio`]; `None`: not measurable, e.g. a coarse
    /// quantum).
    pub noise_x_image: Option<f64>,
    /// The image reads the temperature ([`uses_temperature`]) but the record has no
    /// `temp_c`: its temperature terms ran at the model's reference (off).
    pub temperature_missing: bool,
    /// Largest |rate|, deg/s.
    pub max_abs_rate_dps: f32,
    /// Rows flagged still.
    pub still_rows: usize,
    /// The variance of a window mean at rest the filter learned by the end of the record
    /// (white noise, quantization and any vibration at rest), as a white-noise density,
    /// deg/sqrt(h).
    pub noise_learned_deg_rth: f64,
    /// The image's white-noise density, deg/sqrt(h).
    pub noise_image_deg_rth: f64,
    /// Windows the filter's test found still (updates made).
    pub level_updates: u32,
    /// Updates undone because the next window failed.
    pub updates_undone: u32,
    /// Largest |drift estimate|, deg/h.
    pub max_abs_drift_dph: f64,
    /// Raw angle (integral of the rate) at the end, deg.
    pub raw_angle_end_deg: f64,
    /// Compensated angle at the end, deg.
    pub compensated_angle_end_deg: f64,
    /// DSP-3000 fault lines.
    pub fault_lines: u64,
    /// The gaps in `t_s` ([`record::Holes`]; none in a capture or a CSV without `t_s`).
    pub holes: HolesSummary,
    /// The line printed on stderr for them ([`record::Holes::warning`]), if any.
    #[serde(skip)]
    pub holes_warning: Option<String>,
    /// Byte counts of a capture.
    pub bytes: Option<BytesSummary>,
    /// Scores against the truth, identifier beside the baselines.
    pub scores: Option<nav::Comparison>,
    /// The record's result, from `scores` ([`Pooled`] over this one record): the
    /// identifier's heading-error RMS against each baseline's, the verdict against the best;
    /// printed first.
    pub result: Option<Pooled>,
    /// Scores over a set of test records beside this one (`host-sim demo`), when given.
    pub test_set: Option<TestSet>,
    /// How the image's two scales were tuned (`host-sim demo`), when they were.
    pub level_tuning: Option<crate::motion::tune::Tuning>,
    /// What the firmware does with the image (`host-sim demo`, which wrote it); absent from
    /// the JSON otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub firmware: Option<crate::firmware_fit::FirmwareFit>,
}

/// Mean scores over several test records with truth, the identifier beside the baselines
/// (`host-sim demo`: the replayed record is one draw; the set says whether its outcome is
/// typical), and the result in one verdict ([`Pooled`]).
#[derive(Debug, Clone, Serialize)]
pub struct TestSet {
    /// What the records are.
    pub records: String,
    /// Per record, heading-error RMS per estimator, deg (rows' order).
    pub heading_rms_deg: Vec<Vec<(String, f64)>>,
    /// Mean over the records per estimator, deg (rows' order).
    pub mean_heading_rms_deg: Vec<(String, f64)>,
    /// Records on which the identifier's heading-error RMS is below every baseline's.
    pub identifier_best: usize,
    /// The result: the means above against each baseline, the verdict, the count (none
    /// without a baseline).
    pub headline: Option<Pooled>,
}

impl TestSet {
    /// From per-record comparisons (the identifier first in each, as [`nav::compare`]
    /// writes them).
    pub fn new(records: String, tables: &[nav::Comparison]) -> Self {
        let per = heading_rms(tables);
        let (mean, identifier_best) = pool(&per);
        Self {
            records,
            headline: Pooled::new(&mean, per.len(), "test vehicles", identifier_best),
            heading_rms_deg: per,
            mean_heading_rms_deg: mean,
            identifier_best,
        }
    }
    /// The result first ([`Pooled::text`]), then what the records are: as printed by
    /// `host-sim demo` and in the report.
    pub fn text(&self) -> String {
        let mut text = self.headline.as_ref().map(Pooled::text).unwrap_or_default();
        text.push_str(&format!("test vehicles: {}", self.records));
        text
    }
}

/// A replay's summary and, when asked for ([`MotionOptions::figures`]), its figures'
/// decimated data (for the report).
pub struct MotionOutcome {
    /// Summary.
    pub summary: MotionSummary,
    /// The report's figures.
    pub figures: Option<MotionFigures>,
}

/// The built-in image for `sensor`: the model of its specification alone.
pub fn builtin_image(sensor: SensorConfig) -> Image {
    motion::untrained(&sensor)
}

/// The built-in sensor whose rate is `hz` (within [`fog_core::image::RATE_TOLERANCE`]):
/// E-Core 2000 (100 Hz) or KVH DSP-1750 (1 kHz); the E-Core otherwise (the rate check then
/// names the mismatch).
pub fn sensor_for_rate(hz: f32) -> SensorConfig {
    [SensorConfig::ECORE_2000, SensorConfig::KVH_DSP_1750]
        .into_iter()
        .find(|s| {
            (hz - s.sample_rate_hz).abs() <= fog_core::image::RATE_TOLERANCE * s.sample_rate_hz
        })
        .unwrap_or(SensorConfig::ECORE_2000)
}

/// The filter's release delay: its window, samples.
pub fn release_samples(image: &Image) -> usize {
    (image.config.window_s * image.model.sample_rate_hz)
        .round()
        .max(0.0) as usize
}

/// The baselines' q: `--baseline-q-dps2`, else tuned on `--validate`, else the model's level
/// noise per sample ([`motion::level_q_dps2_per_sample`]).
fn baseline_config(o: &MotionOptions, image: &Image) -> Result<BaselineConfig> {
    let r_dps2 = f64::from(image.model.sample_var_dps2());
    if let Some((q, from)) = &o.baseline_q {
        if !(q.is_finite() && *q >= 0.0) {
            bail!("{from} {q}: must be finite and >= 0");
        }
        return Ok(BaselineConfig {
            q_dps2: *q,
            q_source: from.clone(),
            r_dps2,
            release_samples: release_samples(image),
        });
    }
    if !o.validate.is_empty() {
        let files = CsvFiles::from_args(&o.validate, &ReadOptions::default())?;
        let mut recs = Vec::new();
        for i in 0..files.len() {
            let p = &files.0[i];
            let r = NavRecord::try_from(&Record::read(p, &ReadOptions::default())?)?;
            recs.push(r);
        }
        let grid = nav::log_grid(1e-18, 1e-8, 2);
        let t = nav::tune_gated_q(&recs, r_dps2, &grid)
            .ok_or_else(|| anyhow!("--validate: no record to tune on"))?;
        return Ok(BaselineConfig {
            q_dps2: t.q_dps2,
            q_source: format!(
                "tuned on {} validation records (truth still flags, grid 1e-18..1e-8, mean heading RMS {:.4} deg)",
                recs.len(),
                t.heading_rms_deg
            ),
            r_dps2,
            release_samples: release_samples(image),
        });
    }
    Ok(BaselineConfig {
        q_dps2: motion::level_q_dps2_per_sample(&image.model),
        q_source: "the image's model (rate random walk and Gauss-Markov terms)".into(),
        r_dps2,
        release_samples: release_samples(image),
    })
}

/// A record's noise this many times above or below the image's is warned about (ASSUMED:
/// 10; a family spreads 0.5x to 3x, vibration at stops adds up to about 3x more).
pub const NOISE_WARN: f64 = 10.0;

pub use crate::motion::show::uses_temperature;

/// The image `o` names (checked against `--gyro`), with its name for messages.
fn file_image(o: &MotionOptions) -> Result<Option<(Image, String)>> {
    let Some(p) = &o.identifier else {
        return Ok(None);
    };
    let im = motion::read_image(p)?;
    // The file fixes what the stream is (rate, full scale, quantum); the image's noise and
    // drift bound were learned from the calibration runs.
    let differs = |s: SensorConfig| {
        let i = motion::sensor_of(&im);
        (s.sample_rate_hz, s.full_scale_dps, s.quantum_dps)
            != (i.sample_rate_hz, i.full_scale_dps, i.quantum_dps)
    };
    if o.sensor.is_some_and(differs) {
        bail!(
            "{}: its sensor (rate, full scale, quantum) differs from --gyro's; leave --gyro out",
            p.display()
        );
    }
    Ok(Some((im, p.display().to_string())))
}

/// The image to run: `file`, else `--gyro`'s `[identified]` model, else the built-in one for
/// `--gyro`'s sensor or for the record's rate `hz`; checked against `hz`.
fn image_for(
    file: Option<(Image, String)>,
    o: &MotionOptions,
    input: &Path,
    hz: f32,
) -> Result<(Image, String)> {
    let (image, identifier) = match (file, &o.gyro_image) {
        (Some(f), _) => f,
        (None, Some(g)) => g.clone(),
        (None, None) => {
            let (sensor, how) = match o.sensor {
                Some(s) => (s, "--gyro"),
                None => (sensor_for_rate(hz), "picked by the record's rate"),
            };
            (
                builtin_image(sensor),
                format!(
                    "built-in: the sensor's specification alone (no calibration run), sensor {} Hz / {} deg/s ({how})",
                    sensor.sample_rate_hz, sensor.full_scale_dps
                ),
            )
        }
    };
    image.check_rate(hz).map_err(|e| {
        anyhow!(
            "{}: {e} ({}; give --gyro or an identifier for this rate)",
            identifier,
            input.display()
        )
    })?;
    Ok((image, identifier))
}

/// Replays `input` into `output` (atomically; nothing written on any error), streaming:
/// memory stays bounded whatever the record's length (the rate's look-ahead
/// [`input::LOOKAHEAD`], the report's decimations; module docs).
pub fn replay(input: &Path, output: &Path, o: &MotionOptions) -> Result<MotionOutcome> {
    let mut inputs = vec![input];
    if let Some(id) = &o.identifier {
        inputs.push(id);
    }
    record::refuse_overwrite_all(&inputs, &[output])?;
    let file_image = file_image(o)?;
    let decode_sensor = file_image
        .as_ref()
        .map(|f| motion::sensor_of(&f.0))
        .or(o.sensor)
        .unwrap_or(SensorConfig::ECORE_2000);
    // 0 = "the sensor's" (the command line left them out).
    let mut sopts = o.stream.clone();
    if sopts.rate_hz == 0.0 {
        sopts.rate_hz = f64::from(decode_sensor.sample_rate_hz);
    }
    if !(sopts.rate_hz.is_finite() && sopts.rate_hz > 0.0) {
        bail!("--rate-hz {}: must be finite and > 0", sopts.rate_hz);
    }
    if sopts.full_scale_dps == 0.0 {
        sopts.full_scale_dps = decode_sensor.full_scale_dps;
    }
    let mut rec = Input::open(input, &sopts, &o.csv)?;
    // A CSV without time stamps has no rate of its own: it must be stated (an identifier's
    // rate would pass the rate check below by construction, whatever the record's is).
    if rec.format == InputFormat::Csv
        && rec.t_s_from_rate
        && o.stream.rate_hz == 0.0
        && o.sensor.is_none()
    {
        bail!(
            "{}: no t_s column, so the record's sample rate is unknown: give --rate-hz HZ or --gyro NAME|FILE (the {} Hz of {} is not assumed)",
            input.display(),
            sopts.rate_hz,
            if o.identifier.is_some() { "the identifier" } else { "the default sensor" }
        );
    }
    let hz_ahead = (1.0 / rec.lookahead_period_s()?) as f32;
    let (image, identifier) = image_for(file_image, o, input, hz_ahead)?;
    let sensor = motion::sensor_of(&image);
    let mut est = motion::filter(&image, &identifier)?;
    let cols = rec.columns;
    let mut cmp = if cols.truth() {
        Some(Comparer::new(
            "motion identifier",
            cols.moving,
            baseline_config(o, &image)?,
        ))
    } else {
        None
    };
    let mut figs = o.figures.then(|| {
        let rows = cmp.as_ref().map_or(&[][..], |c| &c.labels()[..]);
        MotionFigures::new(rows, cols.moving)
    });
    let mut tally = Tally::new(sensor.full_scale_dps);
    record::write_atomic(output, |w| {
        writeln!(w, "{OUTPUT_HEADER}")?;
        while let Some(x) = rec.next_sample()? {
            let rate = x.rate_dps as f32;
            let temp = x.temp_c.map_or(f32::NAN, |t| t as f32);
            let m = motion::push_row(&mut est, rate, temp, x.still);
            writeln!(
                w,
                "{},{},{},,{},{},{}",
                tally.rows,
                x.t_s,
                rate,
                m.drift_dps,
                m.compensated_dps,
                u8::from(m.still),
            )?;
            tally.push(x.t_s, rate, &m);
            let drift = f64::from(m.drift_dps);
            let heading = cmp.as_mut().map(|c| {
                let truth = TruthSample {
                    t_s: x.t_s,
                    rate_dps: x.rate_dps,
                    temp_c: x.temp_c,
                    true_rate_dps: x.true_rate_dps.unwrap_or(f64::NAN),
                    drift_dps: x.drift_dps.unwrap_or(f64::NAN),
                    moving: x.moving.unwrap_or(false),
                };
                c.push(&truth, drift, m.still)
            });
            if let Some(f) = figs.as_mut() {
                let h = heading.as_ref().map_or(&[][..], |h| &h[..]);
                f.push(&x, drift, m.still, h);
            }
        }
        // The whole record's rate (the estimator started on the look-ahead's).
        let hz = (1.0 / rec.sample_period_s()) as f32;
        image.check_rate(hz).map_err(|e| {
            anyhow!(
                "{}: over the whole record: {e} (the first {} samples gave {hz_ahead} Hz)",
                input.display(),
                input::LOOKAHEAD
            )
        })
    })?;
    let hz = (1.0 / rec.sample_period_s()) as f32;
    let holes = rec.holes();
    let scores = cmp.map(Comparer::finish);
    let result = scores.as_ref().and_then(|c| {
        let (mean, below) = pool(&heading_rms([c]));
        Pooled::new(&mean, 1, "record", below)
    });
    let summary = MotionSummary {
        input: input.display().to_string(),
        format: rec.format.name(),
        output: output.display().to_string(),
        identifier,
        trained_runs: image.trained_runs,
        sensor: sensor.into(),
        t_s_source: rec.t_s_source,
        rate_column: (rec.format == InputFormat::Csv).then(|| o.csv.rate_column.clone()),
        rate_scale: o.csv.rate_scale,
        rows: tally.rows,
        at_full_scale: tally.at_full_scale,
        temperature_missing: !cols.temp_c && uses_temperature(&image),
        noise_x_image: tally.noise.noise_ratio(image.model.sample_var_dps2()),
        max_abs_rate_dps: tally.max_abs_rate_dps,
        still_rows: tally.still_rows,
        noise_learned_deg_rth: (f64::from(est.window_var_dps2()) * f64::from(est.window_samples())
            / f64::from(hz))
        .sqrt()
            * 60.0,
        noise_image_deg_rth: f64::from(image.model.white_dps_rthz) * 60.0,
        level_updates: est.stats().still_windows,
        updates_undone: est.stats().undone,
        max_abs_drift_dph: tally.max_abs_drift_dps * 3600.0,
        raw_angle_end_deg: tally.raw.deg(),
        compensated_angle_end_deg: tally.compensated.deg(),
        fault_lines: rec.fault_lines(),
        holes: HolesSummary::new(&input.display().to_string(), &holes),
        holes_warning: holes.warning(&input.display().to_string(), &gap_treatment(&holes)),
        bytes: rec.bytes(),
        scores,
        result,
        test_set: None,
        level_tuning: None,
        firmware: None,
    };
    Ok(MotionOutcome {
        summary,
        figures: figs,
    })
}

/// What the motion replay does with the gaps in `t_s` (the end of the line of
/// [`record::Holes::warning`]): the estimator takes the samples as evenly spaced at the
/// record's rate (it has no clock but the sample count), none dropped or interpolated, so
/// after a gap its time since power-on is behind `t_s`; the raw and compensated angles (and
/// the scores' headings) integrate the rate over the actual `t_s` steps, trapezoids, so a
/// gap is bridged by one trapezoid over its whole length (rate x actual dt, not x the
/// nominal period).
pub fn gap_treatment(h: &record::Holes) -> String {
    let angles = "the raw and compensated angles (and the scores' headings) bridge each gap with one trapezoid over its actual length (rate x actual dt)";
    if h.irregular() {
        format!("the estimator takes the samples as evenly spaced at that rate, none dropped or interpolated; {angles}")
    } else {
        format!(
            "the estimator takes the samples as evenly spaced at that rate, none dropped or interpolated (after the gaps its time since power-on runs {:.3} s behind t_s); {angles}",
            h.behind_s()
        )
    }
}

/// What to do about a record whose white noise is `k` times the image's (beyond
/// [`NOISE_WARN`]), naming the flag that fixes each cause: `--rate-scale` for a rate column
/// in another unit (`rate_scale`: the factor given), `--sensor` / `--identifier` for
/// another sensor (`builtin`: the image is the built-in one of a sensor's specification).
pub fn noise_hint(k: f64, rate_scale: f64, builtin: bool) -> String {
    const DPS_PER_RADPS: f64 = 57.29578;
    let near = |x: f64| (x - 1.0).abs() < 0.5;
    let scaled = (rate_scale / DPS_PER_RADPS - 1.0).abs() < 1e-3;
    let sensor = if builtin {
        "another sensor than the built-in one used: give the record's with --gyro NAME|FILE (its gyro file, or a built-in: ecore2000, kvh1750), or --identifier F.fogi fitted on this unit"
    } else {
        "another sensor than the identifier's: give an --identifier fitted on this unit (or, without one, --gyro NAME|FILE)"
    };
    if near(k * DPS_PER_RADPS) && !scaled {
        format!("a rate in rad/s read as deg/s? then --rate-scale 57.29578; or {sensor}")
    } else if near(k / DPS_PER_RADPS) && scaled {
        format!(
            "a rate in deg/s scaled as rad/s? then drop --rate-scale {rate_scale} (or --rate-scale 1); or {sensor}"
        )
    } else {
        format!(
            "{sensor}; or a rate column in another unit: --rate-scale K converts it to deg/s (given: {rate_scale}; 57.29578 from rad/s)"
        )
    }
}

/// The result line printed first when the record has truth ([`MotionSummary::result`]):
/// `NAME: heading error RMS: fog loses: X deg against Y deg for the best baseline (+P %),
/// BASELINE`.
pub fn result_line(s: &MotionSummary) -> Option<String> {
    s.result
        .as_ref()
        .map(|r| format!("{}: heading error RMS: {}", s.input, r.verdict_line()))
}

/// Prints the summary on stderr: the result first when the record has truth
/// ([`result_line`]), then what the replay did, the warnings, and the score table.
pub fn print_summary(s: &MotionSummary) -> Result<()> {
    let mut err = std::io::stderr().lock();
    if let Some(line) = result_line(s) {
        writeln!(err, "{line}")?;
    }
    writeln!(
        err,
        "{}: {} rows ({}) through the drift filter ({}; fitted on {} calibration runs); sensor full scale {} deg/s, {} Hz, drift bound {:.1} deg/h; {} still; noise at rest learned {:.4} deg/sqrt(h) (image {:.4}); {} still windows, {} updates undone; max |drift| {:.2} deg/h; angle at the end raw {:.4} deg, compensated {:.4} deg -> {}",
        s.input,
        s.rows,
        s.format,
        s.identifier,
        s.trained_runs,
        s.sensor.full_scale_dps,
        s.sensor.sample_rate_hz,
        s.sensor.drift_bound_dph,
        s.still_rows,
        s.noise_learned_deg_rth,
        s.noise_image_deg_rth,
        s.level_updates,
        s.updates_undone,
        s.max_abs_drift_dph,
        s.raw_angle_end_deg,
        s.compensated_angle_end_deg,
        s.output
    )?;
    if s.at_full_scale > 0 {
        writeln!(
            err,
            "{}: warning: {} samples at or beyond the sensor's full scale ({} deg/s; max |rate| {} deg/s): give the right --gyro",
            s.input, s.at_full_scale, s.sensor.full_scale_dps, s.max_abs_rate_dps
        )?;
    }
    if let Some(k) = s
        .noise_x_image
        .filter(|k| !(1.0 / NOISE_WARN..=NOISE_WARN).contains(k))
    {
        writeln!(
            err,
            "{}: warning: the record's white noise is {k:.3}x the identifier's: {}",
            s.input,
            noise_hint(k, s.rate_scale, s.trained_runs == 0)
        )?;
    }
    if s.temperature_missing {
        writeln!(
            err,
            "{}: warning: no temp_c column, but the image's model reads the temperature (its temperature links): they ran at the last temperature known (none: the reference), i.e. off; the drift follows the level and the warm-up alone",
            s.input
        )?;
    }
    if s.fault_lines > 0 {
        writeln!(
            err,
            "{}: {} DSP-3000 fault lines (no output rows)",
            s.input, s.fault_lines
        )?;
    }
    if let Some(w) = &s.holes_warning {
        writeln!(err, "{w}")?;
    }
    if let Some(c) = &s.scores {
        write!(err, "{}", nav::table(c))?;
    }
    Ok(())
}

/// One validation record's scores (`identify --preset motion --validate`).
#[derive(Debug, Clone, Serialize)]
pub struct RecordScores {
    /// The record.
    pub record: String,
    /// Identifier and baselines.
    pub scores: nav::Comparison,
    /// The gaps in its `t_s`, from the read that loaded it (the command reports them).
    #[serde(skip)]
    pub holes: record::Holes,
}

/// Scores over a set of validation records.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationScores {
    /// Per record.
    pub records: Vec<RecordScores>,
    /// Mean heading-error RMS over the records per estimator, deg (rows' order).
    pub mean_heading_rms_deg: Vec<(String, f64)>,
    /// The result: the means above against each baseline, the verdict, the count (none
    /// without a baseline).
    pub headline: Option<Pooled>,
}

/// A record with truth read whole (validation records: `identify --validate`).
pub struct TruthRecord {
    /// What the estimator runs on.
    pub series: Series,
    /// The truth.
    pub truth: NavRecord,
    /// The record has a `moving` column.
    pub moving_known: bool,
    /// The gaps in its `t_s` ([`Record::holes`]).
    pub holes: record::Holes,
}

/// The CSV record `p` at `image`'s sample rate, with its truth; refused, naming the file,
/// without truth (`true_rate_dps` and `drift_dps`) or at another rate.
pub fn read_truth_csv(image: &Image, p: &Path) -> Result<TruthRecord> {
    let rate_hz = f64::from(image.model.sample_rate_hz);
    let r = Record::read(
        p,
        &ReadOptions {
            rate_hz: Some(rate_hz),
            ..ReadOptions::default()
        },
    )?;
    if r.true_rate_dps.is_none() || r.drift_dps.is_none() {
        bail!(
            "{}: no truth (`true_rate_dps` and `drift_dps`): cannot score",
            p.display()
        );
    }
    let truth = NavRecord::try_from(&r)?;
    let hz = (1.0 / r.sample_period_s()) as f32;
    image
        .check_rate(hz)
        .map_err(|e| anyhow!("{}: {e}", p.display()))?;
    let series: Series = (&r).into();
    Ok(TruthRecord {
        holes: series.holes.unwrap_or_else(|| r.holes()),
        series,
        truth,
        moving_known: r.moving.is_some(),
    })
}

/// Runs `image` over each record with truth in `paths` (files or folders) and scores it
/// beside the baselines; the baselines' q is `baseline_q` or tuned on these records
/// ([`nav::tune_gated_q`], truth still flags). A record without truth is refused.
pub fn score_records(
    image: &Image,
    paths: &[PathBuf],
    baseline_q: Option<(f64, String)>,
) -> Result<ValidationScores> {
    let files = CsvFiles::from_args(paths, &ReadOptions::default())?;
    let mut recs = Vec::new();
    for p in &files.0 {
        recs.push((p.display().to_string(), read_truth_csv(image, p)?));
    }
    let r_dps2 = f64::from(image.model.sample_var_dps2());
    let cfg = match baseline_q {
        Some((q, from)) => BaselineConfig {
            q_dps2: q,
            q_source: from,
            r_dps2,
            release_samples: release_samples(image),
        },
        None => {
            let truths: Vec<NavRecord> = recs.iter().map(|r| r.1.truth.clone()).collect();
            let t = nav::tune_gated_q(&truths, r_dps2, &nav::log_grid(1e-18, 1e-8, 2))
                .ok_or_else(|| anyhow!("--validate: no record"))?;
            BaselineConfig {
                q_dps2: t.q_dps2,
                q_source: format!(
                    "tuned on these {} validation records (truth still flags)",
                    truths.len()
                ),
                r_dps2,
                release_samples: release_samples(image),
            }
        }
    };
    let mut out = Vec::new();
    for (name, r) in &recs {
        let mut est = motion::filter(image, name)?;
        let o = motion::run(&mut est, &r.series);
        let drift: Vec<f64> = o.iter().map(|m| f64::from(m.drift_dps)).collect();
        let still: Vec<bool> = o.iter().map(|m| m.still).collect();
        let c = nav::compare(
            &r.truth,
            "motion identifier",
            &drift,
            &still,
            r.moving_known,
            cfg.clone(),
        );
        out.push(RecordScores {
            record: name.clone(),
            scores: c.table,
            holes: r.holes,
        });
    }
    let (mean, below) = pool(&heading_rms(out.iter().map(|r| &r.scores)));
    Ok(ValidationScores {
        headline: Pooled::new(&mean, out.len(), "validation records", below),
        records: out,
        mean_heading_rms_deg: mean,
    })
}

/// Prints validation scores on stderr: the result over every record first ([`Pooled::text`]:
/// the mean heading-error RMS per estimator, the verdict against the best baseline, the
/// count), then each record's table.
pub fn print_validation(v: &ValidationScores) -> Result<()> {
    let mut err = std::io::stderr().lock();
    match &v.headline {
        Some(h) => write!(err, "{}", h.text())?,
        None => {
            writeln!(
                err,
                "mean heading error RMS over {} validation records:",
                v.records.len()
            )?;
            for (name, m) in &v.mean_heading_rms_deg {
                writeln!(err, "  {name:<50} {m:>10.4} deg")?;
            }
        }
    }
    for r in &v.records {
        writeln!(err, "{}:", r.record)?;
        write!(err, "{}", nav::table(&r.scores))?;
    }
    Ok(())
}
