//! `host-sim identify --preset motion --save-identifier` and `host-sim replay --identifier`
//! end to end: output columns, one row per input row, the external still flag, and refusals
//! of corrupt, truncated, wrong-version and wrong-rate identifiers (one line naming the
//! file, non-zero exit, nothing written). A run on the real KVH DSP-1750 log (skipped when
//! `../shared` is absent) checks that rotation is not taken for drift.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

mod common;

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

fn simulate(seed: u64, duration_s: &str, rate_hz: Option<&str>, out: &Path) {
    let mut c = host_sim();
    c.args([
        "simulate",
        "--gyro",
        "ecore2000",
        "--duration-s",
        duration_s,
    ]);
    c.args(["--seed", &seed.to_string(), "--output"]).arg(out);
    if let Some(r) = rate_hz {
        c.args(["--rate-hz", r]);
    }
    c.assert().success();
}

/// Two short static records (seeds 1 and 2, 120 s) in `d/train`.
fn train_dir(d: &Path) -> PathBuf {
    let train = d.join("train");
    fs::create_dir(&train).expect("test");
    simulate(1, "120", None, &train.join("a.csv"));
    simulate(2, "120", None, &train.join("b.csv"));
    train
}

/// `identify --preset motion` on the records of [`train_dir`], `extra` arguments, image `out`.
fn identify(train: &Path, extra: &[&str], out: &Path) -> assert_cmd::assert::Assert {
    host_sim()
        .args(["identify", "--preset", "motion", "--input"])
        .arg(train.join("a.csv"))
        .arg(train.join("b.csv"))
        .args(extra)
        .arg("--save-identifier")
        .arg(out)
        .assert()
}

/// Two short static records, a trained image, and a record to replay.
fn setup(d: &Path) -> (PathBuf, PathBuf) {
    let train = train_dir(d);
    let img = d.join("m.fogi");
    identify(&train, &[], &img).success();
    let rec = d.join("rec.csv");
    simulate(3, "60", None, &rec);
    (img, rec)
}

/// `replay --input rec --identifier img --output out [--json json]`; checks the header, one
/// row per input row, compensated = rate - drift and the drift bound; returns the rows and
/// the still rows.
fn replay_checked(img: &Path, rec: &Path, out: &Path, json: Option<&Path>) -> (usize, usize) {
    let mut c = host_sim();
    c.args(["replay", "--input"])
        .arg(rec)
        .arg("--identifier")
        .arg(img)
        .arg("--output")
        .arg(out);
    if let Some(j) = json {
        c.arg("--json").arg(j);
    }
    c.assert().success();
    let r = rows(out);
    assert_eq!(r[0].join(","), host_sim::motion::OUTPUT_HEADER);
    let input = fs::read_to_string(rec).expect("test");
    assert_eq!(r.len(), input.lines().count(), "one row per input row");
    let bound = fog_core::image::Image::parse(&fs::read(img).expect("image"))
        .expect("image parses")
        .model
        .drift_bound_dps;
    let mut still = 0;
    for row in &r[1..] {
        let rate: f32 = row[2].parse().expect("test");
        let drift: f32 = row[4].parse().expect("test");
        let comp: f32 = row[5].parse().expect("test");
        assert_eq!(comp, rate - drift);
        assert!(drift.abs() <= bound);
        still += usize::from(row[6] == "1");
    }
    (r.len() - 1, still)
}

