//! Helpers for the system tests in `tests/tests/`.

use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

/// The `host-sim` binary, built once per test process (so that `cargo test -p
/// fog-system-tests` works alone, without relying on another package's build).
///
/// # Panics
/// If the build fails: a test cannot go on without the binary.
pub fn host_sim() -> Command {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    let bin = BIN.get_or_init(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let status = Command::new(cargo)
            .args(["build", "-q", "-p", "host-sim", "--bin", "host-sim"])
            .status()
            .expect("cargo runs");
        assert!(status.success(), "building host-sim failed");
        let target = std::env::var_os("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target"));
        target.join("debug/host-sim")
    });
    Command::new(bin)
}

/// `../shared/data/real` when present (CI has it, a user's clone does not); otherwise
/// prints why the caller skips and returns `None`.
pub fn shared_real() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!(
            "SKIPPED: {} is absent (it exists in CI, not in a user's clone)",
            p.display()
        );
        None
    }
}
