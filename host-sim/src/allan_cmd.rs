//! `host-sim allan`: overlapping Allan deviation of a record, chi-square bounds, the fit of
//! the noise terms ([`crate::allan`] documents each method), JSON and an optional SVG plot.
//!
//! The sample period `tau0` is the median step of `t_s` (the record's stated rate is not
//! trusted); gaps (steps over [`record::GAP_FACTOR`] x the median) are reported on stderr and
//! in the JSON, and the samples are analysed as if evenly spaced. The input is read into
//! memory (`t_s` f64, rate f32: 12 bytes per sample) with only those two columns kept.

use crate::allan::{self, edf, Taus};
use crate::record;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `host-sim allan`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Interchange CSV (`t_s`, `rate_dps`; other columns ignored).
    #[arg(long)]
    pub input: PathBuf,
    /// JSON result to write.
    #[arg(long)]
    pub json: PathBuf,
    /// Log-log SVG plot to write.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Averaging times: `octave` (m = 1, 2, 4, ...), `all`, or `decade:N` (N per decade).
    #[arg(long, default_value = "octave")]
    pub taus: Taus,
    /// Also fit a first-order Gauss-Markov term (sigma, T).
    #[arg(long)]
    pub markov: bool,
}

/// `t_s` and `rate_dps` of a record, validated like [`record::Record::read`] but without
/// keeping the rows.
pub struct Series {
    /// Sample times, s.
    pub t_s: Vec<f64>,
    /// Rates, deg/s.
    pub rate_dps: Vec<f32>,
    /// Gaps: (line after the gap, step in s).
    pub gaps: Vec<(u64, f64)>,
}

