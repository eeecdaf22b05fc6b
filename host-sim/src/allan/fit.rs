//! Weighted non-negative least-squares fit of the IEEE Std 952 noise terms on the Allan
//! variance:
//! ```text
//! AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2
//!             [+ gm_avar(sigma^2, T, tau) or + sigma_band^2 band_avar(f1, f2, tau)]
//! ```
//! Units (rate in deg/s, tau in s): Q deg (angle quantization; also arcsec), N deg/s/sqrt(Hz)
//! = deg/sqrt(s) (also deg/sqrt(h) = 60 N), B deg/s (also deg/h), K deg/s^1.5 = deg/s/sqrt(s)
//! (also deg/h/sqrt(h) = 216000 K), R deg/s^2 (also deg/h^2), Gauss-Markov sigma deg/s and
//! correlation time T s, band sigma deg/s over the band `[f1, f2]` Hz ([`super::band`]).
//!
//! # Method
//! - Unknowns: the coefficients `c = (Q^2, N^2, B^2, K^2, R^2[, sigma^2])`, linear in AVAR,
//!   constrained `c >= 0`.
//! - Weights: the variance of an AVAR estimate with `edf` degrees of freedom is
//!   `2 AVAR^2 / edf`; the model's own relative accuracy `rel` is added, so each point is
//!   weighted by `1 / (model^2 (2 / edf + rel^2))`. `rel` is 0 when all terms together fit
//!   the points within their statistics, else the value that brings the reduced chi-square
//!   to 1 ([`Fit::model_rel`]: how far the vocabulary is from the curve). `model` starts as
//!   the measured AVAR and is replaced by the fitted curve for 5 iterations (iteratively
//!   reweighted least squares, which avoids the downward bias of weighting by the data).
//! - NNLS: exact, by enumeration of the 2^5 - 1 (or 2^6 - 1) supports: the least-squares
//!   solution on each support (Householder QR on scaled columns) that is strictly positive
//!   and has the smallest weighted residual is the NNLS optimum.
//! - Term selection: a term is reported only when the data support it: the support with the
//!   lowest information criterion `chi2 / max(1, chi2_red) + SELECT_BIC_FACTOR ln(points)
//!   |support|` over every support wins, and each of its terms must make
//!   [`SELECT_MIN_SHARE`] of the fitted AVAR at some tau (else it is removed and the
//!   selection repeated). Each term's `selection` says why, with the figures.
//! - Gauss-Markov (`--markov`): T is searched on a grid of 8 points per decade spanning the
//!   taus of the curve; the best (T, support) wins. T has no error bar (grid step 33 %).
//! - A hump ([`fit`] only, not [`fit_statistical`]): when the IEEE 952 terms cannot describe
//!   the curve within its statistics (`model_rel` > 0), or with `--markov`, one hump term is
//!   tried beside them: a Gauss-Markov term (T on the grid above) or an octave band of rate
//!   noise ([`super::band`]: centre from `0.371 / last tau` to `0.354 / tau0`, so the hump
//!   peaks within the curve and the band stays below the Nyquist frequency, 8 per decade). The shape whose fit on every term has
//!   the lowest weighted cost (at the IEEE terms' `model_rel`) is kept; `model_rel` is
//!   fitted again with it and the term selection decides, the hump counting as two
//!   parameters (its size and its shape). A hump the selection drops leaves the IEEE-only
//!   fit, with the hump listed as not in the model and why.
//! - Uncertainty: the covariance of the active coefficients is `(A^T W A)^-1`, multiplied by
//!   the reduced chi-square when that exceeds 1; values get `sigma_c / (2 sqrt(c))` (delta
//!   method). Overlapping ADEV points at nearby taus are correlated, which this ignores:
//!   treat the uncertainties as optimistic. An inactive term (at the bound 0) has value 0
//!   and no uncertainty.

use super::{band, AdevPoint};
use anyhow::{bail, Result};
use serde::Serialize;

/// `2 ln 2 / pi`: Allan variance of flicker noise per unit `B^2`.
pub const FLICKER_AVAR: f64 = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI;

/// Term selection: the support (set of active terms) with the lowest information criterion
/// `chi2 / max(1, chi2_reduced) + SELECT_BIC_FACTOR ln(points) |support|` (BIC's penalty per
/// parameter, doubled because overlapping Allan points at octave taus are correlated and
/// the weights count them as independent) ...
pub const SELECT_BIC_FACTOR: f64 = 2.0;
/// ... and if it makes at least this share of the fitted AVAR at some fitted tau (a term
/// that never matters to a fifth of the curve is not a property the data show).
pub const SELECT_MIN_SHARE: f64 = 0.2;

/// Range of the term model's own relative accuracy on AVAR ([`Fit::model_rel`]), added in
/// quadrature to each point's statistical one. A real sensor's curve is not an exact sum of
/// the IEEE 952 power laws (filters, aliasing, sample-and-hold near tau0); without it, the
/// short-tau points (hundreds of thousands of degrees of freedom) outweigh the rest and a
/// mismatch there drags the fit below the long-tau points (the ADIS16405: reduced
/// chi-square 57,895 with it 0).
pub const MODEL_REL_MIN: f64 = 1e-4;
/// Upper end of that range: 100 %.
pub const MODEL_REL_MAX: f64 = 1.0;

/// A term of the noise model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// Angle quantization Q.
    Quantization,
    /// Angle random walk N.
    Arw,
    /// Bias instability B.
    BiasInstability,
    /// Rate random walk K.
    Rrw,
    /// Rate ramp R.
    RateRamp,
    /// First-order Gauss-Markov (sigma, T).
    GaussMarkov,
    /// An octave band of rate noise (sigma, centre frequency): a hump ([`super::band`]).
    Band,
}

