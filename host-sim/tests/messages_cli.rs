//! Messages that tell the user what to do (issue 44): `replay`'s unit hints name the flag
//! that fixes them, a truncated `.csv.gz` is reported as such with the line reached and the
//! compressed bytes read, and each command's `--rate-hz` help speaks of that command.

use assert_cmd::Command;
use std::fs;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// A static E-Core record (100 Hz, `duration_s`, seed `seed`) simulated into `dir/name`.
fn simulated(dir: &Path, name: &str, duration_s: u32, seed: u32) -> PathBuf {
    let p = dir.join(name);
    host_sim()
        .args(["simulate", "--preset", "ecore2000", "--duration-s"])
        .arg(duration_s.to_string())
        .args(["--seed", &seed.to_string(), "--output"])
        .arg(&p)
        .assert()
        .success();
    p
}

/// `src`'s `rate_dps` column times `k`, written to `dst`.
fn scaled(src: &Path, dst: &Path, k: f64) {
    let text = fs::read_to_string(src).expect("record");
    let mut lines = text.lines();
    let header = lines.next().expect("header");
    let col = header
        .split(',')
        .position(|h| h == "rate_dps")
        .expect("rate_dps");
    let mut out = format!("{header}\n");
    for l in lines {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        f[col] = (f[col].parse::<f64>().expect("rate") * k).to_string();
        out += &(f.join(",") + "\n");
    }
    fs::write(dst, out).expect("write");
}

/// `replay --input REC --output dir/o.csv` and `extra`; its stderr's noise warning.
fn noise_warning(dir: &Path, rec: &Path, extra: &[&str]) -> String {
    let a = host_sim()
        .args(["replay", "--input"])
        .arg(rec)
        .arg("--output")
        .arg(dir.join(format!(
            "{}.out.csv",
            rec.file_stem().and_then(|s| s.to_str()).expect("name")
        )))
        .args(extra)
        .assert()
        .success();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    err.lines()
        .find(|l| l.contains("warning: the record's white noise is"))
        .unwrap_or_else(|| panic!("no noise warning: {err}"))
        .to_string()
}

/// Noise 40x the built-in sensor's (another sensor, picked by the record's rate) names
/// `--gyro` (and `--rate-scale` for a column in another unit); a deg/s column given
/// `--rate-scale 57.29578` names the fix: drop it.
#[test]
fn replay_unit_hints_name_the_flag_that_fixes_them() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let rec = simulated(d, "ecore.csv", 60, 3);
    let loud = d.join("loud.csv");
    scaled(&rec, &loud, 40.0);
    let w = noise_warning(d, &loud, &[]);
    assert!(
        w.contains("another sensor than the built-in one used"),
        "{w}"
    );
    assert!(w.contains("--gyro NAME|FILE"), "{w}");
    assert!(w.contains("--rate-scale K"), "{w}");
    // Scaled as rad/s though in deg/s: 57x the image's.
    let w = noise_warning(d, &rec, &["--rate-scale", "57.29578"]);
    assert!(w.contains("a rate in deg/s scaled as rad/s?"), "{w}");
    assert!(
        w.contains("then drop --rate-scale 57.29578 (or --rate-scale 1)"),
        "{w}"
    );
    assert!(w.contains("--gyro NAME|FILE"), "{w}");
}

/// A `.csv.gz` cut short: the error names the line reached (the first line not read whole)
/// and says the gzip data is truncated or corrupt, with the compressed bytes read; the same
/// from `allan` and `replay`, and nothing written.
#[test]
fn a_truncated_csv_gz_names_the_line_and_the_compressed_offset() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let rec = simulated(d, "whole.csv", 120, 4);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&fs::read(&rec).expect("record"))
        .expect("gzip");
    let bytes = gz.finish().expect("gzip");
    let cut = bytes.len() / 2;
    let trunc = d.join("trunc.csv.gz");
    fs::write(&trunc, &bytes[..cut]).expect("write");
    // What a gzip reader gets out of the cut file before its error: the lines read whole.
    let mut got = Vec::new();
    let mut dec = flate2::read::GzDecoder::new(&bytes[..cut]);
    let mut buf = [0u8; 4096];
    loop {
        match dec.read(&mut buf) {
            Ok(0) => panic!("a cut gzip stream must fail"),
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(_) => break,
        }
    }
    let line = got.iter().filter(|&&b| b == b'\n').count() + 1;
    assert!(line > 2, "the cut is past the header");
    for args in [
        vec!["allan", "--json", "a.json"],
        vec!["replay", "--output", "o.csv"],
    ] {
        let mut c = host_sim();
        c.current_dir(d).arg(args[0]).arg("--input").arg(&trunc);
        let a = c.args(&args[1..]).assert().failure();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        let expected = format!("trunc.csv.gz:{line}: read error at line {line}");
        assert!(err.contains(&expected), "{}: {expected} in {err}", args[0]);
        assert!(
            err.contains("the gzip data is truncated or corrupt"),
            "{err}"
        );
        assert!(
            err.contains(&format!("compressed bytes read of the file's {cut}")),
            "{err}"
        );
        assert!(!err.contains("trunc.csv.gz:0:"), "{err}");
        assert!(!d.join(args[2]).exists(), "{}: nothing written", args[0]);
    }
}

/// The `--rate-hz` paragraph of `host-sim CMD --help`.
fn rate_hz_help(cmd: &str) -> String {
    let a = host_sim().args([cmd, "--help"]).assert().success();
    let help = String::from_utf8_lossy(&a.get_output().stdout).to_string();
    let start = help
        .find("--rate-hz")
        .unwrap_or_else(|| panic!("{cmd}: no --rate-hz"));
    let rest = &help[start..];
    // Up to the next option (a line starting with spaces and `-`).
    let end = rest
        .match_indices('\n')
        .map(|(i, _)| i)
        .find(|&i| rest[i + 1..].trim_start().starts_with('-'))
        .unwrap_or(rest.len());
    rest[..end].to_string()
}

/// `allan` and `denoise` (and the other CSV readers) speak of a CSV without `t_s`, not of
/// `replay`; `replay` speaks of its captures.
#[test]
fn rate_hz_help_speaks_of_its_own_command() {
    for cmd in ["allan", "denoise", "identify", "gap"] {
        let h = rate_hz_help(cmd);
        assert!(!h.contains("replay"), "{cmd}: {h}");
        assert!(!h.contains("capture"), "{cmd}: {h}");
        assert!(h.contains("without a `t_s` column"), "{cmd}: {h}");
    }
    let h = rate_hz_help("replay");
    assert!(h.contains("captures"), "{h}");
    assert!(h.contains("without a `t_s` column"), "{h}");
}
