//! The independent NumPy generator `scripts/gen_nav_records.py`: its self-check passes, and
//! its records read as [`NavRecord`]s that the baselines score. Skips (with a message) when
//! python3 or numpy is absent, but fails when `FOG_REQUIRE_NUMPY` (set by
//! `scripts/test-all.sh`, after `scripts/setup.sh` installed numpy) or `CI` is set: the
//! independent generator is never skipped there.

mod common;

use host_sim::nav::{run, AlignmentBias, GatedKalman, NavRecord, NoCompensation};
use host_sim::record::{ReadOptions, Record};
use std::path::PathBuf;
use std::process::Command;

fn script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scripts/gen_nav_records.py")
}

#[test]
fn second_generator_self_check() {
    if !common::python_with_numpy("the second generator") {
        return;
    }
    let out = Command::new("python3")
        .arg(script())
        .arg("--self-check")
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "self-check failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn second_generator_records_are_scored() {
    if !common::python_with_numpy("the second generator") {
        return;
    }
    let dir = tempfile::tempdir().expect("tmp");
    let csv = dir.path().join("v.csv");
    let status = Command::new("python3")
        .arg(script())
        .args(["--kind", "vehicle", "--seed", "3", "--duration-s", "900"])
        .args(["--unit-seed", "1", "--unit-spread", "0.2", "--out"])
        .arg(&csv)
        .status()
        .expect("run python3");
    assert!(status.success());
    let rec = NavRecord::try_from(&Record::read(&csv, &ReadOptions::default()).expect("reads"))
        .expect("reads as a NavRecord");
    assert_eq!(rec.len(), 90_000);
    assert!(rec.temp_c.is_some());
    assert!(rec.moving.iter().any(|&m| m) && rec.moving[..30_000].iter().all(|&m| !m));
    let still = rec.still_truth();
    let none = run(&rec, &mut NoCompensation, &still).scores;
    let align = run(&rec, &mut AlignmentBias::default(), &still).scores;
    let zaru = run(&rec, &mut GatedKalman::new(1e-12, 1.2e-4), &still).scores;
    eprintln!(
        "second generator, vehicle seed 3, 900 s: heading RMS none {:.4} deg, alignment {:.4}, \
         gated Kalman {:.4}",
        none.heading_rms_deg, align.heading_rms_deg, zaru.heading_rms_deg
    );
    // The truth-gated baselines never take rotation for drift: their heading errors stay
    // at the drift's scale (deg), nowhere near the turns' (hundreds of deg).
    assert!(align.heading_rms_deg < 1.0 && zaru.heading_rms_deg < 1.0);
    assert!(none.heading_rms_deg.is_finite());
}
