//! One reader for every subcommand: `allan`, `denoise`, `gap`, `identify` and `replay` read
//! the same `.csv.gz` multi-column record with the same options (`--rate-column`,
//! `--rate-scale`, `--rate-hz` without `t_s`) and refuse a missing column with the same
//! message (file, line 1, the header).

use assert_cmd::Command;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// `n` rows at 100 Hz of white noise in rad/s in column `gz_rads` beside `temp_c`, without
/// `t_s`, gzip-compressed.
fn gz_record(dir: &Path, n: usize) -> PathBuf {
    let mut text = String::from("temp_c,gz_rads\n");
    let mut x = 12345u64;
    for _ in 0..n {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        text += &format!("25,{}\n", 1e-4 * u);
    }
    let p = dir.join("rec.csv.gz");
    let mut gz = flate2::write::GzEncoder::new(
        fs::File::create(&p).expect("create"),
        flate2::Compression::default(),
    );
    gz.write_all(text.as_bytes()).expect("write");
    gz.finish().expect("finish");
    p
}

const RAD: &str = "57.29577951308232";

/// The rate options of the record: its rate in rad/s in `gz_rads`, 100 Hz, no `t_s`.
const RATE_OPTIONS: [&str; 6] = [
    "--rate-column",
    "gz_rads",
    "--rate-scale",
    RAD,
    "--rate-hz",
    "100",
];

#[test]
fn allan_and_denoise_read_a_gz_record_without_t_s_with_the_rate_options() {
    let dir = tempfile::tempdir().expect("tmp");
    let rec = gz_record(dir.path(), 2048);
    let json = dir.path().join("a.json");
    host_sim()
        .args(["allan", "--input"])
        .arg(&rec)
        .arg("--json")
        .arg(&json)
        .args(RATE_OPTIONS)
        .assert()
        .success();
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("JSON");
    assert_eq!(v["n_samples"], 2048);
    assert!(
        (v["tau0_s"].as_f64().expect("tau0") - 0.01).abs() < 1e-12,
        "{v}"
    );
    let out = dir.path().join("d.csv");
    host_sim()
        .args(["denoise", "--input"])
        .arg(&rec)
        .arg("--output")
        .arg(&out)
        .args(RATE_OPTIONS)
        .assert()
        .success();
    let text = fs::read_to_string(&out).expect("output");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("temp_c,gz_rads,denoised_dps"));
    assert_eq!(lines.count(), 2048);
    // Without `--rate-hz` a record without `t_s` is refused, naming the file and header.
    host_sim()
        .args(["allan", "--input"])
        .arg(&rec)
        .arg("--json")
        .arg(&json)
        .args(["--rate-column", "gz_rads"])
        .assert()
        .failure()
        .stderr(predicates::str::contains(
            "rec.csv.gz:1: missing column `t_s` (the header has: temp_c, gz_rads)",
        ));
}

#[test]
fn a_missing_rate_column_is_the_same_message_in_every_command() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let rec = d.join("x.csv");
    let mut text = String::from("t_s,rate_dps\n");
    for k in 0..3000 {
        text += &format!("{},0.001\n", k as f64 * 0.01);
    }
    fs::write(&rec, text).expect("write");
    let s = |p: PathBuf| p.to_string_lossy().into_owned();
    let (json, out) = (s(d.join("o.json")), s(d.join("o.csv")));
    let r = s(rec.clone());
    let commands: Vec<Vec<&str>> = vec![
        vec!["allan", "--input", &r, "--json", &json],
        vec!["denoise", "--input", &r, "--output", &out],
        vec!["gap", "--rounds", "1", "--input", &r, "--json", &json],
        vec![
            "identify",
            "--preset",
            "level-trend",
            "--train",
            &r,
            "--validate",
            &r,
            "--json",
            &json,
        ],
        vec!["replay", "--input", &r, "--output", &out],
    ];
    for c in &commands {
        host_sim()
            .args(c)
            .args(["--rate-column", "gz_dps"])
            .assert()
            .failure()
            .stderr(predicates::str::contains(
                "x.csv:1: missing column `gz_dps` (the header has: t_s, rate_dps)",
            ));
    }
}