fn rows(p: &Path) -> Vec<Vec<String>> {
    fs::read_to_string(p)
        .expect("test")
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn train_save_and_replay() {
    let dir = tempfile::tempdir().expect("test");
    let (img, rec) = setup(dir.path());
    assert_eq!(
        fs::metadata(&img).expect("test").len(),
        fog_core::image::IMAGE_LEN as u64
    );
    let (n, still) = replay_checked(&img, &rec, &dir.path().join("out.csv"), None);
    // A static record: still after the first few seconds.
    assert!(still > n * 8 / 10, "{still}");
}

/// The retired estimator's flags (its arrangements, level noise, priors, trainer) are
/// refused with one line naming the flag, and no image is written; the image holds the
/// fitted model (the calibration runs' white noise, a drift bound, the runs counted).
#[test]
fn the_image_holds_the_fitted_model_and_retired_flags_are_refused() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let train = train_dir(d);
    let img = d.join("m.fogi");
    identify(&train, &[], &img).success();
    let image = fog_core::image::Image::parse(&fs::read(&img).expect("test")).expect("test");
    assert_eq!(image.trained_runs, 2);
    // The simulator's E-Core preset: 0.0667 deg/sqrt(h) white noise.
    let white = image.model.white_dps_rthz * 60.0;
    assert!((white / 0.0667 - 1.0).abs() < 0.05, "{white}");
    assert!(image.model.is_valid());
    for flag in [
        "--level-update",
        "--thermal-prior-dph-per-c",
        "--bank-b-dph",
        "--level-q-dph2-per-h",
        "--epochs",
        "--motion-trainer",
        "--stale-s",
        "--gm-sigma-dph",
    ] {
        let bad = d.join("bad.fogi");
        identify(&train, &[flag, "1"], &bad)
            .failure()
            .stderr(predicates::str::contains(format!(
                "unexpected argument '{flag}'"
            )));
        assert!(!bad.exists());
    }
}

/// A CSV without `t_s` has no rate of its own: replaying it with an identifier alone (whose
/// rate would pass the rate check by construction) or with nothing is refused, naming the
/// file and the flags; `--rate-hz` or `--gyro` states it.
#[test]
fn a_csv_without_time_stamps_needs_its_rate_stated() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (img, _) = setup(d);
    let rec = d.join("no_t.csv");
    let mut text = String::from("rate_dps,temp_c\n");
    for k in 0..2000 {
        text += &format!("{},25\n", 0.001 * (k % 7) as f64);
    }
    fs::write(&rec, text).expect("test");
    let out = d.join("out.csv");
    for with_image in [true, false] {
        let mut c = host_sim();
        c.args(["replay", "--input"])
            .arg(&rec)
            .arg("--output")
            .arg(&out);
        if with_image {
            c.arg("--identifier").arg(&img);
        }
        let a = c.assert().failure();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        assert!(err.contains("no_t.csv: no t_s column"), "{err}");
        assert!(err.contains("give --rate-hz HZ or --gyro"), "{err}");
        assert!(!out.exists());
    }
    host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--identifier")
        .arg(&img)
        .args(["--rate-hz", "100", "--output"])
        .arg(&out)
        .assert()
        .success();
    assert_eq!(rows(&out).len(), 2001);
}

/// The default image reads the temperature (the unit's temperature link): a record without
/// `temp_c` runs, with a warning and `temperature_missing` in the summary; with `temp_c`,
/// neither.
#[test]
fn a_record_without_temperature_is_said() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (img, _) = setup(d);
    for with_temp in [false, true] {
        let rec = d.join(format!("r{with_temp}.csv"));
        let mut text = String::from(if with_temp {
            "t_s,rate_dps,temp_c\n"
        } else {
            "t_s,rate_dps\n"
        });
        for k in 0..2000 {
            text += &format!(
                "{},{}{}\n",
                k as f64 * 0.01,
                0.001,
                if with_temp { ",25" } else { "" }
            );
        }
        fs::write(&rec, text).expect("test");
        let json = d.join(format!("s{with_temp}.json"));
        let a = host_sim()
            .args(["replay", "--input"])
            .arg(&rec)
            .arg("--identifier")
            .arg(&img)
            .arg("--output")
            .arg(d.join(format!("o{with_temp}.csv")))
            .arg("--json")
            .arg(&json)
            .assert()
            .success();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        assert_eq!(
            err.contains("warning: no temp_c column"),
            !with_temp,
            "{err}"
        );
        let summary = fs::read_to_string(&json).expect("test");
        assert!(
            summary.contains(&format!("\"temperature_missing\": {}", !with_temp)),
            "{summary}"
        );
    }
}

