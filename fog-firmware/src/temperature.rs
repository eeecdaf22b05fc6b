//! Board temperature for the sample processing: an optional TMP117 (`fog_core::tmp117`) on
//! the board's I2C bus, read at most once per second of gyro samples.
//!
//! The firmware runs with or without the sensor. A board without an I2C bus passes `None`;
//! a board with one passes it, and [`TemperatureSource::probe`] checks
//! the device id at boot and logs on defmt whether a TMP117 answered. [`sample`] is called once
//! per gyro sample and gives `temp_c: Option<f32>`:
//!
//! - the last good reading, refreshed every [`REFRESH_SAMPLES`] samples (1 s at the gyro's
//!   100 Hz; the sensor is configured for one result per second, 8 averages);
//! - after a failed read, the previous reading is kept for at most [`HOLD_SAMPLES`] samples
//!   (5 s) since the last good one, then `None` until a read succeeds again; every failed read
//!   is counted ([`failures`]) and the transitions (lost, back) are logged;
//! - `None` when no sensor was found, and before the first good reading.
//!
//! A read is one write-read on the bus (address, register, address, 2 bytes: about 47 bit
//! times, 0.5 ms at 100 kHz), blocking, made in the main loop on the sample that is due; the
//! other samples cost a counter update.
//!
//! The refresh and hold policy is `temperature_hold.rs` (tested on the host).
//!
//! [`sample`]: TemperatureSource::sample
//! [`failures`]: TemperatureSource::failures
#![forbid(unsafe_code)]

use embedded_hal::i2c::{self, ErrorKind, I2c};
use fog_core::tmp117::{self, Address, Config, Tmp117};

use crate::pipeline;
use crate::temperature_hold::Hold;

/// Samples between two reads: 1 s of gyro samples at the E-Core's 100 Hz (0.01 s per
/// sample). An image at another rate keeps 100 samples (ASSUMED harmless: 5 s at 20 Hz,
/// 0.05 s at 2 kHz, against a case temperature whose time constant is minutes).
pub const REFRESH_SAMPLES: u32 = (pipeline::SAMPLE_RATE_HZ + 0.5) as u32;

/// Samples a reading stays valid after the last good read: 5 s (five missed refreshes).
pub const HOLD_SAMPLES: u32 = 5 * REFRESH_SAMPLES;

/// Sensor configuration written at boot: continuous, one result per second, 8 averages (the
/// TMP117's power-on setting, written anyway so that an EEPROM changed by someone else does
/// not change what the firmware reads).
pub const SENSOR_CONFIG: Config = Config {
    mode: tmp117::Mode::Continuous,
    averaging: tmp117::Averaging::Avg8,
    cycle: tmp117::ConversionCycle::S1,
};

/// The optional sensor and the reading handed to the sample processing.
#[derive(Debug)]
pub struct TemperatureSource<I2C> {
    sensor: Option<Tmp117<I2C>>,
    hold: Hold,
}

/// One-word description of a driver error, for defmt (the bus error types of the HALs do
/// not all implement `defmt::Format`).
fn describe<E: i2c::Error>(e: &tmp117::Error<E>) -> &'static str {
    match e {
        tmp117::Error::I2c(bus) => match bus.kind() {
            ErrorKind::NoAcknowledge(_) => "no acknowledge",
            ErrorKind::ArbitrationLoss => "arbitration loss",
            ErrorKind::Bus => "bus error",
            ErrorKind::Overrun => "overrun",
            _ => "other bus error",
        },
        tmp117::Error::WrongDevice { .. } => "wrong device id",
        tmp117::Error::NotReady => "no conversion yet",
    }
}

impl<I2C: I2c> TemperatureSource<I2C> {
    /// Probes for a TMP117 at `address` on `bus` (none when `bus` is `None`) and configures
    /// it with [`SENSOR_CONFIG`]; logs the outcome. Without a sensor every
    /// [`sample`](Self::sample) is `None`.
    pub fn probe(bus: Option<I2C>, address: Address) -> Self {
        let sensor = bus.and_then(|bus| {
            let mut sensor = Tmp117::new(bus, address);
            match sensor.init(SENSOR_CONFIG) {
                Ok(id) => {
                    defmt::info!(
                        "temperature: TMP117 at {=u8:#x}, id {=u16:#x}",
                        address as u8,
                        id
                    );
                    Some(sensor)
                }
                Err(e) => {
                    match e {
                        tmp117::Error::WrongDevice { id } => defmt::warn!(
                            "temperature: no TMP117 at {=u8:#x} (device id {=u16:#x}); running without temperature",
                            address as u8,
                            id
                        ),
                        _ => defmt::info!(
                            "temperature: no TMP117 at {=u8:#x} ({=str}); running without temperature",
                            address as u8,
                            describe(&e)
                        ),
                    }
                    None
                }
            }
        });
        if sensor.is_none() {
            defmt::info!("temperature: no sensor, temp_c is None");
        }
        Self {
            sensor,
            hold: Hold::new(REFRESH_SAMPLES, HOLD_SAMPLES),
        }
    }

    /// Whether a TMP117 was found at boot.
    pub fn present(&self) -> bool {
        self.sensor.is_some()
    }

    /// Failed reads since boot.
    pub fn failures(&self) -> u32 {
        self.hold.failures()
    }

    /// Temperature for the current gyro sample, °C; call once per sample. Reads the sensor
    /// when a refresh is due (every [`REFRESH_SAMPLES`] calls), otherwise returns the held
    /// value (see the module documentation).
    pub fn sample(&mut self) -> Option<f32> {
        let sensor = self.sensor.as_mut()?;
        if self.hold.tick() {
            match sensor.read_temp_c() {
                Ok(t) => {
                    if self.hold.good(t) {
                        defmt::info!("temperature: reading again, {=f32} C", t);
                    }
                }
                Err(e) => {
                    self.hold.failed();
                    defmt::debug!(
                        "temperature: read failed ({=str}), {=u32} failures",
                        describe(&e),
                        self.hold.failures()
                    );
                }
            }
        }
        if self.hold.expire() {
            defmt::warn!(
                "temperature: no good read for {=u32} samples, temp_c is None ({=u32} failures)",
                self.hold.age_samples(),
                self.hold.failures()
            );
        }
        self.hold.value()
    }
}
