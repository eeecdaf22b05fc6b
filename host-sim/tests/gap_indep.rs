//! Smoke test of the independent-generator benchmark (issue 13): records made by
//! `scripts/gap_indep_gen.py` (numpy, written from the physics, not from the simulator),
//! 600 s at 25 Hz, 6 simulations per model, fitted baseline (no `--sim`): a strong
//! temperature effect (drift follows `temp_c` and its rate; must not be missed), a strong
//! sinusoid (must be named), and a `none` record carrying a temperature channel the drift
//! does not follow (must be `none`).
//! Skips with a message when python3 or numpy is absent (fails when `FOG_REQUIRE_NUMPY`,
//! set by `scripts/test-all.sh`, or `CI` is set). The full benchmark is
//! `scripts/gap_indep_bench.py` (docs/gap.md), not a CI test.

mod common;

use host_sim::gap::{self, Options};
use std::path::Path;
use std::process::Command;

fn generate(dir: &Path, class: &str, seed: u64, strength: Option<f64>) -> std::path::PathBuf {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/gap_indep_gen.py");
    let mut cmd = Command::new("python3");
    cmd.arg(script)
        .arg("--out")
        .arg(dir)
        .args(["--first-seed", &seed.to_string()])
        .args(["--per-class", "1", "--classes", class])
        .args(["--duration-s", "600", "--fs", "25", "--with-temp"]);
    if let Some(s) = strength {
        cmd.args(["--strength", &s.to_string()]);
    }
    let out = cmd.output().expect("python3 runs");
    assert!(
        out.status.success(),
        "generator failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir.join(format!("{class}-{seed}.csv"))
}

fn named(path: &Path) -> String {
    let (rec, time) =
        gap::read_rec(path, &host_sim::record::ReadOptions::default()).expect("record reads");
    let o = Options {
        seeds: 6,
        task: false,
        ..Default::default()
    };
    let d = gap::diagnose(&rec, time, None, &o).expect("diagnosis");
    eprintln!("{}: {} ({})", path.display(), d.effect, d.decision);
    d.effect
}

#[test]
fn independent_records_are_named() {
    if !common::python_with_numpy("the independent-generator benchmark") {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let t = generate(dir.path(), "temperature", 7, Some(15.0));
    let s = generate(dir.path(), "sinusoid", 7, Some(40.0));
    let n = generate(dir.path(), "none", 11, None);
    // Known failure (docs/gap.md): a strong drift driven mostly by d temp_c/dt during the
    // sensor's warm-up is flagged but named `warmup` (the temperature test's null holds
    // surrogate channels that also explain a transient). Asserted: it is not missed.
    assert_ne!(named(&t), "none");
    assert_eq!(named(&s), "sinusoid");
    assert_eq!(named(&n), "none");
}
