//! Board temperature for the sample processing: an optional TMP117 (`fog_core::tmp117`) or,
//! failing that, a TMP105 (`fog_core::tmp105`) on the board's I2C bus, read at most once per
//! second of gyro samples through `fog_core::temp_sensor::TemperatureSensor`.
//!
//! The firmware runs with or without a sensor. A board without an I2C bus passes `None`;
//! a board with one passes it, and [`TemperatureSource::probe`] checks for a TMP117 first (its
//! device id register), then for a TMP105 (no id register: the configuration written at 12
//! bits must read back), and logs on defmt which one answered (the part's name as a `{=str}`
//! argument, so it is legible in the raw log). [`sample`] is called once per gyro sample and
//! gives `temp_c: Option<f32>`:
//!
//! - the last good reading, refreshed every [`REFRESH_SAMPLES`] samples (1 s at the gyro's
//!   100 Hz; a TMP117 is configured for one result per second, 8 averages, a TMP105 for
//!   continuous 12-bit conversions);
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
use fog_core::temp_sensor::TemperatureSensor;
use fog_core::tmp105::{self, Tmp105};
use fog_core::tmp117::{self, Config, Tmp117};

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

/// TMP105 resolution set at boot: 12 bits, 0.0625 °C (the power-on 9 bits give 0.5 °C).
pub const TMP105_RESOLUTION: tmp105::Resolution = tmp105::Resolution::Bits12;

/// The sensor found at boot.
#[derive(Debug)]
enum Sensor<I2C> {
    Tmp117(Tmp117<I2C>),
    Tmp105(Tmp105<I2C>),
}

impl<I2C: I2c> Sensor<I2C> {
    /// One reading, or why it failed (one word for defmt).
    fn read(&mut self) -> Result<f32, &'static str> {
        match self {
            Self::Tmp117(s) => read_with(s, describe_tmp117),
            Self::Tmp105(s) => read_with(s, describe_tmp105),
        }
    }

    fn model(&self) -> &'static str {
        match self {
            Self::Tmp117(s) => s.model(),
            Self::Tmp105(s) => s.model(),
        }
    }
}

fn read_with<S: TemperatureSensor>(
    sensor: &mut S,
    describe: fn(&S::Error) -> &'static str,
) -> Result<f32, &'static str> {
    sensor.read_temp_c().map_err(|e| describe(&e))
}

/// The optional sensor and the reading handed to the sample processing.
#[derive(Debug)]
pub struct TemperatureSource<I2C> {
    sensor: Option<Sensor<I2C>>,
    hold: Hold,
}

/// One-word description of a bus error, for defmt (the bus error types of the HALs do not
/// all implement `defmt::Format`).
fn describe_bus<E: i2c::Error>(bus: &E) -> &'static str {
    match bus.kind() {
        ErrorKind::NoAcknowledge(_) => "no acknowledge",
        ErrorKind::ArbitrationLoss => "arbitration loss",
        ErrorKind::Bus => "bus error",
        ErrorKind::Overrun => "overrun",
        _ => "other bus error",
    }
}

fn describe_tmp117<E: i2c::Error>(e: &tmp117::Error<E>) -> &'static str {
    match e {
        tmp117::Error::I2c(bus) => describe_bus(bus),
        tmp117::Error::WrongDevice { .. } => "wrong device id",
        tmp117::Error::NotReady => "no conversion yet",
    }
}

fn describe_tmp105<E: i2c::Error>(e: &tmp105::Error<E>) -> &'static str {
    match e {
        tmp105::Error::I2c(bus) => describe_bus(bus),
        tmp105::Error::ConfigMismatch { .. } => "configuration does not read back",
    }
}

impl<I2C: I2c> TemperatureSource<I2C> {
    /// Probes for a TMP117 at `tmp117_address` on `bus` (none when `bus` is `None`) and
    /// configures it with [`SENSOR_CONFIG`]; without one, for a TMP105 at `tmp105_address`,
    /// configured at [`TMP105_RESOLUTION`]. Logs the outcome. Without a sensor every
    /// [`sample`](Self::sample) is `None`.
    pub fn probe(
        bus: Option<I2C>,
        tmp117_address: tmp117::Address,
        tmp105_address: tmp105::Address,
    ) -> Self {
        let sensor = bus.and_then(|bus| {
            let mut t117 = Tmp117::new(bus, tmp117_address);
            match t117.init(SENSOR_CONFIG) {
                Ok(id) => {
                    defmt::info!(
                        "temperature: {=str} at {=u8:#x}, id {=u16:#x}",
                        t117.model(),
                        t117.bus_address(),
                        id
                    );
                    return Some(Sensor::Tmp117(t117));
                }
                Err(e) => {
                    if let tmp117::Error::WrongDevice { id } = e {
                        defmt::info!(
                            "temperature: no TMP117 at {=u8:#x} ({=str}: {=u16:#x})",
                            t117.bus_address(),
                            describe_tmp117(&e),
                            id
                        );
                    } else {
                        defmt::info!(
                            "temperature: no TMP117 at {=u8:#x} ({=str})",
                            t117.bus_address(),
                            describe_tmp117(&e)
                        );
                    }
                }
            }
            let mut t105 = Tmp105::new(t117.release(), tmp105_address);
            match t105.init(TMP105_RESOLUTION) {
                Ok(()) => {
                    defmt::info!(
                        "temperature: {=str} at {=u8:#x}, resolution {=f32} C",
                        t105.model(),
                        t105.bus_address(),
                        t105.resolution_c()
                    );
                    Some(Sensor::Tmp105(t105))
                }
                Err(e) => {
                    defmt::info!(
                        "temperature: no TMP105 at {=u8:#x} ({=str}); running without temperature",
                        t105.bus_address(),
                        describe_tmp105(&e)
                    );
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

    /// The part found at boot (`"TMP117"`, `"TMP105"`), `None` without one.
    pub fn model(&self) -> Option<&'static str> {
        self.sensor.as_ref().map(Sensor::model)
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
            match sensor.read() {
                Ok(t) => {
                    if self.hold.good(t) {
                        defmt::info!("temperature: reading again, {=f32} C", t);
                    }
                }
                Err(e) => {
                    self.hold.failed();
                    defmt::debug!(
                        "temperature: read failed ({=str}), {=u32} failures",
                        e,
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
