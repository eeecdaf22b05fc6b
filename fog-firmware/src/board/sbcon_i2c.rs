//! I2C master on an ARM SBCon two-wire port (MPS2 FPGA images, e.g. AN386): the program
//! drives SCL and SDA bit by bit, an `embedded_hal::i2c::I2c` on top.
//!
//! Registers (ARM "V2M-MPS2 Technical Reference Manual", SBCon; as QEMU's `arm_sbcon_i2c`
//! models them): offset 0x0 read = line state (bit 0 SCL, bit 1 SDA), offset 0x0 write = set
//! the bits written to 1 (release the line), offset 0x4 write = clear them (drive it low).
//! Open drain: a line reads high only if no one drives it low.
//!
//! Timing: every half clock period waits [`HALF_PERIOD_CYCLES`] core cycles (about 100 kHz at
//! the AN386's 25 MHz). No clock stretching: a slave that holds SCL low is not waited for.
//! Under QEMU nothing is attached to these buses unless the command line adds a device, so
//! every address is answered with a NACK.

use cortex_m::asm;
use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation};

/// Base address of the Shield1 SBCon port of the MPS2 (one of the two Arduino-shield
/// headers: where an external sensor board goes). Touch is at 0x4002_2000, audio at
/// 0x4002_3000, Shield0 at 0x4002_9000. QEMU's `-device tmp105,address=0x48` (a device
/// without an explicit bus) lands on this port, which the system test
/// `tests/tests/firmware_temperature.rs` uses.
pub const SHIELD1_BASE: usize = 0x4002_A000;

/// Read: line state. Write: release the lines whose bits are 1.
const CONTROL_SET: usize = 0x0;
/// Write: drive low the lines whose bits are 1.
const CONTROL_CLR: usize = 0x4;
const SCL: u32 = 1 << 0;
const SDA: u32 = 1 << 1;

/// Core cycles per half SCL period: 125 at 25 MHz is 5 us, 100 kHz (standard mode).
const HALF_PERIOD_CYCLES: u32 = 125;

/// One SBCon port.
#[derive(Debug)]
pub struct SbconI2c {
    base: usize,
}

impl SbconI2c {
    /// The port at `base` (one of the MPS2's SBCon I2C ports), both lines released.
    ///
    /// # Safety
    /// `base` must be an SBCon port of this machine, and no other code may drive it.
    pub unsafe fn new(base: usize) -> Self {
        let bus = Self { base };
        bus.release(SCL | SDA);
        bus
    }

    fn release(&self, lines: u32) {
        // SAFETY: `base` is an SBCon port (constructor contract): a word-aligned MMIO
        // register whose write has no effect but releasing the lines written as 1.
        unsafe { core::ptr::write_volatile((self.base + CONTROL_SET) as *mut u32, lines) };
        asm::delay(HALF_PERIOD_CYCLES);
    }

    fn drive_low(&self, lines: u32) {
        // SAFETY: as `release`, for the clear register.
        unsafe { core::ptr::write_volatile((self.base + CONTROL_CLR) as *mut u32, lines) };
        asm::delay(HALF_PERIOD_CYCLES);
    }

    fn sda_high(&self) -> bool {
        // SAFETY: as `release`; reading the line state has no side effect.
        let state = unsafe { core::ptr::read_volatile((self.base + CONTROL_SET) as *const u32) };
        state & SDA != 0
    }

    /// START (or repeated START): SDA falls while SCL is high; ends with SCL low.
    fn start(&self) {
        self.release(SDA);
        self.release(SCL);
        self.drive_low(SDA);
        self.drive_low(SCL);
    }

    /// STOP: SDA rises while SCL is high; leaves both lines released.
    fn stop(&self) {
        self.drive_low(SDA);
        self.release(SCL);
        self.release(SDA);
    }

    /// One bit out, SCL low before and after.
    fn write_bit(&self, high: bool) {
        if high {
            self.release(SDA);
        } else {
            self.drive_low(SDA);
        }
        self.release(SCL);
        self.drive_low(SCL);
    }

    /// One bit in (SDA released), SCL low before and after.
    fn read_bit(&self) -> bool {
        self.release(SDA);
        self.release(SCL);
        let bit = self.sda_high();
        self.drive_low(SCL);
        bit
    }

    /// Sends `byte` MSB first; `true` when the slave acknowledged.
    fn write_byte(&self, byte: u8) -> bool {
        for i in (0..8).rev() {
            self.write_bit(byte & (1 << i) != 0);
        }
        !self.read_bit()
    }

    /// Receives one byte MSB first, then acknowledges it (`ack`) or not (the last byte).
    fn read_byte(&self, ack: bool) -> u8 {
        let mut byte = 0u8;
        for _ in 0..8 {
            byte = (byte << 1) | u8::from(self.read_bit());
        }
        self.write_bit(!ack);
        byte
    }

    fn run(&self, address: u8, operations: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
        // Direction of the previous operation: a START and the address only when it changes.
        let mut previous_read: Option<bool> = None;
        let count = operations.len();
        for index in 0..count {
            let next_is_read = operations
                .get(index + 1)
                .map(|op| matches!(op, Operation::Read(_)));
            let Some(op) = operations.get_mut(index) else {
                break;
            };
            let is_read = matches!(op, Operation::Read(_));
            if previous_read != Some(is_read) {
                self.start();
                if !self.write_byte((address << 1) | u8::from(is_read)) {
                    return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
                }
                previous_read = Some(is_read);
            }
            match op {
                Operation::Write(bytes) => {
                    for &b in bytes.iter() {
                        if !self.write_byte(b) {
                            return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data));
                        }
                    }
                }
                Operation::Read(buffer) => {
                    // The last byte before a direction change or the STOP is not
                    // acknowledged (the slave then releases SDA).
                    let last_of_run = next_is_read != Some(true);
                    let n = buffer.len();
                    for (i, slot) in buffer.iter_mut().enumerate() {
                        *slot = self.read_byte(!(last_of_run && i + 1 == n));
                    }
                }
            }
        }
        Ok(())
    }
}

impl ErrorType for SbconI2c {
    type Error = ErrorKind;
}

impl I2c for SbconI2c {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), ErrorKind> {
        if operations.is_empty() {
            return Ok(());
        }
        let result = self.run(address & 0x7F, operations);
        self.stop();
        result
    }
}
