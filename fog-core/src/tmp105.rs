//! Driver for the Texas Instruments TMP105 digital temperature sensor on I2C.
//!
//! Generic over [`embedded_hal::i2c::I2c`] (embedded-hal 1.0) and over its bus error: every
//! method returns [`Error<E>`] with the bus's own error inside. No heap, no panic path, no
//! floating point besides the final conversion in [`Tmp105::read_temp_c`]. Implements
//! [`TemperatureSensor`], as the TMP117 driver does.
//!
//! # Register map used here
//! Source: TI TMP105 datasheet (SLLS648, "Digital Temperature Sensor with Two-Wire
//! Interface"), pointer and register descriptions; written from those facts and run against
//! QEMU's model of the part (`hw/sensor/tmp105.c`, `-device tmp105`), not against a device.
//!
//! | pointer | register | used as |
//! |---|---|---|
//! | `0b00` | Temperature | 16 bits, two's complement, left-justified: the top 9 to 12 bits hold the result (1 LSB of the 16-bit word = 1/256 °C; 0.0625 °C at 12 bits); read only |
//! | `0b01` | Configuration | 8 bits: bit 0 SD (shutdown), bit 1 TM (thermostat mode), bit 2 POL, bits 4:3 fault queue, bits 6:5 R1:R0 resolution (9, 10, 11, 12 bits), bit 7 OS (one-shot); power-on value `0x00` (9 bits, continuous, comparator) |
//! | `0b10`, `0b11` | T_LOW, T_HIGH | alert limits; not used here |
//!
//! A register read is `write_read(addr, [pointer], [msb, lsb])` (the configuration register
//! gives one byte), a configuration write is `write(addr, [0x01, byte])`.
//!
//! **No id register.** Unlike the TMP117, nothing in the part names it. [`Tmp105::init`]
//! therefore writes the configuration and reads it back: an acknowledged address whose
//! configuration register keeps the bits written (6:0; bit 7, OS, is left out: it reads back
//! differently in shutdown mode) is taken as a TMP105 or a register-compatible part
//! (TMP100/101/75 style). Another device at the address would have a byte written into
//! whatever its register 1 is; probe the parts that do have an id first (the firmware probes
//! for a TMP117 before a TMP105).
//!
//! Datasheet figures: resolution 9 to 12 bits (0.5 °C to 0.0625 °C), conversion time growing
//! with the resolution (a few hundred ms at 12 bits); accuracy ±2 °C (max) from -25 °C to 85
//! °C, ±3 °C from -40 °C to 125 °C; two addresses (pin A0).
//!
//! ```
//! use embedded_hal_mock::eh1::i2c::{Mock, Transaction};
//! use fog_core::tmp105::{Address, Resolution, Tmp105};
//!
//! let addr = Address::A0Low as u8; // 0x48
//! let mut bus = Mock::new(&[
//!     Transaction::write(addr, vec![0x01, 0x60]),                   // 12 bits
//!     Transaction::write_read(addr, vec![0x01], vec![0x60]),        // read back
//!     Transaction::write_read(addr, vec![0x00], vec![0x19, 0x10]), // 25.0625 °C
//! ]);
//! let mut sensor = Tmp105::new(&mut bus, Address::A0Low);
//! assert_eq!(sensor.init(Resolution::Bits12), Ok(()));
//! assert_eq!(sensor.read_temp_c(), Ok(25.0625));
//! bus.done();
//! ```

use embedded_hal::i2c::{self, I2c};

use crate::temp_sensor::TemperatureSensor;

/// Temperature of one LSB of the 16-bit temperature register word, °C (the result is
/// left-justified: at 12 bits the low 4 bits are 0 and one step is 16 LSB = 0.0625 °C).
pub const CELSIUS_PER_LSB: f32 = 1.0 / 256.0;

/// Pointer register values (bits 1:0; the other bits must be 0).
mod reg {
    pub const TEMPERATURE: u8 = 0b00;
    pub const CONFIGURATION: u8 = 0b01;
}

/// Configuration register fields.
mod cfg {
    pub const RESOLUTION_SHIFT: u8 = 5;
    /// Bits that read back as written (OS, bit 7, left out).
    pub const READ_BACK_MASK: u8 = 0x7F;
}

