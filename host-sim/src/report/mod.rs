//! The report of a replay (`host-sim replay --report DIR`, `host-sim demo`): the streaming
//! state it needs ([`Collector`]), the summary ([`Summary`]) and the files it writes.
//!
//! # Files (all written atomically, in `DIR`)
//! - `fig3_denoised.svg`: measured rate and its wavelet-denoised version (paper figure 3);
//! - `fig5_drift.svg`: measured rate and the identified drift, with the true drift when it
//!   is known (paper figure 5); `fig5_drift_detail.svg`: the same drifts alone, deg/h;
//! - `allan.svg`: overlapping Allan deviation of the measured rate with the fitted IEEE 952
//!   terms ([`crate::allan`]);
//! - `error_vs_truth.svg` (only when the true drift is known): identified drift minus true
//!   drift over time, with the two baselines' errors;
//! - `summary.json`: [`Summary`]; `index.html`: everything above on one page, the SVGs
//!   inlined (no external resource).
//!
//! # Bounded memory
//! Time series are decimated with [`decimate::MinMax`] (at most
//! [`decimate::DEFAULT_BUCKETS`] buckets each). The Allan deviation needs the samples
//! themselves: the measured rate of the **first [`ALLAN_MAX_SAMPLES`] samples** is kept
//! (8 MB of f64; 10 486 s at 100 Hz) and analysed at octave-spaced taus; a longer record's
//! remainder is not in the Allan plot, and the summary says so (`allan.samples_used`,
//! `allan.truncated`). The sample period of the analysis is the identifier's, `1 / rate_hz`.

pub mod decimate;
mod heading;
mod html;
pub mod motion;
mod plots;

pub use heading::{
    heading_error_svg, heading_error_svg_labelled, still_spans, tick_label, time_axis,
    HeadingSeries, Spans,
};

use crate::allan::{self, edf, Taus};
use crate::record;
use anyhow::{Context, Result};
use decimate::MinMax;
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// Samples kept for the Allan deviation (the first ones of the record): 2^20.
pub const ALLAN_MAX_SAMPLES: usize = 1 << 20;

/// Conversion deg/s -> deg/h.
pub const DPH_PER_DPS: f64 = 3600.0;

/// What the report keeps while the record streams through (bounded, see the module docs).
#[derive(Debug, Clone, Default)]
pub struct Collector {
    /// Measured rate, deg/s.
    pub measured: MinMax,
    /// Denoised rate (block by block, one block late), deg/s.
    pub denoised: MinMax,
    /// Identified drift, deg/s.
    pub drift: MinMax,
    /// True drift, deg/s (when known).
    pub truth: MinMax,
    /// Identified minus true drift, deg/h.
    pub err_identifier: MinMax,
    /// 10-s moving average minus true drift, deg/h.
    pub err_moving_average: MinMax,
    /// Random-walk Kalman filter minus true drift, deg/h.
    pub err_kalman: MinMax,
    /// Measured rate of the first [`ALLAN_MAX_SAMPLES`] samples, deg/s.
    pub allan_rate: Vec<f64>,
    /// Samples offered to the Allan buffer (kept or not).
    pub allan_seen: u64,
}

impl Collector {
    /// Keeps the measured rate for the Allan analysis while there is room.
    pub fn push_allan(&mut self, rate_dps: f32) {
        self.allan_seen += 1;
        if self.allan_rate.len() < ALLAN_MAX_SAMPLES {
            self.allan_rate.push(f64::from(rate_dps));
        }
    }
}

/// Byte and frame counts of a binary or ASCII capture ([`fog_core::frame::ByteStats`]).
#[derive(Debug, Clone, Serialize)]
pub struct BytesSummary {
    /// Bytes read.
    pub bytes_total: u64,
    /// Bytes of delivered frames or lines (fault lines included).
    pub bytes_good: u64,
    /// Bytes dropped, all reasons.
    pub bytes_dropped: u64,
    /// Bytes dropped, per reason.
    pub skipped: SkippedSummary,
    /// Good samples delivered.
    pub frames_good: u64,
    /// DSP-3000 fault lines (counted, not identified).
    pub frames_fault: u64,
    /// Frames or line segments begun and dropped.
    pub frames_bad: u64,
    /// Offset of the byte at which the decoder first dropped bytes (0-based).
    pub first_drop_at_byte: Option<u64>,
    /// The capture ends inside a frame or line: those bytes are dropped as `incomplete`.
    pub tail: Option<Tail>,
}

/// A partial frame or line at the end of a capture.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Tail {
    /// Bytes dropped.
    pub bytes: u64,
    /// Offset of its first byte (0-based).
    pub offset: u64,
}

/// [`fog_core::frame::Skipped`] as JSON.
#[derive(Debug, Clone, Serialize)]
pub struct SkippedSummary {
    /// No sync flag / before the first CR LF.
    pub no_sync: u64,
    /// E-Core checksum failures.
    pub checksum: u64,
    /// E-Core frames cut short by a sync byte.
    pub cut_short: u64,
    /// Lost to UART errors, all kinds.
    pub uart: u64,
    /// DSP-3000 malformed lines.
    pub malformed: u64,
    /// DSP-3000 bytes too far before a CR LF.
    pub too_long: u64,
    /// Partial frame or line at the end.
    pub incomplete: u64,
}

