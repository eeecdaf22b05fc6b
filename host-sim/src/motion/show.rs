//! What an identifier image holds, for a person (`host-sim image`): format, checksum, the
//! arrangement and its second state, the sensor and detector the calibration runs set, the
//! level noise, the safety net's time, the model's size and reach, and what the firmware
//! does with it ([`crate::firmware_fit`]).

use super::LevelUpdateArg;
use crate::replay::motion::uses_temperature;
use fog_core::image::Image;
use fog_core::wnn::Neuron;
use serde::Serialize;

/// An image described (units in the field names).
#[derive(Debug, Clone, Serialize)]
pub struct ImageInfo {
    /// Format version of the file (1, 2 or 3).
    pub format_version: u16,
    /// File size, bytes.
    pub bytes: usize,
    /// The CRC-32 stored in the file (checked by the parser).
    pub crc32: u32,
    /// `--level-update` name of the arrangement.
    pub arrangement: String,
    /// The second state's fields as the image stores them (dual-thermal: the temperature
    /// coefficient's prior, deg/h per deg C; bank: B deg/h and the longest tau s).
    pub second_state: String,
    /// Sample rate, Hz.
    pub sample_rate_hz: f32,
    /// Full scale, deg/s.
    pub full_scale_dps: f32,
    /// Output step, deg/s (0: not quantized).
    pub quantum_dps: f32,
    /// White-noise density, deg/sqrt(h).
    pub noise_deg_rth: f32,
    /// Bound on the drift estimate, deg/h.
    pub drift_bound_dph: f32,
    /// Detector window, s.
    pub window_s: f32,
    /// Passing windows needed for rest after motion, s.
    pub min_still_s: f32,
    /// The family's noise range, x the noise density.
    pub noise_range: (f32, f32),
    /// Level random walk, (deg/h)^2 per hour.
    pub level_q_dph2_per_h: f32,
    /// Safety net: hold after this long without a still sample, s.
    pub stale_s: f32,
    /// Model: time since power-on range, s.
    pub model_time_max_s: f32,
    /// Model neurons with a nonzero output weight: wavelet, linear, bias.
    pub model_terms: (usize, usize, usize),
    /// Largest |output weight|, deg/h.
    pub model_max_weight_dph: f32,
    /// The image reads the temperature (unit link or model terms).
    pub uses_temperature: bool,
    /// Record passes trained into the image (records x DRLS passes; least squares: the
    /// records).
    pub record_passes_trained: u32,
    /// What the firmware does with the image ([`crate::firmware_fit`]).
    pub firmware: crate::firmware_fit::FirmwareFit,
}

/// Describes `image`, parsed from `bytes`.
pub fn describe(image: &Image, bytes: &[u8]) -> ImageInfo {
    let c = &image.config;
    let s = &c.sensor;
    let g = image.second_state;
    let second_state = if image.arrangement.is_bank() {
        format!(
            "bank B {} deg/h, longest tau {} s",
            g.sigma * 3600.0,
            g.tau_s
        )
    } else {
        format!(
            "temperature coefficient prior {} deg/h per deg C",
            g.sigma * 3600.0
        )
    };
    let m = &image.model;
    let mut terms = (0, 0, 0);
    for (w, k) in m.weights.iter().zip(m.shape.kind.iter()) {
        if *w != 0.0 {
            match k {
                Neuron::Wavelet => terms.0 += 1,
                Neuron::Linear(_) => terms.1 += 1,
                Neuron::Bias => terms.2 += 1,
            }
        }
    }
    let word = |at: usize| {
        bytes
            .get(at..at + 4)
            .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    ImageInfo {
        format_version: bytes
            .get(4..6)
            .map_or(0, |b| u16::from_le_bytes([b[0], b[1]])),
        bytes: bytes.len(),
        crc32: word(bytes.len().saturating_sub(4)),
        arrangement: LevelUpdateArg::of(image.arrangement).cli_name(),
        second_state,
        sample_rate_hz: s.sample_rate_hz,
        full_scale_dps: s.full_scale_dps,
        quantum_dps: s.quantum_dps,
        noise_deg_rth: s.noise_density_dps_rthz * 60.0,
        drift_bound_dph: s.drift_bound_dps * 3600.0,
        window_s: c.still.window_s,
        min_still_s: c.still.min_still_s,
        noise_range: (c.still.noise_lo, c.still.noise_hi),
        level_q_dph2_per_h: c.level_q_dps2_per_s * 3600.0 * 3600.0 * 3600.0,
        stale_s: c.stale_s,
        model_time_max_s: m.time_max_s,
        model_terms: terms,
        model_max_weight_dph: m.weights.iter().fold(0.0f32, |a, w| a.max(w.abs())) * 3600.0,
        uses_temperature: uses_temperature(image),
        record_passes_trained: image.records_trained,
        firmware: crate::firmware_fit::check(image, bytes),
    }
}

/// The description as lines of text.
pub fn text(name: &str, i: &ImageInfo) -> String {
    format!(
        "{name}: identifier image, format {}, {} bytes, CRC-32 0x{:08x}\n\
         arrangement: {} ({})\n\
         sensor: {} Hz, full scale {} deg/s, quantum {} deg/s, noise {:.4} deg/sqrt(h), drift bound {:.1} deg/h\n\
         detector: window {} s, rest after {} s of passing windows, noise range {:.3}x to {:.3}x\n\
         level: random walk {:.3} (deg/h)^2/h; safety net after {} s without rest\n\
         model: time since power-on 0..{} s; nonzero terms: {} wavelet, {} linear, {} bias; largest |weight| {:.3} deg/h; reads temperature: {}\n\
         trained on {} record passes (records x DRLS passes)\n",
        i.format_version,
        i.bytes,
        i.crc32,
        i.arrangement,
        i.second_state,
        i.sample_rate_hz,
        i.full_scale_dps,
        i.quantum_dps,
        i.noise_deg_rth,
        i.drift_bound_dph,
        i.window_s,
        i.min_still_s,
        i.noise_range.0,
        i.noise_range.1,
        i.level_q_dph2_per_h,
        i.stale_s,
        i.model_time_max_s,
        i.model_terms.0,
        i.model_terms.1,
        i.model_terms.2,
        i.model_max_weight_dph,
        if i.uses_temperature { "yes" } else { "no" },
        i.record_passes_trained,
    )
}
