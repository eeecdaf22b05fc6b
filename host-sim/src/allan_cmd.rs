//! `host-sim allan`: overlapping Allan deviation of a record, chi-square bounds, the fit of
//! the noise terms ([`crate::allan`] documents each method), JSON and an optional SVG plot.
//!
//! The sample period `tau0` comes from `t_s` (the record's stated rate is not trusted)
//! ([`sample_period`], the rule of [`record::Holes`]): the mean step with the gaps left out
//! (steps over [`record::GAP_FACTOR`] x the median, reported on stderr and in the JSON) when
//! they are rare (at most [`RARE_GAPS`] of the steps: missing data), else the mean of every
//! step (irregular or bursty stamps, where the median is not the rate: said on stderr). The
//! samples are analysed as if evenly spaced. The input (CSV, or `.csv.gz`) is read into
//! memory ([`Record`]: `t_s` and the rate, f64: 16 bytes per sample) with only those two
//! columns read.
//!
//! A record that is not static is refused with `gap`'s test
//! ([`crate::gap::not_static_series`]: a 1-s mean more than 1 deg/s from the median), unless
//! the known rotation is given (`--reference-column`, deg/s): then the residual (rate minus
//! reference) is tested and analysed. The summary ([`allan::summary`]) goes to stdout; the
//! JSON (`--json`) and the plot (`--svg`) are written when asked for.

use crate::allan::summary::round9;
use crate::allan::{self, edf, Taus};
use crate::record::{self, Holes, ReadOptions, Record};
use crate::record_args::RecordArgs;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `host-sim allan`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Interchange CSV (`t_s` and the rate column; other columns ignored), or `.csv.gz`.
    #[arg(long)]
    pub input: PathBuf,
    /// The rate column and scale, the sample rate of a record without `t_s`.
    #[command(flatten)]
    pub record: RecordArgs,
    /// JSON result to write (optional: the summary is printed on stdout either way).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Reference (true) rate column, deg/s (not scaled by `--rate-scale`), e.g. a turntable's
    /// rate: subtracted from the rate before the static test and the analysis, to analyse a
    /// record that turns. Without it a record that turns is refused (the test `gap` uses).
    #[arg(long)]
    pub reference_column: Option<String>,
    /// Log-log SVG plot to write.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Averaging times: `octave` (m = 1, 2, 4, ...), `all`, or `decade:N` (N per decade).
    #[arg(long, default_value = "octave")]
    pub taus: Taus,
    /// Try a hump term (first-order Gauss-Markov or a band) even when the IEEE 952 terms
    /// describe the curve within its statistics (without it, only when they do not).
    #[arg(long)]
    pub markov: bool,
    /// Also write the fitted terms as a gyro file (host_sim::gyro: `simulate --gyro`
    /// takes it).
    #[arg(long, alias = "save-model", value_name = "FILE")]
    pub save_gyro: Option<PathBuf>,
}

/// `t_s` and the rate of a record ([`read_series`]) with its gaps.
pub struct AllanInput {
    /// The record (`t_s`, the rate column times the scale).
    pub record: Record,
    /// Its gaps (against the median step).
    pub holes: Holes,
}

/// Steps over [`record::GAP_FACTOR`] x the median are gaps (missing data, left out of
/// `tau0`) when at most this fraction of the steps are (ASSUMED: 1 %); beyond it the stamps
/// are irregular and `tau0` is the mean of every step ([`record::RARE_GAPS`]).
pub const RARE_GAPS: f64 = record::RARE_GAPS;

/// How `tau0` was found ([`sample_period`]).
pub struct SamplePeriod {
    /// Seconds.
    pub tau0_s: f64,
    /// The method, for the JSON and stderr.
    pub method: &'static str,
    /// Median step, s.
    pub median_s: f64,
    /// The steps over the gap factor are not rare: irregular stamps, not missing data.
    pub irregular: bool,
}

/// `tau0` of a series read by [`read_series`] (module docs; [`Holes::period_s`]).
pub fn sample_period(s: &AllanInput) -> SamplePeriod {
    let h = &s.holes;
    SamplePeriod {
        tau0_s: h.period_s(),
        method: if h.irregular() {
            "mean of every t_s step (irregular stamps)"
        } else {
            "mean t_s step, gaps left out"
        },
        median_s: h.nominal_step_s,
        irregular: h.irregular(),
    }
}

/// Reads `t_s` and the rate (the rate column times the scale, deg/s) from an interchange
/// CSV or `.csv.gz` ([`Record::read`]; other columns are not read), minus the reference
/// column (deg/s) when `reference_column` names one; errors name the file and line.
pub fn read_series(
    path: &Path,
    args: &RecordArgs,
    reference_column: Option<&str>,
) -> Result<AllanInput> {
    let opts = ReadOptions {
        optional_columns: false,
        reference_column: reference_column.map(str::to_string),
        ..args.options()
    };
    let mut record = Record::read(path, &opts)?;
    if let Some(reference) = record.true_rate_dps.take() {
        for (r, t) in record.rate_dps.iter_mut().zip(&reference) {
            *r -= t;
        }
    }
    let name = path.display();
    let t_s = &record.t_s;
    if t_s.len() < 8 {
        bail!(
            "{name}: {} data rows; the Allan analysis needs at least 8",
            t_s.len()
        );
    }
    let holes = record.holes();
    Ok(AllanInput { record, holes })
}

