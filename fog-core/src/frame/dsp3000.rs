//! KVH DSP-3000 ASCII line: decoder and number parser.
//!
//! Layout and assumptions D1-D6: see the [parent module](super#kvh-dsp-3000-ascii-line).
//!
//! ```text
//! column  0         1         2
//!         012345678901234567890
//!         "       0.015733   1\r\n"     value right-aligned in 0..18, status at 18, CR LF
//! ```

use super::stats::{ByteStats, SkipReason};
use super::{Decoder, UartError};

/// Bytes per line, CR LF included.
pub const LINE_LEN: usize = 21;
/// Columns `0..VALUE_FIELD_LEN` hold the value (leading spaces, number, spaces).
pub const VALUE_FIELD_LEN: usize = 18;
/// Column of the status character.
pub const STATUS_AT: usize = 18;
/// Status character of a valid sample.
pub const STATUS_VALID: u8 = b'1';
/// Status character of a fault sample.
pub const STATUS_FAULT: u8 = b'0';

const CR: u8 = b'\r';
const LF: u8 = b'\n';

/// Most decimals a value may have: enough for any number that fits the value field.
pub const MAX_DECIMALS: u8 = 18;

/// `10^d` for `d` in `0..=MAX_DECIMALS`, f32 (exact up to `10^10`).
const POW10_F32: [f32; MAX_DECIMALS as usize + 1] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18,
];
/// `10^d` for `d` in `0..=MAX_DECIMALS`, f64 (all exact).
const POW10_F64: [f64; MAX_DECIMALS as usize + 1] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18,
];

/// A decimal value exactly as printed: `mantissa / 10^decimals`.
///
/// Unit: deg/s in rate mode (the default), deg in angle modes (assumption D6).
///
/// # Precision of the conversions
/// The parse is exact. [`Self::to_f32`] computes `mantissa as f32 / 10^decimals` in f32:
/// both operands are exact when `|mantissa| <= 2^24 = 16_777_216` and `decimals <= 10`, and
/// an IEEE division of exact operands is correctly rounded, so the result is then the f32
/// nearest to the printed decimal (every value up to 8 significant digits, e.g. `16.777216`).
/// Beyond that (the 9 digits of `-999.999999`) the mantissa is rounded first, and the error
/// stays within about 1 ulp (relative 1.2e-7). f32 resolves about 7 significant digits, so
/// a 6-decimal value above 100 deg/s does not survive in f32 anyway; use [`Self::to_f64`]
/// (correctly rounded whenever `|mantissa| <= 2^53`, i.e. 15 digits) or the exact fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Dsp3000Value {
    /// The printed digits as an integer, with the sign.
    pub mantissa: i64,
    /// Digits after the decimal point, `0..=MAX_DECIMALS`.
    pub decimals: u8,
}

impl Dsp3000Value {
    /// Parses a number: optional sign (`-` or `+`), digits with at most one `.`, at least
    /// one digit, no exponent, at most 18 digits. `None` for anything else (spaces
    /// included).
    pub fn parse(s: &[u8]) -> Option<Self> {
        let (negative, digits) = match s.split_first() {
            Some((b'-', rest)) => (true, rest),
            Some((b'+', rest)) => (false, rest),
            _ => (false, s),
        };
        let mut mantissa: i64 = 0;
        let mut n_digits = 0usize;
        let mut decimals: Option<u8> = None;
        for &c in digits {
            match c {
                b'0'..=b'9' => {
                    n_digits += 1;
                    if n_digits > usize::from(MAX_DECIMALS) {
                        return None;
                    }
                    mantissa = mantissa * 10 + i64::from(c - b'0');
                    if let Some(d) = decimals.as_mut() {
                        *d += 1;
                    }
                }
                b'.' if decimals.is_none() => decimals = Some(0),
                _ => return None,
            }
        }
        if n_digits == 0 {
            return None;
        }
        Some(Self {
            mantissa: if negative { -mantissa } else { mantissa },
            decimals: decimals.unwrap_or(0),
        })
    }

