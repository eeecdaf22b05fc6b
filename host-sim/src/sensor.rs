//! The sensor file: a gyro's specification as a small TOML file that a user writes for any
//! gyro, read into a [`fog_core::still::SensorConfig`] (`--sensor NAME|FILE` of `identify`
//! and `replay`).
//!
//! ```toml
//! # KVH E-Core 2000, 60 deg/s unit (sources and ASSUMED values in comments)
//! name = "ecore2000"                 # shown in messages and reports (not empty)
//! sample_rate_hz = 100.0             # output data rate, Hz, 10 to 2000
//! full_scale_dps = 60.0              # largest rate the unit reports, deg/s, > 0
//! quantum_dps = 0.0018310546875      # one output count, deg/s, >= 0 (0: floating-point output)
//! noise_density_deg_rth = 0.0666666  # white noise (angle random walk), deg/sqrt(h), > 0
//! drift_bound_dph = 30.0             # largest drift the unit can have, deg/h, > 0
//!
//! [temperature]                      # optional table
//! column = "temp_c"                  # CSV column of the case temperature, deg C; absent or "": none
//! ```
//!
//! Every key but `[temperature]` is required; an unknown key is refused. Conversions to
//! [`SensorConfig`]'s units, in f64 then rounded once to f32: noise density
//! `N deg/sqrt(h) = N / 60 deg/s/sqrt(Hz)`, drift bound `D deg/h = D / 3600 deg/s`. A bad
//! file stops with one message naming the file, the line and the column
//! (`FILE:LINE:COL: ...`).
//!
//! The built-in sensors ([`BUILTIN`]) are files of the same form in `host-sim/sensors/`,
//! embedded in the binary and read by the same code; each reproduces its fog-core constant
//! (`SensorConfig::ECORE_2000`, `SensorConfig::KVH_DSP_1750`) bit for bit (unit tests).
//!
//! `[temperature] column`: today every host-sim reader takes the temperature from a column
//! named `temp_c` when the record has one, whatever the sensor file says (the readers of
//! `identify`, `replay`, `--validate` and `--tune-on` name it literally). The key is parsed
//! and kept in [`SensorSpec::temperature_column`] for the day the readers take it; until
//! then a name other than `temp_c` is refused rather than silently ignored, and absent or
//! `""` ("no temperature") does not stop a record's `temp_c` column from being read.

use anyhow::{anyhow, Result};
use fog_core::still::SensorConfig;
use serde::Deserialize;
use std::ops::RangeInclusive;
use std::path::Path;
use toml::Spanned;

/// Output data rates a sensor file may give, Hz. The range the project supports (the
/// records it is tested on are at 100 Hz and 1 kHz). ASSUMED: at 10 Hz the stillness
/// detector's 1-s window still holds its minimum of 8 samples; above 2 kHz nothing has been
/// run (the firmware's per-sample budget is measured at 1 kHz at most).
pub const SAMPLE_RATE_RANGE_HZ: RangeInclusive<f64> = 10.0..=2000.0;

/// The column name every host-sim reader takes the temperature from (see the module doc).
pub const TEMPERATURE_COLUMN: &str = "temp_c";

/// The built-in sensors: (name, file in the repository, its text).
pub const BUILTIN: [(&str, &str, &str); 2] = [
    (
        "ecore2000",
        "host-sim/sensors/ecore2000.toml",
        include_str!("../sensors/ecore2000.toml"),
    ),
    (
        "kvh1750",
        "host-sim/sensors/kvh1750.toml",
        include_str!("../sensors/kvh1750.toml"),
    ),
];

/// A sensor read from a sensor file or a built-in.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpec {
    /// The file's `name`.
    pub name: String,
    /// The specification in fog-core's units (deg/s, Hz).
    pub config: SensorConfig,
    /// `[temperature] column`: `Some("temp_c")` or `None` (absent or `""`); see the module
    /// doc for what the readers do with it today.
    pub temperature_column: Option<String>,
    /// Where it came from: the path as given, or `host-sim/sensors/NAME.toml` for a built-in.
    pub source: String,
    /// True for a built-in ([`BUILTIN`]).
    pub builtin: bool,
}

/// The file as written (user units).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorFile {
    name: Spanned<String>,
    sample_rate_hz: Spanned<f64>,
    full_scale_dps: Spanned<f64>,
    quantum_dps: Spanned<f64>,
    noise_density_deg_rth: Spanned<f64>,
    drift_bound_dph: Spanned<f64>,
    #[serde(default)]
    temperature: Option<TemperatureTable>,
}

/// `[temperature]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TemperatureTable {
    #[serde(default)]
    column: Option<Spanned<String>>,
}

