//! Hardware-in-the-loop test of the firmware under QEMU (`-machine mps2-an386`, Cortex-M4F).
//!
//! A simulated E-Core 2000 record (seeded, deterministic: bias + slow drift + white noise,
//! quantized to 60/32768 deg/s) is encoded into frames, damaged in known ways (noise bytes, a
//! cut frame, a checksum error, a random burst), followed by the end marker, and sent to the
//! firmware's UART0. The host decodes the same bytes with the same fog-core decoder and runs
//! the same per-sample code (`fog-firmware/src/pipeline.rs`, compiled here). Every per-sample
//! record must match bit for bit, and the final statistics record must match the host's
//! byte counters exactly. The record format is parsed here independently, from
//! `fog-firmware/README.md`.

use std::io::{Read, Write};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use fog_core::frame::{ecore, ByteStats, Decoder, EcoreDecoder};
use fog_system_tests::{firmware_elf, qemu_system_arm};

#[allow(dead_code)]
#[path = "../../fog-firmware/src/pipeline.rs"]
mod pipeline;

/// Samples in the simulated record.
const SAMPLES: usize = 4000;
/// Whole test, QEMU included, must end within this.
const DEADLINE: Duration = Duration::from_secs(50);

/// xorshift64*: small, seeded, identical everywhere.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (sum of 12 uniforms, minus 6).
    fn normal(&mut self) -> f64 {
        (0..12).map(|_| self.uniform()).sum::<f64>() - 6.0
    }
}

/// E-Core-like rates in counts: turn-on bias 0.012 deg/s (43 deg/h), a slow drift of a few
/// mdeg/s (warm-up exponential + sine), white noise 0.015 deg/s per sample (54 deg/h at
/// 100 Hz), quantized to 60/32768 deg/s.
fn simulated_counts(n: usize, seed: u64) -> Vec<i16> {
    let mut rng = Rng(seed);
    let lsb_dps = 60.0 / 32768.0;
    (0..n)
        .map(|k| {
            let t_s = k as f64 * 0.01;
            let drift_dps = 0.006 * (1.0 - (-t_s / 15.0).exp())
                + 0.003 * (2.0 * std::f64::consts::PI * t_s / 25.0).sin();
            let rate_dps = 0.012 + drift_dps + 0.015 * rng.normal();
            (rate_dps / lsb_dps).round() as i16
        })
        .collect()
}

/// The byte stream sent to the UART: frames with known damage, then the end marker.
fn wire_stream(counts: &[i16], seed: u64) -> Vec<u8> {
    let mut rng = Rng(seed);
    // Starts mid-frame: the tail of a frame the firmware never saw the start of.
    let mut s = Vec::from(&ecore::encode(123, [0; 4])[3..]);
    for (k, &c) in counts.iter().enumerate() {
        let raw = [0x10, (k >> 8) as u8, k as u8, 0x5A];
        let mut frame = ecore::encode(c, raw);
        match k {
            // Line noise between frames (no sync flag).
            100 | 2500 => s.extend([0x00, 0x13, 0x7F, 0x42, 0x01]),
            // A frame cut short by the next one's sync byte.
            700 => {
                s.extend(&frame[..5]);
                continue;
            }
            // A corrupted bit: the checksum catches it.
            1300 => frame[3] ^= 0x01,
            // A random burst of any bytes (may contain sync bytes).
            2000 => s.extend((0..20).map(|_| rng.next_u64() as u8)),
            _ => {}
        }
        s.extend(frame);
    }
    s.extend(pipeline::END_MARKER);
    s
}

/// What the host expects: one entry per good frame, then the flushed counters.
struct Expected {
    samples: Vec<(f32, pipeline::Estimate, u8)>,
    stats: ByteStats,
}

fn host_reference(stream: &[u8]) -> Expected {
    let mut decoder = EcoreDecoder::new(pipeline::FULL_SCALE_DPS).expect("valid full scale");
    let mut stage = pipeline::new_stage().expect("valid identifier");
    let mut samples = Vec::new();
    for &b in stream {
        if let Some(frame) = decoder.push(b) {
            let (est, status) = pipeline::process(&mut stage, frame.rate_dps);
            samples.push((frame.rate_dps, est, status));
        }
    }
    decoder.flush();
    Expected {
        samples,
        stats: *decoder.stats(),
    }
}

