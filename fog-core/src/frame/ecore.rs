//! E-Core 2000 binary frame: decoder, encoder and the 7-bit packing.
//!
//! Layout and assumptions E1-E7: see the [parent module](super#e-core-2000-binary-frame).
//!
//! ```text
//! wire  [1 a6..a0] [0 b6..b0] ... [0 h6..h0]        8 bytes, sync flag in bit 7
//! bits  a6..a0 b6..b0 ... h6..h0                    56 bits, most significant first
//! m     m[0] m[1] m[2] m[3] m[4] m[5] m[6]          7 bytes; sum mod 256 == 0
//!       csum  raw (not decoded)   counts (i16 BE)
//! ```

use super::stats::{ByteStats, SkipReason};
use super::{ConfigError, Decoder, UartError};

/// Bytes per frame on the wire.
pub const FRAME_LEN: usize = 8;
/// Payload bytes `m[0..7)` carried by one frame.
pub const PAYLOAD_LEN: usize = 7;
/// Sync flag: bit 7, set on the first byte of a frame only.
pub const SYNC_FLAG: u8 = 0x80;
/// Counts at full scale: one count is `full_scale_dps / 32768` deg/s.
pub const COUNTS_PER_FULL_SCALE: f32 = 32768.0;

/// Joins the low 7 bits of the 8 wire bytes, most significant first, into `m[0..7)`.
///
/// The sync flags (bit 7) are ignored; [`pack`] is the inverse.
pub const fn unpack(wire: &[u8; FRAME_LEN]) -> [u8; PAYLOAD_LEN] {
    // Two 28-bit halves (cheap on a 32-bit core): bits = hi << 28 | lo.
    let w = [
        (wire[0] & 0x7F) as u32,
        (wire[1] & 0x7F) as u32,
        (wire[2] & 0x7F) as u32,
        (wire[3] & 0x7F) as u32,
        (wire[4] & 0x7F) as u32,
        (wire[5] & 0x7F) as u32,
        (wire[6] & 0x7F) as u32,
        (wire[7] & 0x7F) as u32,
    ];
    let hi = w[0] << 21 | w[1] << 14 | w[2] << 7 | w[3];
    let lo = w[4] << 21 | w[5] << 14 | w[6] << 7 | w[7];
    [
        (hi >> 20) as u8,
        (hi >> 12) as u8,
        (hi >> 4) as u8,
        (hi << 4 | lo >> 24) as u8,
        (lo >> 16) as u8,
        (lo >> 8) as u8,
        lo as u8,
    ]
}

/// Splits `m[0..7)` into 8 wire bytes of 7 bits, most significant first, and sets the sync
/// flag on the first. Any payload is representable; the checksum is not touched.
pub const fn pack(m: &[u8; PAYLOAD_LEN]) -> [u8; FRAME_LEN] {
    let mut bits: u64 = 0;
    let mut j = 0;
    while j < PAYLOAD_LEN {
        bits = (bits << 8) | m[j] as u64;
        j += 1;
    }
    let mut wire = [0u8; FRAME_LEN];
    let mut i = 0;
    while i < FRAME_LEN {
        wire[i] = ((bits >> (7 * (FRAME_LEN - 1 - i))) & 0x7F) as u8;
        i += 1;
    }
    wire[0] |= SYNC_FLAG;
    wire
}

/// `m[0] + ... + m[6]` mod 256; a good frame gives 0.
pub const fn payload_sum(m: &[u8; PAYLOAD_LEN]) -> u8 {
    let mut sum = 0u8;
    let mut j = 0;
    while j < PAYLOAD_LEN {
        sum = sum.wrapping_add(m[j]);
        j += 1;
    }
    sum
}

/// Payload of a good frame: `m[1..5) = raw`, `m[5..7) = counts` big-endian and the
/// checksum byte `m[0]` that makes the sum 0 mod 256.
pub const fn payload(counts: i16, raw: [u8; 4]) -> [u8; PAYLOAD_LEN] {
    let c = counts.to_be_bytes();
    let mut m = [0, raw[0], raw[1], raw[2], raw[3], c[0], c[1]];
    m[0] = 0u8.wrapping_sub(payload_sum(&m));
    m
}

