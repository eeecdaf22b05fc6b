//! The identifier image: a trained [`crate::motion`] identifier as a versioned binary file
//! (train once on the bench, flash the result).
//!
//! Little-endian, fixed layout for format version 3 ([`IMAGE_LEN`] = 584 bytes for
//! `N` = [`MOTION_N`], `L` = [`MOTION_L`]):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `FOGI` |
//! | 4 | 2 | format version (u16, [`FORMAT_VERSION`]) |
//! | 6 | 2 | preset id (u16, 1 = `motion`) |
//! | 8 | 1+1+1+1 | inputs `N`, neurons `L`, activation (0 Gaussian, 1 Mexican hat), 0 |
//! | 12 | 5 x f32 | sensor: full scale dps, quantum dps, sample rate Hz, noise density dps/sqrt(Hz), drift bound dps |
//! | 32 | 5 x f32 | detector: window s, min still s, var_z, mean_k, noise scale |
//! | 52 | f32 | level random-walk density, deg^2/s^3 |
//! | 56 | f32 | model time range, s |
//! | 60 | 2N x f32 | input scaling: offsets, then gains |
//! | 84 | L x 20 | neurons: kind (0 wavelet, 1 bias, 2 linear), linear input, 0, 0, `a[N]` f32, `b` f32 |
//! | 404 | L x f32 | output weights, deg/s |
//! | 468 | 4 x f32 + 4 | trainer (DRLS): lambda, u0, u_max, w_max, mode (0 parallel, 1 sequential), form (0 gain, 1 energy), 0, 0 |
//! | 488 | L x f32 | trainer state (`U` or `S` per weight) |
//! | 552 | u32 | records trained on (passes included) |
//! | 556 | 1+3 | level arrangement ([`Arrangement`]: 4 bank-dual, 5 bank-guarded, 6 dual-thermal; 0 to 3 are refused, [`ImageError::RetiredArrangement`]), 0, 0, 0 |
//! | 560 | 2 x f32 | second state ([`SecondState`]): dual-thermal (6): the temperature coefficient's prior sigma deg/s per deg C (> 0) and 0; bank (4, 5): its `B` deg/s (> 0) and longest correlation time s (1 to 10^4) |
//! | 568 | 3 x f32 | the family's white-noise range as multiples of the sensor's sigma (`noise_lo`, `noise_hi` of [`StillConfig`]), the safety net's time s ([`MotionConfig::stale_s`]) |
//! | 580 | u32 | CRC-32/ISO-HDLC of bytes 0..580 |
//!
//! Version 2 ([`IMAGE_LEN_V2`] = 572 bytes) is version 3 without bytes 568..580 (its CRC at
//! 568): it loads with the noise range 1..1 (the specification) and the default
//! [`MotionConfig::DEFAULT_STALE_S`]. Version 1 (560 bytes, no arrangement byte) ran an
//! arrangement this code no longer runs: it is refused
//! ([`ImageError::RetiredArrangement`]); retrain the image. [`Image::to_bytes`] writes
//! version 3 only.
//!
//! [`Image::parse`] never panics (fuzzed by a proptest) and returns a typed [`ImageError`]:
//! the magic and version are checked first (so that another version's layout is named as
//! such), then the length, the checksum, then the content.

use crate::motion::{MotionConfig, MotionError, MotionModel, MOTION_L, MOTION_N};
use crate::preset::{Arrangement, PresetEstimator, SecondState};
use crate::still::{SensorConfig, StillConfig};
use crate::train::{Drls, DrlsConfig, DrlsForm, DrlsMode};
use crate::wnn::{Activation, Evaluation, Neuron, WnnShape};

/// `FOGI`.
pub const MAGIC: [u8; 4] = *b"FOGI";
/// The format this code writes (it reads this one and version 2).
pub const FORMAT_VERSION: u16 = 3;
/// Preset id of [`crate::motion`].
pub const PRESET_MOTION: u16 = 1;
/// Bytes of a version-3 image.
pub const IMAGE_LEN: usize = 584;
/// Bytes of a version-2 image (still read: module docs).
pub const IMAGE_LEN_V2: usize = 572;
/// A stream's rate may differ from the image's by this fraction (timing of a real unit).
pub const RATE_TOLERANCE: f32 = 0.01;

