//! The gyro file (host_sim::gyro): one file for one gyro, `--gyro NAME|FILE` on `simulate`,
//! `gap`, `identify`, `replay` and `image`; the built-ins converted bit for bit; the old
//! formats refused with their new keys named and converted by `gyro convert`; the writers
//! (`identify`, `allan`, `gap --save-gyro`) give files the readers take.

use assert_cmd::Command;
use host_sim::gyro::Gyro;
use host_sim::sim::{self, Model, Simulator};
use predicates::str::contains;
use std::fs;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// The old-format files the built-ins were converted from (the former
/// `host-sim/presets/*.toml` and `host-sim/sensors/*.toml`, kept as test data).
fn old(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/old-format")
        .join(name)
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// `n` samples of `model` at `seed` as the CSV rows `simulate` writes.
fn csv_bytes(model: &Model, seed: u64, n: usize) -> Vec<u8> {
    let rate = model.sample_rate_hz.expect("rate");
    let mut sim = Simulator::new(model, seed, rate).expect("simulator");
    let mut out = Vec::new();
    for _ in 0..n {
        host_sim::simulate_cmd::write_csv_row(&mut out, &sim.next_sample(), false).expect("row");
    }
    out
}

/// `simulate --gyro G` of `duration_s` at `seed` into `out`; its bytes.
fn simulate(gyro: &str, duration_s: &str, seed: &str, out: &Path) -> Vec<u8> {
    host_sim()
        .args(["simulate", "--gyro", gyro, "--duration-s", duration_s])
        .args(["--seed", seed, "--output"])
        .arg(out)
        .assert()
        .success();
    fs::read(out).expect("output")
}

#[test]
fn builtins_give_the_old_presets_model_bit_for_bit() {
    for name in ["ecore2000", "kvh1750"] {
        let text = fs::read_to_string(old(&format!("model-{name}.toml"))).expect("old preset");
        let before = Model::from_toml_str(&text, "old").expect("old preset parses");
        let now = sim::preset(name).expect("built-in");
        assert_eq!(now, before, "{name}");
        assert_eq!(
            csv_bytes(&now, 7, 20_000),
            csv_bytes(&before, 7, 20_000),
            "{name}"
        );
    }
}

#[test]
fn convert_gives_the_same_records_and_the_same_sensor() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    // The old preset converted: `simulate` writes the same bytes as from the built-in.
    let conv = d.join("ecore-model.toml");
    host_sim()
        .args(["gyro", "convert", "--input"])
        .arg(old("model-ecore2000.toml"))
        .arg("--output")
        .arg(&conv)
        .assert()
        .success();
    let text = fs::read_to_string(&conv).expect("converted");
    assert!(text.contains("arw_deg_per_rth = 0.0666666"), "{text}");
    assert!(text.contains("turn_on_sigma_dph = 5.000004"), "{text}");
    assert!(!text.contains("dps_per_rthz"), "{text}");
    let a = simulate(&s(&conv), "30", "3", &d.join("a.csv"));
    let b = simulate("ecore2000", "30", "3", &d.join("b.csv"));
    assert_eq!(a, b);
    // The old sensor and model files merged: the built-in's sensor and model.
    let merged = d.join("merged.toml");
    host_sim()
        .args(["gyro", "convert", "--input"])
        .arg(old("sensor-kvh1750.toml"))
        .arg("--input")
        .arg(old("model-kvh1750.toml"))
        .arg("--output")
        .arg(&merged)
        .assert()
        .success();
    let g = Gyro::load(&merged).expect("merged file");
    let k = Gyro::builtin_named("kvh1750").expect("built-in");
    assert_eq!(g.model, k.model);
    assert_eq!(
        g.sensor().expect("sensor").config,
        k.sensor().expect("sensor").config
    );
    assert_eq!(g.name, "kvh1750");
    // The old sensor file alone: renamed in place, its comments kept.
    let sensor = d.join("sensor.toml");
    host_sim()
        .args(["gyro", "convert", "--input"])
        .arg(old("sensor-ecore2000.toml"))
        .arg("--output")
        .arg(&sensor)
        .assert()
        .success();
    let text = fs::read_to_string(&sensor).expect("converted");
    assert!(text.contains("arw_deg_per_rth = 0.0666666"), "{text}");
    assert!(
        text.contains("# [spec] 60/32768 deg/s: one i16 count"),
        "{text}"
    );
    let e = Gyro::builtin_named("ecore2000").expect("built-in");
    assert_eq!(
        Gyro::load(&sensor).expect("file").sensor().expect("sensor"),
        host_sim::sensor::SensorSpec {
            source: s(&sensor),
            builtin: false,
            ..e.sensor().expect("sensor")
        }
    );
    // A gyro file is not converted again; nothing is written.
    let again = d.join("again.toml");
    host_sim()
        .args(["gyro", "convert", "--input"])
        .arg(&conv)
        .arg("--output")
        .arg(&again)
        .assert()
        .failure()
        .stderr(contains("already a gyro file"));
    assert!(!again.exists());
    // Sensor and model that disagree: refused, naming both.
    let other = d.join("other.toml");
    host_sim()
        .args(["gyro", "convert", "--input"])
        .arg(old("sensor-ecore2000.toml"))
        .arg("--input")
        .arg(old("model-kvh1750.toml"))
        .arg("--output")
        .arg(&other)
        .assert()
        .failure()
        .stderr(contains("sample_rate_hz"));
    assert!(!other.exists());
}

