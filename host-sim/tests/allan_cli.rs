//! `host-sim allan` end to end: JSON and SVG from a simulated record, bad inputs.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// Simulates `duration_s` of white + flicker noise at 10 Hz into `dir/name`.
fn simulated(dir: &Path, name: &str, duration_s: &str) -> PathBuf {
    let model = dir.join("m.toml");
    fs::write(
        &model,
        "sample_rate_hz = 10.0\narw_deg_per_rth = 0.06\nbias_instability_dph = 0.72\n[noise]\nflicker_tau_min_s = 0.5\n",
    )
    .expect("write model");
    let out = dir.join(name);
    host_sim()
        .args(["simulate", "--gyro"])
        .arg(&model)
        .args(["--duration-s", duration_s, "--seed", "5", "--output"])
        .arg(&out)
        .assert()
        .success();
    out
}

fn allan(input: &Path, json: &Path, extra: &[&str]) -> assert_cmd::assert::Assert {
    host_sim()
        .args(["allan", "--input"])
        .arg(input)
        .arg("--json")
        .arg(json)
        .args(extra)
        .assert()
}

#[test]
fn json_and_svg() {
    let dir = tempfile::tempdir().expect("tmp");
    let input = simulated(dir.path(), "r.csv", "3000");
    let json = dir.path().join("a.json");
    let svg = dir.path().join("a.svg");
    let a = allan(&input, &json, &["--svg", &svg.to_string_lossy()]).success();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(
        stderr.contains("tau0 = 0.1 s (mean t_s step, gaps left out"),
        "{stderr}"
    );
    let stdout = String::from_utf8_lossy(&a.get_output().stdout).to_string();
    assert!(stdout.contains("least Allan deviation"), "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("valid JSON");
    let tau0 = v["tau0_s"].as_f64().expect("tau0");
    assert!((tau0 - 0.1).abs() < 1e-9);
    assert_eq!(v["n_samples"], 30_000);
    let pts = v["points"].as_array().expect("points");
    assert_eq!(pts.len(), 14, "octave m = 1 .. 8192");
    for p in pts {
        let (lo, d, hi) = (
            p["adev_lower_dps"].as_f64().expect("lo"),
            p["adev_dps"].as_f64().expect("adev"),
            p["adev_upper_dps"].as_f64().expect("hi"),
        );
        assert!(lo < d && d < hi, "{p}");
        assert!(p["edf"].as_f64().expect("edf") >= 1.0);
        assert!(p["tau_s"].as_f64().expect("tau") > 0.0);
    }
    let terms = v["fit"]["terms"].as_array().expect("terms");
    let arw = terms.iter().find(|t| t["term"] == "arw").expect("ARW term");
    assert_eq!(arw["unit"], "deg/s/sqrt(Hz)");
    assert_eq!(arw["unit_alt"], "deg/sqrt(h)");
    let n = arw["value"].as_f64().expect("N");
    assert!((n / 1e-3 - 1.0).abs() < 0.05, "N = {n}");
    assert!(arw["sigma"].as_f64().expect("sigma") > 0.0);
    let b = terms
        .iter()
        .find(|t| t["term"] == "bias_instability")
        .expect("B term");
    assert_eq!(b["unit_alt"], "deg/h");
    let svg = fs::read_to_string(&svg).expect("svg");
    assert!(svg.starts_with("<svg"));
    assert!(svg.contains("<text") && svg.contains("tau (s)"));
    assert!(svg.contains("<circle") && svg.contains("<polyline"));
}

#[test]
fn other_tau_sets_and_markov() {
    let dir = tempfile::tempdir().expect("tmp");
    let input = simulated(dir.path(), "r.csv", "200");
    let json = dir.path().join("a.json");
    let count = |extra: &[&str]| {
        allan(&input, &json, extra).success();
        let v: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("JSON");
        v["points"].as_array().map_or(0, |p| p.len())
    };
    assert_eq!(count(&["--taus", "all"]), 1000);
    let d = count(&["--taus", "decade:5", "--markov"]);
    assert!((14..=17).contains(&d), "{d}");
    allan(&input, &json, &["--taus", "decade:0"]).failure();
    allan(&input, &json, &["--taus", "weekly"]).failure();
}

fn expect_error(content: &str, needle: &str) {
    let dir = tempfile::tempdir().expect("tmp");
    let input = dir.path().join("bad.csv");
    fs::write(&input, content).expect("write");
    let json = dir.path().join("out.json");
    let svg = dir.path().join("out.svg");
    let a = allan(&input, &json, &["--svg", &svg.to_string_lossy()]).failure();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(stderr.contains(needle), "expected {needle:?} in {stderr}");
    assert!(!json.exists() && !svg.exists(), "no output left behind");
    let leftovers = fs::read_dir(dir.path())
        .expect("dir")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .count();
    assert_eq!(leftovers, 0);
}

fn rows(n: usize) -> String {
    (0..n)
        .map(|i| format!("{},{}\n", i as f64 * 0.01, ((i * 7919) % 13) as f64 * 1e-3))
        .collect()
}

#[test]
fn nan_is_refused_with_file_and_line() {
    expect_error(
        &format!("t_s,rate_dps\n{}1.0,NaN\n", rows(100)),
        "bad.csv:102: `rate_dps` is not finite",
    );
}

#[test]
fn other_bad_inputs() {
    expect_error(
        "t_s,gyro\n0,1\n",
        "bad.csv:1: missing column `rate_dps` (the header has: t_s, gyro)",
    );
    expect_error(&format!("t_s,rate_dps\n{}", rows(5)), "at least 8");
    expect_error(
        &format!("t_s,rate_dps\n{}0.5,1\n", rows(100)),
        "bad.csv:102: t_s = 0.5 does not increase",
    );
    expect_error(
        "t_s,rate_dps\n0,1\n1,1\n2,1\n3,1\n4,1\n5,1\n6,1\n7,1\n8,1\n",
        "constant rate",
    );
}

#[test]
fn gaps_are_reported() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut text = String::from("t_s,rate_dps\n");
    for i in 0..400 {
        let t = if i < 200 {
            i as f64 * 0.01
        } else {
            i as f64 * 0.01 + 1.0
        };
        text.push_str(&format!("{t},{}\n", ((i * 7919) % 13) as f64 * 1e-3));
    }
    let input = dir.path().join("gap.csv");
    fs::write(&input, text).expect("write");
    let json = dir.path().join("g.json");
    let a = allan(&input, &json, &[]).success();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(
        stderr.contains("1 gap(s)") && stderr.contains("line 202"),
        "{stderr}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("JSON");
    assert_eq!(v["gaps"], 1);
}

/// Bursty stamps (steps of 2 ms and 6 ms in turn: 250 Hz): tau0 is the mean step (4 ms), not
/// the median (which alternates the two), and stderr says the stamps are irregular; the
/// same samples as a `.csv.gz` with the rate in rad/s in another column give the same tau0
/// and, scaled back with `--rate-scale`, the same deviations.
#[test]
fn bursty_stamps_gz_and_a_rate_column() {
    let dir = tempfile::tempdir().expect("tmp");
    let (mut plain, mut rad) = (
        String::from("t_s,rate_dps\n"),
        String::from("t_s,gz_rad_s\n"),
    );
    let mut t = 0.0f64;
    for i in 0..4000u64 {
        let r = ((i * 7919) % 13) as f64 * 1e-3;
        plain.push_str(&format!("{t},{r}\n"));
        rad.push_str(&format!("{t},{}\n", r / 57.29578));
        t += if i % 2 == 0 { 0.002 } else { 0.006 };
    }
    let input = dir.path().join("bursty.csv");
    fs::write(&input, plain).expect("write");
    let gz = dir.path().join("bursty_rad.csv.gz");
    {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(
            fs::File::create(&gz).expect("gz"),
            flate2::Compression::default(),
        );
        e.write_all(rad.as_bytes()).expect("gz");
        e.finish().expect("gz");
    }
    let json = dir.path().join("b.json");
    let a = allan(&input, &json, &[]).success();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(stderr.contains("irregular stamps"), "{stderr}");
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("JSON");
    assert!(
        (v["tau0_s"].as_f64().expect("tau0") - 0.004).abs() < 1e-6,
        "{v}"
    );
    let json2 = dir.path().join("b2.json");
    allan(
        &gz,
        &json2,
        &["--rate-column", "gz_rad_s", "--rate-scale", "57.29578"],
    )
    .success();
    let w: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json2).expect("json")).expect("JSON");
    assert_eq!(v["tau0_s"], w["tau0_s"]);
    let (p, q) = (
        v["points"].as_array().expect("p"),
        w["points"].as_array().expect("q"),
    );
    assert_eq!(p.len(), q.len());
    for (a, b) in p.iter().zip(q) {
        let (a, b) = (
            a["adev_dps"].as_f64().expect("a"),
            b["adev_dps"].as_f64().expect("b"),
        );
        assert!((a / b - 1.0).abs() < 1e-5, "{a} {b}");
    }
}

