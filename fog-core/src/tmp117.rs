//! Driver for the Texas Instruments TMP117 digital temperature sensor on I2C.
//!
//! Generic over [`embedded_hal::i2c::I2c`] (embedded-hal 1.0) and over its bus error: every
//! method returns [`Error<E>`] with the bus's own error inside. No heap, no panic path, no
//! floating point besides the final conversion in [`Tmp117::read_temp_c`]. Implements
//! [`TemperatureSensor`], as the TMP105 driver does.
//!
//! # Register map used here
//! Source: TI TMP117 datasheet (SNOSD82, "TMP117 High-Accuracy, Low-Power, Digital Temperature
//! Sensor With SMBus and I2C-Compatible Interface"), section 7.6 "Register Map"; written from
//! those facts, not checked against a device (this crate has never run on one).
//!
//! | reg | name | used as |
//! |---|---|---|
//! | `0x00` | Temp_Result | 16-bit two's complement, 1 LSB = 7.8125 m°C (1/128 °C); reads `0x8000` (-256 °C) from power-on until the first conversion ends |
//! | `0x01` | Configuration | bit 13 Data_Ready (cleared by reading this register), bits 11:10 MOD (00 continuous, 01 shutdown, 10 continuous, 11 one-shot), bits 9:7 CONV, bits 6:5 AVG (1, 8, 32, 64 conversions), bits 4:2 alert pin, bit 1 soft reset; power-on value `0x0220` (continuous, CONV 100 = 1 s cycle, 8 averages) |
//! | `0x0F` | Device_ID | bits 15:12 revision, bits 11:0 device id `0x117` (register reads `0x0117` on revision 0) |
//!
//! Registers are big-endian on the wire: a read is `write_read(addr, [reg], [msb, lsb])`, a
//! write is `write(addr, [reg, msb, lsb])`. Writing the configuration register changes the
//! running configuration only: the EEPROM copy that the device loads at power-on is not
//! touched (that needs the EEPROM unlock sequence, not implemented).
//!
//! Accuracy (datasheet): ±0.1 °C from -20 °C to 50 °C, ±0.15 °C from -40 °C to 70 °C, ±0.2 °C
//! from -40 °C to 100 °C; operating range -55 °C to 150 °C.
//!
//! ```
//! use embedded_hal_mock::eh1::i2c::{Mock, Transaction};
//! use fog_core::tmp117::{Address, Tmp117};
//!
//! let addr = Address::Gnd as u8; // 0x48
//! let mut bus = Mock::new(&[
//!     Transaction::write_read(addr, vec![0x0F], vec![0x01, 0x17]), // device id
//!     Transaction::write_read(addr, vec![0x00], vec![0x0C, 0x80]), // 25 °C
//! ]);
//! let mut sensor = Tmp117::new(&mut bus, Address::Gnd);
//! assert_eq!(sensor.probe(), Ok(0x0117));
//! assert_eq!(sensor.read_temp_c(), Ok(25.0));
//! bus.done();
//! ```

use embedded_hal::i2c::{self, I2c};

use crate::temp_sensor::TemperatureSensor;

/// Temperature of one LSB of the result register, °C (7.8125 m°C).
pub const CELSIUS_PER_LSB: f32 = 1.0 / 128.0;

/// Device-id field (bits 11:0 of register `0x0F`) of every TMP117.
pub const DEVICE_ID: u16 = 0x0117;

/// Content of the result register from power-on until the first conversion has ended
/// (-256 °C, outside the sensor's range).
pub const RESULT_AT_RESET: u16 = 0x8000;

/// Register addresses (datasheet section 7.6).
mod reg {
    pub const TEMP_RESULT: u8 = 0x00;
    pub const CONFIGURATION: u8 = 0x01;
    pub const DEVICE_ID: u8 = 0x0F;
}

/// Configuration register fields.
mod cfg {
    pub const DATA_READY: u16 = 1 << 13;
    pub const MOD_SHIFT: u16 = 10;
    pub const CONV_SHIFT: u16 = 7;
    pub const AVG_SHIFT: u16 = 5;
    pub const TWO_BITS: u16 = 0b11;
    pub const THREE_BITS: u16 = 0b111;
}

