//! Helpers for the system tests in `tests/tests/`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The `host-sim` binary: the one `FOG_HOST_SIM_BIN` names (an absolute path), else built
/// once per test process (so that `cargo test -p fog-system-tests` works alone, without
/// relying on another package's build).
///
/// `scripts/test-all.sh` sets `FOG_HOST_SIM_BIN` to the binary its workspace test step
/// built (`target/debug/host-sim`): `cargo build -p host-sim` unifies other features than
/// `cargo test --workspace` and would build the crate a second time (docs/reliability.md,
/// "CI time").
///
/// # Panics
/// If `FOG_HOST_SIM_BIN` names no file, or the build fails: a test cannot go on without
/// the binary.
pub fn host_sim() -> Command {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    let bin = BIN.get_or_init(|| {
        if let Some(given) = std::env::var_os("FOG_HOST_SIM_BIN") {
            let given = PathBuf::from(given);
            assert!(
                given.is_file(),
                "FOG_HOST_SIM_BIN={} is not a file",
                given.display()
            );
            return given;
        }
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

/// One firmware build: where cargo builds it and what it builds it from.
///
/// Builds that differ only in their inputs share a target directory, so that only the
/// firmware crate itself rebuilds between them.
#[derive(Clone, Copy, Debug)]
pub struct FirmwareBuild<'a> {
    /// Cargo's target directory, relative to `fog-firmware/` (e.g. `target/bankimg`).
    pub target_subdir: &'a str,
    /// Arguments after `cargo build -q --release` (features).
    pub cargo_args: &'a [&'a str],
    /// Files `build.rs` embeds, as (environment variable naming the file, its bytes):
    /// `FOG_IDENTIFIER` (the identifier image; absent: `identifier/default.fogi`),
    /// `FOG_RT_CAPTURE` (the real-time feed's capture).
    pub input_files: &'a [(&'a str, &'a [u8])],
    /// Other environment variables for the build (e.g. `FOG_RT_BAUD`).
    pub envs: &'a [(&'a str, &'a str)],
}

impl FirmwareBuild<'static> {
    /// The release build for the QEMU board (`mps2-an386`) with the default image, into
    /// `fog-firmware/target` (where `scripts/test-all.sh` and a user build it).
    pub const DEFAULT: FirmwareBuild<'static> = FirmwareBuild {
        target_subdir: "target",
        cargo_args: &[],
        input_files: &[],
        envs: &[],
    };

    /// The STM32F407 board build, in its own target directory (as `scripts/test-all.sh`
    /// builds it).
    pub const STM32F407: FirmwareBuild<'static> = FirmwareBuild {
        target_subdir: "target/stm32",
        cargo_args: &["--no-default-features", "--features", "board-stm32f407"],
        ..Self::DEFAULT
    };

    /// The STM32 build's QEMU variant (`netduinoplus2`), in its own target directory.
    pub const NETDUINO: FirmwareBuild<'static> = FirmwareBuild {
        target_subdir: "target/netduino",
        cargo_args: &["--no-default-features", "--features", "qemu-netduinoplus2"],
        ..Self::DEFAULT
    };
}

/// Every variable `fog-firmware/build.rs` reads: removed from the caller's environment so
/// that only the build's own values reach it.
const FIRMWARE_BUILD_VARS: [&str; 3] = ["FOG_IDENTIFIER", "FOG_RT_CAPTURE", "FOG_RT_BAUD"];

/// The static of the firmware that holds each embedded input, by its variable.
const EMBEDDED_STATICS: [(&str, &str); 2] = [
    ("FOG_IDENTIFIER", "IDENTIFIER_IMAGE"),
    ("FOG_RT_CAPTURE", "CAPTURE"),
];

/// A firmware ELF of one test's own: a copy of the build's ELF in a folder no other test
/// writes (`fog-firmware/target/hil/LABEL-XXXXXX`), for the test's captures and logs too.
/// The folder is removed when the test passes and kept (its path printed) when it panics,
/// or always with `FOG_KEEP_HIL=1`.
#[derive(Debug)]
pub struct Firmware {
    /// The ELF this test runs.
    pub elf: PathBuf,
    /// The folder (taken by `drop`, which keeps or removes it).
    dir: Option<tempfile::TempDir>,
}