/// A rate in rad/s read as deg/s runs, but the record's white noise (57x below the
/// identifier's) draws a warning naming `--rate-scale 57.29578`; the same record in deg/s
/// does not, and its ratio in the summary is near 1.
#[test]
fn a_rate_in_rad_per_s_is_said() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (img, rec) = setup(d);
    let text = fs::read_to_string(&rec).expect("test");
    let mut lines = text.lines();
    let header = lines.next().expect("test");
    let col = header
        .split(',')
        .position(|h| h == "rate_dps")
        .expect("test");
    let mut rad = format!("{header}\n");
    for l in lines {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        f[col] = (f[col].parse::<f64>().expect("test") / 57.29578).to_string();
        rad += &(f.join(",") + "\n");
    }
    let rad_rec = d.join("rad.csv");
    fs::write(&rad_rec, rad).expect("test");
    for (input, warned) in [(&rad_rec, true), (&rec, false)] {
        let json = d.join("s.json");
        let a = host_sim()
            .args(["replay", "--input"])
            .arg(input)
            .arg("--identifier")
            .arg(&img)
            .arg("--output")
            .arg(d.join("o.csv"))
            .arg("--json")
            .arg(&json)
            .assert()
            .success();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        assert_eq!(err.contains("--rate-scale 57.29578"), warned, "{err}");
        let v: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(&json).expect("test")).expect("test");
        let k = v["noise_x_image"].as_f64().expect("test");
        if warned {
            assert!((k * 57.29578 - 1.0).abs() < 0.5, "{k}");
        } else {
            assert!((0.5..2.0).contains(&k), "{k}");
        }
    }
}

/// One sample beyond the sensor's full scale in a calibration run is refused, naming the
/// run, the sample and its time; a run without the rate column names the header it has.
#[test]
fn a_glitch_or_a_wrong_column_in_a_calibration_run_is_named() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let train = train_dir(d);
    let text = fs::read_to_string(train.join("a.csv")).expect("test");
    let header = text.lines().next().expect("test");
    let col = header
        .split(',')
        .position(|h| h == "rate_dps")
        .expect("test");
    let glitch: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let mut f: Vec<&str> = l.split(',').collect();
            if i == 101 {
                f[col] = "1000000";
            }
            f.join(",") + "\n"
        })
        .collect();
    let g = d.join("glitch.csv");
    fs::write(&g, glitch).expect("test");
    let img = d.join("g.fogi");
    let run = |input: &Path| {
        host_sim()
            .args(["identify", "--preset", "motion", "--input"])
            .arg(input)
            .arg(train.join("b.csv"))
            .arg("--save-identifier")
            .arg(&img)
            .assert()
            .failure()
    };
    run(&g).stderr(predicates::str::contains(
        "glitch.csv: sample 100 (t_s = 1 s): rate 1000000 deg/s beyond the sensor's full scale 60 deg/s",
    ));
    let renamed = d.join("renamed.csv");
    fs::write(&renamed, text.replacen("rate_dps", "gz_dps", 1)).expect("test");
    run(&renamed).stderr(predicates::str::contains("(the header has: t_s, gz_dps"));
    assert!(!img.exists());
}

/// `host-sim image` says what an image holds: its format, the CRC stored in its last 4
/// bytes, the runs it was fitted on, its noise, the sensor's rate; JSON beside; a
/// damaged image is refused naming it, and `--json` never overwrites the image.
#[test]
fn image_command_describes_an_image() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let train = train_dir(d);
    let img = d.join("th.fogi");
    identify(&train, &[], &img).success();
    let bytes = fs::read(&img).expect("test");
    let crc = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().expect("test"));
    let json = d.join("i.json");
    host_sim()
        .args(["image", "--input"])
        .arg(&img)
        .arg("--json")
        .arg(&json)
        .assert()
        .success()
        .stdout(predicates::str::contains(format!(
            "th.fogi: drift-filter image, format 5, 128 bytes, CRC-32 0x{crc:08x}; fitted on 2 calibration runs"
        )))
        .stdout(predicates::str::contains("noise: white 0.06"))
        .stdout(predicates::str::contains(
            "sensor: 100 Hz, full scale 60 deg/s",
        ));
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("test")).expect("test");
    assert_eq!(v["crc32"].as_u64(), Some(u64::from(crc)));
    assert_eq!(v["trained_runs"], 2);
    let mut bad = bytes.clone();
    bad[60] ^= 1;
    let bad_path = d.join("bad.fogi");
    fs::write(&bad_path, &bad).expect("test");
    host_sim()
        .args(["image", "--input"])
        .arg(&bad_path)
        .assert()
        .failure()
        .stderr(predicates::str::contains("bad.fogi: checksum mismatch"));
    host_sim()
        .args(["image", "--input"])
        .arg(&img)
        .arg("--json")
        .arg(&img)
        .assert()
        .failure()
        .stderr(predicates::str::contains(
            "refusing to overwrite the input file",
        ));
    assert_eq!(fs::read(&img).expect("test"), bytes);
}

