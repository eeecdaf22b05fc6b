//! The drift image: a fitted [`GyroModel`] and its [`DriftFilterConfig`] as a versioned
//! binary file (`host-sim identify` fits the model on calibration runs, the firmware loads
//! the result and runs [`DriftFilter`]).
//!
//! Little-endian, fixed layout for format version 5 ([`IMAGE_LEN`] = 128 bytes for
//! [`MAX_MARKOV`] = 3): the header, every field of [`GyroModel`] in declaration order (a
//! Gauss-Markov term as sigma, tau; a [`Spread`] as mean, sigma), every field of
//! [`DriftFilterConfig`] in declaration order, the sensor's full scale, the calibration runs,
//! and the checksum last:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `FOGI` ([`MAGIC`]) |
//! | 4 | 2 | format version (u16, [`FORMAT_VERSION`]) |
//! | 6 | 2 | preset id (u16, [`PRESET_DRIFT_FILTER`] = 2) |
//! | 8 | 12 | model, 3 x f32: sample rate Hz, white noise deg/s/sqrt(Hz), quantum deg/s |
//! | 20 | 24 | model, [`MAX_MARKOV`] x 2 x f32: Gauss-Markov terms, each sigma deg/s, tau s |
//! | 44 | 4 | model, f32: rate random walk deg/s/sqrt(s) |
//! | 48 | 8 | model, 2 x f32: turn-on bias mean, sigma deg/s |
//! | 56 | 8 | model, 2 x f32: warm-up amplitude mean, sigma deg/s |
//! | 64 | 8 | model, 2 x f32: warm-up time constant least, largest s |
//! | 72 | 4 | model, f32: temperature reference deg C |
//! | 76 | 8 | model, 2 x f32: temperature link mean, sigma deg/s per deg C |
//! | 84 | 8 | model, 2 x f32: temperature-rate link mean, sigma deg/s per (deg C/s) |
//! | 92 | 4 | model, f32: drift bound deg/s |
//! | 96 | 12 | filter, 3 x f32: window s, NIS limit, resolved rate deg/s |
//! | 108 | 4 | filter, u32: learning windows |
//! | 112 | 4 | filter, f32: temperature-rate time constant s |
//! | 116 | 4 | f32: sensor full scale deg/s (> 0) |
//! | 120 | 4 | u32: calibration runs the model was fitted on |
//! | 124 | 4 | u32: CRC-32/ISO-HDLC ([`crc32`]) of bytes 0..124 |
//!
//! Versions 1 to 3 held the retired dual-thermal and bank estimators with the wavelet
//! network, version 4 the drift filter with one known warm-up time constant: they are
//! refused by name ([`ImageError::RetiredFormat`]); retrain with `host-sim identify`.
//! [`Image::to_bytes`] writes version 5 only, and only an image
//! that [`Image::parse`] accepts.
//!
//! [`Image::parse`] never panics (fuzzed by a proptest) and returns a typed
//! [`ImageError`]: the magic and version are checked first (so that another version's
//! layout is named as such), then the length, the checksum, then the content (the preset,
//! then the values). An image it accepts builds its filter ([`Image::filter`]).

use crate::drift_filter::{DriftFilter, DriftFilterConfig, DriftFilterError};
use crate::gyro_model::{GyroModel, MarkovTerm, Spread, MAX_MARKOV};
/// `FOGI`.
pub const MAGIC: [u8; 4] = *b"FOGI";
/// A stream's rate may differ from the image's by this fraction (timing of a real unit).
pub const RATE_TOLERANCE: f32 = 0.01;

/// CRC-32/ISO-HDLC (the zlib/PNG CRC) of `bytes`, the image checksum.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// CRC-32/ISO-HDLC (the `crc` crate's catalogue entry: poly 0x04C11DB7 reflected, init and
/// xor-out 0xFFFFFFFF; check value 0xCBF43926).
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// The format this code writes and reads.
pub const FORMAT_VERSION: u16 = 5;
/// Preset id of [`crate::drift_filter`] (1 was the retired motion identifier).
pub const PRESET_DRIFT_FILTER: u16 = 2;
/// Bytes of a version-5 image.
pub const IMAGE_LEN: usize = 128;

