//! Fault injection in the hardware-in-the-loop test: the firmware under QEMU
//! (`-machine mps2-an386`) gets an E-Core 2000 stream with faults of every kind a serial gyro
//! link shows, in one run of about 3 000 frames:
//!
//! | frames | fault |
//! |---|---|
//! | 200 | one byte dropped inside a frame |
//! | 400 | three bytes dropped, the next frame's sync byte among them |
//! | 600 | a 64-byte burst of random bytes between two frames |
//! | 800 | a frame's middle overwritten by random bytes (sync bytes possible) |
//! | 1000 | the UART stalls for 2.5 s between two frames (the writer pauses) |
//! | 1200 | the gyro restarts mid-frame: cut after 3 bytes, 16 bytes of power-up garbage, then frames with a new turn-on bias |
//! | 1500-1999 | a stuck value: 500 identical frames |
//! | 2200-2599 | the rate at full scale: 200 frames at +32767 counts, 200 at -32768 |
//!
//! Checked:
//! - the firmware keeps running: it exits normally at the end marker (status 0), writes one
//!   record per good frame, and during the stall it answers every frame sent before it with
//!   no further input (the stall lasts 2.5 s, longer if QEMU runs slowly on a loaded
//!   machine, until those records are out; a firmware waiting for input would hit the
//!   deadline);
//! - it recovers within one frame: for each fault, the first whole frame after the fault
//!   ends is decoded (every frame carries its index in its raw bytes);
//! - nothing else is lost: every frame no fault touched is decoded;
//! - its counters explain every byte: the statistics record equals the host's accounting of
//!   the same bytes (fog-core's decoder), `bytes_total` equals the bytes sent, and the
//!   invariant `total = good + skipped + pending` holds; every record is bit-identical to the
//!   host's run of the same per-sample code; no sample is refused and every estimate is
//!   finite, the full-scale stretch included.
//!
//! Not injected here: UART error flags (overrun, framing...), which QEMU's stdin cannot
//! raise; the decoder's handling of them is covered by fog-core's tests and the fuzz targets.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use fog_core::frame::ecore;
use fog_system_tests::{default_firmware, qemu_system_arm};

mod hil;
use hil::{host_reference, parse_records, pipeline, run_qemu_paced, Piece, Rng};

const FRAMES: usize = 3000;
const STALL: Duration = Duration::from_millis(2500);
const LSB_DPS: f64 = 60.0 / 32768.0;

/// One injected fault: the first frame index whose bytes are whole after it.
struct Fault {
    what: &'static str,
    /// Index of the first frame sent whole after the fault has ended.
    recovered_by: usize,
}

/// The stream in pieces (a pause after the first), the faults, and the frames sent whole.
struct Plan {
    pieces: Vec<(Vec<u8>, Duration)>,
    faults: Vec<Fault>,
    whole: BTreeSet<usize>,
    sent: usize,
    /// Frames whose bytes were all written before the stall.
    before_stall: usize,
}

fn raw(k: usize) -> [u8; 4] {
    [0x10, (k >> 8) as u8, k as u8, 0x5A]
}

fn frame_index(raw: [u8; 4]) -> Option<usize> {
    (raw[0] == 0x10 && raw[3] == 0x5A).then(|| (usize::from(raw[1]) << 8) | usize::from(raw[2]))
}