/// Fletcher-16 as README.md defines it (written again here on purpose).
fn fletcher16(bytes: &[u8]) -> u16 {
    let (mut a, mut b) = (0u32, 0u32);
    for &x in bytes {
        a = (a + u32::from(x)) % 255;
        b = (b + a) % 255;
    }
    (a | (b << 8)) as u16
}

#[derive(Debug)]
struct SampleRecord {
    index: u32,
    bits: [u32; 4],
    status: u8,
}

#[derive(Debug)]
struct StatsRecord {
    counters: [u64; 17],
    samples: u32,
    rejected: u32,
    serial_errors: u32,
    stack_bytes: u32,
}

fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes(b.try_into().expect("4 bytes"))
}

/// Splits the UART output into records; panics on anything malformed.
fn parse_records(out: &[u8]) -> (Vec<SampleRecord>, Option<StatsRecord>) {
    let mut samples = Vec::new();
    let mut stats = None;
    let mut i = 0;
    while i < out.len() {
        assert!(stats.is_none(), "bytes after the statistics record at {i}");
        assert_eq!(out[i], 0xA5, "record sync at offset {i}");
        assert!(i + 3 <= out.len(), "truncated header at {i}");
        let (kind, len) = (out[i + 1], usize::from(out[i + 2]));
        let end = i + 3 + len + 2;
        assert!(end <= out.len(), "truncated record at {i}");
        let sum = u16::from_le_bytes([out[end - 2], out[end - 1]]);
        assert_eq!(
            sum,
            fletcher16(&out[i + 1..end - 2]),
            "checksum of record at {i}"
        );
        let p = &out[i + 3..i + 3 + len];
        match (kind, len) {
            (0x01, 21) => samples.push(SampleRecord {
                index: le_u32(&p[0..4]),
                bits: [
                    le_u32(&p[4..8]),
                    le_u32(&p[8..12]),
                    le_u32(&p[12..16]),
                    le_u32(&p[16..20]),
                ],
                status: p[20],
            }),
            (0x02, 152) => {
                let mut counters = [0u64; 17];
                for (c, chunk) in counters.iter_mut().zip(p[..136].chunks_exact(8)) {
                    *c = u64::from_le_bytes(chunk.try_into().expect("8 bytes"));
                }
                stats = Some(StatsRecord {
                    counters,
                    samples: le_u32(&p[136..140]),
                    rejected: le_u32(&p[140..144]),
                    serial_errors: le_u32(&p[144..148]),
                    stack_bytes: le_u32(&p[148..152]),
                });
            }
            other => panic!("unknown record (kind, len) {other:?} at {i}"),
        }
        i = end;
    }
    (samples, stats)
}

