//! db4 discrete wavelet transform in lifting form (Daubechies-Sweldens factorization).
// The constants keep all the digits the derivation script printed (f64), so that they can
// be checked against it; the compiler rounds them to the nearest f32.
#![allow(clippy::excessive_precision)]
//!
//! The forward transform [`forward`] and its inverse [`inverse`] work on a slice whose
//! length is a power of two, with periodic boundary handling. After a forward transform of
//! `levels` levels the slice holds the coefficients in the order and with the values of
//! PyWavelets
//!
//! ```text
//! pywt.wavedec(x, 'db4', mode='periodization', level=levels)
//! = [cA_levels, cD_levels, cD_levels-1, ..., cD_1]   (concatenated)
//! ```
//!
//! so the finest details `cD_1` occupy the upper half of the slice.
//!
//! # Lifting steps
//! One level splits `x` into `s[n] = x[2n]` and `d[n] = x[2n+1]` (`H = len/2`, indices
//! modulo `H`), then applies five lifting steps and a scaling:
//!
//! | step | kind    | operation |
//! |------|---------|-----------|
//! | 1 | predict | `d[n] += P0 * s[n+1]` |
//! | 2 | update  | `s[n] += U1[0] * d[n] + U1[1] * d[n-1]` |
//! | 3 | predict | `d[n] += P2[0] * s[n+2] + P2[1] * s[n+1]` |
//! | 4 | update  | `s[n] += U3[0] * d[n] + U3[1] * d[n-1]` |
//! | 5 | predict | `d[n] += P4[0] * s[n] + P4[1] * s[n-1] + P4[2] * s[n-2]` |
//! | 6 | scale   | `s *= K_S`, `d *= K_D` |
//!
//! The constants are MATLAB's `liftwave('db4')` values refined to double precision by
//! `scripts/derive_db4_lifting.py`, which checks the result against PyWavelets to 2e-16.
//! PyWavelets' coefficients are then `cA[n] = s[n-1]` and `cD[n] = d[n+1]`: the rotation by
//! one coefficient per level is folded into the write-back, so it costs nothing.
//!
//! # Cost and accuracy
//! Per level and per input sample: 5 multiply-adds and one scaling multiply (10 taps per
//! pair of samples), against 8 for the two-filter form; plus one de-interleave copy through
//! the scratch buffer. In f32 the coefficients agree with PyWavelets (f64) to about 1e-6 of
//! the signal's RMS (tested to 2e-6 for lengths 64..=4096 and levels 1..=5).

/// Predict step 1 (`d += P0 * s[n+1]`).
pub(crate) const P0: [f32; 1] = [-3.222_758_880_002_811_2e-1];
/// Update step 2 (taps `d[n]`, `d[n-1]`).
pub(crate) const U1: [f32; 2] = [-1.117_123_605_116_217_2, -3.001_422_585_491_521_6e-1];
/// Predict step 3 (taps `s[n+2]`, `s[n+1]`).
pub(crate) const P2: [f32; 2] = [-1.880_835_272_775_004_1e-2, 1.176_480_868_035_395_1e-1];
/// Update step 4 (taps `d[n]`, `d[n-1]`).
pub(crate) const U3: [f32; 2] = [2.131_816_712_612_866_7, 6.364_282_709_619_261_1e-1];
/// Predict step 5 (taps `s[n]`, `s[n-1]`, `s[n-2]`).
pub(crate) const P4: [f32; 3] = [
    -4.690_834_789_330_211e-1,
    1.400_392_377_392_728_2e-1,
    -2.479_123_815_827_083_4e-2,
];
/// Scaling of the approximation channel.
pub(crate) const K_S: f32 = 7.341_245_277_004_642_1e-1;
/// Scaling of the detail channel.
pub(crate) const K_D: f32 = 1.362_166_720_041_831_5;

/// Shortest coarsest approximation a transform may leave: the db4 filter length.
///
/// This is the same limit as `pywt.dwt_max_level(len, 8)` for power-of-two lengths.
pub const MIN_COARSEST_LEN: usize = 8;