const CRC_AT: usize = IMAGE_LEN - 4;
/// Offset of the arrangement byte (versions 2 and 3).
const ARRANGEMENT_AT: usize = 556;
/// Offset of the noise range and the safety net's time (version 3).
const FAMILY_AT: usize = 568;

/// Why an image was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImageError {
    /// The first 4 bytes are not `FOGI`.
    BadMagic,
    /// The data ends at this byte offset, before the field that needs it.
    Truncated {
        /// Bytes available.
        offset: usize,
    },
    /// A format version this code does not read.
    UnsupportedVersion(u16),
    /// The image names an arrangement this code no longer runs (window 0, sample 1, dual 2,
    /// bank 3; a version-1 image is window): they lost to the others on every measured
    /// vehicle family (docs/unit-fit.md). Retrain with `host-sim identify`.
    RetiredArrangement(u8),
    /// Bytes after the end of the image (count of them).
    TrailingBytes(usize),
    /// The stored CRC-32 is not that of the content.
    Checksum {
        /// Stored in the image.
        stored: u32,
        /// Computed over the content.
        computed: u32,
    },
    /// A preset this code does not run.
    UnknownPreset(u16),
    /// The layout does not fit this build's network (`N`, `L`, a neuron kind or input,
    /// activation): byte offset of the field.
    Layout {
        /// Byte offset.
        offset: usize,
    },
    /// A value outside its valid range (non-finite, negative, invalid configuration): byte
    /// offset of the field or of its section.
    BadValue {
        /// Byte offset.
        offset: usize,
    },
    /// The image is for another sample rate.
    RateMismatch {
        /// The image's rate, Hz.
        image_hz: f32,
        /// The stream's rate, Hz.
        stream_hz: f32,
    },
    /// The output buffer is shorter than [`IMAGE_LEN`].
    BufferTooSmall,
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BadMagic => f.write_str("not an identifier image (bad magic, expected FOGI)"),
            Self::Truncated { offset } => write!(f, "truncated at byte offset {offset}"),
            Self::UnsupportedVersion(v) => {
                write!(
                    f,
                    "format version {v} unsupported (this build reads 2 to {FORMAT_VERSION})"
                )
            }
            Self::RetiredArrangement(a) => write!(
                f,
                "arrangement {a} ({}) is no longer run: retrain the image with `host-sim identify --preset motion`",
                match a {
                    0 => "window",
                    1 => "sample",
                    2 => "dual",
                    _ => "bank",
                }
            ),
            Self::TrailingBytes(n) => write!(f, "{n} bytes after the end of the image"),
            Self::Checksum { stored, computed } => write!(
                f,
                "checksum mismatch (stored {stored:#010x}, computed {computed:#010x})"
            ),
            Self::UnknownPreset(p) => write!(f, "unknown preset id {p}"),
            Self::Layout { offset } => {
                write!(f, "network layout does not fit N = {MOTION_N}, L = {MOTION_L} (byte offset {offset})")
            }
            Self::BadValue { offset } => write!(f, "invalid value at byte offset {offset}"),
            Self::RateMismatch {
                image_hz,
                stream_hz,
            } => write!(
                f,
                "identifier is for {image_hz} Hz, the record is {stream_hz} Hz"
            ),
            Self::BufferTooSmall => write!(f, "output buffer shorter than {IMAGE_LEN} bytes"),
        }
    }
}

impl core::error::Error for ImageError {}

/// CRC-32/ISO-HDLC (the zlib/PNG CRC) of `bytes`, the image checksum.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// CRC-32/ISO-HDLC (the `crc` crate's catalogue entry: poly 0x04C11DB7 reflected, init and
/// xor-out 0xFFFFFFFF; check value 0xCBF43926).
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// A trained motion identifier: everything the estimator and further training need.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Sensor, detector and level settings.
    pub config: MotionConfig,
    /// The trained network.
    pub model: MotionModel,
    /// The trainer's configuration.
    pub drls: DrlsConfig,
    /// The trainer's per-weight state ([`Drls::state`]).
    pub drls_state: [f32; MOTION_L],
    /// Records trained on (passes included).
    pub records_trained: u32,
    /// How the level learns.
    pub arrangement: Arrangement,
    /// The second state's parameters (the thermal prior or the bank's).
    pub second_state: SecondState,
}

struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) {
        if let Some(dst) = self.out.get_mut(self.at..self.at + b.len()) {
            dst.copy_from_slice(b);
        }
        self.at += b.len();
    }
    fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const K: usize>(&mut self) -> [u8; K] {
        // The length was checked before reading: the fallback is never taken.
        let mut v = [0u8; K];
        if let Some(src) = self.b.get(self.at..self.at + K) {
            v.copy_from_slice(src);
        }
        self.at += K;
        v
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    /// A finite f32, or BadValue at its offset.
    fn f32(&mut self) -> Result<f32, ImageError> {
        let offset = self.at;
        let v = f32::from_le_bytes(self.take());
        if v.is_finite() {
            Ok(v)
        } else {
            Err(ImageError::BadValue { offset })
        }
    }
    /// f32 that may be infinite (DRLS guards), not NaN.
    fn f32_or_inf(&mut self) -> Result<f32, ImageError> {
        let offset = self.at;
        let v = f32::from_le_bytes(self.take());
        if v.is_nan() {
            Err(ImageError::BadValue { offset })
        } else {
            Ok(v)
        }
    }
}

impl Image {
    /// An image of `model` trained by `drls` (state included) for `config`, with the
    /// default arrangement and its default prior ([`Arrangement::DualThermal`],
    /// [`SecondState::THERMAL`]; another: [`Image::with_arrangement`]).
    pub fn new(
        config: MotionConfig,
        model: MotionModel,
        drls: &Drls<MOTION_L>,
        records_trained: u32,
    ) -> Self {
        Self {
            config,
            model,
            drls: *drls.config(),
            drls_state: *drls.state(),
            records_trained,
            arrangement: Arrangement::DualThermal,
            second_state: SecondState::THERMAL,
        }
    }

    /// The same image with `arrangement` and its second state's parameters.
    pub fn with_arrangement(mut self, arrangement: Arrangement, second: SecondState) -> Self {
        self.arrangement = arrangement;
        self.second_state = second;
        self
    }

    /// Writes the image into `out` (at least [`IMAGE_LEN`] bytes); returns the bytes
    /// written.
    pub fn to_bytes(&self, out: &mut [u8]) -> Result<usize, ImageError> {
        if out.len() < IMAGE_LEN {
            return Err(ImageError::BufferTooSmall);
        }
        let mut w = Writer { out, at: 0 };
        w.bytes(&MAGIC);
        w.bytes(&FORMAT_VERSION.to_le_bytes());
        w.bytes(&PRESET_MOTION.to_le_bytes());
        let act = match self.model.shape.activation {
            Activation::Gaussian => 0u8,
            Activation::MexicanHat => 1u8,
        };
        w.bytes(&[MOTION_N as u8, MOTION_L as u8, act, 0]);
        let s = &self.config.sensor;
        for v in [
            s.full_scale_dps,
            s.quantum_dps,
            s.sample_rate_hz,
            s.noise_density_dps_rthz,
            s.drift_bound_dps,
        ] {
            w.f32(v);
        }
        let d = &self.config.still;
        for v in [d.window_s, d.min_still_s, d.var_z, d.mean_k, d.noise_scale] {
            w.f32(v);
        }
        w.f32(self.config.level_q_dps2_per_s);
        w.f32(self.model.time_max_s);
        for v in self
            .model
            .scaling
            .offset
            .iter()
            .chain(&self.model.scaling.gain)
        {
            w.f32(*v);
        }
        let sh = &self.model.shape;
        for l in 0..MOTION_L {
            let (kind, input) = match sh.kind[l] {
                Neuron::Wavelet => (0u8, 0u8),
                Neuron::Bias => (1, 0),
                Neuron::Linear(j) => (2, j),
            };
            w.bytes(&[kind, input, 0, 0]);
            for v in sh.a[l] {
                w.f32(v);
            }
            w.f32(sh.b[l]);
        }
        for v in self.model.weights {
            w.f32(v);
        }
        let t = &self.drls;
        for v in [t.lambda, t.u0, t.u_max, t.w_max] {
            w.f32(v);
        }
        let mode = match t.mode {
            DrlsMode::Parallel => 0u8,
            DrlsMode::Sequential => 1,
        };
        let form = match t.form {
            DrlsForm::Gain => 0u8,
            DrlsForm::Energy => 1,
        };
        w.bytes(&[mode, form, 0, 0]);
        for v in self.drls_state {
            w.f32(v);
        }
        w.bytes(&self.records_trained.to_le_bytes());
        w.bytes(&[self.arrangement.to_byte(), 0, 0, 0]);
        w.f32(self.second_state.sigma);
        w.f32(self.second_state.tau_s);
        w.f32(d.noise_lo);
        w.f32(d.noise_hi);
        w.f32(self.config.stale_s);
        let crc = crc32(w.out.get(..CRC_AT).unwrap_or(&[]));
        w.bytes(&crc.to_le_bytes());
        Ok(w.at)
    }

