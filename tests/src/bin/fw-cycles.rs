//! `fw-cycles ELF`: runs the firmware's budget image under QEMU (`mps2-an386`, `-icount
//! shift=6,align=off,sleep=off`, the same command as `scripts/fw-budget.sh`) with the trace
//! plugin `scripts/qemu-trace/fogtrace.c`, prints the firmware's own table (instructions,
//! from `-icount`), then the cycle estimate from the trace of that same run, with the
//! instruction-count cross-check. See `fog_system_tests::cycles` for the cost model.
//!
//! Exit status 1 when the cross-check fails or an executed address maps to no function.
//!
//! Options: `--keep DIR` keeps the trace (`trace.bin`) and the firmware's output
//! (`table.txt`) in DIR; `--offline DIR` analyses a kept run instead of running QEMU;
//! `--top N` functions in the profile (default 15); `--explain NAME` prints, for each
//! function whose name contains NAME, every instruction with its TRM rule and its cycles in
//! each model when executed alone (no flash), a check by hand against the TRM.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use fog_system_tests::cycles::{
    self, analyse, cross_check, Disassembly, COST_TABLE_SOURCE, EXCEPTION_ENTRY, MODELS,
};

/// Clock and sample period of the goal: 10 % of a 1 kHz period at 168 MHz.
const CLOCK_HZ: u64 = 168_000_000;
const SAMPLE_RATE_HZ: u64 = 1_000;
const GOAL_FRACTION_PERCENT: u64 = 10;

/// The window kinds of the report, with the firmware's row names and what each is per.
const REPORT_ROWS: [(&str, &str, &str); 5] = [
    ("Decode", "frame decode (8 bytes)", "frame"),
    ("Estimate", "drift filter push + stillness test", "sample"),
    ("Denoise", "denoise db4 x3, B=512, resumable", "sample"),
    ("Stage", "stage (filter + denoiser + status)", "sample"),
    ("Pipeline", "whole pipeline (decode+stage+record)", "sample"),
];

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let mut elf: Option<PathBuf> = None;
    let mut keep: Option<PathBuf> = None;
    let mut offline: Option<PathBuf> = None;
    let mut explain: Option<String> = None;
    let mut top = 15usize;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--keep" => keep = args.next().map(PathBuf::from),
            "--offline" => offline = args.next().map(PathBuf::from),
            "--explain" => explain = args.next(),
            "--top" => top = args.next().and_then(|v| v.parse().ok()).unwrap_or(top),
            "-h" | "--help" => {
                eprintln!("{USAGE}");
                return ExitCode::SUCCESS;
            }
            _ => elf = Some(PathBuf::from(a)),
        }
    }
    let Some(elf) = elf else {
        eprintln!("{USAGE}");
        return ExitCode::from(2);
    };
    if let Some(name) = explain {
        return match explain_functions(&elf, &name) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("fw-cycles: {e}");
                ExitCode::from(2)
            }
        };
    }
    let result = match offline {
        Some(dir) => analyse_dir(&elf, &dir, top, false),
        None => run(&elf, keep.as_deref(), top),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("fw-cycles: {e}");
            ExitCode::from(2)
        }
    }
}

const USAGE: &str =
    "usage: fw-cycles [--keep DIR | --offline DIR] [--top N] [--explain NAME] BUDGET_ELF";

