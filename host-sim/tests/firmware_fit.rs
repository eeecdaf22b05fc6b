//! What the firmware does with an identifier image (host_sim::firmware_fit), in one
//! verdict: `host-sim image` states it on stderr and in its JSON (the same verdict and
//! reasons) and exits non-zero on an image that does not fit; `identify --save-identifier`
//! states it too and writes an image that does not fit only with `--force`.

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

/// The verdict line of `text` (`firmware: fits: ...` or `firmware: does not fit: ...`),
/// which must be the first `firmware:` line, as the JSON's `verdict` starts it.
fn verdict_line(text: &str) -> String {
    let first = text
        .lines()
        .find(|l| l.starts_with("firmware:"))
        .expect("a firmware line");
    first.trim_start_matches("firmware: ").to_string()
}

/// The text states the JSON's verdict first and every reason's detail under it, and the
/// verdict lists every reason's short form.
fn text_agrees_with_json(err: &str, f: &serde_json::Value) {
    let verdict = f["verdict"].as_str().expect("verdict");
    let line = verdict_line(err);
    assert!(line.starts_with(verdict), "{line:?} vs {verdict:?}");
    let reasons = f["reasons"].as_array().expect("reasons");
    assert_eq!(f["fits"].as_bool(), Some(reasons.is_empty()));
    if reasons.is_empty() {
        assert_eq!(verdict, "fits");
    } else {
        let shorts: Vec<&str> = reasons
            .iter()
            .map(|r| r["short"].as_str().expect("short"))
            .collect();
        assert_eq!(line, format!("does not fit: {}", shorts.join(", ")));
    }
    for r in reasons {
        let d = r["detail"].as_str().expect("detail");
        assert!(err.contains(&format!("firmware:   - {d}")), "{d} in {err}");
    }
    assert!(!err.contains("accepts this image"), "{err}");
}

