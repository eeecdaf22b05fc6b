//! The record the motion replay reads: an interchange CSV (any rate column, scaled; `t_s`
//! optional), or a binary / ASCII capture decoded whole, with the truth columns when the
//! record carries them.

use super::stream::{self, Decoded, InputFormat, Options};
use crate::identify::series::Series;
use crate::motion::MotionRecord;
use crate::nav::NavRecord;
use crate::record;
use crate::report::BytesSummary;
use anyhow::{anyhow, bail, Result};
use std::path::Path;

/// Where the rate is in a CSV: `rate_dps = column value * scale`.
#[derive(Debug, Clone, PartialEq)]
pub struct RateSpec {
    /// Column name (default `rate_dps`).
    pub column: String,
    /// Factor to deg/s (default 1; `1000` turns the KVH log's `dtheta_x_deg`, deg per 1-ms
    /// sample, into deg/s).
    pub scale: f64,
}

impl Default for RateSpec {
    fn default() -> Self {
        Self {
            column: "rate_dps".into(),
            scale: 1.0,
        }
    }
}

/// A record read for the motion replay.
#[derive(Debug, Clone)]
pub struct Input {
    /// What the estimator runs on.
    pub record: MotionRecord,
    /// The truth, when the record has both `true_rate_dps` and `drift_dps` (`moving`
    /// optional: without it every sample counts as still).
    pub truth: Option<NavRecord>,
    /// Format read.
    pub format: InputFormat,
    /// Where `t_s` came from.
    pub t_s_source: &'static str,
    /// `t_s` is `row index / rate_hz` (no time stamps in the input): the rate is the
    /// caller's, not the record's.
    pub t_s_from_rate: bool,
    /// Byte counts of a capture.
    pub bytes: Option<BytesSummary>,
    /// DSP-3000 fault lines (no sample, no output row).
    pub fault_lines: u64,
}

fn parse_flag(raw: &str) -> std::result::Result<Option<bool>, ()> {
    match raw.trim() {
        "" => Ok(None),
        "1" | "true" | "still" => Ok(Some(true)),
        "0" | "false" | "moving" => Ok(Some(false)),
        _ => Err(()),
    }
}

/// Reads `path`: CSV (see [`read_csv`]) or a capture decoded with `opts`.
pub fn read(
    path: &Path,
    opts: &Options,
    rate: &RateSpec,
    still_column: Option<&str>,
) -> Result<Input> {
    let is_csv = match opts.format {
        InputFormat::Csv => true,
        InputFormat::Auto => {
            let mut head = vec![0u8; 8192];
            let n = {
                use std::io::Read;
                let mut f = std::fs::File::open(path)
                    .map_err(|e| anyhow!("{}: cannot open: {e}", path.display()))?;
                f.read(&mut head)
                    .map_err(|e| anyhow!("{}: read failed at byte 0: {e}", path.display()))?
            };
            let head = &head[..n];
            !head.iter().any(|&b| b & 0x80 != 0)
                && head
                    .split(|&b| b == b'\n')
                    .next()
                    .is_some_and(|l| l.contains(&b','))
        }
        _ => false,
    };
    if is_csv {
        return read_csv(path, rate, opts.rate_hz, still_column);
    }
    if still_column.is_some() {
        bail!("--still-column needs CSV input");
    }
    let Decoded {
        format,
        t_s,
        rate_dps,
        fault_lines,
        bytes,
    } = stream::decode(path, opts)?;
    if rate_dps.is_empty() {
        bail!("{}: no sample decoded", path.display());
    }
    Ok(Input {
        record: MotionRecord {
            series: Series {
                name: path.display().to_string(),
                t_s,
                rate_dps,
                drift_dps: None,
                temp_c: None,
            },
            still: None,
            true_rate_dps: None,
        },
        truth: None,
        format,
        t_s_source: "index / rate_hz (no time stamps in the capture)",
        t_s_from_rate: true,
        bytes,
        fault_lines,
    })
}