/// 1-based line and column (in characters) of byte `offset` of `text`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
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
fn at(text: &str, source: &str, offset: usize) -> String {
    let (l, c) = line_col(text, offset);
    format!("{source}:{l}:{c}")
}

/// Checks one value; the error names its line and column.
fn check(
    text: &str,
    source: &str,
    key: &str,
    v: &Spanned<f64>,
    ok: bool,
    want: &str,
) -> Result<f64> {
    let x = *v.get_ref();
    if ok && x.is_finite() {
        Ok(x)
    } else {
        Err(anyhow!(
            "{}: {key} = {x}: must be {want}",
            at(text, source, v.span().start)
        ))
    }
}

/// `x` rounded to f32, refused when it does not stay finite and (for `positive`) > 0.
fn to_f32(
    text: &str,
    source: &str,
    key: &str,
    v: &Spanned<f64>,
    x: f64,
    positive: bool,
) -> Result<f32> {
    let y = x as f32;
    if y.is_finite() && (!positive || y > 0.0) {
        Ok(y)
    } else {
        Err(anyhow!(
            "{}: {key} = {}: out of f32 range once converted to deg/s ({x:e})",
            at(text, source, v.span().start),
            v.get_ref()
        ))
    }
}

impl SensorSpec {
    /// Parses and validates sensor-file text; `source` (the file name) starts every error
    /// message, with the line and column when known.
    pub fn from_toml_str(text: &str, source: &str) -> Result<Self> {
        let f: SensorFile = toml::from_str(text).map_err(|e| {
            let place = e
                .span()
                .map_or(source.to_string(), |s| at(text, source, s.start));
            anyhow!("{place}: {}", e.message().trim().replace('\n', " "))
        })?;
        let name = f.name.get_ref().trim().to_string();
        if name.is_empty() {
            return Err(anyhow!(
                "{}: name: must not be empty",
                at(text, source, f.name.span().start)
            ));
        }
        let (lo, hi) = (*SAMPLE_RATE_RANGE_HZ.start(), *SAMPLE_RATE_RANGE_HZ.end());
        let r = &f.sample_rate_hz;
        let rate_hz = check(
            text,
            source,
            "sample_rate_hz",
            r,
            SAMPLE_RATE_RANGE_HZ.contains(r.get_ref()),
            &format!("{lo} to {hi} Hz (the supported range)"),
        )?;
        let fs = &f.full_scale_dps;
        let full_scale_dps = check(
            text,
            source,
            "full_scale_dps",
            fs,
            *fs.get_ref() > 0.0,
            "> 0",
        )?;
        let q = &f.quantum_dps;
        let quantum_dps = check(
            text,
            source,
            "quantum_dps",
            q,
            *q.get_ref() >= 0.0 && *q.get_ref() < full_scale_dps,
            ">= 0 (0: floating-point output) and below full_scale_dps",
        )?;
        let n = &f.noise_density_deg_rth;
        let noise_deg_rth = check(
            text,
            source,
            "noise_density_deg_rth",
            n,
            *n.get_ref() > 0.0,
            "> 0 (deg/sqrt(h))",
        )?;
        let d = &f.drift_bound_dph;
        let bound_dph = check(
            text,
            source,
            "drift_bound_dph",
            d,
            *d.get_ref() > 0.0,
            "> 0 (deg/h)",
        )?;
        let config = SensorConfig {
            full_scale_dps: to_f32(text, source, "full_scale_dps", fs, full_scale_dps, true)?,
            quantum_dps: to_f32(text, source, "quantum_dps", q, quantum_dps, false)?,
            sample_rate_hz: to_f32(text, source, "sample_rate_hz", r, rate_hz, true)?,
            noise_density_dps_rthz: to_f32(
                text,
                source,
                "noise_density_deg_rth",
                n,
                noise_deg_rth / 60.0,
                true,
            )?,
            drift_bound_dps: to_f32(text, source, "drift_bound_dph", d, bound_dph / 3600.0, true)?,
        };
        if !config.is_valid() {
            return Err(anyhow!("{source}: not a valid sensor configuration"));
        }
        let column = f.temperature.and_then(|t| t.column);
        let temperature_column = match column {
            None => None,
            Some(c) if c.get_ref().trim().is_empty() => None,
            Some(c) if c.get_ref().trim() == TEMPERATURE_COLUMN => {
                Some(TEMPERATURE_COLUMN.to_string())
            }
            Some(c) => {
                return Err(anyhow!(
                    "{}: [temperature] column = {:?}: host-sim reads the temperature from a column named `{TEMPERATURE_COLUMN}` only (today); rename the record's column or leave this out",
                    at(text, source, c.span().start),
                    c.get_ref()
                ))
            }
        };
        Ok(Self {
            name,
            config,
            temperature_column,
            source: source.to_string(),
            builtin: false,
        })
    }

