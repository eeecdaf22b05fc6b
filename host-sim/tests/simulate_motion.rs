//! Motion profiles (`vehicle`, `turntable`, `file`), the `moving` truth and the gyro family.

use assert_cmd::Command;
use host_sim::gyro::Gyro;
use host_sim::sim::{self, Model, Platform, Profile, Simulator, Vehicle};
use rand::SeedableRng;
use std::fs;

/// A gyro file's simulator model (host_sim::gyro: the reader every command uses).
fn read(toml: &str, name: &str) -> anyhow::Result<Model> {
    Gyro::from_toml_str(toml, name, None).map(|g| g.model)
}

fn model(toml: &str) -> Model {
    read(toml, "test.toml").expect("valid model")
}

fn samples(m: &Model, seed: u64, rate_hz: f64, duration_s: f64) -> Vec<sim::Sample> {
    let mut s = Simulator::new(m, seed, rate_hz).expect("simulator");
    let mut out = Vec::new();
    loop {
        let x = s.next_sample();
        if x.t_s >= duration_s {
            return out;
        }
        out.push(x);
    }
}

/// FNV-1a, 64 bit.
fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[test]
fn static_record_is_bit_identical_to_before_motion_profiles() {
    // Hash of `host-sim simulate --gyro ecore2000 --duration-s 200 --seed 3` written by the
    // simulator before the motion profiles existed (commit 9005f48): 1332744 bytes.
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("s.csv");
    Command::cargo_bin("host-sim")
        .expect("binary")
        .args(["simulate", "--gyro", "ecore2000", "--duration-s", "200"])
        .args(["--seed", "3", "--output"])
        .arg(&out)
        .assert()
        .success();
    let bytes = fs::read(&out).expect("read");
    assert_eq!(bytes.len(), 1_332_744);
    assert_eq!(fnv(&bytes), 0xa966_7e76_af5f_0c49);
}

const VEHICLE: &str = "sample_rate_hz = 10.0\n[motion]\nprofile = \"vehicle\"\n";

#[test]
fn vehicle_is_reproducible_by_seed() {
    let m = model(VEHICLE);
    let a = samples(&m, 7, 10.0, 2000.0);
    let b = samples(&m, 7, 10.0, 2000.0);
    let c = samples(&m, 8, 10.0, 2000.0);
    assert_eq!(a, b);
    assert!(a
        .iter()
        .zip(&c)
        .any(|(x, y)| x.true_rate_dps != y.true_rate_dps));
}

#[test]
fn vehicle_statistics_match_its_parameters() {
    let m = model(VEHICLE);
    let v = Vehicle::default();
    let mut p = Platform::new(&m.motion, rand_pcg::Pcg64Mcg::seed_from_u64(11)).expect("p");
    let dt_s = 0.1;
    let n = 400_000; // 40000 s, about 200 stop/drive cycles
    let (mut still, mut after, mut max_dps) = (0usize, 0usize, 0.0f64);
    let (mut road, mut road_in_band) = (0usize, 0usize);
    for k in 0..n {
        let t = k as f64 * dt_s;
        let s = p.at(t);
        max_dps = max_dps.max(s.rate_dps.abs());
        if t < v.align_s {
            assert!(!s.moving && s.rate_dps == 0.0, "alignment is still at {t}");
            continue;
        }
        after += 1;
        if !s.moving {
            still += 1;
            assert_eq!(s.rate_dps, 0.0, "a stop has rate 0 at {t}");
        } else if s.rate_dps.abs() < v.road_rate_max_dps {
            road += 1;
            if s.rate_dps.abs() >= 0.05 {
                road_in_band += 1;
            }
        }
    }
    let frac = still as f64 / after as f64;
    let want = v.still_fraction();
    assert!(
        (frac - want).abs() < 0.04,
        "still fraction {frac} vs {want}"
    );
    assert!(max_dps <= v.max_rate_dps() + 1e-9, "max {max_dps}");
    assert!(max_dps > v.turn_rate_min_dps, "turns happen: max {max_dps}");
    let band = road_in_band as f64 / road as f64;
    assert!(band > 0.7, "road yaw mostly 0.05..3 deg/s: {band}");
}