#[test]
fn a_100_hz_image_fits_and_says_so() {
    let dir = tempfile::tempdir().expect("tmp");
    let img = image_file(dir.path(), "u100.fogi", 100.0, 60.0);
    let j = dir.path().join("u100.json");
    let a = image(&img, &j)
        .success()
        .stderr(contains(
            "firmware: fits: runs this image at its 100 Hz (rates 10 to 2000 Hz)",
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
    assert_eq!(f["fits"], true);
    assert_eq!(f["verdict"], "fits");
    assert_eq!(f["setup_accepts"], true);
    assert_eq!(f["sample_rate_hz"], 100.0);
    assert_eq!(f["reasons"].as_array().map(Vec::len), Some(0));
    text_agrees_with_json(&err, f);
}

/// A 200-Hz image of a 100 deg/s unit does not fit (the decoder's full scale): `image`
/// says so first, writes the JSON with the same verdict and exits non-zero.
#[test]
fn a_200_hz_image_of_a_100_dps_unit_does_not_fit() {
    let dir = tempfile::tempdir().expect("tmp");
    let img = image_file(dir.path(), "u200.fogi", 200.0, 100.0);
    let j = dir.path().join("u200.json");
    let a = image(&img, &j)
        .failure()
        .stderr(contains(
            "firmware: does not fit: decoder full scale 60 deg/s < unit's 100 deg/s\n",
        ))
        .stderr(contains(format!(
            "load at 200 Hz: {} instructions/s",
            ff::grouped(ff::INSTRUCTIONS_MEAN * 200.0, 0)
        )))
        .stderr(contains(
            "firmware:   - the unit's full scale 100 deg/s is beyond the decoder's 60 deg/s",
        ))
        .stderr(contains(
            "u200.fogi: the image does not fit the firmware: decoder full scale 60 deg/s < unit's 100 deg/s",
        ));
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    let f = &json(&j)["firmware"];
    assert_eq!(f["fits"], false);
    assert_eq!(f["setup_accepts"], true);
    assert_eq!(f["decoder_full_scale_dps"], 60.0);
    assert_eq!(f["image_full_scale_dps"], 100.0);
    assert_eq!(f["reasons"].as_array().map(Vec::len), Some(1));
    text_agrees_with_json(&err, f);
}

/// A gyro file and two static calibration runs (120 s) of a unit at `rate_hz` and
/// `full_scale_dps`, in `d`.
fn unit_runs(d: &Path, rate_hz: u32, full_scale_dps: u32) -> (PathBuf, [PathBuf; 2]) {
    let sensor = d.join(format!("unit{rate_hz}.toml"));
    fs::write(
        &sensor,
        format!("name = \"unit{rate_hz}\"\nsample_rate_hz = {rate_hz}.0\nfull_scale_dps = {full_scale_dps}.0\nquantum_dps = 0.0\narw_deg_per_rth = 0.0667\ndrift_bound_dph = 30.0\n"),
    )
    .expect("write");
    // Two calibration runs (the model's unit-to-unit spread needs two), 120 s each.
    let recs = [d.join("r1.csv"), d.join("r2.csv")];
    for (seed, rec) in recs.iter().enumerate() {
        host_sim()
            .args(["simulate", "--gyro", "ecore2000", "--duration-s", "120"])
            .args([
                "--rate-hz",
                &rate_hz.to_string(),
                "--seed",
                &(seed + 1).to_string(),
                "--output",
            ])
            .arg(rec)
            .assert()
            .success();
    }
    (sensor, recs)
}

/// `identify --preset motion --gyro G --input RUNS --save-identifier IMG --json J` and
/// `extra`.
fn identify(
    sensor: &Path,
    recs: &[PathBuf],
    img: &Path,
    j: &Path,
    extra: &[&str],
) -> assert_cmd::assert::Assert {
    host_sim()
        .args(["identify", "--preset", "motion", "--gyro"])
        .arg(sensor)
        .arg("--input")
        .args(recs)
        .arg("--save-identifier")
        .arg(img)
        .arg("--json")
        .arg(j)
        .args(extra)
        .assert()
}

/// A 1 kHz, 100 deg/s unit: one verdict, every reason (the UART's records, the decoder's
/// full scale); `identify` writes neither image nor JSON without `--force`, and with it
/// writes both and says so; `image` then exits non-zero with the same verdict as its JSON.
#[test]
fn a_1_khz_100_dps_unit_does_not_fit_and_is_written_only_with_force() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let (sensor, recs) = unit_runs(d, 1000, 100);
    let (img, j) = (d.join("k.fogi"), d.join("k.json"));
    let verdict =
        "does not fit: UART 226 % (records out), decoder full scale 60 deg/s < unit's 100 deg/s";
    let a = identify(&sensor, &recs, &img, &j, &[])
        .failure()
        .stderr(contains(format!("firmware: {verdict}\n")));
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(
        errors[0].contains("k.fogi: not written: the image does not fit the firmware: UART 226 % (records out), decoder full scale 60 deg/s < unit's 100 deg/s (write it anyway: --force)"),
        "{err}"
    );
    assert!(!err.contains("accepts this image"), "{err}");
    assert!(!img.exists() && !j.exists(), "nothing written");

    let a = identify(&sensor, &recs, &img, &j, &["--force"])
        .success()
        .stderr(contains(format!("firmware: {verdict}\n")))
        .stderr(contains("k.fogi: WARNING: written because of --force"));
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(img.exists());
    let v = json(&j);
    assert_eq!(v["written_with_force"], true);
    let f = &v["firmware"];
    assert_eq!(f["verdict"], verdict);
    assert_eq!(f["reasons"].as_array().map(Vec::len), Some(2));
    text_agrees_with_json(&err, f);

    let j2 = d.join("k-image.json");
    let a = image(&img, &j2).failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    let f = &json(&j2)["firmware"];
    assert_eq!(f["verdict"], verdict);
    assert_eq!(f["fits"], false);
    text_agrees_with_json(&err, f);
    assert!(
        err.lines().any(|l| l.starts_with("error:")
            && l.contains("k.fogi: the image does not fit the firmware: UART 226 %")),
        "{err}"
    );
}

/// The writer says it too: `identify` with a 200-Hz, 60 deg/s sensor file fits.
#[test]
fn identify_states_the_fit_of_the_image_it_writes() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let (sensor, recs) = unit_runs(d, 200, 60);
    let (img, j) = (d.join("m.fogi"), d.join("m.json"));
    let a = identify(&sensor, &recs, &img, &j, &[])
        .success()
        .stderr(contains("firmware: fits: runs this image at its 200 Hz"));
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(img.exists());
    let v = json(&j);
    assert_eq!(v["written_with_force"], false);
    assert_eq!(v["firmware"]["image_full_scale_dps"], 60.0);
    text_agrees_with_json(&err, &v["firmware"]);
}

#[test]
fn an_image_outside_the_firmwares_rates_is_refused_and_not_written() {
    let dir = tempfile::tempdir().expect("tmp");
    let img = image_file(dir.path(), "u5k.fogi", 5000.0, 60.0);
    let j = dir.path().join("u5k.json");
    let a = image(&img, &j)
        .failure()
        .stderr(contains(
            "firmware: does not fit: set-up refuses it (sample rate 5000 Hz outside the 10 to 2000 Hz it runs)",
        ));
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(
        errors[0].contains("u5k.fogi: the image does not fit the firmware: set-up refuses it"),
        "{err}"
    );
    // The JSON states the same verdict.
    let f = &json(&j)["firmware"];
    assert_eq!(f["setup_accepts"], false);
    text_agrees_with_json(&err, f);

    // A command that writes the image refuses it and writes nothing, unless forced.
    let mut image = default_image();
    image.model.sample_rate_hz = 5000.0;
    let out = dir.path().join("written.fogi");
    let e = host_sim::motion::write_image(&out, &image, false).expect_err("refused");
    let msg = format!("{e:#}");
    assert!(msg.contains("written.fogi: not written"), "{msg}");
    assert!(msg.contains("5000 Hz outside the 10 to 2000 Hz"), "{msg}");
    assert!(!out.exists());
    let fit = host_sim::motion::write_image(&out, &image, true).expect("forced");
    assert!(!fit.fits && out.exists());
}
