//! Byte-at-a-time decoders for the gyro serial formats, with exact byte accounting.
//!
//! - [`ecore`]: E-Core 2000 8-byte binary frames: [`EcoreDecoder`], and the encoder
//!   [`ecore::encode`] used by host tools to write captures;
//! - [`dsp3000`]: KVH DSP-3000 21-byte ASCII lines: [`Dsp3000Decoder`];
//! - [`stats`]: the counters, [`ByteStats`].
//!
//! [`crate::driver::GyroReader`] feeds either decoder from an `embedded-hal-nb` serial port.
//! Both decoders implement [`Decoder`]: [`Decoder::push`] takes one received byte and
//! returns a sample when that byte completes a frame; [`Decoder::push_error`] accounts for a
//! byte the UART received with an error; [`Decoder::flush`] ends the stream. They are
//! fixed-size state machines (at most 21 bytes of buffer), do constant work per byte (at
//! most a 20-byte shift), never allocate and never panic, whatever the input. They have no
//! notion of time and assume no sample rate.
//!
//! # Protocol assumptions
//! Source: `spec/serial-protocols.md`, sections 1 and 2. No datasheet of the E-Core 2000
//! digital output is public; the layout is the one a public acquisition driver
//! (`gyroread.c`) parses, and the test vectors were built from that layout, not captured.
//! Every assumption the decoders make is listed here and nowhere else.
//!
//! ## E-Core 2000 binary frame
//! - **E1** A frame is 8 bytes. Bit 7 is the sync flag: set on the first byte of a frame,
//!   clear on the other seven.
//! - **E2** A byte with bit 7 set always starts a new frame, even while a frame is in
//!   progress: the partial frame is dropped as *cut short* (an 8-byte frame cannot contain
//!   a sync byte, so the partial one is certainly damaged).
//! - **E3** A byte with bit 7 clear outside a frame is noise (*no sync*); this also drops the
//!   tail of a frame when the stream starts mid-frame.
//! - **E4** The low 7 bits of the 8 bytes, joined most significant first, are 56 bits =
//!   7 payload bytes `m[0..7)`. The unpack is generic (shifts of the whole 56-bit word); the
//!   reference driver's `0x06` mask (meant `0x60`) is not reproduced. Every 7-byte payload
//!   is representable, so the encoder has no constraint beyond the sync flag.
//! - **E5** A frame is good iff `(m[0] + ... + m[6]) mod 256 == 0`. This sum detects any
//!   single corrupted byte but lets a random corruption through with probability 1/256;
//!   nothing else in the frame can be checked.
//! - **E6** Rate: `counts = i16::from_be_bytes([m[5], m[6]])`, `rate_dps = counts *
//!   full_scale_dps / 32768`, in deg/s. Full scale is configuration (60 and 30 deg/s units
//!   exist), never a constant.
//! - **E7** `m[1..5)` (probably status and temperature) are not interpreted; they are kept
//!   raw in [`EcoreFrame::payload`].
//!
//! ## KVH DSP-3000 ASCII line
//! - **D1** A line is exactly 21 bytes: columns `0..18` hold the value, right-aligned in
//!   the unit's output; column 18 the status; columns 19 and 20 CR LF. The decoder accepts,
//!   in columns `0..18`, any number of leading spaces, one number and at least one space.
//! - **D2** Number: an optional sign (`-`, or `+`), decimal digits with an optional `.`,
//!   at least one digit, no exponent (the unit prints `(-)xxx.xxxxxx`). It is parsed
//!   exactly into an integer mantissa and a count of decimals ([`Dsp3000Value`]); the
//!   conversion to a float and its precision are documented there.
//! - **D3** Status `1` is a valid sample, `0` a fault sample (reported as
//!   [`Dsp3000Line::Fault`], with the value if it parses); anything else is malformed.
//! - **D4** Lines are delimited by the pair CR LF only. Resynchronisation: the bytes
//!   between two CR LF pairs form one segment; a segment yields a line iff its last 21
//!   bytes (CR LF included) are a well-formed line. So garbage in front of a line costs the
//!   garbage only (its bytes are *too long*), and any defect is forgotten at the next CR LF.
//! - **D5** Until the first CR LF the decoder is not synchronised: the first segment yields
//!   a line only if it is a whole well-formed line, otherwise its bytes are *no sync*.
//! - **D6** The value is in deg/s in rate mode (the default), in deg in incremental-angle
//!   (`A`) or integrated-angle (`P`) mode. The decoder sends no command and does not know
//!   the mode; the caller does.
//!
//! ## UART errors (both formats)
//! - **U1** Each error the port reports ([`Decoder::push_error`]) stands for one byte slot
//!   whose value is lost. Bytes the hardware drops without reporting them (an overrun can
//!   lose several) cannot be counted; they show up as damaged frames.
//! - **U2** A frame or line holding an error slot is never decoded. E-Core drops the frame
//!   at its end (8 slots, a new sync byte or [`Decoder::flush`]); an error outside a frame
//!   counts one byte. The DSP-3000 decoder drops at once the segment so far, which can no
//!   longer end in a good line, and goes on with the bytes after the error (a whole line
//!   after it is still decoded). Bytes dropped because of an error, including the rest of
//!   the damaged E-Core frame or DSP-3000 segment, are counted under that error's kind (the
//!   first one if several hit the same frame or segment), which takes precedence over every
//!   other reason.
//!
//! # Byte accounting
//! Every byte (and every error slot) given to a decoder is counted once in
//! [`ByteStats::bytes_total`] and, at every moment, in exactly one of:
//! - [`ByteStats::bytes_good`]: bytes of frames or lines delivered by `push`, fault lines
//!   included (they are well received; the sensor reports a fault);
//! - [`ByteStats::skipped`]: bytes dropped, one counter per [`SkipReason`];
//! - [`ByteStats::bytes_pending`]: bytes held in the partial frame or line, not yet judged.
//!
//! so that after every call
//!
//! ```text
//! bytes_total == bytes_good + skipped.total() + bytes_pending      (ByteStats::is_consistent)
//! ```
//!
//! and [`Decoder::flush`] empties `bytes_pending` (into `skipped.incomplete`, or a UART
//! kind). Frames: [`ByteStats::frames_good`] valid samples delivered,
//! [`ByteStats::frames_fault`] DSP-3000 fault lines delivered, [`ByteStats::frames_bad`]
//! E-Core frames begun (sync byte seen) and dropped, or DSP-3000 line segments (after
//! synchronisation) that hold a UART error or end without a line, each counted once.
//! Counters are `u64` and wrap (they never
//! saturate, so the invariant holds modulo 2^64); at 1 Mbyte/s wrapping takes 580 000
//! years.

