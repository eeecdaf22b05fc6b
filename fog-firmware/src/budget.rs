//! Instruction budget (feature `budget`): measures each stage on built-in data and prints a
//! table on the UART. Run by `scripts/fw-budget.sh` under QEMU with
//! `-icount shift=6,align=off,sleep=off`, where the board's counter advances a fixed number
//! of ticks per instruction; the ratio is calibrated here with a loop of known length.
//!
//! Figures are **instructions** executed, not cycles: on a real Cortex-M4F, VDIV (14
//! cycles), loads, taken branches and flash wait states make cycles larger. The cycle
//! estimate comes from the instruction trace of this run (`fw-cycles`, see [`probe`] and
//! `tests/src/cycles.rs`).
#![forbid(unsafe_code)]

use embedded_hal_nb::serial::Write;
use fog_core::denoise::{DenoiseConfig, ResumableDenoiser};
use fog_core::frame::{ecore, Decoder, EcoreDecoder};
use fog_core::image::Image;

use crate::app::{image_bytes, TickCounter, IDENTIFIER_IMAGE};
use crate::pipeline::{self, BLOCK};

mod probe;
mod resumable;

use probe::Window;

/// Samples measured: 8 blocks (41 s at 100 Hz).
const SAMPLES: usize = 8 * BLOCK;
/// A turn in the measured data: samples in this range get [`TURN_DPS`] added, so that the
/// filter's stillness test finds windows moving, undoes an update, and finds still windows
/// again during the run.
const TURN: core::ops::Range<usize> = 1800..2600;
/// Rate of that turn, deg/s.
const TURN_DPS: f32 = 12.0;
/// Goal: worst sample <= this times the mean (issue 14).
const GOAL_WORST_OVER_MEAN: u64 = 3;
/// Clock and sample rate of the budget line.
const CLOCK_HZ: u64 = 168_000_000;
const SAMPLE_RATE_HZ: u64 = 1_000;
/// Goals (instructions per sample at L = 30, flash, RAM).
const GOAL_PIPELINE_INSTR: u64 = 2_000;

/// Ticks to instructions: `instr = ticks * cal_instr / cal_ticks`, after removing the
/// counter's own overhead.
#[derive(Clone, Copy)]
struct Calibration {
    overhead_ticks: u32,
    cal_ticks: u64,
    cal_instr: u64,
}

impl Calibration {
    /// Instructions times 10 (one decimal).
    fn instr_x10(&self, ticks: u64, measurements: u64) -> u64 {
        let net = ticks.saturating_sub(u64::from(self.overhead_ticks) * measurements);
        if self.cal_ticks == 0 {
            return 0;
        }
        (net * self.cal_instr * 10 + self.cal_ticks / 2) / self.cal_ticks
    }
}

/// Sum, count and maximum of measured ticks.
#[derive(Default, Clone, Copy)]
struct Acc {
    ticks: u64,
    n: u64,
    max: u32,
}

impl Acc {
    fn add(&mut self, ticks: u32) {
        self.ticks += u64::from(ticks);
        self.n += 1;
        self.max = self.max.max(ticks);
    }
}

/// Times `f` once, in ticks, in a window of kind `W` (see [`probe`]: the counter is read in
/// functions the cycle tool finds in the trace).
#[inline(always)]
fn time<W: Window, C: TickCounter, R>(c: &C, f: impl FnOnce() -> R) -> (R, u32) {
    let t0 = W::open(c);
    let r = f();
    (r, W::close(c, t0))
}

fn calibrate<C: TickCounter>(c: &C, spin: fn(u32)) -> Calibration {
    let overhead_ticks = (0..16)
        .map(|_| time::<probe::Empty, _, _>(c, || ()).1)
        .min()
        .unwrap_or(0);
    // Two loop lengths: the difference cancels the call and the counter overhead.
    let (n1, n2) = (1_000u32, 101_000u32);
    let t1 = (0..4)
        .map(|_| time::<probe::Spin, _, _>(c, || spin(n1)).1)
        .min()
        .unwrap_or(0);
    let t2 = (0..4)
        .map(|_| time::<probe::Spin, _, _>(c, || spin(n2)).1)
        .min()
        .unwrap_or(0);
    Calibration {
        overhead_ticks,
        cal_ticks: u64::from(t2.saturating_sub(t1)),
        cal_instr: 2 * u64::from(n2 - n1),
    }
}

