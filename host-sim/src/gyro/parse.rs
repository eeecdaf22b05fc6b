//! Gyro-file text to a [`Gyro`]: the structure checked by serde (unknown keys and wrong
//! types, with their place), the old formats' keys named, each number converted exactly from
//! the decimal written ([`super::units`]) into the simulator's [`Model`] (whose own rules then
//! check the values, reported at the key in the file), `[identified]` into a
//! [`GyroModel`].

use super::units::{self, read_exact};
use super::{Gyro, Identified};
use crate::sensor::TEMPERATURE_COLUMN;
use crate::sim::{Bad, Family, Faults, Model, Motion, QuantMode, ScaleFactor, Timing};
use anyhow::{anyhow, bail, Result};
use fog_core::gyro_model::{GyroModel, MarkovTerm, Spread, MAX_MARKOV};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// A number of the file: its path in the gyro file, its path in the simulator's model (the
/// old model-file format: `section.key`), and the factor from the model's unit to the
/// file's (file = model x factor).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Key {
    /// Path in the gyro file (`bias.warmup_dph`; top level: `arw_deg_per_rth`).
    pub new: &'static str,
    /// Path in the old model file (`bias.warmup_dps`).
    pub old: &'static str,
    /// File unit per model unit.
    pub factor: f64,
}

const fn key(new: &'static str, old: &'static str, factor: f64) -> Key {
    Key { new, old, factor }
}

/// Every number of the datasheet part and of `[noise]`, `[bias]`, `[temperature]` (the
/// sections whose units changed); `[scale_factor]`, `[motion]`, `[timing]`, `[faults]`,
/// `[family]` are the model's, unchanged.
pub(crate) const KEYS: &[Key] = &[
    key("sample_rate_hz", "sample_rate_hz", 1.0),
    key("full_scale_dps", "full_scale_dps", 1.0),
    key("quantum_dps", "quantization.quantum_dps", 1.0),
    key("arw_deg_per_rth", "noise.arw_dps_per_rthz", units::DEG_RTH),
    key(
        "bias_instability_dph",
        "noise.bias_instability_dps",
        units::DPH,
    ),
    key(
        "rrw_dph_per_rth",
        "noise.rrw_dps_per_s_rthz",
        units::DPH_RTH,
    ),
    key(
        "rate_ramp_dph_per_h",
        "noise.rate_ramp_dps_per_s",
        units::DPH_PER_H,
    ),
    key("noise.flicker_tau_min_s", "noise.flicker_tau_min_s", 1.0),
    key("noise.flicker_tau_max_s", "noise.flicker_tau_max_s", 1.0),
    key("noise.gm_sigma_dph", "noise.gm_sigma_dps", units::DPH),
    key("noise.gm_tau_s", "noise.gm_tau_s", 1.0),
    key(
        "noise.sine_amplitude_dph",
        "noise.sine_amplitude_dps",
        units::DPH,
    ),
    key("noise.sine_freq_hz", "noise.sine_freq_hz", 1.0),
    key("noise.sine_phase_deg", "noise.sine_phase_deg", 1.0),
    key("bias.turn_on_dph", "bias.turn_on_dps", units::DPH),
    key(
        "bias.turn_on_sigma_dph",
        "bias.turn_on_sigma_dps",
        units::DPH,
    ),
    key("bias.warmup_dph", "bias.warmup_dps", units::DPH),
    key("bias.warmup_tau_s", "bias.warmup_tau_s", 1.0),
    key("temperature.initial_c", "temperature.initial_c", 1.0),
    key("temperature.ramp_c_per_s", "temperature.ramp_c_per_s", 1.0),
    key(
        "temperature.cycle_amplitude_c",
        "temperature.cycle_amplitude_c",
        1.0,
    ),
    key(
        "temperature.cycle_period_s",
        "temperature.cycle_period_s",
        1.0,
    ),
    key(
        "temperature.warmup_rise_c",
        "temperature.warmup_rise_c",
        1.0,
    ),
    key("temperature.warmup_tau_s", "temperature.warmup_tau_s", 1.0),
    key("temperature.reference_c", "temperature.reference_c", 1.0),
    key(
        "temperature.bias_dph_per_c",
        "temperature.bias_dps_per_c",
        units::DPH,
    ),
    key(
        "temperature.shupe_dph_per_c_per_min",
        "temperature.shupe_dps_per_c_per_s",
        units::DPH_PER_C_PER_MIN,
    ),
];

