//! The gap in plain units, for a person: how far the real record's Allan deviation, PSD,
//! time-window means and value distribution sit from the model (in %, deg/h, at which tau,
//! frequency or time), before and after adding the named effect (the effect's parameters
//! and their 95 % intervals head the HTML report, `report.rs`).

use super::{Curves, FeatureRow};
use serde::Serialize;

/// One curve's largest departure.
#[derive(Debug, Clone, Serialize)]
pub struct Departure {
    /// `100 (real / model - 1)` where its magnitude is largest, %.
    pub percent: f64,
    /// Where: tau (s) or band centre frequency (Hz).
    pub at: f64,
    /// Unit of `at`.
    pub at_unit: &'static str,
    /// Median over the curve of `|100 (real / model - 1)|`, %.
    pub median_abs_percent: f64,
}

/// The plain-units summary.
#[derive(Debug, Clone, Serialize)]
pub struct Plain {
    /// ADEV, real vs the baseline's median simulation (whole record).
    pub adev: Option<Departure>,
    /// ADEV, real vs the baseline + named effect.
    pub adev_after: Option<Departure>,
    /// PSD in 20 log-spaced bands, real vs baseline.
    pub psd: Option<Departure>,
    /// PSD, real vs baseline + named effect.
    pub psd_after: Option<Departure>,
    /// Largest departure of a time window's mean from the model, deg/h, and the window, s.
    pub mean_offset_dph: Option<(f64, [f64; 2])>,
    /// Distribution features: real vs model (median simulation), in words.
    pub distribution: Vec<String>,
    /// One paragraph.
    pub summary: String,
}

fn departure(x: &[f64], real: &[f64], model: &[f64], unit: &'static str) -> Option<Departure> {
    let d: Vec<(f64, f64)> = x
        .iter()
        .zip(real.iter().zip(model))
        .filter(|(x, (r, m))| x.is_finite() && **x > 0.0 && r.is_finite() && **m > 0.0)
        .map(|(x, (r, m))| (100.0 * (r / m - 1.0), *x))
        .collect();
    let worst = d
        .iter()
        .copied()
        .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))?;
    let abs: Vec<f64> = d.iter().map(|v| v.0.abs()).collect();
    Some(Departure {
        percent: worst.0,
        at: worst.1,
        at_unit: unit,
        median_abs_percent: super::features::median(&abs),
    })
}

/// Band means of a PSD over `bands` log-spaced bands (DC skipped): (centre Hz, mean).
fn bands(f: &[f64], p: &[f64], bands: usize) -> (Vec<f64>, Vec<f64>) {
    let pos: Vec<(f64, f64)> = f
        .iter()
        .zip(p)
        .filter(|(f, p)| **f > 0.0 && p.is_finite())
        .map(|(f, p)| (*f, *p))
        .collect();
    let (Some(lo), Some(hi)) = (pos.first().map(|v| v.0), pos.last().map(|v| v.0)) else {
        return (Vec::new(), Vec::new());
    };
    let (llo, lhi) = (lo.ln(), hi.ln() + 1e-9);
    let mut sum = vec![(0.0, 0usize); bands];
    for (f, p) in pos {
        let k = (((f.ln() - llo) / (lhi - llo)) * bands as f64) as usize;
        let k = k.min(bands - 1);
        sum[k].0 += p;
        sum[k].1 += 1;
    }
    let centres = (0..bands)
        .map(|k| (llo + (k as f64 + 0.5) * (lhi - llo) / bands as f64).exp())
        .collect();
    let means = sum
        .iter()
        .map(|&(s, c)| if c > 0 { s / c as f64 } else { f64::NAN })
        .collect();
    (centres, means)
}

/// Builds the summary from the report curves and the full-record feature rows.
pub fn build(c: &Curves, features: &[FeatureRow], effect: &str) -> Plain {
    let adev = departure(&c.tau_s, &c.adev_real, &c.adev_base, "s");
    let adev_after = (!c.adev_after.is_empty())
        .then(|| departure(&c.tau_s, &c.adev_real, &c.adev_after, "s"))
        .flatten();
    let (fc, pr) = bands(&c.freq_hz, &c.psd_real, 20);
    let (_, pb) = bands(&c.freq_hz, &c.psd_base, 20);
    let psd = departure(&fc, &pr, &pb, "Hz");
    let psd_after = (!c.psd_after.is_empty())
        .then(|| {
            let (_, pa) = bands(&c.freq_hz, &c.psd_after, 20);
            departure(&fc, &pr, &pa, "Hz")
        })
        .flatten();
    let mean_offset_dph = features
        .iter()
        .filter_map(|f| {
            let w = f.feature.strip_prefix("mean@")?.strip_suffix('s')?;
            let (a, b) = w.split_once('-')?;
            Some((
                3600.0 * (f.real - f.sim_median),
                [a.parse().ok()?, b.parse().ok()?],
            ))
        })
        .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()));
    let distribution: Vec<String> = features
        .iter()
        .filter(|f| {
            matches!(
                f.feature.as_str(),
                "excess_kurtosis"
                    | "count_beyond_5sigma"
                    | "count_beyond_10sigma"
                    | "ks_distance_to_normal"
                    | "missing_slots"
            ) && f.z.abs() > 2.0
        })
        .map(|f| {
            format!(
                "{}: {:.3} in the record vs {:.3} +- {:.3} in the model",
                f.feature, f.real, f.sim_median, f.sim_spread
            )
        })
        .collect();
    let mut s = String::new();
    // One sentence per spectrum: where it departs most, and what is left with the effect.
    let mut sentence =
        |subject: &str, at: &str, before: &Option<Departure>, after: &Option<Departure>| {
            if let Some(a) = before {
                s.push_str(&format!(
                    "{subject} by up to {:+.0} % ({at} {:.3} {}; median {:.0} %)",
                    a.percent, a.at, a.at_unit, a.median_abs_percent
                ));
                if let Some(b) = after {
                    s.push_str(&format!(
                        ", with {effect} added by up to {:+.0} % (at {:.3} {}; median {:.0} %)",
                        b.percent, b.at, b.at_unit, b.median_abs_percent
                    ));
                }
                s.push_str(". ");
            }
        };
    sentence(
        "The Allan deviation departs from the model",
        "at tau",
        &adev,
        &adev_after,
    );
    sentence("The PSD departs", "band at", &psd, &psd_after);
    if let Some((v, [a, b])) = mean_offset_dph {
        s.push_str(&format!(
            "The largest departure of a window mean is {v:+.2} deg/h (t = {a:.0}-{b:.0} s). "
        ));
    }
    if !distribution.is_empty() {
        s.push_str(&format!("Distribution: {}.", distribution.join("; ")));
    }
    Plain {
        adev,
        adev_after,
        psd,
        psd_after,
        mean_offset_dph,
        distribution,
        summary: s.trim().to_string(),
    }
}