/// A band's Allan deviation peaks near `tau = BAND_PEAK / f` (that of a sinusoid of
/// frequency `f`).
pub const BAND_PEAK: f64 = 0.371;

/// The terms always fitted, in order.
pub const BASE: [Kind; 5] = [
    Kind::Quantization,
    Kind::Arw,
    Kind::BiasInstability,
    Kind::Rrw,
    Kind::RateRamp,
];

impl Kind {
    /// AVAR of the term per unit coefficient at `tau_s` (`shape`: the GM correlation time,
    /// s, or the band's centre frequency, Hz).
    pub fn basis(self, tau_s: f64, shape: f64) -> f64 {
        match self {
            Kind::Quantization => 3.0 / (tau_s * tau_s),
            Kind::Arw => 1.0 / tau_s,
            Kind::BiasInstability => FLICKER_AVAR,
            Kind::Rrw => tau_s / 3.0,
            Kind::RateRamp => tau_s * tau_s / 2.0,
            Kind::GaussMarkov => crate::sim::gm_avar(1.0, shape, tau_s),
            Kind::Band => {
                let (lo, hi) = band::edges_hz(shape);
                band::band_avar(lo, hi, tau_s)
            }
        }
    }

    /// Power-law noise type (alpha of the frequency PSD) the term looks like at `tau_s`.
    pub fn alpha(self, tau_s: f64, shape: f64) -> i32 {
        match self {
            Kind::Quantization => 2,
            Kind::Arw => 0,
            Kind::BiasInstability => -1,
            Kind::Rrw | Kind::RateRamp => -2,
            Kind::GaussMarkov if tau_s < shape => -2,
            Kind::GaussMarkov => 0,
            // Below the band's peak its ADEV rises (like a random walk), above it falls as
            // tau^-1 (like white phase noise).
            Kind::Band if tau_s < BAND_PEAK / shape => -2,
            Kind::Band => 2,
        }
    }

    /// (symbol, unit, other unit, factor to the other unit).
    pub fn units(self) -> (&'static str, &'static str, &'static str, f64) {
        match self {
            Kind::Quantization => ("Q", "deg", "arcsec", 3600.0),
            Kind::Arw => ("N", "deg/s/sqrt(Hz)", "deg/sqrt(h)", 60.0),
            Kind::BiasInstability => ("B", "deg/s", "deg/h", 3600.0),
            Kind::Rrw => ("K", "deg/s^1.5", "deg/h/sqrt(h)", 3600.0 * 60.0),
            Kind::RateRamp => ("R", "deg/s^2", "deg/h^2", 3600.0 * 3600.0),
            Kind::GaussMarkov => ("sigma_gm", "deg/s", "deg/h", 3600.0),
            Kind::Band => ("sigma_band", "deg/s", "deg/h", 3600.0),
        }
    }
}

/// One fitted term.
#[derive(Debug, Clone, Serialize)]
pub struct Term {
    /// Which term.
    pub term: Kind,
    /// Its symbol.
    pub symbol: &'static str,
    /// Coefficient on the Allan variance (the value squared), in `unit`^2.
    pub coefficient: f64,
    /// Its standard uncertainty (`None` when the term is at the bound 0).
    pub coefficient_sigma: Option<f64>,
    /// Value (square root of the coefficient), in `unit`.
    pub value: f64,
    /// Its standard uncertainty, in `unit`.
    pub sigma: Option<f64>,
    /// Unit of `value`.
    pub unit: &'static str,
    /// Value in the other customary unit.
    pub value_alt: f64,
    /// Its uncertainty in that unit.
    pub sigma_alt: Option<f64>,
    /// The other unit.
    pub unit_alt: &'static str,
    /// Whether the term is in the selected model (coefficient > 0).
    pub active: bool,
    /// Why the term is in the model or not (the selection test's figures).
    pub selection: String,
}

/// Result of the fit.
#[derive(Debug, Clone, Serialize)]
pub struct Fit {
    /// Every fitted term (the hump, Gauss-Markov or band, only when it was tried).
    pub terms: Vec<Term>,
    /// Gauss-Markov correlation time, s (when that term is active).
    pub gm_tau_s: Option<f64>,
    /// The band's edges, Hz (when that term is active).
    pub band_hz: Option<[f64; 2]>,
    /// Weighted residual sum of squares over (points - parameters), final weights.
    pub chi2_reduced: f64,
    /// Points fitted.
    pub n_points: usize,
    /// The model's own relative accuracy on AVAR added to each point's (0: the terms fit
    /// the points within their statistics).
    pub model_rel: f64,
    /// Points the fitted curve does not follow: missed by more than [`FOLLOW_TOL`] of their
    /// deviation, or by more than [`NOT_FOLLOWED_Z`] of their statistical and model
    /// uncertainty.
    pub not_followed: Vec<Miss>,
}

/// Points further than this many standard uncertainties (statistical and
/// [`Fit::model_rel`], on log ADEV) from the fitted curve are reported as not followed.
pub const NOT_FOLLOWED_Z: f64 = 3.0;

/// Points whose fitted deviation is further than this fraction of the measured one are
/// reported as not followed, whatever their statistics (issue 43's goal: 25 %).
pub const FOLLOW_TOL: f64 = 0.25;