/// `quantization_mode`: the model's `[quantization] mode`.
pub(crate) const MODE: Key = key("quantization_mode", "quantization.mode", 1.0);

/// The old sensor file's key that a gyro file names otherwise (same unit).
pub(crate) const SENSOR_NOISE: Key = key("arw_deg_per_rth", "noise_density_deg_rth", 1.0);

/// The model's sections a gyro file holds as they are.
pub(crate) const SAME_SECTIONS: [&str; 5] =
    ["scale_factor", "motion", "timing", "faults", "family"];

/// `[identified]`'s numbers: (key, factor file unit per fog-core unit).
pub(crate) const IDENTIFIED: [(&str, f64); 14] = [
    ("arw_deg_per_rth", units::DEG_RTH),
    ("rrw_dph_per_rth", units::DPH_RTH),
    ("drift_bound_dph", units::DPH),
    ("turn_on_dph", units::DPH),
    ("turn_on_sigma_dph", units::DPH),
    ("warmup_dph", units::DPH),
    ("warmup_sigma_dph", units::DPH),
    ("warmup_tau_min_s", 1.0),
    ("warmup_tau_max_s", 1.0),
    ("reference_c", 1.0),
    ("temperature_dph_per_c", units::DPH),
    ("temperature_sigma_dph_per_c", units::DPH),
    (
        "temperature_rate_dph_per_c_per_min",
        units::DPH_PER_C_PER_MIN,
    ),
    (
        "temperature_rate_sigma_dph_per_c_per_min",
        units::DPH_PER_C_PER_MIN,
    ),
];