/// Offset of the model (after the 8-byte header).
const MODEL_AT: usize = 8;
/// Offset of the filter configuration.
const CONFIG_AT: usize = 96;
/// Offset of the full scale.
const FULL_SCALE_AT: usize = 116;
/// Offset of the calibration runs.
const RUNS_AT: usize = 120;
/// Offset of the checksum.
const CRC_AT: usize = IMAGE_LEN - 4;

// The layout counts 16 + 2 MAX_MARKOV words of model: another MAX_MARKOV is another format
// (a new version and table), not a silent change of this one.
const _: () = assert!(
    MODEL_AT + 4 * (16 + 2 * MAX_MARKOV) == CONFIG_AT
        && CONFIG_AT + 4 * 5 == FULL_SCALE_AT
        && FULL_SCALE_AT + 4 == RUNS_AT
        && RUNS_AT + 4 == CRC_AT
);

/// Why a drift image was refused.
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
    /// A format version 1 to 4: the identifier images of the retired dual-thermal and bank
    /// estimators with the wavelet network (1 to 3), the drift filter with one known warm-up
    /// time constant (4). Retrain with `host-sim identify`.
    RetiredFormat(u16),
    /// Any other format version this code does not read.
    UnsupportedVersion(u16),
    /// Bytes after the end of the image (count of them).
    TrailingBytes(usize),
    /// The stored CRC-32 is not that of the content.
    BadChecksum {
        /// Stored in the image.
        stored: u32,
        /// Computed over the content.
        computed: u32,
    },
    /// The image is for another preset than [`PRESET_DRIFT_FILTER`].
    WrongPreset(u16),
    /// The model, the configuration or the full scale is invalid (a value not finite,
    /// [`GyroModel::is_valid`] or [`DriftFilterConfig::is_valid`] false, a full scale not
    /// > 0, a window of fewer than 2 samples): no filter can be built from it.
    BadModel,
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
            Self::BadMagic => f.write_str("not a drift image (bad magic, expected FOGI)"),
            Self::Truncated { offset } => write!(f, "truncated at byte offset {offset}"),
            Self::RetiredFormat(v) if *v >= 4 => write!(
                f,
                "format version {v} held the drift filter with one known warm-up time constant (this build reads {FORMAT_VERSION}): retrain with `host-sim identify`"
            ),
            Self::RetiredFormat(v) => write!(
                f,
                "format version {v} held the retired dual-thermal/bank estimators with the wavelet network: retrain with `host-sim identify`"
            ),
            Self::UnsupportedVersion(v) => write!(
                f,
                "format version {v} unsupported (this build reads {FORMAT_VERSION})"
            ),
            Self::TrailingBytes(n) => write!(f, "{n} bytes after the end of the image"),
            Self::BadChecksum { stored, computed } => write!(
                f,
                "checksum mismatch (stored {stored:#010x}, computed {computed:#010x})"
            ),
            Self::WrongPreset(p) => write!(
                f,
                "preset id {p} is not the drift filter ({PRESET_DRIFT_FILTER})"
            ),
            Self::BadModel => f.write_str("invalid gyro model, filter configuration or full scale"),
            Self::RateMismatch {
                image_hz,
                stream_hz,
            } => write!(
                f,
                "drift image is for {image_hz} Hz, the record is {stream_hz} Hz"
            ),
            Self::BufferTooSmall => {
                write!(f, "output buffer shorter than {IMAGE_LEN} bytes")
            }
        }
    }
}

impl core::error::Error for ImageError {}

/// A fitted gyro model with everything its filter needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Image {
    /// The gyro model.
    pub model: GyroModel,
    /// How its filter runs.
    pub config: DriftFilterConfig,
    /// The sensor's largest rate, deg/s (> 0).
    pub full_scale_dps: f32,
    /// Calibration runs the model was fitted on.
    pub trained_runs: u32,
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
    fn spread(&mut self, s: Spread) {
        self.f32(s.mean);
        self.f32(s.sigma);
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
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    /// Any f32 (checked as a whole afterwards, [`Image::check`]).
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    fn spread(&mut self) -> Spread {
        Spread {
            mean: self.f32(),
            sigma: self.f32(),
        }
    }
}