#[test]
fn moving_column_follows_the_profile() {
    let m = model(VEHICLE);
    let s = samples(&m, 1, 10.0, 3000.0);
    assert!(s.iter().any(|x| x.moving) && s.iter().any(|x| !x.moving));
    for x in &s {
        if x.true_rate_dps != 0.0 {
            assert!(
                x.moving,
                "rate {} at {} called still",
                x.true_rate_dps, x.t_s
            );
        }
    }
    let stat = sim::preset("ecore2000").expect("preset");
    assert!(samples(&stat, 1, 100.0, 10.0).iter().all(|x| !x.moving));
}

const TURNTABLE: &str = "sample_rate_hz = 1000.0
[motion]
profile = \"turntable\"
[[motion.turntable.step]]
duration_s = 10.0
[[motion.turntable.step]]
angle_deg = 90.0
rate_dps = 10.0
[[motion.turntable.step]]
duration_s = 5.0
[[motion.turntable.step]]
angle_deg = -45.0
rate_dps = 15.0
[[motion.turntable.step]]
rate_dps = 2.0
duration_s = 10.0
";

#[test]
fn turntable_angle_steps_integrate_to_the_commanded_angles() {
    let m = model(TURNTABLE);
    let s = samples(&m, 1, 1000.0, 60.0);
    let dt = 1e-3;
    // (end of step s, commanded cumulative angle deg)
    let marks = [
        (10.0, 0.0),
        (19.0, 90.0),
        (24.0, 90.0),
        (27.0, 45.0),
        (37.0, 65.0),
    ];
    let mut angle = 0.0f64;
    let mut it = marks.iter().peekable();
    for x in &s {
        if let Some(&&(t_end, want)) = it.peek() {
            if x.t_s >= t_end - 1e-9 {
                assert!(
                    (angle - want).abs() < 0.02,
                    "at {t_end} s: {angle} vs {want}"
                );
                it.next();
            }
        }
        angle += x.true_rate_dps * dt;
    }
    assert!(it.peek().is_none());
    assert!(
        (angle - 65.0).abs() < 0.02,
        "still after the schedule: {angle}"
    );
    assert!(!s.last().expect("samples").moving);
}

#[test]
fn file_profile_interpolates_its_input() {
    let dir = tempfile::tempdir().expect("tmp");
    fs::write(
        dir.path().join("rate.csv"),
        "t_s,true_rate_dps\n0,0\n10,5\n20,-5\n",
    )
    .expect("write");
    let toml = "sample_rate_hz = 10.0\n[motion]\nprofile = \"file\"\nfile = \"rate.csv\"\n";
    let path = dir.path().join("m.toml");
    fs::write(&path, toml).expect("write");
    let m = Gyro::load(&path).expect("model").model;
    let s = samples(&m, 1, 10.0, 25.0);
    for x in &s {
        let want = if x.t_s <= 10.0 {
            0.5 * x.t_s
        } else if x.t_s <= 20.0 {
            5.0 - (x.t_s - 10.0)
        } else {
            -5.0
        };
        assert!(
            (x.true_rate_dps - want).abs() < 1e-12,
            "{} {}",
            x.t_s,
            x.true_rate_dps
        );
        assert_eq!(x.moving, want != 0.0);
    }
    fs::write(
        dir.path().join("rate.csv"),
        "t_s,true_rate_dps\n0,0\n10,abc\n",
    )
    .expect("write");
    let e = Simulator::new(&m, 1, 10.0)
        .expect_err("bad number")
        .to_string();
    assert!(e.contains("rate.csv:3") && e.contains("abc"), "{e}");
    fs::write(dir.path().join("rate.csv"), "t_s,true_rate_dps\n0,0\n0,1\n").expect("write");
    let e = Simulator::new(&m, 1, 10.0).expect_err("t").to_string();
    assert!(
        e.contains("rate.csv:3") && e.contains("does not increase"),
        "{e}"
    );
}