/// I2C address, set by the A0 pin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Address {
    /// A0 low: `0x48` (QEMU's `-device tmp105,address=0x48`).
    #[default]
    A0Low = 0x48,
    /// A0 high: `0x49`.
    A0High = 0x49,
}

/// Converter resolution (configuration bits 6:5, R1:R0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Resolution {
    /// 9 bits, 0.5 °C (the power-on value).
    #[default]
    Bits9,
    /// 10 bits, 0.25 °C.
    Bits10,
    /// 11 bits, 0.125 °C.
    Bits11,
    /// 12 bits, 0.0625 °C.
    Bits12,
}

impl Resolution {
    /// The configuration register byte for this resolution in continuous comparator mode
    /// (shutdown off, alert active low, fault queue 1): only R1:R0 set.
    pub const fn config_byte(self) -> u8 {
        (self as u8) << cfg::RESOLUTION_SHIFT
    }

    /// The resolution field of a configuration byte.
    pub const fn from_config_byte(byte: u8) -> Self {
        match (byte >> cfg::RESOLUTION_SHIFT) & 0b11 {
            0 => Self::Bits9,
            1 => Self::Bits10,
            2 => Self::Bits11,
            _ => Self::Bits12,
        }
    }

    /// One step of the result, °C: 0.5, 0.25, 0.125 or 0.0625.
    pub const fn step_c(self) -> f32 {
        match self {
            Self::Bits9 => 0.5,
            Self::Bits10 => 0.25,
            Self::Bits11 => 0.125,
            Self::Bits12 => 0.0625,
        }
    }
}

/// Error of a [`Tmp105`], generic over the bus error `E`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The bus reported an error (no acknowledge when nothing answers at the address).
    I2c(E),
    /// A device answered, but its configuration register did not keep the byte written
    /// (bits 6:0): not a TMP105-compatible register map.
    ConfigMismatch {
        /// The byte written.
        wrote: u8,
        /// The byte read back.
        read: u8,
    },
}

impl<E: i2c::Error> core::fmt::Display for Error<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::I2c(e) => write!(f, "TMP105 bus error: {}", e.kind()),
            Self::ConfigMismatch { wrote, read } => write!(
                f,
                "not a TMP105: configuration 0x{wrote:02X} written, 0x{read:02X} read back"
            ),
        }
    }
}

impl<E: i2c::Error> core::error::Error for Error<E> {}

/// Temperature register word to °C: two's complement times 1/256 °C. Exact in `f32` for
/// every word (16 significant bits); `0x7FF0` is 127.9375 °C, `0x8000` -128 °C.
pub const fn raw_to_celsius(raw: u16) -> f32 {
    raw as i16 as f32 * CELSIUS_PER_LSB
}

/// A TMP105 at one address of bus `I2C`.
#[derive(Debug)]
pub struct Tmp105<I2C> {
    i2c: I2C,
    address: u8,
    resolution: Resolution,
}

impl<I2C> Tmp105<I2C> {
    /// Driver of the sensor at `address` on `i2c`, assumed at its power-on resolution (9
    /// bits). Talks to nothing: call [`init`](Self::init).
    pub const fn new(i2c: I2C, address: Address) -> Self {
        Self {
            i2c,
            address: address as u8,
            resolution: Resolution::Bits9,
        }
    }

    /// The 7-bit bus address.
    pub const fn address(&self) -> u8 {
        self.address
    }

    /// The resolution last written by [`init`](Self::init) (9 bits before).
    pub const fn resolution(&self) -> Resolution {
        self.resolution
    }

    /// Gives the bus back.
    pub fn release(self) -> I2C {
        self.i2c
    }
}

impl<I2C: I2c> Tmp105<I2C> {
    /// Writes the configuration (continuous conversions at `resolution`, comparator mode)
    /// and reads it back: the check that a TMP105-compatible part answers (see the module
    /// documentation: the part has no id register).
    ///
    /// `Err(Error::I2c(_))` when nothing acknowledges, `Err(Error::ConfigMismatch)` when
    /// the byte does not read back.
    pub fn init(&mut self, resolution: Resolution) -> Result<(), Error<I2C::Error>> {
        let wrote = resolution.config_byte();
        self.i2c
            .write(self.address, &[reg::CONFIGURATION, wrote])
            .map_err(Error::I2c)?;
        let read = self.config_byte()?;
        if read & cfg::READ_BACK_MASK != wrote & cfg::READ_BACK_MASK {
            return Err(Error::ConfigMismatch { wrote, read });
        }
        self.resolution = resolution;
        Ok(())
    }

