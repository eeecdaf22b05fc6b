//! `host-sim simulate` end to end: model errors, reproducibility, E-Core frames, atomicity.

use assert_cmd::Command;
use fog_core::frame::ecore::EcoreDecoder;
use fog_core::frame::Decoder;
use std::fs;
use std::path::Path;

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

fn simulate(args: &[&str], output: &Path) -> assert_cmd::assert::Assert {
    host_sim()
        .arg("simulate")
        .args(args)
        .arg("--output")
        .arg(output)
        .assert()
}

/// Runs `simulate` on a model file holding `toml`; expects a one-line error containing every
/// needle, naming the file, and no output (nor temporary file) left behind.
fn expect_model_error(toml: &str, needles: &[&str]) {
    let dir = tempfile::tempdir().expect("tmp");
    let model = dir.path().join("bad_model.toml");
    fs::write(&model, toml).expect("write");
    let output = dir.path().join("out.csv");
    let a = simulate(
        &[
            "--gyro",
            &model.to_string_lossy(),
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--rate-hz",
            "100",
        ],
        &output,
    )
    .failure();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(
        stderr.contains("bad_model.toml"),
        "names the file: {stderr}"
    );
    for n in needles {
        assert!(stderr.contains(n), "expected {n:?} in {stderr}");
    }
    assert!(!output.exists(), "no output left behind");
    assert_no_tmp(dir.path());
}

fn assert_no_tmp(dir: &Path) {
    let leftovers: Vec<_> = fs::read_dir(dir)
        .expect("dir")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary file left behind");
}

#[test]
fn unknown_key_names_key_file_and_line() {
    expect_model_error(
        "arw_deg_per_rth = 0.06\n[noise]\nflux_capacitor_dps = 1.0\n",
        &["bad_model.toml:3", "unknown field `flux_capacitor_dps`"],
    );
    expect_model_error("[warp]\nspeed_c = 9\n", &["unknown field `warp`"]);
}

#[test]
fn negative_noise_density_is_refused() {
    expect_model_error(
        "bias_instability_dph = 0.36\narw_deg_per_rth = -0.06\n",
        &[
            "bad_model.toml:2:19",
            "arw_deg_per_rth = -0.06",
            "noise density must be >= 0",
        ],
    );
    expect_model_error("rrw_dph_per_rth = -0.2\n", &["rrw_dph_per_rth", ">= 0"]);
}

#[test]
fn wrong_or_missing_units_are_refused() {
    expect_model_error(
        "arw = 0.06\n",
        &["bad_model.toml:1", "`arw` has no unit", "arw_deg_per_rth"],
    );
    expect_model_error(
        "arw_dph_per_rthz = 4.0\n",
        &[
            "unknown field `arw_dph_per_rthz`",
            "wrong unit",
            "arw_deg_per_rth",
        ],
    );
    expect_model_error(
        "[temperature]\nbias_dph_per_k = 0.1\n",
        &["bias_dph_per_k", "bias_dph_per_c"],
    );
    // A key of the old model file: its new name, and the command that converts the file.
    expect_model_error(
        "[noise]\narw_dps_per_rthz = 1e-3\n",
        &[
            "bad_model.toml:2:1",
            "arw_dps_per_rthz -> arw_deg_per_rth (top level, x 60)",
            "host-sim gyro convert",
        ],
    );
}

#[test]
fn bad_values_are_refused() {
    expect_model_error("[faults]\ndrop_probability = 1.5\n", &["probability"]);
    expect_model_error(
        "[noise]\ngm_sigma_dph = 3.6\ngm_tau_s = 0\n",
        &["gm_tau_s", "> 0"],
    );
    expect_model_error("arw_deg_per_rth = \"a lot\"\n", &["bad_model.toml:1:19"]);
}

