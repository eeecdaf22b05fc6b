//! `host-sim gyro convert`: an old sensor file, an old model file, or one of each (merged)
//! into one gyro file.
//!
//! - An old sensor file alone: its text with `noise_density_deg_rth` renamed
//!   `arw_deg_per_rth` (the same unit): its comments kept.
//! - An old model file (with or without a sensor file): written anew by
//!   [`super::write`] (the old file's comments are not carried over), every number in the
//!   gyro file's unit as the shortest decimal that reads back to the same value: the
//!   converted file gives the simulator the same model, bit for bit (checked before
//!   anything is written). A sensor file given with it adds `name`, `drift_bound_dph` and
//!   `[temperature] column`; where both give the rate, full scale, quantum or white noise
//!   they must agree.
//!
//! A file already in the gyro-file format is refused (nothing to convert); so is a file
//! that is neither.

use super::parse::{at, SENSOR_NOISE};
use super::units::{read_exact, DEG_RTH, DPH};
use super::write::{self, Parts};
use super::Gyro;
use crate::sim::Model;
use anyhow::{anyhow, bail, Result};
use serde::Deserialize;
use std::path::Path;
use toml::de::DeTable;

/// The old sensor file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OldSensor {
    name: String,
    sample_rate_hz: f64,
    full_scale_dps: f64,
    quantum_dps: f64,
    noise_density_deg_rth: f64,
    drift_bound_dph: f64,
    #[serde(default)]
    temperature: Option<OldTemperature>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OldTemperature {
    #[serde(default)]
    column: Option<String>,
}

/// One old file read.
enum Old {
    /// A sensor file: its text and contents.
    Sensor(String, OldSensor),
    /// A model file: the model (its motion file as written).
    Model(Box<Model>),
}

/// `x` (an f64 read from a decimal) in `factor`-times-smaller units, exactly.
fn scaled(x: f64, factor: f64) -> f64 {
    read_exact(&format!("{x:e}"), factor).unwrap_or(x / factor)
}

/// Reads one input and tells which old format it is.
fn read_old(path: &Path) -> Result<Old> {
    let source = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{source}: {e}"))?;
    let doc = DeTable::parse(&text).map_err(|e| {
        let place = e
            .span()
            .map_or(source.clone(), |s| at(&text, &source, s.start));
        anyhow!("{place}: {}", e.message().trim().replace('\n', " "))
    })?;
    if doc
        .get_ref()
        .iter()
        .any(|(k, _)| k.get_ref() == SENSOR_NOISE.old)
    {
        let s: OldSensor = toml::from_str(&text).map_err(|e| {
            let place = e
                .span()
                .map_or(source.clone(), |s| at(&text, &source, s.start));
            anyhow!(
                "{place}: {} (an old sensor file)",
                e.message().trim().replace('\n', " ")
            )
        })?;
        return Ok(Old::Sensor(text, s));
    }
    let gyro_error = match Gyro::from_toml_str(&text, &source, path.parent()) {
        Ok(_) => bail!("{source}: already a gyro file: nothing to convert"),
        Err(e) => e,
    };
    Model::from_toml_str(&text, &source)
        .map(|m| Old::Model(Box::new(m)))
        .map_err(|old| {
            anyhow!(
                "{source}: neither a gyro file ({gyro_error:#}) nor an old model file ({old:#})"
            )
        })
}

/// The old sensor file's text with its one renamed key (comments kept).
fn renamed_sensor(text: &str) -> Result<String> {
    let doc = DeTable::parse(text).map_err(|e| anyhow!("{}", e.message()))?;
    let span = doc
        .get_ref()
        .iter()
        .find(|(k, _)| k.get_ref() == SENSOR_NOISE.old)
        .map(|(k, _)| k.span())
        .ok_or_else(|| anyhow!("no {} key", SENSOR_NOISE.old))?;
    Ok(format!(
        "# Converted from the old sensor file by `host-sim gyro convert` ({} -> {}, the same unit).\n{}{}{}",
        SENSOR_NOISE.old,
        SENSOR_NOISE.new,
        &text[..span.start],
        SENSOR_NOISE.new,
        &text[span.end..]
    ))
}

/// Where a relative motion file of a model read from `input` is, seen from `output`'s
/// folder: unchanged when both are in one folder, else absolute.
fn motion_file_for(model: &mut Model, input: &Path, output: &Path) {
    let Some(f) = &model.motion.file else {
        return;
    };
    let in_dir = input.parent().unwrap_or(Path::new(""));
    let out_dir = output.parent().unwrap_or(Path::new(""));
    let same = match (in_dir.canonicalize(), out_dir.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => in_dir == out_dir,
    };
    if f.is_relative() && !same {
        let joined = in_dir.join(f);
        model.motion.file = Some(joined.canonicalize().unwrap_or(joined));
    }
}