/// Prints each instruction of the functions whose name contains `name` with its TRM rule and
/// its cycles alone (taken for branches), in each model, without flash wait states.
fn explain_functions(elf: &Path, name: &str) -> Result<(), String> {
    let disasm = Disassembly::of(elf)?;
    let funcs = cycles::functions(elf)?;
    let mut found = false;
    for f in funcs.iter().filter(|f| f.name.contains(name)) {
        found = true;
        println!("{} ({:#x}, {} bytes):", f.name, f.start, f.size);
        println!(
            "  {:>8}  {:<36} {:<40} {:>4} {:>4} {:>4}",
            "address", "instruction", "TRM rule", "low", "est", "high"
        );
        let mut addrs: Vec<u32> = disasm
            .insns
            .keys()
            .copied()
            .filter(|&a| a >= f.start && a < f.start + f.size)
            .collect();
        addrs.sort_unstable();
        let mut sums = [0u32; 3];
        let mut prev: Option<&cycles::Insn> = None;
        for a in addrs {
            let i = &disasm.insns[&a];
            // Straight-line reading: branches and PC writes counted as taken.
            let taken = true;
            let c = MODELS.map(|m| m.cost(i, taken, prev));
            for (s, x) in sums.iter_mut().zip(c) {
                *s += x;
            }
            prev = Some(i);
            let stalled = c[0] > MODELS[0].cost(i, taken, None);
            let rule = if stalled {
                format!("{} +1 address dep.", cycles::rule(i))
            } else {
                cycles::rule(i)
            };
            println!(
                "  {a:>8x}  {:<36} {:<40} {:>4} {:>4} {:>4}",
                i.text, rule, c[0], c[1], c[2]
            );
        }
        println!(
            "  straight through (branches taken, no flash wait states): {} / {} / {} cycles (low / estimate / high)",
            sums[0], sums[1], sums[2]
        );
    }
    if found {
        Ok(())
    } else {
        Err(format!("no function symbol contains '{name}'"))
    }
}

/// Builds the plugin into `dir` with the system C compiler.
fn build_plugin(dir: &Path) -> Result<PathBuf, String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/qemu-trace/fogtrace.c");
    let so = dir.join("libfogtrace.so");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let st = Command::new(&cc)
        .args(["-O2", "-shared", "-fPIC", "-o"])
        .arg(&so)
        .arg(&src)
        .status()
        .map_err(|e| format!("{cc}: {e}"))?;
    if !st.success() {
        return Err(format!("{cc} could not build {}", src.display()));
    }
    Ok(so)
}

fn run(elf: &Path, keep: Option<&Path>, top: usize) -> Result<bool, String> {
    match keep {
        Some(d) => {
            std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
            run_in(elf, d, top)
        }
        // A folder of this run's own (`fog-cycles-XXXXXX`), removed at the end.
        None => {
            let dir = tempfile::Builder::new()
                .prefix("fog-cycles-")
                .tempdir()
                .map_err(|e| format!("a temporary folder: {e}"))?;
            run_in(elf, dir.path(), top)
        }
    }
}