impl Firmware {
    /// The test's own folder.
    pub fn dir(&self) -> &Path {
        self.dir
            .as_ref()
            .map(tempfile::TempDir::path)
            .expect("the folder is held until drop")
    }

    /// A file named `name` in the test's own folder.
    pub fn file(&self, name: &str) -> PathBuf {
        self.dir().join(name)
    }

    /// The bytes of the firmware's static `name` (e.g. `IDENTIFIER_IMAGE`), read from the
    /// ELF's symbol table and the section that holds it; `None` if no symbol names it.
    ///
    /// # Panics
    /// If the ELF cannot be read or parsed, or the symbol's bytes are outside its section.
    pub fn embedded(&self, name: &str) -> Option<Vec<u8>> {
        embedded_static(&self.elf, name)
    }

    /// Panics unless the ELF's static for input `var` (`FOG_IDENTIFIER`: `IDENTIFIER_IMAGE`,
    /// `FOG_RT_CAPTURE`: `CAPTURE`) holds exactly `bytes`.
    ///
    /// # Panics
    /// If it does not, or `var` is not an embedded input.
    pub fn assert_carries(&self, var: &str, bytes: &[u8]) {
        let name = EMBEDDED_STATICS
            .iter()
            .find(|(v, _)| *v == var)
            .map(|(_, s)| *s)
            .unwrap_or_else(|| panic!("no embedded static known for {var}"));
        let embedded = self
            .embedded(name)
            .unwrap_or_else(|| panic!("no symbol {name} in {}", self.elf.display()));
        assert!(
            embedded == bytes,
            "{}: the ELF's {name} ({} bytes, FNV-1a {:016x}) is not the {var} asked for \
             ({} bytes, {:016x})",
            self.elf.display(),
            embedded.len(),
            fnv1a64(&embedded),
            bytes.len(),
            fnv1a64(bytes)
        );
    }
}

impl Drop for Firmware {
    fn drop(&mut self) {
        let keep = std::thread::panicking() || std::env::var_os("FOG_KEEP_HIL").is_some();
        if let Some(dir) = self.dir.take() {
            if keep {
                eprintln!("kept for inspection: {}", dir.keep().display());
            }
        }
    }
}

/// The bytes of static `name` of `elf`: the symbol whose (mangled) name has the path
/// segment `name` (`..3app16IDENTIFIER_IMAGE17h..E`), its address and size.
fn embedded_static(elf: &Path, name: &str) -> Option<Vec<u8>> {
    use object::{Object, ObjectSection, ObjectSymbol};
    let data = std::fs::read(elf).unwrap_or_else(|e| panic!("{}: {e}", elf.display()));
    let file = object::File::parse(&*data).unwrap_or_else(|e| panic!("{}: {e}", elf.display()));
    let segment = format!("{}{name}17h", name.len());
    let symbol = file
        .symbols()
        .find(|s| s.name().is_ok_and(|n| n.contains(&segment)))?;
    let section = symbol
        .section_index()
        .and_then(|i| file.section_by_index(i).ok())
        .unwrap_or_else(|| panic!("{}: {name} has no section", elf.display()));
    let bytes = section
        .data_range(symbol.address(), symbol.size())
        .ok()
        .flatten()
        .unwrap_or_else(|| panic!("{}: {name}'s bytes are outside its section", elf.display()));
    Some(bytes.to_vec())
}

/// FNV-1a, 64 bits: names an input file by its content.
fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

