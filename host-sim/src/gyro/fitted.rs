//! What `allan` and `gap` fitted, as gyro files ([`super::write`]) that `simulate --gyro`
//! takes: `allan --save-gyro` (the IEEE 952 terms of its fit) and `gap --save-gyro` (the
//! model its last round simulated).

use super::units::{self, rounded, write_f64};
use super::write::{self, Parts};
use super::Gyro;
use crate::allan::fit::{Fit, Kind};
use crate::sim::{Model, QuantMode};
use anyhow::Result;
use std::path::Path;

/// `allan --save-gyro`: the terms `fit` keeps (each at 0 when dropped: left out), for a
/// record of sample period `tau0_s`: `sample_rate_hz = 1 / tau0` (9 significant digits),
/// N as `arw_deg_per_rth`, B as `bias_instability_dph` (with the flicker bank's shortest
/// time at 2.5 tau0, so that its floor is flat from 50 tau0), K as `rrw_dph_per_rth`, R as
/// `rate_ramp_dph_per_h`, the angle quantization Q as `quantum_dps = Q sqrt(12) / tau0`
/// with `quantization_mode = "angle"` (the simulator's `3 Q^2 / tau^2`), the Gauss-Markov
/// term as `[noise] gm_sigma_dph`, `gm_tau_s`, each rounded to 6 significant digits in the
/// file's unit (the fit's uncertainty is far larger). No full scale, no drift bound: allan
/// does not see them (identify, replay and image ask for them).
pub fn allan_parts<'a>(fit: &Fit, tau0_s: f64, name: &'a str, input: &Path) -> Parts<'a> {
    let value = |k: Kind| fit.get(k).filter(|t| t.active).map_or(0.0, |t| t.value);
    let six = |x: f64, factor: f64| rounded(x, factor, 6);
    let rate_hz = rate_of(tau0_s);
    let mut m = Model {
        sample_rate_hz: Some(rate_hz),
        ..Default::default()
    };
    let q = value(Kind::Quantization);
    if q > 0.0 {
        m.quantization.quantum_dps = six(q * 12f64.sqrt() / tau0_s, 1.0);
        m.quantization.mode = QuantMode::Angle;
    }
    m.noise.arw_dps_per_rthz = six(value(Kind::Arw), units::DEG_RTH);
    m.noise.bias_instability_dps = six(value(Kind::BiasInstability), units::DPH);
    if m.noise.bias_instability_dps > 0.0 {
        m.noise.flicker_tau_min_s = six(2.5 * tau0_s, 1.0);
    }
    m.noise.rrw_dps_per_s_rthz = six(value(Kind::Rrw), units::DPH_RTH);
    m.noise.rate_ramp_dps_per_s = six(value(Kind::RateRamp), units::DPH_PER_H);
    if let (Some(t), Some(tau)) = (fit.get(Kind::GaussMarkov), fit.gm_tau_s) {
        if t.active {
            m.noise.gm_sigma_dps = six(t.value, units::DPH);
            m.noise.gm_tau_s = six(tau, 1.0);
        }
    }
    let kept: Vec<&str> = fit
        .terms
        .iter()
        .filter(|t| t.active)
        .map(|t| t.symbol)
        .collect();
    let header = vec![
        format!(
            "Written by host-sim allan --save-gyro from {}: the noise terms its fit kept ({}),",
            input.display(),
            if kept.is_empty() {
                "none".to_string()
            } else {
                kept.join(", ")
            }
        ),
        format!(
            "at the record's rate (tau0 {} s). allan sees no full scale and no drift bound: add",
            write_f64(tau0_s, 1.0)
        ),
        "full_scale_dps and drift_bound_dph before identify, replay or image take this file."
            .into(),
    ];
    Parts {
        header,
        name,
        model: m,
        ..Default::default()
    }
}

/// The rate of a sample period, 9 significant digits (a 100-Hz record's stamps give
/// 99.99999999781 Hz: 100 is what the file says).
fn rate_of(period_s: f64) -> f64 {
    format!("{:.8e}", 1.0 / period_s)
        .parse()
        .unwrap_or(1.0 / period_s)
}

/// The default name of a file fitted on `record`: its stem (`run1` of `run1.csv.gz`).
pub fn record_name(record: &Path) -> String {
    let stem = record.file_name().map_or_else(
        || "record".to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    stem.trim_end_matches(".gz")
        .trim_end_matches(".csv")
        .to_string()
}

/// Writes `allan`'s fit as a gyro file.
pub fn save_allan(path: &Path, fit: &Fit, tau0_s: f64, input: &Path) -> Result<()> {
    let name = record_name(input);
    write::save(path, &allan_parts(fit, tau0_s, &name, input), &[input])?;
    eprintln!(
        "{}: the fitted terms as a gyro file -> {} (simulate --gyro takes it)",
        input.display(),
        path.display()
    );
    Ok(())
}

/// `gap --save-gyro`: the last round's model as a gyro file, with what it leaves out.
pub fn save_gap(
    path: &std::path::Path,
    real: &std::path::Path,
    gyro: Option<&Gyro>,
    out: &crate::gap::rounds::Outcome,
    dt_s: f64,
) -> Result<()> {
    let mut model = out.model.clone();
    model.sample_rate_hz = Some(model.sample_rate_hz.unwrap_or_else(|| rate_of(dt_s)));
    // A named ramp leaves the record in the rounds (the held-out comparison wants the
    // record's own in-sample residual), but the model holds a ramp term: it goes back in.
    model.noise.rate_ramp_dps_per_s += out.ramp_out_dps_per_s;
    let name = gyro.map_or_else(|| record_name(real), |g| g.name.clone());
    let source = gyro.map_or_else(
        || "the baseline gap fitted (ARW, bias instability, rate random walk)".to_string(),
        |g| format!("the gyro {}", g.source),
    );
    let mut header = vec![format!(
        "Written by host-sim gap --save-gyro on {}: {source}",
        real.display()
    )];
    let named: Vec<&str> = out
        .rounds
        .iter()
        .filter(|r| !r.applied.is_empty())
        .map(|r| r.effect.as_str())
        .collect();
    header.push(if named.is_empty() {
        "with no effect added (none named, or the last round's not applied).".to_string()
    } else {
        format!(
            "with each named effect applied as the rounds applied it: {} (an effect taken out",
            named.join(", ")
        )
    });
    if !named.is_empty() {
        header.push(
            "of the record rather than put into the model, e.g. temperature, sinusoid, scale_factor,"
                .into(),
        );
        header.push(
            "spikes, is not in this file: see the JSON's rounds; a ramp taken out is put back)."
                .into(),
        );
    }
    let parts = Parts {
        header,
        name: &name,
        model,
        drift_bound_dps: gyro.and_then(|g| g.drift_bound_dps),
        temperature_column: gyro.and_then(|g| g.temperature_column.as_deref()),
        identified: None,
    };
    write::save(path, &parts, &[real])?;
    eprintln!("gap: the last round's model -> {}", path.display());
    Ok(())
}