/// Why a transform was refused. Nothing is modified when an error is returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TransformError {
    /// The signal length is not a power of two.
    LengthNotPowerOfTwo,
    /// `levels` is 0 or leaves fewer than [`MIN_COARSEST_LEN`] approximation coefficients.
    BadLevels,
    /// The scratch buffer is shorter than the signal.
    ScratchTooShort,
}

impl core::fmt::Display for TransformError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::LengthNotPowerOfTwo => "signal length is not a power of two",
            Self::BadLevels => {
                "levels must be >= 1 and leave at least 8 approximation coefficients"
            }
            Self::ScratchTooShort => "scratch buffer is shorter than the signal",
        })
    }
}

impl core::error::Error for TransformError {}

/// Largest number of levels a signal of `len` samples supports (0 if none).
pub const fn max_levels(len: usize) -> u32 {
    if len < MIN_COARSEST_LEN || !len.is_power_of_two() {
        return 0;
    }
    (len / MIN_COARSEST_LEN).trailing_zeros()
}

/// Checks the arguments shared by [`forward`] and [`inverse`].
pub fn check(len: usize, scratch_len: usize, levels: u32) -> Result<(), TransformError> {
    if !len.is_power_of_two() {
        return Err(TransformError::LengthNotPowerOfTwo);
    }
    if levels == 0 || levels > max_levels(len) {
        return Err(TransformError::BadLevels);
    }
    if scratch_len < len {
        return Err(TransformError::ScratchTooShort);
    }
    Ok(())
}

/// Ghost cells kept on each side of the even and odd channels during one level: the lifting
/// steps reach at most 4 samples across the periodic boundary, so with the channels extended
/// periodically by 4 on each side every value the write-back needs is computed without
/// modular indexing.
const GHOST: usize = 4;

/// `v[i]`, or 0 out of range. The lifting code only reads in range (the lengths were
/// validated by [`check`]); `get` instead of indexing keeps the firmware free of
/// bounds-check panics where the compiler cannot prove the range itself.
#[inline(always)]
pub(crate) fn ld(v: &[f32], i: usize) -> f32 {
    v.get(i).copied().unwrap_or(0.0)
}

/// `v[i] = x` when `i` is in range (see [`ld`]).
#[inline(always)]
pub(crate) fn st(v: &mut [f32], i: usize, x: f32) {
    if let Some(o) = v.get_mut(i) {
        *o = x;
    }
}

/// `v[i] += x` when `i` is in range (see [`ld`]): the same f32 operation as `v[i] += x`.
#[inline(always)]
pub(crate) fn add(v: &mut [f32], i: usize, x: f32) {
    if let Some(o) = v.get_mut(i) {
        *o += x;
    }
}

/// `v[i] -= x` when `i` is in range (see [`ld`]).
#[inline(always)]
pub(crate) fn sub(v: &mut [f32], i: usize, x: f32) {
    if let Some(o) = v.get_mut(i) {
        *o -= x;
    }
}

/// Copies `src` into the start of `dst` (as many values as both have).
#[inline(always)]
fn copy(dst: &mut [f32], src: &[f32]) {
    for (o, v) in dst.iter_mut().zip(src) {
        *o = *v;
    }
}

/// `a * x + b * y`, in this order (the same f32 operations everywhere).
#[inline(always)]
pub(crate) fn two(c: &[f32; 2], a: f32, b: f32) -> f32 {
    c[0] * a + c[1] * b
}

/// `((0 + c0 * a) + c1 * b) + c2 * e`, in this order.
#[inline(always)]
pub(crate) fn three(c: &[f32; 3], a: f32, b: f32, e: f32) -> f32 {
    let mut acc = 0.0f32;
    acc += c[0] * a;
    acc += c[1] * b;
    acc += c[2] * e;
    acc
}

/// Sweep iterations per block of [`forward_interior_blocked`] and [`inverse_interior_blocked`]: 2 x 1 KiB of
/// each channel, well inside any L1 cache.
const BLOCK: usize = 256;

