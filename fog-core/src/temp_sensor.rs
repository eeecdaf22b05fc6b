//! One interface over the board temperature sensors that fog-core drives: the TI TMP117
//! ([`crate::tmp117`]) and the TI TMP105 ([`crate::tmp105`]).
//!
//! The firmware probes for a sensor at boot and then only reads it; this trait is that
//! "only reads it" part, so the code that refreshes and holds a reading does not care which
//! part answered. Probing and configuring stay with each driver (the parts have nothing in
//! common there: the TMP117 has an id register, the TMP105 none).
//!
//! ```
//! use embedded_hal_mock::eh1::i2c::{Mock, Transaction};
//! use fog_core::temp_sensor::TemperatureSensor;
//! use fog_core::{tmp105, tmp117};
//!
//! fn read_twice<S: TemperatureSensor>(s: &mut S) -> Result<[f32; 2], S::Error> {
//!     Ok([s.read_temp_c()?, s.read_temp_c()?])
//! }
//!
//! let mut bus117 = Mock::new(&[
//!     Transaction::write_read(0x48, vec![0x00], vec![0x0C, 0x80]), // 25 °C
//!     Transaction::write_read(0x48, vec![0x00], vec![0x0C, 0x81]), // 25.0078125 °C
//! ]);
//! let mut bus105 = Mock::new(&[
//!     Transaction::write_read(0x49, vec![0x00], vec![0x19, 0x00]), // 25 °C
//!     Transaction::write_read(0x49, vec![0x00], vec![0x19, 0x10]), // 25.0625 °C
//! ]);
//! let mut a = tmp117::Tmp117::new(&mut bus117, tmp117::Address::Gnd);
//! let mut b = tmp105::Tmp105::new(&mut bus105, tmp105::Address::A0High);
//! assert_eq!(read_twice(&mut a), Ok([25.0, 25.0078125]));
//! assert_eq!(read_twice(&mut b), Ok([25.0, 25.0625]));
//! assert_eq!((a.model(), b.model()), ("TMP117", "TMP105"));
//! bus117.done();
//! bus105.done();
//! ```

/// A temperature sensor that has been found and configured: reads and what they mean.
pub trait TemperatureSensor {
    /// The driver's error (bus errors inside).
    type Error: core::fmt::Debug;

    /// The part's name, for logs (`"TMP117"`, `"TMP105"`).
    fn model(&self) -> &'static str;

    /// The 7-bit bus address.
    fn bus_address(&self) -> u8;

    /// One LSB of a reading as the part is configured now, °C.
    fn resolution_c(&self) -> f32;

    /// The last conversion result, °C.
    fn read_temp_c(&mut self) -> Result<f32, Self::Error>;
}
