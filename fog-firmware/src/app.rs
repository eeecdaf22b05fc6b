//! The main loop, shared by every board: serial bytes in, records out, statistics.
#![forbid(unsafe_code)]

use core::cell::Cell;

use embedded_hal_nb::serial::{ErrorType, Read, Write};
use fog_core::driver::GyroReader;
use fog_core::frame::{ByteStats, Decoder, EcoreDecoder};

use crate::pipeline::{self, Command, CommandDetector, RunTotals};
use crate::temperature::TemperatureSource;

/// The identifier image embedded at build time: `build.rs` copies the file named by
/// `FOG_IDENTIFIER` (default `fog-firmware/identifier/default.fogi`) to `OUT_DIR`. It is
/// parsed and checked at boot ([`pipeline::new_stage`]), read through [`image_bytes`]. An
/// array (not a slice reference), so that the ELF's symbol table names its bytes and their
/// length: the HIL tests read the image back from the ELF they run (`tests/src/lib.rs`,
/// `Firmware::embedded`).
pub static IDENTIFIER_IMAGE: [u8; IDENTIFIER_IMAGE_LEN] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/identifier.fogi"));

/// Length of [`IDENTIFIER_IMAGE`], bytes.
pub const IDENTIFIER_IMAGE_LEN: usize =
    include_bytes!(concat!(env!("OUT_DIR"), "/identifier.fogi")).len();

/// The embedded image as data the compiler knows nothing of ([`core::hint::black_box`]):
/// the firmware parses whatever bytes the flash holds at [`IDENTIFIER_IMAGE`]. Without it the
/// compiler evaluates the parse of a known image at build time (a truncated image's parse
/// folded to its error) and drops the bytes from the ELF, so the image written into the
/// ELF or the flash would not be the one that runs, and could not be read back.
pub fn image_bytes() -> &'static [u8] {
    core::hint::black_box(&IDENTIFIER_IMAGE)
}

/// Periodic statistics on defmt every this many samples.
pub const STATS_EVERY_SAMPLES: u32 = 1000;

/// A free-running counter of the board (SysTick or DWT CYCCNT).
pub trait TickCounter {
    /// What one tick is, for the logs.
    const UNIT: &'static str;
    /// Ticks per instruction, times 10 (16 on QEMU under `-icount shift=6`; 10 when the unit
    /// is a core cycle and cycles are reported as they are).
    const TICKS_PER_UNIT_X10: u32;
    /// Current stamp.
    fn stamp(&self) -> u32;
    /// Ticks elapsed since `start` (one wrap at most).
    fn ticks_since(&self, start: u32) -> u32;
    /// Ticks converted to the unit reported (instructions or cycles).
    fn to_units(ticks: u32) -> u32 {
        (u64::from(ticks) * 10 / u64::from(Self::TICKS_PER_UNIT_X10)) as u32
    }
}

/// Bytes the board's receive path lost before the decoder could see them (see
/// `board::rx`): each loss also reaches the decoder as one receive error at the place in
/// the stream where it happened, so the frame it cut is dropped and counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RxLoss {
    /// Bytes overwritten in the receive register before the receive interrupt read them
    /// (a real UART only flags the event: counted 1 per event there).
    pub overrun: u32,
    /// Bytes dropped because the receive queue was full.
    pub queue_full: u32,
}

/// Why the loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Stop {
    /// The end marker arrived; the final record was written.
    EndOfInput,
    /// The stage could not be built.
    Setup,
}

/// What the in-band commands set so far (see [`pipeline::Command`]).
#[derive(Debug, Clone, Copy, Default)]
struct Commands {
    ended: bool,
    still: Option<bool>,
    count: u32,
}

/// A receive half that watches for the in-band commands ([`pipeline::END_MARKER`], the
/// still-flag markers) and reports `WouldBlock` for ever once the end marker has passed.
/// Every byte, those of the commands included, is given to the decoder like any byte (it
/// counts them as skipped).
struct CommandTap<'a, R> {
    rx: R,
    detector: CommandDetector,
    state: &'a Cell<Commands>,
}

impl<R: ErrorType> ErrorType for CommandTap<'_, R> {
    type Error = R::Error;
}