#[test]
fn external_still_flag_column() {
    let dir = tempfile::tempdir().expect("test");
    let (img, _) = setup(dir.path());
    // A constant 1 deg/s turn flagged still from outside: the flag wins (and the bound
    // keeps the drift estimate small).
    let rec = dir.path().join("turn.csv");
    let mut text = String::from("t_s,rate_dps,zupt\n");
    for k in 0..3000 {
        text += &format!(
            "{},{},{}\n",
            k as f64 * 0.01,
            1.0,
            if k < 1500 { "0" } else { "1" }
        );
    }
    fs::write(&rec, text).expect("test");
    let out = dir.path().join("out.csv");
    host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--identifier")
        .arg(&img)
        .args(["--still-column", "zupt", "--output"])
        .arg(&out)
        .assert()
        .success();
    let r = rows(&out);
    assert!(r[1..1501].iter().all(|row| row[6] == "0"));
    assert!(r[1501..].iter().all(|row| row[6] == "1"));
    let bound = fog_core::image::Image::parse(&fs::read(&img).expect("image"))
        .expect("image parses")
        .model
        .drift_bound_dps;
    assert!(r[1..]
        .iter()
        .all(|row| row[4].parse::<f32>().expect("test").abs() <= bound));
    // A missing column is refused.
    host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--identifier")
        .arg(&img)
        .args(["--still-column", "nope", "--output"])
        .arg(dir.path().join("x.csv"))
        .assert()
        .failure()
        .stderr(predicates::str::contains(
            "turn.csv:1: missing column `nope` (the header has: t_s, rate_dps, zupt)",
        ));
}

/// Replay with a damaged image: fails with one line naming it, writes nothing.
fn refused(img_bytes: &[u8], rec: &Path, d: &Path, expect: &str) {
    let img = d.join("bad.fogi");
    fs::write(&img, img_bytes).expect("test");
    let out = d.join("never.csv");
    let a = host_sim()
        .args(["replay", "--input"])
        .arg(rec)
        .arg("--identifier")
        .arg(&img)
        .arg("--output")
        .arg(&out)
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("bad.fogi"), "{err}");
    assert!(err.contains(expect), "{expect}: {err}");
    assert!(!out.exists());
}

/// No output of `replay` may destroy an input or another output: `--json` naming the
/// record, the identifier or `--output`, and `--output` naming the identifier, fail before
/// anything is written, and every input is left byte for byte.
#[test]
fn replay_outputs_never_overwrite_inputs() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (img, rec) = setup(d);
    let (rec_bytes, img_bytes) = (fs::read(&rec).expect("test"), fs::read(&img).expect("test"));
    let out = d.join("out.csv");
    for (output, json, expect) in [
        (&out, Some(&rec), "refusing to overwrite the input file"),
        (&out, Some(&img), "refusing to overwrite the input file"),
        (&img, None, "refusing to overwrite the input file"),
        (&out, Some(&out), "--json and --output name the same file"),
    ] {
        let mut c = host_sim();
        c.args(["replay", "--input"])
            .arg(&rec)
            .arg("--identifier")
            .arg(&img)
            .arg("--output")
            .arg(output);
        if let Some(j) = json {
            c.arg("--json").arg(j);
        }
        let a = c.assert().failure();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        assert!(err.contains(expect), "{expect}: {err}");
        assert_eq!(fs::read(&rec).expect("test"), rec_bytes);
        assert_eq!(fs::read(&img).expect("test"), img_bytes);
        assert!(!out.exists(), "{err}");
    }
}

