//! How a fuzz input becomes a stream of UART slots (shared by the decoder targets).
//!
//! Bytes are taken as received bytes, except the escape `0xFE`: `0xFE k` with `k < 5` is one
//! receive-error slot of kind `k` (overrun, framing, parity, noise, other); `0xFE 0xFE` is one
//! received `0xFE`; `0xFE` followed by anything else (or nothing) is one received `0xFE` and
//! the next byte is read as usual. Every byte sequence is thus reachable, errors included.

use fog_core::frame::UartError;

/// One slot of the UART: a received byte or an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    Byte(u8),
    Error(UartError),
}

const ESCAPE: u8 = 0xFE;
const KINDS: [UartError; 5] = [
    UartError::Overrun,
    UartError::Framing,
    UartError::Parity,
    UartError::Noise,
    UartError::Other,
];

/// The slots of `data` (see the module docs).
pub fn slots(data: &[u8]) -> Vec<Slot> {
    let mut out = Vec::with_capacity(data.len());
    let mut i = 0;
    while let Some(&b) = data.get(i) {
        i += 1;
        if b != ESCAPE {
            out.push(Slot::Byte(b));
            continue;
        }
        match data.get(i) {
            Some(&k) if usize::from(k) < KINDS.len() => {
                out.push(Slot::Error(KINDS[usize::from(k)]));
                i += 1;
            }
            Some(&ESCAPE) => {
                out.push(Slot::Byte(ESCAPE));
                i += 1;
            }
            _ => out.push(Slot::Byte(ESCAPE)),
        }
    }
    out
}
