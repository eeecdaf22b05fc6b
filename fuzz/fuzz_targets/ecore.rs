//! Fuzz target: the E-Core 2000 decoder (`fog_core::frame::EcoreDecoder`) on any stream of
//! bytes and receive errors (encoding: `slots.rs`).
//!
//! Invariants checked after every slot:
//! - every slot counted once: `bytes_total` = slots so far, and the accounting invariant
//!   `bytes_total == bytes_good + skipped + pending` holds; at most 7 bytes pending; 8 good
//!   bytes per delivered frame; no DSP-3000 reason used;
//! - outputs exactly characterised: a frame is delivered at a slot iff that slot and the 7
//!   before it are received bytes forming a good frame (`decode_frame`, assumptions E1-E5),
//!   and it is that frame; it re-encodes to the same 8 bytes (`ecore::encode`);
//! - no NaN or infinity out: `rate_dps` finite, `|rate_dps| <= full scale`;
//! - `flush` leaves nothing pending and keeps the invariant.
//!
//! The first input byte picks the full scale (finite ones only; invalid ones must be refused).
#![no_main]

use fog_core::frame::{ecore, Decoder, EcoreDecoder};
use libfuzzer_sys::fuzz_target;

mod slots;
use slots::{slots, Slot};

const FULL_SCALES_DPS: [f32; 4] = [60.0, 30.0, f32::MAX, f32::MIN_POSITIVE];

fuzz_target!(|data: &[u8]| {
    for bad in [0.0, -60.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert!(EcoreDecoder::new(bad).is_err(), "full scale {bad} accepted");
    }
    let (&pick, rest) = data.split_first().unwrap_or((&0, &[]));
    let full_scale_dps = FULL_SCALES_DPS[usize::from(pick) % FULL_SCALES_DPS.len()];
    let Ok(mut d) = EcoreDecoder::new(full_scale_dps) else {
        panic!("full scale {full_scale_dps} refused");
    };
    let input = slots(rest);
    let mut errors = 0u64;
    for (n, &slot) in input.iter().enumerate() {
        let out = match slot {
            Slot::Byte(b) => d.push(b),
            Slot::Error(e) => {
                errors += 1;
                d.push_error(e);
                None
            }
        };
        let s = *d.stats();
        assert!(s.is_consistent(), "slot {n}: {s:?}");
        assert_eq!(s.bytes_total, n as u64 + 1, "slot {n}");
        assert!(s.bytes_pending <= 7, "slot {n}: {s:?}");
        assert_eq!(s.bytes_good, 8 * s.frames_good, "slot {n}");
        assert_eq!(s.frames_fault, 0);
        assert_eq!(s.skipped.malformed + s.skipped.too_long, 0);
        // An error slot inside a frame stays pending until the frame ends (U2).
        assert!(
            s.skipped.uart() + s.bytes_pending >= errors,
            "slot {n}: {s:?}"
        );

        // The frame the last 8 slots would make, if they are all bytes.
        let window: Option<[u8; 8]> = n
            .checked_sub(7)
            .and_then(|start| input.get(start..=n))
            .and_then(|w| {
                let mut f = [0u8; 8];
                for (dst, s) in f.iter_mut().zip(w) {
                    match s {
                        Slot::Byte(b) => *dst = *b,
                        Slot::Error(_) => return None,
                    }
                }
                Some(f)
            });
        let expected = window.and_then(|w| d.decode_frame(&w));
        assert_eq!(out, expected, "slot {n}: window {window:02x?}");
        if let (Some(f), Some(w)) = (out, window) {
            assert_eq!(ecore::encode(f.counts, f.raw()), w, "slot {n}");
            assert!(f.rate_dps.is_finite(), "slot {n}: {f:?}");
            assert!(f.rate_dps.abs() <= full_scale_dps, "slot {n}: {f:?}");
            assert_eq!(f.rate_dps, f32::from(f.counts) * d.lsb_dps());
        }
    }
    d.flush();
    let s = d.stats();
    assert_eq!(s.bytes_pending, 0);
    assert!(s.is_consistent(), "{s:?}");
    assert_eq!(s.bytes_total, input.len() as u64);
    assert!(s.skipped.uart() >= errors, "{s:?}");
});