#[test]
fn bad_identifiers_are_refused() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let (img, rec) = setup(d);
    let good = fs::read(&img).expect("test");
    let mut flipped = good.clone();
    flipped[60] ^= 0x10;
    refused(&flipped, &rec, d, "checksum mismatch");
    refused(&good[..100], &rec, d, "truncated at byte offset 100");
    let mut v6 = good.clone();
    v6[4] = 6;
    refused(&v6, &rec, d, "format version 6 unsupported");
    // An image of the filter with one known warm-up time constant (format 4).
    let mut v4 = good.clone();
    v4[4] = 4;
    refused(&v4, &rec, d, "one known warm-up time constant");
    // An image of the retired estimator (format 3) is named as such.
    let mut v3 = good.clone();
    v3[4] = 3;
    refused(&v3, &rec, d, "retired dual-thermal/bank estimators");
    refused(b"hello, world", &rec, d, "bad magic");
    // The right image, a record at another rate.
    let slow = d.join("slow.csv");
    simulate(4, "60", Some("50"), &slow);
    let out = d.join("never.csv");
    let a = host_sim()
        .args(["replay", "--input"])
        .arg(&slow)
        .arg("--identifier")
        .arg(&img)
        .arg("--output")
        .arg(&out)
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(
        err.contains("m.fogi") && err.contains("100 Hz") && err.contains("50 Hz"),
        "{err}"
    );
    assert!(!out.exists());
    // Training refuses a record at another rate, naming it, and writes nothing.
    let img2 = d.join("m2.fogi");
    host_sim()
        .args(["identify", "--preset", "motion", "--input"])
        .arg(&slow)
        .arg("--save-identifier")
        .arg(&img2)
        .assert()
        .failure()
        .stderr(predicates::str::contains("slow.csv"));
    assert!(!img2.exists());
    // --preset motion without --save-identifier fits and describes without an image (see
    // vocabulary_cli); the record at another rate is still refused, nothing written.
    let x = d.join("x.json");
    host_sim()
        .args(["identify", "--preset", "motion", "--input"])
        .arg(&slow)
        .arg("--json")
        .arg(&x)
        .assert()
        .failure()
        .stderr(predicates::str::contains("slow.csv"));
    assert!(!x.exists());
}