/// Reads an interchange CSV: the rate from `rate.column` times `rate.scale`; `t_s` from its
/// column, or `row index / rate_hz` when there is none; optional `temp_c`, `drift_dps`,
/// `true_rate_dps`, `moving` (0/1) and the still flag column. Every row must parse (one-line
/// error naming file and line, nothing written).
pub fn read_csv(
    path: &Path,
    rate: &RateSpec,
    rate_hz: f64,
    still_column: Option<&str>,
) -> Result<Input> {
    let name = path.display().to_string();
    if !(rate.scale.is_finite() && rate.scale != 0.0) {
        bail!("--rate-scale {}: must be finite and not 0", rate.scale);
    }
    let (mut rdr, header) = record::csv_with_header(&name, record::open_maybe_gz(path)?)?;
    let col = |want: &str| header.iter().position(|h| h.trim() == want);
    let Some(rc) = col(&rate.column) else {
        bail!(
            "{name}:1: no column `{}` (header: {}); give --rate-column",
            rate.column,
            header.iter().collect::<Vec<_>>().join(",")
        );
    };
    let sc = match still_column {
        Some(c) => Some(col(c).ok_or_else(|| anyhow!("{name}:1: no column `{c}`"))?),
        None => None,
    };
    let (tc, cc, dc, vc, mc) = (
        col("t_s"),
        col("temp_c"),
        col("drift_dps"),
        col("true_rate_dps"),
        col("moving"),
    );
    let (mut t_s, mut rate_dps) = (Vec::new(), Vec::new());
    let mut temp = cc.map(|_| Vec::new());
    let mut drift = dc.map(|_| Vec::new());
    let mut truth = vc.map(|_| Vec::new());
    let mut still = sc.map(|_| Vec::new());
    let mut moving = Vec::new();
    let mut prev_t: Option<f64> = None;
    for (i, row) in rdr.records().enumerate() {
        let row = row.map_err(|e| anyhow!("{name}: {e}"))?;
        let line = row.position().map_or(i as u64 + 2, |p| p.line());
        let t = match tc {
            Some(c) => record::parse_field::<f64>(&row, c, "t_s", path, line)?,
            None => i as f64 / rate_hz,
        };
        if let Some(p) = prev_t {
            if t <= p {
                bail!("{name}:{line}: t_s = {t} does not increase (previous row {p})");
            }
        }
        prev_t = Some(t);
        t_s.push(t);
        let r: f64 = record::parse_field(&row, rc, &rate.column, path, line)?;
        let r = r * rate.scale;
        if !r.is_finite() || r.abs() > f64::from(f32::MAX) {
            bail!(
                "{name}:{line}: `{}` * {} is out of range",
                rate.column,
                rate.scale
            );
        }
        rate_dps.push(r as f32);
        if let (Some(c), Some(v)) = (cc, temp.as_mut()) {
            v.push(record::parse_field::<f32>(&row, c, "temp_c", path, line)?);
        }
        if let (Some(c), Some(v)) = (dc, drift.as_mut()) {
            v.push(record::parse_field::<f32>(
                &row,
                c,
                "drift_dps",
                path,
                line,
            )?);
        }
        if let (Some(c), Some(v)) = (vc, truth.as_mut()) {
            v.push(record::parse_field::<f32>(
                &row,
                c,
                "true_rate_dps",
                path,
                line,
            )?);
        }
        if let (Some(c), Some(v)) = (sc, still.as_mut()) {
            let raw = row.get(c).unwrap_or("");
            v.push(parse_flag(raw).map_err(|()| {
                anyhow!("{name}:{line}: still flag {raw:?} is not 1/0/true/false/empty")
            })?);
        }
        if let Some(c) = mc {
            moving.push(match row.get(c).unwrap_or("").trim() {
                "0" => false,
                "1" => true,
                f => bail!("{name}:{line}: `moving` = `{f}`: must be 0 or 1"),
            });
        }
    }
    if t_s.is_empty() {
        bail!("{name}: no data rows after the header");
    }
    let n = t_s.len();
    let nav = match (&truth, &drift) {
        (Some(tr), Some(d)) => Some(NavRecord {
            t_s: t_s.clone(),
            rate_dps: rate_dps.iter().map(|&r| f64::from(r)).collect(),
            temp_c: temp
                .as_ref()
                .map(|v| v.iter().map(|&c| f64::from(c)).collect()),
            true_rate_dps: tr.iter().map(|&r| f64::from(r)).collect(),
            drift_dps: d.iter().map(|&r| f64::from(r)).collect(),
            moving: if mc.is_some() { moving } else { vec![false; n] },
        }),
        _ => None,
    };
    Ok(Input {
        record: MotionRecord {
            series: Series {
                name,
                t_s,
                rate_dps,
                drift_dps: drift,
                temp_c: temp,
            },
            still,
            true_rate_dps: truth,
        },
        truth: nav,
        format: InputFormat::Csv,
        t_s_source: if tc.is_some() {
            "the CSV's t_s column"
        } else {
            "row index / rate_hz (the CSV has no t_s column)"
        },
        t_s_from_rate: tc.is_none(),
        bytes: None,
        fault_lines: 0,
    })
}