/// Wire bytes of a good frame carrying `counts` and the raw bytes `m[1..5)`.
///
/// [`EcoreDecoder`] decodes it back to the same `counts` and `raw`, whatever they are.
pub const fn encode(counts: i16, raw: [u8; 4]) -> [u8; FRAME_LEN] {
    pack(&payload(counts, raw))
}

/// Whether `wire` has the sync layout of a frame: bit 7 set on byte 0 and clear on 1..8.
pub const fn has_frame_layout(wire: &[u8; FRAME_LEN]) -> bool {
    if wire[0] & SYNC_FLAG == 0 {
        return false;
    }
    let mut i = 1;
    while i < FRAME_LEN {
        if wire[i] & SYNC_FLAG != 0 {
            return false;
        }
        i += 1;
    }
    true
}

/// One good frame.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EcoreFrame {
    /// Payload `m[0..7)`: checksum, 4 raw bytes not decoded (probably status and
    /// temperature), rate counts big-endian.
    pub payload: [u8; PAYLOAD_LEN],
    /// Rate in counts, `i16::from_be_bytes([m[5], m[6]])`.
    pub counts: i16,
    /// Rate, deg/s: `counts * full_scale_dps / 32768`.
    pub rate_dps: f32,
}

impl EcoreFrame {
    /// The undecoded bytes `m[1..5)`.
    pub const fn raw(&self) -> [u8; 4] {
        [
            self.payload[1],
            self.payload[2],
            self.payload[3],
            self.payload[4],
        ]
    }
}

/// Byte-at-a-time E-Core 2000 frame decoder with byte accounting.
///
/// Size: 8 bytes of frame buffer, the scale and the counters; no heap.
#[derive(Debug, Clone)]
pub struct EcoreDecoder {
    /// Rate of one count, deg/s.
    lsb_dps: f32,
    /// The frame in progress, wire bytes (an error slot holds 0).
    buf: [u8; FRAME_LEN],
    /// Slots filled in `buf`; 0 while hunting for a sync byte.
    len: usize,
    /// First UART error inside the frame in progress.
    damage: Option<UartError>,
    stats: ByteStats,
}

impl EcoreDecoder {
    /// Decoder for a unit whose full scale is `full_scale_dps` deg/s (32768 counts), for
    /// example 60.0 or 30.0. Refused unless finite and > 0.
    pub fn new(full_scale_dps: f32) -> Result<Self, ConfigError> {
        let lsb_dps = full_scale_dps / COUNTS_PER_FULL_SCALE;
        if !full_scale_dps.is_finite() || lsb_dps <= 0.0 {
            return Err(ConfigError::BadFullScale);
        }
        Ok(Self {
            lsb_dps,
            buf: [0; FRAME_LEN],
            len: 0,
            damage: None,
            stats: ByteStats::ZERO,
        })
    }

    /// Full scale, deg/s.
    pub fn full_scale_dps(&self) -> f32 {
        self.lsb_dps * COUNTS_PER_FULL_SCALE
    }

    /// Rate of one count, deg/s.
    pub fn lsb_dps(&self) -> f32 {
        self.lsb_dps
    }

    /// Decodes one whole frame, without touching the stream state or the counters.
    ///
    /// `None` unless `wire` has the sync layout and a good checksum.
    pub fn decode_frame(&self, wire: &[u8; FRAME_LEN]) -> Option<EcoreFrame> {
        if !has_frame_layout(wire) {
            return None;
        }
        self.decode_payload(wire)
    }

    /// Checksum and conversion of a frame whose sync layout is known to be right.
    #[inline]
    fn decode_payload(&self, wire: &[u8; FRAME_LEN]) -> Option<EcoreFrame> {
        let payload = unpack(wire);
        if payload_sum(&payload) != 0 {
            return None;
        }
        let counts = i16::from_be_bytes([payload[5], payload[6]]);
        Some(EcoreFrame {
            payload,
            counts,
            rate_dps: f32::from(counts) * self.lsb_dps,
        })
    }

    /// Drops the frame in progress, if any, for `reason` unless an error damaged it.
    fn drop_partial(&mut self, reason: SkipReason) {
        if self.len > 0 {
            let reason = self.damage.map_or(reason, SkipReason::Uart);
            self.stats.skip(self.len, reason);
            self.stats.bad_frame();
        }
        self.len = 0;
        self.damage = None;
    }

