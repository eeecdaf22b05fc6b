//! Cycle estimate of the firmware from an instruction trace (`fw-cycles`, `bash
//! scripts/fw-budget.sh`).
//!
//! QEMU counts instructions, not cycles. This module takes the trace of one run of the budget
//! image (every executed instruction's address, in order, written by the TCG plugin
//! `scripts/qemu-trace/fogtrace.c`), the ELF's symbols (`arm-none-eabi-nm`) and its
//! disassembly (`arm-none-eabi-objdump`), and gives each executed instruction a cost in
//! Cortex-M4F cycles from the instruction timings of the Cortex-M4 Technical Reference
//! Manual ([`COST_TABLE_SOURCE`], table in [`classify`] and [`Model::cost`]) plus a model of
//! the STM32F407's flash wait states and ART accelerator at 168 MHz (an ASSUMPTION, see
//! [`Model`]). It sums the cycles per timing window of the budget image (the windows are
//! found by the entry addresses of `fog_firmware::budget::probe`'s functions) and per
//! function.
//!
//! Three models bracket what the trace cannot tell (pipeline refill length, divide operands,
//! the ART's hits): [`Model::LOW`], [`Model::ESTIMATE`] and [`Model::HIGH`].
//!
//! Not modelled (each named in the report): data loads through a register from flash
//! (constant tables in `.rodata`; the trace has no data addresses, so they are costed as
//! SRAM loads, 0 wait states), bus contention, and interrupt latency beyond a fixed entry
//! cost.

use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::Path;
use std::process::Command;

/// Where the per-instruction timings come from.
pub const COST_TABLE_SOURCE: &str = "ARM Cortex-M4 Technical Reference Manual r0p1 (DDI 0439), \
     section 3.3.1 'Cortex-M4 instruction set summary' (Table 3-1, integer) and section 7.2.3 \
     (Table 7-1, FPU); STM32F407 flash: RM0090 section 3.5.1 (Table 10: 5 wait states at \
     168 MHz, 2.7-3.6 V) and 3.5.2 (ART: 64 lines x 128 bits instruction cache, 8 lines data \
     cache, prefetch)";

/// What an instruction does, for its cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// Data processing, moves, shifts, extends, bit fields, saturation: 1.
    Alu,
    /// MUL, MLA, MLS, long multiplies and MACs: 1 (the M4's single-cycle MAC).
    Mul,
    /// SDIV, UDIV: 2 to 12, depending on the operands (early termination).
    Div,
    /// LDR, LDRB, LDRH, LDRSB, LDRSH, LDREX: 2, or 1 when pipelined after a load.
    LoadSingle,
    /// STR, STRB, STRH, STREX: 2, or 1 when pipelined after a load.
    StoreSingle,
    /// LDRD, STRD: 1 + N with N = 2.
    Double,
    /// LDM, STM, PUSH, POP: 1 + N (N registers); + P when PC is loaded.
    Multiple,
    /// B, BL, BX, BLX: 1 + P taken, 1 not taken.
    Branch,
    /// CBZ, CBNZ: 1 + P taken, 1 not taken.
    CompareBranch,
    /// TBB, TBH: 2 + P.
    Table,
    /// IT: 1 (the TRM lets it fold onto a preceding 16-bit instruction, 0; not assumed).
    It,
    /// DMB, DSB: 1; ISB: 1 + P (pipeline flush).
    Barrier,
    /// MSR, MRS, CPS, BKPT (semihosting), WFI...: 2 (rare; outside the timed windows).
    System,
    /// VADD, VSUB, VMUL, VNMUL, VABS, VNEG, VCMP, VCVT, VMOV, VMRS, VMSR: 1.
    FpSimple,
    /// VMOV between two core registers and two singles or a double: 2.
    FpMove2,
    /// VMLA, VMLS, VNMLA, VNMLS, VFMA, VFMS, VFNMA, VFNMS: 3.
    FpMac,
    /// VDIV.F32, VSQRT.F32: 14.
    FpDivSqrt,
    /// VLDR, VSTR: 2.
    FpLoadStore,
    /// VLDM, VSTM, VPUSH, VPOP: 1 + N (N words).
    FpMultiple,
    /// A mnemonic this table does not know: costed 1 and listed in the report.
    Unknown,
}

/// One instruction of the disassembly.
#[derive(Debug, Clone)]
pub struct Insn {
    /// Size in bytes (2 or 4).
    pub size: u32,
    /// The mnemonic as objdump prints it.
    pub mnemonic: String,
    /// Mnemonic and operands.
    pub text: String,
    /// Its cost class.
    pub class: Class,
    /// Registers moved (LDM/STM/PUSH/POP and their FP forms, in 32-bit words).
    pub regs: u32,
    /// Writes the PC (POP {.., pc}, LDR pc, MOV pc, ...): a branch.
    pub writes_pc: bool,
    /// Base register written back (`!` or post-indexed): such a load is not pipelined.
    pub writeback: bool,
    /// A PC-relative load's literal address (read from flash through the ART's data cache).
    pub literal: Option<u32>,
    /// A load whose address is in a register other than SP and PC: it may read flash
    /// (`.rodata`), which the trace cannot tell; costed as SRAM and counted for a bound.
    pub register_load: bool,
    /// Core registers written (bit n = rn; 13 SP, 14 LR, 15 PC), for the address dependency.
    pub writes: u16,
    /// The base register of a load or store (PUSH/POP/VPUSH/VPOP: SP).
    pub base: Option<u8>,
    /// A single store with an immediate offset and no write-back (`STR Rx, [Ry, #imm]`).
    pub store_imm: bool,
}

/// A core register's number (`r0`..`r12`, `sl`, `fp`, `ip`, `sp`, `lr`, `pc`).
pub fn reg_num(r: &str) -> Option<u8> {
    match r.trim().trim_end_matches('!') {
        "sl" => Some(10),
        "fp" => Some(11),
        "ip" => Some(12),
        "sp" => Some(13),
        "lr" => Some(14),
        "pc" => Some(15),
        x => x.strip_prefix('r')?.parse::<u8>().ok().filter(|&n| n < 16),
    }
}

const CONDITIONS: [&str; 17] = [
    "eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
    "al",
];