impl<R: Read<u8>> Read<u8> for CommandTap<'_, R> {
    fn read(&mut self) -> nb::Result<u8, Self::Error> {
        let mut st = self.state.get();
        if st.ended {
            return Err(nb::Error::WouldBlock);
        }
        let byte = self.rx.read()?;
        match self.detector.push(byte) {
            Some(Command::End) => st.ended = true,
            Some(c) => {
                st.still = c.still_flag();
                st.count = st.count.wrapping_add(1);
            }
            None => return Ok(byte),
        }
        self.state.set(st);
        Ok(byte)
    }
}

/// A short reason for a refused image, sent as a `{=str}` argument (so that it appears
/// verbatim in the defmt log, not only as an interned index).
fn image_error_reason(e: &fog_core::image::ImageError) -> &'static str {
    use fog_core::image::ImageError as E;
    match e {
        E::BadMagic => "bad magic",
        E::Truncated { .. } => "truncated",
        E::RetiredFormat(_) => {
            "retired format (the old estimators' image): retrain with host-sim identify"
        }
        E::UnsupportedVersion(_) => "unsupported format version",
        E::TrailingBytes(_) => "trailing bytes",
        E::BadChecksum { .. } => "checksum mismatch",
        E::WrongPreset(_) => "not a drift filter image (preset id)",
        E::BadModel => "invalid gyro model or filter configuration",
        E::RateMismatch { .. } => "sample rate mismatch",
        E::BufferTooSmall => "buffer too small",
    }
}

/// Writes all of `bytes`, blocking. A transmit error loses the rest of this record only.
pub fn write_all<W: Write<u8>>(tx: &mut W, bytes: &[u8]) {
    for &b in bytes {
        if nb::block!(tx.write(b)).is_err() {
            return;
        }
    }
}

/// Per-period instruction statistics.
#[derive(Default)]
struct Period {
    samples: u32,
    ticks_sum: u64,
    ticks_max: u32,
}

fn log_stats<C: TickCounter>(s: &ByteStats, t: &RunTotals, p: &Period) {
    let mean = if p.samples > 0 {
        (p.ticks_sum / u64::from(p.samples)) as u32
    } else {
        0
    };
    defmt::info!(
        "samples {=u32}: frames good {=u64} bad {=u64}; bytes total {=u64} good {=u64} skipped {=u64} pending {=u64}; serial errors {=u32}; identify+record per sample: mean {=u32}, max {=u32} {=str}",
        t.samples,
        s.frames_good,
        s.frames_bad,
        s.bytes_total,
        s.bytes_good,
        s.skipped.total(),
        s.bytes_pending,
        t.serial_errors,
        C::to_units(mean),
        C::to_units(p.ticks_max),
        C::UNIT
    );
}