    /// The configuration register as it is.
    pub fn config_byte(&mut self) -> Result<u8, Error<I2C::Error>> {
        let mut byte = [0u8; 1];
        self.i2c
            .write_read(self.address, &[reg::CONFIGURATION], &mut byte)
            .map_err(Error::I2c)?;
        Ok(byte[0])
    }

    /// The temperature register word as it is (see [`raw_to_celsius`]).
    pub fn read_raw(&mut self) -> Result<u16, Error<I2C::Error>> {
        let mut word = [0u8; 2];
        self.i2c
            .write_read(self.address, &[reg::TEMPERATURE], &mut word)
            .map_err(Error::I2c)?;
        Ok(u16::from_be_bytes(word))
    }

    /// The last conversion result, °C (in steps of [`Resolution::step_c`]).
    pub fn read_temp_c(&mut self) -> Result<f32, Error<I2C::Error>> {
        Ok(raw_to_celsius(self.read_raw()?))
    }
}

impl<I2C: I2c> TemperatureSensor for Tmp105<I2C> {
    type Error = Error<I2C::Error>;

    fn model(&self) -> &'static str {
        "TMP105"
    }

    fn bus_address(&self) -> u8 {
        self.address
    }

    fn resolution_c(&self) -> f32 {
        self.resolution.step_c()
    }

    fn read_temp_c(&mut self) -> Result<f32, Self::Error> {
        Tmp105::read_temp_c(self)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec;

    use super::*;
    use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource};
    use embedded_hal_mock::eh1::i2c::{Mock, Transaction};

    const ADDR: u8 = 0x48;

    fn read_temp(word: u16) -> Transaction {
        Transaction::write_read(ADDR, vec![0x00], word.to_be_bytes().to_vec())
    }

    fn write_config(byte: u8) -> Transaction {
        Transaction::write(ADDR, vec![0x01, byte])
    }

    fn read_config(byte: u8) -> Transaction {
        Transaction::write_read(ADDR, vec![0x01], vec![byte])
    }

    #[test]
    fn addresses_follow_a0() {
        assert_eq!([Address::A0Low as u8, Address::A0High as u8], [0x48, 0x49]);
        let mut bus = Mock::new(&[Transaction::write_read(0x49, vec![0x00], vec![0, 0])]);
        let mut s = Tmp105::new(&mut bus, Address::A0High);
        assert_eq!(s.address(), 0x49);
        assert_eq!(s.bus_address(), 0x49);
        assert_eq!(s.read_temp_c(), Ok(0.0));
        bus.done();
    }

    #[test]
    fn resolution_field_round_trips() {
        let all = [
            (Resolution::Bits9, 0x00, 0.5),
            (Resolution::Bits10, 0x20, 0.25),
            (Resolution::Bits11, 0x40, 0.125),
            (Resolution::Bits12, 0x60, 0.0625),
        ];
        for (r, byte, step) in all {
            assert_eq!(r.config_byte(), byte, "{r:?}");
            assert_eq!(Resolution::from_config_byte(byte), r);
            // Other bits do not change the field.
            assert_eq!(Resolution::from_config_byte(byte | 0x9F), r);
            assert_eq!(r.step_c(), step);
        }
        assert_eq!(Resolution::default(), Resolution::Bits9);
    }

    #[test]
    fn init_writes_and_checks_the_configuration() {
        let mut bus = Mock::new(&[
            write_config(0x60),
            read_config(0x60),
            // OS (bit 7) reading back set is accepted.
            write_config(0x40),
            read_config(0xC0),
        ]);
        let mut s = Tmp105::new(&mut bus, Address::A0Low);
        assert_eq!(s.resolution(), Resolution::Bits9);
        assert_eq!(s.resolution_c(), 0.5);
        assert_eq!(s.init(Resolution::Bits12), Ok(()));
        assert_eq!(s.resolution(), Resolution::Bits12);
        assert_eq!(s.resolution_c(), 0.0625);
        assert_eq!(s.init(Resolution::Bits11), Ok(()));
        assert_eq!(s.resolution_c(), 0.125);
        bus.done();
    }

    /// A device that does not keep the byte (a register of another width or meaning, a bus
    /// that floats high) is refused, and the resolution is not taken.
    #[test]
    fn init_refuses_a_configuration_that_does_not_read_back() {
        let mut bus = Mock::new(&[
            write_config(0x60),
            read_config(0x00),
            write_config(0x60),
            read_config(0xFF),
        ]);
        let mut s = Tmp105::new(&mut bus, Address::A0Low);
        assert_eq!(
            s.init(Resolution::Bits12),
            Err(Error::ConfigMismatch {
                wrote: 0x60,
                read: 0x00
            })
        );
        assert_eq!(
            s.init(Resolution::Bits12),
            Err(Error::ConfigMismatch {
                wrote: 0x60,
                read: 0xFF
            })
        );
        assert_eq!(s.resolution(), Resolution::Bits9);
        bus.done();
    }

    #[test]
    fn bus_errors_propagate() {
        let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
        let mut bus = Mock::new(&[
            write_config(0x60).with_error(nack),
            write_config(0x60),
            read_config(0).with_error(ErrorKind::ArbitrationLoss),
            read_temp(0).with_error(ErrorKind::Bus),
        ]);
        let mut s = Tmp105::new(&mut bus, Address::A0Low);
        assert_eq!(s.init(Resolution::Bits12), Err(Error::I2c(nack)));
        assert_eq!(
            s.init(Resolution::Bits12),
            Err(Error::I2c(ErrorKind::ArbitrationLoss))
        );
        assert_eq!(s.read_temp_c(), Err(Error::I2c(ErrorKind::Bus)));
        bus.done();
    }

    #[test]
    fn conversions_at_known_points() {
        // Datasheet-style table at 12 bits (word = 12-bit value << 4).
        let points: [(u16, f32); 8] = [
            (0x0000, 0.0),
            (0x1900, 25.0),
            (0x0010, 0.0625),
            (0xFFF0, -0.0625),
            (0xE700, -25.0),
            (0x7FF0, 127.9375),
            (0x8000, -128.0),
            (0x4B00, 75.0),
        ];
        for (raw, want) in points {
            assert_eq!(raw_to_celsius(raw), want, "0x{raw:04X}");
        }
        // Every word converts exactly (16 significant bits): back to the word.
        for raw in 0..=u16::MAX {
            let c = raw_to_celsius(raw);
            assert_eq!((c * 256.0) as i16 as u16, raw);
        }
    }

    #[test]
    fn read_temp_c_through_the_trait() {
        fn read<S: TemperatureSensor>(s: &mut S) -> Result<f32, S::Error> {
            s.read_temp_c()
        }
        let mut bus = Mock::new(&[read_temp(0x1910), read_temp(0xFF80)]);
        let mut s = Tmp105::new(&mut bus, Address::A0Low);
        assert_eq!(s.model(), "TMP105");
        assert_eq!(read(&mut s), Ok(25.0625));
        assert_eq!(read(&mut s), Ok(-0.5));
        bus.done();
    }

    #[test]
    fn release_returns_the_bus() {
        let bus = Mock::new(&[]);
        let s = Tmp105::new(bus, Address::A0High);
        let mut bus = s.release();
        bus.done();
    }

    #[test]
    fn errors_display_one_line() {
        let e: Error<ErrorKind> = Error::ConfigMismatch {
            wrote: 0x60,
            read: 0x00,
        };
        assert_eq!(
            std::format!("{e}"),
            "not a TMP105: configuration 0x60 written, 0x00 read back"
        );
        let e: Error<ErrorKind> =
            Error::I2c(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
        let s = std::format!("{e}");
        assert!(
            s.starts_with("TMP105 bus error: ") && !s.contains('\n'),
            "{s}"
        );
        let _: &dyn core::error::Error = &e;
    }
}