    /// Reads an image (see the module docs for the order of the checks): the magic, version,
    /// length and checksum here, then each part of the layout, in order, by its `read_*`
    /// function.
    pub fn parse(bytes: &[u8]) -> Result<Self, ImageError> {
        let head = |n: usize| {
            bytes.get(..n).ok_or(ImageError::Truncated {
                offset: bytes.len(),
            })
        };
        // The magic as far as it goes: a short file that is not ours says so.
        let m = bytes.len().min(4);
        if bytes.get(..m) != MAGIC.get(..m) {
            return Err(ImageError::BadMagic);
        }
        let version = Reader { b: head(6)?, at: 4 }.u16();
        let len = match version {
            1 => return Err(ImageError::RetiredArrangement(0)),
            2 => IMAGE_LEN_V2,
            FORMAT_VERSION => IMAGE_LEN,
            _ => return Err(ImageError::UnsupportedVersion(version)),
        };
        let crc_at = len - 4;
        let body = head(len)?;
        if bytes.len() > len {
            return Err(ImageError::TrailingBytes(bytes.len() - len));
        }
        let mut r = Reader { b: body, at: 0 };
        let computed = crc32(body.get(..crc_at).unwrap_or(&[]));
        r.at = crc_at;
        let stored = r.u32();
        if stored != computed {
            return Err(ImageError::Checksum { stored, computed });
        }
        r.at = 6;
        let activation = read_layout(&mut r)?;
        let mut config = read_motion_config(&mut r)?;
        match config.check() {
            Ok(()) => {}
            Err(MotionError::BadLevelNoise) => return Err(ImageError::BadValue { offset: 52 }),
            Err(_) => return Err(ImageError::BadValue { offset: 32 }),
        }
        let mut model = blank_model(activation);
        read_model(&mut r, &mut model)?;
        let drls = read_drls_config(&mut r)?;
        let mut drls_state = [0.0; MOTION_L];
        read_drls_state(&mut r, &mut drls_state)?;
        let records_trained = r.u32();
        let (arrangement, second_state) = read_level(&mut r, config.level_q_dps2_per_s)?;
        if version >= 3 {
            read_family(&mut r, &mut config)?;
        }
        Ok(Self {
            config,
            model,
            drls,
            drls_state,
            records_trained,
            arrangement,
            second_state,
        })
    }

    /// Refuses a stream whose rate differs from the image's by more than
    /// [`RATE_TOLERANCE`].
    pub fn check_rate(&self, stream_hz: f32) -> Result<(), ImageError> {
        let image_hz = self.config.sensor.sample_rate_hz;
        if (stream_hz - image_hz).abs() <= RATE_TOLERANCE * image_hz {
            Ok(())
        } else {
            Err(ImageError::RateMismatch {
                image_hz,
                stream_hz,
            })
        }
    }

    /// The estimator at power-on: the image's arrangement and second state.
    pub fn estimator(&self) -> Result<PresetEstimator, MotionError> {
        PresetEstimator::new(self.model, self.config, self.arrangement, self.second_state)
    }

    /// The trainer's state, to continue training (on line, or on more records).
    pub fn trainer(&self) -> Option<Drls<MOTION_L>> {
        let mut d = Drls::new(self.drls)?;
        d.set_state(&self.drls_state).then_some(d)
    }
}

// The readers of `Image::parse`, one per part of the layout (module docs), each reading
// from where the previous one stopped. They are `#[inline(always)]` and write the arrays in
// place (`&mut`), so that `parse` compiles to one body inlined into the firmware's set-up:
// out of line, or returning the arrays by value, they enlarge the firmware's permanent
// stack frame (stack high-water about 700 bytes higher on mps2-an386) and its flash (up to
// 5 KiB more), measured with `scripts/fw-budget.sh`.