/// An old model file with every section and many keys off their defaults.
const RICH_OLD_MODEL: &str = r#"sample_rate_hz = 50.0
full_scale_dps = 200.0
[quantization]
quantum_dps = 0.01
mode = "angle"
[noise]
arw_dps_per_rthz = 0.0011
bias_instability_dps = 0.00031
flicker_tau_min_s = 0.2
flicker_tau_max_s = 2.0e5
rrw_dps_per_s_rthz = 3.3e-6
rate_ramp_dps_per_s = 1.7e-9
gm_sigma_dps = 0.00093
gm_tau_s = 37.0
sine_amplitude_dps = 0.0007
sine_freq_hz = 0.013
sine_phase_deg = 12.5
[bias]
turn_on_dps = 0.0021
turn_on_sigma_dps = 0.00138889
warmup_dps = -0.000833333
warmup_tau_s = 450.0
[temperature]
initial_c = 18.0
ramp_c_per_s = 0.0007
cycle_amplitude_c = 1.5
cycle_period_s = 1800.0
warmup_rise_c = 4.0
warmup_tau_s = 700.0
reference_c = 22.0
bias_dps_per_c = 2.78e-5
shupe_dps_per_c_per_s = 0.0166667
[scale_factor]
error_ppm = 150.0
quadratic_ppm_per_dps = 0.3
[motion]
profile = "turntable"
rate_dps = 0.1
latitude_deg = 45.0
[motion.turntable]
repeat = true
[[motion.turntable.step]]
duration_s = 5.0
[[motion.turntable.step]]
angle_deg = 90.0
rate_dps = 10.0
[timing]
rate_error_ppm = 40.0
jitter_rms_s = 0.0001
[faults]
drop_probability = 0.001
spike_probability = 0.0005
spike_amplitude_dps = 2.0
[family]
unit_seed = 3
unit_spread = 0.2
initial_c_range = [10.0, 35.0]
"#;

/// `gyro convert` keeps every term the simulator has: the converted file gives the old
/// model, and the same records, bit for bit.
#[test]
fn convert_keeps_every_simulator_term_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let old_path = d.join("rich.toml");
    fs::write(&old_path, RICH_OLD_MODEL).expect("write");
    let conv = d.join("rich-gyro.toml");
    host_sim()
        .args([
            "gyro",
            "convert",
            "--input",
            &s(&old_path),
            "--output",
            &s(&conv),
        ])
        .assert()
        .success();
    let before = Model::from_toml_str(RICH_OLD_MODEL, "old").expect("old model");
    let now = Gyro::load(&conv).expect("converted").model;
    assert_eq!(now, before);
    assert_eq!(csv_bytes(&now, 5, 5000), csv_bytes(&before, 5, 5000));
    let text = fs::read_to_string(&conv).expect("text");
    for key in [
        "quantization_mode = \"angle\"",
        "rate_ramp_dph_per_h = 0.022032",
        "shupe_dph_per_c_per_min = 1.000002",
        "[[motion.turntable.step]]",
        "[family]",
    ] {
        assert!(text.contains(key), "{key}: {text}");
    }
    // `gyro show` of the file: the same model again.
    let out = host_sim()
        .args(["gyro", "show", &s(&conv)])
        .output()
        .expect("runs");
    assert!(out.status.success());
    let shown = String::from_utf8_lossy(&out.stdout).to_string();
    let g = Gyro::from_toml_str(&shown, "shown.toml", None).expect("parses");
    assert_eq!(g.model, before);
}