/// The file's structure (every number's value is read from its literal, exactly).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)] // The fields are checked by serde; the values are read from the text.
struct File {
    name: Option<String>,
    sample_rate_hz: Option<f64>,
    full_scale_dps: Option<f64>,
    quantum_dps: Option<f64>,
    quantization_mode: Option<QuantMode>,
    arw_deg_per_rth: Option<f64>,
    bias_instability_dph: Option<f64>,
    rrw_dph_per_rth: Option<f64>,
    rate_ramp_dph_per_h: Option<f64>,
    drift_bound_dph: Option<f64>,
    noise: Option<NoiseSection>,
    bias: Option<BiasSection>,
    temperature: Option<TemperatureSection>,
    scale_factor: Option<ScaleFactor>,
    motion: Option<Motion>,
    timing: Option<Timing>,
    faults: Option<Faults>,
    family: Option<Family>,
    identified: Option<IdentifiedSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct NoiseSection {
    flicker_tau_min_s: Option<f64>,
    flicker_tau_max_s: Option<f64>,
    gm_sigma_dph: Option<f64>,
    gm_tau_s: Option<f64>,
    sine_amplitude_dph: Option<f64>,
    sine_freq_hz: Option<f64>,
    sine_phase_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct BiasSection {
    turn_on_dph: Option<f64>,
    turn_on_sigma_dph: Option<f64>,
    warmup_dph: Option<f64>,
    warmup_tau_s: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct TemperatureSection {
    column: Option<Spanned<String>>,
    initial_c: Option<f64>,
    ramp_c_per_s: Option<f64>,
    cycle_amplitude_c: Option<f64>,
    cycle_period_s: Option<f64>,
    warmup_rise_c: Option<f64>,
    warmup_tau_s: Option<f64>,
    reference_c: Option<f64>,
    bias_dph_per_c: Option<f64>,
    shupe_dph_per_c_per_min: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct IdentifiedSection {
    runs: u32,
    arw_deg_per_rth: f64,
    rrw_dph_per_rth: f64,
    drift_bound_dph: f64,
    turn_on_dph: f64,
    turn_on_sigma_dph: f64,
    warmup_dph: f64,
    warmup_sigma_dph: f64,
    warmup_tau_min_s: f64,
    warmup_tau_max_s: f64,
    reference_c: f64,
    temperature_dph_per_c: f64,
    temperature_sigma_dph_per_c: f64,
    temperature_rate_dph_per_c_per_min: f64,
    temperature_rate_sigma_dph_per_c_per_min: f64,
    #[serde(default)]
    markov: Vec<MarkovSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct MarkovSection {
    sigma_dph: f64,
    tau_s: f64,
}

/// 1-based line and column (in characters) of byte `offset` of `text`.
pub(crate) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut at = offset.min(text.len());
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[start..].chars().count() + 1)
}

/// `source:LINE:COL` of byte `offset`.
pub(crate) fn at(text: &str, source: &str, offset: usize) -> String {
    let (l, c) = line_col(text, offset);
    format!("{source}:{l}:{c}")
}

/// Where each key is and what its value says, by path (`motion.turntable.step[1].rate_dps`).
#[derive(Default)]
struct Layout {
    /// Byte offset of the value.
    value_at: BTreeMap<String, usize>,
    /// Byte offset of the key.
    key_at: BTreeMap<String, usize>,
    /// Numbers as written (decimal; a hexadecimal, octal or binary integer in decimal).
    literals: BTreeMap<String, String>,
}

impl Layout {
    fn walk(&mut self, prefix: &str, table: &DeTable<'_>) {
        for (k, v) in table.iter() {
            let path = if prefix.is_empty() {
                k.get_ref().to_string()
            } else {
                format!("{prefix}.{}", k.get_ref())
            };
            self.key_at.insert(path.clone(), k.span().start);
            self.value_at.insert(path.clone(), v.span().start);
            match v.get_ref() {
                DeValue::Float(f) => {
                    self.literals.insert(path, f.as_str().to_string());
                }
                DeValue::Integer(i) => {
                    let text = if i.radix() == 10 {
                        Some(i.as_str().to_string())
                    } else {
                        i64::from_str_radix(i.as_str(), i.radix())
                            .ok()
                            .map(|n| n.to_string())
                    };
                    if let Some(t) = text {
                        self.literals.insert(path, t);
                    }
                }
                DeValue::Table(t) => self.walk(&path, t),
                DeValue::Array(a) => {
                    for (i, item) in a.iter().enumerate() {
                        if let DeValue::Table(t) = item.get_ref() {
                            let p = format!("{path}[{i}]");
                            self.value_at.insert(p.clone(), item.span().start);
                            self.walk(&p, t);
                        }
                    }
                }
                _ => {}
            }
        }
    }
}

/// Parses gyro-file text ([`super::Gyro::from_toml_str`]).
pub(super) fn parse(text: &str, source: &str, dir: Option<&Path>) -> Result<Gyro> {
    let doc = DeTable::parse(text).map_err(|e| toml_error(text, source, &e))?;
    let mut layout = Layout::default();
    layout.walk("", doc.get_ref());
    refuse_old_keys(text, source, &layout)?;
    let file: File = toml::from_str(text).map_err(|e| toml_error(text, source, &e))?;
    let place = |path: &str| -> String {
        layout
            .value_at
            .get(path)
            .map_or(source.to_string(), |&o| at(text, source, o))
    };
    let value = |path: &str, factor: f64| -> Option<f64> {
        let lit = layout.literals.get(path)?;
        read_exact(lit, factor).or_else(|| lit.parse::<f64>().ok().map(|v| v / factor))
    };

    // The simulator's model, in the old model file's form, then deserialized: the model's
    // defaults and types are the ones the simulator has always had.
    let mut old = toml::Table::new();
    for k in KEYS {
        if let Some(v) = value(k.new, k.factor) {
            insert(&mut old, k.old, toml::Value::Float(v));
        }
    }
    if let Some(m) = &file.quantization_mode {
        let mode = match m {
            QuantMode::Round => "round",
            QuantMode::Angle => "angle",
        };
        insert(&mut old, MODE.old, toml::Value::String(mode.into()));
    }
    let whole: toml::Table = toml::from_str(text).map_err(|e| toml_error(text, source, &e))?;
    for s in SAME_SECTIONS {
        if let Some(v) = whole.get(s) {
            old.insert(s.to_string(), v.clone());
        }
    }
    let mut model: Model = toml::Value::Table(old)
        .try_into()
        .map_err(|e: toml::de::Error| anyhow!("{source}: {}", e.message().trim()))?;
    model.check().map_err(|bad| {
        let (path, what) = match bad {
            Bad::Value {
                section,
                key,
                value: _,
                why,
            } => {
                let old_path = if section.is_empty() {
                    key.to_string()
                } else {
                    format!("{section}.{key}")
                };
                let new = KEYS
                    .iter()
                    .find(|k| k.old == old_path)
                    .map_or(old_path.clone(), |k| k.new.to_string());
                let lit = layout
                    .literals
                    .get(&new)
                    .cloned()
                    .unwrap_or_else(|| "(default)".into());
                (new.clone(), format!("{} = {lit}: {why}", shown(&new)))
            }
            Bad::Step { index, key, why } => {
                let p = format!("motion.turntable.step[{index}].{key}");
                let p = if layout.value_at.contains_key(&p) {
                    p
                } else {
                    format!("motion.turntable.step[{index}]")
                };
                (
                    p,
                    format!("[[motion.turntable.step]] #{} {key}: {why}", index + 1),
                )
            }
            Bad::NoMotionFile => (
                "motion.profile".to_string(),
                "[motion] profile = \"file\" needs `file = \"PATH.csv\"`".to_string(),
            ),
            Bad::Family { key, why } => (format!("family.{key}"), format!("[family] {key}: {why}")),
        };
        anyhow!("{}: {what}", place(&path))
    })?;
    if let (Some(f), Some(dir)) = (&model.motion.file, dir) {
        if f.is_relative() {
            model.motion.file = Some(dir.join(f));
        }
    }

    let drift_bound_dps = match value("drift_bound_dph", units::DPH) {
        Some(b) if !(b.is_finite() && b > 0.0) => bail!(
            "{}: drift_bound_dph = {}: must be > 0 (deg/h)",
            place("drift_bound_dph"),
            layout.literals.get("drift_bound_dph").map_or("", |s| s)
        ),
        b => b,
    };
    let temperature_column = column(text, source, file.temperature.as_ref())?;
    let name = match &file.name {
        Some(n) if n.trim().is_empty() => {
            bail!("{}: name: must not be empty", place("name"))
        }
        Some(n) => n.trim().to_string(),
        None => Path::new(source)
            .file_stem()
            .map_or_else(|| source.to_string(), |s| s.to_string_lossy().into_owned()),
    };
    let identified = match &file.identified {
        None => None,
        Some(s) => Some(identified(s, &model, &value, &place)?),
    };
    let given = [
        "sample_rate_hz",
        "full_scale_dps",
        "arw_deg_per_rth",
        "drift_bound_dph",
    ]
    .into_iter()
    .filter(|k| layout.literals.contains_key(*k))
    .collect();
    let places = layout
        .value_at
        .iter()
        .map(|(k, &o)| (k.clone(), at(text, source, o)))
        .collect();
    Ok(Gyro {
        name,
        source: source.to_string(),
        path: None::<PathBuf>,
        builtin: false,
        model,
        drift_bound_dps,
        temperature_column,
        identified,
        given,
        places,
        literals: layout.literals,
    })
}

/// A path as the messages show it: `[bias] warmup_dph`, a top-level key alone.
fn shown(path: &str) -> String {
    match path.rsplit_once('.') {
        Some((s, k)) => format!("[{s}] {k}"),
        None => path.to_string(),
    }
}

/// Sets `path` (`section.key` or `key`) of `t`.
fn insert(t: &mut toml::Table, path: &str, v: toml::Value) {
    match path.split_once('.') {
        Some((s, k)) => {
            let sec = t
                .entry(s.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(st) = sec {
                st.insert(k.to_string(), v);
            }
        }
        None => {
            t.insert(path.to_string(), v);
        }
    }
}

/// `[temperature] column`: `temp_c` or none (absent or `""`); another name is refused.
fn column(text: &str, source: &str, t: Option<&TemperatureSection>) -> Result<Option<String>> {
    let Some(c) = t.and_then(|t| t.column.as_ref()) else {
        return Ok(None);
    };
    let name = c.get_ref().trim();
    if name.is_empty() {
        Ok(None)
    } else if name == TEMPERATURE_COLUMN {
        Ok(Some(TEMPERATURE_COLUMN.to_string()))
    } else {
        Err(anyhow!(
            "{}: [temperature] column = {:?}: host-sim reads the temperature from a column named `{TEMPERATURE_COLUMN}` only (today); rename the record's column or leave this out",
            at(text, source, c.span().start),
            c.get_ref()
        ))
    }
}

/// `[identified]` as fog-core's model (rate and quantum from the datasheet part).
fn identified(
    s: &IdentifiedSection,
    model: &Model,
    value: &dyn Fn(&str, f64) -> Option<f64>,
    place: &dyn Fn(&str) -> String,
) -> Result<Identified> {
    let Some(rate_hz) = model.sample_rate_hz else {
        bail!(
            "{}: [identified] needs sample_rate_hz in the datasheet part (top level)",
            place("identified")
        );
    };
    // Each number in fog-core's unit, f32, refused where it breaks the model's rules.
    let get = |k: &str, factor: f64, rule: Rule| -> Result<f32> {
        let path = format!("identified.{k}");
        let v = value(&path, factor).unwrap_or(f64::NAN);
        let x = v as f32;
        let ok = x.is_finite()
            && match rule {
                Rule::Any => true,
                Rule::NonNegative => x >= 0.0,
                Rule::Positive => x > 0.0,
            };
        if ok {
            Ok(x)
        } else {
            Err(anyhow!(
                "{}: [identified] {k}: must be {}",
                place(&path),
                match rule {
                    Rule::Any => "finite (and within f32's range)",
                    Rule::NonNegative => ">= 0",
                    Rule::Positive => "> 0",
                }
            ))
        }
    };
    let f = |k: &str| IDENTIFIED.iter().find(|x| x.0 == k).map_or(1.0, |x| x.1);
    let g = |k: &str, rule: Rule| get(k, f(k), rule);
    if s.markov.len() > MAX_MARKOV {
        bail!(
            "{}: [[identified.markov]]: at most {MAX_MARKOV} terms, {} given",
            place(&format!("identified.markov[{MAX_MARKOV}]")),
            s.markov.len()
        );
    }
    let mut markov = [MarkovTerm::default(); MAX_MARKOV];
    for (i, m) in markov.iter_mut().enumerate().take(s.markov.len()) {
        m.sigma_dps = get(
            &format!("markov[{i}].sigma_dph"),
            units::DPH,
            Rule::NonNegative,
        )?;
        m.tau_s = get(&format!("markov[{i}].tau_s"), 1.0, Rule::NonNegative)?;
    }
    let spread = |mean: &str, sigma: &str| -> Result<Spread> {
        Ok(Spread {
            mean: g(mean, Rule::Any)?,
            sigma: g(sigma, Rule::NonNegative)?,
        })
    };
    let gm = GyroModel {
        sample_rate_hz: rate_hz as f32,
        white_dps_rthz: g("arw_deg_per_rth", Rule::Positive)?,
        quantum_dps: model.quantization.quantum_dps as f32,
        markov,
        rrw_dps_per_s_rthz: g("rrw_dph_per_rth", Rule::NonNegative)?,
        turn_on_dps: spread("turn_on_dph", "turn_on_sigma_dph")?,
        warmup_dps: spread("warmup_dph", "warmup_sigma_dph")?,
        warmup_tau_min_s: g("warmup_tau_min_s", Rule::Positive)?,
        warmup_tau_max_s: g("warmup_tau_max_s", Rule::Positive)?,
        temp_ref_c: g("reference_c", Rule::Any)?,
        temp_dps_per_c: spread("temperature_dph_per_c", "temperature_sigma_dph_per_c")?,
        temp_rate_dps_per_c_per_s: spread(
            "temperature_rate_dph_per_c_per_min",
            "temperature_rate_sigma_dph_per_c_per_min",
        )?,
        drift_bound_dps: g("drift_bound_dph", Rule::Positive)?,
    };
    if !gm.is_valid() {
        bail!(
            "{}: [identified]: not a valid gyro model (sample_rate_hz and quantum_dps of the datasheet part included)",
            place("identified")
        );
    }
    Ok(Identified {
        model: gm,
        runs: s.runs,
    })
}

/// What an `[identified]` number must be.
#[derive(Clone, Copy)]
enum Rule {
    Any,
    NonNegative,
    Positive,
}

/// A TOML or serde error as `FILE:LINE:COL: message`, with a hint for a key written with a
/// wrong or missing unit or below a section.
fn toml_error(text: &str, source: &str, e: &toml::de::Error) -> anyhow::Error {
    let place = e
        .span()
        .map_or(source.to_string(), |s| at(text, source, s.start));
    let msg = e.message().trim().replace('\n', " ");
    anyhow!("{place}: {msg}{}", unit_hint(&msg))
}

/// Every key name a gyro file may hold (for the hints).
fn key_names() -> Vec<&'static str> {
    let mut v: Vec<&'static str> = KEYS
        .iter()
        .map(|k| k.new.rsplit('.').next().unwrap_or(k.new))
        .collect();
    v.extend(["name", "drift_bound_dph", "quantization_mode", "column"]);
    v.extend(IDENTIFIED.iter().map(|x| x.0));
    for (section, keys) in crate::sim::KEYS {
        if SAME_SECTIONS.iter().any(|s| section.starts_with(s)) {
            v.extend(keys.iter().copied());
        }
    }
    v
}

/// Top-level keys (a hint when one is written below a section header).
const TOP_LEVEL: [&str; 10] = [
    "name",
    "sample_rate_hz",
    "full_scale_dps",
    "quantum_dps",
    "quantization_mode",
    "arw_deg_per_rth",
    "bias_instability_dph",
    "rrw_dph_per_rth",
    "rate_ramp_dph_per_h",
    "drift_bound_dph",
];

/// For an "unknown field `x`" message: the key `x` most likely meant.
fn unit_hint(msg: &str) -> String {
    let Some(unknown) = crate::sim::unknown_field(msg) else {
        return String::new();
    };
    if TOP_LEVEL.contains(&unknown) {
        return format!(
            " (`{unknown}` is a top-level key: write it above the first [section] header)"
        );
    }
    let stem = crate::sim::key_stem;
    let want = stem(unknown);
    // The keys the section takes, from serde's "expected one of `a`, `b`", else every key.
    let expected: Vec<&str> = msg
        .split_once("expected")
        .map(|(_, e)| e.split('`').skip(1).step_by(2).collect())
        .unwrap_or_default();
    let names = if expected.is_empty() {
        key_names()
    } else {
        expected
    };
    match names.iter().find(|k| !want.is_empty() && stem(k) == want) {
        Some(k) if unknown == want => {
            format!(" (`{unknown}` has no unit; a gyro file takes `{k}`)")
        }
        Some(k) => format!(" (wrong unit in `{unknown}`? a gyro file takes `{k}`)"),
        None => String::new(),
    }
}

/// A key of an old format: its old path, the gyro file's path, the factor (new per old).
pub(crate) fn old_keys() -> Vec<(String, &'static str, f64)> {
    let mut v: Vec<(String, &'static str, f64)> = KEYS
        .iter()
        .chain([&MODE, &SENSOR_NOISE])
        .filter(|k| k.old != k.new)
        .map(|k| (k.old.to_string(), k.new, k.factor))
        .collect();
    // `[quantization]` is gone as a section.
    v.retain(|(o, _, _)| o != "quantization.quantum_dps" && o != "quantization.mode");
    v.push(("quantization.quantum_dps".into(), "quantum_dps", 1.0));
    v.push(("quantization.mode".into(), "quantization_mode", 1.0));
    v
}

/// Refuses a file of the old sensor- or model-file format: one message naming each old
/// key met, its new name and unit factor, and the command that converts the file.
fn refuse_old_keys(text: &str, source: &str, layout: &Layout) -> Result<()> {
    let old = old_keys();
    let mut found: Vec<(&String, &'static str, f64)> = layout
        .key_at
        .keys()
        .filter_map(|p| {
            old.iter()
                .find(|(o, _, _)| o == p)
                .map(|(_, n, f)| (p, *n, *f))
        })
        .collect();
    // In the file's order.
    found.sort_by_key(|(p, _, _)| layout.key_at.get(p.as_str()).copied());
    let Some((first, _, _)) = found.first() else {
        return Ok(());
    };
    let what = if found.iter().any(|(p, _, _)| p.as_str() == SENSOR_NOISE.old) {
        "the old sensor-file format"
    } else {
        "the old model-file format (deg/s units)"
    };
    let list: Vec<String> = found
        .iter()
        .map(|(p, n, f)| {
            let times = if *f == 1.0 {
                "same unit".to_string()
            } else {
                format!("x {f}")
            };
            let top = if p.contains('.') && !n.contains('.') {
                "top level, "
            } else {
                ""
            };
            format!("{} -> {} ({top}{times})", shown(p), shown(n))
        })
        .collect();
    let place = layout
        .key_at
        .get(first.as_str())
        .map_or(source.to_string(), |&o| at(text, source, o));
    bail!(
        "{place}: {what}: a gyro file names these keys otherwise: {}; convert the file with `host-sim gyro convert --input {source} --output NEW.toml`",
        list.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_characters() {
        assert_eq!(line_col("ab\ncd", 0), (1, 1));
        assert_eq!(line_col("ab\ncd", 4), (2, 2));
        assert_eq!(line_col("é\nx", 3), (2, 1));
        assert_eq!(line_col("éx", 2), (1, 2));
        assert_eq!(line_col("x", 99), (1, 2));
    }

    #[test]
    fn every_model_number_has_one_gyro_key() {
        // Each number of [noise], [bias], [temperature] and the top level of the model has
        // exactly one key in KEYS (nothing the simulator does is out of reach).
        for (section, keys) in crate::sim::KEYS {
            if SAME_SECTIONS.iter().any(|s| section.starts_with(s)) {
                continue;
            }
            for k in *keys {
                let old = if section.is_empty() {
                    k.to_string()
                } else {
                    format!("{section}.{k}")
                };
                let n = KEYS.iter().filter(|x| x.old == old).count() + usize::from(old == MODE.old);
                assert_eq!(n, 1, "{old}");
            }
        }
    }
}
