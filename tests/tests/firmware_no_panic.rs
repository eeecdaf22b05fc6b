//! The release firmware has no reachable panic, or every remaining path is listed with its
//! reason.
//!
//! The test builds the QEMU board's release ELF, disassembles it (`arm-none-eabi-objdump`,
//! from binutils-arm-none-eabi, installed by `scripts/setup.sh`) and finds every branch into
//! the panic machinery: `core::panicking::*` (panic formatting, bounds checks, arithmetic
//! and `unwrap` panics), `core::slice::index::*` (range checks), `unwrap_failed` and
//! `expect_failed`, and the core routines that reach them (e.g. the selection algorithm
//! behind `select_nth_unstable`). Each call site is mapped through the debug info
//! (`arm-none-eabi-addr2line -i`) to the innermost fog-core or fog-firmware function it was
//! inlined from: the function whose source holds the check.
//!
//! The result must equal [`REMAINING`], the reviewed list of functions that still hold a
//! check, each with why it cannot fire. A new site fails the test (fix it, or review it and
//! add it with its reason); a listed function with no site left fails too (remove it: the
//! list only shrinks). When the list is empty, the ELF must not contain any panic symbol at
//! all, which is the goal: see docs/reliability.md.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use fog_system_tests::{default_firmware, firmware, FirmwareBuild};

/// Functions (innermost fog-core / fog-firmware frame) that still hold a panicking check in
/// the release ELF, and why none can fire. Keep in step with docs/reliability.md.
const REMAINING: &[(&str, &str)] = &[];

/// Prefixes of the panic machinery (demangled names).
const PANIC_ROOTS: &[&str] = &[
    "core::panicking::",
    "core::slice::index::",
    "core::option::unwrap_failed",
    "core::option::expect_failed",
    "core::result::unwrap_failed",
    "core::str::slice_error_fail",
    "core::cell::panic_already",
    "rust_begin_unwind",
    "__rustc::rust_begin_unwind",
];

/// Symbols that must be absent once [`REMAINING`] is empty.
const PANIC_SYMBOLS: &[&str] = &[
    "core::panicking::panic_fmt",
    "core::panicking::panic_bounds_check",
    "core::slice::index::slice_index_fail",
    "core::slice::index::slice_end_index_len_fail",
    "core::slice::index::slice_start_index_len_fail",
    "core::slice::index::slice_index_order_fail",
    "core::option::unwrap_failed",
    "core::option::expect_failed",
    "core::result::unwrap_failed",
    "core::panicking::panic_const",
    "core::fmt::Formatter",
];

fn tool(name: &str) -> Option<PathBuf> {
    let find = || {
        std::env::var_os("PATH").and_then(|paths| {
            std::env::split_paths(&paths)
                .map(|d| d.join(name))
                .find(|p| p.is_file())
        })
    };
    if let Some(p) = find() {
        return Some(p);
    }
    let setup = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scripts/setup.sh");
    eprintln!("{name} not found: running {}", setup.display());
    let ran = Command::new("bash").arg(&setup).status();
    let found = find();
    if found.is_none() {
        eprintln!(
            "SKIPPED: {name} is missing and {} could not install it ({ran:?})",
            setup.display()
        );
    }
    found
}

fn run(cmd: &mut Command) -> String {
    let out = cmd.output().expect("tool runs");
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8 output")
}

/// Functions (start address, demangled name), sorted by address.
type Functions = Vec<(u32, String)>;
/// Branches (site address, target address).
type Branches = Vec<(u32, u32)>;