/// I2C address, set by the ADD0 pin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Address {
    /// ADD0 to ground: `0x48`.
    #[default]
    Gnd = 0x48,
    /// ADD0 to V+: `0x49`.
    Vplus = 0x49,
    /// ADD0 to SDA: `0x4A`.
    Sda = 0x4A,
    /// ADD0 to SCL: `0x4B`.
    Scl = 0x4B,
}

/// Error of a [`Tmp117`], generic over the bus error `E`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The bus reported an error (no acknowledge when nothing answers at the address).
    I2c(E),
    /// A device answered, but its id register (bits 11:0) is not `0x117`; `id` is the
    /// whole register.
    WrongDevice {
        /// Content of register `0x0F`.
        id: u16,
    },
    /// The result register still holds its power-on value (`0x8000`): no conversion has
    /// ended since power-on or reset.
    NotReady,
}

impl<E: i2c::Error> core::fmt::Display for Error<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::I2c(e) => write!(f, "TMP117 bus error: {}", e.kind()),
            Self::WrongDevice { id } => {
                write!(
                    f,
                    "not a TMP117: device id register 0x{id:04X}, expected 0x0117"
                )
            }
            Self::NotReady => f.write_str("TMP117 has no conversion result yet"),
        }
    }
}

impl<E: i2c::Error> core::error::Error for Error<E> {}

/// Conversion mode (configuration bits 11:10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    /// Converts continuously, one result per [`ConversionCycle`] (the power-on mode).
    #[default]
    Continuous,
    /// No conversion; lowest supply current.
    Shutdown,
    /// One conversion (with its averaging), then shutdown. Started by each
    /// [`Tmp117::configure`] or [`Tmp117::trigger_one_shot`].
    OneShot,
}

/// Conversions averaged per result (configuration bits 6:5). The active time of one result
/// is 15.5 ms per conversion: 15.5 ms, 125 ms, 500 ms, 1 s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Averaging {
    /// One conversion per result.
    None,
    /// 8 conversions per result (the power-on value).
    #[default]
    Avg8,
    /// 32 conversions per result.
    Avg32,
    /// 64 conversions per result.
    Avg64,
}

/// Conversion cycle in continuous mode (configuration bits 9:7, datasheet table "Conversion
/// Cycle Time"). The cycle is never shorter than the averaging's active time: with 8
/// averages the two shortest settings are both 125 ms, with 32 averages everything up to
/// `Ms500` is 500 ms, with 64 averages up to `S1` is 1 s. See
/// [`Config::cycle_time_ms`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConversionCycle {
    /// CONV 000: back to back (15.5 ms without averaging).
    Fastest,
    /// CONV 001: 125 ms.
    Ms125,
    /// CONV 010: 250 ms.
    Ms250,
    /// CONV 011: 500 ms.
    Ms500,
    /// CONV 100: 1 s (the power-on value).
    #[default]
    S1,
    /// CONV 101: 4 s.
    S4,
    /// CONV 110: 8 s.
    S8,
    /// CONV 111: 16 s.
    S16,
}

/// What [`Tmp117::configure`] writes. The alert-pin bits (4:2) stay 0 (alert mode, active
/// low, pin shows the alert flags), as at power-on; the EEPROM is not written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Conversion mode.
    pub mode: Mode,
    /// Conversions per result.
    pub averaging: Averaging,
    /// Cycle time in continuous mode (ignored in one-shot mode).
    pub cycle: ConversionCycle,
}

impl Config {
    /// The configuration register word.
    pub const fn register(self) -> u16 {
        let mode: u16 = match self.mode {
            Mode::Continuous => 0b00,
            Mode::Shutdown => 0b01,
            Mode::OneShot => 0b11,
        };
        let avg: u16 = match self.averaging {
            Averaging::None => 0b00,
            Averaging::Avg8 => 0b01,
            Averaging::Avg32 => 0b10,
            Averaging::Avg64 => 0b11,
        };
        (mode << cfg::MOD_SHIFT)
            | ((self.cycle as u16 & cfg::THREE_BITS) << cfg::CONV_SHIFT)
            | (avg << cfg::AVG_SHIFT)
    }

