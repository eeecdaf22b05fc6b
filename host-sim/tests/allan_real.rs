//! `host-sim allan` on what a user brings: a record that turns (refused, or analysed
//! against its reference rate), a record too short for its longest taus, no `--json`, and
//! the real curves of `../shared/data/real` (tests that read them skip without it).
//! The full sweep of every real record and axis is `scripts/allan_real_table.py`.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

fn real(rel: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real")
        .join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIPPED: {} absent (no ../shared)", p.display());
        None
    }
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(path).expect("json")).expect("valid JSON")
}

fn stdout(a: &assert_cmd::assert::Assert) -> String {
    String::from_utf8_lossy(&a.get_output().stdout).to_string()
}

fn stderr(a: &assert_cmd::assert::Assert) -> String {
    String::from_utf8_lossy(&a.get_output().stderr).to_string()
}

/// 300 s of the ecore2000 preset's noise at 100 Hz (`simulate`), as (t_s, rate_dps) text
/// rows.
fn static_noise(dir: &Path) -> Vec<(String, f64)> {
    let sim = dir.join("sim.csv");
    host_sim()
        .args(["simulate", "--preset", "ecore2000", "--duration-s", "300"])
        .args(["--seed", "3", "--output"])
        .arg(&sim)
        .assert()
        .success();
    let text = fs::read_to_string(&sim).expect("sim");
    text.lines()
        .skip(1)
        .map(|l| {
            let mut f = l.split(',');
            let t = f.next().expect("t").to_string();
            let r: f64 = f.next().expect("rate").parse().expect("number");
            (t, r)
        })
        .collect()
}