pub mod dsp3000;
pub mod ecore;
pub mod stats;

pub use dsp3000::{Dsp3000Decoder, Dsp3000Line, Dsp3000Value};
pub use ecore::{EcoreDecoder, EcoreFrame};
pub use stats::{ByteStats, SkipReason, Skipped};

/// Error a UART reported for one received byte (its value is lost).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UartError {
    /// The receive buffer was overrun: earlier bytes may have been lost too.
    Overrun,
    /// Framing error: no stop bit where one was expected.
    Framing,
    /// Parity check failed.
    Parity,
    /// Noise detected on the line while sampling the byte.
    Noise,
    /// Any other receive error.
    Other,
}

impl core::fmt::Display for UartError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Overrun => "UART overrun",
            Self::Framing => "UART framing error",
            Self::Parity => "UART parity error",
            Self::Noise => "UART noise error",
            Self::Other => "UART receive error",
        })
    }
}

impl core::error::Error for UartError {}

/// A decoder configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// Full scale must be finite and > 0 deg/s.
    BadFullScale,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::BadFullScale => "full scale must be finite and > 0 deg/s",
        })
    }
}

impl core::error::Error for ConfigError {}

/// A byte-at-a-time frame decoder with byte accounting (see the module docs).
pub trait Decoder {
    /// What a complete, accepted frame or line decodes to.
    type Output;

    /// Feeds one received byte; returns the decoded frame when this byte completes one.
    fn push(&mut self, byte: u8) -> Option<Self::Output>;

    /// Accounts for one byte slot the UART received with `error` (its value is lost).
    fn push_error(&mut self, error: UartError);

    /// Ends the stream: drops any partial frame (its bytes go to `skipped.incomplete`, or
    /// to the UART error that damaged it) and forgets the synchronisation.
    fn flush(&mut self);

    /// Counters since construction.
    fn stats(&self) -> &ByteStats;
}
