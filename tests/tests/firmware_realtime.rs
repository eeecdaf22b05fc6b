//! Bytes that arrive in real time: the firmware under QEMU `-icount` (deterministic virtual
//! time, one instruction = one cycle of a modelled 168 MHz core) with its input delivered at
//! 115,200 baud into a one-byte receive register, whether or not the firmware is ready
//! (`fog-firmware` feature `rt-feed`; model and limits in `fog-firmware/src/board/rt_feed.rs`).
//!
//! - With the receive interrupt and the queue (the production receive path): **no byte is
//!   lost** across the heaviest samples (every block end), and every record equals the
//!   host's bit for bit, counters included.
//! - With the receive interrupt disabled (`rt-feed-poll`: the main loop polls the register,
//!   as the firmware did before the queue), the same capture at 1,000,000 baud (a byte
//!   every 1,680 instructions, less than the heaviest sample) **loses bytes**: the test can
//!   fail, and this half shows it would. (At 115,200 baud polling would not lose any more:
//!   with the resumable denoiser no sample outlasts a byte period.)
//!
//! - At 8,000,000 baud (a byte every 210 instructions) the main loop cannot keep up: the
//!   queue fills, the receive interrupt pauses (back-pressure), bytes are overwritten in the
//!   register, and the loss markers must reach the decoder at their place: every frame the
//!   firmware decodes is a real one, in order, and decoding resumes after each loss.
//!
//! The capture is generated here (seeded) and compiled into the test images
//! (`FOG_RT_CAPTURE`); each image is read back from its ELF before it runs.

use std::io::Read;
use std::path::Path;
use std::process::Stdio;
use std::sync::mpsc;
use std::time::Instant;

use fog_core::frame::ecore;
use fog_system_tests::{firmware, qemu_system_arm, Firmware, FirmwareBuild};

mod hil;
use hil::{host_reference, parse_records, pipeline, spawn_qemu, Rng, StatsRecord};

/// Samples in the capture: three completed denoising blocks (the heaviest samples) and
/// training from the second block on.
const SAMPLES: usize = 1600;
/// Line rate of the test, bit/s (8N1: 10 bits per byte).
const BAUD: &str = "115200";
/// The polling control's line rate: a byte every 1,680 instructions, shorter than the
/// heaviest samples (about 2,540 instructions: a drift filter window end), so that a main loop
/// that polls between samples must lose bytes. (At 115,200 baud, a byte every 14,583
/// instructions, no sample of the stage outlasts a byte since the denoiser is resumable:
/// polling would lose nothing there, and the control could not fail.)
const POLL_BAUD: &str = "1000000";
/// A line rate at which the main loop cannot keep up on average (a byte every 280
/// instructions, a frame every 2,240, less than a sample with its record and the feed's and
/// receive interrupts cost; 893 mean for the pipeline alone with the drift filter image):
/// the queue fills, the receive interrupt pauses (back-pressure) and bytes are overwritten
/// (measured: 3,642 bytes in 101 loss events). (With the retired estimators' images, at
/// 8,000,000 baud the feed's and the receive interrupts left the main loop too little time
/// and the run did not end within the deadline; not re-run with the drift filter.)
const FAST_BAUD: &str = "6000000";

/// Line idle before the end marker (bytes without the sync flag, skipped by the decoder as
/// `no_sync`): the main loop drains its backlog meanwhile, so that the end marker itself is
/// not overwritten on the lossy lines (else the firmware would never see the end).
const IDLE_FILL: [u8; 512] = [0; 512];

/// Frames whose counts are `10 k - 8000` plus noise in 0..=9 counts (each frame tells which
/// one it is; the noise keeps the denoiser's work realistic), then the end marker.
fn ramp_capture(seed: u64) -> Vec<u8> {
    let mut rng = Rng(seed);
    let mut s = Vec::new();
    for k in 0..SAMPLES {
        let counts = (10 * k) as i16 - 8_000 + (rng.next_u64() % 10) as i16;
        s.extend(ecore::encode(counts, [0x20, (k >> 8) as u8, k as u8, 0x33]));
    }
    s.extend(IDLE_FILL);
    s.extend(pipeline::END_MARKER);
    s
}

