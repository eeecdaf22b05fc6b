//! Per-sample processing and the output records: everything the firmware computes, with no
//! hardware in it.
//!
//! This file depends on `fog-core` and `core` only. The hardware-in-the-loop test
//! (`tests/tests/firmware_qemu.rs`) compiles this very file on the host (`#[path]`), runs it
//! on the bytes it sends to QEMU, and requires the firmware's records to be bit-identical.
//!
//! # The estimation stage
//! [`Stage`] is `fog_core::identify::presets::LevelTrend<512>`: inputs `[10-s level, trend,
//! T]`, bias + linear link + 28 Gaussians (L = 30), sequential guarded DRLS, targets from the
//! paper's block denoiser (`B` = 512), built by [`new_stage`]. [`process`] runs one sample.
//!
//! # Records (see `fog-firmware/README.md`, the normative description)
//! Every record is `[0xA5, kind, len, payload (len bytes), fletcher16 (2 bytes, LE)]`; the
//! checksum covers `kind`, `len` and the payload. All multi-byte fields are little-endian.
#![forbid(unsafe_code)]

use fog_core::frame::ByteStats;
use fog_core::identify::{presets, IdentifyError};

pub use fog_core::identify::Estimate;

/// Full scale of the E-Core 2000 unit the firmware decodes, deg/s.
pub const FULL_SCALE_DPS: f32 = 60.0;

/// Sample period of the gyro's output, s (100 Hz; the network's time input `T` counts
/// samples times this).
pub const SAMPLE_PERIOD_S: f32 = 0.01;

/// Samples per denoising block.
pub const BLOCK: usize = 512;

/// Neurons of the network, bias and direct link included.
pub const NEURONS: usize = presets::L;

/// First byte of every record.
pub const RECORD_SYNC: u8 = 0xA5;
/// `kind` of a per-sample record.
pub const KIND_SAMPLE: u8 = 0x01;
/// `kind` of the final statistics record.
pub const KIND_STATS: u8 = 0x02;
/// Payload bytes of a per-sample record.
pub const SAMPLE_PAYLOAD_LEN: usize = 21;
/// Bytes of a whole per-sample record.
pub const SAMPLE_RECORD_LEN: usize = 3 + SAMPLE_PAYLOAD_LEN + 2;
/// Payload bytes of the statistics record: 17 `u64` counters and 6 `u32`.
pub const STATS_PAYLOAD_LEN: usize = 17 * 8 + 6 * 4;
/// Bytes of the whole statistics record.
pub const STATS_RECORD_LEN: usize = 3 + STATS_PAYLOAD_LEN + 2;

/// Status bit: a training step was made at this sample (`train_error_dps` is a number).
pub const STATUS_TRAINED: u8 = 1 << 0;
/// Status bit: this sample completed a denoising block.
pub const STATUS_BLOCK_DONE: u8 = 1 << 1;
/// Status bit: the sample was refused (non-finite or out of range); the three estimates are
/// NaN and the identifier did not change.
pub const STATUS_REJECTED: u8 = 1 << 7;

/// End of input: these 8 bytes in a row (`b"FOG-END!"` with bit 7 set on each) end the run.
///
/// They are ordinary input for the decoder too (a valid E-Core stream never holds two sync
/// bytes in a row, so they decode as 7 frames cut short and one pending byte), so the host
/// reproduces the counters by decoding exactly the bytes it sent.
pub const END_MARKER: [u8; 8] = [0xC6, 0xCF, 0xC7, 0xAD, 0xC5, 0xCE, 0xC4, 0xA1];

/// The stage the firmware runs.
pub type Stage = presets::LevelTrend<BLOCK>;

/// Builds the stage: the level-trend preset with its default scaling and trainer.
pub fn new_stage() -> Result<Stage, IdentifyError> {
    presets::level_trend::<BLOCK>(presets::LEVEL_TREND_SCALING, SAMPLE_PERIOD_S)
}

/// One sample through the stage: its estimate and the record's status byte. A refused
/// sample gives NaN estimates and [`STATUS_REJECTED`].
///
/// `temp_c` is the board temperature, °C (`None` without a sensor or while its reading is
/// stale; see `temperature.rs`). The level-trend stage has no temperature input and does not
/// use it yet: this argument is the one place where the temperature enters the sample
/// processing, for the identifier with a temperature input.
pub fn process(stage: &mut Stage, rate_dps: f32, temp_c: Option<f32>) -> (Estimate, u8) {
    let _ = temp_c;
    match stage.push(rate_dps) {
        Ok(est) => {
            let mut status = 0;
            if !est.train_error_dps.is_nan() {
                status |= STATUS_TRAINED;
            }
            if est.block_done {
                status |= STATUS_BLOCK_DONE;
            }
            (est, status)
        }
        Err(_) => (
            Estimate {
                drift_dps: f32::NAN,
                compensated_dps: f32::NAN,
                train_error_dps: f32::NAN,
                block_done: false,
            },
            STATUS_REJECTED,
        ),
    }
}

