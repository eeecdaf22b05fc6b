//! Byte and frame counters shared by the decoders. Semantics and invariant: see the
//! [parent module](super#byte-accounting).

use super::UartError;

/// Why bytes were dropped; each reason has one counter in [`Skipped`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SkipReason {
    /// Outside any frame: E-Core bytes without the sync flag between frames or before the
    /// first sync byte; DSP-3000 bytes before the first CR LF that do not form a line.
    NoSync,
    /// An E-Core frame of 8 bytes whose payload sum is not 0 mod 256.
    Checksum,
    /// An E-Core partial frame ended by a new sync byte (the sync byte starts a new frame
    /// and is not counted here).
    CutShort,
    /// Bytes lost to a UART error: the error slot itself and the bytes of the frame or line
    /// segment it damaged.
    Uart(UartError),
    /// A DSP-3000 line segment that ended in CR LF but is not a well-formed 21-byte line
    /// (bad ASCII, bad number, bad status, too short).
    Malformed,
    /// DSP-3000 bytes more than 21 before the next CR LF: they cannot belong to a line.
    TooLong,
    /// A partial frame or line dropped by [`super::Decoder::flush`].
    Incomplete,
}

/// Bytes dropped, per reason (`u64`, wrapping).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Skipped {
    /// [`SkipReason::NoSync`].
    pub no_sync: u64,
    /// [`SkipReason::Checksum`].
    pub checksum: u64,
    /// [`SkipReason::CutShort`].
    pub cut_short: u64,
    /// [`SkipReason::Uart`] with [`UartError::Overrun`].
    pub uart_overrun: u64,
    /// [`SkipReason::Uart`] with [`UartError::Framing`].
    pub uart_framing: u64,
    /// [`SkipReason::Uart`] with [`UartError::Parity`].
    pub uart_parity: u64,
    /// [`SkipReason::Uart`] with [`UartError::Noise`].
    pub uart_noise: u64,
    /// [`SkipReason::Uart`] with [`UartError::Other`].
    pub uart_other: u64,
    /// [`SkipReason::Malformed`].
    pub malformed: u64,
    /// [`SkipReason::TooLong`].
    pub too_long: u64,
    /// [`SkipReason::Incomplete`].
    pub incomplete: u64,
}

impl Skipped {
    /// All zero.
    pub const ZERO: Self = Self {
        no_sync: 0,
        checksum: 0,
        cut_short: 0,
        uart_overrun: 0,
        uart_framing: 0,
        uart_parity: 0,
        uart_noise: 0,
        uart_other: 0,
        malformed: 0,
        too_long: 0,
        incomplete: 0,
    };

    /// Bytes dropped for `reason`.
    pub const fn get(&self, reason: SkipReason) -> u64 {
        match reason {
            SkipReason::NoSync => self.no_sync,
            SkipReason::Checksum => self.checksum,
            SkipReason::CutShort => self.cut_short,
            SkipReason::Uart(UartError::Overrun) => self.uart_overrun,
            SkipReason::Uart(UartError::Framing) => self.uart_framing,
            SkipReason::Uart(UartError::Parity) => self.uart_parity,
            SkipReason::Uart(UartError::Noise) => self.uart_noise,
            SkipReason::Uart(UartError::Other) => self.uart_other,
            SkipReason::Malformed => self.malformed,
            SkipReason::TooLong => self.too_long,
            SkipReason::Incomplete => self.incomplete,
        }
    }

    fn slot_mut(&mut self, reason: SkipReason) -> &mut u64 {
        match reason {
            SkipReason::NoSync => &mut self.no_sync,
            SkipReason::Checksum => &mut self.checksum,
            SkipReason::CutShort => &mut self.cut_short,
            SkipReason::Uart(UartError::Overrun) => &mut self.uart_overrun,
            SkipReason::Uart(UartError::Framing) => &mut self.uart_framing,
            SkipReason::Uart(UartError::Parity) => &mut self.uart_parity,
            SkipReason::Uart(UartError::Noise) => &mut self.uart_noise,
            SkipReason::Uart(UartError::Other) => &mut self.uart_other,
            SkipReason::Malformed => &mut self.malformed,
            SkipReason::TooLong => &mut self.too_long,
            SkipReason::Incomplete => &mut self.incomplete,
        }
    }

    /// Bytes lost to UART errors, all kinds.
    pub const fn uart(&self) -> u64 {
        self.uart_overrun
            .wrapping_add(self.uart_framing)
            .wrapping_add(self.uart_parity)
            .wrapping_add(self.uart_noise)
            .wrapping_add(self.uart_other)
    }