    /// Value as f32 (precision: see the type docs).
    pub fn to_f32(self) -> f32 {
        let p = POW10_F32
            .get(usize::from(self.decimals))
            .copied()
            .unwrap_or(f32::INFINITY);
        self.mantissa as f32 / p
    }

    /// Value as f64 (precision: see the type docs).
    pub fn to_f64(self) -> f64 {
        let p = POW10_F64
            .get(usize::from(self.decimals))
            .copied()
            .unwrap_or(f64::INFINITY);
        self.mantissa as f64 / p
    }
}

/// One well-formed line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Dsp3000Line {
    /// Status `1`: a valid sample.
    Valid(Dsp3000Value),
    /// Status `0`: the unit reports a fault; the value is given if it parses but must not
    /// be used as a measurement.
    Fault(Option<Dsp3000Value>),
}

impl Dsp3000Line {
    /// Parses one whole line (assumptions D1-D3). `None` if malformed.
    pub fn parse(line: &[u8; LINE_LEN]) -> Option<Self> {
        let (field, tail) = line.split_at(VALUE_FIELD_LEN);
        let [status, CR, LF] = *tail else {
            return None;
        };
        let value = parse_field(field);
        match status {
            STATUS_VALID => value.map(Self::Valid),
            STATUS_FAULT => Some(Self::Fault(value)),
            _ => None,
        }
    }

    /// The sample, if valid.
    pub fn valid(self) -> Option<Dsp3000Value> {
        match self {
            Self::Valid(v) => Some(v),
            Self::Fault(_) => None,
        }
    }
}

/// Value field: leading spaces, one number, at least one trailing space.
fn parse_field(field: &[u8]) -> Option<Dsp3000Value> {
    let start = field.iter().position(|&c| c != b' ')?;
    let len = field[start..].iter().position(|&c| c == b' ')?;
    let (number, spaces) = field[start..].split_at(len);
    if spaces.iter().any(|&c| c != b' ') {
        return None;
    }
    Dsp3000Value::parse(number)
}

/// Byte-at-a-time DSP-3000 line decoder with byte accounting.
///
/// Keeps the last 20 bytes of the current segment (a line is the 21 bytes up to and
/// including LF, assumption D4); no heap.
#[derive(Debug, Clone)]
pub struct Dsp3000Decoder {
    /// Last bytes of the current segment, oldest first.
    buf: [u8; LINE_LEN - 1],
    /// Bytes held in `buf`.
    len: usize,
    /// A CR LF has been seen since construction or the last flush (D5).
    synced: bool,
    /// First UART error in the current segment (U2).
    damage: Option<UartError>,
    /// The current segment has been counted in `frames_bad`.
    counted_bad: bool,
    stats: ByteStats,
}

impl Default for Dsp3000Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Dsp3000Decoder {
    /// A decoder waiting for its first line.
    pub const fn new() -> Self {
        Self {
            buf: [0; LINE_LEN - 1],
            len: 0,
            synced: false,
            damage: None,
            counted_bad: false,
            stats: ByteStats::ZERO,
        }
    }

    /// Reason for bytes dropped from the current segment: a UART error first, then lack of
    /// synchronisation, then `default`.
    fn reason(&self, default: SkipReason) -> SkipReason {
        match self.damage {
            Some(e) => SkipReason::Uart(e),
            None if !self.synced => SkipReason::NoSync,
            None => default,
        }
    }

    /// Counts the current segment in `frames_bad`, once, if synchronised.
    fn bad_segment(&mut self) {
        if self.synced && !self.counted_bad {
            self.stats.bad_frame();
            self.counted_bad = true;
        }
    }

