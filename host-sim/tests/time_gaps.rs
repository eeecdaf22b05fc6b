//! Gaps in `t_s` are never silent: `identify` and `replay` take the rate from the steps that
//! are not gaps (a 10-s hole does not move it) and report every record with a gap on stderr,
//! naming the file, and in their JSON (`host_sim::record::Holes`); a record without a gap
//! gets no such line.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

mod common;

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// A static 100-Hz record, `t_s,rate_dps,temp_c`, of 4000 sample slots (40 s): white noise
/// of the E-Core's density (0.011 deg/s per sample) on a small constant drift; with `hole`,
/// the 1000 samples of 20.00 ..= 29.99 s are missing (a 10-s hole: the step from line 2001,
/// t_s 19.99 s, to line 2002, t_s 30 s).
fn record(dir: &Path, name: &str, hole: bool) -> PathBuf {
    record_of(dir, name, hole, 4000)
}

/// [`record`] of `slots` sample slots.
fn record_of(dir: &Path, name: &str, hole: bool, slots: u32) -> PathBuf {
    let mut text = String::from("t_s,rate_dps,temp_c\n");
    let mut x = 0x2545_f491_4f6c_dd1du64;
    for k in 0..slots {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        if hole && (2000..3000).contains(&k) {
            continue;
        }
        let u = (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        text += &format!("{:.2},{},25\n", f64::from(k) * 0.01, 0.0005 + 0.0385 * u);
    }
    let p = dir.join(name);
    fs::write(&p, text).expect("write the record");
    p
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(path).expect("JSON written")).expect("valid JSON")
}

fn stderr(a: &assert_cmd::assert::Assert) -> String {
    String::from_utf8_lossy(&a.get_output().stderr).to_string()
}

/// The gap line for the hole record `p`: the file, the count, the largest one's start (line
/// and time) and length, the samples missing, the rate from the other steps.
fn assert_gap_line(err: &str, p: &Path) {
    let line = err
        .lines()
        .find(|l| l.contains("gap(s) in t_s"))
        .unwrap_or_else(|| panic!("no gap line:\n{err}"));
    assert!(
        line.starts_with(&format!("{}: warning: 1 gap(s) in t_s", p.display()))
            && line.contains("the largest 10.01 s from t_s = 19.99 s (line 2001) to line 2002")
            && line.contains("1000 samples missing")
            && line.contains("rate 100.0000 Hz"),
        "{line}"
    );
}

/// The JSON's holes of the hole record.
fn assert_holes_json(h: &serde_json::Value) {
    assert_eq!(h["count"], 1, "{h}");
    assert_eq!(h["samples_missing"], 1000, "{h}");
    assert_eq!(h["largest_start_line"], 2001, "{h}");
    assert!((h["largest_s"].as_f64().expect("length") - 10.01).abs() < 1e-9);
    assert!(
        (h["rate_hz"].as_f64().expect("rate") - 100.0).abs() < 0.1,
        "{h}"
    );
}

#[test]
fn identify_takes_the_rate_from_the_steps_and_reports_the_hole() {
    let dir = tempfile::tempdir().expect("tmp");
    for (name, hole) in [("hole.csv", true), ("even.csv", false)] {
        // 90-s runs (the model's fit needs 60 s), and a second, even one (its unit-to-unit
        // spread needs two).
        let p = record_of(dir.path(), name, hole, 9000);
        let second = record_of(dir.path(), &format!("second-{name}"), false, 9000);
        let (image, out) = (dir.path().join("id.fogi"), dir.path().join("id.json"));
        let a = host_sim()
            .args(["identify", "--preset", "motion", "--input"])
            .arg(&p)
            .arg(&second)
            .arg("--save-identifier")
            .arg(&image)
            .arg("--json")
            .arg(&out)
            .assert()
            .success();
        let err = stderr(&a);
        let v = json(&out);
        // The calibration's rate: 100 Hz within 0.1 % (the mean step would say 75 Hz and
        // the sensor check refuse the record).
        let hz = v["calibration"]["runs"][0]["rate_hz"]
            .as_f64()
            .expect("rate");
        assert!((hz / 100.0 - 1.0).abs() < 1e-3, "{name}: {hz} Hz\n{err}");
        if hole {
            assert_gap_line(&err, &p);
            assert!(err.contains("assume uniform sampling"), "{err}");
            assert_holes_json(&v["holes"][0]);
        } else {
            assert!(!err.contains("gap(s)"), "{err}");
            assert_eq!(v["holes"][0]["count"], 0);
        }
    }
}

#[test]
fn replay_reports_the_hole_and_how_it_integrates_across_it() {
    let dir = tempfile::tempdir().expect("tmp");
    for (name, hole) in [("hole.csv", true), ("even.csv", false)] {
        let p = record(dir.path(), name, hole);
        let (out, summary) = (dir.path().join("out.csv"), dir.path().join("s.json"));
        let a = host_sim()
            .args(["replay", "--input"])
            .arg(&p)
            .arg("--output")
            .arg(&out)
            .arg("--json")
            .arg(&summary)
            .assert()
            .success();
        let err = stderr(&a);
        let v = json(&summary);
        // The built-in sensor picked by the record's rate: the E-Core's 100 Hz.
        assert_eq!(v["sensor"]["sample_rate_hz"], 100.0, "{err}");
        if hole {
            assert_gap_line(&err, &p);
            assert!(
                err.contains("10.000 s behind t_s") && err.contains("rate x actual dt"),
                "{err}"
            );
            assert_holes_json(&v["holes"]);
            assert_eq!(v["rows"], 3000);
        } else {
            assert!(!err.contains("gap(s)"), "{err}");
            assert_eq!(v["holes"]["count"], 0);
            assert_eq!(v["rows"], 4000);
        }
    }
}