/// Iterations `lo..hi` of the forward sweep (`lo >= 5`, `hi + 1 <= s.len()`), which at
/// iteration `i` applies step 1 and 2 at `i`, steps 3 and 4 at `i - 2` and step 5 at `i - 3`.
///
/// Done a block of iterations at a time, one step after the other over the whole block:
/// every step then reads one channel and writes the other, a loop the compiler vectorises.
/// Each value still goes through the same f32 operations, in the same order, as in the
/// one-iteration-at-a-time sweep: within a block no step reads a value that a step the
/// sweep would have run before it writes later in this order, or the reverse (checked
/// step pair by step pair in `docs/denoiser.md`; the bit-identity test against the
/// multi-pass reference covers it).
fn forward_interior_blocked(s: &mut [f32], d: &mut [f32], lo: usize, hi: usize) {
    let mut a = lo;
    while a < hi {
        let b = (a + BLOCK).min(hi);
        for (o, v) in d[a..b].iter_mut().zip(&s[a + 1..b + 1]) {
            *o += P0[0] * v;
        }
        for ((o, u), v) in s[a..b].iter_mut().zip(&d[a..b]).zip(&d[a - 1..b - 1]) {
            *o += two(&U1, *u, *v);
        }
        for ((o, u), v) in d[a - 2..b - 2]
            .iter_mut()
            .zip(&s[a..b])
            .zip(&s[a - 1..b - 1])
        {
            *o += two(&P2, *u, *v);
        }
        for ((o, u), v) in s[a - 2..b - 2]
            .iter_mut()
            .zip(&d[a - 2..b - 2])
            .zip(&d[a - 3..b - 3])
        {
            *o += two(&U3, *u, *v);
        }
        for (((o, u), v), w) in d[a - 3..b - 3]
            .iter_mut()
            .zip(&s[a - 3..b - 3])
            .zip(&s[a - 4..b - 4])
            .zip(&s[a - 5..b - 5])
        {
            *o += three(&P4, *u, *v, *w);
        }
        a = b;
    }
}

/// Iterations `lo..hi` of the inverse sweep (`lo >= 5`, `hi <= s.len()`), which at iteration
/// `i` undoes step 5 at `i`, 4 at `i - 2`, 3 and 2 at `i - 4`, 1 at `i - 5`; blocked like
/// [`forward_interior_blocked`], with the same bit-for-bit guarantee.
fn inverse_interior_blocked(s: &mut [f32], d: &mut [f32], lo: usize, hi: usize) {
    let mut a = lo;
    while a < hi {
        let b = (a + BLOCK).min(hi);
        for (((o, u), v), w) in d[a..b]
            .iter_mut()
            .zip(&s[a..b])
            .zip(&s[a - 1..b - 1])
            .zip(&s[a - 2..b - 2])
        {
            *o -= three(&P4, *u, *v, *w);
        }
        for ((o, u), v) in s[a - 2..b - 2]
            .iter_mut()
            .zip(&d[a - 2..b - 2])
            .zip(&d[a - 3..b - 3])
        {
            *o -= two(&U3, *u, *v);
        }
        for ((o, u), v) in d[a - 4..b - 4]
            .iter_mut()
            .zip(&s[a - 2..b - 2])
            .zip(&s[a - 3..b - 3])
        {
            *o -= two(&P2, *u, *v);
        }
        for ((o, u), v) in s[a - 4..b - 4]
            .iter_mut()
            .zip(&d[a - 4..b - 4])
            .zip(&d[a - 5..b - 5])
        {
            *o -= two(&U1, *u, *v);
        }
        for (o, v) in d[a - 5..b - 5].iter_mut().zip(&s[a - 4..b - 4]) {
            *o -= P0[0] * v;
        }
        a = b;
    }
}

/// Whether the interior of each level's sweep runs blocked ([`forward_interior_blocked`],
/// [`inverse_interior_blocked`]) or one iteration at a time ([`forward_interior_fused`],
/// [`inverse_interior_fused`]). Both give the same bits; the choice is speed only.
///
/// Blocked on targets with SIMD floating point, where the compiler vectorises each step's
/// loop (x86_64 baseline SSE2: 1.8x the throughput of the whole denoiser at 2^20 samples).
/// One iteration at a time elsewhere, e.g. the Cortex-M4F, which has no SIMD floating
/// point: there the blocked form only adds loads, stores and loop overhead (measured with
/// `scripts/fw-budget.sh`: 123,296 instructions per 512-sample block instead of 105,711).
const BLOCKED_SWEEP: bool = cfg!(any(
    target_feature = "sse2",
    target_feature = "neon",
    target_feature = "simd128"
));