/// Bias, a slow sine and white noise, quantized to E-Core counts; clean frames, then the end
/// marker.
fn capture(seed: u64) -> Vec<u8> {
    let mut rng = Rng(seed);
    let lsb_dps = 60.0 / 32768.0;
    let mut s = Vec::new();
    for k in 0..SAMPLES {
        let t_s = k as f64 * 0.01;
        let rate_dps =
            0.01 + 0.004 * (2.0 * std::f64::consts::PI * t_s / 7.0).sin() + 0.015 * rng.normal();
        let counts = (rate_dps / lsb_dps).round() as i16;
        s.extend(ecore::encode(counts, [0x20, (k >> 8) as u8, k as u8, 0x33]));
    }
    s.extend(IDLE_FILL);
    s.extend(pipeline::END_MARKER);
    s
}

/// Runs `elf` under `-icount shift=6,align=off,sleep=off` with no UART input; returns UART0's
/// output and QEMU's exit code.
fn run_icount(qemu: &Path, elf: &Path, defmt_log: &Path) -> (Vec<u8>, Option<i32>) {
    let mut proc = spawn_qemu(
        qemu,
        elf,
        &["-icount", "shift=6,align=off,sleep=off"],
        Stdio::null(),
        defmt_log,
    );
    let mut stdout = proc.0.stdout.take().expect("piped stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut out = Vec::new();
        let r = stdout.read_to_end(&mut out);
        let _ = tx.send((out, r));
    });
    let (out, r) = rx
        .recv_timeout(hil::DEADLINE)
        .unwrap_or_else(|_| panic!("QEMU did not finish within {:?}", hil::DEADLINE));
    r.expect("reading QEMU's stdout");
    (out, proc.exit_code())
}

/// Builds the test image with `feature` and `capture` at `baud` (in `fog-firmware/target/rt`);
/// the test's own copy, its capture read back from the ELF.
fn build(feature: &str, capture: &[u8], baud: &str, name: &str) -> Firmware {
    firmware(
        &FirmwareBuild {
            target_subdir: "target/rt",
            cargo_args: &["--features", feature],
            input_files: &[("FOG_RT_CAPTURE", capture)],
            envs: &[("FOG_RT_BAUD", baud)],
        },
        name,
    )
}

