//! `host-sim identify` and `reproduce` end to end.

use assert_cmd::Command;
use predicates::prelude::PredicateBooleanExt;
use std::fs;
use std::path::Path;

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

fn simulate(dir: &Path, seed: u32, duration_s: u32) -> std::path::PathBuf {
    let out = dir.join(format!("rec{seed}.csv"));
    host_sim()
        .args([
            "simulate",
            "--gyro",
            "ecore2000",
            "--duration-s",
            &duration_s.to_string(),
            "--seed",
            &seed.to_string(),
            "--output",
        ])
        .arg(&out)
        .assert()
        .success();
    out
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(path).expect("report written")).expect("valid JSON")
}

#[test]
fn identify_reports_every_figure_and_the_baselines() {
    let dir = tempfile::tempdir().expect("tmp");
    let (tr, va) = (dir.path().join("train"), dir.path().join("val"));
    fs::create_dir_all(&tr).expect("mkdir");
    fs::create_dir_all(&va).expect("mkdir");
    for s in 1..=2 {
        simulate(&tr, s, 120);
    }
    simulate(&va, 9, 120);
    let out = dir.path().join("id.json");
    host_sim()
        .args(["identify", "--preset", "level-trend"])
        .arg("--train")
        .arg(&tr)
        .arg("--validate")
        .arg(&va)
        .arg("--json")
        .arg(&out)
        .assert()
        .success();
    let r = json(&out);
    for key in [
        "e_rel",
        "e_range",
        "e_max",
        "e_truth",
        "rms_err_truth_dph",
        "samples_per_s",
        "samples_to_goal",
        "config",
        "baselines",
    ] {
        assert!(r.get(key).is_some(), "missing {key}");
    }
    let e = r["e_truth"]
        .as_f64()
        .expect("finite e_truth for the level-trend preset");
    assert!(e > 0.0 && e < 2.0, "{e}");
    let names: Vec<&str> = r["baselines"]
        .as_array()
        .expect("list")
        .iter()
        .filter_map(|b| b["name"].as_str())
        .collect();
    assert!(
        names.contains(&"kalman_random_walk_q_over_r") && names.contains(&"moving_average_10s"),
        "{names:?}"
    );
    assert!(r["baselines"][0]["e_truth"].as_f64().is_some());

    // The paper's exact configuration diverges on such data: reported as null, not as a number.
    let out2 = dir.path().join("paper.json");
    host_sim()
        .args(["identify", "--preset", "paper", "--train"])
        .arg(&tr)
        .arg("--validate")
        .arg(&va)
        .arg("--json")
        .arg(&out2)
        .assert()
        .success();
    let p = json(&out2);
    assert!(
        p["e_truth"].is_null() && p["diverged_at_sample"].as_u64().is_some(),
        "{}",
        p["e_truth"]
    );
}

#[test]
fn identify_bad_input_names_the_place() {
    let dir = tempfile::tempdir().expect("tmp");
    let good = simulate(dir.path(), 1, 60);
    let bad = dir.path().join("bad.csv");
    let mut text = fs::read_to_string(&good).expect("read");
    text = text.replacen("\n0.05,", "\n0.05,NaN-oops,", 1);
    fs::write(&bad, text).expect("write");
    let out = dir.path().join("o.json");
    let a = host_sim()
        .args(["identify", "--preset", "level-trend"])
        .arg("--train")
        .arg(&bad)
        .arg("--validate")
        .arg(&good)
        .arg("--json")
        .arg(&out)
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(
        err.contains("bad.csv:7:") && err.lines().count() == 1,
        "{err}"
    );
    assert!(!out.exists());
    host_sim()
        .args(["identify", "--preset", "level-trend"])
        .arg("--train")
        .arg(dir.path().join("missing"))
        .arg("--validate")
        .arg(&good)
        .arg("--json")
        .arg(&out)
        .assert()
        .failure();
    host_sim()
        .args(["identify", "--preset", "level-trend"])
        .arg("--train")
        .arg(&good)
        .arg("--validate")
        .arg(&good)
        .args(["--hidden", "7", "--json"])
        .arg(&out)
        .assert()
        .failure();
}

#[test]
fn reproduce_runs_a_small_set() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("r.json");
    host_sim()
        .args([
            "reproduce",
            "--records",
            "3",
            "--train",
            "2",
            "--duration-s",
            "120",
            "--json",
        ])
        .arg(&out)
        .assert()
        .success();
    let r = json(&out);
    assert_eq!(r["records"], 3);
    assert_eq!(r["train_records"], 2);
    assert!(r["e_truth"].as_f64().is_some());
    host_sim()
        .args(["reproduce", "--records", "3", "--train", "3", "--json"])
        .arg(&out)
        .assert()
        .failure();
}

/// The temperature-aware presets and baselines: simulated CSVs carry `temp_c`; the
/// level-bank identifier reports the temperature-aware baselines and the drift
/// decomposition; time-temp refuses records without a temperature column, naming the file.
#[test]
fn temperature_inputs_and_baselines() {
    let dir = tempfile::tempdir().expect("tmp");
    let (tr, va) = (dir.path().join("train"), dir.path().join("val"));
    fs::create_dir_all(&tr).expect("mkdir");
    fs::create_dir_all(&va).expect("mkdir");
    for s in 1..=2 {
        simulate(&tr, s, 120);
    }
    simulate(&va, 9, 120);
    let out = dir.path().join("lb.json");
    host_sim()
        .args(["identify", "--preset", "level-bank", "--train"])
        .arg(&tr)
        .arg("--validate")
        .arg(&va)
        .arg("--json")
        .arg(&out)
        .assert()
        .success();
    let r = json(&out);
    assert!(r["e_truth"].as_f64().expect("finite").is_finite());
    let names: Vec<&str> = r["baselines"]
        .as_array()
        .expect("list")
        .iter()
        .filter_map(|b| b["name"].as_str())
        .collect();
    assert!(names.contains(&"kalman_on_rate_minus_temperature_regression"));
    assert!(names.contains(&"kalman_on_rate_minus_batch_ls_of_network_basis"));
    let dec = &r["drift_decomposition"];
    assert_eq!(dec["explained"].as_array().expect("list").len(), 3);
    assert!(dec["rms_time_varying_dph"].as_f64().expect("number") > 0.0);
    // A CSV without temp_c: time-temp refuses it and names the file.
    let bare = dir.path().join("bare.csv");
    fs::write(&bare, "t_s,rate_dps\n0,0.001\n0.01,0.002\n").expect("write");
    host_sim()
        .args(["identify", "--preset", "time-temp", "--train"])
        .arg(&bare)
        .arg("--validate")
        .arg(&bare)
        .arg("--json")
        .arg(dir.path().join("tt.json"))
        .assert()
        .failure()
        .stderr(predicates::str::contains("bare.csv").and(predicates::str::contains("temp_c")));
}