/// Iterations `lo..hi` of the forward sweep, one at a time (see [`forward_interior_blocked`]).
fn forward_interior_fused(s: &mut [f32], d: &mut [f32], lo: usize, hi: usize) {
    for i in lo..hi {
        d[i] += P0[0] * s[i + 1];
        s[i] += two(&U1, d[i], d[i - 1]);
        let e = i - 2;
        d[e] += two(&P2, s[e + 2], s[e + 1]);
        s[e] += two(&U3, d[e], d[e - 1]);
        let e = i - 3;
        d[e] += three(&P4, s[e], s[e - 1], s[e - 2]);
    }
}

/// Iterations `lo..hi` of the inverse sweep, one at a time (see [`inverse_interior_blocked`]).
fn inverse_interior_fused(s: &mut [f32], d: &mut [f32], lo: usize, hi: usize) {
    let (Some(s), Some(d)) = (s.get_mut(..hi), d.get_mut(..hi)) else {
        return;
    };
    for i in lo.max(5)..hi {
        d[i] -= three(&P4, s[i], s[i - 1], s[i - 2]);
        let e = i - 2;
        s[e] -= two(&U3, d[e], d[e - 1]);
        let e = i - 4;
        d[e] -= two(&P2, s[e + 2], s[e + 1]);
        s[e] -= two(&U1, d[e], d[e - 1]);
        let e = i - 5;
        d[e] -= P0[0] * s[e + 1];
    }
}

/// One forward level on `x` (len `2H`, `H >= 8`); writes `[cA | cD]` to `x`. `offset` is
/// subtracted from every sample as it is read (0 leaves the samples exactly as they are).
///
/// The even channel `s` is extended to `H + 8` samples in `x[..H + 8]` itself, the odd
/// channel `d` in `scratch[..H + 8]` (extended index `e` = sample `n = e - 4`). All five
/// lifting steps then run in **one sweep**, each lagging the previous one by the reach of
/// its taps, so the data crosses memory once per level instead of once per step.
fn forward_level(x: &mut [f32], scratch: &mut [f32], offset: f32, blocked: bool) {
    let n2 = x.len();
    let h = n2 / 2;
    let e_len = h + 2 * GHOST;
    let Some(d) = scratch.get_mut(..e_len) else {
        return;
    };
    // Odd samples first (x is still intact): d[e] = x[2(e - 4) + 1 mod 2H].
    for e in 0..GHOST {
        st(d, e, ld(x, n2 - 2 * GHOST + 2 * e + 1) - offset);
        st(d, h + GHOST + e, ld(x, 2 * e + 1) - offset);
    }
    for (v, pair) in d[GHOST..h + GHOST].iter_mut().zip(x.chunks_exact(2)) {
        *v = pair[1] - offset;
    }
    // Even samples compacted into x itself: s[e] = x[2(e - 4) mod 2H], ascending e. Read
    // positions below 16 may already be overwritten, so those come from a copy.
    let mut head = [0.0f32; 16];
    copy(&mut head, x);
    let mut tail = [0.0f32; GHOST];
    for (e, t) in tail.iter_mut().enumerate() {
        *t = ld(x, n2 - 2 * GHOST + 2 * e) - offset;
    }
    copy(x, &tail);
    for e in GHOST..GHOST + 8 {
        st(x, e, ld(&head, 2 * (e - GHOST)) - offset);
    }
    // x[e] = x[2 (e - 4)] - offset for e in 12..H + 4, ascending (each read is ahead of
    // every write so far). Through cells: reads and writes of the same slice by iterators,
    // with no index to check.
    let cells = core::cell::Cell::from_mut(&mut *x).as_slice_of_cells();
    for (dst, src) in cells
        .iter()
        .skip(GHOST + 8)
        .zip(cells.iter().skip(16).step_by(2))
        .take(h.saturating_sub(8))
    {
        dst.set(src.get() - offset);
    }
    for e in 0..GHOST {
        st(x, h + GHOST + e, ld(&head, 2 * e) - offset);
    }
    let Some(s) = x.get_mut(..e_len) else {
        return;
    };
    // Sweep: steps 1 and 2 at e = i, steps 3 and 4 at i - 2, step 5 at i - 3. Each step
    // overwrites only values that no later step still needs in their previous form. The
    // first and last iterations check which steps are in range; the interior does not.
    let edge = |s: &mut [f32], d: &mut [f32], i: usize| {
        if i + 1 < e_len {
            add(d, i, P0[0] * ld(s, i + 1));
            if i >= 1 {
                add(s, i, two(&U1, ld(d, i), ld(d, i - 1)));
            }
        }
        if i >= 2 && (1..e_len - 3).contains(&(i - 2)) {
            let e = i - 2;
            add(d, e, two(&P2, ld(s, e + 2), ld(s, e + 1)));
            if e >= 2 {
                add(s, e, two(&U3, ld(d, e), ld(d, e - 1)));
            }
        }
        if i >= 3 && (4..e_len - 3).contains(&(i - 3)) {
            let e = i - 3;
            add(d, e, three(&P4, ld(s, e), ld(s, e - 1), ld(s, e - 2)));
        }
    };
    for i in 0..7 {
        edge(s, d, i);
    }
    if blocked {
        forward_interior_blocked(s, d, 7, e_len - 1);
    } else {
        forward_interior_fused(s, d, 7, e_len - 1);
    }
    for i in e_len - 1..e_len + 1 {
        edge(s, d, i);
    }
    // Scale and rotate into PyWavelets order: cA[n] = s[n - 1] (e = n + 3), cD[n] = d[n + 1]
    // (e = n + 5). Reading x[n + 3] while writing x[n] in ascending order is safe.
    for n in 0..h {
        x[n] = K_S * x[n + GHOST - 1];
    }
    for (c, v) in x[h..].iter_mut().zip(&scratch[GHOST + 1..]) {
        *c = K_D * v;
    }
}

