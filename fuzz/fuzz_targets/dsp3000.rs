//! Fuzz target: the KVH DSP-3000 line decoder (`fog_core::frame::Dsp3000Decoder`) on any
//! stream of bytes and receive errors (encoding: `slots.rs`), and its number parser.
//!
//! Invariants checked after every slot:
//! - every slot counted once: `bytes_total` = slots so far, the accounting invariant holds,
//!   at most 20 bytes pending, 21 good bytes per delivered line, no E-Core reason used;
//! - outputs exactly characterised: a line is delivered at a slot iff that slot and the 20
//!   before it are received bytes forming a well-formed line (`Dsp3000Line::parse`,
//!   assumptions D1-D3) with no CR LF before its end (D4), and it is that line;
//! - numbers: a parsed value agrees with Rust's own decimal parser of the same text (f64,
//!   within 4 ulp) and converts to finite f32 and f64 (no NaN or infinity out);
//! - `flush` leaves nothing pending and keeps the invariant.
#![no_main]

use fog_core::frame::dsp3000::{LINE_LEN, VALUE_FIELD_LEN};
use fog_core::frame::{Decoder, Dsp3000Decoder, Dsp3000Line, Dsp3000Value};
use libfuzzer_sys::fuzz_target;

mod slots;
use slots::{slots, Slot};

/// `value` against `str::parse::<f64>` of the text it came from.
fn check_value(text: &[u8], value: Dsp3000Value) {
    let Ok(s) = std::str::from_utf8(text) else {
        panic!("non-ASCII number accepted: {text:02x?}");
    };
    let Ok(want) = s.parse::<f64>() else {
        panic!("{s:?} accepted as {value:?} but Rust does not parse it");
    };
    let got = value.to_f64();
    assert!(got.is_finite() && value.to_f32().is_finite(), "{s:?}");
    let tol = 4.0 * f64::EPSILON * want.abs();
    assert!((got - want).abs() <= tol, "{s:?}: {got} vs {want}");
    let got32 = f64::from(value.to_f32());
    assert!(
        (got32 - want).abs() <= 3.0e-7 * want.abs(),
        "{s:?}: f32 {got32}"
    );
}

/// The number in a line's value field, for [`check_value`].
fn field_number(line: &[u8; LINE_LEN]) -> &[u8] {
    let field = &line[..VALUE_FIELD_LEN];
    let start = field.iter().position(|&c| c != b' ').unwrap_or(field.len());
    let rest = &field[start..];
    let len = rest.iter().position(|&c| c == b' ').unwrap_or(rest.len());
    &rest[..len]
}

fuzz_target!(|data: &[u8]| {
    // The number parser alone, on the first 24 bytes.
    let head = &data[..data.len().min(24)];
    if let Some(v) = Dsp3000Value::parse(head) {
        check_value(head, v);
    }

    let input = slots(data);
    let mut d = Dsp3000Decoder::new();
    for (n, &slot) in input.iter().enumerate() {
        let out = match slot {
            Slot::Byte(b) => d.push(b),
            Slot::Error(e) => {
                d.push_error(e);
                None
            }
        };
        let s = *d.stats();
        assert!(s.is_consistent(), "slot {n}: {s:?}");
        assert_eq!(s.bytes_total, n as u64 + 1, "slot {n}");
        assert!(s.bytes_pending < LINE_LEN as u64, "slot {n}: {s:?}");
        assert_eq!(
            s.bytes_good,
            21 * (s.frames_good + s.frames_fault),
            "slot {n}"
        );
        assert_eq!(s.skipped.checksum + s.skipped.cut_short, 0);

        let window: Option<[u8; LINE_LEN]> = n
            .checked_sub(LINE_LEN - 1)
            .and_then(|start| input.get(start..=n))
            .and_then(|w| {
                let mut l = [0u8; LINE_LEN];
                for (dst, s) in l.iter_mut().zip(w) {
                    match s {
                        Slot::Byte(b) => *dst = *b,
                        Slot::Error(_) => return None,
                    }
                }
                Some(l)
            });
        // A CR LF inside the 21 bytes ends a segment there (D4): no line then, even when the
        // 21 bytes parse (a fault line's value field may hold anything, CR LF included).
        // The pair may straddle the window's start: a CR just before it and an LF first in it.
        let cr_before = n
            .checked_sub(LINE_LEN)
            .and_then(|i| input.get(i))
            .is_some_and(|s| *s == Slot::Byte(b'\r'));
        let expected = window
            .filter(|w| !w[..LINE_LEN - 2].windows(2).any(|p| p == b"\r\n"))
            .filter(|w| !(cr_before && w[0] == b'\n'))
            .and_then(|w| Dsp3000Line::parse(&w));
        assert_eq!(out, expected, "slot {n}: window {window:?}");
        if let (Some(line), Some(w)) = (out, window) {
            match line {
                Dsp3000Line::Valid(v) | Dsp3000Line::Fault(Some(v)) => {
                    check_value(field_number(&w), v)
                }
                Dsp3000Line::Fault(None) => {}
            }
        }
    }
    d.flush();
    let s = d.stats();
    assert_eq!(s.bytes_pending, 0);
    assert!(s.is_consistent(), "{s:?}");
    assert_eq!(s.bytes_total, input.len() as u64);
});
