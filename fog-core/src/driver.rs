//! Non-blocking gyro reader: an `embedded-hal-nb` serial port feeding a frame decoder.
//!
//! [`GyroReader::read`] pulls bytes until the decoder completes a sample, and returns
//! `nb::Error::WouldBlock` as soon as the port has no byte, so it can be polled from a main
//! loop or wrapped in `nb::block!`. A receive error reported by the port is given to the
//! decoder's accounting as one lost byte ([`Decoder::push_error`], with the port's
//! [`ErrorKind`] mapped to a [`UartError`]) and then returned as [`Error::Serial`]; the
//! reader stays usable, call `read` again.
//!
//! ```
//! use fog_core::driver::GyroReader;
//! use fog_core::frame::{ecore, EcoreDecoder};
//! use embedded_hal_mock::eh1::serial::{Mock, Transaction};
//!
//! let mut port = Mock::new(&[
//!     Transaction::read_many(ecore::encode(1000, [0; 4])),
//!     Transaction::read_error(nb::Error::WouldBlock),
//! ]);
//! let decoder = EcoreDecoder::new(60.0).expect("valid full scale");
//! let mut gyro = GyroReader::new(&mut port, decoder);
//! assert_eq!(gyro.read().map(|f| f.rate_dps), Ok(1.8310546875));
//! assert_eq!(gyro.read().map(|f| f.rate_dps), Err(nb::Error::WouldBlock));
//! port.done();
//! ```

use embedded_hal_nb::serial::{self, ErrorKind, Read};

use crate::frame::{ByteStats, Decoder, UartError};

/// Error of a [`GyroReader`], generic over the serial port's error `E`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The port reported a receive error; the byte is already counted as lost.
    Serial(E),
}

impl<E: serial::Error> core::fmt::Display for Error<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Serial(e) => write!(f, "serial receive error: {}", e.kind()),
        }
    }
}

impl<E: serial::Error> core::error::Error for Error<E> {}

impl From<ErrorKind> for UartError {
    fn from(kind: ErrorKind) -> Self {
        match kind {
            ErrorKind::Overrun => Self::Overrun,
            ErrorKind::FrameFormat => Self::Framing,
            ErrorKind::Parity => Self::Parity,
            ErrorKind::Noise => Self::Noise,
            _ => Self::Other,
        }
    }
}

/// A gyro on a serial port: reads bytes from `R` and decodes them with `D`.
#[derive(Debug)]
pub struct GyroReader<R, D> {
    serial: R,
    decoder: D,
}

impl<R, D> GyroReader<R, D> {
    /// Reader of `serial` (already configured: baud rate, 8N1) decoding with `decoder`.
    pub const fn new(serial: R, decoder: D) -> Self {
        Self { serial, decoder }
    }

    /// The decoder (its counters, configuration).
    pub fn decoder(&self) -> &D {
        &self.decoder
    }

    /// The decoder, mutably (for [`Decoder::flush`]).
    pub fn decoder_mut(&mut self) -> &mut D {
        &mut self.decoder
    }

    /// Gives the port and the decoder back.
    pub fn release(self) -> (R, D) {
        (self.serial, self.decoder)
    }
}

impl<R: Read<u8>, D: Decoder> GyroReader<R, D> {
    /// Reads bytes until one completes a sample.
    ///
    /// `WouldBlock` when the port has no more byte (the partial frame is kept);
    /// `Other(Error::Serial)` after a receive error, which the decoder has counted.
    pub fn read(&mut self) -> nb::Result<D::Output, Error<R::Error>> {
        loop {
            match self.serial.read() {
                Ok(byte) => {
                    if let Some(sample) = self.decoder.push(byte) {
                        return Ok(sample);
                    }
                }
                Err(nb::Error::WouldBlock) => return Err(nb::Error::WouldBlock),
                Err(nb::Error::Other(e)) => {
                    self.decoder.push_error(serial::Error::kind(&e).into());
                    return Err(nb::Error::Other(Error::Serial(e)));
                }
            }
        }
    }