/// Runs until the end marker: decodes E-Core frames from `rx`, writes one record per good
/// frame to `tx`, then flushes the decoder and writes the statistics record.
///
/// `stack_bytes` and `rx_loss` are called once at the end for the final record. `temperature`
/// gives each sample's `temp_c` (`None` without a sensor). `still_input` is the board's
/// external still flag (a GPIO input; `None` when the board has none). The external flag of
/// a sample is the last still-flag command of the stream when one set it (`FOG-STL!` or
/// `FOG-MOV!`), else `still_input()`.
pub fn run<R, W, C, I>(
    rx: R,
    tx: &mut W,
    counter: &C,
    stack_bytes: fn() -> u32,
    rx_loss: fn() -> RxLoss,
    mut temperature: TemperatureSource<I>,
    still_input: fn() -> Option<bool>,
) -> Stop
where
    R: Read<u8>,
    W: Write<u8>,
    C: TickCounter,
    I: embedded_hal::i2c::I2c,
{
    let Ok(decoder) = EcoreDecoder::new(pipeline::FULL_SCALE_DPS) else {
        defmt::error!("decoder configuration refused");
        return Stop::Setup;
    };
    // The stage is used where `new_stage` wrote it (a borrow of the result, not a move out
    // of it): moving it out would keep a second copy of it (about 7 KiB) on the stack.
    let mut built = pipeline::new_stage(image_bytes());
    let stage = match &mut built {
        Ok(s) => s,
        Err(pipeline::SetupError::Image(e)) => {
            defmt::error!(
                "identifier image refused ({=usize} bytes embedded): {=str}: {}",
                IDENTIFIER_IMAGE.len(),
                image_error_reason(e),
                e
            );
            return Stop::Setup;
        }
        Err(pipeline::SetupError::Estimator(e)) => {
            defmt::error!("identifier image: drift filter refused: {}", e);
            return Stop::Setup;
        }
        Err(pipeline::SetupError::Denoiser(e)) => {
            defmt::error!("denoiser configuration refused: {}", e);
            return Stop::Setup;
        }
    };
    let commands = Cell::new(Commands::default());
    let tap = CommandTap {
        rx,
        detector: CommandDetector::default(),
        state: &commands,
    };
    let mut reader = GyroReader::new(tap, decoder);
    let mut totals = RunTotals::default();
    let mut period = Period::default();
    defmt::info!(
        "fog-firmware: E-Core {=f32} deg/s full scale, {=f32} Hz, drift filter image ({=usize} bytes) loaded, drift bound {=f32} deg/s, window {=u32} samples, denoise block {=usize} (resumable), denoised field {=usize} samples late",
        pipeline::FULL_SCALE_DPS,
        stage.sample_rate_hz(),
        IDENTIFIER_IMAGE.len(),
        stage.filter().model().drift_bound_dps,
        stage.filter().window_samples(),
        pipeline::BLOCK,
        pipeline::DENOISED_DELAY_SAMPLES
    );
    loop {
        match reader.read() {
            Ok(frame) => {
                let temp_c = temperature.sample();
                let external = commands.get().still.or_else(still_input);
                let t0 = counter.stamp();
                let (out, status) = pipeline::process(stage, frame.rate_dps, temp_c, external);
                let record = pipeline::sample_record(totals.samples, frame.rate_dps, &out, status);
                let ticks = counter.ticks_since(t0);
                write_all(tx, &record);
                totals.samples = totals.samples.wrapping_add(1);
                if status & pipeline::STATUS_REJECTED != 0 {
                    totals.rejected = totals.rejected.wrapping_add(1);
                }
                period.samples += 1;
                period.ticks_sum += u64::from(ticks);
                period.ticks_max = period.ticks_max.max(ticks);
                if period.samples >= STATS_EVERY_SAMPLES {
                    log_stats::<C>(reader.stats(), &totals, &period);
                    period = Period::default();
                }
            }
            Err(nb::Error::WouldBlock) => {
                if commands.get().ended {
                    break;
                }
            }
            Err(nb::Error::Other(_)) => {
                // Already counted by the decoder as one lost byte.
                totals.serial_errors = totals.serial_errors.wrapping_add(1);
            }
        }
    }
    reader.decoder_mut().flush();
    totals.stack_bytes = stack_bytes();
    totals.still_commands = commands.get().count;
    let loss = rx_loss();
    (totals.rx_overrun, totals.rx_queue_full) = (loss.overrun, loss.queue_full);
    let stats = *reader.stats();
    log_stats::<C>(&stats, &totals, &period);
    defmt::info!(
        "end of input: {=u32} samples, stack high-water {=u32} bytes, receive bytes lost: {=u32} overrun, {=u32} queue full; accounting consistent {=bool}",
        totals.samples,
        totals.stack_bytes,
        totals.rx_overrun,
        totals.rx_queue_full,
        stats.is_consistent()
    );
    let m = stage.filter().stats();
    defmt::info!(
        "drift filter: {=u32} samples, {=u32} windows, {=u32} still (updates), {=u32} undone, {=u32} refused; still-flag commands {=u32}",
        m.samples,
        m.windows,
        m.still_windows,
        m.undone,
        m.rejected,
        totals.still_commands
    );
    defmt::info!(
        "temperature: sensor {=str}, failed reads {=u32}",
        temperature.model().unwrap_or("none"),
        temperature.failures()
    );
    write_all(tx, &pipeline::stats_record(&stats, &totals));
    // A transmit error at this point has nowhere to be reported.
    let _ = nb::block!(tx.flush());
    Stop::EndOfInput
}