    /// [`Decoder::push`] for a sync byte, a byte outside a frame, or a frame's last byte
    /// (the byte is already counted as received).
    #[inline(never)]
    fn push_slow(&mut self, byte: u8) -> Option<EcoreFrame> {
        if byte & SYNC_FLAG != 0 {
            self.drop_partial(SkipReason::CutShort);
            self.buf[0] = byte;
            self.len = 1;
            return None;
        }
        match self.buf.get_mut(self.len) {
            Some(slot) if self.len > 0 => {
                *slot = byte;
                self.len += 1;
                self.complete()
            }
            _ => {
                // Hunting (E3); `len` never reaches FRAME_LEN outside `complete`.
                self.stats.skip(1, SkipReason::NoSync);
                None
            }
        }
    }

    /// Judges the frame in progress once all 8 slots are filled.
    fn complete(&mut self) -> Option<EcoreFrame> {
        if self.len < FRAME_LEN {
            return None;
        }
        // `push` puts a sync byte only in slot 0 and bytes without it in slots 1..8, so
        // the layout holds here and only the checksum is left to check.
        let frame = match self.damage {
            Some(_) => None,
            None => self.decode_payload(&self.buf),
        };
        match frame {
            Some(frame) => {
                self.stats.deliver(FRAME_LEN, false);
                self.len = 0;
                Some(frame)
            }
            None => {
                self.drop_partial(SkipReason::Checksum);
                None
            }
        }
    }
}

impl Decoder for EcoreDecoder {
    type Output = EcoreFrame;