/// Kills QEMU whatever happens to the test.
struct KillOnDrop(Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Runs the firmware under QEMU with `input` on UART0; returns (UART0 output, exit code).
/// defmt's frames (semihosting stderr) go to `defmt_log`.
fn run_qemu(qemu: &Path, elf: &Path, input: Vec<u8>, defmt_log: &Path) -> (Vec<u8>, Option<i32>) {
    let start = Instant::now();
    let log = std::fs::File::create(defmt_log).expect("defmt log file");
    let child = Command::new(qemu)
        .args(["-machine", "mps2-an386", "-nographic", "-monitor", "none"])
        .args(["-serial", "stdio"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .arg("-kernel")
        .arg(elf)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(log))
        .spawn()
        .expect("qemu-system-arm starts");
    let mut qemu_proc = KillOnDrop(child);
    let mut stdin = qemu_proc.0.stdin.take().expect("piped stdin");
    let mut stdout = qemu_proc.0.stdout.take().expect("piped stdout");

    // Writer and reader on their own threads: neither pipe can block the other.
    let (done_tx, done_rx) = mpsc::channel();
    let writer = std::thread::spawn(move || {
        let r = stdin.write_all(&input).and_then(|()| stdin.flush());
        // Keep stdin open until the run is over (EOF is not the end-of-input signal).
        let _ = done_rx.recv_timeout(DEADLINE);
        r
    });
    let (out_tx, out_rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut out = Vec::new();
        let r = stdout.read_to_end(&mut out);
        let _ = out_tx.send((out, r));
    });

    let remaining = DEADLINE.saturating_sub(start.elapsed());
    let received = out_rx.recv_timeout(remaining);
    let _ = done_tx.send(());
    let (out, read_result) = match received {
        Ok(v) => v,
        Err(_) => {
            drop(qemu_proc);
            panic!("QEMU did not finish within {DEADLINE:?}");
        }
    };
    read_result.expect("reading QEMU's stdout");
    // stdout closed: QEMU is exiting; give it a moment, then kill.
    let mut code = None;
    let wait_until = Instant::now() + Duration::from_secs(5);
    while Instant::now() < wait_until {
        if let Ok(Some(status)) = qemu_proc.0.try_wait() {
            code = status.code();
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    writer
        .join()
        .expect("writer thread")
        .expect("writing QEMU's stdin");
    (out, code)
}

#[test]
fn firmware_under_qemu_matches_host_bit_for_bit() {
    let t0 = Instant::now();
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let elf = firmware_elf(&[]);
    let built = t0.elapsed();

    let counts = simulated_counts(SAMPLES, 0x05EE_DF06);
    let stream = wire_stream(&counts, 0xBADB_17E5);
    let expected = host_reference(&stream);

    let log = elf.with_file_name("hil-defmt.bin");
    let t_run = Instant::now();
    let (out, code) = run_qemu(&qemu, &elf, stream.clone(), &log);
    let ran = t_run.elapsed();
    let (records, stats) = parse_records(&out);

    assert_eq!(code, Some(0), "QEMU's exit code (semihosting)");
    let stats = stats.expect("final statistics record");
    assert_eq!(
        records.len(),
        expected.samples.len(),
        "one record per good frame"
    );
    let mut mismatches = 0;
    for (k, (r, (rate_dps, est, status))) in records.iter().zip(&expected.samples).enumerate() {
        let want = [
            rate_dps.to_bits(),
            est.drift_dps.to_bits(),
            est.compensated_dps.to_bits(),
            est.train_error_dps.to_bits(),
        ];
        if r.index as usize != k || r.bits != want || r.status != *status {
            mismatches += 1;
            if mismatches <= 5 {
                eprintln!(
                    "sample {k}: firmware index {} bits {:08x?} status {}; host bits {want:08x?} status {status}",
                    r.index, r.bits, r.status
                );
            }
        }
    }
    assert_eq!(mismatches, 0, "per-sample records differ from the host");

    let want = expected.stats.counters();
    assert_eq!(
        stats.counters, want,
        "byte counters (ByteStats field order)"
    );
    assert_eq!(stats.samples as usize, expected.samples.len());
    assert_eq!(stats.rejected, 0);
    assert_eq!(stats.serial_errors, 0);
    assert!(expected.stats.is_consistent());

    // The damage was seen as intended.
    let s = &expected.stats;
    assert_eq!(s.bytes_total, stream.len() as u64);
    assert_eq!(s.skipped.checksum, 8, "one checksum error");
    assert!(s.skipped.cut_short >= 5 + 7, "cut frame and end marker");
    assert!(
        s.skipped.no_sync >= 5 + 10,
        "noise bytes and the mid-frame start"
    );
    assert!(s.frames_good >= SAMPLES as u64 - 3);
    // The identifier trained (two blocks in) and tracked.
    let trained = expected
        .samples
        .iter()
        .filter(|(_, _, st)| st & pipeline::STATUS_TRAINED != 0)
        .count();
    assert!(trained >= SAMPLES - 2 * pipeline::BLOCK - 3, "{trained}");

    eprintln!(
        "HIL: {} bytes in, {} records bit-identical, counters identical; frames good {} bad {}; \
         stack high-water {} bytes; build {:.1} s, QEMU run {:.2} s, total {:.1} s",
        stream.len(),
        records.len(),
        s.frames_good,
        s.frames_bad,
        stats.stack_bytes,
        built.as_secs_f64(),
        ran.as_secs_f64(),
        t0.elapsed().as_secs_f64()
    );
    // The firmware build is a prerequisite (cached after the first run), not part of the limit.
    assert!(
        t0.elapsed() - built < Duration::from_secs(60),
        "HIL test too slow"
    );
}