impl Image {
    /// Writes the image into `out` (at least [`IMAGE_LEN`] bytes); returns the bytes
    /// written. An image [`Image::parse`] would refuse is not written
    /// ([`ImageError::BadModel`]).
    pub fn to_bytes(&self, out: &mut [u8]) -> Result<usize, ImageError> {
        if out.len() < IMAGE_LEN {
            return Err(ImageError::BufferTooSmall);
        }
        self.check()?;
        let mut w = Writer { out, at: 0 };
        w.bytes(&MAGIC);
        w.bytes(&FORMAT_VERSION.to_le_bytes());
        w.bytes(&PRESET_DRIFT_FILTER.to_le_bytes());
        let m = &self.model;
        w.f32(m.sample_rate_hz);
        w.f32(m.white_dps_rthz);
        w.f32(m.quantum_dps);
        for t in m.markov {
            w.f32(t.sigma_dps);
            w.f32(t.tau_s);
        }
        w.f32(m.rrw_dps_per_s_rthz);
        w.spread(m.turn_on_dps);
        w.spread(m.warmup_dps);
        w.f32(m.warmup_tau_min_s);
        w.f32(m.warmup_tau_max_s);
        w.f32(m.temp_ref_c);
        w.spread(m.temp_dps_per_c);
        w.spread(m.temp_rate_dps_per_c_per_s);
        w.f32(m.drift_bound_dps);
        let c = &self.config;
        w.f32(c.window_s);
        w.f32(c.nis_limit);
        w.f32(c.resolve_dps);
        w.bytes(&c.learn_windows.to_le_bytes());
        w.f32(c.temp_rate_tau_s);
        w.f32(self.full_scale_dps);
        w.bytes(&self.trained_runs.to_le_bytes());
        let crc = crc32(w.out.get(..CRC_AT).unwrap_or(&[]));
        w.bytes(&crc.to_le_bytes());
        Ok(w.at)
    }