/// One inverse level: reads `[cA | cD]` from `x` (len `2H`) and writes the signal back,
/// undoing the steps of [`forward_level`] in one sweep, with the same ghost-cell layout.
/// `offset` is added to every sample as it is written.
// Kept out of line: inlined into the firmware's main loop, its locals enlarged that
// function's (permanent) stack frame; out of line they only exist during the call.
// Measured with `scripts/fw-budget.sh`: stack high-water 16,208 bytes instead of 16,228.
#[inline(never)]
fn inverse_level(x: &mut [f32], scratch: &mut [f32], offset: f32, blocked: bool) {
    let n2 = x.len();
    let h = n2 / 2;
    let e_len = h + 2 * GHOST;
    // d[e] = cD[n - 1] / K_D = K_S * cD[(e - 5) mod H].
    {
        let (Some(cd), Some(d)) = (x.get(h..), scratch.get_mut(..e_len)) else {
            return;
        };
        for e in 0..GHOST + 1 {
            st(d, e, K_S * ld(cd, h - GHOST - 1 + e));
        }
        for (v, c) in d.iter_mut().skip(GHOST + 1).zip(cd) {
            *v = K_S * c;
        }
        for e in h + GHOST + 1..e_len {
            st(d, e, K_S * ld(cd, e - GHOST - 1 - h));
        }
    }
    // s[e] = cA[n + 1] / K_S = K_D * cA[(e - 3) mod H], written into x[e] in descending
    // order (reads x[e - 3], below the write position); wrapped reads come from copies.
    let mut ca_head = [0.0f32; 8];
    copy(&mut ca_head, x);
    let mut ca_tail = [0.0f32; 8];
    copy(&mut ca_tail, x.get(h - 8..h).unwrap_or(&[]));
    for e in (h + GHOST - 1..e_len).rev() {
        st(x, e, K_D * ld(&ca_head, e - (h + GHOST - 1)));
    }
    // The middle, x[e] = K_D * x[e - 3]: scaled in place, then moved up by 3 (memmove); two
    // vectorised passes instead of one descending scalar one. Same products.
    for v in x.iter_mut().take(h) {
        *v *= K_D;
    }
    // x[..h] moved up by GHOST - 1 (a memmove), on a sub-slice of exactly the length it
    // needs, so the compiler proves copy_within's range check.
    if let Some(part) = x.get_mut(..h + GHOST - 1) {
        part.copy_within(..h, GHOST - 1);
    }
    for e in 0..GHOST - 1 {
        st(x, e, K_D * ld(&ca_tail, 8 - (GHOST - 1) + e));
    }
    let (Some(s), Some(d)) = (x.get_mut(..e_len), scratch.get_mut(..e_len)) else {
        return;
    };
    // Undo 5 at e = i, 4 at i - 2, 3 and 2 at i - 4, 1 at i - 5; range checks only at the
    // first and last iterations.
    let edge = |s: &mut [f32], d: &mut [f32], i: usize| {
        if (2..e_len).contains(&i) {
            sub(d, i, three(&P4, ld(s, i), ld(s, i - 1), ld(s, i - 2)));
        }
        if i >= 2 && (3..e_len).contains(&(i - 2)) {
            let e = i - 2;
            sub(s, e, two(&U3, ld(d, e), ld(d, e - 1)));
        }
        if i >= 4 && (3..e_len - 2).contains(&(i - 4)) {
            let e = i - 4;
            sub(d, e, two(&P2, ld(s, e + 2), ld(s, e + 1)));
            if e >= 4 {
                sub(s, e, two(&U1, ld(d, e), ld(d, e - 1)));
            }
        }
        if i >= 5 && (4..e_len - 3).contains(&(i - 5)) {
            let e = i - 5;
            sub(d, e, P0[0] * ld(s, e + 1));
        }
    };
    for i in 0..9 {
        edge(s, d, i);
    }
    if blocked {
        inverse_interior_blocked(s, d, 9, e_len);
    } else {
        inverse_interior_fused(s, d, 9, e_len);
    }
    for i in e_len..e_len + 5 {
        edge(s, d, i);
    }
    // Interleave back: x[2n] = s[n + 4], x[2n + 1] = d[n + 4]. s lives in x, where the
    // interleaved output would overwrite it, so it is first copied out: s[4..12] (n < 8) to
    // the stack, the rest (n = 8..H, H - 8 values) to scratch[H + 8..2H], which the sweep
    // does not use. The interleaving loop then reads only copies and vectorises.
    let mut s_head = [0.0f32; 8];
    copy(&mut s_head, x.get(GHOST..).unwrap_or(&[]));
    copy(
        scratch.get_mut(h + 2 * GHOST..n2).unwrap_or(&mut []),
        x.get(GHOST + 8..h + GHOST).unwrap_or(&[]),
    );
    let Some((d_all, s_rest)) = scratch
        .get(..n2)
        .and_then(|v| v.split_at_checked(h + 2 * GHOST))
    else {
        return;
    };
    let Some((x_head, x_rest)) = x.split_at_mut_checked(16) else {
        return;
    };
    for ((pair, sv), dv) in x_head.chunks_exact_mut(2).zip(&s_head).zip(&d_all[GHOST..]) {
        pair[0] = sv + offset;
        pair[1] = dv + offset;
    }
    for ((pair, sv), dv) in x_rest
        .chunks_exact_mut(2)
        .zip(s_rest)
        .zip(&d_all[GHOST + 8..])
    {
        pair[0] = sv + offset;
        pair[1] = dv + offset;
    }
}

