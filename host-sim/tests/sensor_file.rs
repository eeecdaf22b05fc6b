//! `--gyro FILE`: a user's gyro file (host_sim::gyro) drives `identify --preset
//! motion` and `replay` like a built-in: the rate check uses the file's rate, the image
//! carries its configuration, and a bad file stops the command naming the file and line.

use assert_cmd::Command;
use predicates::str::contains;
use std::fs;
use std::path::Path;

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// A 50-Hz, 100 deg/s gyro file (its datasheet part).
const SENSOR_50HZ: &str = r#"# A test gyro (ASSUMED values)
name = "test50"
sample_rate_hz = 50.0
full_scale_dps = 100.0
quantum_dps = 0.0
arw_deg_per_rth = 0.0667
drift_bound_dph = 30.0

[temperature]
column = "temp_c"
"#;

/// A static 60-s E-Core record at `rate_hz`.
fn simulate(seed: u64, rate_hz: &str, out: &Path) {
    host_sim()
        .args(["simulate", "--gyro", "ecore2000", "--duration-s", "60"])
        .args([
            "--rate-hz",
            rate_hz,
            "--seed",
            &seed.to_string(),
            "--output",
        ])
        .arg(out)
        .assert()
        .success();
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(p).expect("test")).expect("json")
}

#[test]
fn identify_and_replay_use_the_files_rate() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let sensor = d.join("test50.toml");
    fs::write(&sensor, SENSOR_50HZ).expect("test");
    let (r50, r50b, r100) = (d.join("r50.csv"), d.join("r50b.csv"), d.join("r100.csv"));
    simulate(1, "50", &r50);
    simulate(3, "50", &r50b);
    simulate(2, "100", &r100);

    // A 100-Hz record against the file's 50 Hz: refused by the rate check, nothing written.
    let img = d.join("m.fogi");
    host_sim()
        .args(["identify", "--preset", "motion", "--gyro"])
        .arg(&sensor)
        .arg("--input")
        .arg(&r100)
        .arg("--save-identifier")
        .arg(&img)
        .assert()
        .failure()
        .stderr(contains(
            "sample rate 100.000 Hz, the sensor configuration says 50 Hz",
        ));
    assert!(!img.exists());

    // The 50-Hz records (two: the model's unit spread needs two): fitted; the image and the
    // report carry the file's sensor.
    let j = d.join("id.json");
    host_sim()
        .args(["identify", "--preset", "motion", "--gyro"])
        .arg(&sensor)
        .arg("--input")
        .arg(&r50)
        .arg(&r50b)
        .arg("--save-identifier")
        .arg(&img)
        .arg("--json")
        .arg(&j)
        // 100 deg/s is not the firmware decoder's 60: written for the host only.
        .arg("--force")
        .assert()
        .success();
    let report = json(&j);
    assert_eq!(report["sensor"], "test50");
    assert_eq!(report["sensor_source"], sensor.display().to_string());
    let image = host_sim::motion::read_image(&img).expect("image");
    assert_eq!(image.model.sample_rate_hz, 50.0);
    assert_eq!(image.full_scale_dps, 100.0);
    assert_eq!(image.model.drift_bound_dps, (30.0f64 / 3600.0) as f32);

    // replay with the file and no identifier: the built-in untrained model at 50 Hz.
    let out = d.join("o.csv");
    host_sim()
        .args(["replay", "--gyro"])
        .arg(&sensor)
        .arg("--input")
        .arg(&r50)
        .arg("--output")
        .arg(&out)
        .assert()
        .success()
        .stderr(contains("sensor 50 Hz / 100 deg/s (--gyro)"));
    assert!(out.exists());
    // The same sensor with the image it trained: accepted (they agree).
    let out2 = d.join("o2.csv");
    host_sim()
        .args(["replay", "--gyro"])
        .arg(&sensor)
        .arg("--identifier")
        .arg(&img)
        .arg("--input")
        .arg(&r50)
        .arg("--output")
        .arg(&out2)
        .assert()
        .success();
    // The 100-Hz record with the 50-Hz file: refused, naming both rates; nothing written.
    let out3 = d.join("o3.csv");
    host_sim()
        .args(["replay", "--gyro"])
        .arg(&sensor)
        .arg("--input")
        .arg(&r100)
        .arg("--output")
        .arg(&out3)
        .assert()
        .failure()
        .stderr(contains("50"))
        .stderr(contains("100"));
    assert!(!out3.exists());
}

#[test]
fn bad_sensor_files_and_names_are_refused() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let bad = d.join("bad.toml");
    fs::write(&bad, SENSOR_50HZ.replace("50.0", "5.0")).expect("test");
    let name = bad.display().to_string();
    host_sim()
        .args(["replay", "--gyro", &name, "--input", "x.csv", "--output"])
        .arg(d.join("o.csv"))
        .assert()
        .failure()
        .stderr(contains(format!("{name}:3:18: sample_rate_hz = 5")))
        .stderr(contains("10 to 2000 Hz"));
    fs::write(
        &bad,
        SENSOR_50HZ.replace("quantum_dps = 0.0\n", "quantum_dps = 0.0\nrate_hz = 1\n"),
    )
    .expect("test");
    host_sim()
        .args(["identify", "--preset", "motion", "--gyro", &name])
        .args(["--input", "x.csv", "--save-identifier"])
        .arg(d.join("m.fogi"))
        .assert()
        .failure()
        .stderr(contains(format!("{name}:6:1: unknown field `rate_hz`")));
    host_sim()
        .args(["replay", "--gyro", "ecore", "--input", "x.csv", "--output"])
        .arg(d.join("o.csv"))
        .assert()
        .failure()
        .stderr(contains("ecore2000, kvh1750"))
        .stderr(contains(".toml"));
}