/// Deterministic E-Core-like counts, in f32: turn-on bias 0.002 deg/s (7 deg/h), a slow drift
/// of about 1 deg/h (warm-up + sine), white noise 0.0105 deg/s per sample (about the image
/// model's: 4 deg/h/sqrt(Hz) at 100 Hz, so that the stillness test finds the still
/// periods), 60/32768 deg/s per count, and the turn of [`TURN`].
struct Source {
    state: u32,
    k: u32,
}

impl Source {
    fn uniform(&mut self) -> f32 {
        self.state = self
            .state
            .wrapping_mul(1_664_525)
            .wrapping_add(1_013_904_223);
        (self.state >> 8) as f32 / (1u32 << 24) as f32
    }

    fn next_counts(&mut self) -> i16 {
        let t_s = self.k as f32 * (1.0 / pipeline::SAMPLE_RATE_HZ);
        let turn_dps = if TURN.contains(&(self.k as usize)) {
            TURN_DPS
        } else {
            0.0
        };
        self.k += 1;
        let mut n = -6.0f32;
        for _ in 0..12 {
            n += self.uniform();
        }
        let drift_dps = 0.0002 * (1.0 - libm::expf(-t_s / 15.0))
            + 0.0001 * libm::sinf(2.0 * core::f32::consts::PI * t_s / 25.0);
        let rate_dps = 0.002 + drift_dps + 0.0105 * n + turn_dps;
        libm::roundf(rate_dps / (pipeline::FULL_SCALE_DPS / 32768.0)) as i16
    }
}

fn row<W: core::fmt::Write>(
    w: &mut W,
    cal: &Calibration,
    name: &str,
    per: &str,
    acc: &Acc,
) -> core::fmt::Result {
    let mean = cal.instr_x10(acc.ticks, acc.n) / acc.n.max(1);
    let max = cal.instr_x10(u64::from(acc.max), 1);
    writeln!(
        w,
        "| {name:<40} | {per:<6} | {:>7}.{} | {:>7}.{} |",
        mean / 10,
        mean % 10,
        max / 10,
        max % 10
    )
}

/// Ticks per window kind over the [`SAMPLES`] samples, and what the run gave besides.
#[derive(Default)]
struct Measured {
    decode: Acc,
    estimate: Acc,
    /// The drift filter's pushes that end a window (its predict, test and update).
    estimate_window: Acc,
    denoise: Acc,
    /// The denoiser's pushes that do not complete a block.
    denoise_mid: Acc,
    stage: Acc,
    /// Whole pipeline: frame decode, stage and record.
    pipeline: Acc,
    /// Samples whose status says still (the last window ended was still).
    still_samples: u32,
    /// The stage's filter's counters at the end.
    windows: u32,
    still_windows: u32,
    undone: u32,
    /// Sum of results, printed so that no timed call is optimised away.
    sink: f32,
}

/// Measures and prints; false if something could not be set up.
pub fn run<W, C>(tx: &mut W, c: &C, spin: fn(u32), stack_bytes: fn() -> u32) -> bool
where
    W: Write<u8>,
    C: TickCounter,
{
    let cal = calibrate(c, spin);
    let mut measured = Measured::default();
    if measure(c, &mut measured).is_none() {
        return false;
    }
    // Stack used by all of the above (the stage and the copies live on the stack here).
    let stack = stack_bytes();
    let mut out = Out(tx);
    let r = report(&mut out, c, &cal, &measured, stack);
    let _ = nb::block!(out.0.flush());
    r.is_ok()
}