/// A record that turns 180 deg (30 deg/s for 6 s from t = 100 s) is refused with `gap`'s
/// static test, naming when it moves and what to do; nothing is written. With the turn as
/// its reference (`--reference-column table_dps`) the residual is analysed, and its Allan
/// deviation is the static noise's.
#[test]
fn a_record_that_turns_is_refused_unless_its_reference_is_given() {
    let dir = tempfile::tempdir().expect("tmp");
    let noise = static_noise(dir.path());
    let (mut turning, mut still) = (
        String::from("t_s,rate_dps,table_dps\n"),
        String::from("t_s,rate_dps\n"),
    );
    for (i, (t, r)) in noise.iter().enumerate() {
        let table = if (10_000..10_600).contains(&i) {
            30.0
        } else {
            0.0
        };
        turning.push_str(&format!("{t},{},{table}\n", r + table));
        still.push_str(&format!("{t},{r}\n"));
    }
    let input = dir.path().join("turn.csv");
    fs::write(&input, turning).expect("write");
    let out = dir.path().join("turn.json");
    let a = host_sim()
        .args(["allan", "--input"])
        .arg(&input)
        .arg("--json")
        .arg(&out)
        .assert()
        .failure();
    let err = stderr(&a);
    assert!(err.contains("not a static record"), "{err}");
    assert!(err.contains("from t = 100.0 s"), "{err}");
    assert!(
        err.contains("--reference-column") && err.contains("static part"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written for a refused record");

    let a = host_sim()
        .args(["allan", "--input"])
        .arg(&input)
        .arg("--json")
        .arg(&out)
        .args(["--reference-column", "table_dps"])
        .assert()
        .success();
    assert!(stderr(&a).contains("reference `table_dps` subtracted"));
    let turned = json(&out);
    assert_eq!(turned["reference_column"], "table_dps");
    let plain = dir.path().join("still.csv");
    fs::write(&plain, still).expect("write");
    let still_json = dir.path().join("still.json");
    host_sim()
        .args(["allan", "--input"])
        .arg(&plain)
        .arg("--json")
        .arg(&still_json)
        .assert()
        .success();
    let still = json(&still_json);
    let (p, q) = (
        turned["points"].as_array().expect("points"),
        still["points"].as_array().expect("points"),
    );
    assert_eq!(p.len(), q.len());
    for (a, b) in p.iter().zip(q) {
        let (a, b) = (
            a["adev_dps"].as_f64().expect("a"),
            b["adev_dps"].as_f64().expect("b"),
        );
        assert!((a / b - 1.0).abs() < 1e-6, "{a} {b}");
    }
    // A reference column the file lacks is named.
    host_sim()
        .args(["allan", "--input"])
        .arg(&plain)
        .args(["--reference-column", "table_dps"])
        .assert()
        .failure()
        .stderr(predicates::str::contains("missing column `table_dps`"));
}

/// The KVH 1750 log that turns 180 deg about x (issue 44: `allan` kept K = 1.7e7
/// deg/h/sqrt(h) on it) is refused, saying why and what to do.
#[test]
fn the_kvh_turning_log_is_refused() {
    let Some(rec) = real("kvh1750_fog_yoos/kvh_direct_ext_rate.csv") else {
        return;
    };
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("kvh.json");
    let a = host_sim()
        .args(["allan", "--input"])
        .arg(&rec)
        .arg("--json")
        .arg(&out)
        .args(["--rate-column", "dtheta_x_deg", "--rate-scale", "1000"])
        .args(["--rate-hz", "1000"])
        .assert()
        .failure();
    let err = stderr(&a);
    assert!(
        err.contains("kvh_direct_ext_rate.csv: not a static record"),
        "{err}"
    );
    assert!(
        err.contains("cut the record to its static part") && err.contains("--reference-column"),
        "{err}"
    );
    assert!(!out.exists());
}

/// The first 1.9 s of the KVH log (its static lead-in, cut here at run time): the taus with
/// fewer than 9 independent clusters (0.256 and 0.512 s) are named and not fitted, and a
/// bias instability is never reported without saying that the curve still falls at the
/// longest supported tau (issue 44: B = 13.1 deg/h without a word).
#[test]
fn a_short_record_names_its_unsupported_taus_and_bounds_b() {
    let Some(rec) = real("kvh1750_fog_yoos/kvh_direct_ext_rate.csv") else {
        return;
    };
    let dir = tempfile::tempdir().expect("tmp");
    let text = fs::read_to_string(&rec).expect("kvh");
    let lead: Vec<&str> = text.lines().take(1 + 1900).collect();
    let input = dir.path().join("kvh_first_1.9s.csv");
    fs::write(&input, lead.join("\n") + "\n").expect("write");
    let out = dir.path().join("lead.json");
    let a = host_sim()
        .args(["allan", "--input"])
        .arg(&input)
        .arg("--json")
        .arg(&out)
        .args(["--rate-column", "dtheta_x_deg", "--rate-scale", "1000"])
        .args(["--rate-hz", "1000"])
        .assert()
        .success();
    let text = stdout(&a);
    assert!(
        text.contains(
            "too long for the record: tau 0.256, 0.512 s hold fewer than 9 independent clusters"
        ),
        "{text}"
    );
    let v = json(&out);
    let pts = v["points"].as_array().expect("points");
    for p in pts {
        let tau = p["tau_s"].as_f64().expect("tau");
        assert_eq!(p["supported"], tau < 0.2, "{p}");
    }
    assert_eq!(
        v["fit"]["n_points"], 8,
        "only the supported taus are fitted"
    );
    let b_active = v["fit"]["terms"]
        .as_array()
        .expect("terms")
        .iter()
        .any(|t| t["symbol"] == "B" && t["active"] == true);
    let word = if b_active {
        "is not a bias instability this record shows: the curve still falls"
    } else {
        "no bias-instability floor: the curve still falls"
    };
    assert!(text.contains(word), "{text}");
    assert!(text.contains("a longer record measures it"), "{text}");
}

/// Without `--json` the summary goes to stdout and nothing is written; with it the JSON's
/// `summary` is the same lines.
#[test]
fn json_is_optional_and_the_summary_is_on_stdout() {
    let dir = tempfile::tempdir().expect("tmp");
    let noise = static_noise(dir.path());
    let mut text = String::from("t_s,rate_dps\n");
    for (t, r) in &noise {
        text.push_str(&format!("{t},{r}\n"));
    }
    let input = dir.path().join("still.csv");
    fs::write(&input, text).expect("write");
    let before = fs::read_dir(dir.path()).expect("dir").count();
    let a = host_sim()
        .args(["allan", "--input"])
        .arg(&input)
        .assert()
        .success();
    let out = stdout(&a);
    assert!(out.contains("still.csv: least Allan deviation"), "{out}");
    assert!(out.contains("  fit: reduced chi-square"), "{out}");
    assert!(out.contains("too long for the record"), "{out}");
    assert_eq!(
        fs::read_dir(dir.path()).expect("dir").count(),
        before,
        "nothing written without --json"
    );
    let path = dir.path().join("still.json");
    let b = host_sim()
        .args(["allan", "--input"])
        .arg(&input)
        .arg("--json")
        .arg(&path)
        .assert()
        .success();
    let v = json(&path);
    let lines: Vec<String> = v["summary"]
        .as_array()
        .expect("summary")
        .iter()
        .map(|l| l.as_str().expect("line").to_string())
        .collect();
    assert_eq!(stdout(&b).lines().collect::<Vec<_>>(), lines);
    assert_eq!(stdout(&b), out);
}

/// Runs `allan` on `input` with `args` and checks issue 43's goal on its JSON: every
/// supported point within 25 % of the fit or named as not followed, the unsupported taus
/// named, model uncertainty at most 50 %. Returns the JSON.
fn followed_or_named(input: &Path, args: &[&str], dir: &Path, tag: &str) -> serde_json::Value {
    let out = dir.join(format!("{tag}.json"));
    let a = host_sim()
        .args(["allan", "--input"])
        .arg(input)
        .arg("--json")
        .arg(&out)
        .args(args)
        .assert()
        .success();
    let text = stdout(&a);
    let v = json(&out);
    let named: Vec<f64> = v["fit"]["not_followed"]
        .as_array()
        .expect("not_followed")
        .iter()
        .map(|m| m["tau_s"].as_f64().expect("tau"))
        .collect();
    let mut unsupported = 0;
    for p in v["points"].as_array().expect("points") {
        let tau = p["tau_s"].as_f64().expect("tau");
        let e =
            p["fit_adev_dps"].as_f64().expect("fit") / p["adev_dps"].as_f64().expect("adev") - 1.0;
        if p["supported"] == true {
            assert!(
                e.abs() <= 0.25 || named.iter().any(|&t| (t - tau).abs() < 1e-9 * tau),
                "{tag}: tau {tau} s off by {:.0} % and not named\n{text}",
                100.0 * e
            );
        } else {
            unsupported += 1;
        }
    }
    if unsupported > 0 {
        assert!(text.contains("too long for the record"), "{tag}: {text}");
    }
    let rel = v["fit"]["model_rel"].as_f64().expect("model_rel");
    assert!(rel <= 0.5, "{tag}: model uncertainty {rel}\n{text}");
    eprintln!(
        "{tag}: model uncertainty {:.1} %, {} not followed, {unsupported} unsupported",
        100.0 * rel,
        named.len()
    );
    v
}

/// Issue 43's goal on the cheap real records (the MPU-6050 10-min static record, the
/// Xsens MTi's first 50 s, the KVH's first 1.9 s; every axis): every supported point within
/// 25 % of the fit or named, model uncertainty <= 50 %. (Before: the MPU x axis was 35 %
/// off at 41 s without a word, the Xsens x 44 % at 5 s.)
#[test]
fn real_curves_are_followed_or_the_range_is_named() {
    let (Some(mpu), Some(xsens), Some(kvh)) = (
        real("mpu6050_sunsided/unmoved-with-x-pointing-forward-10min.csv"),
        real("xsens_mti_imutk/xsens_mti_raw.csv"),
        real("kvh1750_fog_yoos/kvh_direct_imu_rate.csv"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    for ax in ["x", "y", "z"] {
        let col = format!("g{ax}_dps");
        followed_or_named(&mpu, &["--rate-column", &col], d, &format!("mpu_{ax}"));
    }
    let text = fs::read_to_string(&xsens).expect("xsens");
    let lead: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(i, l)| {
            *i == 0
                || l.split(',')
                    .next()
                    .and_then(|t| t.parse::<f64>().ok())
                    .is_some_and(|t| t < 50.0)
        })
        .map(|(_, l)| l)
        .collect();
    let xs = d.join("xsens_first_50s.csv");
    fs::write(&xs, lead.join("\n") + "\n").expect("write");
    for (ax, gain) in [("x", 4778.0), ("y", 4758.0), ("z", 4766.0)] {
        let col = format!("g{ax}_counts");
        let scale = format!("{}", 180.0 / std::f64::consts::PI / gain);
        followed_or_named(
            &xs,
            &["--rate-column", &col, "--rate-scale", &scale],
            d,
            &format!("xsens_{ax}"),
        );
    }
    let text = fs::read_to_string(&kvh).expect("kvh");
    let lead: Vec<&str> = text.lines().take(1 + 1828).collect();
    let k = d.join("kvh_imu_first_1.9s.csv");
    fs::write(&k, lead.join("\n") + "\n").expect("write");
    for ax in ["x", "y", "z"] {
        let col = format!("dtheta_{ax}_deg");
        followed_or_named(
            &k,
            &[
                "--rate-column",
                &col,
                "--rate-scale",
                "1000",
                "--rate-hz",
                "962.4",
            ],
            d,
            &format!("kvh_{ax}"),
        );
    }
}

/// A curve like the withheld ring-laser gyro's (issue 43: ADEV falling as tau^-1 to about
/// 1 s, then flat; `allan` gave a Q term only at 100 % model uncertainty): the first hour
/// of ADIS16405 run 1 z with its angle counted in coarse quanta (integrated, rounded to
/// 0.15 deg, differenced; the bias makes the counts a pattern near 2 Hz, like a dither
/// band): its ADEV falls from 9,500 deg/h at 0.01 s, as tau^-1 from 0.16 s to 1.28 s, to a
/// floor of 34 deg/h near 40-80 s. The fit keeps a quantization term, describes the hump, and follows every
/// supported point within 25 % or names it, at a model uncertainty <= 50 % (before: 52 %,
/// the fit 2.1 times the 0.01-s point, nothing named).
#[test]
fn an_angle_counted_real_record_is_followed() {
    let Some(rec) = real("adis16405_calgary/adis16405_run1_gyro.csv") else {
        return;
    };
    let dir = tempfile::tempdir().expect("tmp");
    let text = fs::read_to_string(&rec).expect("adis");
    let quantum_deg = 0.15;
    let (mut angle, mut counted) = (0.0f64, 0.0f64);
    let mut out = String::from("t_s,rate_dps\n");
    for line in text.lines().skip(1).take(360_000) {
        let f: Vec<&str> = line.split(',').collect();
        let rate: f64 = f[3].parse().expect("gz");
        angle += rate * 0.01;
        let now = (angle / quantum_deg).round() * quantum_deg;
        out.push_str(&format!("{},{}\n", f[0], (now - counted) / 0.01));
        counted = now;
    }
    let input = dir.path().join("adis_counted.csv");
    fs::write(&input, out).expect("write");
    let v = followed_or_named(&input, &[], dir.path(), "counted");
    let terms = v["fit"]["terms"].as_array().expect("terms");
    let active = |s: &str| {
        terms
            .iter()
            .any(|t| t["symbol"] == s && t["active"] == true)
    };
    assert!(active("Q"), "a quantization term: {terms:?}");
    assert!(
        active("sigma_band") || active("sigma_gm"),
        "the hump described: {terms:?}"
    );
    // The curve does fall as about tau^-1 to 1 s (from the pattern's period on), then
    // flattens.
    let pts = v["points"].as_array().expect("points");
    let adev = |tau: f64| {
        pts.iter()
            .find(|p| (p["tau_s"].as_f64().expect("tau") - tau).abs() < 1e-6)
            .and_then(|p| p["adev_dps"].as_f64())
            .expect("point")
    };
    let slope = (adev(1.28) / adev(0.16)).ln() / 8f64.ln();
    assert!((-1.15..-0.8).contains(&slope), "slope 0.16-1.28 s: {slope}");
    assert!(adev(81.92) > 0.5 * adev(20.48), "flat beyond 20 s");
}