/// A point the fit does not follow.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Miss {
    /// Tau, s.
    pub tau_s: f64,
    /// Measured ADEV, deg/s.
    pub adev_dps: f64,
    /// Fitted ADEV, deg/s.
    pub fit_adev_dps: f64,
    /// `ln(fit / measured)` in standard uncertainties (statistical and model).
    pub z: f64,
    /// `ln(fit / measured)` in the point's statistical standard uncertainty alone.
    pub z_statistical: f64,
    /// `fit / measured - 1`.
    pub rel_error: f64,
}

impl Fit {
    /// The term `kind`, if fitted.
    pub fn get(&self, kind: Kind) -> Option<&Term> {
        self.terms.iter().find(|t| t.term == kind)
    }

    /// The shape parameter of `kind` ([`Kind::basis`]; 1 when it has none).
    fn shape(&self, kind: Kind) -> f64 {
        match kind {
            Kind::GaussMarkov => self.gm_tau_s.unwrap_or(1.0),
            Kind::Band => self.band_hz.map_or(1.0, |[lo, hi]| (lo * hi).sqrt()),
            _ => 1.0,
        }
    }

    /// Fitted AVAR of one term at `tau_s`.
    pub fn term_avar(&self, kind: Kind, tau_s: f64) -> f64 {
        self.get(kind)
            .map_or(0.0, |t| t.coefficient * kind.basis(tau_s, self.shape(kind)))
    }

    /// Fitted total AVAR at `tau_s`.
    pub fn avar(&self, tau_s: f64) -> f64 {
        self.terms
            .iter()
            .map(|t| t.coefficient * t.term.basis(tau_s, self.shape(t.term)))
            .sum()
    }

    /// Noise type of the dominant fitted term at `tau_s` (white FM when none).
    pub fn dominant_alpha(&self, tau_s: f64) -> i32 {
        self.terms
            .iter()
            .filter(|t| t.active)
            .max_by(|a, b| {
                let va = a.coefficient * a.term.basis(tau_s, self.shape(a.term));
                let vb = b.coefficient * b.term.basis(tau_s, self.shape(b.term));
                va.total_cmp(&vb)
            })
            .map_or(0, |t| t.term.alpha(tau_s, self.shape(t.term)))
    }
}

/// Best NNLS solution for one design: coefficients (all columns), covariance on the
/// support, weighted cost.
struct Solution {
    coef: Vec<f64>,
    sigma: Vec<Option<f64>>,
    cost: f64,
    active: usize,
}

/// Fits the points (their `edf` must be set), the model's own accuracy fitted
/// ([`Fit::model_rel`]): `host-sim allan` and the replay report.
pub fn fit(points: &[AdevPoint], markov: bool) -> Result<Fit> {
    fit_with(points, markov, true)
}

/// Fits the points under their statistics alone (`model_rel` 0): the gap diagnosis's
/// baseline, which compares the record with simulations of the fitted model and measures
/// the misfit itself (its decision thresholds were calibrated on this fit).
pub fn fit_statistical(points: &[AdevPoint], markov: bool) -> Result<Fit> {
    fit_with(points, markov, false)
}

fn fit_with(points: &[AdevPoint], markov: bool, fit_model_rel: bool) -> Result<Fit> {
    if !fit_model_rel {
        let problem = Problem::new(points, markov.then_some(Kind::GaussMarkov), None)?;
        let (s, t, reasons) = problem.select_terms(0.0)?;
        return Ok(problem.finish(&s, t, reasons, 0.0));
    }
    let base = Problem::new(points, None, None)?;
    let rel0 = base.fitted_model_rel()?;
    let (s, t, reasons) = base.select_terms(rel0)?;
    let mut fit = base.finish(&s, t, reasons, rel0);
    if !(rel0 > 0.0 || markov) {
        return Ok(fit);
    }
    let Some((kind, shape)) = hump_search(points, rel0)? else {
        return Ok(fit);
    };
    let mut p = Problem::new(points, Some(kind), Some(vec![shape]))?;
    p.hump_params = 2;
    let rel1 = p.fitted_model_rel()?;
    let (s, t, mut reasons) = p.select_terms(rel1)?;
    let what = describe_shape(kind, shape);
    let hump = BASE.len();
    if s.coef[hump] > 0.0 {
        if let Some(r) = reasons[hump].as_mut() {
            *r = format!(
                "{what}: {r} (the hump counts as 2 terms: size and shape); model uncertainty {:.1} % with it, {:.1} % without it",
                100.0 * rel1,
                100.0 * rel0
            );
        }
        return Ok(p.finish(&s, t, reasons, rel1));
    }
    let why = reasons[hump]
        .take()
        .unwrap_or_else(|| "at the bound 0 in the NNLS fit".into());
    fit.terms.push(term(
        kind,
        0.0,
        None,
        1.0,
        Some(format!(
            "tried ({}); best shape {what}; {why}",
            if rel0 > 0.0 {
                "the IEEE 952 terms miss the curve beyond its statistics"
            } else {
                "--markov"
            }
        )),
    ));
    Ok(fit)
}

/// The hump shape in words: `Gauss-Markov T = 3.2 s` or `band 2.1-4.2 Hz`.
fn describe_shape(kind: Kind, shape: f64) -> String {
    match kind {
        Kind::Band => {
            let (lo, hi) = band::edges_hz(shape);
            format!(
                "band {lo:.3}-{hi:.3} Hz (ADEV peak near tau {:.4} s)",
                BAND_PEAK / shape
            )
        }
        _ => format!("Gauss-Markov T = {shape:.4} s"),
    }
}

