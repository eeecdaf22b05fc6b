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

use std::time::{Duration, Instant};

use fog_core::frame::ecore;
use fog_system_tests::{firmware_elf, qemu_system_arm};

mod hil;
use hil::{host_reference, parse_records, pipeline, run_qemu, Rng};

/// Samples in the simulated record.
const SAMPLES: usize = 4000;

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
    // QEMU's UART waits for the guest (flow control): the receive queue never overflows.
    assert_eq!(
        (stats.rx_overrun, stats.rx_queue_full),
        (0, 0),
        "bytes lost"
    );
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