#[test]
fn old_formats_are_refused_naming_the_new_keys() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("o.csv");
    let model = s(&old("model-ecore2000.toml"));
    host_sim()
        .args([
            "simulate",
            "--gyro",
            &model,
            "--duration-s",
            "1",
            "--seed",
            "1",
        ])
        .arg("--output")
        .arg(&out)
        .assert()
        .failure()
        .stderr(contains(format!("{model}:15:1: the old model-file format")))
        .stderr(contains(
            "[quantization] quantum_dps -> quantum_dps (top level, same unit)",
        ))
        .stderr(contains(
            "[noise] arw_dps_per_rthz -> arw_deg_per_rth (top level, x 60)",
        ))
        .stderr(contains(
            "[temperature] shupe_dps_per_c_per_s -> [temperature] shupe_dph_per_c_per_min (x 60)",
        ))
        .stderr(contains("host-sim gyro convert --input"));
    assert!(!out.exists());
    let sensor = s(&old("sensor-kvh1750.toml"));
    host_sim()
        .args(["replay", "--gyro", &sensor, "--input", "x.csv", "--output"])
        .arg(&out)
        .assert()
        .failure()
        .stderr(contains("the old sensor-file format"))
        .stderr(contains(
            "noise_density_deg_rth -> arw_deg_per_rth (same unit)",
        ));
    assert!(!out.exists());
}

/// A static E-Core record of `duration_s` at `seed`.
fn ecore_record(d: &Path, seed: &str, duration_s: &str) -> PathBuf {
    let p = d.join(format!("rec{seed}.csv"));
    simulate("ecore2000", duration_s, seed, &p);
    p
}

#[test]
fn gap_takes_a_builtin_name_and_writes_its_model() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let rec = d.join("kvh.csv");
    simulate("kvh1750", "60", "4", &rec);
    let json = d.join("gap.json");
    let saved = d.join("gap-model.toml");
    // `--sim kvh1750` was "No such file"; the old flag name is kept as an alias.
    for flag in ["--gyro", "--sim"] {
        host_sim()
            .args(["gap", "--input", &s(&rec), flag, "kvh1750", "--no-task"])
            .args([
                "--simulations",
                "4",
                "--rounds",
                "1",
                "--effects",
                "white_noise",
            ])
            .arg("--json")
            .arg(&json)
            .arg("--save-gyro")
            .arg(&saved)
            .assert()
            .success();
        let j: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("json");
        assert_eq!(j["baseline_source"], "user model (--gyro)");
    }
    // The saved model is the gyro's (one round: nothing applied), and simulate takes it.
    let g = Gyro::load(&saved).expect("saved model");
    assert_eq!(g.model, Gyro::builtin_named("kvh1750").expect("b").model);
    assert_eq!(g.name, "kvh1750");
    let a = simulate(&s(&saved), "2", "9", &d.join("a.csv"));
    let b = simulate("kvh1750", "2", "9", &d.join("b.csv"));
    assert_eq!(a, b);
    // Without a gyro: the fitted baseline's terms, in datasheet units.
    let fitted = d.join("fitted.toml");
    host_sim()
        .args([
            "gap",
            "--input",
            &s(&rec),
            "--no-task",
            "--simulations",
            "4",
        ])
        .args(["--rounds", "1", "--json"])
        .arg(&json)
        .arg("--save-model")
        .arg(&fitted)
        .assert()
        .success();
    let text = fs::read_to_string(&fitted).expect("fitted");
    assert!(text.contains("arw_deg_per_rth = "), "{text}");
    assert!(text.contains("sample_rate_hz = 1000.0"), "{text}");
    let f = Gyro::load(&fitted).expect("fitted file");
    let arw_deg_rth = f.model.noise.arw_dps_per_rthz * 60.0;
    assert!((arw_deg_rth / 0.012 - 1.0).abs() < 0.1, "{arw_deg_rth}");
    simulate(&s(&fitted), "2", "1", &d.join("c.csv"));
}