    /// Reads an image (see the module docs for the order of the checks).
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
        match version {
            1..=4 => return Err(ImageError::RetiredFormat(version)),
            FORMAT_VERSION => {}
            _ => return Err(ImageError::UnsupportedVersion(version)),
        }
        let body = head(IMAGE_LEN)?;
        if bytes.len() > IMAGE_LEN {
            return Err(ImageError::TrailingBytes(bytes.len() - IMAGE_LEN));
        }
        let mut r = Reader {
            b: body,
            at: CRC_AT,
        };
        let stored = r.u32();
        let computed = crc32(body.get(..CRC_AT).unwrap_or(&[]));
        if stored != computed {
            return Err(ImageError::BadChecksum { stored, computed });
        }
        r.at = 6;
        let preset = r.u16();
        if preset != PRESET_DRIFT_FILTER {
            return Err(ImageError::WrongPreset(preset));
        }
        let sample_rate_hz = r.f32();
        let white_dps_rthz = r.f32();
        let quantum_dps = r.f32();
        let mut markov = [MarkovTerm::default(); MAX_MARKOV];
        for t in markov.iter_mut() {
            t.sigma_dps = r.f32();
            t.tau_s = r.f32();
        }
        let model = GyroModel {
            sample_rate_hz,
            white_dps_rthz,
            quantum_dps,
            markov,
            rrw_dps_per_s_rthz: r.f32(),
            turn_on_dps: r.spread(),
            warmup_dps: r.spread(),
            warmup_tau_min_s: r.f32(),
            warmup_tau_max_s: r.f32(),
            temp_ref_c: r.f32(),
            temp_dps_per_c: r.spread(),
            temp_rate_dps_per_c_per_s: r.spread(),
            drift_bound_dps: r.f32(),
        };
        let config = DriftFilterConfig {
            window_s: r.f32(),
            nis_limit: r.f32(),
            resolve_dps: r.f32(),
            learn_windows: r.u32(),
            temp_rate_tau_s: r.f32(),
        };
        let image = Self {
            model,
            config,
            full_scale_dps: r.f32(),
            trained_runs: r.u32(),
        };
        image.check()?;
        Ok(image)
    }

    /// Every value finite (an absent Gauss-Markov term's `tau` too, which
    /// [`GyroModel::is_valid`] does not look at), the full scale > 0, and a filter that
    /// builds (valid model and configuration, a window of at least 2 samples).
    fn check(&self) -> Result<(), ImageError> {
        let taus_finite = self.model.markov.iter().all(|t| t.tau_s.is_finite());
        let full_scale = self.full_scale_dps > 0.0 && self.full_scale_dps.is_finite();
        if taus_finite && full_scale && DriftFilter::check(&self.model, &self.config).is_ok() {
            Ok(())
        } else {
            Err(ImageError::BadModel)
        }
    }

    /// Refuses a stream whose rate differs from the model's by more than
    /// [`RATE_TOLERANCE`].
    pub fn check_rate(&self, stream_hz: f32) -> Result<(), ImageError> {
        let image_hz = self.model.sample_rate_hz;
        if (stream_hz - image_hz).abs() <= RATE_TOLERANCE * image_hz {
            Ok(())
        } else {
            Err(ImageError::RateMismatch {
                image_hz,
                stream_hz,
            })
        }
    }

    /// The model's filter at power-on.
    pub fn filter(&self) -> Result<DriftFilter, DriftFilterError> {
        DriftFilter::new(self.model, self.config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gyro_model::tests::ecore_like;
    use proptest::prelude::*;

    extern crate std;

    fn sample() -> Image {
        let mut model = ecore_like();
        // A present third term and nonzero means: every field distinct and nonzero.
        model.markov[2] = MarkovTerm {
            sigma_dps: 0.5 / 3600.0,
            tau_s: 20.0,
        };
        model.turn_on_dps.mean = 3.0 / 3600.0;
        model.warmup_dps.mean = -2.0 / 3600.0;
        model.warmup_tau_min_s = 150.0;
        model.warmup_tau_max_s = 1500.0;
        model.temp_rate_dps_per_c_per_s = Spread {
            mean: 1.0e-4,
            sigma: 2.0e-4,
        };
        Image {
            model,
            config: DriftFilterConfig {
                learn_windows: 12,
                ..DriftFilterConfig::default()
            },
            full_scale_dps: 490.0,
            trained_runs: 37,
        }
    }

    fn bytes(img: &Image) -> [u8; IMAGE_LEN] {
        let mut b = [0u8; IMAGE_LEN];
        assert_eq!(img.to_bytes(&mut b), Ok(IMAGE_LEN));
        b
    }

    /// `b` with its CRC made valid again.
    fn recrc(mut b: [u8; IMAGE_LEN]) -> [u8; IMAGE_LEN] {
        let crc = crc32(&b[..CRC_AT]);
        b[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// `b` with `v` at `at` and its CRC made valid again.
    fn patched(mut b: [u8; IMAGE_LEN], at: usize, v: [u8; 4]) -> [u8; IMAGE_LEN] {
        b[at..at + 4].copy_from_slice(&v);
        recrc(b)
    }

    fn f32_at(b: &[u8], at: usize) -> f32 {
        f32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
    }

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
    }

    /// Every f32 of an image, in layout order, as bits.
    fn f32_bits(img: &Image) -> std::vec::Vec<u32> {
        let m = &img.model;
        let c = &img.config;
        let mut v = std::vec![m.sample_rate_hz, m.white_dps_rthz, m.quantum_dps];
        for t in m.markov {
            v.extend([t.sigma_dps, t.tau_s]);
        }
        v.extend([
            m.rrw_dps_per_s_rthz,
            m.turn_on_dps.mean,
            m.turn_on_dps.sigma,
            m.warmup_dps.mean,
            m.warmup_dps.sigma,
            m.warmup_tau_min_s,
            m.warmup_tau_max_s,
            m.temp_ref_c,
            m.temp_dps_per_c.mean,
            m.temp_dps_per_c.sigma,
            m.temp_rate_dps_per_c_per_s.mean,
            m.temp_rate_dps_per_c_per_s.sigma,
            m.drift_bound_dps,
            c.window_s,
            c.nis_limit,
            c.resolve_dps,
            c.temp_rate_tau_s,
            img.full_scale_dps,
        ]);
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// The module docs' layout table: (offset, size) of each row.
    fn doc_table() -> std::vec::Vec<(usize, usize)> {
        include_str!("image.rs")
            .lines()
            .filter_map(|l| l.strip_prefix("//! | "))
            .filter_map(|row| {
                let mut cells = row.split(" | ");
                let offset = cells.next()?.trim().parse().ok()?;
                let size = cells.next()?.trim().parse().ok()?;
                Some((offset, size))
            })
            .collect()
    }

    #[test]
    fn doc_table_adds_up_to_the_length() {
        let rows = doc_table();
        assert_eq!(rows.len(), 19, "{rows:?}");
        let mut at = 0;
        for &(offset, size) in &rows {
            assert_eq!(
                offset, at,
                "row at {offset} does not follow the previous one"
            );
            at += size;
        }
        assert_eq!(at, IMAGE_LEN);
        for want in [MODEL_AT, CONFIG_AT, FULL_SCALE_AT, RUNS_AT, CRC_AT] {
            assert!(
                rows.iter().any(|&(o, _)| o == want),
                "{want} not in the table"
            );
        }
    }

    #[test]
    fn fields_sit_at_their_documented_offsets() {
        let img = sample();
        let b = bytes(&img);
        let m = &img.model;
        assert_eq!(&b[0..4], b"FOGI");
        assert_eq!(u16::from_le_bytes([b[4], b[5]]), 5);
        assert_eq!(u16::from_le_bytes([b[6], b[7]]), 2);
        assert_eq!(f32_at(&b, 8), m.sample_rate_hz);
        assert_eq!(f32_at(&b, 16), m.quantum_dps);
        assert_eq!(f32_at(&b, 20), m.markov[0].sigma_dps);
        assert_eq!(f32_at(&b, 40), m.markov[2].tau_s);
        assert_eq!(f32_at(&b, 44), m.rrw_dps_per_s_rthz);
        assert_eq!(f32_at(&b, 48), m.turn_on_dps.mean);
        assert_eq!(f32_at(&b, 56), m.warmup_dps.mean);
        assert_eq!(f32_at(&b, 64), m.warmup_tau_min_s);
        assert_eq!(f32_at(&b, 68), m.warmup_tau_max_s);
        assert_eq!(f32_at(&b, 72), m.temp_ref_c);
        assert_eq!(f32_at(&b, 80), m.temp_dps_per_c.sigma);
        assert_eq!(f32_at(&b, 84), m.temp_rate_dps_per_c_per_s.mean);
        assert_eq!(f32_at(&b, 92), m.drift_bound_dps);
        assert_eq!(f32_at(&b, CONFIG_AT), img.config.window_s);
        assert_eq!(f32_at(&b, 104), img.config.resolve_dps);
        assert_eq!(u32_at(&b, 108), img.config.learn_windows);
        assert_eq!(f32_at(&b, 112), img.config.temp_rate_tau_s);
        assert_eq!(f32_at(&b, FULL_SCALE_AT), img.full_scale_dps);
        assert_eq!(u32_at(&b, RUNS_AT), img.trained_runs);
        assert_eq!(u32_at(&b, CRC_AT), crc32(&b[..CRC_AT]));
    }

    #[test]
    fn round_trip_is_bit_for_bit() {
        let img = sample();
        let b = bytes(&img);
        let back = Image::parse(&b).expect("test");
        assert_eq!(back, img);
        assert_eq!(f32_bits(&back), f32_bits(&img));
        assert_eq!(back.config.learn_windows, img.config.learn_windows);
        assert_eq!(back.trained_runs, img.trained_runs);
        assert_eq!(bytes(&back), b);
        // Signed zeros and an absent term's tau survive as written.
        let mut z = img;
        z.model.temp_ref_c = -0.0;
        z.model.markov[2] = MarkovTerm {
            sigma_dps: 0.0,
            tau_s: -7.5,
        };
        let back = Image::parse(&bytes(&z)).expect("test");
        assert_eq!(f32_bits(&back), f32_bits(&z));
        let mut small = [0u8; IMAGE_LEN - 1];
        assert_eq!(img.to_bytes(&mut small), Err(ImageError::BufferTooSmall));
    }

    #[test]
    fn filter_runs_bit_for_bit() {
        let img = sample();
        let back = Image::parse(&bytes(&img)).expect("test");
        let mut a = DriftFilter::new(img.model, img.config).expect("test");
        let mut b = back.filter().expect("test");
        for k in 0..3000u32 {
            let x = 1.0e-3 * ((k as f32) * 0.37).sin() + if k > 2000 { 0.5 } else { 0.0 };
            let t = 25.0 + k as f32 * 1.0e-3;
            let (ya, yb) = (a.push(x, t, None), b.push(x, t, None));
            assert_eq!(
                ya.map(|o| o.drift_dps.to_bits()),
                yb.map(|o| o.drift_dps.to_bits())
            );
        }
    }

    #[test]
    fn check_rate() {
        let img = sample();
        assert_eq!(img.check_rate(100.0), Ok(()));
        assert_eq!(img.check_rate(100.9), Ok(()));
        assert_eq!(img.check_rate(99.1), Ok(()));
        assert_eq!(
            img.check_rate(101.5),
            Err(ImageError::RateMismatch {
                image_hz: 100.0,
                stream_hz: 101.5
            })
        );
        assert!(img.check_rate(f32::NAN).is_err());
    }

    #[test]
    fn typed_errors() {
        let b = bytes(&sample());
        let mut c = b;
        c[0] = b'X';
        assert_eq!(Image::parse(&c), Err(ImageError::BadMagic));
        assert_eq!(Image::parse(b"FOX"), Err(ImageError::BadMagic));
        for v in [0u16, 6, 0xFFFF] {
            let mut c = b;
            c[4..6].copy_from_slice(&v.to_le_bytes());
            assert_eq!(Image::parse(&c), Err(ImageError::UnsupportedVersion(v)));
        }
        for v in 1u16..=4 {
            let mut c = b;
            c[4..6].copy_from_slice(&v.to_le_bytes());
            assert_eq!(Image::parse(&c), Err(ImageError::RetiredFormat(v)));
            // Named whatever the length: the version comes before it.
            assert_eq!(Image::parse(&c[..6]), Err(ImageError::RetiredFormat(v)));
        }
        let mut c = b;
        c[50] ^= 1;
        assert_eq!(
            Image::parse(&c),
            Err(ImageError::BadChecksum {
                stored: u32_at(&b, CRC_AT),
                computed: crc32(&c[..CRC_AT]),
            })
        );
        // The preset behind a valid checksum.
        let mut c = b;
        c[6..8].copy_from_slice(&1u16.to_le_bytes());
        assert_eq!(Image::parse(&recrc(c)), Err(ImageError::WrongPreset(1)));
        let mut long = [0u8; IMAGE_LEN + 3];
        long[..IMAGE_LEN].copy_from_slice(&b);
        assert_eq!(Image::parse(&long), Err(ImageError::TrailingBytes(3)));
    }

    #[test]
    fn bad_values_are_bad_model() {
        let b = bytes(&sample());
        for (at, v) in [
            (8, f32::NAN),             // sample rate
            (8, 0.0),                  // sample rate
            (12, -1.0e-3),             // white noise
            (20, f32::INFINITY),       // Gauss-Markov sigma
            (24, 0.0),                 // a present term's tau
            (40, f32::NAN),            // an absent term's tau (sigma 0 below)
            (52, -1.0),                // turn-on sigma
            (64, 0.0),                 // least warm-up time constant
            (64, 2000.0),              // least warm-up time constant above the largest
            (72, f32::NEG_INFINITY),   // temperature reference
            (92, 0.0),                 // drift bound
            (CONFIG_AT, 0.0),          // window
            (CONFIG_AT, 0.01),         // a window of 1 sample at 100 Hz
            (CONFIG_AT + 4, f32::NAN), // NIS limit
            (112, -60.0),              // temperature-rate time constant
            (FULL_SCALE_AT, 0.0),
            (FULL_SCALE_AT, f32::INFINITY),
        ] {
            let mut c = b;
            if at == 40 {
                c[36..40].copy_from_slice(&0.0f32.to_le_bytes());
            }
            let c = patched(c, at, v.to_le_bytes());
            assert_eq!(Image::parse(&c), Err(ImageError::BadModel), "{at} = {v}");
        }
        // to_bytes refuses to write what parse would refuse.
        let mut bad = sample();
        bad.full_scale_dps = -1.0;
        let mut out = [0u8; IMAGE_LEN];
        assert_eq!(bad.to_bytes(&mut out), Err(ImageError::BadModel));
        let mut bad = sample();
        bad.model.markov[2] = MarkovTerm {
            sigma_dps: 0.0,
            tau_s: f32::NAN,
        };
        assert_eq!(bad.to_bytes(&mut out), Err(ImageError::BadModel));
    }

    #[test]
    fn a_retired_image_is_refused_by_name() {
        for version in 1u16..=4 {
            let mut head = [0u8; 584];
            head[..4].copy_from_slice(b"FOGI");
            head[4..6].copy_from_slice(&version.to_le_bytes());
            head[6..8].copy_from_slice(&1u16.to_le_bytes());
            assert_eq!(Image::parse(&head), Err(ImageError::RetiredFormat(version)));
            assert_eq!(
                Image::parse(&head[..8]),
                Err(ImageError::RetiredFormat(version))
            );
        }
        let msg = std::format!("{}", ImageError::RetiredFormat(3));
        assert!(msg.contains("retrain with `host-sim identify`"), "{msg}");
    }

    #[test]
    fn every_truncation_is_refused() {
        let b = bytes(&sample());
        for n in 0..IMAGE_LEN {
            assert_eq!(
                Image::parse(&b[..n]),
                Err(ImageError::Truncated { offset: n }),
                "{n}"
            );
        }
    }

    #[test]
    fn every_single_byte_change_is_refused() {
        let b = bytes(&sample());
        for i in 0..IMAGE_LEN {
            for flip in 1u8..=255 {
                let mut c = b;
                c[i] ^= flip;
                assert!(Image::parse(&c).is_err(), "byte {i} ^ {flip:#x} accepted");
            }
        }
    }

    #[test]
    fn error_messages() {
        let all = [
            ImageError::BadMagic,
            ImageError::Truncated { offset: 3 },
            ImageError::RetiredFormat(2),
            ImageError::UnsupportedVersion(9),
            ImageError::TrailingBytes(1),
            ImageError::BadChecksum {
                stored: 1,
                computed: 2,
            },
            ImageError::WrongPreset(1),
            ImageError::BadModel,
            ImageError::RateMismatch {
                image_hz: 100.0,
                stream_hz: 200.0,
            },
            ImageError::BufferTooSmall,
        ];
        for e in all {
            assert!(!std::format!("{e}").is_empty());
        }
    }

    proptest! {
        #[test]
        fn parse_never_panics(data in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = Image::parse(&data);
        }

        /// Random content behind a valid header and checksum: refused, or a valid image
        /// that writes back to the same bytes and builds its filter.
        #[test]
        fn parse_random_content(
            body in proptest::collection::vec(any::<u8>(), IMAGE_LEN - 8),
            cut in 0usize..=IMAGE_LEN,
        ) {
            let mut b = bytes(&sample());
            b[8..].copy_from_slice(&body);
            let b = recrc(b);
            if let Ok(img) = Image::parse(&b) {
                prop_assert_eq!(bytes(&img), b);
                prop_assert!(img.filter().is_ok());
            }
            let _ = Image::parse(&b[..cut]);
        }

        /// One byte of a valid image changed (without fixing the checksum): refused.
        #[test]
        fn one_changed_byte_is_refused(
            i in 0usize..IMAGE_LEN,
            flip in 1u8..=255,
        ) {
            let mut b = bytes(&sample());
            b[i] ^= flip;
            prop_assert!(Image::parse(&b).is_err());
        }

        /// One byte changed and the checksum fixed: never a panic; accepted only as the
        /// image those bytes hold.
        #[test]
        fn parse_near_valid(
            i in 8usize..CRC_AT,
            v in any::<u8>(),
            cut in 0usize..=IMAGE_LEN,
        ) {
            let mut b = bytes(&sample());
            b[i] = v;
            let b = recrc(b);
            if let Ok(img) = Image::parse(&b) {
                prop_assert_eq!(bytes(&img), b);
            }
            let _ = Image::parse(&b[..cut]);
        }
    }
}
