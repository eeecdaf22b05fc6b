//! Overlapping Allan deviation (NIST SP 1065 eq. 11) of a rate record, its confidence
//! bounds and the fit of the IEEE Std 952 noise terms.
//!
//! The rate `y_i` (deg/s, sample period `tau0`) becomes the angle ("phase")
//! `x_0 = 0, x_{k+1} = x_k + (y_k - mean(y)) tau0` in f64 (the cumulative-sum formulation, as
//! in `allantools.frequency2phase`; removing the mean does not change the result, it keeps
//! `x` small). For `tau = m tau0`, with `N` rate samples:
//! ```text
//! AVAR(tau) = sum_{i=0}^{N-2m} (x_{i+2m} - 2 x_{i+m} + x_i)^2 / (2 tau^2 (N - 2m + 1))
//! ```
//! O(N) per tau, `1 <= m <= N/2`.
//!
//! # Taus the record supports
//! A tau is fitted only when the record holds at least [`MIN_CLUSTERS`] independent
//! (non-overlapping) clusters of that length, `N / m >= 9`: IEEE Std 952-1997 Annex C gives
//! the relative (1-sigma) error of an Allan deviation from `K` clusters as
//! `1 / sqrt(2 (K - 1))`, at most 25 % for `K >= 9`. The longer taus are computed and
//! reported (marked `supported: false`) but not fitted: their curve is too uncertain to
//! take a term from, e.g. a bias-instability floor.

pub mod band;
pub mod edf;
pub mod fit;
pub mod plot;
pub mod summary;

use anyhow::{bail, Result};
use serde::Serialize;

/// Angle (phase) series of a rate series: `N + 1` points, mean rate removed, deg.
pub fn phase_from_rate(rate: &[f64], tau0_s: f64) -> Vec<f64> {
    let n = rate.len().max(1) as f64;
    let mean = rate.iter().sum::<f64>() / n;
    let mut x = Vec::with_capacity(rate.len() + 1);
    let mut acc = 0.0f64;
    x.push(0.0);
    for &y in rate {
        acc += y - mean;
        x.push(acc * tau0_s);
    }
    x
}

/// Overlapping Allan variance at `m` from a phase series (see the module docs), with the
/// number of second differences summed; `None` unless `1 <= m` and `2m < phase.len()`.
pub fn oavar_phase(phase: &[f64], tau0_s: f64, m: usize) -> Option<(f64, usize)> {
    if m == 0 || 2 * m >= phase.len() {
        return None;
    }
    let n = phase.len() - 2 * m;
    let s: f64 = (0..n)
        .map(|i| {
            let d = phase[i + 2 * m] - 2.0 * phase[i + m] + phase[i];
            d * d
        })
        .sum();
    let tau = m as f64 * tau0_s;
    Some((s / (2.0 * n as f64 * tau * tau), n))
}

/// Independent clusters a tau must hold in the record to be fitted (module docs).
pub const MIN_CLUSTERS: usize = 9;

/// Independent (non-overlapping) clusters of the point's length in its record: `N / m`,
/// with `N` rate samples (`n_diff = N + 1 - 2m` second differences were summed).
pub fn clusters(p: &AdevPoint) -> f64 {
    let m = p.m.max(1);
    (p.n_diff + 2 * m - 1) as f64 / m as f64
}

/// Whether the record supports the point's tau ([`MIN_CLUSTERS`]).
pub fn supported(p: &AdevPoint) -> bool {
    clusters(p) >= MIN_CLUSTERS as f64
}

/// Which averaging factors `m` (tau = m tau0) to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Taus {
    /// 1, 2, 4, 8, ... (the default).
    Octave,
    /// Every m from 1 to N/2 (O(N^2) in all: slow on long records).
    All,
    /// About `n` log-spaced factors per decade (distinct integers).
    Decade(u32),
}

impl std::str::FromStr for Taus {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "octave" => Ok(Self::Octave),
            "all" => Ok(Self::All),
            _ => match s.strip_prefix("decade:").map(str::parse::<u32>) {
                Some(Ok(n)) if (1..=100).contains(&n) => Ok(Self::Decade(n)),
                _ => Err(format!(
                    "expected `octave`, `all` or `decade:N` (N in 1..=100), got {s:?}"
                )),
            },
        }
    }
}

