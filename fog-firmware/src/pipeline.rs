//! Per-sample processing and the output records: everything the firmware computes, with no
//! hardware in it.
//!
//! This file depends on `fog-core` and `core` only. The hardware-in-the-loop test
//! (`tests/tests/firmware_qemu.rs`) compiles this very file on the host (`#[path]`), runs it
//! on the bytes it sends to QEMU with the same drift image, and requires the firmware's
//! records to be bit-identical.
//!
//! # The estimation stage
//! [`Stage`] runs the image's drift filter, `fog_core::drift_filter::DriftFilter`: the
//! Kalman filter of the image's gyro model (`fog_core::gyro_model::GyroModel`: level,
//! Gauss-Markov terms, warm-up, temperature and temperature-rate links), run per window of
//! the image's `window_s` (2 s in the default configuration). A window that the filter's
//! stillness test (or the external still flag) finds still updates the filter; the update
//! is undone when the next window fails. Per sample the drift is `h(t, T) x`, clamped to
//! the model's drift bound, and the compensated rate is `rate - drift`. [`new_stage`] builds
//! it from the drift image: `fog_core::image::Image::parse` (format 5; formats 1 to 4, the
//! retired estimators' images, are refused by name), the model's rate within
//! [`MIN_RATE_HZ`] .. [`MAX_RATE_HZ`], `Image::filter`. Beside it runs the paper's block
//! denoiser (db4, 3 levels, `B` = 512) in its resumable form
//! (`fog_core::denoise::ResumableDenoiser`: block `j`'s transform spread over the pushes of
//! block `j + 1`, bit-identical to `BlockDenoiser`), its output reported per sample
//! [`DENOISED_DELAY_SAMPLES`] late.
//! [`process`] runs one sample.
//!
//! # Records (see `fog-firmware/README.md`, the normative description)
//! Every record is `[0xA5, kind, len, payload (len bytes), fletcher16 (2 bytes, LE)]`; the
//! checksum covers `kind`, `len` and the payload. All multi-byte fields are little-endian.
#![forbid(unsafe_code)]

use fog_core::denoise::{DenoiseConfig, DenoiseError, ResumableDenoiser, MAX_ABS_INPUT};
use fog_core::drift_filter::{DriftFilter, DriftFilterError};
use fog_core::frame::ByteStats;
use fog_core::image::{Image, ImageError};

/// Full scale of the E-Core 2000 unit the firmware decodes, deg/s.
pub const FULL_SCALE_DPS: f32 = 60.0;

/// Sample rate of the E-Core 2000 and of the committed default image's model, Hz. The firmware runs
/// at the image's rate ([`Stage::sample_rate_hz`], within [`MIN_RATE_HZ`] ..
/// [`MAX_RATE_HZ`]); this one is the temperature refresh's basis
/// (`temperature::REFRESH_SAMPLES`: 100 samples, 1 s at this rate).
pub const SAMPLE_RATE_HZ: f32 = 100.0;
/// Slowest image rate the firmware runs, Hz (the sensor file's supported range).
pub const MIN_RATE_HZ: f32 = 10.0;
/// Fastest image rate the firmware runs, Hz.
pub const MAX_RATE_HZ: f32 = 2000.0;

/// Samples per denoising block.
pub const BLOCK: usize = 512;

/// The denoised field of sample `k`'s record is the denoised rate of sample
/// `k - DENOISED_DELAY_SAMPLES` (NaN before): two blocks. Block `j` is transformed while
/// block `j + 1` fills (so that no sample pays for a whole transform), comes out whole when
/// block `j + 1` completes, one block later than `BlockDenoiser` would give it, and is read
/// out sample by sample while block `j + 2` fills.
pub const DENOISED_DELAY_SAMPLES: usize = 2 * BLOCK;

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
/// Payload bytes of the statistics record: 17 `u64` counters and 7 `u32`.
pub const STATS_PAYLOAD_LEN: usize = 17 * 8 + 7 * 4;
/// Bytes of the whole statistics record.
pub const STATS_RECORD_LEN: usize = 3 + STATS_PAYLOAD_LEN + 2;

