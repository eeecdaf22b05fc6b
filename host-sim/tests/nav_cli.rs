//! `host-sim replay` (motion preset, the default) on records with truth: the navigator's
//! scores beside the causal baselines, `--json`, the report's heading-error figure, the
//! sensor option.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// Deterministic white noise of standard deviation `sigma` (sum of 12 uniforms).
struct Noise(u64);
impl Noise {
    fn next(&mut self, sigma: f64) -> f64 {
        let mut s = 0.0;
        for _ in 0..12 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            s += (self.0 >> 11) as f64 / (1u64 << 53) as f64;
        }
        (s - 6.0) * sigma
    }
}

const DRIFT_DPS: f64 = 0.002; // 7.2 deg/h, inside the E-Core bound (30 deg/h)

/// 200 s at 100 Hz: still, a 10-deg/s turn from 100 s to 110 s (`moving` = 1), still.
/// `rate = true + DRIFT_DPS + noise` (the E-Core noise model's per-sample sigma).
/// Returns the path and the expected no-compensation heading error at the end (trapezoid of
/// `rate - true` over `t_s`, computed here independently) and its RMS.
fn record(dir: &Path) -> (PathBuf, f64, f64) {
    let sigma = 0.001_111_11 * 10.0;
    let mut n = Noise(7);
    let mut text = String::from("t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving\n");
    let (mut h, mut prev, mut sum_sq, mut count) = (0.0f64, None::<(f64, f64)>, 0.0, 0u32);
    for k in 0..20_000u32 {
        let t = f64::from(k) * 0.01;
        let moving = (100.0..110.0).contains(&t);
        let truth = if moving { 10.0 } else { 0.0 };
        // Written with the precision the reader parses back to (f32 rate).
        let rate = f64::from((truth + DRIFT_DPS + n.next(sigma)) as f32);
        let e = rate - truth;
        if let Some((t0, e0)) = prev {
            h += 0.5 * (e0 + e) * (t - t0);
        }
        prev = Some((t, e));
        sum_sq += h * h;
        count += 1;
        text += &format!("{t},{rate},25,{DRIFT_DPS},{truth},{}\n", u8::from(moving));
    }
    let p = dir.join("turn.csv");
    fs::write(&p, text).expect("test");
    (p, h, (sum_sq / f64::from(count)).sqrt())
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(p).expect("json")).expect("json parses")
}

#[test]
fn scores_beside_the_baselines_with_a_hand_checkable_heading_error() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (rec, h_end, h_rms) = record(d);
    // Without compensation the heading error is the integral of the drift and noise:
    // about DRIFT_DPS * 200 s = 0.4 deg at the end.
    assert!((h_end - 0.4).abs() < 0.05, "{h_end}");
    let j = d.join("s.json");
    let a = host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--output")
        .arg(d.join("out.csv"))
        .arg("--json")
        .arg(&j)
        .assert()
        .success();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    for want in [
        "heading error RMS: motion identifier",
        "no compensation",
        "alignment bias",
        "gated random-walk Kalman (ZARU)",
        "gated Kalman + temperature regression",
        "gated Kalman, own detector (alignment-calibrated)",
        "detector: false-still",
    ] {
        assert!(err.contains(want), "missing {want}: {err}");
    }
    let s = json(&j);
    let rows = s["scores"]["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 6);
    assert_eq!(rows[0]["name"], "motion identifier");
    let sc = |i: usize, k: &str| rows[i]["scores"][k].as_f64().expect(k);
    // The no-compensation row is the hand computation.
    assert!((sc(1, "heading_final_deg") - h_end).abs() < 1e-9);
    assert!((sc(1, "heading_rms_deg") - h_rms).abs() < 1e-9);
    assert!((sc(1, "e_truth_still_dph") - DRIFT_DPS * 3600.0).abs() < 1e-5);
    assert!((sc(1, "e_truth_moving_dph") - DRIFT_DPS * 3600.0).abs() < 1e-5);
    // The identifier learns the drift in the first 100 s still and keeps it through the turn;
    // so do the gated baselines: each well below no compensation, the turn never learnt (the
    // last, with its own detector, although its 120-s alignment holds the turn).
    for i in [0, 2, 3, 4, 5] {
        assert!(
            sc(i, "heading_rms_deg") < 0.3 * h_rms,
            "row {i}: {} vs {h_rms}",
            sc(i, "heading_rms_deg")
        );
        assert!(sc(i, "e_truth_moving_dph") < 3.0, "row {i}");
    }
    let det = &s["scores"]["detector"];
    assert_eq!(det["moving_samples"], 1000);
    assert_eq!(det["still_samples"], 19_000);
    assert!(det["false_still_rate"].as_f64().expect("rate") < 0.2);
    assert!(det["missed_still_rate"].as_f64().expect("rate") < 0.2);
    assert_eq!(
        s["scores"]["baselines"]["q_source"],
        "the image's model (rate random walk and Gauss-Markov terms)"
    );
}