/// Bytes 6..12: the preset and the network layout, which must be this build's; the
/// activation.
#[inline(always)]
fn read_layout(r: &mut Reader<'_>) -> Result<Activation, ImageError> {
    let preset = r.u16();
    if preset != PRESET_MOTION {
        return Err(ImageError::UnknownPreset(preset));
    }
    if usize::from(r.u8()) != MOTION_N {
        return Err(ImageError::Layout { offset: 8 });
    }
    if usize::from(r.u8()) != MOTION_L {
        return Err(ImageError::Layout { offset: 9 });
    }
    let activation = match r.u8() {
        0 => Activation::Gaussian,
        1 => Activation::MexicanHat,
        _ => return Err(ImageError::Layout { offset: 10 }),
    };
    r.u8();
    Ok(activation)
}

/// Bytes 12..56: the sensor (checked), the detector and the level noise (for the caller to
/// check with [`MotionConfig::check`]); the noise range 1..1 and the default safety-net time
/// (a version-3 image's: [`read_family`]).
#[inline(always)]
fn read_motion_config(r: &mut Reader<'_>) -> Result<MotionConfig, ImageError> {
    let sensor = SensorConfig {
        full_scale_dps: r.f32()?,
        quantum_dps: r.f32()?,
        sample_rate_hz: r.f32()?,
        noise_density_dps_rthz: r.f32()?,
        drift_bound_dps: r.f32()?,
    };
    if !sensor.is_valid() {
        return Err(ImageError::BadValue { offset: 12 });
    }
    let still = StillConfig {
        window_s: r.f32()?,
        min_still_s: r.f32()?,
        var_z: r.f32()?,
        mean_k: r.f32()?,
        noise_scale: r.f32()?,
        noise_lo: 1.0,
        noise_hi: 1.0,
    };
    Ok(MotionConfig {
        sensor,
        still,
        level_q_dps2_per_s: r.f32()?,
        stale_s: MotionConfig::DEFAULT_STALE_S,
    })
}

/// A model of `activation` with every number 0, for [`read_model`] to fill.
#[inline(always)]
fn blank_model(activation: Activation) -> MotionModel {
    MotionModel {
        shape: WnnShape {
            a: [[0.0; MOTION_N]; MOTION_L],
            b: [0.0; MOTION_L],
            activation,
            kind: [Neuron::Wavelet; MOTION_L],
            evaluation: Evaluation::Direct,
        },
        scaling: crate::wnn::InputScaling::IDENTITY,
        time_max_s: 0.0,
        weights: [0.0; MOTION_L],
    }
}

/// Bytes 56..468 into `model`: its time range (s, > 0), input scaling, neurons and output
/// weights (deg/s).
#[inline(always)]
fn read_model(r: &mut Reader<'_>, model: &mut MotionModel) -> Result<(), ImageError> {
    let time_at = r.at;
    let time_max_s = r.f32()?;
    if time_max_s <= 0.0 {
        return Err(ImageError::BadValue { offset: time_at });
    }
    model.time_max_s = time_max_s;
    for offset in model.scaling.offset.iter_mut() {
        *offset = r.f32()?;
    }
    for gain in model.scaling.gain.iter_mut() {
        *gain = r.f32()?;
    }
    let shape = &mut model.shape;
    for ((kind, a), b) in shape.kind.iter_mut().zip(&mut shape.a).zip(&mut shape.b) {
        let at = r.at;
        let [k, input, _, _] = r.take::<4>();
        *kind = match k {
            0 => Neuron::Wavelet,
            1 => Neuron::Bias,
            2 if usize::from(input) < MOTION_N => Neuron::Linear(input),
            _ => return Err(ImageError::Layout { offset: at }),
        };
        for a_j in a.iter_mut() {
            *a_j = r.f32()?;
        }
        *b = r.f32()?;
    }
    for w in model.weights.iter_mut() {
        *w = r.f32()?;
    }
    Ok(())
}

/// Bytes 468..488: the trainer's configuration, checked.
#[inline(always)]
fn read_drls_config(r: &mut Reader<'_>) -> Result<DrlsConfig, ImageError> {
    let drls_at = r.at;
    let (lambda, u0) = (r.f32()?, r.f32()?);
    let (u_max, w_max) = (r.f32_or_inf()?, r.f32_or_inf()?);
    let [mode, form, _, _] = r.take::<4>();
    let drls = DrlsConfig {
        lambda,
        u0,
        u_max,
        w_max,
        mode: match mode {
            0 => DrlsMode::Parallel,
            1 => DrlsMode::Sequential,
            _ => {
                return Err(ImageError::BadValue {
                    offset: drls_at + 16,
                })
            }
        },
        form: match form {
            0 => DrlsForm::Gain,
            1 => DrlsForm::Energy,
            _ => {
                return Err(ImageError::BadValue {
                    offset: drls_at + 17,
                })
            }
        },
    };
    if drls.is_valid() {
        Ok(drls)
    } else {
        Err(ImageError::BadValue { offset: drls_at })
    }
}