/// The ELF's functions and branches.
fn disassemble(objdump: &Path, elf: &Path) -> (Functions, Branches) {
    let text = run(Command::new(objdump)
        .args(["-d", "-C", "--no-show-raw-insn"])
        .arg(elf));
    let mut functions = Vec::new();
    let mut branches = Vec::new();
    for line in text.lines() {
        if let Some(head) = line.strip_suffix(">:") {
            if let Some((addr, name)) = head.split_once(" <") {
                if let Ok(a) = u32::from_str_radix(addr, 16) {
                    functions.push((a, name.to_string()));
                }
            }
            continue;
        }
        // "    2668:\tbl\t2bbc <core::slice::index::slice_index_fail>"
        let mut parts = line.trim_start().split('\t');
        let (Some(addr), Some(mnemonic), Some(operands)) =
            (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let Some(Ok(site)) = addr.strip_suffix(':').map(|a| u32::from_str_radix(a, 16)) else {
            continue;
        };
        let m = mnemonic.trim();
        if !(m.starts_with('b') || m.starts_with("cb"))
            || m.starts_with("bx")
            || m.starts_with("blx")
        {
            continue;
        }
        let target = operands.split(',').next_back().unwrap_or("").trim();
        let target = target.split(' ').next().unwrap_or("");
        if let Ok(t) = u32::from_str_radix(target, 16) {
            branches.push((site, t));
        }
    }
    functions.sort();
    (functions, branches)
}

fn containing(functions: &[(u32, String)], addr: u32) -> Option<&str> {
    let i = functions.partition_point(|(a, _)| *a <= addr);
    i.checked_sub(1).map(|i| functions[i].1.as_str())
}

fn is_first_party(name: &str) -> bool {
    let n = name.trim_start_matches('<');
    n.starts_with("fog_core::") || n.starts_with("fog_firmware::")
}

/// The innermost fog-core / fog-firmware function of each site's inline chain, with its
/// source line.
fn owners(addr2line: &Path, elf: &Path, sites: &[u32]) -> BTreeMap<u32, (String, String)> {
    let mut cmd = Command::new(addr2line);
    cmd.args(["-a", "-i", "-f", "-C", "-e"]).arg(elf);
    for s in sites {
        cmd.arg(format!("{s:#x}"));
    }
    let text = run(&mut cmd);
    let mut out = BTreeMap::new();
    let mut current: Option<u32> = None;
    let mut lines = text.lines();
    while let Some(l) = lines.next() {
        if let Some(hex) = l.strip_prefix("0x") {
            current = u32::from_str_radix(hex, 16).ok();
            continue;
        }
        let loc = lines.next().unwrap_or("?");
        if let Some(site) = current {
            if is_first_party(l) && !out.contains_key(&site) {
                out.insert(site, (l.to_string(), loc.to_string()));
            }
        }
    }
    out
}

#[test]
fn release_firmware_has_no_unlisted_panic_path() {
    let (Some(objdump), Some(addr2line), Some(nm)) = (
        tool("arm-none-eabi-objdump"),
        tool("arm-none-eabi-addr2line"),
        tool("arm-none-eabi-nm"),
    ) else {
        return;
    };
    // Both boards' release ELFs: QEMU mps2-an386 (default) and STM32F407 (its own target
    // directory, as scripts/test-all.sh builds it), and the STM32 build's QEMU variant
    // (feature qemu-netduinoplus2, as the HIL test builds it).
    let boards = [
        ("mps2-an386", default_firmware("no-panic-mps2")),
        (
            "stm32f407",
            firmware(&FirmwareBuild::STM32F407, "no-panic-stm32f407"),
        ),
        (
            "stm32f407 qemu-netduinoplus2",
            firmware(&FirmwareBuild::NETDUINO, "no-panic-netduino"),
        ),
    ];
    for (board, fw) in &boards {
        eprintln!("== {board}: {}", fw.elf.display());
        check_elf(&objdump, &addr2line, &nm, &fw.elf);
    }
}

fn check_elf(objdump: &Path, addr2line: &Path, nm: &Path, elf: &Path) {
    let (functions, branches) = disassemble(objdump, elf);
    assert!(
        functions.len() > 20,
        "disassembly found {} functions",
        functions.len()
    );

    // The panic machinery: the roots, and every core routine that branches into it.
    let is_root = |n: &str| PANIC_ROOTS.iter().any(|r| n.starts_with(r));
    let mut panicking: BTreeSet<String> = functions
        .iter()
        .filter(|(_, n)| is_root(n))
        .map(|(_, n)| n.clone())
        .collect();
    loop {
        let before = panicking.len();
        for &(site, target) in &branches {
            let (Some(from), Some(to)) =
                (containing(&functions, site), containing(&functions, target))
            else {
                continue;
            };
            if panicking.contains(to) && from.starts_with("core::") {
                panicking.insert(from.to_string());
            }
        }
        if panicking.len() == before {
            break;
        }
    }
    // Sites: branches from outside the machinery into it.
    let mut sites = Vec::new();
    for &(site, target) in &branches {
        let (Some(from), Some(to)) = (containing(&functions, site), containing(&functions, target))
        else {
            continue;
        };
        if panicking.contains(to) && !panicking.contains(from) {
            sites.push((site, from.to_string(), to.to_string()));
        }
    }
    let owner = owners(
        addr2line,
        elf,
        &sites.iter().map(|s| s.0).collect::<Vec<_>>(),
    );
    let mut found: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (site, from, to) in &sites {
        let (name, loc) = owner
            .get(site)
            .cloned()
            .unwrap_or_else(|| (from.clone(), "no fog frame in the debug info".to_string()));
        let key = REMAINING
            .iter()
            .find(|(f, _)| name.contains(f))
            .map_or(name.clone(), |(f, _)| f.to_string());
        found
            .entry(key)
            .or_default()
            .push(format!("{site:#x} in {from} -> {to} ({name} at {loc})"));
    }
    eprintln!("panic call sites in the release firmware, by function:");
    for (f, v) in &found {
        eprintln!("  {f}: {} site(s)", v.len());
        for s in v {
            eprintln!("    {s}");
        }
    }
    let listed: BTreeSet<&str> = REMAINING.iter().map(|(f, _)| *f).collect();
    let unlisted: Vec<&String> = found
        .keys()
        .filter(|k| !listed.contains(k.as_str()))
        .collect();
    let stale: Vec<&&str> = listed.iter().filter(|f| !found.contains_key(**f)).collect();
    assert!(
        unlisted.is_empty(),
        "new panic paths in the release firmware (fix them, or review and list them in \
         REMAINING with the reason): {unlisted:?}"
    );
    assert!(
        stale.is_empty(),
        "listed functions no longer hold a panic path: remove them from REMAINING: {stale:?}"
    );

    let symbols = run(Command::new(nm).arg("-C").arg(elf));
    let present: Vec<&str> = PANIC_SYMBOLS
        .iter()
        .copied()
        .filter(|p| symbols.lines().any(|l| l.contains(p)))
        .collect();
    eprintln!(
        "{} panic call sites in {} listed functions; panic symbols linked: {present:?}",
        sites.len(),
        found.len()
    );
    if REMAINING.is_empty() {
        assert!(present.is_empty(), "panic symbols linked: {present:?}");
    } else {
        assert!(!present.is_empty(), "no panic symbol left: empty REMAINING");
    }
}