/// Every tick label of every SVG in `dir`: no `e-` exponents (e.g. `6.939e-18`).
fn assert_readable_ticks(dir: &Path) -> usize {
    let mut svgs = 0;
    for e in fs::read_dir(dir).expect("dir") {
        let p = e.expect("entry").path();
        if p.extension().is_some_and(|x| x == "svg") {
            svgs += 1;
            let svg = fs::read_to_string(&p).expect("svg");
            for label in svg
                .split("<text")
                .skip(1)
                .filter_map(|s| s.split('>').nth(1))
                .map(|s| s.split('<').next().unwrap_or("").trim())
            {
                let looks_exp = label.contains("e-") && label.parse::<f64>().is_ok();
                assert!(!looks_exp, "{}: tick label {label}", p.display());
            }
        }
    }
    svgs
}

#[test]
fn report_has_the_heading_error_figure_and_readable_axes() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (rec, _, _) = record(d);
    let rep = d.join("rep");
    host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--output")
        .arg(d.join("out.csv"))
        .args(["--baseline-q-dps2", "1e-12", "--report"])
        .arg(&rep)
        .assert()
        .success();
    let html = fs::read_to_string(rep.join("index.html")).expect("html");
    let head = html
        .find("heading error RMS: motion identifier")
        .expect("headline");
    let fig = html.find("id=\"heading_error.svg\"").expect("figure");
    assert!(head < fig, "headline first");
    let svg = fs::read_to_string(rep.join("heading_error.svg")).expect("svg");
    for want in [
        "heading error (deg)",
        "time since power-on (s)",
        "still (truth)",
        "motion identifier",
        "gated random-walk Kalman (ZARU)",
        "<rect",
    ] {
        assert!(svg.contains(want), "missing {want}");
    }
    assert!(!svg.contains("no compensation"), "left out of the figure");
    assert!(fs::read_to_string(rep.join("drift.svg"))
        .expect("svg")
        .contains("drift (deg/h)"));
    let corr = fs::read_to_string(rep.join("heading_correction.svg")).expect("svg");
    assert!(
        corr.contains("heading correction (deg)") && corr.contains("integral of the true drift")
    );
    assert_eq!(assert_readable_ticks(&rep), 4);
    let s = json(&rep.join("summary.json"));
    assert_eq!(s["scores"]["baselines"]["q_source"], "--baseline-q-dps2");
    assert_eq!(s["scores"]["baselines"]["q_dps2"], 1e-12);
}

#[test]
fn baseline_q_tuned_on_validation_records() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (rec, _, _) = record(d);
    let j = d.join("s.json");
    host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--validate")
        .arg(&rec)
        .arg("--output")
        .arg(d.join("out.csv"))
        .arg("--json")
        .arg(&j)
        .assert()
        .success();
    let s = json(&j);
    let src = s["scores"]["baselines"]["q_source"].as_str().expect("str");
    assert!(src.starts_with("tuned on 1 validation records"), "{src}");
}

#[test]
fn sensor_option_sets_full_scale_and_rate() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    // 1 kHz, a 200 deg/s turn: the E-Core's 60 deg/s full scale is exceeded.
    let mut text = String::from("t_s,rate_dps\n");
    for k in 0..5000 {
        let t = f64::from(k) * 0.001;
        text += &format!("{t},{}\n", if t > 2.0 && t < 3.0 { 200.0 } else { 0.0 });
    }
    let rec = d.join("fast.csv");
    fs::write(&rec, &text).expect("test");
    let out = d.join("o.csv");
    let a = host_sim()
        .args(["replay", "--gyro", "kvh1750", "--input"])
        .arg(&rec)
        .arg("--output")
        .arg(&out)
        .assert()
        .success();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(err.contains("full scale 490 deg/s, 1000 Hz"), "{err}");
    assert!(!err.contains("beyond the sensor's full scale"), "{err}");
    // The E-Core sensor at 1 kHz: refused, naming the rates; nothing written.
    let out2 = d.join("o2.csv");
    host_sim()
        .args(["replay", "--gyro", "ecore2000", "--input"])
        .arg(&rec)
        .arg("--output")
        .arg(&out2)
        .assert()
        .failure()
        .stderr(predicates::str::contains("1000"));
    assert!(!out2.exists());
    // The E-Core at its own rate with a 200 deg/s turn: replayed, with a full-scale warning.
    let mut text = String::from("t_s,rate_dps\n");
    for k in 0..500 {
        text += &format!(
            "{},{}\n",
            f64::from(k) * 0.01,
            if k == 250 { 200.0 } else { 0.0 }
        );
    }
    fs::write(&rec, &text).expect("test");
    host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--output")
        .arg(&out2)
        .assert()
        .success()
        .stderr(predicates::str::contains(
            "1 samples at or beyond the sensor's full scale (60 deg/s",
        ));
}