/// Bytes 488..552 into `state`: the trainer's state, each value > 0.
#[inline(always)]
fn read_drls_state(r: &mut Reader<'_>, state: &mut [f32; MOTION_L]) -> Result<(), ImageError> {
    for v in state.iter_mut() {
        let at = r.at;
        *v = r.f32()?;
        if *v <= 0.0 {
            return Err(ImageError::BadValue { offset: at });
        }
    }
    Ok(())
}

/// Bytes 556..568: the level arrangement and its second state, checked (a bank's against
/// the level noise `level_q_dps2_per_s`, deg^2/s^3).
#[inline(always)]
fn read_level(
    r: &mut Reader<'_>,
    level_q_dps2_per_s: f32,
) -> Result<(Arrangement, SecondState), ImageError> {
    let [a, _, _, _] = r.take::<4>();
    let arrangement = match Arrangement::from_byte(a) {
        Some(arrangement) => arrangement,
        None if a <= 3 => return Err(ImageError::RetiredArrangement(a)),
        None => {
            return Err(ImageError::BadValue {
                offset: ARRANGEMENT_AT,
            })
        }
    };
    let second_state = SecondState {
        sigma: r.f32()?,
        tau_s: r.f32()?,
    };
    if !second_state.is_valid_for(arrangement)
        || (arrangement.is_bank() && !second_state.bank(level_q_dps2_per_s).is_valid())
    {
        return Err(ImageError::BadValue {
            offset: ARRANGEMENT_AT + 4,
        });
    }
    Ok((arrangement, second_state))
}

