//! What the firmware does with an identifier image (host_sim::firmware_fit): `host-sim
//! image` states it on stderr and in its JSON, `identify --save-identifier` too, and an
//! image the firmware would refuse at set-up is refused (non-zero exit, one line naming the
//! file, nothing written).

use assert_cmd::Command;
use fog_core::image::{Image, IMAGE_LEN};
use host_sim::firmware_fit as ff;
use predicates::str::contains;
use std::fs;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// `host-sim image --input IMG --json J`, run.
fn image(img: &Path, j: &Path) -> assert_cmd::assert::Assert {
    host_sim()
        .args(["image", "--input"])
        .arg(img)
        .arg("--json")
        .arg(j)
        .assert()
}

/// The firmware's committed default image (100 Hz, 60 deg/s, dual-thermal).
fn default_image() -> Image {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fog-firmware/identifier/default.fogi");
    Image::parse(&fs::read(&p).expect("default image")).expect("parses")
}

/// The default image at `rate_hz` for a unit of `full_scale_dps`, written to `dir/name`.
fn image_file(dir: &Path, name: &str, rate_hz: f32, full_scale_dps: f32) -> PathBuf {
    let mut image = default_image();
    image.model.sample_rate_hz = rate_hz;
    image.full_scale_dps = full_scale_dps;
    let mut buf = vec![0u8; IMAGE_LEN];
    let n = image.to_bytes(&mut buf).expect("image written");
    let p = dir.join(name);
    fs::write(&p, &buf[..n]).expect("write");
    p
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(p).expect("read")).expect("json")
}

#[test]
fn a_100_hz_image_fits_and_says_so() {
    let dir = tempfile::tempdir().expect("tmp");
    let img = image_file(dir.path(), "u100.fogi", 100.0, 60.0);
    let j = dir.path().join("u100.json");
    let a = image(&img, &j)
        .success()
        .stderr(contains(
            "firmware: accepts this image and runs at its 100 Hz (accepted: 10 to 2000 Hz)",
        ))
        .stderr(contains(
            "firmware: decodes E-Core 2000 frames only, full scale 60 deg/s; this image's unit: 60 deg/s",
        ))
        .stderr(contains(format!(
            "= {:.2} % of a 168 MHz core",
            100.0 * ff::CYCLES_MEAN * 100.0 / ff::CLOCK_HZ
        )))
        .stderr(contains("measured on the default image"))
        .stderr(contains(format!(
            "RAM incl. stack {} B (mps2-an386)",
            ff::grouped(f64::from(ff::RAM_MPS2_BYTES), 0)
        )));
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(!err.contains("WARNING"), "{err}");
    let f = &json(&j)["firmware"];
    assert_eq!(f["accepted"], true);
    assert_eq!(f["sample_rate_hz"], 100.0);
    assert_eq!(f["warnings"].as_array().map(Vec::len), Some(0));
}

#[test]
fn a_200_hz_image_of_a_100_dps_unit_is_warned_about() {
    let dir = tempfile::tempdir().expect("tmp");
    let img = image_file(dir.path(), "u200.fogi", 200.0, 100.0);
    let j = dir.path().join("u200.json");
    image(&img, &j)
        .success()
        .stderr(contains(
            "firmware: accepts this image and runs at its 200 Hz",
        ))
        .stderr(contains(format!(
            "load at 200 Hz: {} instructions/s",
            ff::grouped(ff::INSTRUCTIONS_MEAN * 200.0, 0)
        )))
        .stderr(contains(
            "firmware: WARNING: the unit's full scale 100 deg/s is beyond the decoder's 60 deg/s",
        ));
    let f = &json(&j)["firmware"];
    assert_eq!(f["accepted"], true);
    assert_eq!(f["decoder_full_scale_dps"], 60.0);
    assert_eq!(f["image_full_scale_dps"], 100.0);
    assert_eq!(f["warnings"].as_array().map(Vec::len), Some(1));
}

/// The writer says it too: `identify` with a 200-Hz, 100 deg/s gyro file.
#[test]
fn identify_states_the_fit_of_the_image_it_writes() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let sensor = d.join("unit100.toml");
    fs::write(
        &sensor,
        "name = \"unit100\"\nsample_rate_hz = 200.0\nfull_scale_dps = 100.0\nquantum_dps = 0.0\narw_deg_per_rth = 0.0667\ndrift_bound_dph = 30.0\n",
    )
    .expect("write");
    // Two calibration runs (the model's unit-to-unit spread needs two), 120 s each.
    let recs = [d.join("r1.csv"), d.join("r2.csv")];
    for (seed, rec) in recs.iter().enumerate() {
        host_sim()
            .args(["simulate", "--gyro", "ecore2000", "--duration-s", "120"])
            .args([
                "--rate-hz",
                "200",
                "--seed",
                &(seed + 1).to_string(),
                "--output",
            ])
            .arg(rec)
            .assert()
            .success();
    }
    let (img, j) = (d.join("m.fogi"), d.join("m.json"));
    host_sim()
        .args(["identify", "--preset", "motion", "--gyro"])
        .arg(&sensor)
        .arg("--input")
        .args(&recs)
        .arg("--save-identifier")
        .arg(&img)
        .arg("--json")
        .arg(&j)
        .assert()
        .success()
        .stderr(contains(
            "firmware: accepts this image and runs at its 200 Hz",
        ))
        .stderr(contains("beyond the decoder's 60 deg/s"));
    assert!(img.exists());
    assert_eq!(json(&j)["firmware"]["image_full_scale_dps"], 100.0);
}

#[test]
fn an_image_outside_the_firmwares_rates_is_refused_and_not_written() {
    let dir = tempfile::tempdir().expect("tmp");
    let img = image_file(dir.path(), "u5k.fogi", 5000.0, 60.0);
    let j = dir.path().join("u5k.json");
    let a = image(&img, &j)
        .failure()
        .stderr(contains(
            "firmware: REFUSES this image (it stops at set-up): sample rate 5000 Hz outside the 10 to 2000 Hz it runs",
        ));
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(
        errors[0].contains("u5k.fogi: the firmware would refuse this image at set-up"),
        "{err}"
    );
    assert!(!j.exists(), "no JSON for a refused image");

    // A command that writes the image refuses it and writes nothing.
    let mut image = default_image();
    image.model.sample_rate_hz = 5000.0;
    let out = dir.path().join("written.fogi");
    let e = host_sim::motion::write_image(&out, &image).expect_err("refused");
    let msg = format!("{e:#}");
    assert!(msg.contains("written.fogi: not written"), "{msg}");
    assert!(msg.contains("5000 Hz outside the 10 to 2000 Hz"), "{msg}");
    assert!(!out.exists());
}