    /// Bytes dropped, all reasons (wrapping sum).
    pub const fn total(&self) -> u64 {
        self.no_sync
            .wrapping_add(self.checksum)
            .wrapping_add(self.cut_short)
            .wrapping_add(self.uart())
            .wrapping_add(self.malformed)
            .wrapping_add(self.too_long)
            .wrapping_add(self.incomplete)
    }
}

/// Byte and frame counters of one decoder (`u64`, wrapping).
///
/// Invariant after every decoder call ([`Self::is_consistent`]):
/// `bytes_total == bytes_good + skipped.total() + bytes_pending` (mod 2^64).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ByteStats {
    /// Bytes given to the decoder, error slots included.
    pub bytes_total: u64,
    /// Bytes of frames and lines delivered (DSP-3000 fault lines included).
    pub bytes_good: u64,
    /// Bytes of the partial frame or line held by the decoder, not yet judged (at most 20).
    pub bytes_pending: u64,
    /// Bytes dropped, per reason.
    pub skipped: Skipped,
    /// Valid samples delivered.
    pub frames_good: u64,
    /// DSP-3000 fault lines delivered (status `0`).
    pub frames_fault: u64,
    /// E-Core frames begun (sync byte seen) and dropped; DSP-3000 line segments, after
    /// synchronisation, that hold a UART error or end without a line (each once).
    pub frames_bad: u64,
}

impl ByteStats {
    /// Number of counters in [`ByteStats::counters`].
    pub const COUNTERS: usize = 17;

    /// Every counter in one fixed order (the order of the firmware's statistics record):
    /// `bytes_total, bytes_good, bytes_pending`, the skipped bytes by reason (`no_sync,
    /// checksum, cut_short, uart_overrun, uart_framing, uart_parity, uart_noise, uart_other,
    /// malformed, too_long, incomplete`), then `frames_good, frames_fault, frames_bad`.
    pub fn counters(&self) -> [u64; Self::COUNTERS] {
        let k = &self.skipped;
        [
            self.bytes_total,
            self.bytes_good,
            self.bytes_pending,
            k.no_sync,
            k.checksum,
            k.cut_short,
            k.uart_overrun,
            k.uart_framing,
            k.uart_parity,
            k.uart_noise,
            k.uart_other,
            k.malformed,
            k.too_long,
            k.incomplete,
            self.frames_good,
            self.frames_fault,
            self.frames_bad,
        ]
    }

    /// All zero.
    pub const ZERO: Self = Self {
        bytes_total: 0,
        bytes_good: 0,
        bytes_pending: 0,
        skipped: Skipped::ZERO,
        frames_good: 0,
        frames_fault: 0,
        frames_bad: 0,
    };

    /// `bytes_good + skipped.total() + bytes_pending` (wrapping): equals `bytes_total`.
    pub const fn accounted(&self) -> u64 {
        self.bytes_good
            .wrapping_add(self.skipped.total())
            .wrapping_add(self.bytes_pending)
    }

    /// Whether the accounting invariant holds (it always should).
    pub const fn is_consistent(&self) -> bool {
        self.accounted() == self.bytes_total
    }

    /// One byte or error slot arrived; it is pending until judged.
    #[inline]
    pub(crate) fn receive(&mut self) {
        self.bytes_total = self.bytes_total.wrapping_add(1);
        self.bytes_pending = self.bytes_pending.wrapping_add(1);
    }

    /// `n` pending bytes are dropped for `reason`.
    pub(crate) fn skip(&mut self, n: usize, reason: SkipReason) {
        let n = n as u64;
        self.bytes_pending = self.bytes_pending.wrapping_sub(n);
        let slot = self.skipped.slot_mut(reason);
        *slot = slot.wrapping_add(n);
    }

    /// `n` pending bytes form a frame that is delivered (`fault`: a DSP-3000 fault line).
    pub(crate) fn deliver(&mut self, n: usize, fault: bool) {
        self.bytes_pending = self.bytes_pending.wrapping_sub(n as u64);
        self.bytes_good = self.bytes_good.wrapping_add(n as u64);
        if fault {
            self.frames_fault = self.frames_fault.wrapping_add(1);
        } else {
            self.frames_good = self.frames_good.wrapping_add(1);
        }
    }

    /// One frame was dropped (its bytes are counted by [`Self::skip`]).
    pub(crate) fn bad_frame(&mut self) {
        self.frames_bad = self.frames_bad.wrapping_add(1);
    }
}
