//! Writes a gyro file ([`super`]) from the simulator's model and what goes beside it: the
//! one writer of `identify --save-gyro`, `allan --save-gyro`, `gap --save-gyro`, `gap-bench
//! --write-records` and `gyro convert`. Every number is written as the shortest decimal that
//! reads back to the same value ([`super::units`]), so a written file gives the model it was
//! written from, bit for bit. Keys at their default are left out (the defaults are the
//! reader's); each key written carries its unit in a comment.

use super::parse::{Key, IDENTIFIED, KEYS, SAME_SECTIONS};
use super::units::{write_f32, write_f64};
use super::Identified;
use crate::sim::{Model, QuantMode};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::io::Write as _;

/// What a gyro file holds.
#[derive(Debug, Clone, Default)]
pub struct Parts<'a> {
    /// Comment lines at the top (without `# `).
    pub header: Vec<String>,
    /// `name`.
    pub name: &'a str,
    /// The datasheet part and the simulator's sections.
    pub model: Model,
    /// `drift_bound_dph`, in deg/s.
    pub drift_bound_dps: Option<f64>,
    /// `[temperature] column`.
    pub temperature_column: Option<&'a str>,
    /// `[identified]`.
    pub identified: Option<Identified>,
}

/// The unit (and meaning) of a key, for its comment.
fn note(path: &str) -> &'static str {
    match path {
        "sample_rate_hz" => "output data rate, Hz",
        "full_scale_dps" => "largest rate the unit reports, deg/s",
        "quantum_dps" => "one output count, deg/s",
        "arw_deg_per_rth" => "angle random walk (white rate noise), deg/sqrt(h)",
        "bias_instability_dph" => "bias instability B, deg/h (Allan floor 0.664 B)",
        "rrw_dph_per_rth" => "rate random walk K, deg/h/sqrt(h)",
        "rate_ramp_dph_per_h" => "rate ramp R, deg/h per h",
        "drift_bound_dph" => "largest drift the unit can have, deg/h",
        "noise.flicker_tau_min_s" => "flicker bank: shortest correlation time, s",
        "noise.flicker_tau_max_s" => "flicker bank: longest correlation time, s",
        "noise.gm_sigma_dph" => "Gauss-Markov term: sigma, deg/h",
        "noise.gm_tau_s" => "Gauss-Markov term: correlation time, s",
        "noise.sine_amplitude_dph" => "sinusoidal drift: amplitude, deg/h",
        "noise.sine_freq_hz" => "sinusoidal drift: frequency, Hz",
        "noise.sine_phase_deg" => "sinusoidal drift: phase at t = 0, deg",
        "bias.turn_on_dph" => "fixed turn-on bias, deg/h",
        "bias.turn_on_sigma_dph" => "run-to-run turn-on bias, 1 sigma, deg/h",
        "bias.warmup_dph" => "warm-up transient at switch-on, deg/h",
        "bias.warmup_tau_s" => "its time constant, s",
        "temperature.initial_c" => "temperature at switch-on, deg C",
        "temperature.ramp_c_per_s" => "ramp, deg C/s",
        "temperature.cycle_amplitude_c" => "cycle amplitude, deg C",
        "temperature.cycle_period_s" => "cycle period, s",
        "temperature.warmup_rise_c" => "self-heating rise, deg C",
        "temperature.warmup_tau_s" => "its time constant, s",
        "temperature.reference_c" => "temperature of zero temperature drift, deg C",
        "temperature.bias_dph_per_c" => "drift per deg C, deg/h",
        "temperature.shupe_dph_per_c_per_min" => "drift per deg C/min of change, deg/h",
        _ => "",
    }
}

/// `key = value   # note`.
fn line(out: &mut String, key: &str, value: &str, note: &str) {
    let kv = format!("{key} = {value}");
    if note.is_empty() {
        let _ = writeln!(out, "{kv}");
    } else {
        let _ = writeln!(out, "{kv:<35} # {note}");
    }
}

/// The model as the old model file's table (every field, defaults included).
fn table(m: &Model) -> Result<toml::Table> {
    toml::Table::try_from(m).context("the model as TOML")
}

/// The value at `path` (`section.key`) of `t`.
fn get<'t>(t: &'t toml::Table, path: &str) -> Option<&'t toml::Value> {
    match path.split_once('.') {
        Some((s, k)) => t.get(s)?.as_table()?.get(k),
        None => t.get(path),
    }
}

/// `t` less what equals `default` (recursively; empty tables dropped).
fn diff(t: &toml::Table, default: &toml::Table) -> toml::Table {
    let mut out = toml::Table::new();
    for (k, v) in t {
        match (v, default.get(k)) {
            (toml::Value::Table(a), Some(toml::Value::Table(b))) => {
                let d = diff(a, b);
                if !d.is_empty() {
                    out.insert(k.clone(), toml::Value::Table(d));
                }
            }
            (v, Some(d)) if v == d => {}
            (v, _) => {
                out.insert(k.clone(), v.clone());
            }
        }
    }
    out
}