/// Base mnemonics and their class; `true` when the base takes an `s` (flag-setting) suffix.
const BASES: &[(&str, Class, bool)] = &[
    // Integer data processing.
    ("mov", Class::Alu, true),
    ("movw", Class::Alu, false),
    ("movt", Class::Alu, false),
    ("mvn", Class::Alu, true),
    ("add", Class::Alu, true),
    ("addw", Class::Alu, false),
    ("adc", Class::Alu, true),
    ("sub", Class::Alu, true),
    ("subw", Class::Alu, false),
    ("sbc", Class::Alu, true),
    ("rsb", Class::Alu, true),
    ("neg", Class::Alu, true),
    ("and", Class::Alu, true),
    ("orr", Class::Alu, true),
    ("orn", Class::Alu, true),
    ("eor", Class::Alu, true),
    ("bic", Class::Alu, true),
    ("cmp", Class::Alu, false),
    ("cmn", Class::Alu, false),
    ("tst", Class::Alu, false),
    ("teq", Class::Alu, false),
    ("lsl", Class::Alu, true),
    ("lsr", Class::Alu, true),
    ("asr", Class::Alu, true),
    ("ror", Class::Alu, true),
    ("rrx", Class::Alu, true),
    ("clz", Class::Alu, false),
    ("rbit", Class::Alu, false),
    ("rev", Class::Alu, false),
    ("rev16", Class::Alu, false),
    ("revsh", Class::Alu, false),
    ("sxtb", Class::Alu, false),
    ("sxth", Class::Alu, false),
    ("uxtb", Class::Alu, false),
    ("uxth", Class::Alu, false),
    ("uxtb16", Class::Alu, false),
    ("sxtb16", Class::Alu, false),
    ("uxtab", Class::Alu, false),
    ("uxtah", Class::Alu, false),
    ("sxtab", Class::Alu, false),
    ("sxtah", Class::Alu, false),
    ("ubfx", Class::Alu, false),
    ("sbfx", Class::Alu, false),
    ("bfi", Class::Alu, false),
    ("bfc", Class::Alu, false),
    ("adr", Class::Alu, false),
    ("ssat", Class::Alu, false),
    ("usat", Class::Alu, false),
    ("qadd", Class::Alu, false),
    ("qsub", Class::Alu, false),
    ("uqsub16", Class::Alu, false),
    ("uqadd16", Class::Alu, false),
    ("pkhbt", Class::Alu, false),
    ("pkhtb", Class::Alu, false),
    ("sel", Class::Alu, false),
    ("nop", Class::Alu, false),
    // Multiply, divide.
    ("mul", Class::Mul, true),
    ("mla", Class::Mul, false),
    ("mls", Class::Mul, false),
    ("umull", Class::Mul, false),
    ("smull", Class::Mul, false),
    ("umlal", Class::Mul, false),
    ("smlal", Class::Mul, false),
    ("umaal", Class::Mul, false),
    ("smmul", Class::Mul, false),
    ("smmla", Class::Mul, false),
    ("sdiv", Class::Div, false),
    ("udiv", Class::Div, false),
    // Loads and stores.
    ("ldr", Class::LoadSingle, false),
    ("ldrb", Class::LoadSingle, false),
    ("ldrh", Class::LoadSingle, false),
    ("ldrsb", Class::LoadSingle, false),
    ("ldrsh", Class::LoadSingle, false),
    ("ldrex", Class::LoadSingle, false),
    ("ldrexb", Class::LoadSingle, false),
    ("ldrexh", Class::LoadSingle, false),
    ("str", Class::StoreSingle, false),
    ("strb", Class::StoreSingle, false),
    ("strh", Class::StoreSingle, false),
    ("strex", Class::StoreSingle, false),
    ("strexb", Class::StoreSingle, false),
    ("strexh", Class::StoreSingle, false),
    ("ldrd", Class::Double, false),
    ("strd", Class::Double, false),
    ("ldm", Class::Multiple, false),
    ("ldmia", Class::Multiple, false),
    ("ldmdb", Class::Multiple, false),
    ("stm", Class::Multiple, false),
    ("stmia", Class::Multiple, false),
    ("stmdb", Class::Multiple, false),
    ("push", Class::Multiple, false),
    ("pop", Class::Multiple, false),
    // Branches.
    ("b", Class::Branch, false),
    ("bl", Class::Branch, false),
    ("bx", Class::Branch, false),
    ("blx", Class::Branch, false),
    ("cbz", Class::CompareBranch, false),
    ("cbnz", Class::CompareBranch, false),
    ("tbb", Class::Table, false),
    ("tbh", Class::Table, false),
    // Barriers, system.
    ("dmb", Class::Barrier, false),
    ("dsb", Class::Barrier, false),
    ("isb", Class::Barrier, false),
    ("msr", Class::System, false),
    ("mrs", Class::System, false),
    ("cpsid", Class::System, false),
    ("cpsie", Class::System, false),
    ("bkpt", Class::System, false),
    ("udf", Class::System, false),
    ("svc", Class::System, false),
    ("wfi", Class::System, false),
    ("wfe", Class::System, false),
    ("sev", Class::System, false),
    // FPU.
    ("vadd", Class::FpSimple, false),
    ("vsub", Class::FpSimple, false),
    ("vmul", Class::FpSimple, false),
    ("vnmul", Class::FpSimple, false),
    ("vabs", Class::FpSimple, false),
    ("vneg", Class::FpSimple, false),
    ("vcmp", Class::FpSimple, false),
    ("vcmpe", Class::FpSimple, false),
    ("vcvt", Class::FpSimple, false),
    ("vcvtr", Class::FpSimple, false),
    ("vmov", Class::FpSimple, false),
    ("vmrs", Class::FpSimple, false),
    ("vmsr", Class::FpSimple, false),
    ("vmla", Class::FpMac, false),
    ("vmls", Class::FpMac, false),
    ("vnmla", Class::FpMac, false),
    ("vnmls", Class::FpMac, false),
    ("vfma", Class::FpMac, false),
    ("vfms", Class::FpMac, false),
    ("vfnma", Class::FpMac, false),
    ("vfnms", Class::FpMac, false),
    ("vdiv", Class::FpDivSqrt, false),
    ("vsqrt", Class::FpDivSqrt, false),
    ("vldr", Class::FpLoadStore, false),
    ("vstr", Class::FpLoadStore, false),
    ("vldmia", Class::FpMultiple, false),
    ("vldmdb", Class::FpMultiple, false),
    ("vstmia", Class::FpMultiple, false),
    ("vstmdb", Class::FpMultiple, false),
    ("vpush", Class::FpMultiple, false),
    ("vpop", Class::FpMultiple, false),
];

/// Base mnemonic, class and whether it is conditional, for an objdump mnemonic
/// (`addcc.w`, `vmovne.f32`, `popcc`, `bls.n`, `itte`).
pub fn split_mnemonic(m: &str) -> (String, Class, bool) {
    let lower = m.to_ascii_lowercase();
    // The part before the first '.': drops `.w`/`.n` and FP data types (`.f32`, `.u32`).
    let core = lower.split('.').next().unwrap_or("");
    if core.len() >= 2 && core.starts_with("it") && core[2..].chars().all(|c| c == 't' || c == 'e')
    {
        return ("it".into(), Class::It, false);
    }
    let mut best: Option<(usize, &str, Class, bool)> = None;
    for &(base, class, takes_s) in BASES {
        let Some(rest) = core.strip_prefix(base) else {
            continue;
        };
        let rest_no_s = if takes_s {
            rest.strip_prefix('s').unwrap_or(rest)
        } else {
            rest
        };
        let cond = if rest_no_s.is_empty() {
            Some(false)
        } else if CONDITIONS.contains(&rest_no_s) {
            Some(true)
        } else {
            None
        };
        if let Some(c) = cond {
            if best.is_none_or(|b| base.len() > b.0) {
                best = Some((base.len(), base, class, c));
            }
        }
    }
    match best {
        Some((_, base, class, cond)) => (base.to_string(), class, cond),
        None => (core.to_string(), Class::Unknown, false),
    }
}