fn plan(seed: u64) -> Plan {
    let mut rng = Rng(seed);
    let mut bias_dps = 0.012;
    let mut stuck = None;
    let mut s: Vec<u8> = Vec::new();
    let mut pieces = Vec::new();
    let mut faults = Vec::new();
    let mut whole = BTreeSet::new();
    let mut before_stall = 0;
    for k in 0..FRAMES {
        let rate_dps = bias_dps + 0.003 * (k as f64 * 0.01 / 5.0).sin() + 0.015 * rng.normal();
        let mut counts = (rate_dps / LSB_DPS).round() as i16;
        if (1500..2000).contains(&k) {
            counts = *stuck.get_or_insert(counts);
        }
        if (2200..2400).contains(&k) {
            counts = i16::MAX;
        }
        if (2400..2600).contains(&k) {
            counts = i16::MIN;
        }
        let f = ecore::encode(counts, raw(k));
        match k {
            200 => {
                s.extend(&f[..4]);
                s.extend(&f[5..]);
                faults.push(Fault {
                    what: "one byte dropped",
                    recovered_by: 201,
                });
                continue;
            }
            400 => {
                // The last two bytes of frame 400 and the sync byte of frame 401.
                s.extend(&f[..6]);
                let next = ecore::encode(counts, raw(401));
                s.extend(&next[1..]);
                faults.push(Fault {
                    what: "three bytes dropped",
                    recovered_by: 402,
                });
                continue;
            }
            401 => continue,
            600 => {
                s.extend((0..64).map(|_| rng.next_u64() as u8));
                faults.push(Fault {
                    what: "noise burst",
                    recovered_by: 600,
                });
            }
            800 => {
                let mut g = f;
                for b in &mut g[2..6] {
                    *b = rng.next_u64() as u8;
                }
                s.extend(g);
                faults.push(Fault {
                    what: "frame overwritten by noise",
                    recovered_by: 801,
                });
                continue;
            }
            1000 => {
                pieces.push((std::mem::take(&mut s), STALL));
                before_stall = whole.len();
                faults.push(Fault {
                    what: "UART stall",
                    recovered_by: 1000,
                });
            }
            1200 => {
                s.extend(&f[..3]);
                s.extend([0x00, 0x00, 0xFF, 0xFF, 0x80, 0x00, 0x7F, 0x00]);
                s.extend([0x55, 0xAA, 0x55, 0xAA, 0x00, 0x00, 0x00, 0x00]);
                bias_dps = 0.031;
                faults.push(Fault {
                    what: "gyro restart",
                    recovered_by: 1201,
                });
                continue;
            }
            1500 => faults.push(Fault {
                what: "stuck value",
                recovered_by: 2000,
            }),
            2200 => faults.push(Fault {
                what: "full scale",
                recovered_by: 2600,
            }),
            _ => {}
        }
        s.extend(f);
        whole.insert(k);
    }
    s.extend(pipeline::END_MARKER);
    pieces.push((s, Duration::ZERO));
    let sent = pieces.iter().map(|(p, _)| p.len()).sum();
    Plan {
        pieces,
        faults,
        whole,
        sent,
        before_stall,
    }
}