/// The ADIS16405 run 1 (z, 10,000 s at 100 Hz, `../shared/data/real`): its curve is not a
/// sum of the IEEE 952 terms within its statistics (the 0.02-s point equals the 0.01-s
/// one: a band of the sensor's own noise near 20 Hz), so a hump term is fitted (a band) and
/// the model's own accuracy with it; the fit follows every supported point (1,311 s and
/// 2,621 s hold fewer than 9 clusters and are not fitted) within 25 % (with statistical
/// weights alone it ran up to 24x below them, at a reduced chi-square of 57,895; with the
/// IEEE terms alone 24 % off at 0.02 s, at 18.7 % model uncertainty). The least deviation
/// and its tau are printed. Skipped without `../shared` (a user's clone).
#[test]
fn a_real_mems_curve_is_followed_where_the_terms_can() {
    let rec = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/adis16405_calgary/adis16405_run1.csv.gz");
    if !rec.exists() {
        eprintln!("SKIPPED: {} absent (no ../shared)", rec.display());
        return;
    }
    let dir = tempfile::tempdir().expect("tmp");
    let json = dir.path().join("adis.json");
    let a = allan(&rec, &json, &["--rate-column", "gz_dps"]).success();
    let stdout = String::from_utf8_lossy(&a.get_output().stdout).to_string();
    assert!(stdout.contains("least Allan deviation 29.13"), "{stdout}");
    assert!(stdout.contains("at tau 81.92 s"), "{stdout}");
    assert!(
        stdout.contains("too long for the record: tau 1310.72, 2621.44 s"),
        "{stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("JSON");
    let fit = &v["fit"];
    let rel = fit["model_rel"].as_f64().expect("model_rel");
    assert!(rel > 0.02 && rel < 0.15, "model accuracy fitted: {rel}");
    let band = fit["band_hz"].as_array().expect("a band term");
    let lo = band[0].as_f64().expect("lo");
    assert!((10.0..30.0).contains(&lo), "{band:?}");
    let mut fitted = 0;
    for p in v["points"].as_array().expect("points") {
        let tau = p["tau_s"].as_f64().expect("tau");
        let adev = p["adev_dps"].as_f64().expect("adev");
        let model = p["fit_adev_dps"].as_f64().expect("fit");
        assert_eq!(p["supported"], tau < 1111.2, "{p}");
        if p["supported"] == true {
            fitted += 1;
            assert!(
                (model / adev - 1.0).abs() < 0.25,
                "tau {tau}: fit {model} vs {adev}"
            );
        }
    }
    assert_eq!(fitted, 17);
    assert_eq!(fit["n_points"], 17);
}