/// Counts the registers of a `{r4, r5, lr}` / `{d8-d15}` / `{s16-s31}` list, in 32-bit words.
fn count_regs(ops: &str) -> u32 {
    let (Some(a), Some(b)) = (ops.find('{'), ops.find('}')) else {
        return 0;
    };
    let mut n = 0;
    for item in ops[a + 1..b].split(',') {
        let item = item.trim();
        let words = if item.starts_with('d') { 2 } else { 1 };
        if let Some((lo, hi)) = item.split_once('-') {
            let num = |s: &str| {
                s.trim()
                    .trim_start_matches(['r', 's', 'd'])
                    .parse::<u32>()
                    .ok()
            };
            if let (Some(l), Some(h)) = (num(lo), num(hi)) {
                n += (h.saturating_sub(l) + 1) * words;
            }
        } else if !item.is_empty() {
            n += words;
        }
    }
    n
}

/// Classifies one disassembled instruction.
pub fn classify(size: u32, mnemonic: &str, operands: &str, comment: &str) -> Insn {
    let (base, mut class, _) = split_mnemonic(mnemonic);
    let ops = operands.trim();
    // `vmov r0, r1, s0, s1` / `vmov r0, r1, d0` and the reverse: two core registers.
    if base == "vmov" && ops.split(',').count() >= 3 {
        class = Class::FpMove2;
    }
    let regs = match class {
        Class::Multiple | Class::FpMultiple => count_regs(ops),
        Class::Double => 2,
        _ => 0,
    };
    let first = ops.split(',').next().unwrap_or("").trim();
    let writes_pc = match class {
        Class::Multiple => {
            (base == "pop" || base.starts_with("ldm"))
                && ops.contains("pc}")
                && !ops.starts_with("pc")
        }
        Class::LoadSingle | Class::Alu => first == "pc",
        _ => false,
    };
    let writeback = ops.contains('!') || ops.contains("], ");
    let is_load = match class {
        Class::LoadSingle | Class::Double | Class::Multiple => base.starts_with("ld"),
        Class::FpLoadStore | Class::FpMultiple => base.starts_with("vld"),
        _ => false,
    };
    // The base register: inside `[...]`, or the first operand of LDM/VLDM (`r0!, {...}`).
    let base_reg = match ops.find('[') {
        Some(i) => ops[i + 1..].split([',', ']']).next().unwrap_or("").trim(),
        None => first.trim_end_matches('!'),
    };
    let register_load = is_load && base_reg != "sp" && base_reg != "pc";
    let memory = matches!(
        class,
        Class::LoadSingle
            | Class::StoreSingle
            | Class::Double
            | Class::Multiple
            | Class::FpLoadStore
            | Class::FpMultiple
    );
    let base_num = if !memory {
        None
    } else if matches!(base.as_str(), "push" | "pop" | "vpush" | "vpop") {
        Some(13)
    } else {
        reg_num(base_reg)
    };
    let operands: Vec<&str> = ops.split(',').map(str::trim).collect();
    let mut writes = 0u16;
    let mut write = |r: &str| {
        if let Some(n) = reg_num(r) {
            writes |= 1 << n;
        }
    };
    match class {
        Class::Alu if !matches!(base.as_str(), "cmp" | "cmn" | "tst" | "teq" | "nop") => {
            write(first)
        }
        Class::Mul
            if matches!(
                base.as_str(),
                "umull" | "smull" | "umlal" | "smlal" | "umaal"
            ) =>
        {
            write(first);
            write(operands.get(1).copied().unwrap_or(""));
        }
        Class::Mul | Class::Div | Class::LoadSingle => write(first),
        Class::Double if base.starts_with("ld") => {
            write(first);
            write(operands.get(1).copied().unwrap_or(""));
        }
        _ => {}
    }
    // Base write-back writes the base too (`ldr r0, [r1], #4`, `ldmia r0!, {..}`).
    if writeback {
        if let Some(b) = base_num {
            writes |= 1 << b;
        }
    }
    let store_imm = class == Class::StoreSingle
        && !writeback
        && ops.find('[').is_some_and(|i| {
            ops[i..]
                .split(',')
                .nth(1)
                .is_none_or(|o| o.trim().starts_with('#'))
        });
    // `ldr r0, [pc, #72]	@ (450 <Reset+0x50>)`: the literal's address is in the comment.
    let literal = if ops.contains("[pc") {
        comment
            .split_once('(')
            .and_then(|(_, r)| r.split_whitespace().next())
            .and_then(|h| u32::from_str_radix(h.trim_end_matches(')'), 16).ok())
    } else {
        None
    };
    Insn {
        size,
        mnemonic: mnemonic.to_string(),
        text: format!("{mnemonic} {ops}").trim().to_string(),
        class,
        regs,
        writes_pc,
        writeback,
        literal,
        register_load,
        writes,
        base: base_num,
        store_imm,
    }
}

/// The disassembly of an ELF's code: instruction by address.
pub struct Disassembly {
    pub insns: HashMap<u32, Insn>,
}