#[test]
fn same_seed_same_bytes_other_seed_other_bytes() {
    let dir = tempfile::tempdir().expect("tmp");
    let run = |seed: &str, name: &str| {
        let out = dir.path().join(name);
        simulate(
            &["--gyro", "ecore2000", "--duration-s", "20", "--seed", seed],
            &out,
        )
        .success();
        fs::read(out).expect("read")
    };
    let a = run("42", "a.csv");
    let b = run("42", "b.csv");
    let c = run("43", "c.csv");
    assert_eq!(a, b);
    assert_ne!(a, c);
    let text = String::from_utf8(a).expect("utf8");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,rate_dps,temp_c,drift_dps,true_rate_dps")
    );
    assert_eq!(lines.count(), 2000, "20 s at 100 Hz");
}

#[test]
fn ecore_frames_decode_to_the_counts() {
    let dir = tempfile::tempdir().expect("tmp");
    let csv_out = dir.path().join("r.csv");
    let bin_out = dir.path().join("r.bin");
    let args = ["--gyro", "ecore2000", "--duration-s", "30", "--seed", "7"];
    simulate(&args, &csv_out).success();
    let mut bin_args = args.to_vec();
    bin_args.extend(["--format", "ecore-bin"]);
    simulate(&bin_args, &bin_out).success();
    let bytes = fs::read(&bin_out).expect("read");
    assert_eq!(bytes.len(), 8 * 3000, "8 bytes per sample");
    let mut dec = EcoreDecoder::new(60.0).expect("decoder");
    let frames: Vec<_> = bytes.iter().filter_map(|&b| dec.push(b)).collect();
    assert_eq!(frames.len(), 3000);
    assert_eq!(dec.stats().frames_bad, 0);
    let mut rdr = csv::Reader::from_path(&csv_out).expect("csv");
    let mut nonzero = 0;
    for (row, f) in rdr.records().zip(&frames) {
        let row = row.expect("row");
        let rate: f64 = row[1].parse().expect("rate");
        let counts = rate * 32768.0 / 60.0;
        assert_eq!(counts, counts.round(), "CSV rate is a whole count");
        assert_eq!(f.counts as f64, counts);
        assert_eq!(f64::from(f.rate_dps), rate);
        nonzero += usize::from(f.counts != 0);
    }
    assert!(nonzero > 1000, "the counts carry the noise");
}

#[test]
fn no_half_written_output_on_error() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("keep.csv");
    fs::write(&out, "previous content\n").expect("write");
    let model = dir.path().join("m.toml");
    // No full_scale_dps: ecore-bin is refused; the old file must survive untouched.
    fs::write(&model, "sample_rate_hz = 100.0\narw_deg_per_rth = 0.06\n").expect("w");
    simulate(
        &[
            "--gyro",
            &model.to_string_lossy(),
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--format",
            "ecore-bin",
        ],
        &out,
    )
    .failure();
    assert_eq!(
        fs::read_to_string(&out).expect("read"),
        "previous content\n"
    );
    assert_no_tmp(dir.path());
    // Output into a missing directory: an error naming it, nothing written.
    let a = simulate(
        &["--gyro", "ecore2000", "--duration-s", "1", "--seed", "1"],
        &dir.path().join("missing/out.csv"),
    )
    .failure();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(stderr.contains("missing"), "{stderr}");
    // A good run replaces the old content.
    simulate(
        &[
            "--gyro",
            &model.to_string_lossy(),
            "--duration-s",
            "1",
            "--seed",
            "1",
        ],
        &out,
    )
    .success();
    assert!(fs::read_to_string(&out)
        .expect("read")
        .starts_with("t_s,rate_dps"));
}

#[test]
fn needs_a_model_and_a_rate() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("o.csv");
    simulate(&["--duration-s", "1", "--seed", "1"], &out).failure();
    let model = dir.path().join("m.toml");
    fs::write(&model, "arw_deg_per_rth = 0.06\n").expect("w");
    let a = simulate(
        &[
            "--gyro",
            &model.to_string_lossy(),
            "--duration-s",
            "1",
            "--seed",
            "1",
        ],
        &out,
    )
    .failure();
    let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(stderr.contains("--rate-hz"), "{stderr}");
    assert!(!out.exists());
}