#[derive(Serialize)]
struct Output<'a> {
    input: String,
    n_samples: usize,
    tau0_s: f64,
    tau0_method: &'static str,
    gaps: usize,
    largest_gap_s: Option<f64>,
    adev_method: &'static str,
    edf_method: &'static str,
    confidence: f64,
    fit_method: &'static str,
    reference_column: Option<&'a str>,
    min_clusters: usize,
    points: Vec<PointOut<'a>>,
    fit: &'a allan::fit::Fit,
    summary: &'a [String],
}

/// A point as written: the Allan point, how many independent clusters the record holds at
/// its tau, whether it was fitted and the fitted deviation there.
#[derive(Serialize)]
struct PointOut<'a> {
    #[serde(flatten)]
    point: &'a allan::AdevPoint,
    clusters: f64,
    supported: bool,
    fit_adev_dps: f64,
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    for out in args
        .json
        .iter()
        .chain(args.svg.as_ref())
        .chain(args.save_gyro.as_ref())
    {
        record::refuse_overwrite(&args.input, out)?;
    }
    let reference = args.reference_column.as_deref();
    let s = read_series(&args.input, &args.record, reference)?;
    let name = args.input.display().to_string();
    let period = sample_period(&s);
    let tau0_s = period.tau0_s;
    if let Some(why) =
        crate::gap::not_static_series(&s.record.t_s, &s.record.rate_dps, None, tau0_s)
    {
        let what = match reference {
            Some(c) => format!("(the rate minus `{c}`) "),
            None => String::new(),
        };
        bail!(
            "{name}: {what}{why}; the Allan analysis needs the sensor at rest (its noise alone, the test `gap` applies): cut the record to its static part, or give the known rotation as a column of reference rate in deg/s (--reference-column COL) to analyse the residual"
        );
    }
    // The rate in single precision, as the firmware holds it.
    let rate: Vec<f64> = s
        .record
        .rate_dps
        .iter()
        .map(|&v| f64::from(v as f32))
        .collect();
    let ms = allan::tau_factors(rate.len(), args.taus);
    let (points, fit) = allan::analyse(&rate, tau0_s, &ms, args.markov, edf::ONE_SIGMA)
        .with_context(|| name.clone())?;
    let summary = allan::summary::lines(&name, &points, &fit);
    let largest = s.holes.largest.map(|g| g.dt_s);
    let doc = Output {
        input: name.clone(),
        n_samples: rate.len(),
        tau0_s,
        tau0_method: period.method,
        gaps: s.holes.count as usize,
        largest_gap_s: largest,
        adev_method: "overlapping Allan deviation, NIST SP 1065 eq. 11, f64 cumulative sum (phase)",
        edf_method: "NIST SP 1065 Table 5 simple approximations (Howe/Allan/Barnes, Stein), \
                     noise type from the dominant fitted term; chi-square bounds (statrs below \
                     100 dof, Wilson-Hilferty above)",
        confidence: edf::ONE_SIGMA,
        fit_method:
            "IEEE 952 terms (and one hump: Gauss-Markov or band, when they miss the curve) on \
             AVAR of the taus with at least min_clusters independent clusters, NNLS by support \
             enumeration, weights edf/(2 model^2), 5 IRLS iterations; sigma from \
             (A^T W A)^-1 x max(1, chi2_red)",
        reference_column: reference,
        min_clusters: allan::MIN_CLUSTERS,
        points: points
            .iter()
            .map(|p| PointOut {
                point: p,
                clusters: allan::clusters(p),
                supported: allan::supported(p),
                fit_adev_dps: fit.avar(p.tau_s).sqrt(),
            })
            .collect(),
        fit: &fit,
        summary: &summary,
    };
    let svg = match &args.svg {
        Some(_) => Some(allan::plot::svg(
            &points,
            &fit,
            &format!("Allan deviation: {name}"),
        )?),
        None => None,
    };
    if let Some(path) = &args.json {
        let json = serde_json::to_string_pretty(&doc)?;
        record::write_atomic(path, |w| {
            w.write_all(json.as_bytes())
                .with_context(|| format!("{}: write failed", path.display()))
        })?;
    }
    if let (Some(path), Some(svg)) = (&args.svg, svg) {
        record::write_atomic(path, |w| {
            w.write_all(svg.as_bytes())
                .with_context(|| format!("{}: write failed", path.display()))
        })?;
    }
    if let Some(p) = &args.save_gyro {
        crate::gyro::fitted::save_allan(p, &fit, tau0_s, &args.input)?;
    }
    let mut err = std::io::stderr().lock();
    writeln!(
        err,
        "{name}: {} samples, tau0 = {} s ({}; median step {} s), {} taus{}{}",
        rate.len(),
        round9(tau0_s),
        period.method,
        round9(period.median_s),
        points.len(),
        reference.map_or(String::new(), |c| format!(", reference `{c}` subtracted")),
        args.json
            .as_ref()
            .map_or(String::new(), |p| format!(" -> {}", p.display()))
    )?;
    if let Some(w) = s.holes.warning(
        &name,
        "tau0 is that period, and the samples are analysed as if evenly spaced",
    ) {
        writeln!(err, "{w}")?;
    }
    let mut out = std::io::stdout().lock();
    for line in &summary {
        writeln!(out, "{line}")?;
    }
    Ok(())
}