/// Multi-level forward transform in place; see the module docs for the output layout.
///
/// `scratch` must be at least as long as `x`; its contents on return are unspecified.
pub fn forward(x: &mut [f32], scratch: &mut [f32], levels: u32) -> Result<(), TransformError> {
    forward_offset(x, scratch, levels, 0.0)
}

/// [`forward`] of `x - offset`: the offset is subtracted as the first level reads the
/// samples, which saves a pass over the data (the denoiser removes the block mean this way).
pub fn forward_offset(
    x: &mut [f32],
    scratch: &mut [f32],
    levels: u32,
    offset: f32,
) -> Result<(), TransformError> {
    check(x.len(), scratch.len(), levels)?;
    let mut n = x.len();
    for level in 0..levels {
        forward_level(
            &mut x[..n],
            scratch,
            if level == 0 { offset } else { 0.0 },
            BLOCKED_SWEEP,
        );
        n /= 2;
    }
    Ok(())
}

/// Multi-level inverse of [`forward`] in place (same `levels`).
pub fn inverse(x: &mut [f32], scratch: &mut [f32], levels: u32) -> Result<(), TransformError> {
    inverse_offset(x, scratch, levels, 0.0)
}

/// [`inverse`], then `+ offset` on every sample, in the same pass as the last level.
pub fn inverse_offset(
    x: &mut [f32],
    scratch: &mut [f32],
    levels: u32,
    offset: f32,
) -> Result<(), TransformError> {
    check(x.len(), scratch.len(), levels)?;
    let mut n = x.len() >> (levels - 1);
    for level in (0..levels).rev() {
        // `get_mut`, not `[..n]`: n <= x.len() (checked above); no range check in the firmware.
        if let Some(part) = x.get_mut(..n) {
            inverse_level(
                part,
                scratch,
                if level == 0 { offset } else { 0.0 },
                BLOCKED_SWEEP,
            );
        }
        n *= 2;
    }
    Ok(())
}