impl From<&fog_core::frame::Skipped> for SkippedSummary {
    fn from(s: &fog_core::frame::Skipped) -> Self {
        Self {
            no_sync: s.no_sync,
            checksum: s.checksum,
            cut_short: s.cut_short,
            uart: s.uart(),
            malformed: s.malformed,
            too_long: s.too_long,
            incomplete: s.incomplete,
        }
    }
}

/// Rows of an interchange CSV.
#[derive(Debug, Clone, Serialize)]
pub struct CsvSummary {
    /// Data rows read.
    pub rows: u64,
    /// Steps of `t_s` larger than [`record::GAP_FACTOR`] sample periods.
    pub gaps: u64,
    /// Largest such step, s.
    pub largest_gap_s: Option<f64>,
    /// Line (1-based, header = 1) after the largest gap.
    pub largest_gap_line: Option<u64>,
    /// Mean step of `t_s`, s.
    pub mean_step_s: Option<f64>,
    /// The gaps (against `1 / rate_hz`), for the warning line.
    #[serde(skip)]
    pub holes: record::Holes,
}

/// One figure per estimator of the drift.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PerEstimator {
    /// The on-line identifier (the firmware's).
    pub identifier: f64,
    /// Causal 10-s moving average of the measured rate (current sample included).
    pub moving_average_10s: f64,
    /// `RandomWalkKalman::new(1e-6, 1.0)`: the prediction before each sample.
    pub kalman_random_walk: f64,
}

/// Comparison with the true drift (simulated records).
#[derive(Debug, Clone, Serialize)]
pub struct TruthSummary {
    /// Where the true drift came from.
    pub source: String,
    /// Samples compared (every identified sample).
    pub samples: u64,
    /// RMS of the true drift, deg/h.
    pub rms_true_drift_dph: f64,
    /// RMS of (estimate - true drift), deg/h.
    pub rms_error_dph: PerEstimator,
    /// `e_truth = RMS(y - drift) / RMS(drift)`.
    pub e_truth: PerEstimator,
    /// The estimator with the smallest `e_truth`.
    pub best: &'static str,
}

/// The Allan analysis of the report.
#[derive(Debug, Clone, Serialize)]
pub struct AllanSummary {
    /// Samples analysed (the first ones).
    pub samples_used: u64,
    /// Whether the record was longer than [`ALLAN_MAX_SAMPLES`].
    pub truncated: bool,
    /// Sample period, s (`1 / rate_hz`).
    pub tau0_s: f64,
    /// Allan points.
    pub points: Vec<allan::AdevPoint>,
    /// Fitted terms.
    pub fit: Option<allan::fit::Fit>,
    /// Why there is no analysis, when there is none.
    pub error: Option<String>,
}

/// Everything a replay found, written as `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Input file.
    pub input: String,
    /// Its format.
    pub format: &'static str,
    /// Per-sample output CSV.
    pub output: String,
    /// Identifier configuration.
    pub preset: &'static str,
    /// Denoising block, samples.
    pub block_samples: usize,
    /// Nominal sample rate, Hz.
    pub rate_hz: f64,
    /// The identifier's sample period, s (`1 / rate_hz` rounded to f32).
    pub sample_period_s: f32,
    /// Where `t_s` comes from.
    pub t_s_source: &'static str,
    /// E-Core full scale, deg/s.
    pub full_scale_dps: Option<f32>,
    /// Samples read (DSP-3000 fault lines included).
    pub samples_read: u64,
    /// Samples the identifier took.
    pub samples_identified: u64,
    /// Samples the identifier refused (out of its range); no output row.
    pub samples_rejected: u64,
    /// DSP-3000 fault lines: counted, not identified; no output row.
    pub fault_lines: u64,
    /// Identified drift values that are not finite (the trainer diverged).
    pub drift_non_finite: u64,
    /// Denoising blocks completed.
    pub blocks: u64,
    /// Output rows.
    pub rows_written: u64,
    /// Rows of the final partial block, written with an empty `denoised_dps`.
    pub rows_without_denoised: u64,
    /// `t_s` of the first and last sample read.
    pub t_first_s: Option<f64>,
    /// See `t_first_s`.
    pub t_last_s: Option<f64>,
    /// RMS of the identifier's a-priori training errors, deg/s.
    pub rms_train_error_dps: Option<f64>,
    /// Byte accounting (binary and ASCII input).
    pub bytes: Option<BytesSummary>,
    /// Row accounting (CSV input).
    pub csv: Option<CsvSummary>,
    /// Comparison with the true drift, when known.
    pub truth: Option<TruthSummary>,
    /// Allan analysis (reports only).
    pub allan: Option<AllanSummary>,
}

/// Accumulates estimate errors against the true drift.
#[derive(Debug, Clone, Default)]
pub struct TruthAcc {
    n: u64,
    sum_sq_truth: f64,
    sum_sq_err: [f64; 3],
}