    /// LF after CR: judges the segment (the LF is pending too) and starts a new one.
    fn end_segment(&mut self) -> Option<Dsp3000Line> {
        let n = self.len + 1;
        let line = match self.buf {
            ref b if n == LINE_LEN => {
                let mut l = [LF; LINE_LEN];
                l[..LINE_LEN - 1].copy_from_slice(b);
                Dsp3000Line::parse(&l)
            }
            _ => None,
        };
        match line {
            Some(l) => self
                .stats
                .deliver(LINE_LEN, matches!(l, Dsp3000Line::Fault(_))),
            None => {
                self.stats.skip(n, self.reason(SkipReason::Malformed));
                self.bad_segment();
            }
        }
        self.len = 0;
        self.synced = true;
        self.damage = None;
        self.counted_bad = false;
        line
    }
}

impl Decoder for Dsp3000Decoder {
    type Output = Dsp3000Line;

    fn push(&mut self, byte: u8) -> Option<Dsp3000Line> {
        self.stats.receive();
        let last = self.len.checked_sub(1).and_then(|i| self.buf.get(i));
        if byte == LF && last == Some(&CR) {
            return self.end_segment();
        }
        if self.len >= self.buf.len() {
            // 21 bytes without CR LF at their end: the oldest cannot start a line.
            self.stats.skip(1, self.reason(SkipReason::TooLong));
            self.buf.copy_within(1.., 0);
            self.len = self.buf.len() - 1;
        }
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
            self.len += 1;
        }
        None
    }

    fn push_error(&mut self, error: UartError) {
        self.stats.receive();
        // No line can contain the error slot: drop the segment so far with it (U2).
        self.stats.skip(self.len + 1, SkipReason::Uart(error));
        self.len = 0;
        self.damage.get_or_insert(error);
        self.bad_segment();
    }

    fn flush(&mut self) {
        if self.len > 0 {
            self.stats
                .skip(self.len, self.reason(SkipReason::Incomplete));
            self.bad_segment();
        }
        self.len = 0;
        self.synced = false;
        self.damage = None;
        self.counted_bad = false;
    }

    fn stats(&self) -> &ByteStats {
        &self.stats
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::format;
    use std::string::String;
    use std::vec::Vec;

    use super::*;
    use proptest::prelude::*;

    const LINE: &[u8; LINE_LEN] = b"       0.015733   1\r\n";

    /// A line as the unit prints it: value right-aligned in 15 columns, 3 spaces, status.
    fn line(value: &str, status: char) -> Vec<u8> {
        format!("{value:>15}   {status}\r\n").into_bytes()
    }

    fn feed(d: &mut Dsp3000Decoder, bytes: &[u8]) -> Vec<Dsp3000Line> {
        let mut out = Vec::new();
        for &b in bytes {
            out.extend(d.push(b));
            assert!(d.stats().is_consistent(), "{:?}", d.stats());
        }
        out
    }

    fn v(mantissa: i64, decimals: u8) -> Dsp3000Value {
        Dsp3000Value { mantissa, decimals }
    }

    #[test]
    fn spec_line() {
        assert_eq!(line("0.015733", '1'), LINE);
        let mut d = Dsp3000Decoder::new();
        let got = feed(&mut d, LINE);
        assert_eq!(got, [Dsp3000Line::Valid(v(15_733, 6))]);
        assert_eq!(got[0].valid().map(Dsp3000Value::to_f32), Some(0.015733));
        let s = d.stats();
        assert_eq!((s.bytes_total, s.bytes_good, s.frames_good), (21, 21, 1));
    }

    #[test]
    fn numbers() {
        let p = |s: &str| Dsp3000Value::parse(s.as_bytes());
        assert_eq!(p("-999.999999"), Some(v(-999_999_999, 6)));
        assert_eq!(p("+1.5"), Some(v(15, 1)));
        assert_eq!(p("12"), Some(v(12, 0)));
        assert_eq!(p(".5"), Some(v(5, 1)));
        assert_eq!(p("5."), Some(v(5, 0)));
        assert_eq!(p("-0.000000"), Some(v(0, 6)));
        assert_eq!(p("999999999999999999"), Some(v(999_999_999_999_999_999, 0)));
        for bad in [
            "", "-", ".", "1.2.3", "1e3", " 1", "1 ", "--1", "0x1", "1,5",
        ] {
            assert_eq!(p(bad), None, "{bad:?}");
        }
        assert_eq!(p("1234567890123456789"), None);
        assert_eq!(v(-999_999_999, 6).to_f64(), -999.999999);
        assert_eq!(v(16_777_216, 6).to_f32(), 16.777216);
        assert_eq!(v(-1, 18).to_f64(), -1e-18);
    }

    #[test]
    fn fault_and_malformed_lines() {
        let mut d = Dsp3000Decoder::new();
        let mut s = line("0.5", '1');
        s.extend(line("-0.250000", '0'));
        s.extend(b"        garbage   0\r\n");
        s.extend(line("1.0", '7'));
        s.extend(line("1.0.0", '1'));
        s.extend(b"    1.0 1\r\n");
        s.extend(line("2.5", '1'));
        let got = feed(&mut d, &s);
        assert_eq!(
            got,
            [
                Dsp3000Line::Valid(v(5, 1)),
                Dsp3000Line::Fault(Some(v(-250_000, 6))),
                Dsp3000Line::Fault(None),
                Dsp3000Line::Valid(v(25, 1)),
            ]
        );
        let st = d.stats();
        assert_eq!((st.frames_good, st.frames_fault, st.frames_bad), (2, 2, 3));
        assert_eq!(st.skipped.malformed, 21 + 21 + 11);
        assert_eq!(st.bytes_good, 4 * 21);
    }

    #[test]
    fn resync_mid_line_and_garbage() {
        let mut d = Dsp3000Decoder::new();
        // Starts mid-line, then garbage in front of a good line, then a line without CR LF.
        let mut s = Vec::from(&LINE[9..]);
        s.extend(b"xx\x00\xFF");
        s.extend(line("1", '1'));
        s.extend(&line("2", '1')[..20]);
        s.extend(line("3", '1'));
        s.extend(line("4", '1'));
        let got = feed(&mut d, &s);
        let vals: Vec<_> = got.iter().filter_map(|l| l.valid()).collect();
        // "2" lost its LF: the 20 bytes in front of line "3" are too long, "3" survives.
        assert_eq!(vals, [v(1, 0), v(3, 0), v(4, 0)]);
        let st = d.stats();
        assert_eq!(st.skipped.no_sync, 12);
        assert_eq!(st.skipped.too_long, 4 + 20);
        assert_eq!(st.frames_bad, 0);
    }

    #[test]
    fn uart_errors() {
        let mut d = Dsp3000Decoder::new();
        feed(&mut d, LINE);
        feed(&mut d, &LINE[..5]);
        d.push_error(UartError::Noise);
        assert_eq!(feed(&mut d, &LINE[6..]), []);
        assert_eq!(d.stats().skipped.uart_noise, 21);
        // An error in the CR LF of a line kills it; the next line is whole again.
        feed(&mut d, &LINE[..19]);
        d.push_error(UartError::Framing);
        assert_eq!(feed(&mut d, LINE).len(), 1);
        assert_eq!(d.stats().skipped.uart_framing, 20);
        let st = d.stats();
        assert_eq!((st.frames_good, st.frames_bad), (2, 2));
    }

    #[test]
    fn flush_counts_partial_line() {
        let mut d = Dsp3000Decoder::new();
        feed(&mut d, LINE);
        feed(&mut d, &LINE[..7]);
        d.flush();
        let st = d.stats();
        assert_eq!(
            (st.bytes_pending, st.skipped.incomplete, st.frames_bad),
            (0, 7, 1)
        );
        // After a flush the next stream starts unsynchronised but a whole line is taken.
        assert_eq!(feed(&mut d, LINE).len(), 1);
    }

    /// One input of a UART: a byte or an error slot.
    #[derive(Debug, Clone, Copy)]
    enum Input {
        Byte(u8),
        Error(UartError),
    }

    fn input() -> impl Strategy<Value = Input> {
        prop_oneof![
            10 => proptest::sample::select(b" 0123456789.-+10\r\n".as_slice()).prop_map(Input::Byte),
            5 => any::<u8>().prop_map(Input::Byte),
            1 => proptest::sample::select(&[
                UartError::Overrun,
                UartError::Framing,
                UartError::Parity,
                UartError::Noise,
                UartError::Other,
            ][..])
            .prop_map(Input::Error),
        ]
    }

    fn apply(d: &mut Dsp3000Decoder, i: Input) -> Option<Dsp3000Line> {
        match i {
            Input::Byte(b) => d.push(b),
            Input::Error(e) => {
                d.push_error(e);
                None
            }
        }
    }

    fn value_text() -> impl Strategy<Value = (String, Dsp3000Value)> {
        (any::<bool>(), 0i64..1_000_000_000).prop_map(|(neg, m)| {
            let text = format!(
                "{}{}.{:06}",
                if neg { "-" } else { "" },
                m / 1_000_000,
                m % 1_000_000
            );
            (text, v(if neg { -m } else { m }, 6))
        })
    }

    proptest! {
        #[test]
        fn any_input_is_accounted(inputs in proptest::collection::vec(input(), 0..600)) {
            let mut d = Dsp3000Decoder::new();
            for (n, &i) in inputs.iter().enumerate() {
                apply(&mut d, i);
                let s = d.stats();
                prop_assert!(s.is_consistent(), "{:?}", s);
                prop_assert_eq!(s.bytes_total, n as u64 + 1);
                prop_assert!(s.bytes_pending < LINE_LEN as u64);
                prop_assert_eq!(s.bytes_good, 21 * (s.frames_good + s.frames_fault));
            }
            d.flush();
            prop_assert_eq!(d.stats().bytes_pending, 0);
            prop_assert!(d.stats().is_consistent());
        }

        #[test]
        fn printed_values_parse_exactly((text, value) in value_text(), fault in any::<bool>()) {
            let l = line(&text, if fault { '0' } else { '1' });
            let mut d = Dsp3000Decoder::new();
            let got = feed(&mut d, &l);
            let want = if fault { Dsp3000Line::Fault(Some(value)) } else { Dsp3000Line::Valid(value) };
            prop_assert_eq!(got, [want]);
            // f32 within 1.2e-7 relative of the exact decimal.
            let exact = value.to_f64();
            let err = (f64::from(value.to_f32()) - exact).abs();
            prop_assert!(err <= 1.2e-7 * exact.abs(), "{} {}", text, err);
        }

        #[test]
        fn untouched_lines_survive_garbage(
            lines in proptest::collection::vec(
                (
                    value_text(),
                    proptest::collection::vec(input(), 0..30),
                    proptest::option::weighted(0.2, (1..LINE_LEN, input())),
                ),
                0..30,
            )
        ) {
            let mut d = Dsp3000Decoder::new();
            let mut expected = Vec::new();
            let mut got = Vec::new();
            for ((text, value), garbage, inside) in lines {
                for &i in &garbage {
                    got.extend(apply(&mut d, i));
                }
                let l = line(&text, '1');
                let at = inside.map_or(LINE_LEN, |(at, _)| at);
                for &b in &l[..at] {
                    got.extend(d.push(b));
                }
                if let Some((_, i)) = inside {
                    got.extend(apply(&mut d, i));
                } else {
                    expected.push(value);
                }
                for &b in &l[at..] {
                    got.extend(d.push(b));
                }
            }
            prop_assert!(d.stats().is_consistent());
            let mut rest = got.iter().filter_map(|l| l.valid());
            for e in &expected {
                prop_assert!(rest.any(|g| g == *e), "lost {:?}", e);
            }
        }
    }
}