/// `vehicle` records (truth columns) of the ecore2000 gyro, 300 s at 100 Hz, in `dir`: one
/// per seed, named `v{seed}.csv`; with `hole`, the 1000 rows of 100.00 ..= 109.99 s are
/// dropped (the step from line 10001, t_s 99.99 s, to line 10002, t_s 110 s).
fn vehicle(dir: &Path, seed: u32, hole: bool) -> PathBuf {
    let model = common::vehicle_gyro(dir, &format!("vehicle{seed}.toml"));
    let full = dir.join(format!("full{seed}.csv"));
    common::simulate(&model, 300, u64::from(seed), &full);
    let text = fs::read_to_string(&full).expect("simulated");
    let mut out = String::new();
    for (k, line) in text.lines().enumerate() {
        // Line k + 1; data row k - 1 at t_s = (k - 1) / 100 s.
        if !(hole && (10_001..11_001).contains(&k)) {
            out += line;
            out.push('\n');
        }
    }
    let p = dir.join(format!("v{seed}.csv"));
    fs::write(&p, out).expect("write the vehicle");
    fs::remove_file(&full).expect("remove");
    p
}

/// The gap lines on stderr: one per record with a hole, however often identify reads it.
fn gap_lines(err: &str) -> Vec<&str> {
    err.lines()
        .filter(|l| l.contains("gap(s) in t_s"))
        .collect()
}

/// `identify` reports the holes of every record it reads, each once, from the reads that
/// train and score on them: with the motion preset the calibration runs, the validation
/// and the tune vehicles (the JSON in that order); with level-trend (which reads its
/// records several times) the training and validation records.
#[test]
fn identify_reports_the_holes_of_every_record_it_reads_once() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let run = record_of(d, "run-hole.csv", true, 9000);
    let even = record_of(d, "run-even.csv", false, 9000);
    let (val_dir, tune_dir) = (d.join("val"), d.join("tune"));
    fs::create_dir(&val_dir).expect("mkdir");
    fs::create_dir(&tune_dir).expect("mkdir");
    let val = vehicle(&val_dir, 21, true);
    let tune = vehicle(&tune_dir, 22, true);
    let out = d.join("motion.json");
    let a = host_sim()
        .args(["identify", "--preset", "motion", "--input"])
        .arg(&run)
        .arg(&even)
        .arg("--validate")
        .arg(&val)
        .arg("--tune-on")
        .arg(&tune)
        .arg("--json")
        .arg(&out)
        .assert()
        .success();
    let err = stderr(&a);
    let v = json(&out);
    let holes = v["holes"].as_array().expect("holes");
    let names: Vec<&str> = holes
        .iter()
        .map(|h| h["record"].as_str().expect("name"))
        .collect();
    let want: Vec<String> = [&run, &even, &val, &tune]
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    assert_eq!(names, want, "runs, validation, tune");
    assert_holes_json(&holes[0]);
    assert_eq!(holes[1]["count"], 0);
    for h in [&holes[2], &holes[3]] {
        assert_eq!(h["count"], 1, "{h}");
        assert_eq!(h["samples_missing"], 1000, "{h}");
        assert_eq!(h["largest_start_line"], 10_001, "{h}");
        assert_eq!(h["largest_end_line"], 10_002, "{h}");
    }
    let lines = gap_lines(&err);
    assert_eq!(lines.len(), 3, "{err}");
    for p in [&run, &val, &tune] {
        let n = lines
            .iter()
            .filter(|l| l.starts_with(&format!("{}: warning: 1 gap(s)", p.display())))
            .count();
        assert_eq!(n, 1, "{}:\n{err}", p.display());
    }
    assert_gap_line(&err, &run);

    // level-trend: a hole in the training and in the validation record.
    let val2 = record_of(d, "val-hole.csv", true, 9000);
    let out2 = d.join("level.json");
    let a = host_sim()
        .args(["identify", "--preset", "level-trend", "--train"])
        .arg(&run)
        .arg("--validate")
        .arg(&val2)
        .arg("--json")
        .arg(&out2)
        .assert()
        .success();
    let err = stderr(&a);
    let v = json(&out2);
    let holes = v["holes"].as_array().expect("holes");
    assert_eq!(holes.len(), 2);
    assert_eq!(holes[0]["record"], run.display().to_string());
    assert_eq!(holes[1]["record"], val2.display().to_string());
    assert_holes_json(&holes[0]);
    assert_holes_json(&holes[1]);
    assert_eq!(gap_lines(&err).len(), 2, "{err}");
    assert_gap_line(&err, &run);
}