/// The default replay (no `--identifier`: the built-in untrained motion identifier, its
/// sensor picked by the record's 1 kHz rate) of the KVH log converted to `t_s,rate_dps`
/// (`dtheta_x_deg / 0.001`), and the raw log with `--gyro kvh1750 --rate-column
/// dtheta_x_deg --rate-scale 1000`: the compensated angle stays within 0.5 deg of the raw
/// angle at the 180-deg hold and at the end, nothing clipped at 327 deg/s. Reads `../shared`
/// (non-commercial data, never copied): skipped when absent.
#[test]
fn kvh_log_rotation_is_not_drift() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/kvh1750_fog_yoos/kvh_direct_ext_rate.csv");
    if !src.exists() {
        eprintln!("skipped: {} absent", src.display());
        return;
    }
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let mut rdr = csv::Reader::from_path(&src).expect("test");
    let col = rdr
        .headers()
        .expect("test")
        .iter()
        .position(|h| h == "dtheta_x_deg")
        .expect("test");
    let mut text = String::from("t_s,rate_dps\n");
    let mut n = 0usize;
    for (i, r) in rdr.records().enumerate() {
        let dtheta: f64 = r.expect("test")[col].parse().expect("test");
        text += &format!("{},{}\n", i as f64 * 0.001, dtheta / 0.001);
        n += 1;
    }
    let rec = d.join("kvh.csv");
    fs::write(&rec, text).expect("test");
    let runs: [(&Path, &[&str]); 2] = [
        (&rec, &[]),
        (
            &src,
            &[
                "--gyro",
                "kvh1750",
                "--rate-column",
                "dtheta_x_deg",
                "--rate-scale",
                "1000",
            ],
        ),
    ];
    for (i, (input, extra)) in runs.iter().enumerate() {
        let out = d.join(format!("out{i}.csv"));
        let a = host_sim()
            .args(["replay", "--input"])
            .arg(input)
            .args(*extra)
            .arg("--output")
            .arg(&out)
            .assert()
            .success();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        assert!(err.contains("full scale 490 deg/s, 1000 Hz"), "{err}");
        assert!(
            !err.contains("full scale ("),
            "nothing at full scale: {err}"
        );
        let (mut raw, mut comp) = (0.0f64, 0.0f64);
        let (mut raw_max, mut comp_at_max, mut max_drift, mut max_rate) =
            (f64::MIN, 0.0, 0.0f64, 0.0f64);
        let r = rows(&out);
        assert_eq!(r.len() - 1, n, "one row per input row");
        for row in &r[1..] {
            let rate = row[2].parse::<f64>().expect("test");
            max_rate = max_rate.max(rate.abs());
            raw += rate * 0.001;
            comp += row[5].parse::<f64>().expect("test") * 0.001;
            max_drift = max_drift.max(row[4].parse::<f64>().expect("test").abs());
            if raw > raw_max {
                (raw_max, comp_at_max) = (raw, comp);
            }
        }
        eprintln!(
            "KVH run {i}: raw {raw_max:.3} deg at the hold, compensated {comp_at_max:.3}; end raw {raw:.3}, compensated {comp:.3}; max |drift| {:.2} deg/h; max |rate| {max_rate:.1} deg/s",
            max_drift * 3600.0
        );
        assert!(max_rate > 300.0, "peaks kept unclipped: {max_rate}");
        assert!((raw_max - 180.0).abs() < 1.0, "{raw_max}");
        assert!((comp_at_max - raw_max).abs() < 0.5);
        assert!((comp - raw).abs() < 0.5);
    }
}

/// `identify --tune-on`: the model's two scales tuned on vehicle records with truth, the
/// grid point with the least mean heading RMS saved; the grid in the JSON, the pick in the
/// image.
#[test]
fn tune_on_vehicles_scales_the_model() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let train = train_dir(d);
    // Two 300-s vehicle records of the ecore2000 preset (alignment 60 s).
    let model = common::vehicle_gyro(d, "vehicle.toml");
    let veh = d.join("vehicles");
    fs::create_dir(&veh).expect("test");
    for seed in [21u64, 22] {
        common::simulate(&model, 300, seed, &veh.join(format!("v{seed}.csv")));
    }
    let img = d.join("tuned.fogi");
    let json = d.join("tuned.json");
    let json_s = json.to_str().expect("utf-8 path");
    let veh_s = veh.to_str().expect("utf-8 path");
    let plain = d.join("plain.fogi");
    identify(&train, &[], &plain).success();
    identify(&train, &["--tune-on", veh_s, "--json", json_s], &img)
        .success()
        .stderr(predicates::str::contains("tuned on 2 vehicle records:"));
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("test")).expect("json");
    let grid = v["tuning"]["grid"].as_array().expect("grid");
    assert_eq!(grid.len(), 32);
    let rms = |c: &serde_json::Value| c["heading_rms_deg"].as_f64().expect("rms");
    let least = grid.iter().map(rms).fold(f64::INFINITY, f64::min);
    assert_eq!(rms(&v["tuning"]["picked"]), least);
    let scale = |k: &str| v["tuning"]["picked"][k].as_f64().expect("scale") as f32;
    let image = fog_core::image::Image::parse(&fs::read(&img).expect("test")).expect("image");
    let plain = fog_core::image::Image::parse(&fs::read(&plain).expect("test")).expect("image");
    // The Gauss-Markov terms as fitted, or their total variance in one term of the picked
    // correlation time; then scaled.
    match v["tuning"]["picked"]["markov_tau_s"].as_f64() {
        None => assert_eq!(
            image.model.markov[0].sigma_dps,
            plain.model.markov[0].sigma_dps * scale("markov_scale")
        ),
        Some(tau) => {
            let var: f32 = plain
                .model
                .markov
                .iter()
                .map(|t| t.sigma_dps * t.sigma_dps)
                .sum();
            assert_eq!(image.model.markov[0].tau_s, tau as f32);
            assert_eq!(
                image.model.markov[0].sigma_dps,
                var.sqrt() * scale("markov_scale")
            );
            assert!(image.model.markov[1..].iter().all(|t| t.sigma_dps == 0.0));
        }
    }
    assert_eq!(
        image.model.temp_dps_per_c.sigma,
        plain.model.temp_dps_per_c.sigma * scale("link_scale")
    );
    // Vehicles without truth: one line, no file.
    let bad = d.join("bad.fogi");
    let bare = d.join("bare.csv");
    let mut text = String::from("t_s,rate_dps\n");
    for k in 0..1000 {
        text += &format!("{},0.001\n", k as f64 * 0.01);
    }
    fs::write(&bare, text).expect("test");
    identify(&train, &["--tune-on", bare.to_str().expect("utf-8")], &bad)
        .failure()
        .stderr(predicates::str::contains("bare.csv: no truth"));
    assert!(!bad.exists());
}

