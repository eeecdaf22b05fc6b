//! `fog-core`: fiber-optic-gyro drift identification that runs unchanged on a Cortex-M4F and
//! on the host.
//!
//! `no_std`, no heap, fixed sizes, no panics on any input. Modules:
//! - [`db4`]: db4 wavelet transform in lifting form, PyWavelets-compatible coefficients;
//! - [`threshold`]: noise estimate, universal threshold, soft and hard shrinkage;
//! - [`denoise`]: block denoising (paper section 3) and a sample-by-sample block buffer;
//! - [`wnn`]: the wavelet neural network (paper section 4.1);
//! - [`train`]: DRLS (paper section 4.2) and the RLS / NLMS baselines;
//! - [`features`]: causal network inputs; [`identify`]: the on-line identifier;
//! - [`sensor`]: a gyro's specification (rate, noise, quantum, full scale, drift bound);
//! - [`image`]: the fitted gyro model and its filter's settings as a versioned, checksummed
//!   binary image (what the firmware runs);
//! - [`baseline`]: causal estimators to compare with;
//! - [`gyro_model`]: the gyro model as data; [`kalman`]: the Kalman primitive;
//!   [`warmup_basis`]: the warm-up of an unknown time constant as a few exponentials;
//!   [`drift_filter`]: the model's Kalman filter with its stillness test;
//! - [`frame`], [`driver`]: gyro serial frames and the serial reader;
//! - [`tmp117`], [`tmp105`]: drivers for the TI TMP117 and TMP105 I2C temperature sensors,
//!   both read through [`temp_sensor::TemperatureSensor`].
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod baseline;
pub mod db4;
pub mod denoise;
pub mod drift_filter;
pub mod driver;
pub mod features;
pub mod frame;
pub mod gyro_model;
pub mod identify;
pub mod image;
pub mod kalman;
pub mod sensor;
pub mod temp_sensor;
#[cfg(test)]
mod test_noise;
pub mod threshold;
pub mod tmp105;
pub mod tmp117;
pub mod train;
pub mod warmup_basis;
pub mod wnn;

pub use denoise::{BlockDenoiser, DenoiseConfig, DenoiseError, Push, Thresholds};
pub use threshold::{Sigma, ThresholdRule};