/// Status bit: the sample was taken as still: its external still flag when it has one,
/// else the decision of the last window the filter ended (its stillness test, or the
/// external flag given in that window; before the first window ends: presumed still).
/// `fog_core::drift_filter::DriftOutput::still`.
pub const STATUS_STILL: u8 = 1 << 0;
/// Status bit: this sample completed a denoising block (its transform runs during the next
/// block; the denoised field carries it one block after that).
pub const STATUS_BLOCK_DONE: u8 = 1 << 1;
/// Status bit: an external still flag was given for this sample ([`STATUS_STILL`] is then
/// that flag; it overrides the stillness test for the window it is given in).
pub const STATUS_EXTERNAL: u8 = 1 << 2;
/// Status bit: this sample ended a window found still, and the filter was updated with it
/// (`fog_core::drift_filter::DriftStats::still_windows` went up; the update is undone if the
/// next window fails).
pub const STATUS_LEVEL_UPDATE: u8 = 1 << 3;
/// Status bit: a temperature reading went into the drift filter with this sample.
pub const STATUS_TEMPERATURE: u8 = 1 << 4;
/// Status bit: this sample's drift is not verified: no window since power-on was found still
/// (`DriftStats::still_windows` is 0), so the drift is still the image's prior (its family
/// means) predicted forward, never updated on this unit. Clear from the sample that ends
/// the first still window on (an update undone later does not set it again).
pub const STATUS_UNVERIFIED: u8 = 1 << 5;
/// Status bit: the sample was refused (non-finite or beyond `denoise::MAX_ABS_INPUT`); the
/// three estimates are NaN, and neither the drift filter nor the denoiser changed.
pub const STATUS_REJECTED: u8 = 1 << 7;

/// End of input: these 8 bytes in a row (`b"FOG-END!"` with bit 7 set on each) end the run.
///
/// They are ordinary input for the decoder too (a valid E-Core stream never holds two sync
/// bytes in a row, so they decode as 7 frames cut short and one pending byte), so the host
/// reproduces the counters by decoding exactly the bytes it sent. The still-flag commands
/// ([`Command`]) are built the same way.
pub const END_MARKER: [u8; 8] = marker(*b"FOG-END!");
/// External still flag command: "still" from the next frame on (`b"FOG-STL!"`, bit 7 set).
pub const STILL_MARKER: [u8; 8] = marker(*b"FOG-STL!");
/// External still flag command: "moving" from the next frame on (`b"FOG-MOV!"`, bit 7 set).
pub const MOVING_MARKER: [u8; 8] = marker(*b"FOG-MOV!");
/// External still flag command: no external flag, the stillness test decides (`b"FOG-AUT!"`).
pub const AUTO_MARKER: [u8; 8] = marker(*b"FOG-AUT!");

/// `ascii` with bit 7 set on each byte.
const fn marker(ascii: [u8; 8]) -> [u8; 8] {
    let mut m = ascii;
    let mut i = 0;
    while i < 8 {
        m[i] |= 0x80;
        i += 1;
    }
    m
}

/// Why the stage could not be built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SetupError {
    /// The drift image was refused (corrupt, truncated, a retired or unknown version, an
    /// invalid model, a rate out of range).
    Image(ImageError),
    /// The image parsed but its model and configuration do not build a drift filter.
    Estimator(DriftFilterError),
    /// The denoiser's configuration was refused.
    Denoiser(DenoiseError),
}

/// The per-sample stage: the drift filter from the image, and the resumable block denoiser.
pub struct Stage {
    filter: DriftFilter,
    denoiser: ResumableDenoiser<BLOCK>,
}

impl Stage {
    /// The drift filter (its counters, state, model and configuration).
    pub fn filter(&self) -> &DriftFilter {
        &self.filter
    }

    /// The rate the stage runs at: the image's model's, Hz.
    pub fn sample_rate_hz(&self) -> f32 {
        self.filter.model().sample_rate_hz
    }
}

/// Builds the stage from a drift image (`fog_core::image` format 5) for any rate from
/// [`MIN_RATE_HZ`] to [`MAX_RATE_HZ`] (another rate: `ImageError::RateMismatch` naming the
/// nearer end of the range).
///
/// Stack: the caller should use the result where it is (`match &mut result`), not move the
/// stage out of it (a second copy of about 7 KiB).
pub fn new_stage(image: &[u8]) -> Result<Stage, SetupError> {
    // The parsed image only lives in this block (its stack slot is free after it).
    let filter = {
        let image = Image::parse(image).map_err(SetupError::Image)?;
        let image_hz = image.model.sample_rate_hz;
        if !(MIN_RATE_HZ..=MAX_RATE_HZ).contains(&image_hz) {
            return Err(SetupError::Image(ImageError::RateMismatch {
                image_hz,
                stream_hz: if image_hz < MIN_RATE_HZ {
                    MIN_RATE_HZ
                } else {
                    MAX_RATE_HZ
                },
            }));
        }
        image.filter().map_err(SetupError::Estimator)?
    };
    let denoiser = ResumableDenoiser::new(DenoiseConfig::PAPER).map_err(SetupError::Denoiser)?;
    Ok(Stage { filter, denoiser })
}

/// What one sample gives, besides its status byte.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Output {
    /// Drift estimate, deg/s (within the image's model's drift bound).
    pub drift_dps: f32,
    /// `rate - drift`, deg/s.
    pub compensated_dps: f32,
    /// The paper's denoised rate of sample `k - DENOISED_DELAY_SAMPLES`, deg/s; NaN until
    /// there is one.
    pub denoised_dps: f32,
}