#[test]
fn allan_writes_its_fit_and_simulate_takes_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    // White noise and rate random walk, datasheet units, 50 Hz.
    let gyro = d.join("white.toml");
    fs::write(
        &gyro,
        "name = \"white\"\nsample_rate_hz = 50.0\narw_deg_per_rth = 0.5\nrrw_dph_per_rth = 20.0\n",
    )
    .expect("write");
    let rec = d.join("rec.csv");
    simulate(&s(&gyro), "3600", "2", &rec);
    let saved = d.join("fitted.toml");
    host_sim()
        .args(["allan", "--input", &s(&rec), "--json"])
        .arg(d.join("adev.json"))
        .arg("--save-gyro")
        .arg(&saved)
        .assert()
        .success();
    let text = fs::read_to_string(&saved).expect("saved");
    assert!(text.contains("name = \"rec\""), "{text}");
    assert!(text.contains("sample_rate_hz = 50.0"), "{text}");
    // The file holds allan's fitted terms (6 significant digits), 0 where a term is dropped.
    let g = Gyro::load(&saved).expect("saved file");
    let j: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(d.join("adev.json")).expect("json"))
            .expect("json");
    let fitted = |symbol: &str| -> f64 {
        let terms = j["fit"]["terms"].as_array().expect("terms");
        let t = terms.iter().find(|t| t["symbol"] == symbol).expect("term");
        if t["active"].as_bool().expect("active") {
            t["value"].as_f64().expect("value")
        } else {
            0.0
        }
    };
    let n = &g.model.noise;
    for (symbol, got) in [
        ("N", n.arw_dps_per_rthz),
        ("B", n.bias_instability_dps),
        ("K", n.rrw_dps_per_s_rthz),
        ("R", n.rate_ramp_dps_per_s),
    ] {
        let want = fitted(symbol);
        assert!(
            (got - want).abs() <= 1e-5 * want.abs(),
            "{symbol}: {got} vs {want}"
        );
    }
    // The white noise the record was made with, within 5 %.
    let n_deg_rth = n.arw_dps_per_rthz * 60.0;
    assert!((n_deg_rth / 0.5 - 1.0).abs() < 0.05, "N {n_deg_rth}");
    // simulate takes it as written.
    simulate(&s(&saved), "10", "1", &d.join("again.csv"));
    // identify and replay need a full scale and a drift bound: named.
    host_sim()
        .args([
            "replay",
            "--gyro",
            &s(&saved),
            "--input",
            &s(&rec),
            "--output",
        ])
        .arg(d.join("o.csv"))
        .assert()
        .failure()
        .stderr(contains("full_scale_dps missing"));
}

#[test]
fn identify_writes_the_fitted_model_that_replay_and_image_run() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let runs = [ecore_record(d, "1", "120"), ecore_record(d, "2", "120")];
    let img = d.join("unit.fogi");
    let saved = d.join("unit.toml");
    host_sim()
        .args([
            "identify",
            "--preset",
            "motion",
            "--gyro",
            "ecore2000",
            "--input",
        ])
        .args(runs.iter())
        .arg("--save-identifier")
        .arg(&img)
        .arg("--save-gyro")
        .arg(&saved)
        .assert()
        .success();
    let g = Gyro::load(&saved).expect("saved gyro file");
    let image = host_sim::motion::read_image(&img).expect("image");
    let id = g.identified.expect("[identified]");
    assert_eq!(id.model, image.model, "the image's model, bit for bit");
    assert_eq!(id.runs, 2);
    assert_eq!(g.model, Gyro::builtin_named("ecore2000").expect("b").model);
    // replay with the file runs the same filter as with the image: the same output.
    let rec = ecore_record(d, "3", "60");
    let (a, b) = (d.join("a.csv"), d.join("b.csv"));
    host_sim()
        .args([
            "replay",
            "--input",
            &s(&rec),
            "--identifier",
            &s(&img),
            "--output",
        ])
        .arg(&a)
        .assert()
        .success();
    host_sim()
        .args([
            "replay",
            "--input",
            &s(&rec),
            "--gyro",
            &s(&saved),
            "--output",
        ])
        .arg(&b)
        .assert()
        .success()
        .stderr(contains(
            "[identified] model (fitted on 2 calibration runs)",
        ));
    assert_eq!(fs::read(&a).expect("a"), fs::read(&b).expect("b"));
    // image --gyro describes the same image as image --input.
    let (ja, jb) = (d.join("ia.json"), d.join("ib.json"));
    host_sim()
        .args(["image", "--input", &s(&img), "--json", &s(&ja)])
        .assert()
        .success();
    host_sim()
        .args(["image", "--gyro", &s(&saved), "--json", &s(&jb)])
        .assert()
        .success();
    assert_eq!(fs::read(&ja).expect("a"), fs::read(&jb).expect("b"));
    // simulate takes the file (its datasheet part) and says the fitted part is not simulated.
    host_sim()
        .args([
            "simulate",
            "--gyro",
            &s(&saved),
            "--duration-s",
            "1",
            "--seed",
            "1",
        ])
        .arg("--output")
        .arg(d.join("sim.csv"))
        .assert()
        .success()
        .stderr(contains("[identified]"))
        .stderr(contains("not simulated"));
}