impl TruthAcc {
    /// Adds one sample: the true drift and the three estimates (identifier, moving average,
    /// Kalman), deg/s.
    pub fn add(&mut self, truth: f64, est: [f64; 3]) {
        self.n += 1;
        self.sum_sq_truth += truth * truth;
        for (s, e) in self.sum_sq_err.iter_mut().zip(est) {
            *s += (e - truth) * (e - truth);
        }
    }

    /// The figures, `None` before any sample.
    pub fn summary(&self, source: &str) -> Option<TruthSummary> {
        if self.n == 0 {
            return None;
        }
        let n = self.n as f64;
        let rms_t = (self.sum_sq_truth / n).sqrt();
        let rms = self.sum_sq_err.map(|s| (s / n).sqrt());
        let e = rms.map(|r| r / rms_t);
        let per = |v: [f64; 3], k: f64| PerEstimator {
            identifier: v[0] * k,
            moving_average_10s: v[1] * k,
            kalman_random_walk: v[2] * k,
        };
        let names = ["identifier", "moving_average_10s", "kalman_random_walk"];
        let best = (0..3)
            .min_by(|&a, &b| e[a].total_cmp(&e[b]))
            .map_or("identifier", |i| names[i]);
        Some(TruthSummary {
            source: source.to_string(),
            samples: self.n,
            rms_true_drift_dph: rms_t * DPH_PER_DPS,
            rms_error_dph: per(rms, DPH_PER_DPS),
            e_truth: per(e, 1.0),
            best,
        })
    }
}

/// Runs the Allan analysis of the collected samples.
pub fn analyse_allan(c: &Collector, rate_hz: f64) -> AllanSummary {
    let tau0_s = 1.0 / rate_hz;
    let ms = allan::tau_factors(c.allan_rate.len(), Taus::Octave);
    let (points, fit, error) =
        match allan::analyse(&c.allan_rate, tau0_s, &ms, false, edf::ONE_SIGMA) {
            Ok((p, f)) => (p, Some(f), None),
            Err(e) => (Vec::new(), None, Some(format!("{e:#}"))),
        };
    AllanSummary {
        samples_used: c.allan_rate.len() as u64,
        truncated: c.allan_seen > c.allan_rate.len() as u64,
        tau0_s,
        points,
        fit,
        error,
    }
}

pub(crate) fn write_text(path: &Path, text: &str) -> Result<()> {
    record::write_atomic(path, |w| {
        w.write_all(text.as_bytes())
            .with_context(|| format!("{}: write failed", path.display()))
    })
}

/// Writes the report into `dir` (created if missing); `summary.allan` is filled here.
/// Returns the path of `index.html`.
pub fn write(dir: &Path, summary: &mut Summary, c: &Collector) -> Result<std::path::PathBuf> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the report folder", dir.display()))?;
    let input = Path::new(&summary.input);
    let allan = analyse_allan(c, summary.rate_hz);
    let mut figures: Vec<(&str, String, &str)> = Vec::new();
    figures.push((
        "fig3_denoised.svg",
        plots::fig3(c, &summary.input)?,
        "Figure 3: measured rate and its wavelet-denoised version (db4, 3 levels, soft \
         universal threshold, blocks of 512 samples).",
    ));
    figures.push((
        "fig5_drift.svg",
        plots::fig5(c, &summary.input, summary.truth.is_some())?,
        "Figure 5: measured rate and the drift the on-line identifier outputs, sample by \
         sample, before training on that sample.",
    ));
    figures.push((
        "fig5_drift_detail.svg",
        plots::drift_detail(c, &summary.input, summary.truth.is_some())?,
        "Figure 5, detail: the identified drift alone, in deg/h (min and max per bucket, so \
         its sample-to-sample ripple shows as a band).",
    ));
    if let Some(fit) = &allan.fit {
        figures.push((
            "allan.svg",
            allan::plot::svg(
                &allan.points,
                fit,
                &format!("Allan deviation of the measured rate: {}", summary.input),
            )?,
            "Overlapping Allan deviation of the measured rate, 68 % bounds, weighted NNLS fit \
             of the IEEE 952 terms.",
        ));
    }
    if summary.truth.is_some() {
        figures.push((
            "error_vs_truth.svg",
            plots::error_vs_truth(c, &summary.input)?,
            "Identification error: estimate minus true drift, for the identifier and the two \
             causal baselines.",
        ));
    }
    summary.allan = Some(allan);
    for (name, svg, _) in &figures {
        let p = dir.join(name);
        record::refuse_overwrite(input, &p)?;
        write_text(&p, svg)?;
    }
    let json = serde_json::to_string_pretty(summary)?;
    let json_path = dir.join("summary.json");
    record::refuse_overwrite(input, &json_path)?;
    write_text(&json_path, &json)?;
    let page = html::page(summary, &figures, c)?;
    let index = dir.join("index.html");
    record::refuse_overwrite(input, &index)?;
    write_text(&index, &page)?;
    Ok(index)
}