#[test]
fn motion_errors_name_key_and_line() {
    let e = read(
        "[motion]\nprofile = \"vehicle\"\n[motion.vehicle]\nstop_min_s = 10\nstop_max_s = 5\n",
        "m.toml",
    )
    .expect_err("range")
    .to_string();
    assert!(
        e.starts_with("m.toml:5:") && e.contains("stop_max_s"),
        "{e}"
    );
    let e = read(
        "[motion]\nprofile = \"turntable\"\n[[motion.turntable.step]]\nduration_s = 1\n\
         [[motion.turntable.step]]\nangle_deg = 10\n",
        "m.toml",
    )
    .expect_err("angle without rate")
    .to_string();
    assert!(
        e.starts_with("m.toml:5:") && e.contains("#2 rate_dps"),
        "{e}"
    );
    let e = read("[motion]\nprofile = \"file\"\n", "m.toml")
        .expect_err("no file")
        .to_string();
    assert!(e.starts_with("m.toml:2:"), "{e}");
    let e = read("[motion]\nprofile = \"boat\"\n", "m.toml")
        .expect_err("unknown")
        .to_string();
    assert!(e.starts_with("m.toml:2:") && e.contains("boat"), "{e}");
    assert_eq!(
        model("[motion]\nprofile = \"sine\"\n").motion.profile,
        Profile::Constant
    );
}

#[test]
fn family_spreads_units_and_varies_records() {
    let base = sim::preset("ecore2000").expect("preset");
    let mut m = base.clone();
    m.family.unit_spread = 0.2;
    m.family.unit_seed = Some(1);
    m.family.initial_c_range = Some([10.0, 35.0]);
    m.family.warmup_rise_c_range = Some([2.0, 8.0]);
    m.family.ramp_c_per_s_range = Some([-1e-3, 1e-3]);
    let u1 = sim::realize(&m, 5);
    assert_eq!(u1, sim::realize(&m, 5), "reproducible");
    let mut m2 = m.clone();
    m2.family.unit_seed = Some(2);
    let u2 = sim::realize(&m2, 5);
    assert_ne!(u1.temperature.bias_dps_per_c, u2.temperature.bias_dps_per_c);
    assert_ne!(u1.bias.warmup_dps, base.bias.warmup_dps);
    // Same unit, another power-on: same coefficients, other conditions.
    let r2 = sim::realize(&m, 6);
    assert_eq!(u1.temperature.bias_dps_per_c, r2.temperature.bias_dps_per_c);
    assert_ne!(u1.temperature.initial_c, r2.temperature.initial_c);
    // Spread statistics over many units: relative 1-sigma near 0.2.
    let k: Vec<f64> = (0..2000)
        .map(|u| {
            let mut mu = m.clone();
            mu.family.unit_seed = Some(u);
            sim::realize(&mu, 0).temperature.bias_dps_per_c / base.temperature.bias_dps_per_c
        })
        .collect();
    let mean = k.iter().sum::<f64>() / k.len() as f64;
    let sd = (k.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / k.len() as f64).sqrt();
    assert!(
        (mean - 1.0).abs() < 0.02 && (sd - 0.2).abs() < 0.02,
        "{mean} {sd}"
    );
    for seed in 0..200 {
        let t = sim::realize(&m, seed).temperature;
        assert!((10.0..=35.0).contains(&t.initial_c) && (2.0..=8.0).contains(&t.warmup_rise_c));
    }
    // Off: unchanged.
    assert_eq!(sim::realize(&base, 9), base);
    let e = read(
        "[family]\nunit_spread = 0.1\ninitial_c_range = [30, 10]\n",
        "f.toml",
    )
    .expect_err("range")
    .to_string();
    assert!(
        e.starts_with("f.toml:3:") && e.contains("initial_c_range"),
        "{e}"
    );
}

#[test]
fn simulate_writes_moving_column_for_a_vehicle() {
    let dir = tempfile::tempdir().expect("tmp");
    let mpath = dir.path().join("v.toml");
    fs::write(&mpath, VEHICLE).expect("write");
    let out = dir.path().join("v.csv");
    Command::cargo_bin("host-sim")
        .expect("binary")
        .args(["simulate", "--gyro"])
        .arg(&mpath)
        .args(["--duration-s", "400", "--seed", "2", "--unit-seed", "4"])
        .args(["--unit-spread", "0.2", "--output"])
        .arg(&out)
        .assert()
        .success();
    let text = fs::read_to_string(&out).expect("read");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving")
    );
    let moving: Vec<&str> = lines.map(|l| l.rsplit(',').next().unwrap_or("")).collect();
    assert_eq!(moving.len(), 4000);
    assert!(moving.iter().all(|m| *m == "0" || *m == "1"));
    assert!(moving.contains(&"1") && moving[0] == "0");
}