/// The hump shape (kind and [`Kind::basis`] shape) whose fit on every term at model accuracy
/// `rel` has the lowest weighted cost with the hump active; `None` when no shape makes the
/// hump active. Gauss-Markov: T on [`gm_grid_s`]; band: centre on [`band_grid_hz`].
fn hump_search(points: &[AdevPoint], rel: f64) -> Result<Option<(Kind, f64)>> {
    let n = points.len();
    let (first, last) = (points[0].tau_s, points[n - 1].tau_s);
    let tau0 = first / points[0].m.max(1) as f64;
    let mut best: Option<(Kind, f64, f64)> = None;
    for (kind, grid) in [
        (Kind::GaussMarkov, gm_grid_s(first, last)),
        (Kind::Band, band_grid_hz(tau0, last)),
    ] {
        for shape in grid {
            let p = Problem::new(points, Some(kind), Some(vec![shape]))?;
            let Ok(r) = p.irls(p.all_terms(), rel) else {
                continue;
            };
            let s = r.solution;
            if s.coef[BASE.len()] > 0.0 && best.is_none_or(|b| s.cost < b.2) {
                best = Some((kind, shape, s.cost));
            }
        }
    }
    Ok(best.map(|(k, x, _)| (k, x)))
}

/// Band centres tried, Hz: from `BAND_PEAK / last_tau_s` (a hump that peaks at the
/// curve's last tau) to `0.354 / tau0_s` (the octave's top at the Nyquist frequency, the
/// peak near the first tau), evenly in log, 8 per decade; empty when that range is empty.
fn band_grid_hz(tau0_s: f64, last_tau_s: f64) -> Vec<f64> {
    let (lo, hi) = ((BAND_PEAK / last_tau_s).log10(), (0.354 / tau0_s).log10());
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Vec::new();
    }
    let k = ((hi - lo) * 8.0).ceil().max(1.0) as usize;
    (0..=k)
        .map(|j| 10f64.powf(lo + (hi - lo) * j as f64 / k as f64))
        .collect()
}

/// The reported term `kind` from its fitted coefficient `c` (in its unit squared), the
/// coefficient's standard uncertainty `sc` before inflation, the factor `inflate` on that
/// uncertainty (`sqrt(max(1, chi2_reduced))`) and its selection reason (`None`: the term
/// took no part in a selection round).
fn term(kind: Kind, c: f64, sc: Option<f64>, inflate: f64, reason: Option<String>) -> Term {
    let (symbol, unit, unit_alt, factor) = kind.units();
    let sc = sc.map(|v| v * inflate);
    let value = c.sqrt();
    let sigma = sc.map(|v| if c > 0.0 { v / (2.0 * value) } else { v.sqrt() });
    Term {
        term: kind,
        symbol,
        coefficient: c,
        coefficient_sigma: sc,
        value,
        sigma,
        unit,
        value_alt: value * factor,
        sigma_alt: sigma.map(|v| v * factor),
        unit_alt,
        active: c > 0.0,
        selection: if c > 0.0 {
            reason.unwrap_or_else(|| "kept (the only active term)".into())
        } else {
            reason.unwrap_or_else(|| "at the bound 0 in the NNLS fit".into())
        },
    }
}

/// The points `fit` does not follow: the fitted deviation more than [`FOLLOW_TOL`] from
/// the measured one, or `ln(fitted / measured ADEV)` beyond [`NOT_FOLLOWED_Z`] standard
/// uncertainties (statistical and [`Fit::model_rel`]).
fn not_followed(fit: &Fit, points: &[AdevPoint]) -> Vec<Miss> {
    points
        .iter()
        .filter_map(|p| {
            let model = fit.avar(p.tau_s).sqrt();
            // ADEV's relative sigma is half the AVAR's.
            let stat = 0.5 * (2.0 / p.edf).sqrt();
            let rel = 0.5 * (2.0 / p.edf + fit.model_rel * fit.model_rel).sqrt();
            let ln = (model / p.adev_dps).ln();
            let z = ln / rel;
            let rel_error = model / p.adev_dps - 1.0;
            let missed = z.abs() > NOT_FOLLOWED_Z || rel_error.abs() > FOLLOW_TOL;
            (missed && z.is_finite()).then_some(Miss {
                tau_s: p.tau_s,
                adev_dps: p.adev_dps,
                fit_adev_dps: model,
                z,
                z_statistical: ln / stat,
                rel_error,
            })
        })
        .collect()
}

/// Gauss-Markov correlation times tried, s: from `first_tau_s` to `last_tau_s` evenly
/// spaced in log, steps of at most 1/8 decade (at least 2 points).
fn gm_grid_s(first_tau_s: f64, last_tau_s: f64) -> Vec<f64> {
    let (lo, hi) = (first_tau_s.log10(), last_tau_s.log10());
    let k = ((hi - lo) * 8.0).ceil().max(1.0) as usize;
    (0..=k)
        .map(|j| 10f64.powf(lo + (hi - lo) * j as f64 / k as f64))
        .collect()
}