/// Index range of the detail coefficients `cD_level` (1 = finest) inside a transformed
/// slice of length `len`. Returns an empty range for a level that does not exist.
pub fn detail_range(len: usize, level: u32) -> core::ops::Range<usize> {
    if level == 0 || level > usize::BITS - 1 || len >> level == 0 {
        return 0..0;
    }
    let start = len >> level;
    start..2 * start
}

/// The straightforward multi-pass lifting (one pass per step, modular indexing at the ends),
/// kept as the reference the fused sweep must reproduce bit for bit.
#[cfg(test)]
mod multipass {
    use super::{K_D, K_S, P0, P2, P4, U1, U3};

    /// `dst[n] += sum_i coeffs[i] * src[(n + offset - i) mod H]` for every `n`, `H = dst.len()`.
    ///
    /// The interior, where no index wraps, runs as one multiply-add pass per tap (which the
    /// compiler vectorises); the few wrapped indices at either end are done separately.
    #[inline(always)]
    fn lift_step<const TAPS: usize>(
        dst: &mut [f32],
        src: &[f32],
        coeffs: &[f32; TAPS],
        offset: usize,
    ) {
        let h = dst.len();
        // Indices n + offset - i stay within 0..h for n in lo..hi.
        let lo = (TAPS - 1).saturating_sub(offset).min(h);
        let hi = h.saturating_sub(offset).max(lo);
        let wrapped = |n: usize, dst: &mut [f32]| {
            let mut acc = 0.0f32;
            for (i, c) in coeffs.iter().enumerate() {
                // (n + offset - i) mod h without going negative: add h * TAPS first.
                let j = (n + offset + h * TAPS - i) % h;
                acc += c * src[j];
            }
            dst[n] += acc;
        };
        for n in 0..lo {
            wrapped(n, dst);
        }
        if lo < hi {
            // Accumulate the taps in the same order as `wrapped`, so every sample is computed by
            // the same sequence of f32 operations wherever it lies.
            let base = lo + offset;
            let out = &mut dst[lo..hi];
            match TAPS {
                1 => {
                    for (o, s) in out.iter_mut().zip(&src[base..]) {
                        *o += coeffs[0] * s;
                    }
                }
                2 => {
                    for ((o, s0), s1) in out.iter_mut().zip(&src[base..]).zip(&src[base - 1..]) {
                        *o += coeffs[0] * s0 + coeffs[1] * s1;
                    }
                }
                _ => {
                    for (k, o) in out.iter_mut().enumerate() {
                        let mut acc = 0.0f32;
                        for (i, c) in coeffs.iter().enumerate() {
                            acc += c * src[base + k - i];
                        }
                        *o += acc;
                    }
                }
            }
        }
        for n in hi..h {
            wrapped(n, dst);
        }
    }