/// A record larger than the free space is refused before anything is written, with its
/// estimated size (10^14 samples at 100 Hz); a large one says its size first.
#[test]
fn a_record_beyond_the_free_space_is_refused_with_its_size() {
    let dir = tempfile::tempdir().expect("test");
    let out = dir.path().join("huge.csv");
    simulate(
        &["--gyro", "ecore2000", "--seed", "1", "--duration-s", "1e12"],
        &out,
    )
    .failure()
    .stderr(predicates::str::contains("huge.csv: about "))
    .stderr(predicates::str::contains(" PB to write, "))
    .stderr(predicates::str::contains(" free in "));
    assert!(!out.exists());
    assert_no_tmp(dir.path());
}

/// `--gyro kvh1750` is one gyro for `simulate` and `replay`: 1 kHz, floating-point output,
/// white noise 0.012 deg/sqrt(h) (one-sample sigma 0.0002 sqrt(1000) deg/s, within 5 % on
/// 20,000 samples).
#[test]
fn the_kvh1750_gyro_is_one_file_for_simulate_and_replay() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("kvh.csv");
    simulate(
        &["--gyro", "kvh1750", "--duration-s", "20", "--seed", "4"],
        &out,
    )
    .success()
    .stderr(predicates::str::contains(
        "gyro kvh1750: 20000 samples at 1000 Hz",
    ));
    let text = fs::read_to_string(&out).expect("csv");
    let rates: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).expect("rate").parse().expect("number"))
        .collect();
    assert_eq!(rates.len(), 20_000);
    // First differences: 2 sigma^2 of the white noise (the drift's steps are far smaller).
    let var = rates.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>()
        / (2.0 * (rates.len() - 1) as f64);
    let want = 0.0002 * 1000f64.sqrt();
    assert!(
        (var.sqrt() / want - 1.0).abs() < 0.05,
        "{} vs {want}",
        var.sqrt()
    );
}

/// `--unit-spread` spreads the unit's coefficients and says that the start temperature is
/// the model's; `--initial-c-range` draws it per record (seed), within the range.
#[test]
fn the_start_temperature_spreads_with_initial_c_range() {
    let dir = tempfile::tempdir().expect("tmp");
    let start_c = |seed: &str, extra: &[&str]| {
        let out = dir.path().join(format!("s{seed}.csv"));
        let mut args = vec!["--gyro", "ecore2000", "--duration-s", "1", "--seed", seed];
        args.extend_from_slice(extra);
        let a = simulate(&args, &out).success();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        let text = fs::read_to_string(&out).expect("csv");
        let t: f64 = text
            .lines()
            .nth(1)
            .and_then(|l| l.split(',').nth(2))
            .expect("temp_c")
            .parse()
            .expect("number");
        (t, err)
    };
    let spread = ["--unit-seed", "3", "--unit-spread", "0.2"];
    let (t, err) = start_c("1", &spread);
    assert_eq!(t, 25.0);
    assert!(err.contains("every record starts at 25 deg C"), "{err}");
    let mut seen = Vec::new();
    for seed in ["1", "2", "3"] {
        let mut args = spread.to_vec();
        args.extend(["--initial-c-range", "10,35"]);
        let (t, err) = start_c(seed, &args);
        assert!((10.0..=35.0).contains(&t), "{t}");
        assert!(!err.contains("every record starts"), "{err}");
        seen.push(t);
    }
    assert!(seen[0] != seen[1] && seen[1] != seen[2], "{seen:?}");
    simulate(
        &[
            "--gyro",
            "ecore2000",
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--initial-c-range",
            "35,10",
        ],
        &dir.path().join("bad.csv"),
    )
    .failure()
    .stderr(predicates::str::contains("needs finite lo <= hi"));
}