#[test]
fn unit_runs_make_the_image_that_units() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let train = train_dir(d);
    // Two power-ons of one unit of the family (its own warm-up and links).
    let unit = d.join("unit");
    fs::create_dir(&unit).expect("test");
    for seed in [31u64, 32] {
        host_sim()
            .args(["simulate", "--gyro", "ecore2000", "--duration-s", "120"])
            .args(["--seed", &seed.to_string(), "--unit-seed", "5"])
            .args(["--unit-spread", "0.5", "--output"])
            .arg(unit.join(format!("u{seed}.csv")))
            .assert()
            .success();
    }
    let family = d.join("family.fogi");
    identify(&train, &[], &family).success();
    let img = d.join("unit.fogi");
    let json = d.join("unit.json");
    let unit_s = unit.to_str().expect("utf-8 path");
    identify(
        &train,
        &[
            "--unit-runs",
            unit_s,
            "--json",
            json.to_str().expect("utf-8"),
        ],
        &img,
    )
    .success()
    .stderr(predicates::str::contains(
        "unit: the model made the unit's on its 2 own runs",
    ));
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("test")).expect("json");
    assert_eq!(v["unit"]["runs"].as_array().expect("runs").len(), 2);
    let image = fog_core::image::Image::parse(&fs::read(&img).expect("test")).expect("image");
    let fam = fog_core::image::Image::parse(&fs::read(&family).expect("test")).expect("image");
    // The turn-on is the unit's runs' mean level; the noise terms stay the family's.
    let levels: Vec<f64> = v["unit"]["fit"]["runs"]
        .as_array()
        .expect("runs")
        .iter()
        .map(|r| r["level_dph"].as_f64().expect("level"))
        .collect();
    let mean = levels.iter().sum::<f64>() / levels.len() as f64;
    let turn_on = f64::from(image.model.turn_on_dps.mean) * 3600.0;
    assert!(
        (turn_on - mean).abs() < 1e-3 * mean.abs().max(1.0),
        "{turn_on} vs {mean}"
    );
    assert_ne!(image.model.turn_on_dps.mean, fam.model.turn_on_dps.mean);
    assert_eq!(image.model.markov, fam.model.markov);
    assert_eq!(image.trained_runs, fam.trained_runs + 2);
    // One run of the unit is refused, naming the need; other presets refuse the flag.
    let one = unit.join("u31.csv");
    identify(
        &train,
        &["--unit-runs", one.to_str().expect("utf-8")],
        &d.join("one.fogi"),
    )
    .failure()
    .stderr(predicates::str::contains("at least 2"));
    assert!(!d.join("one.fogi").exists());
    host_sim()
        .args(["identify", "--preset", "paper", "--input"])
        .arg(train.join("a.csv"))
        .args(["--validate"])
        .arg(train.join("b.csv"))
        .args(["--unit-runs", unit_s])
        .assert()
        .failure()
        .stderr(predicates::str::contains(
            "--unit-runs needs --preset motion",
        ));
}
