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

/// The firmware crate's directory (`fog-firmware/`, its own cargo workspace).
pub fn firmware_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fog-firmware")
}

/// Builds the firmware (`cargo build --release` inside `fog-firmware/`, same toolchain,
/// `extra_args` appended, e.g. features) and returns the ELF's path. The firmware always
/// builds into `fog-firmware/target`, whatever `CARGO_TARGET_DIR` says, and without the
/// caller's `RUSTFLAGS` (they are meant for host crates).
///
/// # Panics
/// If the build fails.
pub fn firmware_elf(extra_args: &[&str]) -> PathBuf {
    firmware_elf_in("target", extra_args, &[])
}

/// [`firmware_elf`] into `fog-firmware/TARGET_SUBDIR` (so that a test build with other
/// features does not replace the ELF other tests use), with `envs` set for the build.
///
/// # Panics
/// If the build fails.
pub fn firmware_elf_in(
    target_subdir: &str,
    extra_args: &[&str],
    envs: &[(&str, &std::ffi::OsStr)],
) -> PathBuf {
    let dir = firmware_dir();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let target_dir = dir.join(target_subdir);
    let status = Command::new(cargo)
        .current_dir(&dir)
        .args(["build", "-q", "--release"])
        .args(extra_args)
        .envs(envs.iter().copied())
        .env("CARGO_TARGET_DIR", &target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .status()
        .expect("cargo runs");
    assert!(status.success(), "building fog-firmware failed");
    target_dir.join("thumbv7em-none-eabihf/release/fog-firmware")
}

fn on_path(program: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(program))
            .find(|p| p.is_file())
    })
}

/// `qemu-system-arm`: from `PATH`, or installed by `scripts/setup.sh` (apt-get) if missing.
/// `None`, with the reason printed, only when it is missing and cannot be installed.
pub fn qemu_system_arm() -> Option<PathBuf> {
    if let Some(p) = on_path("qemu-system-arm") {
        return Some(p);
    }
    let setup = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scripts/setup.sh");
    eprintln!("qemu-system-arm not found: running {}", setup.display());
    let ran = Command::new("bash").arg(&setup).status();
    match on_path("qemu-system-arm") {
        Some(p) => Some(p),
        None => {
            eprintln!(
                "SKIPPED: qemu-system-arm is missing and {} could not install it ({ran:?})",
                setup.display()
            );
            None
        }
    }
}

/// The `fw-cycles` tool (this crate's binary), built once per test process in the release
/// profile: it reads traces of about 10^8 instructions, over a minute unoptimised. Returns
/// its path.
///
/// # Panics
/// If the build fails.
pub fn fw_cycles() -> PathBuf {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let status = Command::new(cargo)
            .args(["build", "-q", "--release", "-p", "fog-system-tests"])
            .args(["--bin", "fw-cycles"])
            .status()
            .expect("cargo runs");
        assert!(status.success(), "building fw-cycles failed");
        let target = std::env::var_os("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target"));
        target.join("release/fw-cycles")
    })
    .clone()
}

pub mod cycles;
