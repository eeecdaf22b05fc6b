//! `host-sim denoise` end to end: good input, every bad input the issue names.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// A record of `n` rows at 100 Hz: a slow sine plus deterministic pseudo-noise.
fn write_record(dir: &Path, name: &str, n: usize) -> PathBuf {
    let mut s = String::from("t_s,rate_dps,temp_c,drift_dps\n");
    let mut state = 7u32;
    for i in 0..n {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        let u = f64::from(state >> 8) / f64::from(1u32 << 24) - 0.5;
        let drift = 0.01 * (i as f64 * 0.003).sin();
        s.push_str(&format!(
            "{:.2},{},{},{}\n",
            i as f64 * 0.01,
            drift + 0.05 * u,
            25.0,
            drift
        ));
    }
    let p = dir.join(name);
    fs::write(&p, s).expect("write");
    p
}

fn run_denoise(input: &Path, output: &Path, extra: &[&str]) -> assert_cmd::assert::Assert {
    host_sim()
        .args(["denoise", "--input"])
        .arg(input)
        .arg("--output")
        .arg(output)
        .args(extra)
        .assert()
}

fn rows(path: &Path) -> Vec<Vec<String>> {
    let mut r = csv::Reader::from_path(path).expect("output readable");
    r.records()
        .map(|x| x.expect("row").iter().map(String::from).collect())
        .collect()
}

#[test]
fn keeps_every_row_and_adds_a_column() {
    let dir = tempfile::tempdir().expect("tmp");
    for n in [64usize, 1000, 1024, 1537] {
        let input = write_record(dir.path(), &format!("in{n}.csv"), n);
        let output = dir.path().join(format!("out{n}.csv"));
        run_denoise(&input, &output, &[]).success();
        let inp = rows(&input);
        let out = rows(&output);
        assert_eq!(inp.len(), out.len(), "n = {n}");
        for (a, b) in inp.iter().zip(&out) {
            assert_eq!(&b[..a.len()], &a[..], "original fields repeated exactly");
            let d: f64 = b[a.len()].parse().expect("denoised is a number");
            assert!(d.is_finite());
        }
        let header = csv::Reader::from_path(&output)
            .expect("r")
            .headers()
            .expect("h")
            .clone();
        assert_eq!(header.iter().next_back(), Some("denoised_dps"));
        // Denoising brings the rate closer to the true drift.
        let err = |col: usize| {
            out.iter()
                .map(|r| {
                    (r[col].parse::<f64>().unwrap_or(f64::NAN)
                        - r[3].parse::<f64>().unwrap_or(f64::NAN))
                    .powi(2)
                })
                .sum::<f64>()
        };
        assert!(err(4) < 0.5 * err(1), "n = {n}: {} vs {}", err(4), err(1));
    }
}

#[test]
fn block_option_and_per_level_sigma() {
    let dir = tempfile::tempdir().expect("tmp");
    let input = write_record(dir.path(), "in.csv", 3000);
    let output = dir.path().join("out.csv");
    run_denoise(
        &input,
        &output,
        &[
            "--block",
            "256",
            "--levels",
            "4",
            "--sigma",
            "per-level",
            "--rule",
            "hard",
        ],
    )
    .success();
    assert_eq!(rows(&output).len(), 3000);
    run_denoise(&input, &output, &["--block", "100"]).failure();
    run_denoise(&input, &output, &["--sigma", "-1"]).failure();
}

fn expect_error(content: Option<&str>, needle: &str) {
    let dir = tempfile::tempdir().expect("tmp");
    let input = dir.path().join("bad.csv");
    if let Some(c) = content {
        fs::write(&input, c).expect("write");
    }
    let output = dir.path().join("out.csv");
    let assert = run_denoise(&input, &output, &[]).failure();
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line: {stderr}");
    assert!(stderr.contains("bad.csv"), "names the file: {stderr}");
    assert!(stderr.contains(needle), "expected {needle:?} in {stderr}");
    assert!(!output.exists(), "no output left behind");
    let leftovers: Vec<_> = fs::read_dir(dir.path())
        .expect("dir")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "no temporary file left behind");
}

fn good_rows(n: usize) -> String {
    (0..n).map(|i| format!("{}.0,0.01\n", i)).collect()
}

#[test]
fn missing_file() {
    expect_error(None, "cannot open");
}

#[test]
fn empty_file() {
    expect_error(Some(""), "empty file");
}

#[test]
fn header_only() {
    expect_error(Some("t_s,rate_dps\n"), "no data rows");
}

#[test]
fn missing_rate_column() {
    expect_error(
        Some("t_s,gyro\n0,1\n"),
        "bad.csv:1: missing column `rate_dps`",
    );
}

#[test]
fn non_numeric_field() {
    expect_error(
        Some(&format!("t_s,rate_dps\n{}70.0,abc\n", good_rows(70))),
        "bad.csv:72: `rate_dps` is not a number",
    );
}

#[test]
fn nan_and_infinity() {
    expect_error(
        Some(&format!("t_s,rate_dps\n{}70.0,NaN\n", good_rows(70))),
        "bad.csv:72: `rate_dps` is not finite",
    );
    expect_error(
        Some(&format!("t_s,rate_dps\n{}70.0,-inf\n", good_rows(70))),
        "bad.csv:72: `rate_dps` is not finite",
    );
    // Finite, but not in single precision: said so, not "not finite".
    expect_error(
        Some(&format!("t_s,rate_dps\n{}70.0,1e300\n", good_rows(70))),
        "bad.csv:72: `rate_dps` = \"1e300\" is beyond the single-precision range",
    );
}

#[test]
fn decreasing_time() {
    expect_error(
        Some(&format!("t_s,rate_dps\n{}5.0,0.1\n", good_rows(70))),
        "bad.csv:72: t_s = 5 does not increase",
    );
}

#[test]
fn ragged_row() {
    expect_error(
        Some(&format!("t_s,rate_dps\n{}70.0\n", good_rows(70))),
        "bad.csv:72",
    );
}

#[test]
fn too_short() {
    expect_error(
        Some(&format!("t_s,rate_dps\n{}", good_rows(40))),
        "need at least 64",
    );
}

#[test]
fn refuses_to_overwrite_input() {
    let dir = tempfile::tempdir().expect("tmp");
    let input = write_record(dir.path(), "in.csv", 128);
    let before = fs::read(&input).expect("read");
    run_denoise(&input, &input, &[]).failure();
    assert_eq!(fs::read(&input).expect("read"), before);
}

#[test]
fn reports_gaps() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut s = String::from("t_s,rate_dps\n");
    for i in 0..200 {
        let t = if i < 100 {
            i as f64 * 0.01
        } else {
            5.0 + i as f64 * 0.01
        };
        s.push_str(&format!("{t:.2},0.0{}\n", i % 7));
    }
    let input = dir.path().join("gap.csv");
    fs::write(&input, s).expect("w");
    let out = dir.path().join("o.csv");
    let a = run_denoise(&input, &out, &[]).success();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(
        stderr.contains("1 gap(s)") && stderr.contains("line 102"),
        "{stderr}"
    );
}
