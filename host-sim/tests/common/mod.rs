//! Helpers shared by the CLI tests (a test file that uses them declares `mod common;`).
#![allow(dead_code)] // each test crate uses a part of them

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

/// The `host-sim` binary under test.
pub fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// The built-in ecore2000 gyro as a vehicle (60 s alignment, stops, drives, turns), written
/// to `dir/name`: its records carry truth (`true_rate_dps`, `drift_dps`, `moving`).
pub fn vehicle_gyro(dir: &Path, name: &str) -> PathBuf {
    let preset =
        fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("gyros/ecore2000.toml"))
            .expect("preset");
    // The preset's [motion] table is its last; the vehicle profile replaces it.
    let head = preset.split("[motion]").next().expect("preset head");
    let toml = format!("{head}[motion]\nprofile = \"vehicle\"\n[motion.vehicle]\nalign_s = 60.0\n");
    let path = dir.join(name);
    fs::write(&path, toml).expect("write the vehicle gyro");
    path
}

/// `simulate --gyro GYRO --duration-s S --seed K --output OUT`, which must succeed.
pub fn simulate(gyro: impl AsRef<std::ffi::OsStr>, duration_s: u32, seed: u64, out: &Path) {
    host_sim()
        .args(["simulate", "--gyro"])
        .arg(gyro)
        .arg("--duration-s")
        .arg(duration_s.to_string())
        .arg("--seed")
        .arg(seed.to_string())
        .arg("--output")
        .arg(out)
        .assert()
        .success();
}

/// `host-sim gap ARGS --input P --json J`, which must succeed: (the JSON, stderr).
pub fn gap(p: &Path, json: &Path, args: &[&str]) -> (serde_json::Value, String) {
    let a = host_sim()
        .arg("gap")
        .args(args)
        .arg("--input")
        .arg(p)
        .arg("--json")
        .arg(json)
        .assert()
        .success();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    let v = serde_json::from_str(&fs::read_to_string(json).expect("json")).expect("parse");
    (v, err)
}

/// Whether `python3` with NumPy runs here (the independent generators need it). When it
/// does not: panics if `FOG_REQUIRE_NUMPY` (set by `scripts/test-all.sh` after
/// `scripts/setup.sh` installed NumPy) or `CI` is set, else prints that `what` is not
/// tested and returns false (the caller skips).
pub fn python_with_numpy(what: &str) -> bool {
    let ok = std::process::Command::new("python3")
        .args(["-c", "import numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var_os("FOG_REQUIRE_NUMPY").is_none() && std::env::var_os("CI").is_none(),
            "python3 with numpy not found, and FOG_REQUIRE_NUMPY or CI is set: scripts/setup.sh installs it"
        );
        eprintln!("SKIPPED: python3 with numpy not found; {what} is not tested (scripts/setup.sh installs it)");
    }
    ok
}