/// Averaging factors for `n` rate samples, ascending, each with `2m <= n`.
pub fn tau_factors(n: usize, taus: Taus) -> Vec<usize> {
    let max = n / 2;
    let mut ms: Vec<usize> = match taus {
        Taus::Octave => (0..usize::BITS)
            .map(|k| 1usize << k)
            .take_while(|&m| m <= max)
            .collect(),
        Taus::All => (1..=max).collect(),
        Taus::Decade(per) => {
            let top = (max.max(1) as f64).log10();
            let k = (top * f64::from(per)).floor() as u32;
            (0..=k)
                .map(|j| 10f64.powf(f64::from(j) / f64::from(per)).round() as usize)
                .filter(|&m| m >= 1 && m <= max)
                .collect()
        }
    };
    ms.dedup();
    ms
}

/// One point of the Allan deviation curve.
#[derive(Debug, Clone, Serialize)]
pub struct AdevPoint {
    /// Averaging factor: tau = m tau0.
    pub m: usize,
    /// Averaging time, s.
    pub tau_s: f64,
    /// Overlapping Allan deviation, deg/s.
    pub adev_dps: f64,
    /// Second differences summed.
    pub n_diff: usize,
    /// Equivalent degrees of freedom ([`edf`]).
    pub edf: f64,
    /// Noise type the EDF assumed (power-law alpha: 2 white PM ... -2 random-walk FM).
    pub alpha: i32,
    /// Lower confidence bound, deg/s.
    pub adev_lower_dps: f64,
    /// Upper confidence bound, deg/s.
    pub adev_upper_dps: f64,
}

/// Allan deviations (without EDF and bounds yet) of `rate` at the factors `ms`.
pub fn oadev(rate: &[f64], tau0_s: f64, ms: &[usize]) -> Vec<AdevPoint> {
    let phase = phase_from_rate(rate, tau0_s);
    ms.iter()
        .filter_map(|&m| {
            oavar_phase(&phase, tau0_s, m).map(|(v, n)| AdevPoint {
                m,
                tau_s: m as f64 * tau0_s,
                adev_dps: v.sqrt(),
                n_diff: n,
                edf: f64::NAN,
                alpha: 0,
                adev_lower_dps: f64::NAN,
                adev_upper_dps: f64::NAN,
            })
        })
        .collect()
}

/// The whole analysis: ADEV, then fit and EDF alternately (the EDF needs the noise type at
/// each tau, taken as the dominant fitted term there; the fit weights need the EDF). Only
/// the taus the record supports ([`supported`]) are fitted; every point gets its EDF and
/// bounds.
pub fn analyse(
    rate: &[f64],
    tau0_s: f64,
    ms: &[usize],
    markov: bool,
    confidence: f64,
) -> Result<(Vec<AdevPoint>, fit::Fit)> {
    let mut pts = oadev(rate, tau0_s, ms);
    if !pts.is_empty() && pts.iter().all(|p| p.adev_dps == 0.0) {
        bail!("the Allan deviation is 0 at every tau (constant rate?): nothing to fit");
    }
    let fitted = pts.iter().filter(|p| supported(p)).count();
    if fitted < 3 {
        bail!(
            "{} samples give {} Allan points of which {fitted} hold at least {MIN_CLUSTERS} independent clusters; the fit needs at least 3 (a longer record)",
            rate.len(),
            pts.len()
        );
    }
    let n_phase = rate.len() + 1;
    for p in &mut pts {
        p.alpha = 0;
        p.edf = edf::edf_simple(n_phase, p.m, p.alpha);
    }
    let fit_on = |pts: &[AdevPoint]| {
        let used: Vec<AdevPoint> = pts.iter().filter(|p| supported(p)).cloned().collect();
        fit::fit(&used, markov)
    };
    let mut f = fit_on(&pts)?;
    for _ in 0..2 {
        for p in &mut pts {
            p.alpha = f.dominant_alpha(p.tau_s);
            p.edf = edf::edf_simple(n_phase, p.m, p.alpha);
        }
        f = fit_on(&pts)?;
    }
    for p in &mut pts {
        let (lo, hi) = edf::adev_bounds(p.adev_dps, p.edf, confidence)?;
        p.adev_lower_dps = lo;
        p.adev_upper_dps = hi;
    }
    Ok((pts, f))
}