/// Fletcher-16 (mod 255) of `bytes`: `sum1 | sum2 << 8`, with `sum1 = (sum1 + b) % 255` and
/// `sum2 = (sum2 + sum1) % 255` per byte.
///
/// The sums are reduced once per 256 bytes instead of per byte (same result: both sums are
/// taken mod 255 in the end, and 256 bytes keep them below 2^32 from any reduced start).
pub fn fletcher16(bytes: &[u8]) -> u16 {
    let (mut s1, mut s2) = (0u32, 0u32);
    for chunk in bytes.chunks(256) {
        for &b in chunk {
            s1 += u32::from(b);
            s2 += s1;
        }
        s1 %= 255;
        s2 %= 255;
    }
    (s1 | (s2 << 8)) as u16
}

/// Writes header and checksum around a payload already in `out[3..3 + len]`.
fn seal(out: &mut [u8], kind: u8, len: usize) {
    out[0] = RECORD_SYNC;
    out[1] = kind;
    out[2] = len as u8;
    let c = fletcher16(&out[1..3 + len]).to_le_bytes();
    out[3 + len] = c[0];
    out[4 + len] = c[1];
}

/// The per-sample record of sample `index` (0-based count of good frames).
pub fn sample_record(
    index: u32,
    rate_dps: f32,
    est: &Estimate,
    status: u8,
) -> [u8; SAMPLE_RECORD_LEN] {
    let mut r = [0u8; SAMPLE_RECORD_LEN];
    r[3..7].copy_from_slice(&index.to_le_bytes());
    let values = [
        rate_dps,
        est.drift_dps,
        est.compensated_dps,
        est.train_error_dps,
    ];
    for (chunk, v) in r[7..23].chunks_exact_mut(4).zip(values) {
        chunk.copy_from_slice(&v.to_bits().to_le_bytes());
    }
    r[23] = status;
    seal(&mut r, KIND_SAMPLE, SAMPLE_PAYLOAD_LEN);
    r
}

/// Run totals besides the decoder's counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RunTotals {
    /// Per-sample records written.
    pub samples: u32,
    /// Samples the stage refused.
    pub rejected: u32,
    /// Receive errors the serial port reported.
    pub serial_errors: u32,
    /// Stack high-water mark, bytes (0 when not measured).
    pub stack_bytes: u32,
    /// Received bytes overwritten in the one-byte receive register before the receive
    /// interrupt read them (the real UARTs report overrun events, counted as 1 each).
    pub rx_overrun: u32,
    /// Received bytes dropped because the receive queue was full.
    pub rx_queue_full: u32,
}

/// The final statistics record: every [`ByteStats`] counter, then [`RunTotals`].
pub fn stats_record(s: &ByteStats, t: &RunTotals) -> [u8; STATS_RECORD_LEN] {
    let counters = s.counters();
    let mut r = [0u8; STATS_RECORD_LEN];
    for (chunk, c) in r[3..3 + 17 * 8].chunks_exact_mut(8).zip(counters) {
        chunk.copy_from_slice(&c.to_le_bytes());
    }
    let tail = [
        t.samples,
        t.rejected,
        t.serial_errors,
        t.stack_bytes,
        t.rx_overrun,
        t.rx_queue_full,
    ];
    for (chunk, v) in r[3 + 17 * 8..3 + STATS_PAYLOAD_LEN]
        .chunks_exact_mut(4)
        .zip(tail)
    {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    seal(&mut r, KIND_STATS, STATS_PAYLOAD_LEN);
    r
}

/// Watches a byte stream for [`END_MARKER`].
#[derive(Debug, Clone, Copy, Default)]
pub struct EndDetector {
    matched: usize,
}

impl EndDetector {
    /// Feeds one byte; true when it completes the marker.
    pub fn push(&mut self, byte: u8) -> bool {
        // The marker's first byte occurs nowhere else in it, so a mismatch restarts at 0 or 1.
        self.matched = if END_MARKER.get(self.matched) == Some(&byte) {
            self.matched + 1
        } else {
            usize::from(byte == END_MARKER[0])
        };
        if self.matched == END_MARKER.len() {
            self.matched = 0;
            true
        } else {
            false
        }
    }
}