/// The converted text of `inputs` (one or two old files) for `output`.
pub fn convert(inputs: &[&Path], output: &Path) -> Result<String> {
    let mut sensor: Option<(String, OldSensor, &Path)> = None;
    let mut model: Option<(Model, &Path)> = None;
    for &p in inputs {
        match read_old(p)? {
            Old::Sensor(t, s) if sensor.is_none() => sensor = Some((t, s, p)),
            Old::Model(m) if model.is_none() => model = Some((*m, p)),
            _ => bail!(
                "{}: give at most one old sensor file and one old model file",
                p.display()
            ),
        }
    }
    let out = output.display().to_string();
    let dir = output.parent();
    match (sensor, model) {
        (None, None) => bail!("give an old sensor or model file (--input)"),
        (Some((text, _, p)), None) => {
            let new = renamed_sensor(&text).map_err(|e| anyhow!("{}: {e}", p.display()))?;
            Gyro::from_toml_str(&new, &out, dir)?.sensor()?;
            Ok(new)
        }
        (sensor, Some((mut m, mp))) => {
            motion_file_for(&mut m, mp, output);
            let stem = mp
                .file_stem()
                .map_or_else(|| "gyro".to_string(), |s| s.to_string_lossy().into_owned());
            let mut header = vec![format!(
                "Converted by `host-sim gyro convert` from the old model file {}: the same simulator model,",
                mp.display()
            )];
            header.push("bit for bit; the old file's comments are not carried over.".into());
            let (mut name, mut bound, mut column) = (stem, None, None);
            if let Some((_, s, sp)) = &sensor {
                header.push(format!(
                    "Name, drift bound and temperature column from the old sensor file {}.",
                    sp.display()
                ));
                name = s.name.trim().to_string();
                bound = Some(scaled(s.drift_bound_dph, DPH));
                column = s.temperature.as_ref().and_then(|t| t.column.clone());
                merge(&mut m, s, sp, mp)?;
            } else {
                header.push(
                    "No drift_bound_dph: add it (deg/h) before identify, replay or image take this file."
                        .into(),
                );
            }
            let parts = Parts {
                header,
                name: &name,
                model: m.clone(),
                drift_bound_dps: bound,
                temperature_column: column.as_deref().filter(|c| !c.trim().is_empty()),
                identified: None,
            };
            let new = write::text(&parts)?;
            // The promise: the same model, bit for bit.
            let g = Gyro::from_toml_str(&new, &out, None)?;
            let (mut a, mut b) = (g.model, m);
            a.motion.file = None;
            b.motion.file = None;
            if a != b {
                bail!(
                    "{}: the converted model differs from the old one (a bug: please report)",
                    mp.display()
                );
            }
            Ok(new)
        }
    }
}

/// The sensor file's rate, full scale, quantum and white noise into the model, refused
/// where both give one and they differ.
fn merge(m: &mut Model, s: &OldSensor, sp: &Path, mp: &Path) -> Result<()> {
    let conflict = |what: &str, a: f64, b: f64| {
        anyhow!(
            "{} says {what} {a}, {} says {b}: they describe different gyros; convert them apart",
            sp.display(),
            mp.display()
        )
    };
    match m.sample_rate_hz {
        Some(r) if r != s.sample_rate_hz => {
            return Err(conflict("sample_rate_hz", s.sample_rate_hz, r))
        }
        _ => m.sample_rate_hz = Some(s.sample_rate_hz),
    }
    match m.full_scale_dps {
        Some(f) if f != s.full_scale_dps => {
            return Err(conflict("full_scale_dps", s.full_scale_dps, f))
        }
        _ => m.full_scale_dps = Some(s.full_scale_dps),
    }
    let q = m.quantization.quantum_dps;
    if q != 0.0 && q != s.quantum_dps {
        return Err(conflict("quantum_dps", s.quantum_dps, q));
    }
    m.quantization.quantum_dps = s.quantum_dps;
    let white = scaled(s.noise_density_deg_rth, DEG_RTH);
    let n = m.noise.arw_dps_per_rthz;
    if n != 0.0 && n != white {
        return Err(conflict(
            "white noise (deg/sqrt(h))",
            s.noise_density_deg_rth,
            n * DEG_RTH,
        ));
    }
    m.noise.arw_dps_per_rthz = white;
    Ok(())
}