    /// The decoder's counters.
    pub fn stats(&self) -> &ByteStats {
        self.decoder.stats()
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::frame::{ecore, Dsp3000Decoder, Dsp3000Line, Dsp3000Value, EcoreDecoder};
    use embedded_hal_mock::eh1::serial::{Mock, Transaction};

    fn ecore60() -> EcoreDecoder {
        match EcoreDecoder::new(60.0) {
            Ok(d) => d,
            Err(e) => panic!("{e}"),
        }
    }

    fn err(kind: ErrorKind) -> Transaction<u8> {
        Transaction::read_error(nb::Error::Other(kind))
    }

    fn block() -> Transaction<u8> {
        Transaction::read_error(nb::Error::WouldBlock)
    }

    #[test]
    fn frames_and_would_block() {
        let f1 = ecore::encode(1000, [1, 2, 3, 4]);
        let f2 = ecore::encode(-1000, [0; 4]);
        let mut port = Mock::new(&[
            Transaction::read_many(&f1[..5]),
            block(),
            Transaction::read_many(&f1[5..]),
            Transaction::read_many([0x00, 0x12]),
            Transaction::read_many(f2),
            block(),
        ]);
        let mut gyro = GyroReader::new(&mut port, ecore60());
        assert_eq!(gyro.read().map(|f| f.counts), Err(nb::Error::WouldBlock));
        assert_eq!(gyro.stats().bytes_pending, 5);
        let f = gyro.read();
        assert_eq!(f.map(|f| (f.counts, f.raw())), Ok((1000, [1, 2, 3, 4])));
        assert_eq!(gyro.read().map(|f| f.rate_dps), Ok(-1.831_054_7));
        assert_eq!(gyro.read().map(|f| f.counts), Err(nb::Error::WouldBlock));
        let s = *gyro.stats();
        assert_eq!(
            (s.bytes_total, s.bytes_good, s.skipped.no_sync),
            (18, 16, 2)
        );
        port.done();
    }

    /// Each kind damages one frame; the frame after it is whole.
    #[test]
    fn uart_error_kinds_are_counted() {
        let f = ecore::encode(123, [0; 4]);
        let kinds = [
            (ErrorKind::Overrun, UartError::Overrun),
            (ErrorKind::FrameFormat, UartError::Framing),
            (ErrorKind::Parity, UartError::Parity),
            (ErrorKind::Noise, UartError::Noise),
            (ErrorKind::Other, UartError::Other),
        ];
        let mut script = Vec::new();
        for (kind, _) in kinds {
            // An error in place of byte 3: 3 bytes, the error slot, 4 bytes.
            script.push(Transaction::read_many(&f[..3]));
            script.push(err(kind));
            script.push(Transaction::read_many(&f[4..]));
            script.push(Transaction::read_many(f));
        }
        let mut port = Mock::new(&script);
        let mut gyro = GyroReader::new(&mut port, ecore60());
        for (kind, uart) in kinds {
            assert_eq!(
                gyro.read().map(|f| f.counts),
                Err(nb::Error::Other(Error::Serial(kind)))
            );
            assert_eq!(gyro.read().map(|f| f.counts), Ok(123));
            let s = gyro.stats();
            assert_eq!(
                s.skipped.get(crate::frame::SkipReason::Uart(uart)),
                8,
                "{uart}"
            );
            assert!(s.is_consistent());
        }
        let s = *gyro.stats();
        assert_eq!((s.frames_good, s.frames_bad, s.skipped.uart()), (5, 5, 40));
        port.done();
    }

    #[test]
    fn error_display() {
        let e: Error<ErrorKind> = Error::Serial(ErrorKind::Parity);
        assert_eq!(
            std::format!("{e}"),
            "serial receive error: Parity check failed"
        );
    }

    #[test]
    fn dsp3000_lines() {
        let mut port = Mock::new(&[
            Transaction::read_many(b"3   1\r\n"),
            Transaction::read_many(b"      -1.000001   0\r\n"),
            Transaction::read_many(b"      12.500000   1\r"),
            err(ErrorKind::Noise),
            Transaction::read_many(b"       0.015733   1\r\n"),
        ]);
        let mut gyro = GyroReader::new(&mut port, Dsp3000Decoder::new());
        let fault = Dsp3000Value {
            mantissa: -1_000_001,
            decimals: 6,
        };
        assert_eq!(gyro.read(), Ok(Dsp3000Line::Fault(Some(fault))));
        assert_eq!(
            gyro.read(),
            Err(nb::Error::Other(Error::Serial(ErrorKind::Noise)))
        );
        let l = gyro.read().ok().and_then(Dsp3000Line::valid);
        assert_eq!(l.map(Dsp3000Value::to_f32), Some(0.015733));
        let s = *gyro.stats();
        assert_eq!(
            (s.skipped.no_sync, s.skipped.uart_noise, s.bytes_good),
            (7, 21, 42)
        );
        assert_eq!((s.frames_good, s.frames_fault, s.frames_bad), (1, 1, 1));
        let (port, _) = gyro.release();
        port.done();
    }
}