/// Reads `t_s` and `rate_dps` from an interchange CSV; errors name the file and line.
pub fn read_series(path: &Path) -> Result<Series> {
    let name = path.display();
    let file = std::fs::File::open(path).with_context(|| format!("{name}: cannot open"))?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(std::io::BufReader::new(file));
    let header = rdr
        .headers()
        .with_context(|| format!("{name}:1: cannot read the header"))?
        .clone();
    let col = |want: &str| header.iter().position(|h| h.trim() == want);
    let (Some(tc), Some(rc)) = (col("t_s"), col("rate_dps")) else {
        bail!(
            "{name}:1: need columns `t_s` and `rate_dps` (header: {})",
            header.iter().collect::<Vec<_>>().join(",")
        );
    };
    let mut t_s: Vec<f64> = Vec::new();
    let mut rate_dps: Vec<f32> = Vec::new();
    let mut rec = csv::StringRecord::new();
    loop {
        let more = rdr.read_record(&mut rec).map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            anyhow::anyhow!("{name}:{line}: {e}")
        })?;
        if !more {
            break;
        }
        let line = rec.position().map_or(0, |p| p.line());
        let field = |c: usize, what: &str| -> Result<f64> {
            let raw = rec
                .get(c)
                .with_context(|| format!("{name}:{line}: missing field `{what}`"))?;
            let v: f64 = raw
                .trim()
                .parse()
                .map_err(|_| anyhow::anyhow!("{name}:{line}: `{what}` is not a number: {raw:?}"))?;
            if !v.is_finite() {
                bail!("{name}:{line}: `{what}` is not finite: {raw:?}");
            }
            Ok(v)
        };
        let t = field(tc, "t_s")?;
        let r = field(rc, "rate_dps")?;
        if let Some(&prev) = t_s.last() {
            if t <= prev {
                bail!("{name}:{line}: t_s = {t} does not increase (previous row {prev})");
            }
        }
        t_s.push(t);
        rate_dps.push(r as f32);
    }
    if t_s.len() < 8 {
        bail!(
            "{name}: {} data rows; the Allan analysis needs at least 8",
            t_s.len()
        );
    }
    let med = allan::median_step_s(&t_s).with_context(|| name.to_string())?;
    let gaps = t_s
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[1] - w[0] > record::GAP_FACTOR * med)
        .map(|(i, w)| (i as u64 + 3, w[1] - w[0]))
        .collect();
    Ok(Series {
        t_s,
        rate_dps,
        gaps,
    })
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
    points: &'a [allan::AdevPoint],
    fit: &'a allan::fit::Fit,
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    for out in std::iter::once(&args.json).chain(args.svg.as_ref()) {
        record::refuse_overwrite(&args.input, out)?;
    }
    let s = read_series(&args.input)?;
    let name = args.input.display().to_string();
    let tau0_s = allan::median_step_s(&s.t_s).with_context(|| name.clone())?;
    let rate: Vec<f64> = s.rate_dps.iter().map(|&v| f64::from(v)).collect();
    let ms = allan::tau_factors(rate.len(), args.taus);
    let (points, fit) = allan::analyse(&rate, tau0_s, &ms, args.markov, edf::ONE_SIGMA)
        .with_context(|| name.clone())?;
    let largest = s
        .gaps
        .iter()
        .map(|g| g.1)
        .fold(None, |a: Option<f64>, g| Some(a.map_or(g, |a| a.max(g))));
    let doc = Output {
        input: name.clone(),
        n_samples: rate.len(),
        tau0_s,
        tau0_method: "median of the t_s steps",
        gaps: s.gaps.len(),
        largest_gap_s: largest,
        adev_method: "overlapping Allan deviation, NIST SP 1065 eq. 11, f64 cumulative sum (phase)",
        edf_method: "NIST SP 1065 Table 5 simple approximations (Howe/Allan/Barnes, Stein), \
                     noise type from the dominant fitted term; chi-square bounds (statrs below \
                     100 dof, Wilson-Hilferty above)",
        confidence: edf::ONE_SIGMA,
        fit_method:
            "IEEE 952 terms on AVAR, NNLS by support enumeration, weights edf/(2 model^2), \
                     5 IRLS iterations; sigma from (A^T W A)^-1 x max(1, chi2_red)",
        points: &points,
        fit: &fit,
    };
    let json = serde_json::to_string_pretty(&doc)?;
    let svg = match &args.svg {
        Some(_) => Some(allan::plot::svg(
            &points,
            &fit,
            &format!("Allan deviation: {name}"),
        )?),
        None => None,
    };
    record::write_atomic(&args.json, |w| {
        w.write_all(json.as_bytes())
            .with_context(|| format!("{}: write failed", args.json.display()))
    })?;
    if let (Some(path), Some(svg)) = (&args.svg, svg) {
        record::write_atomic(path, |w| {
            w.write_all(svg.as_bytes())
                .with_context(|| format!("{}: write failed", path.display()))
        })?;
    }
    let mut err = std::io::stderr().lock();
    writeln!(
        err,
        "{name}: {} samples, tau0 = {tau0_s} s (median t_s step), {} taus -> {}",
        rate.len(),
        points.len(),
        args.json.display()
    )?;
    for t in fit.terms.iter().filter(|t| t.active) {
        writeln!(
            err,
            "  {:>8} = {:.4e} {} ({:.4e} {})",
            t.symbol, t.value, t.unit, t.value_alt, t.unit_alt
        )?;
    }
    if let Some(t) = fit.gm_tau_s {
        writeln!(
            err,
            "  {:>8} = {t:.4e} s (Gauss-Markov correlation time)",
            "T_gm"
        )?;
    }
    if let Some(&(line, dt)) = s.gaps.iter().max_by(|a, b| a.1.total_cmp(&b.1)) {
        writeln!(
            err,
            "{name}: warning: {} gap(s) in t_s (step > {} x median), largest {dt:.4} s before line {line}; samples are analysed as if evenly spaced",
            s.gaps.len(),
            record::GAP_FACTOR,
        )?;
    }
    Ok(())
}