fn run_in(elf: &Path, dir: &Path, top: usize) -> Result<bool, String> {
    let plugin = build_plugin(dir)?;
    let trace_path = dir.join("trace.bin");
    let out = Command::new("qemu-system-arm")
        .args(["-machine", "mps2-an386", "-nographic", "-monitor", "none"])
        .args(["-serial", "stdio"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=6,align=off,sleep=off"])
        .arg("-plugin")
        .arg(format!("{},out={}", plugin.display(), trace_path.display()))
        .arg("-kernel")
        .arg(elf)
        .stdin(std::process::Stdio::null())
        .output()
        .map_err(|e| format!("qemu-system-arm: {e}"))?;
    std::fs::write(dir.join("table.txt"), &out.stdout).map_err(|e| e.to_string())?;
    if !out.status.success() {
        return Err(format!(
            "QEMU exited with {}: {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    analyse_dir(elf, dir, top, true)
}

/// Analyses `DIR/trace.bin` against `DIR/table.txt` (a run of `elf`).
fn analyse_dir(elf: &Path, dir: &Path, top: usize, print_table: bool) -> Result<bool, String> {
    let trace_path = dir.join("trace.bin");
    let table = std::fs::read_to_string(dir.join("table.txt"))
        .map_err(|e| format!("{}: {e}", dir.join("table.txt").display()))?;
    if print_table {
        println!("== the firmware's table (QEMU -icount: INSTRUCTIONS, not cycles) ==");
        print!("{table}");
    }
    let disasm = Disassembly::of(elf)?;
    let funcs = cycles::functions(elf)?;
    let f = File::open(&trace_path).map_err(|e| format!("{}: {e}", trace_path.display()))?;
    let a = analyse(&mut BufReader::new(f), &disasm, &funcs)?;
    report(&a, &table, top)
}

fn report(a: &cycles::Analysis, table: &str, top: usize) -> Result<bool, String> {
    let mut ok = true;
    println!();
    println!("== cycle estimate from the instruction trace of the same run (fw-cycles) ==");
    let distinct = a.raw.values().map(Vec::len).sum::<usize>();
    println!(
        "trace: {} instructions executed; {} executed addresses outside every function symbol; {} not in the disassembly; {} exceptions taken; {} timing windows",
        a.executed,
        a.unmapped.len(),
        a.undisassembled.len(),
        a.exceptions,
        distinct
    );
    if !a.unmapped.is_empty() || !a.undisassembled.is_empty() {
        ok = false;
        let show: Vec<String> = a
            .unmapped
            .iter()
            .chain(&a.undisassembled)
            .take(10)
            .map(|x| format!("{x:#x}"))
            .collect();
        println!("FAILED: executed addresses that map to no function or instruction: {show:?}");
    }
    if !a.unknown.is_empty() {
        println!(
            "mnemonics not in the cost table (costed 1 cycle): {:?}",
            a.unknown
        );
    }
    println!("timings: {COST_TABLE_SOURCE}");
    for m in MODELS {
        println!(
            "model {:<8}: pipeline refill P = {}, SDIV/UDIV {} cycles, flash {:?} ({} wait states at 168 MHz), loads pipelined: {}",
            m.name, m.refill, m.div, m.flash, m.wait_states, m.pipelined_loads
        );
    }
    println!(
        "not modelled: loads from flash through a register (.rodata tables: costed as SRAM, 0 wait states; a bound follows), bus contention, FPU result latencies; exception entry {EXCEPTION_ENTRY} cycles"
    );
    println!("ASSUMPTION: the mps2-an386 budget image's code and layout stand for the STM32F407 build's (same fog-core code and compiler settings, other board code)");

    let (oi, oc) = a
        .overhead()
        .ok_or("no Empty (counter overhead) windows in the trace")?;
    println!(
        "counter overhead removed from every window: {oi} instructions, cycles {} / {} / {} (low / estimate / high)",
        oc[0], oc[1], oc[2]
    );

    println!();
    println!("cross-check: instructions per window, counted in the trace vs the firmware's -icount table above (same build, same run):");
    let checks = cross_check(a, table)?;
    println!(
        "| {:<38} | {:>7} | {:>10} | {:>10} | {:>10} | {:>10} | {:<6} |",
        "row", "windows", "trace mean", "fw mean", "trace max", "fw max", "equal?"
    );
    for c in &checks {
        println!(
            "| {:<38} | {:>7} | {:>10.1} | {:>10.1} | {:>10.1} | {:>10.1} | {:<6} |",
            c.row,
            c.windows,
            c.trace_mean,
            c.firmware_mean,
            c.trace_max,
            c.firmware_max,
            if c.ok() { "yes" } else { "NO" }
        );
        ok &= c.ok();
    }
    let tol = checks.first().map_or(0.0, |c| c.tolerance);
    println!(
        "equal = within {tol:.2} instructions: the firmware's figure is two SysTick readings (1.6 ticks per instruction) minus an overhead in ticks, each quantised to 1 tick (2 ticks) plus its printed decimal; cross-check {}",
        if checks.iter().all(cycles::Check::ok) { "PASSED" } else { "FAILED" }
    );

    println!();
    println!(
        "estimated Cortex-M4F CYCLES per window at 168 MHz (overhead removed), beside the INSTRUCTIONS counted in the trace:"
    );
    println!(
        "| {:<38} | {:<6} | {:>17} | {:>17} | {:>17} | {:>17} |",
        "stage", "per", "instr mean/max", "low mean/max", "EST. mean/max", "high mean/max"
    );
    let mut pipeline = None;
    for (kind, row, per) in REPORT_ROWS {
        let Some(s) = a.stats(kind) else { continue };
        let n = s.n.max(1) as f64;
        let cell = |sum: u64, max: u64| format!("{:.1} / {}", sum as f64 / n, max);
        println!(
            "| {:<38} | {:<6} | {:>17} | {:>17} | {:>17} | {:>17} |",
            row,
            per,
            cell(s.instr_sum, s.instr_max),
            cell(s.cycles_sum[0], s.cycles_max[0]),
            cell(s.cycles_sum[1], s.cycles_max[1]),
            cell(s.cycles_sum[2], s.cycles_max[2]),
        );
        if kind == "Pipeline" {
            pipeline = Some(s);
        }
    }
    let p = pipeline.ok_or("no Pipeline windows")?;
    let period = CLOCK_HZ / SAMPLE_RATE_HZ;
    let goal = period * GOAL_FRACTION_PERCENT / 100;
    let mean_ratio = |m: usize| p.cycles_sum[m] as f64 / p.instr_sum.max(1) as f64;
    println!(
        "cycles per instruction (whole pipeline, mean): low {:.2}, estimate {:.2}, high {:.2}",
        mean_ratio(0),
        mean_ratio(1),
        mean_ratio(2)
    );
    let ws = MODELS[2].wait_states;
    println!(
        "loads through a register other than SP/PC (may read .rodata in flash; costed as SRAM): {:.1} per sample, {} at most in one window; bound if every one missed the ART: + {} wait states each, + {} cycles on the worst window",
        p.register_loads_sum as f64 / p.n.max(1) as f64,
        p.register_loads_max,
        ws,
        p.register_loads_max * u64::from(ws)
    );
    for (m, model) in MODELS.iter().enumerate() {
        let worst = p.cycles_max[m];
        println!(
            "goal worst sample <= {goal} cycles ({GOAL_FRACTION_PERCENT} % of a {SAMPLE_RATE_HZ} Hz period at {} MHz), model {}: {} ({worst} cycles = {:.2} % of the period, {:.1} us; mean {:.1} cycles = {:.2} %)",
            CLOCK_HZ / 1_000_000,
            model.name,
            if worst <= goal { "met" } else { "NOT met" },
            100.0 * worst as f64 / period as f64,
            worst as f64 * 1e6 / CLOCK_HZ as f64,
            p.cycles_sum[m] as f64 / p.n.max(1) as f64,
            100.0 * p.cycles_sum[m] as f64 / p.n.max(1) as f64 / period as f64,
        );
    }
    let bound = p.cycles_max[2] + p.register_loads_max * u64::from(ws);
    println!(
        "goal worst sample <= {goal} cycles, bound: model high's worst + every register load a flash miss = {bound} cycles ({:.2} % of the period): {}",
        100.0 * bound as f64 / period as f64,
        if bound <= goal { "met" } else { "NOT met" }
    );

    println!();
    println!(
        "top {top} functions by estimated cycles in the whole-pipeline windows ({} samples; self cost: a function's own instructions, callees apart; probe functions are the counter):",
        a.pipeline_windows
    );
    println!(
        "| {:<60} | {:>10} | {:>11} | {:>11} | {:>12} | {:>12} |",
        "function", "instr/smp", "cycles/smp", "max/sample", "worst: instr", "worst: cyc"
    );
    let n = a.pipeline_windows.max(1) as f64;
    let mut order: Vec<usize> = (0..a.functions.len())
        .filter(|&i| a.functions[i].instr_sum > 0 || a.functions[i].worst_instr > 0)
        .collect();
    order.sort_by_key(|&i| std::cmp::Reverse(a.functions[i].cycles_sum[1]));
    for &i in order.iter().take(top) {
        let f = &a.functions[i];
        let mut name = a.function_names[i]
            .replace("fog_firmware::budget::probe::", "probe::")
            .replace(" as probe::Window>", ">");
        if name.len() > 60 {
            name = format!("{}...", &name[..57]);
        }
        println!(
            "| {:<60} | {:>10.1} | {:>11.1} | {:>11} | {:>12} | {:>12} |",
            name,
            f.instr_sum as f64 / n,
            f.cycles_sum[1] as f64 / n,
            f.cycles_max,
            f.worst_instr,
            f.worst_cycles
        );
    }
    let mut by_class: Vec<(&String, &(u64, u64))> = a.classes.iter().collect();
    by_class.sort_by_key(|(_, v)| std::cmp::Reverse(v.1));
    let total: u64 = a.classes.values().map(|v| v.1).sum();
    println!("per sample by mnemonic (estimate model, top 12 by cycles):");
    for (k, v) in by_class.iter().take(12) {
        println!(
            "  {k:<6} {:>7.1} instr {:>7.1} cycles ({:>4.1} %)",
            v.0 as f64 / n,
            v.1 as f64 / n,
            100.0 * v.1 as f64 / total.max(1) as f64
        );
    }
    Ok(ok)
}