    /// Decodes the mode, averaging and cycle fields of a configuration register word
    /// (mode 10 reads as continuous, as the datasheet says it behaves).
    pub const fn from_register(word: u16) -> Self {
        let mode = match (word >> cfg::MOD_SHIFT) & cfg::TWO_BITS {
            0b01 => Mode::Shutdown,
            0b11 => Mode::OneShot,
            _ => Mode::Continuous,
        };
        let averaging = match (word >> cfg::AVG_SHIFT) & cfg::TWO_BITS {
            0b00 => Averaging::None,
            0b01 => Averaging::Avg8,
            0b10 => Averaging::Avg32,
            _ => Averaging::Avg64,
        };
        let cycle = match (word >> cfg::CONV_SHIFT) & cfg::THREE_BITS {
            0 => ConversionCycle::Fastest,
            1 => ConversionCycle::Ms125,
            2 => ConversionCycle::Ms250,
            3 => ConversionCycle::Ms500,
            4 => ConversionCycle::S1,
            5 => ConversionCycle::S4,
            6 => ConversionCycle::S8,
            _ => ConversionCycle::S16,
        };
        Self {
            mode,
            averaging,
            cycle,
        }
    }

    /// Time of one result, ms: the averaging's active time (15.5 ms per conversion) in
    /// one-shot mode, the larger of it and the cycle in continuous mode; 0 in shutdown.
    pub const fn cycle_time_ms(self) -> f32 {
        let active = match self.averaging {
            Averaging::None => 15.5,
            Averaging::Avg8 => 125.0,
            Averaging::Avg32 => 500.0,
            Averaging::Avg64 => 1000.0,
        };
        let cycle = match self.cycle {
            ConversionCycle::Fastest => 0.0,
            ConversionCycle::Ms125 => 125.0,
            ConversionCycle::Ms250 => 250.0,
            ConversionCycle::Ms500 => 500.0,
            ConversionCycle::S1 => 1000.0,
            ConversionCycle::S4 => 4000.0,
            ConversionCycle::S8 => 8000.0,
            ConversionCycle::S16 => 16000.0,
        };
        match self.mode {
            Mode::Shutdown => 0.0,
            Mode::OneShot => active,
            Mode::Continuous => {
                if cycle > active {
                    cycle
                } else {
                    active
                }
            }
        }
    }
}

/// Result register content to °C: two's complement times 7.8125 m°C. Exact in `f32` for
/// every register value (16 significant bits); `0x7FFF` is 255.9921875 °C, `0x8000` -256 °C.
pub const fn raw_to_celsius(raw: u16) -> f32 {
    raw as i16 as f32 * CELSIUS_PER_LSB
}

/// A TMP117 at one address of bus `I2C`.
#[derive(Debug)]
pub struct Tmp117<I2C> {
    i2c: I2C,
    address: u8,
}

impl<I2C> Tmp117<I2C> {
    /// Driver of the sensor at `address` on `i2c`. Talks to nothing: call
    /// [`probe`](Self::probe) to check that a TMP117 answers.
    pub const fn new(i2c: I2C, address: Address) -> Self {
        Self {
            i2c,
            address: address as u8,
        }
    }

    /// The 7-bit bus address.
    pub const fn address(&self) -> u8 {
        self.address
    }

    /// Gives the bus back.
    pub fn release(self) -> I2C {
        self.i2c
    }
}

impl<I2C: I2c> Tmp117<I2C> {
    /// Reads the device id register and checks its id field (bits 11:0) is `0x117`;
    /// returns the whole register (bits 15:12 are the revision).
    ///
    /// `Err(Error::I2c(_))` when nothing acknowledges, `Err(Error::WrongDevice)` when
    /// another device answers at the address.
    pub fn probe(&mut self) -> Result<u16, Error<I2C::Error>> {
        let id = self.read_register(reg::DEVICE_ID)?;
        if id & 0x0FFF == DEVICE_ID {
            Ok(id)
        } else {
            Err(Error::WrongDevice { id })
        }
    }

    /// [`probe`](Self::probe), then [`configure`](Self::configure) with `config`.
    pub fn init(&mut self, config: Config) -> Result<u16, Error<I2C::Error>> {
        let id = self.probe()?;
        self.configure(config)?;
        Ok(id)
    }