/// Builds the stage and stand-alone copies of its parts, then runs the [`SAMPLES`] samples
/// of [`Source`] through the whole pipeline and through each part on its own, timing every
/// window; `None` if something could not be set up.
///
/// Inlined into [`run`]: the stage and the copies live in its frame, which the stack
/// high-water mark holds. A window's count includes the instructions of this code around
/// the timed call (register moves, spills, the record): an edit here can move the table by
/// a few instructions per window with fog-core unchanged (the per-function table of
/// `fw-cycles` tells them apart: `fog_firmware::budget::run`).
#[inline(always)]
fn measure<C: TickCounter>(c: &C, m: &mut Measured) -> Option<()> {
    let mut decoder = EcoreDecoder::new(pipeline::FULL_SCALE_DPS).ok()?;
    let mut stage = pipeline::new_stage(image_bytes()).ok()?;
    // Stand-alone copies of the stage's parts, timed one by one on the same samples.
    let mut filter = Image::parse(image_bytes()).ok()?.filter().ok()?;
    let mut denoiser = ResumableDenoiser::<BLOCK>::new(DenoiseConfig::PAPER).ok()?;

    let mut source = Source {
        state: 0x5EED,
        k: 0,
    };
    let mut frames = 0u32;

    for k in 0..SAMPLES {
        let counts = source.next_counts();
        let wire = ecore::encode(counts, [0x10, (k >> 8) as u8, k as u8, 0x5A]);

        // Whole pipeline: decode the frame's 8 bytes, the stage (drift filter + denoiser), the
        // record; the stage is also timed on its own, inside.
        let mut rate_dps = f32::NAN;
        let mut stage_ticks = 0;
        let (_, ticks) = time::<probe::Pipeline, _, _>(c, || {
            for &b in &wire {
                if let Some(f) = decoder.push(b) {
                    let ((out, status), t) = time::<probe::Stage, _, _>(c, || {
                        pipeline::process(&mut stage, f.rate_dps, None, None)
                    });
                    stage_ticks = t;
                    let r = pipeline::sample_record(frames, f.rate_dps, &out, status);
                    frames += 1;
                    rate_dps = f.rate_dps;
                    m.sink += f32::from(r[7]);
                    if status & pipeline::STATUS_STILL != 0 {
                        m.still_samples += 1;
                    }
                }
            }
        });
        m.pipeline.add(ticks);
        m.stage.add(stage_ticks);

        // Frame decode alone, on a second decoder fed the same bytes.
        let mut d2 = decoder.clone();
        let (_, t) = time::<probe::Decode, _, _>(c, || {
            let mut n = 0u32;
            for &b in &wire {
                if d2.push(b).is_some() {
                    n += 1;
                }
            }
            n
        });
        m.decode.add(t);

        // The drift filter alone: per sample the drift and the window sums; per window the
        // predict, the stillness test and, for a still window, the update (or the undo).
        let windows = filter.stats().windows;
        let (e, t) = time::<probe::Estimate, _, _>(c, || filter.push(rate_dps, f32::NAN, None));
        m.estimate.add(t);
        if filter.stats().windows != windows {
            m.estimate_window.add(t);
        }
        if let Ok(e) = e {
            m.sink += e.compensated_dps;
        }

        // The resumable denoiser alone (db4, 3 levels, B = 512), every push.
        let (d, t) = time::<probe::Denoise, _, _>(c, || match denoiser.push(rate_dps) {
            Ok(Some(v)) => v,
            _ => 0.0,
        });
        m.denoise.add(t);
        if denoiser.filled() != 0 {
            m.denoise_mid.add(t);
        }
        m.sink += d;
    }
    let s = stage.filter().stats();
    (m.windows, m.still_windows, m.undone) = (s.windows, s.still_windows, s.undone);
    Some(())
}

/// Instructions per sample available at [`CLOCK_HZ`] and [`SAMPLE_RATE_HZ`].
const INSTR_PER_SAMPLE: u64 = CLOCK_HZ / SAMPLE_RATE_HZ;

/// Prints the whole budget: the measured table, the goals, the resumable-denoiser
/// comparison (measured here) and the worst sample against the sample period. Out of
/// line: `m` and `cal` stay in memory during the measurement, as they did when this was a
/// closure of [`run`].
#[inline(never)]
fn report<C: TickCounter, W: core::fmt::Write>(
    out: &mut W,
    c: &C,
    cal: &Calibration,
    m: &Measured,
    stack: u32,
) -> core::fmt::Result {
    let pipe_mean_x10 = cal.instr_x10(m.pipeline.ticks, m.pipeline.n) / m.pipeline.n.max(1);
    let worst = cal.instr_x10(u64::from(m.pipeline.max), 1) / 10;
    header(out, cal, m)?;
    stage_table(out, cal, m)?;
    goals(out, pipe_mean_x10, worst)?;
    writeln!(out)?;
    resumable::table(c, cal, out)?;
    writeln!(out)?;
    writeln!(
        out,
        "worst sample: {worst} instructions = {}.{:03} sample periods ({} us at least) at {} MHz, {} Hz",
        worst / INSTR_PER_SAMPLE,
        worst * 1000 / INSTR_PER_SAMPLE % 1000,
        worst * 1_000_000 / CLOCK_HZ,
        CLOCK_HZ / 1_000_000,
        SAMPLE_RATE_HZ
    )?;
    writeln!(
        out,
        "budget-variant stack high-water: {stack} bytes (holds the stage and copies of its parts; see the production figure from the HIL test)"
    )?;
    writeln!(
        out,
        "(checksum of results, ignore: {})",
        m.sink.to_bits() & 0xFF
    )
}