/// The gyro file's text.
pub fn text(p: &Parts<'_>) -> Result<String> {
    let m = &p.model;
    let t = table(m)?;
    let d = table(&Model::default())?;
    let mut out = String::new();
    for h in &p.header {
        let _ = writeln!(out, "# {h}");
    }
    if !p.header.is_empty() {
        out.push('\n');
    }
    line(&mut out, "name", &format!("{:?}", p.name), "");
    // A key is written when the model's value differs from the default (sample rate and
    // full scale when the model has them).
    let value_of = |k: &Key| -> Option<f64> {
        let v = get(&t, k.old)?;
        let x = v.as_float().or_else(|| v.as_integer().map(|i| i as f64))?;
        let default = get(&d, k.old).and_then(toml::Value::as_float);
        (Some(x) != default).then_some(x)
    };
    let section = |out: &mut String, name: &str| {
        for k in KEYS.iter().filter(|k| {
            k.new
                .split_once('.')
                .map_or(name.is_empty(), |(s, _)| s == name)
        }) {
            if let Some(x) = value_of(k) {
                let key = k.new.rsplit('.').next().unwrap_or(k.new);
                line(out, key, &write_f64(x, k.factor), note(k.new));
            }
            if k.new == "quantum_dps"
                && (m.quantization.quantum_dps > 0.0 || m.quantization.mode != QuantMode::Round)
            {
                let mode = match m.quantization.mode {
                    QuantMode::Round => "\"round\"",
                    QuantMode::Angle => "\"angle\"",
                };
                line(
                    out,
                    "quantization_mode",
                    mode,
                    "round each sample, or the angle",
                );
            }
        }
    };
    section(&mut out, "");
    if let Some(b) = p.drift_bound_dps {
        line(
            &mut out,
            "drift_bound_dph",
            &write_f64(b, super::units::DPH),
            note("drift_bound_dph"),
        );
    }
    for name in ["noise", "bias", "temperature"] {
        let mut body = String::new();
        if name == "temperature" {
            if let Some(c) = p.temperature_column {
                line(
                    &mut body,
                    "column",
                    &format!("{c:?}"),
                    "records' temperature column",
                );
            }
        }
        section(&mut body, name);
        if !body.is_empty() {
            let _ = writeln!(out, "\n[{name}]\n{body}");
            out.pop();
        }
    }
    for name in SAME_SECTIONS {
        let (Some(toml::Value::Table(a)), Some(toml::Value::Table(b))) = (t.get(name), d.get(name))
        else {
            continue;
        };
        let changed = diff(a, b);
        if changed.is_empty() {
            continue;
        }
        let mut wrap = toml::Table::new();
        wrap.insert(name.to_string(), toml::Value::Table(changed));
        let s = toml::to_string(&wrap).with_context(|| format!("[{name}] as TOML"))?;
        let _ = write!(out, "\n{s}");
    }
    if let Some(id) = &p.identified {
        out.push_str(&identified_text(id));
    }
    Ok(out)
}

/// `[identified]`'s text.
fn identified_text(id: &Identified) -> String {
    let g = &id.model;
    let values: [f32; 14] = [
        g.white_dps_rthz,
        g.rrw_dps_per_s_rthz,
        g.drift_bound_dps,
        g.turn_on_dps.mean,
        g.turn_on_dps.sigma,
        g.warmup_dps.mean,
        g.warmup_dps.sigma,
        g.warmup_tau_min_s,
        g.warmup_tau_max_s,
        g.temp_ref_c,
        g.temp_dps_per_c.mean,
        g.temp_dps_per_c.sigma,
        g.temp_rate_dps_per_c_per_s.mean,
        g.temp_rate_dps_per_c_per_s.sigma,
    ];
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\n# The drift filter's gyro model fitted on {} calibration runs (host-sim identify).",
        id.runs
    );
    let _ = writeln!(out, "[identified]");
    line(&mut out, "runs", &id.runs.to_string(), "calibration runs");
    let notes = [
        "white noise, deg/sqrt(h)",
        "rate random walk, deg/h/sqrt(h)",
        "no estimate exceeds it, deg/h",
        "turn-on bias: family mean, deg/h",
        "its unit-to-unit spread, deg/h",
        "warm-up amplitude: family mean, deg/h",
        "its unit-to-unit spread, deg/h",
        "warm-up time constant: least, s",
        "warm-up time constant: largest, s",
        "temperature the links are taken from, deg C",
        "temperature link: family mean",
        "its unit-to-unit spread",
        "temperature-rate link: family mean",
        "its unit-to-unit spread",
    ];
    for (((key, factor), v), note) in IDENTIFIED.iter().zip(values).zip(notes) {
        line(&mut out, key, &write_f32(v, *factor), note);
    }
    // Every term up to the last one present, in order (an absent one between: 0 and 0).
    let n = g
        .markov
        .iter()
        .rposition(|t| t.sigma_dps != 0.0 || t.tau_s != 0.0)
        .map_or(0, |i| i + 1);
    for t in &g.markov[..n] {
        let _ = writeln!(out, "\n[[identified.markov]]");
        line(
            &mut out,
            "sigma_dph",
            &write_f32(t.sigma_dps, super::units::DPH),
            "Gauss-Markov sigma, deg/h",
        );
        line(
            &mut out,
            "tau_s",
            &write_f32(t.tau_s, 1.0),
            "correlation time, s",
        );
    }
    out
}

/// Writes `p` to `path` atomically (nothing written on an error); `inputs` may not be
/// overwritten.
pub fn save(path: &std::path::Path, p: &Parts<'_>, inputs: &[&std::path::Path]) -> Result<()> {
    for i in inputs {
        crate::record::refuse_overwrite(i, path)?;
    }
    let s = text(p)?;
    crate::record::write_atomic(path, |w| {
        w.write_all(s.as_bytes())
            .with_context(|| format!("{}: write failed", path.display()))
    })
}