/// What every fit of one Allan curve shares: the points, their AVAR, the terms and the
/// Gauss-Markov correlation times tried. Terms are addressed by their column `j` in
/// `kinds`, sets of terms (supports) by bit masks of those columns.
struct Problem<'a> {
    points: &'a [AdevPoint],
    /// Tau of each point, s.
    tau_s: Vec<f64>,
    /// Measured AVAR of each point, (deg/s)^2.
    avar: Vec<f64>,
    /// The terms fitted, in column order.
    kinds: Vec<Kind>,
    /// The hump's shapes tried ([`Kind::basis`]: Gauss-Markov correlation times, s, or band
    /// centres, Hz; `[1.0]`, unused, without a hump).
    shapes: Vec<f64>,
    /// The design of each shape ([`Self::columns`]).
    designs: Vec<Vec<Vec<f64>>>,
    /// Parameters the hump counts for in the information criterion (1: its size, the
    /// statistical fit's Gauss-Markov; 2: its size and its searched shape).
    hump_params: usize,
    /// Lower bound of a model AVAR used as a weight or a share's denominator, (deg/s)^2:
    /// 1e-30 of the largest measured AVAR.
    floor: f64,
}

/// An IRLS fit on a set of allowed terms.
struct Reweighted {
    /// The NNLS solution of the last iteration.
    solution: Solution,
    /// Its hump shape: an index of the grid.
    shape: usize,
    /// The weights it was solved with, 1 / (deg/s)^4.
    weights: Vec<f64>,
}

/// The figures of one round of the term selection.
struct Round {
    /// Reduced chi-square of the fit on every allowed term, at least 1.
    chi2_red: f64,
    /// Each allowed support's NNLS fit: (terms active in it, information criterion).
    ics: Vec<(u32, f64)>,
    /// Terms of the fit with the lowest information criterion.
    best_support: u32,
    /// That information criterion.
    best_ic: f64,
}

impl<'a> Problem<'a> {
    /// The problem of `points` (their `edf` set), with the hump term `hump` when given
    /// (its shapes `shapes`, by default the Gauss-Markov grid over the curve's taus);
    /// refuses fewer than 3 points and a curve that is 0 at every tau.
    fn new(points: &'a [AdevPoint], hump: Option<Kind>, shapes: Option<Vec<f64>>) -> Result<Self> {
        let n = points.len();
        if n < 3 {
            bail!("the fit needs at least 3 Allan points, got {n}");
        }
        let tau_s: Vec<f64> = points.iter().map(|p| p.tau_s).collect();
        let avar: Vec<f64> = points.iter().map(|p| p.adev_dps * p.adev_dps).collect();
        if avar.iter().all(|&v| v == 0.0) {
            bail!("the Allan deviation is 0 at every tau (constant rate?): nothing to fit");
        }
        let mut kinds: Vec<Kind> = BASE.to_vec();
        kinds.extend(hump);
        let shapes = match (hump, shapes) {
            (Some(_), Some(shapes)) if !shapes.is_empty() => shapes,
            (Some(_), _) => gm_grid_s(tau_s[0], tau_s[n - 1]),
            (None, _) => vec![1.0],
        };
        let floor = avar.iter().cloned().fold(0.0, f64::max) * 1e-30;
        let designs = shapes
            .iter()
            .map(|&t| Self::columns(&kinds, &tau_s, t))
            .collect();
        Ok(Self {
            points,
            tau_s,
            avar,
            kinds,
            shapes,
            designs,
            hump_params: 1,
            floor,
        })
    }

    /// The reported fit from the selected solution `s` (its hump shape `shape`, each term's
    /// selection reason) at model accuracy `model_rel`.
    fn finish(
        &self,
        s: &Solution,
        shape: f64,
        reasons: Vec<Option<String>>,
        model_rel: f64,
    ) -> Fit {
        let n = self.points.len();
        let hump = self.kinds.get(BASE.len()).copied();
        let hump_active = hump.is_some() && s.coef.last().is_some_and(|&c| c > 0.0);
        let params = s.active + usize::from(hump_active);
        let chi2_reduced = if n > params {
            s.cost / (n - params) as f64
        } else {
            f64::NAN
        };
        let inflate = if chi2_reduced.is_finite() {
            chi2_reduced.max(1.0).sqrt()
        } else {
            1.0
        };
        let terms = self
            .kinds
            .iter()
            .zip(s.coef.iter().zip(&s.sigma))
            .zip(reasons)
            .map(|((&kind, (&c, &sc)), reason)| term(kind, c, sc, inflate, reason))
            .collect();
        let mut fit = Fit {
            terms,
            gm_tau_s: (hump_active && hump == Some(Kind::GaussMarkov)).then_some(shape),
            band_hz: (hump_active && hump == Some(Kind::Band)).then(|| {
                let (lo, hi) = band::edges_hz(shape);
                [lo, hi]
            }),
            chi2_reduced,
            n_points: n,
            model_rel,
            not_followed: Vec::new(),
        };
        fit.not_followed = not_followed(&fit, self.points);
        fit
    }

    /// Every term's bit.
    fn all_terms(&self) -> u32 {
        (1 << self.kinds.len()) - 1
    }

    /// The design for the hump shape `shape`: each term's AVAR per unit coefficient at
    /// every tau.
    fn columns(kinds: &[Kind], tau_s: &[f64], shape: f64) -> Vec<Vec<f64>> {
        kinds
            .iter()
            .map(|k| tau_s.iter().map(|&x| k.basis(x, shape)).collect())
            .collect()
    }

    /// Each point's weight for the model AVAR `model` and the model accuracy `rel`:
    /// `1 / (model^2 (2 / edf + rel^2))`.
    fn weights(&self, model: &[f64], rel: f64) -> Vec<f64> {
        self.points
            .iter()
            .zip(model)
            .map(|(p, &m)| {
                // rel 0: the statistical weight in its own form (bit for bit the gap
                // baseline's calibration).
                if rel == 0.0 {
                    p.edf / (2.0 * m * m)
                } else {
                    1.0 / (m * m * (2.0 / p.edf + rel * rel))
                }
            })
            .collect()
    }