    /// Reads and validates a sensor file.
    pub fn load(path: &Path) -> Result<Self> {
        let source = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{source}: {e}"))?;
        Self::from_toml_str(&text, &source)
    }

    /// The built-in sensor `name` ([`BUILTIN`]), `None` when there is none of that name.
    pub fn builtin(name: &str) -> Option<Result<Self>> {
        let (_, file, text) = BUILTIN.iter().find(|b| b.0 == name)?;
        Some(Self::from_toml_str(text, file).map(|s| Self { builtin: true, ..s }))
    }

    /// `--sensor NAME|FILE`: a built-in's name, else a path to a sensor file (an existing
    /// file, or any argument ending in `.toml`).
    pub fn from_arg(arg: &str) -> Result<Self> {
        if let Some(b) = Self::builtin(arg) {
            return b;
        }
        let path = Path::new(arg);
        if path.is_file() || arg.ends_with(".toml") {
            return Self::load(path);
        }
        let names: Vec<&str> = BUILTIN.iter().map(|b| b.0).collect();
        Err(anyhow!(
            "unknown sensor {arg:?}: give a built-in ({}) or a path to a .toml sensor file",
            names.join(", ")
        ))
    }
}

/// clap's value parser of `--sensor NAME|FILE` ([`SensorSpec::from_arg`]).
pub fn parse_sensor_arg(arg: &str) -> Result<SensorSpec, String> {
    SensorSpec::from_arg(arg).map_err(|e| format!("{e:#}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn builtin(name: &str) -> SensorSpec {
        SensorSpec::builtin(name)
            .expect("a built-in")
            .expect("parses")
    }

    fn err(text: &str) -> String {
        match SensorSpec::from_toml_str(text, "my.toml") {
            Ok(s) => panic!("accepted: {s:?}"),
            Err(e) => format!("{e:#}"),
        }
    }

    const GOOD: &str = "name = \"mine\"\nsample_rate_hz = 50\nfull_scale_dps = 100.0\nquantum_dps = 0.0\nnoise_density_deg_rth = 0.1\ndrift_bound_dph = 10.0\n";

    /// The built-in files give exactly fog-core's constants (every field bit for bit).
    #[test]
    fn builtins_reproduce_fog_core_consts() {
        for (name, want) in [
            ("ecore2000", SensorConfig::ECORE_2000),
            ("kvh1750", SensorConfig::KVH_DSP_1750),
        ] {
            let s = builtin(name);
            assert_eq!(s.name, name);
            assert!(s.builtin);
            let c = s.config;
            let bits = |c: SensorConfig| {
                [
                    c.full_scale_dps,
                    c.quantum_dps,
                    c.sample_rate_hz,
                    c.noise_density_dps_rthz,
                    c.drift_bound_dps,
                ]
                .map(f32::to_bits)
            };
            assert_eq!(bits(c), bits(want), "{name}: {c:?} vs {want:?}");
        }
        assert_eq!(
            builtin("ecore2000").temperature_column.as_deref(),
            Some("temp_c")
        );
        assert_eq!(builtin("kvh1750").temperature_column, None);
    }

    #[test]
    fn a_user_file_converts_units() {
        let s = SensorSpec::from_toml_str(GOOD, "my.toml").expect("parses");
        assert_eq!(s.name, "mine");
        assert_eq!(s.source, "my.toml");
        assert!(!s.builtin);
        assert_eq!(s.config.sample_rate_hz, 50.0);
        assert_eq!(s.config.noise_density_dps_rthz, (0.1f64 / 60.0) as f32);
        assert_eq!(s.config.drift_bound_dps, (10.0f64 / 3600.0) as f32);
        assert_eq!(s.temperature_column, None);
        let t = format!("{GOOD}[temperature]\ncolumn = \"\"\n");
        let s = SensorSpec::from_toml_str(&t, "my.toml").expect("parses");
        assert_eq!(s.temperature_column, None);
    }

    #[test]
    fn unknown_field_names_file_line_and_column() {
        let e = err(&format!("{GOOD}noise_dps = 1.0\n"));
        assert!(e.starts_with("my.toml:7:1: "), "{e}");
        assert!(e.contains("unknown field `noise_dps`"), "{e}");
        let e = err(&format!(
            "{GOOD}[temperature]\ncolumn = \"temp_c\"\nunit = \"C\"\n"
        ));
        assert!(e.starts_with("my.toml:9:1: "), "{e}");
        assert!(e.contains("unknown field `unit`"), "{e}");
    }

    #[test]
    fn bad_value_names_file_line_and_column() {
        // Wrong type.
        let e = err(&GOOD.replace("full_scale_dps = 100.0", "full_scale_dps = \"100\""));
        assert!(e.starts_with("my.toml:3:18: "), "{e}");
        // Out of range: each rule, at the value.
        for (from, to, line, what) in [
            (
                "sample_rate_hz = 50",
                "sample_rate_hz = 5",
                2,
                "10 to 2000 Hz",
            ),
            (
                "sample_rate_hz = 50",
                "sample_rate_hz = 2500",
                2,
                "10 to 2000 Hz",
            ),
            (
                "sample_rate_hz = 50",
                "sample_rate_hz = nan",
                2,
                "10 to 2000 Hz",
            ),
            ("full_scale_dps = 100.0", "full_scale_dps = 0.0", 3, "> 0"),
            ("quantum_dps = 0.0", "quantum_dps = -1e-3", 4, ">= 0"),
            (
                "quantum_dps = 0.0",
                "quantum_dps = 100.0",
                4,
                "below full_scale_dps",
            ),
            (
                "noise_density_deg_rth = 0.1",
                "noise_density_deg_rth = 0",
                5,
                "> 0",
            ),
            (
                "noise_density_deg_rth = 0.1",
                "noise_density_deg_rth = inf",
                5,
                "> 0",
            ),
            ("drift_bound_dph = 10.0", "drift_bound_dph = -3", 6, "> 0"),
        ] {
            let e = err(&GOOD.replace(from, to));
            let key = to.split(' ').next().expect("key");
            let col = key.len() + 4;
            assert!(
                e.starts_with(&format!("my.toml:{line}:{col}: {key} = ")),
                "{e}"
            );
            assert!(e.contains(what), "{e}");
        }
        // Too small for f32 once converted.
        let e = err(&GOOD.replace("drift_bound_dph = 10.0", "drift_bound_dph = 1e-300"));
        assert!(e.starts_with("my.toml:6:19: "), "{e}");
        assert!(e.contains("f32"), "{e}");
        // Empty name; another temperature column than temp_c.
        let e = err(&GOOD.replace("\"mine\"", "\" \""));
        assert!(e.starts_with("my.toml:1:8: name"), "{e}");
        let e = err(&format!("{GOOD}[temperature]\ncolumn = \"case_c\"\n"));
        assert!(e.starts_with("my.toml:8:10: "), "{e}");
        assert!(e.contains("temp_c"), "{e}");
        // Not TOML.
        let e = err("name = \"x\"\nsample_rate_hz = = 3\n");
        assert!(e.starts_with("my.toml:2:"), "{e}");
    }

    #[test]
    fn missing_field_names_file_and_line() {
        let e = err(&GOOD.replace("drift_bound_dph = 10.0\n", ""));
        assert!(e.starts_with("my.toml:1:1: "), "{e}");
        assert!(e.contains("missing field `drift_bound_dph`"), "{e}");
        let e = err("");
        assert!(e.starts_with("my.toml"), "{e}");
        assert!(e.contains("missing field"), "{e}");
    }

    #[test]
    fn arg_is_a_builtin_a_file_or_refused() {
        assert_eq!(
            SensorSpec::from_arg("kvh1750").expect("built-in").config,
            SensorConfig::KVH_DSP_1750
        );
        let dir = tempfile::tempdir().expect("test");
        let p = dir.path().join("mine.toml");
        std::fs::write(&p, GOOD).expect("test");
        let s = parse_sensor_arg(&p.display().to_string()).expect("file");
        assert_eq!((s.name.as_str(), s.config.sample_rate_hz), ("mine", 50.0));
        let e = parse_sensor_arg("ecore").expect_err("unknown");
        assert!(e.contains("ecore2000, kvh1750"), "{e}");
        assert!(e.contains(".toml"), "{e}");
        let missing = dir.path().join("none.toml").display().to_string();
        let e = parse_sensor_arg(&missing).expect_err("missing");
        assert!(e.starts_with(&missing), "{e}");
    }

    #[test]
    fn line_col_counts_characters() {
        assert_eq!(line_col("ab\ncd", 0), (1, 1));
        assert_eq!(line_col("ab\ncd", 4), (2, 2));
        assert_eq!(line_col("é\nx", 3), (2, 1));
        assert_eq!(line_col("éx", 2), (1, 2));
        assert_eq!(line_col("x", 99), (1, 2));
    }
}
