//! When to read the temperature sensor and how long a reading stays valid, counted in gyro
//! samples: no hardware, no logging, `core` only. `temperature.rs` drives the sensor with it,
//! and the host test `tests/tests/firmware_temperature.rs` compiles this very file (`#[path]`).
#![forbid(unsafe_code)]

/// Refresh and hold state of one reading.
///
/// Per sample: [`tick`](Self::tick) says whether a read is due (the first sample, then every
/// `refresh_samples`); the caller reports the read with [`good`](Self::good) or
/// [`failed`](Self::failed); [`value`](Self::value) gives the reading, dropped once more than
/// `hold_samples` samples have passed since the last good read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hold {
    refresh_samples: u32,
    hold_samples: u32,
    /// Samples until the next read (0: read at the next tick).
    until_read: u32,
    /// Samples since the last good read (saturating).
    age_samples: u32,
    /// Failed reads (saturating).
    failures: u32,
    last_c: Option<f32>,
}

impl Hold {
    /// A read every `refresh_samples` samples (0 is taken as 1), a reading valid for
    /// `hold_samples` samples after the last good read.
    pub const fn new(refresh_samples: u32, hold_samples: u32) -> Self {
        Self {
            refresh_samples: if refresh_samples == 0 {
                1
            } else {
                refresh_samples
            },
            hold_samples,
            until_read: 0,
            age_samples: 0,
            failures: 0,
            last_c: None,
        }
    }

    /// Advances one sample; `true` when a read is due at this sample.
    pub fn tick(&mut self) -> bool {
        self.age_samples = self.age_samples.saturating_add(1);
        if self.until_read > 0 {
            self.until_read -= 1;
            false
        } else {
            self.until_read = self.refresh_samples - 1;
            true
        }
    }

    /// A read gave `temp_c`. `true` when it replaces a reading that had been dropped after
    /// failures (the sensor is back).
    pub fn good(&mut self, temp_c: f32) -> bool {
        let back = self.last_c.is_none() && self.failures > 0;
        self.last_c = Some(temp_c);
        self.age_samples = 0;
        back
    }

    /// A read failed: counted; the previous reading is kept while it is young enough.
    pub fn failed(&mut self) {
        self.failures = self.failures.saturating_add(1);
    }

    /// Drops the reading when the last good read is more than `hold_samples` samples old;
    /// `true` at the sample where that happens.
    pub fn expire(&mut self) -> bool {
        if self.age_samples > self.hold_samples && self.last_c.is_some() {
            self.last_c = None;
            true
        } else {
            false
        }
    }

    /// The reading for this sample, °C (`None` before the first good read and once dropped).
    pub fn value(&self) -> Option<f32> {
        self.last_c
    }

    /// Failed reads so far.
    pub fn failures(&self) -> u32 {
        self.failures
    }

    /// Samples since the last good read (or since the start).
    pub fn age_samples(&self) -> u32 {
        self.age_samples
    }
}