    /// Writes `config` to the configuration register (not to the EEPROM). In one-shot mode
    /// this starts a conversion.
    pub fn configure(&mut self, config: Config) -> Result<(), Error<I2C::Error>> {
        self.write_register(reg::CONFIGURATION, config.register())
    }

    /// Reads the running configuration.
    pub fn config(&mut self) -> Result<Config, Error<I2C::Error>> {
        Ok(Config::from_register(
            self.read_register(reg::CONFIGURATION)?,
        ))
    }

    /// Starts one conversion with `averaging` (one-shot mode); the result is ready after
    /// [`Config::cycle_time_ms`] of that configuration, see [`data_ready`](Self::data_ready).
    pub fn trigger_one_shot(&mut self, averaging: Averaging) -> Result<(), Error<I2C::Error>> {
        self.configure(Config {
            mode: Mode::OneShot,
            averaging,
            cycle: ConversionCycle::Fastest,
        })
    }

    /// Whether a conversion has ended since the configuration register was last read (its
    /// Data_Ready flag; this read clears it).
    pub fn data_ready(&mut self) -> Result<bool, Error<I2C::Error>> {
        Ok(self.read_register(reg::CONFIGURATION)? & cfg::DATA_READY != 0)
    }

    /// The result register as it is (two's complement, 7.8125 m°C per LSB); `0x8000` before
    /// the first conversion. See [`raw_to_celsius`].
    pub fn read_raw(&mut self) -> Result<u16, Error<I2C::Error>> {
        self.read_register(reg::TEMP_RESULT)
    }

    /// The last conversion result, °C (resolution 7.8125 m°C).
    ///
    /// `Err(Error::NotReady)` while the register holds its power-on value `0x8000`.
    pub fn read_temp_c(&mut self) -> Result<f32, Error<I2C::Error>> {
        match self.read_raw()? {
            RESULT_AT_RESET => Err(Error::NotReady),
            raw => Ok(raw_to_celsius(raw)),
        }
    }

    fn read_register(&mut self, register: u8) -> Result<u16, Error<I2C::Error>> {
        let mut word = [0u8; 2];
        self.i2c
            .write_read(self.address, &[register], &mut word)
            .map_err(Error::I2c)?;
        Ok(u16::from_be_bytes(word))
    }

    fn write_register(&mut self, register: u8, value: u16) -> Result<(), Error<I2C::Error>> {
        let [msb, lsb] = value.to_be_bytes();
        self.i2c
            .write(self.address, &[register, msb, lsb])
            .map_err(Error::I2c)
    }
}

impl<I2C: I2c> TemperatureSensor for Tmp117<I2C> {
    type Error = Error<I2C::Error>;