    /// Fitted AVAR at every tau of the coefficients `coef` on the design of shape
    /// `shape` (an index of the grid), at least the floor.
    fn model_avar(&self, coef: &[f64], shape: usize) -> Vec<f64> {
        let cols = &self.designs[shape];
        (0..self.tau_s.len())
            .map(|i| {
                cols.iter()
                    .zip(coef)
                    .map(|(col, c)| c * col[i])
                    .sum::<f64>()
                    .max(self.floor)
            })
            .collect()
    }

    /// IRLS on the `allowed` terms at model accuracy `rel`: 5 iterations, the first
    /// weighted by the measured AVAR, the next by the previous fit; each picks the
    /// Gauss-Markov correlation time of the grid with the lowest cost.
    fn irls(&self, allowed: u32, rel: f64) -> Result<Reweighted> {
        let mut model: Vec<f64> = self.avar.iter().map(|&v| v.max(self.floor)).collect();
        let mut best: Option<Reweighted> = None;
        for _ in 0..5 {
            let w = self.weights(&model, rel);
            best = None;
            for (k, cols) in self.designs.iter().enumerate() {
                if let Some(s) = nnls(cols, &self.avar, &w, allowed) {
                    if best.as_ref().is_none_or(|b| s.cost < b.solution.cost) {
                        best = Some(Reweighted {
                            solution: s,
                            shape: k,
                            weights: w.clone(),
                        });
                    }
                }
            }
            let Some(b) = &best else {
                bail!("the least-squares fit failed (no positive solution)");
            };
            model = self.model_avar(&b.solution.coef, b.shape);
        }
        best.ok_or_else(|| anyhow::anyhow!("the least-squares fit failed"))
    }

    /// Reduced chi-square of the fit on every term at model accuracy `rel`.
    fn chi2_reduced_at(&self, rel: f64) -> Result<f64> {
        let full = self.irls(self.all_terms(), rel)?.solution;
        Ok(full.cost / self.points.len().saturating_sub(full.active).max(1) as f64)
    }

    /// The model's own relative accuracy on AVAR ([`Fit::model_rel`]): 0 when every term
    /// together fits the points within their statistics (reduced chi-square <= 1), else
    /// the value that brings the reduced chi-square to 1 (bisection on a log scale,
    /// [`MODEL_REL_MIN`] .. [`MODEL_REL_MAX`], 40 steps; [`MODEL_REL_MAX`] when the
    /// reduced chi-square is still above 1 there).
    fn fitted_model_rel(&self) -> Result<f64> {
        if self.chi2_reduced_at(0.0)? <= 1.0 {
            return Ok(0.0);
        }
        if self.chi2_reduced_at(MODEL_REL_MAX)? > 1.0 {
            return Ok(MODEL_REL_MAX);
        }
        let (mut lo, mut hi) = (MODEL_REL_MIN.ln(), MODEL_REL_MAX.ln());
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if self.chi2_reduced_at(mid.exp())? > 1.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Ok(hi.exp())
    }

    /// Term selection by an information criterion over every support, on the full fit's
    /// weights: `IC(S) = cost(S) / max(1, chi2_red) + SELECT_BIC_FACTOR ln(points) |S|`;
    /// the support with the lowest IC wins; a winning term that never reaches
    /// [`SELECT_MIN_SHARE`] of the fitted AVAR is removed and the selection repeated.
    /// Returns the selected fit, its Gauss-Markov correlation time (s) and each term's
    /// selection reason (`None` for a term never judged).
    fn select_terms(&self, model_rel: f64) -> Result<(Solution, f64, Vec<Option<String>>)> {
        let mut allowed = self.all_terms();
        let mut reasons: Vec<Option<String>> = vec![None; self.kinds.len()];
        loop {
            let full = self.irls(allowed, model_rel)?;
            let t = self.shapes[full.shape];
            let cols = &self.designs[full.shape];
            let Some(round) = self.selection_round(&full, cols, allowed) else {
                return Ok((full.solution, t, reasons));
            };
            let sel = self.irls(round.best_support, model_rel)?.solution;
            match self.judge_terms(&round, &sel, cols, allowed, &mut reasons) {
                Some(j) => allowed = round.best_support & !(1 << j),
                None => return Ok((sel, t, reasons)),
            }
        }
    }

    /// The information criterion of the NNLS fit on every support within `allowed`, with
    /// the weights of `full` (the IRLS fit on all of them) and the design `cols` at its
    /// Gauss-Markov correlation time; `None` when no support has a positive solution.
    fn selection_round(&self, full: &Reweighted, cols: &[Vec<f64>], allowed: u32) -> Option<Round> {
        let n = self.points.len();
        let active = full.solution.active;
        let chi2_red = if n > active {
            (full.solution.cost / (n - active) as f64).max(1.0)
        } else {
            1.0
        };
        let penalty = SELECT_BIC_FACTOR * (n as f64).ln();
        let hump = BASE.len();
        let ic = |x: &Solution| {
            let extra = if x.coef.get(hump).is_some_and(|&c| c > 0.0) {
                self.hump_params - 1
            } else {
                0
            };
            x.cost / chi2_red + penalty * (x.active + extra) as f64
        };
        let mut ics: Vec<(u32, f64)> = Vec::new();
        for mask in 1..=self.all_terms() {
            if mask & !allowed != 0 {
                continue;
            }
            if let Some(x) = nnls(cols, &self.avar, &full.weights, mask) {
                let sup = (0..self.kinds.len())
                    .filter(|&j| x.coef[j] > 0.0)
                    .fold(0u32, |m, j| m | (1 << j));
                ics.push((sup, ic(&x)));
            }
        }
        let &(best_support, best_ic) = ics.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
        Some(Round {
            chi2_red,
            ics,
            best_support,
            best_ic,
        })
    }