/// Bytes 568..580 (version 3) into `config`: the family's noise range and the safety net's
/// time (s), checked.
#[inline(always)]
fn read_family(r: &mut Reader<'_>, config: &mut MotionConfig) -> Result<(), ImageError> {
    config.still.noise_lo = r.f32()?;
    config.still.noise_hi = r.f32()?;
    if !config.still.is_valid() {
        return Err(ImageError::BadValue { offset: FAMILY_AT });
    }
    config.stale_s = r.f32()?;
    if config.check().is_err() {
        return Err(ImageError::BadValue {
            offset: FAMILY_AT + 8,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::{MotionTrainer, MOTION_DRLS};
    use proptest::prelude::*;

    fn sample() -> Image {
        let mut model = MotionModel::standard(1800.0).expect("test");
        for (l, w) in model.weights.iter_mut().enumerate() {
            *w = l as f32 * 1.0e-5 - 3.0e-5;
        }
        let tr = MotionTrainer::new(model, MOTION_DRLS, 1.0).expect("test");
        let mut config = MotionConfig::for_sensor(SensorConfig::ECORE_2000);
        config.still.noise_lo = 0.8;
        config.still.noise_hi = 1.7;
        config.stale_s = 300.0;
        Image::new(config, model, tr.drls(), 12).with_arrangement(
            Arrangement::DualThermal,
            SecondState {
                sigma: 3.0 / 3600.0,
                tau_s: 0.0,
            },
        )
    }

    /// The version-1 image of the same content: bytes 0..556 with version 1, and its CRC.
    fn bytes_v1(img: &Image) -> [u8; 560] {
        let b = bytes(img);
        let mut v1 = [0u8; 560];
        v1[..556].copy_from_slice(&b[..556]);
        v1[4..6].copy_from_slice(&1u16.to_le_bytes());
        let crc = crc32(&v1[..556]);
        v1[556..].copy_from_slice(&crc.to_le_bytes());
        v1
    }

    /// The version-2 image of the same content: bytes 0..568 with version 2, and its CRC.
    fn bytes_v2(img: &Image) -> [u8; IMAGE_LEN_V2] {
        let b = bytes(img);
        let mut v2 = [0u8; IMAGE_LEN_V2];
        v2[..FAMILY_AT].copy_from_slice(&b[..FAMILY_AT]);
        v2[4..6].copy_from_slice(&2u16.to_le_bytes());
        let crc = crc32(&v2[..FAMILY_AT]);
        v2[FAMILY_AT..].copy_from_slice(&crc.to_le_bytes());
        v2
    }

    #[test]
    fn version_2_loads_with_the_specification_and_the_default_safety_net() {
        let img = sample();
        let back = Image::parse(&bytes_v2(&img)).expect("test");
        assert_eq!(back.config.still.noise_lo, 1.0);
        assert_eq!(back.config.still.noise_hi, 1.0);
        assert_eq!(back.config.stale_s, MotionConfig::DEFAULT_STALE_S);
        assert_eq!(back.model, img.model);
        assert_eq!(back.arrangement, img.arrangement);
        // A bad noise range or time in a version-3 image: BadValue at its offset.
        for (at, v, want) in [
            (FAMILY_AT, 0.0f32, FAMILY_AT),
            (FAMILY_AT + 4, 0.5, FAMILY_AT),
            (FAMILY_AT + 8, -1.0, FAMILY_AT + 8),
        ] {
            let c = patched(bytes(&img), at, v.to_le_bytes());
            assert_eq!(
                Image::parse(&c),
                Err(ImageError::BadValue { offset: want }),
                "{at}"
            );
        }
    }

    /// `b` with `v` at `at` and its CRC made valid again.
    fn patched(mut b: [u8; IMAGE_LEN], at: usize, v: [u8; 4]) -> [u8; IMAGE_LEN] {
        b[at..at + 4].copy_from_slice(&v);
        let crc = crc32(&b[..CRC_AT]);
        b[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    fn bytes(img: &Image) -> [u8; IMAGE_LEN] {
        let mut b = [0u8; IMAGE_LEN];
        assert_eq!(img.to_bytes(&mut b), Ok(IMAGE_LEN));
        b
    }

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn round_trip() {
        let img = sample();
        let b = bytes(&img);
        let back = Image::parse(&b).expect("test");
        assert_eq!(back, img);
        assert_eq!(bytes(&back), b);
        assert!(back.trainer().is_some());
        assert!(back.estimator().is_ok());
        assert!(back.check_rate(100.0).is_ok());
        assert!(matches!(
            back.check_rate(1000.0),
            Err(ImageError::RateMismatch { .. })
        ));
        let mut small = [0u8; IMAGE_LEN - 1];
        assert_eq!(img.to_bytes(&mut small), Err(ImageError::BufferTooSmall));
        assert_eq!(
            back.estimator().map(|e| e.arrangement()),
            Ok(Arrangement::DualThermal)
        );
    }

    #[test]
    fn retired_arrangements_and_version_1_are_refused_by_name() {
        let img = sample();
        assert_eq!(
            Image::parse(&bytes_v1(&img)),
            Err(ImageError::RetiredArrangement(0))
        );
        for a in 0u8..=3 {
            let mut c = bytes(&img);
            c[ARRANGEMENT_AT] = a;
            let crc = crc32(&c[..CRC_AT]);
            c[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
            let e = Image::parse(&c);
            assert_eq!(e, Err(ImageError::RetiredArrangement(a)));
            extern crate std;
            let msg = std::format!("{}", ImageError::RetiredArrangement(a));
            assert!(msg.contains("retrain"), "{msg}");
        }
    }

    #[test]
    fn loaded_image_runs_bit_for_bit() {
        let img = sample();
        let back = Image::parse(&bytes(&img)).expect("test");
        let mut a = img.estimator().expect("test");
        let mut b = back.estimator().expect("test");
        for k in 0..5000u32 {
            let x = 1.0e-3 * ((k as f32) * 0.37).sin() + if k > 3000 { 2.0 } else { 0.0 };
            let t = 25.0 + k as f32 * 1.0e-3;
            let (ya, yb) = (a.push(x, t, None), b.push(x, t, None));
            assert_eq!(
                ya.map(|o| o.drift_dps.to_bits()),
                yb.map(|o| o.drift_dps.to_bits())
            );
        }
    }

    #[test]
    fn every_single_byte_flip_is_rejected() {
        let b = bytes(&sample());
        for i in 0..IMAGE_LEN {
            for flip in [0x01u8, 0x80, 0xFF] {
                let mut c = b;
                c[i] ^= flip;
                assert!(Image::parse(&c).is_err(), "byte {i} ^ {flip:#x} accepted");
            }
        }
    }

    #[test]
    fn every_truncation_is_rejected() {
        let b = bytes(&sample());
        for n in 0..IMAGE_LEN {
            match Image::parse(&b[..n]) {
                Err(ImageError::Truncated { offset }) => assert_eq!(offset, n),
                other => panic!("{n}: {other:?}"),
            }
        }
        let mut long = [0u8; IMAGE_LEN + 3];
        long[..IMAGE_LEN].copy_from_slice(&b);
        assert_eq!(Image::parse(&long), Err(ImageError::TrailingBytes(3)));
    }

    #[test]
    fn typed_errors() {
        let b = bytes(&sample());
        let mut c = b;
        c[0] = b'X';
        assert_eq!(Image::parse(&c), Err(ImageError::BadMagic));
        let mut c = b;
        c[4] = 4;
        assert_eq!(Image::parse(&c), Err(ImageError::UnsupportedVersion(4)));
        let mut c = b;
        c[100] ^= 1;
        assert!(matches!(Image::parse(&c), Err(ImageError::Checksum { .. })));
        // A layout error behind a valid checksum.
        let mut c = b;
        c[9] = 30;
        let crc = crc32(&c[..CRC_AT]);
        c[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Image::parse(&c), Err(ImageError::Layout { offset: 9 }));
        // A NaN weight behind a valid checksum.
        let mut c = b;
        c[404..408].copy_from_slice(&f32::NAN.to_le_bytes());
        let crc = crc32(&c[..CRC_AT]);
        c[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Image::parse(&c), Err(ImageError::BadValue { offset: 404 }));
        // An unknown arrangement, a NaN and a negative Gauss-Markov value behind a valid
        // checksum.
        for (at, v, want) in [
            (ARRANGEMENT_AT, [7u8, 0, 0, 0], ARRANGEMENT_AT),
            (560, f32::NAN.to_le_bytes(), 560),
            (564, (-1.0f32).to_le_bytes(), 560),
            (560, 0.0f32.to_le_bytes(), 560),
        ] {
            let c = patched(b, at, v);
            assert_eq!(
                Image::parse(&c),
                Err(ImageError::BadValue { offset: want }),
                "{at}"
            );
        }
        // The dual-thermal: its prior sigma with tau 0 is valid (round trip), a tau is not.
        let th = sample().with_arrangement(Arrangement::DualThermal, SecondState::THERMAL);
        let back = Image::parse(&bytes(&th)).expect("dual-thermal image");
        assert_eq!(back, th);
        assert_eq!(
            back.estimator().map(|e| e.arrangement()),
            Ok(Arrangement::DualThermal)
        );
        let c = patched(bytes(&th), 564, 4.0f32.to_le_bytes());
        assert_eq!(Image::parse(&c), Err(ImageError::BadValue { offset: 560 }));
        // Each bank arrangement with a longest correlation time below 1 s, then valid.
        for a in [Arrangement::BankDual, Arrangement::BankGuarded] {
            let mut c = b;
            c[ARRANGEMENT_AT] = a.to_byte();
            c[564..568].copy_from_slice(&0.5f32.to_le_bytes());
            let crc = crc32(&c[..CRC_AT]);
            c[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
            assert_eq!(Image::parse(&c), Err(ImageError::BadValue { offset: 560 }));
            c[564..568].copy_from_slice(&1000.0f32.to_le_bytes());
            let crc = crc32(&c[..CRC_AT]);
            c[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
            let bank = Image::parse(&c).expect("a valid bank image");
            assert_eq!(bank.arrangement, a);
            assert_eq!(bank.estimator().map(|e| e.arrangement()), Ok(a));
        }
    }

    proptest! {
        #[test]
        fn parse_never_panics(data in proptest::collection::vec(any::<u8>(), 0..700)) {
            let _ = Image::parse(&data);
        }

        #[test]
        fn parse_never_panics_near_valid_v1(i in 0usize..560, v in any::<u8>(), cut in 0usize..=560) {
            let mut b = bytes_v1(&sample());
            b[i] = v;
            let crc = crc32(&b[..556]);
            b[556..].copy_from_slice(&crc.to_le_bytes());
            let _ = Image::parse(&b[..cut]);
        }

        #[test]
        fn parse_never_panics_near_valid(i in 0usize..IMAGE_LEN, v in any::<u8>(), cut in 0usize..=IMAGE_LEN) {
            let mut b = bytes(&sample());
            b[i] = v;
            let crc = crc32(&b[..CRC_AT]);
            b[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
            let _ = Image::parse(&b[..cut]);
        }
    }
}