#[test]
fn firmware_survives_faults_and_accounts_for_every_byte() {
    let t0 = Instant::now();
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let fw = default_firmware("hil-faults");
    let built = t0.elapsed();

    let plan = plan(0xFA17_5EED);
    let stream: Vec<u8> = plan.pieces.iter().flat_map(|(p, _)| p.clone()).collect();
    let expected = host_reference(&stream);
    // The records due for the frames sent before the stall (26 bytes each).
    let records_before = expected
        .frames
        .iter()
        .filter(|f| frame_index(f.raw()).is_some_and(|k| k < 1000))
        .count();
    assert!(records_before >= plan.before_stall);

    // The stall lasts STALL, and longer if the firmware has not yet answered every frame sent
    // before it (a loaded machine runs QEMU slowly): it must answer them with no further
    // input. A firmware that waited for more bytes would hold the writer until DEADLINE.
    let pieces = plan
        .pieces
        .iter()
        .map(|(bytes, pause)| Piece {
            bytes: bytes.clone(),
            pause: *pause,
            resume_after_output: if pause.is_zero() {
                0
            } else {
                26 * records_before
            },
        })
        .collect();
    let log = fw.file("defmt.bin");
    let t_run = Instant::now();
    let run = run_qemu_paced(&qemu, &fw.elf, pieces, &log);
    let ran = t_run.elapsed();
    let (records, stats) = parse_records(&run.out);

    // Keeps running: normal exit at the end marker, one record per good frame.
    assert_eq!(run.code, Some(0), "QEMU's exit code (semihosting)");
    let stats = stats.expect("final statistics record");
    assert_eq!(
        records.len(),
        expected.samples.len(),
        "one record per good frame"
    );

    // Bit for bit the host's run; nothing refused, every estimate finite.
    for (k, (r, (_, _, status))) in records.iter().zip(&expected.samples).enumerate() {
        let want = expected.bits(k);
        assert_eq!(r.index as usize, k, "record index");
        assert_eq!(
            (r.bits, r.status),
            (want, *status),
            "record {k} differs from the host"
        );
        assert_eq!(
            r.status & pipeline::STATUS_REJECTED,
            0,
            "record {k} refused"
        );
        let drift = f32::from_bits(r.bits[1]);
        let comp = f32::from_bits(r.bits[2]);
        assert!(
            drift.is_finite() && comp.is_finite(),
            "record {k}: {drift} {comp}"
        );
    }

    // Counters explain every byte, and equal the host's accounting.
    let s = &expected.stats;
    assert_eq!(
        stats.counters,
        s.counters(),
        "byte counters (ByteStats order)"
    );
    assert_eq!(
        s.bytes_total, plan.sent as u64,
        "every byte sent is counted"
    );
    assert!(s.is_consistent());
    assert_eq!(s.bytes_pending, 0);
    assert_eq!(stats.samples as usize, records.len());
    assert_eq!((stats.rejected, stats.serial_errors), (0, 0));

    // Every whole frame decoded (nothing lost beyond the damaged frames), and recovery within
    // one frame of each fault's end.
    let decoded: BTreeSet<usize> = expected
        .frames
        .iter()
        .filter_map(|f| frame_index(f.raw()))
        .collect();
    let lost: Vec<usize> = plan.whole.difference(&decoded).copied().collect();
    assert!(lost.is_empty(), "whole frames lost: {lost:?}");
    for f in &plan.faults {
        assert!(
            decoded.contains(&f.recovered_by),
            "{}: frame {} after the fault not decoded",
            f.what,
            f.recovered_by
        );
    }
    // The full-scale frames decode to +-60 deg/s (-32768 counts is exactly -60).
    let rates: Vec<f32> = expected
        .frames
        .iter()
        .filter(|f| frame_index(f.raw()).is_some_and(|k| (2200..2600).contains(&k)))
        .map(|f| f.rate_dps)
        .collect();
    assert_eq!(rates.len(), 400);
    assert!(rates[..200].iter().all(|&r| r == 32767.0 * LSB_DPS as f32));
    assert!(rates[200..].iter().all(|&r| r == -60.0));

    // During the stall the firmware answered every frame sent before it: all their records
    // were out before the writer resumed (else the writer waited until the deadline).
    let resumed = *run.resumed.first().expect("one stall");
    let out_before = run.bytes_before(resumed);
    assert!(
        out_before >= 26 * records_before,
        "only {out_before} bytes out before the UART resumed; {records_before} records due"
    );

    eprintln!(
        "HIL faults: {} bytes in, {} records bit-identical, counters identical (good {} bytes, \
         skipped {}: no_sync {}, checksum {}, cut_short {}, incomplete {}; frames bad {}); \
         {} faults, each recovered at the next whole frame; stall of at least {:.1} s, UART \
         resumed at {:.2} s with {out_before} output bytes out; build {:.1} s, QEMU run {:.2} s",
        plan.sent,
        records.len(),
        s.bytes_good,
        s.skipped.total(),
        s.skipped.no_sync,
        s.skipped.checksum,
        s.skipped.cut_short,
        s.skipped.incomplete,
        s.frames_bad,
        plan.faults.len(),
        STALL.as_secs_f64(),
        resumed.as_secs_f64(),
        built.as_secs_f64(),
        ran.as_secs_f64()
    );
}