/// The title, the calibration and what was measured.
fn header<W: core::fmt::Write>(out: &mut W, cal: &Calibration, m: &Measured) -> core::fmt::Result {
    writeln!(
        out,
        "fog-firmware instruction budget (QEMU mps2-an386, -icount shift=6)"
    )?;
    writeln!(
        out,
        "calibration: {} instructions (subs/bne loop) = {} ticks; counter overhead {} ticks (removed)",
        cal.cal_instr, cal.cal_ticks, cal.overhead_ticks
    )?;
    writeln!(
        out,
        "ticks per instruction x1000 = {}",
        (cal.cal_ticks * 1000 + cal.cal_instr / 2) / cal.cal_instr.max(1)
    )?;
    writeln!(
        out,
        "{} samples ({} blocks of {}) at 100 Hz, a {} deg/s turn on samples {}..{}; drift filter from the embedded image ({} bytes); {} samples with status still; windows {}, still (updates) {}, undone {}",
        SAMPLES,
        SAMPLES / BLOCK,
        BLOCK,
        TURN_DPS,
        TURN.start,
        TURN.end,
        IDENTIFIER_IMAGE.len(),
        m.still_samples,
        m.windows,
        m.still_windows,
        m.undone
    )?;
    writeln!(out)
}

/// Mean and max instructions of each stage, then of the whole pipeline.
fn stage_table<W: core::fmt::Write>(
    out: &mut W,
    cal: &Calibration,
    m: &Measured,
) -> core::fmt::Result {
    writeln!(
        out,
        "| {:<40} | {:<6} | {:>9} | {:>9} |",
        "stage", "per", "mean", "max"
    )?;
    writeln!(out, "|{:-<42}|{:-<8}|{:->11}|{:->11}|", "", "", "", "")?;
    let rows: [(&str, &str, &Acc); 7] = [
        ("frame decode (8 bytes)", "frame", &m.decode),
        ("drift filter push + stillness test", "sample", &m.estimate),
        (
            "  of which pushes ending a window",
            "window",
            &m.estimate_window,
        ),
        ("denoise db4 x3, B=512, resumable", "sample", &m.denoise),
        (
            "  of which pushes not completing a block",
            "sample",
            &m.denoise_mid,
        ),
        ("stage (filter + denoiser + status)", "sample", &m.stage),
        (
            "whole pipeline (decode+stage+record)",
            "sample",
            &m.pipeline,
        ),
    ];
    for (name, per, acc) in rows {
        row(out, cal, name, per, acc)?;
    }
    writeln!(out)
}

/// The budget line and the goals on the pipeline's mean and worst sample (instructions;
/// the mean times 10).
fn goals<W: core::fmt::Write>(out: &mut W, pipe_mean_x10: u64, worst: u64) -> core::fmt::Result {
    let pipe = pipe_mean_x10 / 10;
    // pipe_mean_x10 * 100 / instr = percent times 10.
    let percent_x10 = pipe_mean_x10 * 100 / INSTR_PER_SAMPLE;
    writeln!(
        out,
        "budget at {} MHz, {} Hz: {} instructions per sample available; pipeline uses {} ({}.{} %)",
        CLOCK_HZ / 1_000_000,
        SAMPLE_RATE_HZ,
        INSTR_PER_SAMPLE,
        pipe,
        percent_x10 / 10,
        percent_x10 % 10
    )?;
    if pipe <= GOAL_PIPELINE_INSTR {
        writeln!(
            out,
            "goal <= {GOAL_PIPELINE_INSTR} instructions per sample (mean): met, {} to spare",
            GOAL_PIPELINE_INSTR - pipe
        )?;
    } else {
        writeln!(
            out,
            "goal <= {GOAL_PIPELINE_INSTR} instructions per sample (mean): NOT met, over by {}",
            pipe - GOAL_PIPELINE_INSTR
        )?;
    }
    let ratio_x10 = worst * 10 / pipe.max(1);
    writeln!(
        out,
        "goal worst sample <= {GOAL_WORST_OVER_MEAN}x the mean: {} ({worst} / {pipe} = {}.{}x)",
        if worst <= GOAL_WORST_OVER_MEAN * pipe {
            "met"
        } else {
            "NOT met"
        },
        ratio_x10 / 10,
        ratio_x10 % 10
    )
}

/// `core::fmt::Write` over the UART (bytes sent as they are).
struct Out<'a, W>(&'a mut W);

impl<W: Write<u8>> core::fmt::Write for Out<'_, W> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for b in s.bytes() {
            nb::block!(self.0.write(b)).map_err(|_| core::fmt::Error)?;
        }
        Ok(())
    }
}