    /// `dst[n] -= ...`: the exact undo of [`lift_step`] with the same coefficients.
    #[inline(always)]
    fn unlift_step<const TAPS: usize>(
        dst: &mut [f32],
        src: &[f32],
        coeffs: &[f32; TAPS],
        offset: usize,
    ) {
        let neg = coeffs.map(|c| -c);
        lift_step(dst, src, &neg, offset);
    }

    /// One forward level on `x` (len `2H`), using `scratch[..2H]`; writes `[cA | cD]` to `x`.
    pub(crate) fn forward_level_multipass(x: &mut [f32], scratch: &mut [f32]) {
        let h = x.len() / 2;
        let (s, d) = scratch[..2 * h].split_at_mut(h);
        for (n, pair) in x.chunks_exact(2).enumerate() {
            s[n] = pair[0];
            d[n] = pair[1];
        }
        lift_step(d, s, &P0, 1);
        lift_step(s, d, &U1, 0);
        lift_step(d, s, &P2, 2);
        lift_step(s, d, &U3, 0);
        lift_step(d, s, &P4, 0);
        // Scale and rotate into PyWavelets order: cA[n] = s[n-1], cD[n] = d[n+1].
        let (ca, cd) = x.split_at_mut(h);
        ca[0] = K_S * s[h - 1];
        for (a, v) in ca[1..].iter_mut().zip(&s[..h - 1]) {
            *a = K_S * v;
        }
        for (c, v) in cd[..h - 1].iter_mut().zip(&d[1..]) {
            *c = K_D * v;
        }
        cd[h - 1] = K_D * d[0];
    }

    /// One inverse level: reads `[cA | cD]` from `x` (len `2H`) and writes the signal back.
    pub(crate) fn inverse_level_multipass(x: &mut [f32], scratch: &mut [f32]) {
        let h = x.len() / 2;
        let (s, d) = scratch[..2 * h].split_at_mut(h);
        let (ca, cd) = x.split_at(h);
        // K_S * K_D = 1 (to 2e-16 in f64), so dividing by one is multiplying by the other.
        s[h - 1] = K_D * ca[0];
        for (v, a) in s[..h - 1].iter_mut().zip(&ca[1..]) {
            *v = K_D * a;
        }
        for (v, c) in d[1..].iter_mut().zip(&cd[..h - 1]) {
            *v = K_S * c;
        }
        d[0] = K_S * cd[h - 1];
        unlift_step(d, s, &P4, 0);
        unlift_step(s, d, &U3, 0);
        unlift_step(d, s, &P2, 2);
        unlift_step(s, d, &U1, 0);
        unlift_step(d, s, &P0, 1);
        for (n, pair) in x.chunks_exact_mut(2).enumerate() {
            pair[0] = s[n];
            pair[1] = d[n];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fused_and_blocked_sweeps_equal_multipass_bit_for_bit() {
        // Up to 4096 samples: the blocked sweep then runs 8 full blocks and a partial one.
        let mut state = 99u32;
        for m in 4..=12 {
            let n = 1usize << m;
            let x0: [f32; 4096] = core::array::from_fn(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 8) as f32 / 65_536.0 - 128.0
            });
            for blocked in [false, true] {
                let (mut a, mut b) = (x0, x0);
                let mut s = [0.0f32; 4096];
                forward_level(&mut a[..n], &mut s, 0.0, blocked);
                multipass::forward_level_multipass(&mut b[..n], &mut s);
                assert!(
                    a[..n]
                        .iter()
                        .zip(&b[..n])
                        .all(|(u, v)| u.to_bits() == v.to_bits()),
                    "forward, n = {n}, blocked {blocked}"
                );
                inverse_level(&mut a[..n], &mut s, 0.0, blocked);
                multipass::inverse_level_multipass(&mut b[..n], &mut s);
                assert!(
                    a[..n]
                        .iter()
                        .zip(&b[..n])
                        .all(|(u, v)| u.to_bits() == v.to_bits()),
                    "inverse, n = {n}, blocked {blocked}"
                );
            }
        }
    }
}