    /// Fast path inline (a byte inside a frame: count it, store it); the sync byte, noise
    /// and the frame's last byte go out of line.
    #[inline]
    fn push(&mut self, byte: u8) -> Option<EcoreFrame> {
        self.stats.receive();
        if byte & SYNC_FLAG == 0 && self.len > 0 && self.len < FRAME_LEN - 1 {
            if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = byte;
            }
            self.len += 1;
            return None;
        }
        self.push_slow(byte)
    }

    fn push_error(&mut self, error: UartError) {
        self.stats.receive();
        match self.buf.get_mut(self.len) {
            Some(slot) if self.len > 0 => {
                *slot = 0;
                self.len += 1;
                self.damage.get_or_insert(error);
                // A damaged frame is never delivered.
                let _ = self.complete();
            }
            _ => self.stats.skip(1, SkipReason::Uart(error)),
        }
    }

    fn flush(&mut self) {
        self.drop_partial(SkipReason::Incomplete);
    }

    fn stats(&self) -> &ByteStats {
        &self.stats
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use proptest::prelude::*;

    const POS: [u8; 8] = [0x8A, 0x40, 0x00, 0x00, 0x00, 0x00, 0x07, 0x68];
    const NEG: [u8; 8] = [0xF6, 0x00, 0x00, 0x00, 0x00, 0x03, 0x78, 0x18];

    fn dec60() -> EcoreDecoder {
        match EcoreDecoder::new(60.0) {
            Ok(d) => d,
            Err(e) => panic!("{e}"),
        }
    }

    /// Feeds `bytes`, checking the invariant after every byte; returns the frames.
    fn feed(d: &mut EcoreDecoder, bytes: &[u8]) -> Vec<EcoreFrame> {
        let mut out = Vec::new();
        for &b in bytes {
            out.extend(d.push(b));
            assert!(d.stats().is_consistent(), "{:?}", d.stats());
        }
        out
    }

    #[test]
    fn spec_vectors() {
        let mut d = dec60();
        let f = feed(&mut d, &POS);
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].payload, [0x15, 0, 0, 0, 0, 0x03, 0xE8]);
        assert_eq!(f[0].counts, 1000);
        assert_eq!(f[0].rate_dps, 1.831_054_7);
        assert_eq!(f64::from(f[0].rate_dps), 1.8310546875);
        let f = feed(&mut d, &NEG);
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].payload, [0xEC, 0, 0, 0, 0, 0xFC, 0x18]);
        assert_eq!(f[0].counts, -1000);
        assert_eq!(f64::from(f[0].rate_dps), -1.8310546875);
        assert_eq!(f[0].raw(), [0; 4]);
        let s = d.stats();
        assert_eq!((s.bytes_total, s.bytes_good, s.frames_good), (16, 16, 2));
        assert_eq!(s.skipped.total(), 0);
        assert_eq!(encode(1000, [0; 4]), POS);
        assert_eq!(encode(-1000, [0; 4]), NEG);
    }

    #[test]
    fn thirty_dps_unit() {
        let d = EcoreDecoder::new(30.0).ok();
        let f = d.and_then(|d| d.decode_frame(&POS));
        assert_eq!(f.map(|f| f64::from(f.rate_dps)), Some(0.91552734375));
    }

    #[test]
    fn bad_full_scale_refused() {
        for fs in [0.0, -60.0, f32::NAN, f32::INFINITY, 1e-45] {
            assert_eq!(
                EcoreDecoder::new(fs).err(),
                Some(ConfigError::BadFullScale),
                "{fs}"
            );
        }
    }

    #[test]
    fn stream_starting_mid_frame() {
        let mut d = dec60();
        let mut s = Vec::from(&POS[3..]);
        s.extend(NEG);
        let f = feed(&mut d, &s);
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].counts, -1000);
        let st = d.stats();
        assert_eq!(st.skipped.no_sync, 5);
        assert_eq!((st.frames_good, st.frames_bad), (1, 0));
    }

    #[test]
    fn noise_between_frames() {
        let mut d = dec60();
        let mut s = Vec::from(POS);
        s.extend([0x00, 0x7F, 0x13]);
        s.extend(NEG);
        s.push(0x55);
        let f = feed(&mut d, &s);
        assert_eq!(
            f.iter().map(|f| f.counts).collect::<Vec<_>>(),
            [1000, -1000]
        );
        assert_eq!(d.stats().skipped.no_sync, 4);
        assert_eq!(d.stats().bytes_good, 16);
    }

    #[test]
    fn frame_cut_short_by_sync() {
        let mut d = dec60();
        let mut s = Vec::from(&POS[..5]);
        s.extend(NEG);
        let f = feed(&mut d, &s);
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].counts, -1000);
        let st = d.stats();
        assert_eq!(st.skipped.cut_short, 5);
        assert_eq!((st.frames_good, st.frames_bad), (1, 1));
    }

    #[test]
    fn checksum_failure() {
        let mut d = dec60();
        let mut bad = POS;
        bad[3] ^= 0x01;
        let mut s = Vec::from(bad);
        s.extend(POS);
        let f = feed(&mut d, &s);
        assert_eq!(f.len(), 1);
        let st = d.stats();
        assert_eq!(st.skipped.checksum, 8);
        assert_eq!((st.frames_good, st.frames_bad), (1, 1));
        assert_eq!(d.decode_frame(&bad), None);
    }

    #[test]
    fn uart_error_inside_and_outside_frame() {
        let mut d = dec60();
        feed(&mut d, &POS[..3]);
        d.push_error(UartError::Parity);
        d.push_error(UartError::Framing);
        assert_eq!(feed(&mut d, &POS[5..]), []);
        // The damaged frame is dropped after 8 slots, under the first error.
        assert_eq!(d.stats().skipped.uart_parity, 8);
        assert_eq!(d.stats().skipped.uart_framing, 0);
        d.push_error(UartError::Noise);
        assert_eq!(d.stats().skipped.uart_noise, 1);
        // Overrun: bytes lost, the next sync cuts the damaged frame short.
        feed(&mut d, &POS[..2]);
        d.push_error(UartError::Overrun);
        assert_eq!(feed(&mut d, &NEG).len(), 1);
        assert_eq!(d.stats().skipped.uart_overrun, 3);
        let st = *d.stats();
        assert!(st.is_consistent());
        assert_eq!((st.frames_good, st.frames_bad), (1, 2));
    }

    #[test]
    fn flush_counts_partial_frame() {
        let mut d = dec60();
        feed(&mut d, &POS[..6]);
        assert_eq!(d.stats().bytes_pending, 6);
        d.flush();
        let st = d.stats();
        assert_eq!((st.bytes_pending, st.skipped.incomplete), (0, 6));
        assert!(st.is_consistent());
        assert_eq!(feed(&mut d, &POS).len(), 1);
    }

    /// One input of a UART: a byte or an error slot.
    #[derive(Debug, Clone, Copy)]
    enum Input {
        Byte(u8),
        Error(UartError),
    }

    fn uart_error() -> impl Strategy<Value = UartError> {
        prop_oneof![
            Just(UartError::Overrun),
            Just(UartError::Framing),
            Just(UartError::Parity),
            Just(UartError::Noise),
            Just(UartError::Other),
        ]
    }

    fn input() -> impl Strategy<Value = Input> {
        prop_oneof![
            20 => any::<u8>().prop_map(Input::Byte),
            1 => uart_error().prop_map(Input::Error),
        ]
    }

    fn apply(d: &mut EcoreDecoder, i: Input) -> Option<EcoreFrame> {
        match i {
            Input::Byte(b) => d.push(b),
            Input::Error(e) => {
                d.push_error(e);
                None
            }
        }
    }

    proptest! {
        #[test]
        fn any_input_is_accounted(inputs in proptest::collection::vec(input(), 0..400)) {
            let mut d = dec60();
            for (n, &i) in inputs.iter().enumerate() {
                if let Some(f) = apply(&mut d, i) {
                    prop_assert_eq!(payload_sum(&f.payload), 0);
                }
                let s = d.stats();
                prop_assert!(s.is_consistent(), "{:?}", s);
                prop_assert_eq!(s.bytes_total, n as u64 + 1);
                prop_assert!(s.bytes_pending < FRAME_LEN as u64);
                prop_assert_eq!(s.bytes_good, 8 * s.frames_good);
            }
            d.flush();
            prop_assert_eq!(d.stats().bytes_pending, 0);
            prop_assert!(d.stats().is_consistent());
        }

        #[test]
        fn encode_decode_round_trip(counts in any::<i16>(), raw in any::<[u8; 4]>()) {
            let wire = encode(counts, raw);
            prop_assert!(has_frame_layout(&wire));
            let mut d = dec60();
            let f = feed(&mut d, &wire);
            prop_assert_eq!(f.len(), 1);
            prop_assert_eq!(f[0].counts, counts);
            prop_assert_eq!(f[0].raw(), raw);
            prop_assert_eq!(f[0].rate_dps, f32::from(counts) * 60.0 / 32768.0);
            prop_assert_eq!(pack(&f[0].payload), wire);
        }

        #[test]
        fn pack_unpack_round_trip(m in any::<[u8; 7]>(), w in any::<[u8; 8]>()) {
            prop_assert_eq!(unpack(&pack(&m)), m);
            // Any wire word with the sync layout comes back unchanged.
            let mut w = w.map(|b| b & 0x7F);
            w[0] |= SYNC_FLAG;
            prop_assert_eq!(pack(&unpack(&w)), w);
        }

        #[test]
        fn untouched_frames_survive_garbage(
            frames in proptest::collection::vec(
                (
                    any::<i16>(),
                    any::<[u8; 4]>(),
                    proptest::collection::vec(input(), 0..12),
                    proptest::option::weighted(0.2, (1..FRAME_LEN, input())),
                ),
                0..40,
            )
        ) {
            let mut d = dec60();
            let mut expected = Vec::new();
            let mut got = Vec::new();
            for (counts, raw, garbage, inside) in frames {
                let wire = encode(counts, raw);
                // Garbage after the frame's first `at` bytes touches it.
                let at = inside.map_or(FRAME_LEN, |(at, _)| at);
                for &b in &wire[..at] {
                    got.extend(d.push(b));
                }
                if let Some((_, i)) = inside {
                    got.extend(apply(&mut d, i));
                } else {
                    expected.push((counts, raw));
                }
                for &b in &wire[at..] {
                    got.extend(d.push(b));
                }
                for &i in &garbage {
                    got.extend(apply(&mut d, i));
                }
            }
            prop_assert!(d.stats().is_consistent());
            // Every untouched frame is decoded, in order (garbage may add lucky frames).
            let mut rest = got.iter().map(|f| (f.counts, f.raw()));
            for e in &expected {
                prop_assert!(rest.any(|g| g == *e), "lost {:?}", e);
            }
        }
    }
}