/// The output of a refused sample.
const REJECTED: Output = Output {
    drift_dps: f32::NAN,
    compensated_dps: f32::NAN,
    denoised_dps: f32::NAN,
};

/// One sample through the stage: its output and the record's status byte.
///
/// `temp_c`: the board temperature, deg C (`None` without a sensor or while its reading is
/// stale; the filter then gets NaN, as its API asks: it keeps the last reading).
/// `external_still`: the external still flag (`Some(true)` still, `Some(false)` moving,
/// `None` absent: the filter's stillness test decides).
pub fn process(
    stage: &mut Stage,
    rate_dps: f32,
    temp_c: Option<f32>,
    external_still: Option<bool>,
) -> (Output, u8) {
    // Both parts refuse the same samples, so that they stay aligned.
    if !rate_dps.is_finite() || rate_dps.abs() > MAX_ABS_INPUT {
        return (REJECTED, STATUS_REJECTED);
    }
    let still_windows = stage.filter.stats().still_windows;
    let Ok(m) = stage
        .filter
        .push(rate_dps, temp_c.unwrap_or(f32::NAN), external_still)
    else {
        return (REJECTED, STATUS_REJECTED);
    };
    let still_windows_now = stage.filter.stats().still_windows;
    let mut status = 0;
    if m.still {
        status |= STATUS_STILL;
    }
    if external_still.is_some() {
        status |= STATUS_EXTERNAL;
    }
    if still_windows_now != still_windows {
        status |= STATUS_LEVEL_UPDATE;
    }
    if temp_c.is_some() {
        status |= STATUS_TEMPERATURE;
    }
    if still_windows_now == 0 {
        status |= STATUS_UNVERIFIED;
    }
    // The range was checked above: the denoiser cannot refuse this sample.
    let denoised_dps = match stage.denoiser.push(rate_dps) {
        Ok(Some(d)) => d,
        _ => f32::NAN,
    };
    if stage.denoiser.filled() == 0 {
        status |= STATUS_BLOCK_DONE;
    }
    (
        Output {
            drift_dps: m.drift_dps,
            compensated_dps: m.compensated_dps,
            denoised_dps,
        },
        status,
    )
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
    out: &Output,
    status: u8,
) -> [u8; SAMPLE_RECORD_LEN] {
    let mut r = [0u8; SAMPLE_RECORD_LEN];
    r[3..7].copy_from_slice(&index.to_le_bytes());
    let values = [
        rate_dps,
        out.drift_dps,
        out.compensated_dps,
        out.denoised_dps,
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
    /// External still-flag commands received ([`Command::Still`], [`Command::Moving`],
    /// [`Command::Auto`]).
    pub still_commands: u32,
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
        t.still_commands,
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

/// An in-band command on the input stream (8 bytes, see [`END_MARKER`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// [`END_MARKER`]: end of input.
    End,
    /// [`STILL_MARKER`]: external still flag `Some(true)` for the frames that follow.
    Still,
    /// [`MOVING_MARKER`]: external still flag `Some(false)` for the frames that follow.
    Moving,
    /// [`AUTO_MARKER`]: no external flag (`None`) for the frames that follow.
    Auto,
}

impl Command {
    /// The external still flag this command sets (`None` for [`Command::End`] too).
    pub fn still_flag(self) -> Option<bool> {
        match self {
            Self::Still => Some(true),
            Self::Moving => Some(false),
            Self::End | Self::Auto => None,
        }
    }
}

/// Watches a byte stream for the 8-byte commands: the last 8 bytes are kept in a shift
/// register and compared with each marker (a few instructions per byte).
#[derive(Debug, Clone, Copy, Default)]
pub struct CommandDetector {
    last8: u64,
    seen: u8,
}

impl CommandDetector {
    /// Feeds one byte; the command it completes, if any. After a command the register
    /// starts empty, so that no two commands share bytes.
    pub fn push(&mut self, byte: u8) -> Option<Command> {
        self.last8 = (self.last8 << 8) | u64::from(byte);
        self.seen = self.seen.saturating_add(1);
        if self.seen < 8 {
            return None;
        }
        let cmd = [
            (END_MARKER, Command::End),
            (STILL_MARKER, Command::Still),
            (MOVING_MARKER, Command::Moving),
            (AUTO_MARKER, Command::Auto),
        ]
        .into_iter()
        .find(|(m, _)| u64::from_be_bytes(*m) == self.last8)
        .map(|(_, c)| c);
        if cmd.is_some() {
            self.seen = 0;
            self.last8 = 0;
        }
        cmd
    }
}