    fn model(&self) -> &'static str {
        "TMP117"
    }

    fn bus_address(&self) -> u8 {
        self.address
    }

    /// 7.8125 m°C whatever the averaging.
    fn resolution_c(&self) -> f32 {
        CELSIUS_PER_LSB
    }

    fn read_temp_c(&mut self) -> Result<f32, Self::Error> {
        Tmp117::read_temp_c(self)
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

    fn read(register: u8, word: u16) -> Transaction {
        Transaction::write_read(ADDR, vec![register], word.to_be_bytes().to_vec())
    }

    #[test]
    fn addresses_follow_add0() {
        let a = [Address::Gnd, Address::Vplus, Address::Sda, Address::Scl];
        assert_eq!(a.map(|a| a as u8), [0x48, 0x49, 0x4A, 0x4B]);
        let mut bus = Mock::new(&[Transaction::write_read(0x4B, vec![0x0F], vec![0x01, 0x17])]);
        let mut s = Tmp117::new(&mut bus, Address::Scl);
        assert_eq!(s.address(), 0x4B);
        assert_eq!(s.probe(), Ok(0x0117));
        bus.done();
    }

    /// Any revision of a TMP117 passes; a TMP116 (0x1116) and a bus that floats high do not.
    #[test]
    fn probe_checks_the_id_field() {
        let cases = [
            (0x0117, Ok(0x0117)),
            (0x1117, Ok(0x1117)),
            (0x1116, Err(Error::WrongDevice { id: 0x1116 })),
            (0xFFFF, Err(Error::WrongDevice { id: 0xFFFF })),
        ];
        let script: std::vec::Vec<_> = cases.iter().map(|&(id, _)| read(0x0F, id)).collect();
        let mut bus = Mock::new(&script);
        let mut s = Tmp117::new(&mut bus, Address::Gnd);
        for (id, want) in cases {
            assert_eq!(s.probe(), want, "id register 0x{id:04X}");
        }
        bus.done();
    }

    #[test]
    fn bus_errors_propagate() {
        let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
        let mut bus = Mock::new(&[
            read(0x0F, 0).with_error(nack),
            read(0x00, 0).with_error(ErrorKind::Bus),
            Transaction::write(ADDR, vec![0x01, 0x02, 0x20]).with_error(ErrorKind::ArbitrationLoss),
            read(0x01, 0).with_error(ErrorKind::Overrun),
        ]);
        let mut s = Tmp117::new(&mut bus, Address::Gnd);
        assert_eq!(s.probe(), Err(Error::I2c(nack)));
        assert_eq!(s.read_temp_c(), Err(Error::I2c(ErrorKind::Bus)));
        assert_eq!(
            s.configure(Config::default()),
            Err(Error::I2c(ErrorKind::ArbitrationLoss))
        );
        assert_eq!(s.data_ready(), Err(Error::I2c(ErrorKind::Overrun)));
        bus.done();
    }

    #[test]
    fn init_stops_at_a_failed_probe() {
        // Wrong device: nothing is written.
        let mut bus = Mock::new(&[read(0x0F, 0x0075)]);
        let mut s = Tmp117::new(&mut bus, Address::Gnd);
        assert_eq!(
            s.init(Config::default()),
            Err(Error::WrongDevice { id: 0x0075 })
        );
        bus.done();
    }

    #[test]
    fn init_writes_the_configuration() {
        let cfg = Config {
            mode: Mode::Continuous,
            averaging: Averaging::Avg32,
            cycle: ConversionCycle::S1,
        };
        // MOD 00, CONV 100, AVG 10: 0b0000_0010_0100_0000.
        assert_eq!(cfg.register(), 0x0240);
        let mut bus = Mock::new(&[
            read(0x0F, 0x0117),
            Transaction::write(ADDR, vec![0x01, 0x02, 0x40]),
        ]);
        let mut s = Tmp117::new(&mut bus, Address::Gnd);
        assert_eq!(s.init(cfg), Ok(0x0117));
        bus.done();
    }

    #[test]
    fn power_on_configuration_decodes() {
        // 0x0220: continuous, CONV 100 (1 s), AVG 01 (8).
        assert_eq!(Config::from_register(0x0220), Config::default());
        assert_eq!(Config::default().register(), 0x0220);
        // MOD 10 behaves as continuous; flag bits (15:12) and alert bits are ignored.
        let c = Config::from_register(0xF800 | 0b1_1111);
        assert_eq!(c.mode, Mode::Continuous);
    }

    #[test]
    fn config_round_trips_every_field() {
        let modes = [Mode::Continuous, Mode::Shutdown, Mode::OneShot];
        let avgs = [
            Averaging::None,
            Averaging::Avg8,
            Averaging::Avg32,
            Averaging::Avg64,
        ];
        let cycles = [
            ConversionCycle::Fastest,
            ConversionCycle::Ms125,
            ConversionCycle::Ms250,
            ConversionCycle::Ms500,
            ConversionCycle::S1,
            ConversionCycle::S4,
            ConversionCycle::S8,
            ConversionCycle::S16,
        ];
        for mode in modes {
            for averaging in avgs {
                for cycle in cycles {
                    let c = Config {
                        mode,
                        averaging,
                        cycle,
                    };
                    assert_eq!(c.register() & !0x0FE0, 0, "{c:?}");
                    assert_eq!(Config::from_register(c.register()), c);
                }
            }
        }
    }

    #[test]
    fn cycle_times() {
        let c = |mode, averaging, cycle| {
            Config {
                mode,
                averaging,
                cycle,
            }
            .cycle_time_ms()
        };
        use Averaging as A;
        use ConversionCycle as C;
        use Mode as M;
        assert_eq!(c(M::Continuous, A::None, C::Fastest), 15.5);
        assert_eq!(c(M::Continuous, A::Avg8, C::Fastest), 125.0);
        assert_eq!(c(M::Continuous, A::Avg32, C::Ms250), 500.0);
        assert_eq!(c(M::Continuous, A::Avg64, C::Ms500), 1000.0);
        assert_eq!(c(M::Continuous, A::Avg8, C::S1), 1000.0);
        assert_eq!(c(M::Continuous, A::None, C::S16), 16000.0);
        assert_eq!(c(M::OneShot, A::Avg32, C::S16), 500.0);
        assert_eq!(c(M::Shutdown, A::Avg64, C::S1), 0.0);
    }

    #[test]
    fn conversions_at_known_points() {
        let points: [(u16, f32); 7] = [
            (0x0000, 0.0),
            (0x0C80, 25.0),
            (0xFF80, -1.0),
            (0x0001, 0.0078125),
            (0xFFFF, -0.0078125),
            (0x7FFF, 255.992_19),
            (0x8000, -256.0),
        ];
        for (raw, want) in points {
            assert_eq!(raw_to_celsius(raw), want, "0x{raw:04X}");
        }
        assert_eq!(raw_to_celsius(0x7FFF), 32767.0 / 128.0);
    }

    #[test]
    fn read_temp_c_converts_and_reports_not_ready() {
        let mut bus = Mock::new(&[
            read(0x00, 0x0000),
            read(0x00, 0x0C80),
            read(0x00, 0xFF80),
            read(0x00, 0x7FFF),
            read(0x00, 0x8000),
            read(0x00, 0x8000),
            read(0x00, 0x8001),
        ]);
        let mut s = Tmp117::new(&mut bus, Address::Gnd);
        assert_eq!(s.read_temp_c(), Ok(0.0));
        assert_eq!(s.read_temp_c(), Ok(25.0));
        assert_eq!(s.read_temp_c(), Ok(-1.0));
        assert_eq!(s.read_temp_c(), Ok(32767.0 / 128.0));
        assert_eq!(s.read_temp_c(), Err(Error::NotReady));
        assert_eq!(s.read_raw(), Ok(0x8000));
        assert_eq!(s.read_temp_c(), Ok(-32767.0 / 128.0));
        bus.done();
    }

    #[test]
    fn one_shot_and_data_ready() {
        let mut bus = Mock::new(&[
            // MOD 11, CONV 000, AVG 00.
            Transaction::write(ADDR, vec![0x01, 0x0C, 0x00]),
            read(0x01, 0x0C00),
            read(0x01, 0x2C00),
            read(0x00, 0x0C80),
        ]);
        let mut s = Tmp117::new(&mut bus, Address::Gnd);
        assert_eq!(s.trigger_one_shot(Averaging::None), Ok(()));
        assert_eq!(s.data_ready(), Ok(false));
        assert_eq!(s.data_ready(), Ok(true));
        assert_eq!(s.read_temp_c(), Ok(25.0));
        bus.done();
    }

    #[test]
    fn config_reads_back() {
        let mut bus = Mock::new(&[read(0x01, 0x2220)]);
        let mut s = Tmp117::new(&mut bus, Address::Gnd);
        assert_eq!(s.config(), Ok(Config::default()));
        bus.done();
    }

    #[test]
    fn release_returns_the_bus() {
        let bus = Mock::new(&[]);
        let s = Tmp117::new(bus, Address::Sda);
        let mut bus = s.release();
        bus.done();
    }

    #[test]
    fn errors_display_one_line() {
        let e: Error<ErrorKind> = Error::WrongDevice { id: 0x1116 };
        assert_eq!(
            std::format!("{e}"),
            "not a TMP117: device id register 0x1116, expected 0x0117"
        );
        let e: Error<ErrorKind> =
            Error::I2c(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
        let s = std::format!("{e}");
        assert!(
            s.starts_with("TMP117 bus error: ") && !s.contains('\n'),
            "{s}"
        );
        let _: &dyn core::error::Error = &e;
    }
}