    /// Writes the selection reason of every `allowed` term for `round`, whose winning
    /// support refitted is `sel` (design `cols`); returns the last term of that support
    /// that never reaches [`SELECT_MIN_SHARE`] of the fitted AVAR, if any.
    fn judge_terms(
        &self,
        round: &Round,
        sel: &Solution,
        cols: &[Vec<f64>],
        allowed: u32,
        reasons: &mut [Option<String>],
    ) -> Option<usize> {
        let n = self.points.len();
        let (chi2_red, best_ic) = (round.chi2_red, round.best_ic);
        let total: Vec<f64> = (0..n)
            .map(|i| {
                (0..self.kinds.len())
                    .map(|j| sel.coef[j] * cols[j][i])
                    .sum::<f64>()
            })
            .collect();
        let mut weak = None;
        for j in 0..self.kinds.len() {
            if allowed & (1 << j) == 0 {
                continue;
            }
            if round.best_support & (1 << j) != 0 {
                let without_j = lowest_ic(&round.ics, |m| m & (1 << j) == 0);
                let (share, at) = self.largest_share(sel.coef[j], &cols[j], &total);
                let why = format!(
                    "IC without it higher by {:.1} (IC = chi2 / max(1, chi2_red = {chi2_red:.2}) + {SELECT_BIC_FACTOR} ln({n}) per term); largest share of the fitted AVAR {:.0} % at tau {at:.4} s (minimum {:.0} %)",
                    without_j - best_ic,
                    100.0 * share,
                    100.0 * SELECT_MIN_SHARE
                );
                if share < SELECT_MIN_SHARE {
                    weak = Some(j);
                    reasons[j] = Some(format!("dropped (too small to matter): {why}"));
                } else {
                    reasons[j] = Some(format!("kept: {why}"));
                }
            } else {
                let with_j = lowest_ic(&round.ics, |m| m & (1 << j) != 0);
                reasons[j] = Some(format!(
                    "not supported by the data: the lowest IC with it is higher by {:.1} (IC = chi2 / max(1, chi2_red = {chi2_red:.2}) + {SELECT_BIC_FACTOR} ln({n}) per term)",
                    with_j - best_ic
                ));
            }
        }
        weak
    }

    /// A term's largest share of the fitted AVAR `total` over the taus, and the tau (s)
    /// where it is reached (the first such; `(0, 0)` when the share is never positive),
    /// for its coefficient `coef` and design column `col`.
    fn largest_share(&self, coef: f64, col: &[f64], total: &[f64]) -> (f64, f64) {
        (0..self.points.len())
            .map(|i| (coef * col[i] / total[i].max(self.floor), self.tau_s[i]))
            .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
    }
}

/// The lowest information criterion among the fits whose active terms satisfy `keep`
/// (infinity when none does).
fn lowest_ic(ics: &[(u32, f64)], keep: impl Fn(u32) -> bool) -> f64 {
    ics.iter()
        .filter(|(m, _)| keep(*m))
        .map(|x| x.1)
        .fold(f64::INFINITY, f64::min)
}

/// Exact NNLS by enumerating supports (see the module docs).
fn nnls(cols: &[Vec<f64>], b: &[f64], w: &[f64], allowed: u32) -> Option<Solution> {
    let p = cols.len();
    let mut best: Option<Solution> = None;
    for mask in 1u32..(1 << p) {
        if mask & !allowed != 0 {
            continue;
        }
        let support: Vec<usize> = (0..p).filter(|j| mask & (1 << j) != 0).collect();
        let sub: Vec<&[f64]> = support.iter().map(|&j| cols[j].as_slice()).collect();
        let Some((x, cov)) = weighted_lstsq(&sub, b, w) else {
            continue;
        };
        if x.iter().any(|&v| v <= 0.0 || !v.is_finite()) {
            continue;
        }
        let cost: f64 = (0..b.len())
            .map(|i| {
                let fit: f64 = sub.iter().zip(&x).map(|(c, xj)| c[i] * xj).sum();
                w[i] * (b[i] - fit).powi(2)
            })
            .sum();
        if best.as_ref().is_none_or(|s| cost < s.cost) {
            let mut coef = vec![0.0; p];
            let mut sigma = vec![None; p];
            for (k, &j) in support.iter().enumerate() {
                coef[j] = x[k];
                sigma[j] = Some(cov[k].sqrt());
            }
            best = Some(Solution {
                coef,
                sigma,
                cost,
                active: support.len(),
            });
        }
    }
    best
}