#[test]
fn bytes_arriving_at_115200_baud_none_lost_with_the_receive_interrupt() {
    let t0 = Instant::now();
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let stream = capture(0x0A11_7E57);
    let ramp = ramp_capture(0x005E_ED0F_F457);
    let isr = build("rt-feed", &stream, BAUD, "rt-isr");
    let poll = build("rt-feed-poll", &stream, POLL_BAUD, "rt-poll");
    let fast = build("rt-feed", &ramp, FAST_BAUD, "rt-fast");
    let built = t0.elapsed();
    let expected = host_reference(&stream);
    assert_eq!(expected.samples.len(), SAMPLES);

    // The production receive path: interrupt + queue.
    let t_run = Instant::now();
    let (out, code) = run_icount(&qemu, &isr.elf, &isr.file("defmt.bin"));
    let ran_isr = t_run.elapsed();
    assert_eq!(code, Some(0), "QEMU's exit code (semihosting)");
    let (records, stats) = parse_records(&out);
    let stats: StatsRecord = stats.expect("final statistics record");
    assert_eq!(
        (stats.rx_overrun, stats.rx_queue_full),
        (0, 0),
        "bytes lost (overrun, queue full) with the receive interrupt"
    );
    assert_eq!(
        records.len(),
        expected.samples.len(),
        "one record per frame"
    );
    let mismatches = records
        .iter()
        .zip(&expected.samples)
        .enumerate()
        .filter(|(k, (r, (_, _, status)))| {
            r.index as usize != *k || r.bits != expected.bits(*k) || r.status != *status
        })
        .count();
    assert_eq!(mismatches, 0, "records differ from the host's");
    assert_eq!(stats.counters, expected.stats.counters(), "byte counters");
    assert_eq!(expected.stats.bytes_total, stream.len() as u64);
    let block_ends = records
        .iter()
        .filter(|r| r.status & pipeline::STATUS_BLOCK_DONE != 0)
        .count();
    assert_eq!(
        block_ends,
        SAMPLES / pipeline::BLOCK,
        "heaviest samples covered"
    );

    // The same line without the receive interrupt: the main loop polls the register between
    // samples, and bytes that arrive during a long sample are overwritten.
    let t_run = Instant::now();
    let (out, code) = run_icount(&qemu, &poll.elf, &poll.file("defmt.bin"));
    let ran_poll = t_run.elapsed();
    assert_eq!(code, Some(0), "QEMU's exit code (semihosting), polling");
    let (poll_records, poll_stats) = parse_records(&out);
    let poll_stats = poll_stats.expect("final statistics record, polling");
    assert!(
        poll_stats.rx_overrun > 0,
        "polling must lose bytes at {POLL_BAUD} baud (else this test could not fail)"
    );
    assert!(poll_records.len() < SAMPLES, "frames lost when polling");
    let uart_overrun = poll_stats.counters[6];
    assert!(
        uart_overrun > 0,
        "overruns reach the decoder as receive errors"
    );

    // Losses through the queue: markers at their place, every decoded frame a real one.
    let t_run = Instant::now();
    let (out, code) = run_icount(&qemu, &fast.elf, &fast.file("defmt.bin"));
    let ran_fast = t_run.elapsed();
    assert_eq!(
        code,
        Some(0),
        "QEMU's exit code (semihosting), {FAST_BAUD} baud"
    );
    let (fast_records, fast_stats) = parse_records(&out);
    let fast_stats = fast_stats.expect("final statistics record, fast line");
    assert!(fast_stats.rx_overrun > 0, "the fast line must overrun");
    assert_eq!(
        fast_stats.rx_queue_full, 0,
        "back-pressure: the queue never drops"
    );
    assert!(
        fast_stats.serial_errors > 0,
        "loss markers reach the decoder"
    );
    let lsb_dps = 60.0f32 / 32768.0;
    let frame_of = |bits: u32| -> usize {
        let counts = (f32::from_bits(bits) / lsb_dps).round() as i32;
        usize::try_from((counts + 8_000) / 10).expect("a ramp value")
    };
    let decoded: Vec<usize> = fast_records.iter().map(|r| frame_of(r.bits[0])).collect();
    assert!(
        decoded.windows(2).all(|w| w[0] < w[1]),
        "decoded frames are real ones, in order"
    );
    let missing = SAMPLES - decoded.len();
    assert!(missing > 0, "frames lost at {FAST_BAUD} baud");
    // Each loss costs the frames its bytes were in (at most lost / 8 + 2 per event).
    let bound = fast_stats.rx_overrun as usize / 8 + 2 * fast_stats.serial_errors as usize;
    assert!(
        missing <= bound,
        "{missing} frames missing for {} bytes lost in {} events",
        fast_stats.rx_overrun,
        fast_stats.serial_errors
    );

    eprintln!(
        "RT fast: {FAST_BAUD} baud, {} bytes overwritten in {} loss events, {} of {SAMPLES} \
         frames decoded, all real and in order; QEMU {:.2} s",
        fast_stats.rx_overrun,
        fast_stats.serial_errors,
        decoded.len(),
        ran_fast.as_secs_f64()
    );
    eprintln!(
        "RT: {} bytes at {BAUD} baud (8N1; byte period 14,583 instructions = cycles of a 168 MHz \
         core); interrupt + queue: {} records bit-identical, {} block ends, 0 bytes lost; \
         polling at {POLL_BAUD} baud: {} bytes overwritten, {} of {} frames decoded; build {:.1} s, QEMU {:.2} s + \
         {:.2} s",
        stream.len(),
        records.len(),
        block_ends,
        poll_stats.rx_overrun,
        poll_records.len(),
        SAMPLES,
        built.as_secs_f64(),
        ran_isr.as_secs_f64(),
        ran_poll.as_secs_f64()
    );
}
