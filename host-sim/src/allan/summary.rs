//! The result of an Allan analysis in lines a user reads (`host-sim allan` prints them on
//! stdout and writes them as `summary` in its JSON): the least deviation, each term with why
//! it is in the model or not, how far the terms are from the curve, the tau ranges the fit
//! does not follow and why, the taus too long for the record to support
//! ([`super::supported`]), and whether the record shows a bias-instability floor at all.

use super::fit::{Fit, Kind, Miss, FOLLOW_TOL, NOT_FOLLOWED_Z};
use super::{supported, AdevPoint, MIN_CLUSTERS};

/// Above this model uncertainty (of AVAR) the summary says the terms are a rough
/// description (issue 43's bound: 50 %).
pub const MODEL_REL_WARN: f64 = 0.5;

/// `sqrt(2 ln 2 / pi)`: a flicker floor B shows as an Allan deviation of 0.664 B.
const FLICKER_ADEV: f64 = 0.664_282_032_302_755;

/// The summary lines of `points` (every point, supported or not) and their `fit`, for the
/// record `name`.
pub fn lines(name: &str, points: &[AdevPoint], fit: &Fit) -> Vec<String> {
    let mut out = Vec::new();
    let fitted: Vec<&AdevPoint> = points
        .iter()
        .filter(|p| supported(p) && p.adev_dps.is_finite())
        .collect();
    let least = fitted
        .iter()
        .min_by(|a, b| a.adev_dps.total_cmp(&b.adev_dps));
    if let Some(p) = least {
        out.push(format!(
            "{name}: least Allan deviation {:.4} deg/h at tau {} s (over the {} taus the record supports)",
            p.adev_dps * 3600.0,
            round9(p.tau_s),
            fitted.len()
        ));
    }
    let floor = floor_note(&fitted);
    for t in &fit.terms {
        if t.active {
            let pm = |v: Option<f64>| v.map_or(String::new(), |v| format!(" +- {v:.2e}"));
            out.push(format!(
                "  {:>10} = {:.4e}{} {} ({:.4e}{} {}): {}",
                t.symbol,
                t.value,
                pm(t.sigma),
                t.unit,
                t.value_alt,
                pm(t.sigma_alt),
                t.unit_alt,
                t.selection
            ));
            if t.term == Kind::BiasInstability {
                if let Some(note) = &floor {
                    out.push(format!(
                        "  {:>10}   is not a bias instability this record shows: {note}",
                        t.symbol
                    ));
                }
            }
        } else {
            out.push(format!(
                "  {:>10}   not in the model: {}",
                t.symbol, t.selection
            ));
        }
    }
    out.push(format!(
        "  fit: reduced chi-square {:.2} over {} points; model uncertainty {:.1} % of AVAR per point beside the statistical one ({})",
        fit.chi2_reduced,
        fit.n_points,
        100.0 * fit.model_rel,
        if fit.model_rel > 0.0 {
            "the fitted terms do not describe the curve within its statistics"
        } else {
            "all the terms together fit the points within their statistics"
        }
    ));
    if fit.model_rel > MODEL_REL_WARN {
        out.push(format!(
            "  model uncertainty over {:.0} %: the fitted terms are a rough description of this curve; read their values as such",
            100.0 * MODEL_REL_WARN
        ));
    }
    for r in miss_ranges(&fit.not_followed) {
        out.push(format!("  not followed: {r}"));
    }
    if fit.not_followed.is_empty() {
        out.push(format!(
            "  followed: the fit is within {:.0} % of every supported point",
            100.0 * FOLLOW_TOL
        ));
    }
    let unsupported: Vec<String> = points
        .iter()
        .filter(|p| !supported(p))
        .map(|p| format!("{}", round9(p.tau_s)))
        .collect();
    if !unsupported.is_empty() {
        out.push(format!(
            "  too long for the record: tau {} s hold fewer than {MIN_CLUSTERS} independent clusters (an Allan deviation from K clusters is uncertain by 1/sqrt(2 (K - 1)), over 25 % here, IEEE 952 Annex C): shown, not fitted",
            unsupported.join(", ")
        ));
    }
    if let (Some(note), false) = (
        &floor,
        fit.get(Kind::BiasInstability).is_some_and(|t| t.active),
    ) {
        out.push(format!("  no bias-instability floor: {note}"));
    }
    out
}

/// `None` when the supported curve stops falling before its longest tau (a floor, or a
/// rise, is seen); otherwise why the record cannot show a bias-instability floor and the
/// bound its least deviation puts on one.
fn floor_note(fitted: &[&AdevPoint]) -> Option<String> {
    let last = fitted.last()?;
    let least = fitted
        .iter()
        .min_by(|a, b| a.adev_dps.total_cmp(&b.adev_dps))?;
    if least.m != last.m {
        return None;
    }
    Some(format!(
        "the curve still falls at the longest tau the record supports ({} s, {:.4} deg/h), so no floor is seen; a bias instability is at most that deviation / 0.664 = {:.4} deg/h (a longer record measures it)",
        round9(last.tau_s),
        last.adev_dps * 3600.0,
        last.adev_dps * 3600.0 / FLICKER_ADEV
    ))
}

/// Runs of consecutive missed points, each in words: the taus, how far the fit is from
/// the points and the reason.
fn miss_ranges(misses: &[Miss]) -> Vec<String> {
    let mut runs: Vec<Vec<&Miss>> = Vec::new();
    for m in misses {
        // A run continues while the fit stays on the same side of the points.
        match runs.last_mut() {
            Some(run)
                if run.last().is_some_and(|p| {
                    p.rel_error.signum() == m.rel_error.signum() && m.tau_s <= 2.01 * p.tau_s
                }) =>
            {
                run.push(m);
            }
            _ => runs.push(vec![m]),
        }
    }
    runs.iter()
        .map(|run| {
            let (first, last) = (run[0], run[run.len() - 1]);
            let worst = run
                .iter()
                .max_by(|a, b| a.rel_error.abs().total_cmp(&b.rel_error.abs()))
                .map_or(0.0, |m| m.rel_error);
            let zs = run
                .iter()
                .map(|m| m.z_statistical.abs())
                .fold(0.0, f64::max);
            let taus = if run.len() == 1 {
                format!("tau {} s", round9(first.tau_s))
            } else {
                format!("tau {}-{} s", round9(first.tau_s), round9(last.tau_s))
            };
            let shape = if worst > 0.0 {
                "the curve is below the fitted terms there (it falls faster than they allow, or dips)"
            } else {
                "the curve is above the fitted terms there (a hump or band they do not describe)"
            };
            let stats = if zs < 2.0 {
                format!(
                    "; but only {zs:.1} sigma of the points' own statistics: too few clusters there to tell a feature from scatter"
                )
            } else {
                format!("; {zs:.1} sigma of the points' own statistics: a feature of the curve")
            };
            format!(
                "{taus}: fit {:+.0} % from the measured deviation (tolerance {:.0} %, or {NOT_FOLLOWED_Z} sigma with the model uncertainty); {shape}{stats}",
                100.0 * worst,
                100.0 * FOLLOW_TOL
            )
        })
        .collect()
}

/// `x` rounded to 9 decimals for printing (a tau of 0.010000000000218279 s prints 0.01).
pub fn round9(x: f64) -> f64 {
    (x * 1e9).round() / 1e9
}