/// Weighted least squares `min sum w_i (b_i - sum_j x_j a_j[i])^2` by Householder QR on
/// unit-norm columns: the solution and the variances `diag((A^T W A)^-1)`; `None` when the
/// columns are (numerically) dependent.
fn weighted_lstsq(cols: &[&[f64]], b: &[f64], w: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = b.len();
    let p = cols.len();
    if n < p {
        return None;
    }
    let sw: Vec<f64> = w.iter().map(|v| v.sqrt()).collect();
    let mut scale = vec![0.0; p];
    // a[j][i]: column-major copy, weighted and scaled to unit norm.
    let mut a: Vec<Vec<f64>> = Vec::with_capacity(p);
    for (j, c) in cols.iter().enumerate() {
        let col: Vec<f64> = c.iter().zip(&sw).map(|(x, s)| x * s).collect();
        let norm = col.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            return None;
        }
        scale[j] = norm;
        a.push(col.iter().map(|v| v / norm).collect());
    }
    let mut y: Vec<f64> = b.iter().zip(&sw).map(|(v, s)| v * s).collect();
    for k in 0..p {
        let alpha = {
            let norm = a[k][k..].iter().map(|v| v * v).sum::<f64>().sqrt();
            if a[k][k] > 0.0 {
                -norm
            } else {
                norm
            }
        };
        let mut v: Vec<f64> = a[k][k..].to_vec();
        v[0] -= alpha;
        let vnorm2: f64 = v.iter().map(|x| x * x).sum();
        if vnorm2 > 0.0 {
            let apply = |col: &mut [f64]| {
                let d: f64 = col.iter().zip(&v).map(|(x, vi)| x * vi).sum::<f64>() * 2.0 / vnorm2;
                for (x, vi) in col.iter_mut().zip(&v) {
                    *x -= d * vi;
                }
            };
            for col in a.iter_mut().skip(k) {
                apply(&mut col[k..]);
            }
            apply(&mut y[k..]);
        }
    }
    // R is a[j][i] for i <= j.
    let rmax = (0..p).map(|j| a[j][j].abs()).fold(0.0, f64::max);
    if (0..p).any(|j| a[j][j].abs() <= 1e-10 * rmax) {
        return None;
    }
    let mut x = vec![0.0; p];
    for i in (0..p).rev() {
        let s: f64 = (i + 1..p).map(|j| a[j][i] * x[j]).sum();
        x[i] = (y[i] - s) / a[i][i];
    }
    // Rinv (upper triangular), then diag(Rinv Rinv^T).
    let mut rinv = vec![vec![0.0; p]; p];
    for j in 0..p {
        rinv[j][j] = 1.0 / a[j][j];
        for i in (0..j).rev() {
            let s: f64 = (i + 1..=j).map(|k| a[k][i] * rinv[k][j]).sum();
            rinv[i][j] = -s / a[i][i];
        }
    }
    let var: Vec<f64> = (0..p)
        .map(|i| (i..p).map(|j| rinv[i][j].powi(2)).sum::<f64>() / (scale[i] * scale[i]))
        .collect();
    let x = x.iter().zip(&scale).map(|(v, s)| v / s).collect();
    Some((x, var))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(f: impl Fn(f64) -> f64) -> Vec<AdevPoint> {
        (0..16)
            .map(|k| {
                let tau = 0.01 * 2f64.powi(k);
                AdevPoint {
                    m: 1 << k,
                    tau_s: tau,
                    adev_dps: f(tau).sqrt(),
                    n_diff: 1000,
                    edf: 100.0,
                    alpha: 0,
                    adev_lower_dps: 0.0,
                    adev_upper_dps: 0.0,
                }
            })
            .collect()
    }

    #[test]
    fn exact_curve_is_recovered() {
        // Every term well above the selection's minimum share of the Allan variance somewhere.
        let (q, n, b, k) = (1e-4, 1e-3, 3e-4, 2e-5);
        let pts =
            points(|t| 3.0 * q * q / (t * t) + n * n / t + FLICKER_AVAR * b * b + k * k * t / 3.0);
        let f = fit(&pts, false).expect("fit");
        for (kind, want) in [
            (Kind::Quantization, q),
            (Kind::Arw, n),
            (Kind::BiasInstability, b),
            (Kind::Rrw, k),
        ] {
            let got = f.get(kind).map_or(0.0, |t| t.value);
            assert!((got / want - 1.0).abs() < 1e-6, "{kind:?}: {got} vs {want}");
        }
        assert_eq!(f.get(Kind::RateRamp).map(|t| t.active), Some(false));
    }

    #[test]
    fn band_term_is_found_when_the_ieee_terms_miss_the_curve() {
        // White noise and an octave band at 3 Hz: a hump near tau 0.12 s.
        let (lo, hi) = band::edges_hz(3.0);
        let pts = points(|t| 1e-6 / t + 1e-4 * band::band_avar(lo, hi, t));
        let f = fit(&pts, false).expect("fit");
        let b = f.get(Kind::Band).expect("band tried");
        assert!(b.active, "{}", b.selection);
        assert!((b.value / 1e-2 - 1.0).abs() < 0.15, "{}", b.value);
        let [flo, _] = f.band_hz.expect("edges");
        assert!((flo / lo).ln().abs() < 0.2, "{flo} vs {lo}");
        assert!(f.model_rel < 0.05, "{}", f.model_rel);
    }

    #[test]
    fn no_hump_is_tried_when_the_ieee_terms_fit() {
        let pts = points(|t| 1e-6 / t + FLICKER_AVAR * 1e-8);
        let f = fit(&pts, false).expect("fit");
        assert_eq!(f.model_rel, 0.0);
        assert_eq!(f.terms.len(), BASE.len());
    }

    #[test]
    fn markov_term_is_found() {
        let pts = points(|t| 1e-6 / t + crate::sim::gm_avar(1e-4, 3.0, t));
        let f = fit(&pts, true).expect("fit");
        let gm = f.get(Kind::GaussMarkov).expect("gm");
        assert!((gm.value / 1e-2 - 1.0).abs() < 0.1, "{}", gm.value);
        let t = f.gm_tau_s.expect("T");
        assert!((t / 3.0).ln().abs() < 0.3, "{t}");
    }
}
