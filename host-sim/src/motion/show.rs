//! What an image holds, for a person (`host-sim image`): format, checksum, the gyro model the
//! calibration runs fitted (noise terms, turn-on, warm-up, temperature links, bound), the
//! filter's settings, and what the firmware does with it ([`crate::firmware_fit`]).

use fog_core::image::Image;
use serde::Serialize;

/// deg/s -> deg/h.
const DPH: f32 = 3600.0;

/// An image described (units in the field names).
#[derive(Debug, Clone, Serialize)]
pub struct ImageInfo {
    /// Format version of the file (4).
    pub format_version: u16,
    /// File size, bytes.
    pub bytes: usize,
    /// The CRC-32 stored in the file (checked by the parser).
    pub crc32: u32,
    /// Sample rate, Hz.
    pub sample_rate_hz: f32,
    /// Full scale, deg/s.
    pub full_scale_dps: f32,
    /// Output step, deg/s (0: not quantized).
    pub quantum_dps: f32,
    /// White-noise density, deg/sqrt(h).
    pub white_deg_rth: f32,
    /// Gauss-Markov terms present: (sigma deg/h, tau s).
    pub markov_dph_s: Vec<(f32, f32)>,
    /// Rate random walk, deg/h/sqrt(h).
    pub rrw_dph_rth: f32,
    /// Turn-on bias: family mean and unit spread, deg/h.
    pub turn_on_dph: (f32, f32),
    /// Warm-up amplitude: mean and spread, deg/h; time constant: least and largest, s.
    pub warmup_dph_tau_s: (f32, f32, f32, f32),
    /// Temperature link: mean and spread, deg/h per deg C, from this temperature, deg C.
    pub temp_dph_per_c: (f32, f32, f32),
    /// Temperature-rate link: mean and spread, deg/h per (deg C/min).
    pub temp_rate_dph_per_c_per_min: (f32, f32),
    /// Bound on the drift estimate, deg/h.
    pub drift_bound_dph: f32,
    /// Filter window, s.
    pub window_s: f32,
    /// Stillness threshold (chi-square(1) quantile).
    pub nis_limit: f32,
    /// Smallest steady rate the test resolves, deg/h.
    pub resolve_dph: f32,
    /// The image reads the temperature (a link with nonzero mean or spread).
    pub uses_temperature: bool,
    /// Calibration runs the model was fitted on (0: the sensor's specification alone).
    pub trained_runs: u32,
    /// What the firmware does with the image ([`crate::firmware_fit`]).
    pub firmware: crate::firmware_fit::FirmwareFit,
}

/// Whether `image`'s filter reads the temperature.
pub fn uses_temperature(image: &Image) -> bool {
    let m = &image.model;
    [m.temp_dps_per_c, m.temp_rate_dps_per_c_per_s]
        .iter()
        .any(|s| s.mean != 0.0 || s.sigma != 0.0)
}

/// Describes `image`, parsed from `bytes`.
pub fn describe(image: &Image, bytes: &[u8]) -> ImageInfo {
    let m = &image.model;
    let c = &image.config;
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
        sample_rate_hz: m.sample_rate_hz,
        full_scale_dps: image.full_scale_dps,
        quantum_dps: m.quantum_dps,
        white_deg_rth: m.white_dps_rthz * 60.0,
        markov_dph_s: m
            .markov
            .iter()
            .filter(|t| t.sigma_dps > 0.0)
            .map(|t| (t.sigma_dps * DPH, t.tau_s))
            .collect(),
        rrw_dph_rth: m.rrw_dps_per_s_rthz * DPH * 60.0,
        turn_on_dph: (m.turn_on_dps.mean * DPH, m.turn_on_dps.sigma * DPH),
        warmup_dph_tau_s: (
            m.warmup_dps.mean * DPH,
            m.warmup_dps.sigma * DPH,
            m.warmup_tau_min_s,
            m.warmup_tau_max_s,
        ),
        temp_dph_per_c: (
            m.temp_dps_per_c.mean * DPH,
            m.temp_dps_per_c.sigma * DPH,
            m.temp_ref_c,
        ),
        temp_rate_dph_per_c_per_min: (
            m.temp_rate_dps_per_c_per_s.mean * DPH / 60.0,
            m.temp_rate_dps_per_c_per_s.sigma * DPH / 60.0,
        ),
        drift_bound_dph: m.drift_bound_dps * DPH,
        window_s: c.window_s,
        nis_limit: c.nis_limit,
        resolve_dph: c.resolve_dps * DPH,
        uses_temperature: uses_temperature(image),
        trained_runs: image.trained_runs,
        firmware: crate::firmware_fit::check(image, bytes),
    }
}

/// The description as lines of text.
pub fn text(name: &str, i: &ImageInfo) -> String {
    let markov = if i.markov_dph_s.is_empty() {
        "none".to_string()
    } else {
        i.markov_dph_s
            .iter()
            .map(|(s, t)| format!("{s:.3} deg/h at {t} s"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "{name}: drift-filter image, format {}, {} bytes, CRC-32 0x{:08x}; fitted on {} calibration runs\n\
         sensor: {} Hz, full scale {} deg/s, quantum {} deg/s\n\
         noise: white {:.4} deg/sqrt(h); Gauss-Markov {markov}; rate random walk {:.3} deg/h/sqrt(h)\n\
         turn-on {:+.2} +- {:.2} deg/h; warm-up {:+.2} +- {:.2} deg/h, time constant {:.0} to {:.0} s; drift bound {:.1} deg/h\n\
         temperature link {:+.4} +- {:.4} deg/h per deg C from {} deg C; rate link {:+.3} +- {:.3} deg/h per deg C/min; reads temperature: {}\n\
         filter: window {} s, stillness threshold {} (chi-square(1)), resolves {:.1} deg/h\n",
        i.format_version,
        i.bytes,
        i.crc32,
        i.trained_runs,
        i.sample_rate_hz,
        i.full_scale_dps,
        i.quantum_dps,
        i.white_deg_rth,
        i.rrw_dph_rth,
        i.turn_on_dph.0,
        i.turn_on_dph.1,
        i.warmup_dph_tau_s.0,
        i.warmup_dph_tau_s.1,
        i.warmup_dph_tau_s.2,
        i.warmup_dph_tau_s.3,
        i.drift_bound_dph,
        i.temp_dph_per_c.0,
        i.temp_dph_per_c.1,
        i.temp_dph_per_c.2,
        i.temp_rate_dph_per_c_per_min.0,
        i.temp_rate_dph_per_c_per_min.1,
        if i.uses_temperature { "yes" } else { "no" },
        i.window_s,
        i.nis_limit,
        i.resolve_dph,
    )
}
