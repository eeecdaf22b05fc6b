//! The cycle tool (`fw-cycles`, `fog_system_tests::cycles`) on a run of the budget image:
//! its instruction counts per timing window must equal the firmware's own `-icount` figures
//! of the same run, and every executed address must map to a function and an instruction.
//! Two controls show that the checks can fail: a table with one figure moved by 2
//! instructions, and a trace with one address outside every function.
//!
//! The run is the budget image as `scripts/fw-budget.sh` builds it (`target/budget`): about
//! 10^8 instructions, a few seconds of QEMU and of the (release-built) tool. Skipped, with
//! the reason, when QEMU, binutils-arm-none-eabi or a C compiler (for the QEMU plugin) is
//! missing and `scripts/setup.sh` cannot install it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use fog_system_tests::{firmware, fw_cycles, qemu_system_arm, FirmwareBuild};

fn on_path(program: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(program))
            .find(|p| p.is_file())
    })
}

/// The tools the cycle tool needs besides QEMU; `false` (with the reason) if one is missing
/// after `scripts/setup.sh`.
fn tools_present() -> bool {
    let needed = ["arm-none-eabi-objdump", "arm-none-eabi-nm", "cc"];
    if needed.iter().all(|t| on_path(t).is_some()) {
        return true;
    }
    let setup = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scripts/setup.sh");
    let _ = Command::new("bash").arg(&setup).status();
    let missing: Vec<&str> = needed
        .iter()
        .copied()
        .filter(|t| on_path(t).is_none())
        .collect();
    if missing.is_empty() {
        true
    } else {
        eprintln!(
            "SKIPPED: {missing:?} missing and {} could not install them",
            setup.display()
        );
        false
    }
}

fn run(args: &[&std::ffi::OsStr]) -> (Output, String) {
    let out = Command::new(fw_cycles())
        .args(args)
        .output()
        .expect("fw-cycles runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    (out, text)
}

/// The numbers of `trace: N instructions executed; U executed addresses outside every
/// function symbol; D not in the disassembly; ...`.
fn trace_line(text: &str) -> (u64, u64, u64) {
    let line = text
        .lines()
        .find(|l| l.starts_with("trace: "))
        .expect("a trace line");
    let nums: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().expect("a number"))
        .collect();
    (nums[0], nums[1], nums[2])
}

/// Cross-check rows: (row, windows, equal).
fn check_rows(text: &str) -> Vec<(String, u64, bool)> {
    let start = text
        .lines()
        .position(|l| l.starts_with("cross-check:"))
        .expect("a cross-check section");
    text.lines()
        .skip(start + 2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            let f: Vec<&str> = l.split('|').map(str::trim).collect();
            (
                f[1].to_string(),
                f[2].parse().expect("windows"),
                f[7] == "yes",
            )
        })
        .collect()
}

fn samples_in_table(text: &str) -> u64 {
    text.lines()
        .find_map(|l| {
            l.split_once(" samples (")
                .and_then(|(n, _)| n.trim().parse().ok())
        })
        .expect("the firmware's sample count")
}

#[test]
fn trace_counts_equal_icount_and_every_address_maps_to_a_function() {
    if qemu_system_arm().is_none() || !tools_present() {
        return;
    }
    let fw = firmware(
        &FirmwareBuild {
            target_subdir: "target/budget",
            cargo_args: &["--features", "budget"],
            ..FirmwareBuild::DEFAULT
        },
        "cycles-budget",
    );
    let elf = &fw.elf;
    let dir = tempfile::tempdir().expect("temp dir");
    let (out, text) = run(&["--keep".as_ref(), dir.path().as_os_str(), elf.as_os_str()]);
    eprintln!("{text}");
    assert!(
        out.status.success(),
        "fw-cycles failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );

    let (executed, unmapped, undisassembled) = trace_line(&text);
    assert!(executed > 1_000_000, "{executed} instructions traced");
    assert_eq!(unmapped, 0, "executed addresses outside every function");
    assert_eq!(undisassembled, 0, "executed addresses with no instruction");

    let rows = check_rows(&text);
    assert_eq!(rows.len(), 5, "{rows:?}");
    let samples = samples_in_table(&text);
    for (row, windows, equal) in &rows {
        assert!(equal, "{row}: trace and -icount differ");
        assert_eq!(*windows, samples, "{row}: one window per sample");
    }
    assert!(text.contains("cross-check PASSED"));

    // Control 1: the firmware's whole-pipeline mean moved by 2 instructions must fail.
    let table_path = dir.path().join("table.txt");
    let table = std::fs::read_to_string(&table_path).expect("table kept");
    let row = table
        .lines()
        .find(|l| l.contains("whole pipeline (decode+stage+record)"))
        .expect("pipeline row");
    let f: Vec<&str> = row.split('|').collect();
    let mean: f64 = f[3].trim().parse().expect("mean");
    let moved = row.replacen(f[3].trim(), &format!("{:.1}", mean + 2.0), 1);
    std::fs::write(&table_path, table.replacen(row, &moved, 1)).expect("write");
    let (out, text) = offline(dir.path(), elf);
    assert!(!out.status.success(), "a moved figure passed");
    assert!(text.contains("cross-check FAILED"), "{text}");
    std::fs::write(&table_path, &table).expect("restore");

    // Control 2: one executed address in the vector table (no function there) must fail.
    let trace_path = dir.path().join("trace.bin");
    let mut trace = std::fs::read(&trace_path).expect("trace kept");
    trace.extend_from_slice(&0x10u32.to_le_bytes());
    std::fs::write(&trace_path, &trace).expect("write");
    let (out, text) = offline(dir.path(), elf);
    assert!(!out.status.success(), "an unmapped address passed");
    let (_, unmapped, undisassembled) = trace_line(&text);
    assert_eq!((unmapped, undisassembled), (1, 1));
}

fn offline(dir: &Path, elf: &Path) -> (Output, String) {
    run(&["--offline".as_ref(), dir.as_os_str(), elf.as_os_str()])
}