/// Builds the firmware as `build` says (`cargo build --release` inside `fog-firmware/`, same
/// toolchain, without the caller's `RUSTFLAGS` and `FOG_*` variables) and returns a copy of
/// its ELF in a folder of the test's own, named `label-XXXXXX`.
///
/// Tests build in parallel, in one process and across processes (a debug and a release
/// `cargo test` at once): a build, and the copy of its ELF, hold an exclusive lock on
/// `TARGET_SUBDIR/.fog-build.lock`, so no other build can replace the ELF between the two.
/// Each input file is written (under that lock) to `TARGET_SUBDIR/inputs/VAR-HASH.bin`,
/// named by its content, so a build of other content never rewrites it.
///
/// The copy is then proven to carry what was asked: every embedded static read back from
/// the ELF's symbol table equals its input byte for byte (the image: `FOG_IDENTIFIER`'s
/// bytes, else `identifier/default.fogi`).
///
/// # Panics
/// If the lock, the build or the copy fails, or the ELF does not carry its inputs.
pub fn firmware(build: &FirmwareBuild, label: &str) -> Firmware {
    let target_dir = firmware_dir().join(build.target_subdir);
    std::fs::create_dir_all(target_dir.join("inputs"))
        .unwrap_or_else(|e| panic!("{}: {e}", target_dir.display()));
    let runs = firmware_dir().join("target/hil");
    std::fs::create_dir_all(&runs).unwrap_or_else(|e| panic!("{}: {e}", runs.display()));
    let dir = tempfile::Builder::new()
        .prefix(&format!("{label}-"))
        .tempdir_in(&runs)
        .unwrap_or_else(|e| panic!("a folder in {}: {e}", runs.display()));
    let elf = dir.path().join(format!("{label}.elf"));

    let lock_path = target_dir.join(".fog-build.lock");
    let lock = std::fs::File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .unwrap_or_else(|e| panic!("{}: {e}", lock_path.display()));
    lock.lock()
        .unwrap_or_else(|e| panic!("locking {}: {e}", lock_path.display()));
    let mut inputs = Vec::new();
    for (var, bytes) in build.input_files {
        let path = target_dir
            .join("inputs")
            .join(format!("{var}-{:016x}.bin", fnv1a64(bytes)));
        if std::fs::read(&path).ok().as_deref() != Some(*bytes) {
            std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
        inputs.push((*var, path));
    }
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut command = Command::new(cargo);
    command
        .current_dir(firmware_dir())
        .args(["build", "-q", "--release"])
        .args(build.cargo_args)
        .env("CARGO_TARGET_DIR", &target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET");
    for var in FIRMWARE_BUILD_VARS {
        command.env_remove(var);
    }
    command.envs(inputs.iter().map(|(v, p)| (*v, p.as_os_str())));
    command.envs(build.envs.iter().copied());
    let status = command.status().expect("cargo runs");
    assert!(status.success(), "building fog-firmware ({label}) failed");
    let built = target_dir.join("thumbv7em-none-eabihf/release/fog-firmware");
    std::fs::copy(&built, &elf)
        .unwrap_or_else(|e| panic!("{} -> {}: {e}", built.display(), elf.display()));
    drop(lock);

    let fw = Firmware {
        elf,
        dir: Some(dir),
    };
    let default;
    let image: &[u8] = match build
        .input_files
        .iter()
        .find(|(v, _)| *v == "FOG_IDENTIFIER")
    {
        Some((_, bytes)) => bytes,
        None => {
            default = default_image();
            &default
        }
    };
    let expected = build
        .input_files
        .iter()
        .filter(|(v, _)| *v != "FOG_IDENTIFIER")
        .map(|(v, b)| (*v, *b))
        .chain([("FOG_IDENTIFIER", image)]);
    for (var, bytes) in expected {
        fw.assert_carries(var, bytes);
    }
    fw
}

/// The identifier image the firmware embeds by default (`fog-firmware/identifier/default.fogi`,
/// made by `scripts/train-default-identifier.sh`).
///
/// # Panics
/// If it cannot be read.
pub fn default_image() -> Vec<u8> {
    let p = firmware_dir().join("identifier/default.fogi");
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// [`firmware`] with [`FirmwareBuild::DEFAULT`].
pub fn default_firmware(label: &str) -> Firmware {
    firmware(&FirmwareBuild::DEFAULT, label)
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