/// Runs a tool and returns its standard output.
fn run_tool(program: &str, args: &[&str]) -> Result<String, String> {
    let out = Command::new(program)
        .args(args)
        .output()
        .map_err(|e| format!("{program}: {e} (binutils-arm-none-eabi: scripts/setup.sh)"))?;
    if !out.status.success() {
        return Err(format!(
            "{program} {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

impl Disassembly {
    /// `arm-none-eabi-objdump -d ELF`, parsed.
    pub fn of(elf: &Path) -> Result<Self, String> {
        let text = run_tool("arm-none-eabi-objdump", &["-d", &elf.display().to_string()])?;
        Ok(Self::parse(&text))
    }

    /// Parses objdump's `  addr:\tRAW\tMNEMONIC\tOPERANDS[\t@ COMMENT]` lines; data
    /// (`.word`, `.short`) is left out.
    pub fn parse(text: &str) -> Self {
        let mut insns = HashMap::new();
        for line in text.lines() {
            let mut f = line.split('\t');
            let (Some(addr), Some(raw), Some(mnem)) = (f.next(), f.next(), f.next()) else {
                continue;
            };
            let Some(addr) = addr.trim().strip_suffix(':') else {
                continue;
            };
            let Ok(addr) = u32::from_str_radix(addr, 16) else {
                continue;
            };
            let mnem = mnem.trim();
            if mnem.is_empty() || mnem.starts_with('.') {
                continue;
            }
            let hex_digits = raw.chars().filter(char::is_ascii_hexdigit).count() as u32;
            let ops = f.next().unwrap_or("");
            let comment = f.collect::<Vec<_>>().join("\t");
            insns.insert(addr, classify(hex_digits / 2, mnem, ops, &comment));
        }
        Self { insns }
    }
}

/// A function symbol: `[start, start + size)`.
#[derive(Debug, Clone)]
pub struct Function {
    pub start: u32,
    pub size: u32,
    pub name: String,
}

/// Function symbols of an ELF with their sizes (`arm-none-eabi-nm -C -S -n`), sorted.
pub fn functions(elf: &Path) -> Result<Vec<Function>, String> {
    let text = run_tool(
        "arm-none-eabi-nm",
        &[
            "-C",
            "-S",
            "-n",
            "--defined-only",
            &elf.display().to_string(),
        ],
    )?;
    Ok(parse_nm(&text))
}

/// Parses `ADDR SIZE TYPE NAME` lines of text symbols (types t, T, W, w); symbols without a
/// size are left out, and of two at one address the first is kept.
pub fn parse_nm(text: &str) -> Vec<Function> {
    let mut out: Vec<Function> = Vec::new();
    for line in text.lines() {
        let mut f = line.splitn(4, ' ');
        let (Some(a), Some(s), Some(t), Some(name)) = (f.next(), f.next(), f.next(), f.next())
        else {
            continue;
        };
        if !matches!(t, "t" | "T" | "W" | "w") {
            continue;
        }
        let (Ok(start), Ok(size)) = (u32::from_str_radix(a, 16), u32::from_str_radix(s, 16)) else {
            continue;
        };
        // Thumb function symbols may carry bit 0.
        let start = start & !1;
        if size == 0 || out.iter().any(|g| g.start == start) {
            continue;
        }
        out.push(Function {
            start,
            size,
            name: name.to_string(),
        });
    }
    out.sort_by_key(|f| f.start);
    out
}

/// Index of the function holding `addr`.
pub fn function_at(funcs: &[Function], addr: u32) -> Option<usize> {
    let i = funcs.partition_point(|f| f.start <= addr);
    let f = funcs.get(i.checked_sub(1)?)?;
    (addr < f.start + f.size).then_some(i - 1)
}

/// The assumptions of one cycle model. The integer timings are the TRM's; what the trace
/// cannot tell is a parameter here.
#[derive(Debug, Clone, Copy)]
pub struct Model {
    pub name: &'static str,
    /// P, the pipeline refill after a taken branch: 1 to 3 cycles (TRM: "depending on the
    /// alignment and width of the target instruction, and whether the processor manages to
    /// speculate the address early").
    pub refill: u32,
    /// SDIV/UDIV: 2 to 12 cycles depending on the operands, which the trace does not hold.
    pub div: u32,
    /// Flash wait states at 168 MHz (RM0090 Table 10, 2.7-3.6 V): 5, i.e. 6 cycles a read.
    pub wait_states: u32,
    /// Flash model: see [`Flash`].
    pub flash: Flash,
    /// A load or store right after a load costs 1 instead of 2 (TRM: neighbouring load and
    /// store single instructions pipeline; nothing pipelines after a store; not with a base
    /// write-back; not when the load's result is the next one's address).
    pub pipelined_loads: bool,
    /// `STR Rx, [Ry, #imm]` costs 1 (TRM 3.3.2: "always one cycle", the data phase overlaps
    /// the next instruction through the write buffer); otherwise Table 3-1's 2.
    pub store_imm_one: bool,
    /// Extra cycles of a PC-relative load (TRM 3.3.2: `LDR Rx,[PC,#imm]` "might add a cycle
    /// because of contention with the fetch unit").
    pub literal_extra: u32,
}

/// How the flash is seen by the core.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flash {
    /// The ART hides every wait state (ST's "0 wait state execution" claim taken at face value).
    Perfect,
    /// ASSUMPTION: ART instruction cache of 64 lines x 16 bytes and data cache of 8 lines,
    /// each fully associative with LRU replacement (RM0090 gives the sizes, not the
    /// organisation); prefetch on. Entering a 16-byte line that the cache holds: 0. A line
    /// reached sequentially that it does not hold: the prefetch asked for it when the
    /// previous line was entered, so the stall is what is left of the 6-cycle read
    /// (`wait_states + 1 - cycles spent in the previous line`, at least 0). A branch target
    /// it does not hold: `wait_states` cycles on top of the refill. A PC-relative literal
    /// load that misses the data cache: `wait_states`.
    Art,
    /// No cache hits (pessimistic): every taken branch pays `wait_states`, every literal
    /// load too; sequential lines as with [`Flash::Art`]'s prefetch.
    NoCache,
}

impl Model {
    /// The best case the TRM allows: P = 1, divides 2 cycles, no flash penalty.
    pub const LOW: Model = Model {
        name: "low",
        refill: 1,
        div: 2,
        wait_states: 5,
        flash: Flash::Perfect,
        pipelined_loads: true,
        store_imm_one: true,
        literal_extra: 0,
    };
    /// The estimate: P = 2 (the middle of 1-3), divides 12 (their worst: the operands are
    /// not in the trace), the ART as [`Flash::Art`].
    pub const ESTIMATE: Model = Model {
        name: "estimate",
        refill: 2,
        div: 12,
        wait_states: 5,
        flash: Flash::Art,
        pipelined_loads: true,
        store_imm_one: true,
        literal_extra: 0,
    };
    /// A pessimistic case (not a proof of an upper bound: see the module docs for what is not
    /// modelled): P = 3, divides 12, no cache hits, no load pipelining, stores 2, literal
    /// loads + 1.
    pub const HIGH: Model = Model {
        name: "high",
        refill: 3,
        div: 12,
        wait_states: 5,
        flash: Flash::NoCache,
        pipelined_loads: false,
        store_imm_one: false,
        literal_extra: 1,
    };

    /// Cycles of `insn` alone (no flash), given whether it branched (`taken`: the next
    /// executed address is not the next instruction) and the instruction executed before it
    /// (`prev`).
    pub fn cost(&self, insn: &Insn, taken: bool, prev: Option<&Insn>) -> u32 {
        // The previous instruction wrote this one's base register.
        let dependent = match (prev, insn.base) {
            (Some(q), Some(b)) => q.writes & (1 << b) != 0,
            _ => false,
        };
        let after_load = prev.is_some_and(|q| q.class == Class::LoadSingle);
        let pipelined = self.pipelined_loads && after_load && !insn.writeback && !dependent;
        // TRM 3.3.2: "Any load or store that generates an address dependent on the result of
        // a preceding data processing operation stalls the pipeline for an additional cycle".
        let stall = u32::from(
            dependent && prev.is_some_and(|q| matches!(q.class, Class::Alu | Class::Mul)),
        );
        let literal = if insn.literal.is_some() {
            self.literal_extra
        } else {
            0
        };
        stall + literal + self.base_cost(insn, taken, pipelined)
    }

    fn base_cost(&self, insn: &Insn, taken: bool, pipelined: bool) -> u32 {
        let p = self.refill;
        match insn.class {
            Class::Alu | Class::Unknown => {
                if insn.writes_pc {
                    1 + p
                } else {
                    1
                }
            }
            Class::Mul => 1,
            Class::Div => self.div,
            Class::LoadSingle => {
                if insn.writes_pc {
                    2 + p
                } else if pipelined {
                    1
                } else {
                    2
                }
            }
            Class::StoreSingle => {
                if pipelined || (self.store_imm_one && insn.store_imm) {
                    1
                } else {
                    2
                }
            }
            Class::Double => 1 + insn.regs,
            Class::Multiple => 1 + insn.regs + if insn.writes_pc && taken { p } else { 0 },
            Class::Branch | Class::CompareBranch => {
                if taken {
                    1 + p
                } else {
                    1
                }
            }
            Class::Table => 2 + p,
            Class::It => 1,
            Class::Barrier => {
                if insn.mnemonic.starts_with("isb") {
                    1 + p
                } else {
                    1
                }
            }
            Class::System => 2,
            Class::FpSimple => 1,
            Class::FpMove2 => 2,
            Class::FpMac => 3,
            Class::FpDivSqrt => 14,
            Class::FpLoadStore => 2,
            Class::FpMultiple => 1 + insn.regs,
        }
    }
}

/// The TRM's timing rule of an instruction, as text (for `fw-cycles --explain`).
pub fn rule(insn: &Insn) -> String {
    match insn.class {
        Class::Alu if insn.writes_pc => "1+P (writes PC)".into(),
        Class::Alu => "1".into(),
        Class::Unknown => "1 (not in the table)".into(),
        Class::Mul => "1".into(),
        Class::Div => "2..12 (operands)".into(),
        Class::LoadSingle if insn.writes_pc => "2+P (loads PC)".into(),
        Class::LoadSingle | Class::StoreSingle if insn.writeback => {
            "2 (write-back: not pipelined)".into()
        }
        Class::StoreSingle if insn.store_imm => "1 (STR #imm; high: 2)".into(),
        Class::LoadSingle | Class::StoreSingle => "2, 1 right after a load".into(),
        Class::Double => format!("1+N = {}", 1 + insn.regs),
        Class::Multiple if insn.writes_pc => format!("1+N+P = {}+P", 1 + insn.regs),
        Class::Multiple => format!("1+N = {}", 1 + insn.regs),
        Class::Branch | Class::CompareBranch => "1+P taken, 1 not".into(),
        Class::Table => "2+P".into(),
        Class::It => "1 (folding not assumed)".into(),
        Class::Barrier => "1 (ISB 1+P)".into(),
        Class::System => "2".into(),
        Class::FpSimple => "1".into(),
        Class::FpMove2 => "2".into(),
        Class::FpMac => "3".into(),
        Class::FpDivSqrt => "14".into(),
        Class::FpLoadStore => "2".into(),
        Class::FpMultiple => format!("1+N = {}", 1 + insn.regs),
    }
}

/// Exception entry (stacking, vector fetch): 12 cycles (TRM: interrupt latency), charged when
/// an instruction that does not branch is followed by another address.
pub const EXCEPTION_ENTRY: u32 = 12;

/// A fully associative LRU cache of 16-byte lines (most recent first).
struct Lru {
    lines: Vec<u32>,
    capacity: usize,
}

impl Lru {
    fn new(capacity: usize) -> Self {
        Self {
            lines: Vec::with_capacity(capacity),
            capacity,
        }
    }

    /// True on a hit; the line is the most recent afterwards.
    fn access(&mut self, line: u32) -> bool {
        if let Some(i) = self.lines.iter().position(|&l| l == line) {
            self.lines[..=i].rotate_right(1);
            true
        } else {
            if self.lines.len() == self.capacity {
                self.lines.pop();
            }
            self.lines.insert(0, line);
            false
        }
    }
}

/// One model's running state over the trace.
struct Sim {
    model: Model,
    icache: Lru,
    dcache: Lru,
    line: u32,
    cycles_in_line: u32,
    total: u64,
}

impl Sim {
    fn new(model: Model) -> Self {
        Self {
            model,
            icache: Lru::new(64),
            dcache: Lru::new(8),
            line: u32::MAX,
            cycles_in_line: 0,
            total: 0,
        }
    }

    /// Cycles of one executed instruction at `pc`; `arrived_by_jump`: the previous one
    /// branched (or an exception was taken) to here.
    fn step(
        &mut self,
        pc: u32,
        insn: &Insn,
        taken: bool,
        prev: Option<&Insn>,
        jumped: bool,
    ) -> u32 {
        let ws = self.model.wait_states;
        let line = pc >> 4;
        let mut stall = 0;
        if line != self.line {
            stall = match self.model.flash {
                Flash::Perfect => 0,
                Flash::Art | Flash::NoCache => {
                    let hit = self.icache.access(line) && self.model.flash == Flash::Art;
                    if hit {
                        0
                    } else if jumped {
                        ws
                    } else {
                        (ws + 1).saturating_sub(self.cycles_in_line)
                    }
                }
            };
            self.line = line;
            self.cycles_in_line = 0;
        }
        if let Some(lit) = insn.literal {
            stall += match self.model.flash {
                Flash::Perfect => 0,
                Flash::Art => {
                    if self.dcache.access(lit >> 4) {
                        0
                    } else {
                        ws
                    }
                }
                Flash::NoCache => ws,
            };
        }
        let c = self.model.cost(insn, taken, prev) + stall;
        self.cycles_in_line += c;
        self.total += u64::from(c);
        c
    }
}

/// The models reported, in column order.
pub const MODELS: [Model; 3] = [Model::LOW, Model::ESTIMATE, Model::HIGH];

/// Sum, count and maximum of one window kind, in instructions and in each model's cycles.
#[derive(Debug, Clone, Default)]
pub struct WindowStats {
    pub n: u64,
    pub instr_sum: u64,
    pub instr_max: u64,
    pub cycles_sum: [u64; 3],
    pub cycles_max: [u64; 3],
    /// Raw (overhead not removed) values, for the overhead window itself.
    pub instr_min_raw: u64,
    pub cycles_min_raw: [u64; 3],
    /// Loads through a register other than SP/PC ([`Insn::register_load`]).
    pub register_loads_sum: u64,
    pub register_loads_max: u64,
}

/// Per-function instructions and cycles (estimate model) in the pipeline windows.
#[derive(Debug, Clone, Default)]
pub struct FunctionStats {
    pub instr_sum: u64,
    pub cycles_sum: [u64; 3],
    /// Largest estimate-model cycles in one sample.
    pub cycles_max: u64,
    /// In the worst sample (by estimate-model cycles).
    pub worst_instr: u64,
    pub worst_cycles: u64,
}

/// Result of [`analyse`].
#[derive(Debug, Default)]
pub struct Analysis {
    /// Instructions in the trace.
    pub executed: u64,
    /// Executed addresses (distinct) outside every function symbol.
    pub unmapped: Vec<u32>,
    /// Executed addresses (distinct) with no instruction in the disassembly.
    pub undisassembled: Vec<u32>,
    /// Executed mnemonics the cost table does not know, with counts.
    pub unknown: BTreeMap<String, u64>,
    /// Exceptions taken (an instruction that does not branch followed by another address).
    pub exceptions: u64,
    /// Per window kind (probe name, e.g. "Pipeline"), overhead (`Empty`) not removed yet.
    pub raw: BTreeMap<String, Vec<(u64, [u64; 3])>>,
    /// Per window kind, the register loads of each window (same order as `raw`).
    pub raw_register_loads: BTreeMap<String, Vec<u64>>,
    /// Per function (index into the function list) in the `Pipeline` windows.
    pub functions: Vec<FunctionStats>,
    pub function_names: Vec<String>,
    /// Pipeline windows: number and the index of the worst one (estimate cycles).
    pub pipeline_windows: u64,
    /// Per executed class: instructions and estimate-model cycles, in the pipeline windows.
    pub classes: BTreeMap<String, (u64, u64)>,
}

/// Window probe functions: `<fog_firmware::budget::probe::NAME as ...Window>::open/close`.
fn probe_name(symbol: &str) -> Option<(String, bool)> {
    let rest = symbol.strip_prefix("<fog_firmware::budget::probe::")?;
    let (name, tail) = rest.split_once(' ')?;
    if tail.ends_with(">::open") {
        Some((name.to_string(), true))
    } else if tail.ends_with(">::close") {
        Some((name.to_string(), false))
    } else {
        None
    }
}

/// Reads the trace (`u32` little-endian addresses) and costs every instruction.
pub fn analyse(
    trace: &mut dyn Read,
    disasm: &Disassembly,
    funcs: &[Function],
) -> Result<Analysis, String> {
    // Probe entry addresses.
    let mut opens: HashMap<u32, usize> = HashMap::new();
    let mut closes: HashMap<u32, usize> = HashMap::new();
    let mut kinds: Vec<String> = Vec::new();
    for f in funcs {
        if let Some((name, open)) = probe_name(&f.name) {
            let k = kinds.iter().position(|n| *n == name).unwrap_or_else(|| {
                kinds.push(name.clone());
                kinds.len() - 1
            });
            if open {
                opens.insert(f.start, k);
            } else {
                closes.insert(f.start, k);
            }
        }
    }
    let pipeline_kind = kinds.iter().position(|k| k == "Pipeline");
    if pipeline_kind.is_none() {
        return Err(
            "no fog_firmware::budget::probe::Pipeline functions in the ELF: \
                    not the budget image (feature budget)?"
                .into(),
        );
    }

    let mut a = Analysis {
        functions: vec![FunctionStats::default(); funcs.len()],
        function_names: funcs.iter().map(|f| f.name.clone()).collect(),
        ..Analysis::default()
    };
    // A dense table over the code: per halfword address, the instruction, its function and
    // whether a window opens or closes there (hash look-ups per instruction were the cost).
    let lo = disasm.insns.keys().copied().min().unwrap_or(0);
    let hi = disasm.insns.keys().copied().max().unwrap_or(0) + 4;
    let fallback = classify(2, "?", "", "");
    struct Slot {
        insn: Insn,
        known: bool,
        func: Option<usize>,
        open: Option<usize>,
        close: Option<usize>,
        base: String,
    }
    let mut slots: Vec<Slot> = Vec::new();
    let mut slot_of = vec![u32::MAX; ((hi - lo) / 2 + 1) as usize];
    let mut slot_at = |pc: u32, slots: &mut Vec<Slot>| -> usize {
        let di = (pc.wrapping_sub(lo) / 2) as usize;
        if pc >= lo && pc.is_multiple_of(2) && di < slot_of.len() && slot_of[di] != u32::MAX {
            return slot_of[di] as usize;
        }
        let (insn, known) = match disasm.insns.get(&pc) {
            Some(i) => (i.clone(), true),
            None => (fallback.clone(), false),
        };
        let base = split_mnemonic(&insn.mnemonic).0;
        slots.push(Slot {
            insn,
            known,
            func: function_at(funcs, pc),
            open: opens.get(&pc).copied(),
            close: closes.get(&pc).copied(),
            base,
        });
        let s = slots.len() - 1;
        if pc >= lo && pc.is_multiple_of(2) && di < slot_of.len() {
            slot_of[di] = s as u32;
        }
        s
    };
    let mut raw: Vec<Vec<(u64, [u64; 3])>> = vec![Vec::new(); kinds.len()];
    let mut raw_loads: Vec<Vec<u64>> = vec![Vec::new(); kinds.len()];
    let mut register_loads = 0u64;
    let mut load_stack: Vec<u64> = Vec::new();
    let mut sims = MODELS.map(Sim::new);
    // Open windows: kind, instruction index and cycles at the open's entry.
    let mut stack: Vec<(usize, u64, [u64; 3])> = Vec::new();
    let mut in_pipeline = 0usize;
    // Per-function figures of the current pipeline window.
    let mut cur: HashMap<usize, (u64, u64)> = HashMap::new();
    let mut worst_cycles = 0u64;
    let mut unmapped = std::collections::BTreeSet::new();
    let mut undisassembled = std::collections::BTreeSet::new();
    let mut classes: HashMap<String, (u64, u64)> = HashMap::new();

    let mut prev: Option<(u32, usize)> = None;
    // The slot of the instruction executed before the one being costed.
    let mut before: Option<usize> = None;
    let mut jumped = true;
    let mut index: u64 = 0;
    let mut buf = vec![0u8; 1 << 20];
    let mut carry: Vec<u8> = Vec::new();
    loop {
        let n = trace.read(&mut buf).map_err(|e| format!("trace: {e}"))?;
        if n == 0 {
            break;
        }
        carry.extend_from_slice(&buf[..n]);
        let whole = carry.len() / 4 * 4;
        for chunk in carry[..whole].chunks_exact(4) {
            let pc = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
            let si = slot_at(pc, &mut slots);
            // Cost the previous instruction, now that its successor is known.
            if let Some((ppc, psi)) = prev {
                let ps = &slots[psi];
                let pinsn = &ps.insn;
                let fallthrough = ppc.wrapping_add(pinsn.size);
                let taken = pc != fallthrough;
                let branches = matches!(
                    pinsn.class,
                    Class::Branch | Class::CompareBranch | Class::Table
                ) || pinsn.writes_pc;
                let exception = taken && !branches;
                let mut c = [0u64; 3];
                for (i, s) in sims.iter_mut().enumerate() {
                    let q = before.map(|b| &slots[b].insn);
                    let mut x = s.step(ppc, pinsn, taken && branches, q, jumped);
                    if exception {
                        x += EXCEPTION_ENTRY;
                        s.total += u64::from(EXCEPTION_ENTRY);
                    }
                    c[i] = u64::from(x);
                }
                if exception {
                    a.exceptions += 1;
                }
                before = Some(psi);
                jumped = taken;
                if pinsn.register_load {
                    register_loads += 1;
                }
                if in_pipeline > 0 {
                    if let Some(fi) = ps.func {
                        let e = cur.entry(fi).or_default();
                        e.0 += 1;
                        e.1 += c[1];
                        let fs = &mut a.functions[fi];
                        fs.instr_sum += 1;
                        for (sum, cm) in fs.cycles_sum.iter_mut().zip(c) {
                            *sum += cm;
                        }
                    }
                    if let Some(e) = classes.get_mut(&ps.base) {
                        e.0 += 1;
                        e.1 += c[1];
                    } else {
                        classes.insert(ps.base.clone(), (1, c[1]));
                    }
                }
            }
            let totals = [sims[0].total, sims[1].total, sims[2].total];
            let slot = &slots[si];
            if let Some(k) = slot.open {
                stack.push((k, index, totals));
                load_stack.push(register_loads);
                if Some(k) == pipeline_kind {
                    in_pipeline += 1;
                }
            } else if let Some(k) = slot.close {
                let Some((ok, i0, c0)) = stack.pop() else {
                    return Err(format!("window {} closed, none open", kinds[k]));
                };
                if ok != k {
                    return Err(format!(
                        "window {} closed while {} is open",
                        kinds[k], kinds[ok]
                    ));
                }
                let cyc = [totals[0] - c0[0], totals[1] - c0[1], totals[2] - c0[2]];
                raw[k].push((index - i0, cyc));
                raw_loads[k].push(register_loads - load_stack.pop().unwrap_or(register_loads));
                if Some(k) == pipeline_kind {
                    in_pipeline -= 1;
                    a.pipeline_windows += 1;
                    let this: u64 = cyc[1];
                    for (&fi, &(_, fc)) in &cur {
                        let fs = &mut a.functions[fi];
                        fs.cycles_max = fs.cycles_max.max(fc);
                    }
                    if this > worst_cycles {
                        worst_cycles = this;
                        for fs in a.functions.iter_mut() {
                            fs.worst_instr = 0;
                            fs.worst_cycles = 0;
                        }
                        for (&fi, &(fi_n, fc)) in &cur {
                            a.functions[fi].worst_instr = fi_n;
                            a.functions[fi].worst_cycles = fc;
                        }
                    }
                    cur.clear();
                }
            }
            if slot.func.is_none() {
                unmapped.insert(pc);
            }
            if !slot.known {
                undisassembled.insert(pc);
            }
            if slot.insn.class == Class::Unknown {
                *a.unknown.entry(slot.insn.mnemonic.clone()).or_default() += 1;
            }
            prev = Some((pc, si));
            index += 1;
        }
        carry.drain(..whole);
    }
    a.classes = classes.into_iter().collect();
    a.executed = index;
    a.unmapped = unmapped.into_iter().collect();
    a.undisassembled = undisassembled.into_iter().collect();
    for (k, name) in kinds.iter().enumerate() {
        a.raw.insert(name.clone(), std::mem::take(&mut raw[k]));
        a.raw_register_loads
            .insert(name.clone(), std::mem::take(&mut raw_loads[k]));
    }
    Ok(a)
}

impl Analysis {
    /// The counter overhead: the smallest `Empty` window, in instructions and cycles.
    pub fn overhead(&self) -> Option<(u64, [u64; 3])> {
        let e = self.raw.get("Empty")?;
        let i = e.iter().map(|w| w.0).min()?;
        let mut c = [0u64; 3];
        for (m, cm) in c.iter_mut().enumerate() {
            *cm = e.iter().map(|w| w.1[m]).min()?;
        }
        Some((i, c))
    }

    /// Statistics of one window kind with the overhead removed from each window.
    pub fn stats(&self, kind: &str) -> Option<WindowStats> {
        let (oi, oc) = self.overhead()?;
        let w = self.raw.get(kind)?;
        let mut s = WindowStats {
            instr_min_raw: u64::MAX,
            cycles_min_raw: [u64::MAX; 3],
            ..WindowStats::default()
        };
        if let Some(l) = self.raw_register_loads.get(kind) {
            s.register_loads_sum = l.iter().sum();
            s.register_loads_max = l.iter().copied().max().unwrap_or(0);
        }
        for &(i, c) in w {
            s.n += 1;
            let net = i.saturating_sub(oi);
            s.instr_sum += net;
            s.instr_max = s.instr_max.max(net);
            s.instr_min_raw = s.instr_min_raw.min(i);
            for m in 0..3 {
                let net = c[m].saturating_sub(oc[m]);
                s.cycles_sum[m] += net;
                s.cycles_max[m] = s.cycles_max[m].max(net);
                s.cycles_min_raw[m] = s.cycles_min_raw[m].min(c[m]);
            }
        }
        Some(s)
    }
}

/// The firmware's table rows and the window kind each one times.
pub const ROWS: [(&str, &str); 5] = [
    ("frame decode (8 bytes)", "Decode"),
    ("drift filter push + stillness test", "Estimate"),
    ("denoise db4 x3, B=512, resumable", "Denoise"),
    ("stage (filter + denoiser + status)", "Stage"),
    ("whole pipeline (decode+stage+record)", "Pipeline"),
];

/// Mean and max of a firmware table row (`| name | per | mean | max |`).
pub fn table_row(table: &str, name: &str) -> Option<(f64, f64)> {
    table.lines().find_map(|l| {
        let f: Vec<&str> = l.split('|').map(str::trim).collect();
        if f.len() >= 5 && f[1] == name {
            Some((f[3].parse().ok()?, f[4].parse().ok()?))
        } else {
            None
        }
    })
}

/// The firmware's ticks per instruction (`ticks per instruction x1000 = 1600`).
pub fn ticks_per_instruction(table: &str) -> Option<f64> {
    table.lines().find_map(|l| {
        l.strip_prefix("ticks per instruction x1000 = ")
            .and_then(|v| v.trim().parse::<f64>().ok())
            .map(|v| v / 1000.0)
    })
}

/// One row of the instruction-count cross-check.
#[derive(Debug, Clone)]
pub struct Check {
    pub row: &'static str,
    pub kind: &'static str,
    pub windows: u64,
    pub trace_mean: f64,
    pub trace_max: f64,
    pub firmware_mean: f64,
    pub firmware_max: f64,
    pub tolerance: f64,
}

impl Check {
    pub fn ok(&self) -> bool {
        (self.trace_mean - self.firmware_mean).abs() <= self.tolerance
            && (self.trace_max - self.firmware_max).abs() <= self.tolerance
    }
}

/// Compares the trace's instruction counts per window with the firmware's `-icount` table of
/// the same run. The firmware's figure is a difference of two SysTick readings minus the
/// overhead in ticks, each reading quantised to one tick: it is within 2 ticks of the exact
/// count (plus 0.05 for its one printed decimal). That is the tolerance.
pub fn cross_check(a: &Analysis, table: &str) -> Result<Vec<Check>, String> {
    let tpi = ticks_per_instruction(table).ok_or("no 'ticks per instruction' line in the table")?;
    let tolerance = 2.0 / tpi + 0.05;
    let mut out = Vec::new();
    for (row, kind) in ROWS {
        let (fm, fx) = table_row(table, row).ok_or_else(|| format!("no row '{row}'"))?;
        let s = a
            .stats(kind)
            .ok_or_else(|| format!("no {kind} windows in the trace"))?;
        out.push(Check {
            row,
            kind,
            windows: s.n,
            trace_mean: s.instr_sum as f64 / s.n.max(1) as f64,
            trace_max: s.instr_max as f64,
            firmware_mean: fm,
            firmware_max: fx,
            tolerance,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mnemonics_split_into_base_condition_and_class() {
        let c = |m: &str| {
            let (b, k, cond) = split_mnemonic(m);
            (b, k, cond)
        };
        assert_eq!(c("bls.n"), ("b".into(), Class::Branch, true));
        assert_eq!(c("bl"), ("bl".into(), Class::Branch, false));
        assert_eq!(c("bics.w"), ("bic".into(), Class::Alu, false));
        assert_eq!(c("ldrhi.w"), ("ldr".into(), Class::LoadSingle, true));
        assert_eq!(c("ldrhmi"), ("ldrh".into(), Class::LoadSingle, true));
        assert_eq!(c("vdiv.f32"), ("vdiv".into(), Class::FpDivSqrt, false));
        assert_eq!(c("vmovne.f32"), ("vmov".into(), Class::FpSimple, true));
        assert_eq!(c("popcc"), ("pop".into(), Class::Multiple, true));
        assert_eq!(c("itte"), ("it".into(), Class::It, false));
        assert_eq!(c("subsne.w"), ("sub".into(), Class::Alu, true));
        assert_eq!(c("teq"), ("teq".into(), Class::Alu, false));
        assert_eq!(
            c("frobnicate"),
            ("frobnicate".into(), Class::Unknown, false)
        );
    }

    #[test]
    fn trm_timings_for_one_short_function() {
        // A leaf in the shape of a probe function, costed instruction by instruction:
        // push {r7, lr} 1+2; mov 1; sub sp 1; movs 1; str 2 (after an ALU op: not
        // pipelined); mov 1; movw 1; movt 1; ldr 2; add sp 1; pop {r7, pc} 1+2+P.
        let text = "\
    5208:\tb580      \tpush\t{r7, lr}
    520a:\t466f      \tmov\tr7, sp
    520c:\tb081      \tsub\tsp, #4
    520e:\t2003      \tmovs\tr0, #3
    5210:\t9000      \tstr\tr0, [sp, #0]
    5212:\t4668      \tmov\tr0, sp
    5214:\tf24e 0018 \tmovw\tr0, #57368\t@ 0xe018
    5218:\tf2ce 0000 \tmovt\tr0, #57344\t@ 0xe000
    521c:\t6800      \tldr\tr0, [r0, #0]
    521e:\tb001      \tadd\tsp, #4
    5220:\tbd80      \tpop\t{r7, pc}
";
        let d = Disassembly::parse(text);
        assert_eq!(d.insns.len(), 11);
        let m = Model::LOW;
        let mut total = 0;
        let mut prev: Option<&Insn> = None;
        let mut addrs: Vec<u32> = d.insns.keys().copied().collect();
        addrs.sort_unstable();
        for (i, a) in addrs.iter().enumerate() {
            let insn = &d.insns[a];
            let taken = i + 1 == addrs.len();
            total += m.cost(insn, taken, prev);
            prev = Some(insn);
        }
        // str [sp, #0] right after `movs r0` (no dependency on sp): 1 (STR #imm); the ldr
        // after `movt r0` (its base) stalls 1: 2 + 1; the pop after `add sp` (its base)
        // too: 1 + N + P + 1.
        assert_eq!(
            total,
            3 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 3 + 1 + (1 + 2 + 1 + 1)
        );
        assert_eq!(Model::HIGH.cost(&d.insns[&0x5210], false, None), 2);
        assert_eq!(d.insns[&0x5214].size, 4);
        assert_eq!(d.insns[&0x5220].regs, 2);
        assert!(d.insns[&0x5220].writes_pc);
    }

    #[test]
    fn literal_loads_and_lists() {
        let i = classify(2, "ldr", "r0, [pc, #72]", "@ (450 <Reset+0x50>)");
        assert_eq!(i.literal, Some(0x450));
        let v = classify(4, "vpush", "{d8-d15}", "");
        assert_eq!(v.regs, 16);
        assert!(!i.register_load);
        assert_eq!(i.base, Some(15));
        let add = classify(2, "adds", "r1, #4", "");
        assert_eq!(add.writes, 1 << 1);
        let ld = classify(2, "ldr", "r2, [r1, #0]", "");
        assert_eq!(ld.base, Some(1));
        // Address from the preceding data-processing result: + 1 (TRM 3.3.2).
        assert_eq!(Model::LOW.cost(&ld, false, Some(&add)), 3);
        assert_eq!(Model::LOW.cost(&ld, false, None), 2);
        // Pipelined after a load, unless the load produced the address.
        let ld2 = classify(2, "ldr", "r3, [r4, #0]", "");
        assert_eq!(Model::LOW.cost(&ld2, false, Some(&ld)), 1);
        let ld3 = classify(2, "ldr", "r3, [r2, #0]", "");
        assert_eq!(Model::LOW.cost(&ld3, false, Some(&ld)), 2);
        assert!(classify(2, "str", "r1, [r2, #8]", "").store_imm);
        assert!(!classify(2, "str", "r1, [r2, r3]", "").store_imm);
        assert!(!classify(2, "str", "r1, [r2], #4", "").store_imm);
        assert_eq!(classify(2, "push", "{r4, lr}", "").base, Some(13));
        assert!(classify(2, "ldr", "r1, [r1, #0]", "").register_load);
        assert!(!classify(2, "ldr", "r1, [sp, #4]", "").register_load);
        assert!(classify(4, "vldr", "s0, [r2, #8]", "").register_load);
        assert!(!classify(2, "str", "r1, [r2, #0]", "").register_load);
        let p = classify(4, "ldmia.w", "sp!, {r4, r5, r6, r7, r8, pc}", "");
        assert!(!p.register_load);
        assert!(p.writes_pc);
        assert_eq!(p.regs, 6);
    }

    #[test]
    fn lru_keeps_the_most_recent_lines() {
        let mut c = Lru::new(2);
        assert!(!c.access(1));
        assert!(!c.access(2));
        assert!(c.access(1));
        assert!(!c.access(3)); // evicts 2
        assert!(!c.access(2));
        assert!(c.access(3));
    }

    #[test]
    fn the_table_is_read() {
        let t = "ticks per instruction x1000 = 1600\n| whole pipeline (decode+stage+record)     | sample |    1318.1 |    3224.4 |\n";
        assert_eq!(ticks_per_instruction(t), Some(1.6));
        assert_eq!(
            table_row(t, "whole pipeline (decode+stage+record)"),
            Some((1318.1, 3224.4))
        );
    }
}