/// Neither unit fits the firmware (E-Core decoder, 60 deg/s; kvh1750 also at 1 kHz): the
/// image is still described on stdout, then `image` exits non-zero with the verdict.
#[test]
fn image_of_a_builtin_gyro_and_of_a_user_file() {
    host_sim()
        .args(["image", "--gyro", "kvh1750"])
        .assert()
        .code(1) // 1 kHz, 490 deg/s: does not fit the firmware (UART, decoder)
        .stdout(contains("sensor: 1000 Hz, full scale 490 deg/s"))
        .stdout(contains("fitted on 0 calibration runs"))
        .stderr(contains("the image does not fit the firmware"));
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("mine.toml");
    fs::write(
        &p,
        "sample_rate_hz = 200.0\nfull_scale_dps = 100.0\narw_deg_per_rth = 0.05\ndrift_bound_dph = 30.0\n",
    )
    .expect("write");
    host_sim()
        .args(["image", "--gyro", &s(&p)])
        .assert()
        .code(1) // 100 deg/s: beyond the firmware's decoder
        .stderr(contains("decoder full scale 60 deg/s < unit's 100 deg/s"))
        .stdout(contains("sensor: 200 Hz, full scale 100 deg/s"))
        .stdout(contains("white 0.0500 deg/sqrt(h)"));
}

/// Every command that takes a gyro takes `--gyro NAME|FILE`; the old names work, hidden.
#[test]
fn one_flag_for_the_gyro_everywhere() {
    for cmd in ["simulate", "gap", "identify", "replay", "image"] {
        let out = host_sim().args([cmd, "--help"]).output().expect("runs");
        let help = String::from_utf8_lossy(&out.stdout);
        assert!(help.contains("--gyro <NAME|FILE>"), "{cmd}: {help}");
        // The old names are hidden aliases: no option line shows them.
        for line in help.lines().map(str::trim_start) {
            for old in ["--model", "--sensor", "--sim ", "--sim,", "--save-model"] {
                assert!(!line.starts_with(old), "{cmd} shows {old}: {help}");
            }
        }
    }
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let a = simulate("kvh1750", "1", "5", &d.join("a.csv"));
    for flag in ["--model", "--preset"] {
        let out = d.join(format!("{flag}.csv"));
        host_sim()
            .args([
                "simulate",
                flag,
                "kvh1750",
                "--duration-s",
                "1",
                "--seed",
                "5",
            ])
            .arg("--output")
            .arg(&out)
            .assert()
            .success();
        assert_eq!(fs::read(&out).expect("out"), a, "{flag}");
    }
    // A name that is no built-in and no file: the built-ins listed.
    host_sim()
        .args(["replay", "--gyro", "ecore", "--input", "x.csv", "--output"])
        .arg(d.join("o.csv"))
        .assert()
        .failure()
        .stderr(contains("ecore2000, kvh1750"));
}

#[test]
fn gyro_show_prints_a_builtin_to_start_from() {
    let out = host_sim()
        .args(["gyro", "show", "kvh1750"])
        .output()
        .expect("runs");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert_eq!(text, host_sim::gyro::BUILTIN[1].2);
    let g = Gyro::from_toml_str(&text, "shown.toml", None).expect("parses");
    assert_eq!(g.model, sim::preset("kvh1750").expect("b"));
}
