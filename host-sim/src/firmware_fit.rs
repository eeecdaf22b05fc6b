//! Whether an identifier image fits the firmware (`fog-firmware`), and what the firmware
//! will do with it, in ONE verdict: `fits`, or `does not fit:` and every reason (its set-up
//! refuses the image, the UART cannot carry its rate, the decoder's full scale is not the
//! unit's, the core cannot keep up). `host-sim image` prints it (and exits non-zero on an
//! image that does not fit), and every command that writes an image (`identify --preset
//! motion --save-identifier`, `demo`) prints it and refuses to write an image that does not
//! fit unless forced (`identify --force`; [`crate::motion::write_image`]). The JSON carries
//! the same verdict and reasons ([`FirmwareFit`]).
//!
//! # Sources
//! - **The firmware's own set-up code**: `fog-firmware/src/pipeline.rs` is compiled into
//!   host-sim (as the hardware-in-the-loop tests do; it depends on `fog-core` and `core`
//!   only), and an image is accepted exactly when its `new_stage` accepts the image's bytes
//!   (parse, rate within [`MIN_RATE_HZ`] .. [`MAX_RATE_HZ`], estimator and denoiser built).
//!   The decoder's full scale [`DECODER_FULL_SCALE_DPS`] and the record length come from
//!   the same file.
//! - **Measured figures** (per-sample instructions and estimated cycles, flash, RAM): the
//!   last run of `bash scripts/fw-budget.sh`, copied here from `docs/STATUS.md` (a unit test
//!   requires them to be the figures `docs/STATUS.md` states).
//! - **The UART's baud rate**: both boards' `const BAUD` (`fog-firmware/src/board/`; a unit
//!   test reads them).
//!
//! # Assumptions
//! - A sample costs what it cost in the budget run at any rate, for any image: that run
//!   used the committed default image (100 Hz, 2-s filter window). The work done once per
//!   window (the filter's predict, test and update) is in the measured mean spread over the
//!   window's samples; at a lower rate it is spread over fewer, so there the mean is
//!   understated; above 100 Hz it is overstated. The worst sample does not depend on the
//!   rate. `FOG_IDENTIFIER=F.fogi bash scripts/fw-budget.sh` measures an image itself.
//! - Cycles are the budget's estimate at [`CLOCK_HZ`] (instruction trace costed with the
//!   Cortex-M4 timings, 5 flash wait states behind the ART accelerator:
//!   `fog-firmware/README.md`, "Cycles"), not a measurement on a board.
//! - RAM does not depend on the image: every buffer has a fixed size (const generics; the
//!   filter's size is fixed). The stack high-water marks were
//!   measured with the default image.
//! - The UART runs 8N1 (10 bit times per byte) at [`UART_BAUD`] in both directions, one
//!   E-Core frame ([`FRAME_LEN`] bytes) in and one record ([`RECORD_LEN`] bytes) out per
//!   sample; the logs do not use it (defmt goes to semihosting or RTT).

use anyhow::{bail, Result};
use fog_core::image::Image;
use serde::Serialize;
use std::path::Path;

/// `fog-firmware/src/pipeline.rs`, the firmware's per-sample code, compiled on the host.
#[allow(dead_code, clippy::all)]
#[path = "../../fog-firmware/src/pipeline.rs"]
mod pipeline;

/// Slowest image rate the firmware runs, Hz (`pipeline::MIN_RATE_HZ`).
pub const MIN_RATE_HZ: f32 = pipeline::MIN_RATE_HZ;
/// Fastest image rate the firmware runs, Hz (`pipeline::MAX_RATE_HZ`).
pub const MAX_RATE_HZ: f32 = pipeline::MAX_RATE_HZ;
/// Full scale of the firmware's only decoder, E-Core 2000 frames, deg/s
/// (`pipeline::FULL_SCALE_DPS`: 32768 counts = this rate).
pub const DECODER_FULL_SCALE_DPS: f32 = pipeline::FULL_SCALE_DPS;
/// Bytes of one E-Core 2000 frame (one sample in).
pub const FRAME_LEN: usize = fog_core::frame::ecore::FRAME_LEN;
/// Bytes of one per-sample record (one sample out; `pipeline::SAMPLE_RECORD_LEN`).
pub const RECORD_LEN: usize = pipeline::SAMPLE_RECORD_LEN;

/// Core clock the cycle figures are for, Hz (the STM32F407's 168 MHz).
pub const CLOCK_HZ: f64 = 168e6;
/// Whole pipeline (decode + stage + record), instructions per sample, mean (measured,
/// `bash scripts/fw-budget.sh`, default image).
pub const INSTRUCTIONS_MEAN: f64 = 970.7;
/// The same, the worst sample.
pub const INSTRUCTIONS_WORST: f64 = 2_645.0;
/// Whole pipeline, estimated cycles per sample at [`CLOCK_HZ`], mean (the budget's
/// estimate from the instruction trace, default image).
pub const CYCLES_MEAN: f64 = 1_909.4;
/// The same, the worst sample.
pub const CYCLES_WORST: f64 = 5_092.0;
/// RAM including the stack's high-water mark, `mps2-an386` build, bytes.
pub const RAM_MPS2_BYTES: u32 = 10_840;
/// RAM including the stack (measured on its QEMU variant), STM32F407 build, bytes.
pub const RAM_STM32_BYTES: u32 = 11_008;
/// The RAM budget, bytes (16 KiB).
pub const RAM_BUDGET_BYTES: u32 = 16_384;
/// Flash, `mps2-an386` build (the image included), bytes.
pub const FLASH_BYTES: u32 = 41_392;
/// The command that measured the figures above.
pub const MEASURED_BY: &str = "bash scripts/fw-budget.sh";
/// The gyro UART's baud rate on both boards (`const BAUD`, `fog-firmware/src/board/`).
pub const UART_BAUD: f64 = 115_200.0;
/// Bit times per byte on the UART (8N1).
pub const UART_BITS_PER_BYTE: f64 = 10.0;

/// One reason an image does not fit: a few words for the verdict and the whole statement.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Misfit {
    /// For the verdict line (`UART 226 % (records out)`).
    pub short: String,
    /// What happens, in a sentence.
    pub detail: String,
}

/// What the firmware does with an image (units in the field names; shares are fractions).
#[derive(Debug, Clone, Serialize)]
pub struct FirmwareFit {
    /// The one verdict: the firmware runs the image as the unit needs (no [`Self::reasons`]).
    pub fits: bool,
    /// The verdict in words, as printed: `fits` or `does not fit: ` and every reason's short
    /// form ([`Misfit::short`]), comma-separated.
    pub verdict: String,
    /// Why it does not fit (empty when it fits): set-up refusal, decoder full scale, core
    /// load, UART.
    pub reasons: Vec<Misfit>,
    /// The firmware's set-up (`pipeline::new_stage`) takes the image (it may still not fit).
    pub setup_accepts: bool,
    /// Why the set-up refuses it (the firmware stops there), if it does (also a reason).
    pub refusal: Option<String>,
    /// The rate the firmware runs at: the image's, Hz.
    pub sample_rate_hz: f32,
    /// The rates the firmware accepts, Hz.
    pub accepted_rate_hz: (f32, f32),
    /// What the firmware decodes (its only decoder).
    pub decoder: &'static str,
    /// The decoder's full scale, deg/s.
    pub decoder_full_scale_dps: f32,
    /// The image's (the unit's) full scale, deg/s.
    pub image_full_scale_dps: f32,
    /// What the per-sample figures were measured on, and by which command.
    pub measured_on: String,
    /// Instructions per sample (mean, worst), measured.
    pub instructions_per_sample: (f64, f64),
    /// Estimated cycles per sample (mean, worst) at `clock_hz`.
    pub cycles_per_sample: (f64, f64),
    /// Instructions per second at this rate (mean; every sample the worst).
    pub instructions_per_s: (f64, f64),
    /// Estimated cycles per second at this rate (mean; every sample the worst).
    pub cycles_per_s: (f64, f64),
    /// Share of the core (mean; every sample the worst = the worst sample's share of its
    /// period).
    pub core_share: (f64, f64),
    /// Core clock, Hz.
    pub clock_hz: f64,
    /// RAM incl. stack, bytes: `mps2-an386`, STM32F407 (the same for every image).
    pub ram_bytes: (u32, u32),
    /// The RAM budget, bytes.
    pub ram_budget_bytes: u32,
    /// Flash, bytes (`mps2-an386`).
    pub flash_bytes: u32,
    /// UART baud rate.
    pub uart_baud: f64,
    /// Share of the UART's line at this rate: frames in, records out.
    pub uart_share: (f64, f64),
}

impl FirmwareFit {
    /// `Err` naming `output` and the verdict when the image does not fit, unless `force`
    /// (nothing is to be written then).
    pub fn refuse(&self, output: &Path, force: bool) -> Result<()> {
        if !self.fits && !force {
            bail!(
                "{}: not written: the image does not fit the firmware: {} (write it anyway: --force)",
                output.display(),
                self.why()
            );
        }
        Ok(())
    }

    /// Every reason's short form, comma-separated (the verdict after `does not fit: `);
    /// empty when the image fits.
    pub fn why(&self) -> String {
        self.reasons
            .iter()
            .map(|r| r.short.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The statement, a few lines (each starting `firmware:`): the verdict first, then each
    /// reason, then the figures.
    pub fn text(&self) -> String {
        let (lo, hi) = self.accepted_rate_hz;
        let hz = self.sample_rate_hz;
        let mut s = if self.fits {
            format!(
                "firmware: {}: runs this image at its {hz} Hz (rates {lo} to {hi} Hz)\n",
                self.verdict
            )
        } else {
            format!("firmware: {}\n", self.verdict)
        };
        for r in &self.reasons {
            s += &format!("firmware:   - {}\n", r.detail);
        }
        s += &format!(
            "firmware: decodes {}, full scale {} deg/s; this image's unit: {} deg/s\n",
            self.decoder, self.decoder_full_scale_dps, self.image_full_scale_dps
        );
        let (im, iw) = self.instructions_per_sample;
        let (cm, cw) = self.cycles_per_sample;
        s += &format!(
            "firmware: load at {hz} Hz: {} instructions/s, estimated {} cycles/s = {:.2} % of a {} MHz core; worst sample {} cycles = {:.2} % of its {}-us period\n",
            grouped(self.instructions_per_s.0, 0),
            grouped(self.cycles_per_s.0, 0),
            100.0 * self.core_share.0,
            self.clock_hz / 1e6,
            grouped(cw, 0),
            100.0 * self.core_share.1,
            grouped(1e6 / f64::from(hz), 0),
        );
        s += &format!(
            "firmware: per sample (mean / worst) {} / {} instructions, estimated {} / {} cycles, measured on {}\n",
            grouped(im, 1),
            grouped(iw, 1),
            grouped(cm, 1),
            grouped(cw, 0),
            self.measured_on,
        );
        s += &format!(
            "firmware: RAM incl. stack {} B (mps2-an386), {} B (STM32F407) of {} B, the same for every image (fixed sizes); flash {} B\n",
            grouped(f64::from(self.ram_bytes.0), 0),
            grouped(f64::from(self.ram_bytes.1), 0),
            grouped(f64::from(self.ram_budget_bytes), 0),
            grouped(f64::from(self.flash_bytes), 0),
        );
        s += &format!(
            "firmware: UART {} baud at {hz} Hz: frames in {:.1} %, records out {:.1} % of the line\n",
            grouped(self.uart_baud, 0),
            100.0 * self.uart_share.0,
            100.0 * self.uart_share.1,
        );
        s
    }
}

/// What the firmware does with the image `bytes` (already parsed as `image`): accepted or
/// refused by its own set-up code, and the figures at the image's rate.
pub fn check(image: &Image, bytes: &[u8]) -> FirmwareFit {
    let refusal = match pipeline::new_stage(bytes) {
        Ok(_) => None,
        Err(e) => Some(setup_reason(&e)),
    };
    assess(image.model.sample_rate_hz, image.full_scale_dps, refusal)
}

/// [`check`] on an image not yet in bytes (a command about to write it).
pub fn check_image(image: &Image) -> Result<FirmwareFit> {
    let bytes = crate::motion::image_bytes(image)?;
    Ok(check(image, &bytes))
}

/// Why the firmware's set-up refuses an image, in words.
fn setup_reason(e: &pipeline::SetupError) -> String {
    use fog_core::image::ImageError;
    match e {
        pipeline::SetupError::Image(ImageError::RateMismatch { image_hz, .. }) => format!(
            "sample rate {image_hz} Hz outside the {MIN_RATE_HZ} to {MAX_RATE_HZ} Hz it runs"
        ),
        pipeline::SetupError::Image(e) => e.to_string(),
        pipeline::SetupError::Estimator(e) => {
            format!("estimator: {}", crate::motion::filter_error_words(e))
        }
        pipeline::SetupError::Denoiser(e) => format!("denoiser: {e}"),
    }
}

/// The verdict, its reasons and the figures for an image at `sample_rate_hz` from a unit of
/// `full_scale_dps`; `refusal`: the set-up's verdict (a reason too).
pub fn assess(sample_rate_hz: f32, full_scale_dps: f32, refusal: Option<String>) -> FirmwareFit {
    let hz = f64::from(sample_rate_hz);
    let mut reasons = Vec::new();
    let mut why = |short: String, detail: String| reasons.push(Misfit { short, detail });
    if let Some(r) = &refusal {
        why(
            format!("set-up refuses it ({r})"),
            format!("its set-up code refuses the image and the firmware stops there: {r}"),
        );
    }
    let line = |bytes: usize| bytes as f64 * UART_BITS_PER_BYTE * hz / UART_BAUD;
    let uart_share = (line(FRAME_LEN), line(RECORD_LEN));
    let most_hz = |bytes: usize| UART_BAUD / (bytes as f64 * UART_BITS_PER_BYTE);
    for (what, way, bytes, share, consequence) in [
        (
            "records",
            "out",
            RECORD_LEN,
            uart_share.1,
            "the firmware falls behind and loses frames",
        ),
        (
            "frames",
            "in",
            FRAME_LEN,
            uart_share.0,
            "the unit's frames cannot arrive at this rate",
        ),
    ] {
        if share <= 1.0 {
            continue;
        }
        why(
            format!("UART {:.0} % ({what} {way})", 100.0 * share),
            format!(
                "the {what} ({bytes} B per sample) need {:.0} % of the {} baud UART at {sample_rate_hz} Hz (at most {:.0} Hz fit): {consequence}",
                100.0 * share,
                grouped(UART_BAUD, 0),
                most_hz(bytes).floor()
            ),
        );
    }
    let fs = DECODER_FULL_SCALE_DPS;
    if full_scale_dps > fs * (1.0 + 1e-6) {
        why(
            format!("decoder full scale {fs} deg/s < unit's {full_scale_dps} deg/s"),
            format!(
                "the unit's full scale {full_scale_dps} deg/s is beyond the decoder's {fs} deg/s: the firmware decodes E-Core 2000 frames only (16-bit counts, 32768 = {fs} deg/s), so rates beyond {fs} deg/s cannot reach it, and a unit whose counts mean {full_scale_dps} deg/s is read at {:.3}x its rate",
                fs / full_scale_dps
            ),
        );
    } else if full_scale_dps < fs * (1.0 - 1e-6) {
        why(
            format!("decoder full scale {fs} deg/s > unit's {full_scale_dps} deg/s"),
            format!(
                "the unit's full scale {full_scale_dps} deg/s is not the decoder's {fs} deg/s: a unit whose E-Core counts mean {full_scale_dps} deg/s is read at {:.3}x its rate",
                fs / full_scale_dps
            ),
        );
    }
    let period_cycles = CLOCK_HZ / hz;
    if CYCLES_MEAN > period_cycles {
        why(
            format!(
                "core: mean sample {} cycles > {:.0}-cycle period",
                grouped(CYCLES_MEAN, 1),
                period_cycles
            ),
            format!(
                "the mean sample ({} cycles) exceeds the {:.0}-cycle sample period: the firmware falls behind and loses frames",
                grouped(CYCLES_MEAN, 1),
                period_cycles
            ),
        );
    } else if CYCLES_WORST > period_cycles {
        why(
            format!(
                "core: worst sample {} cycles > {:.0}-cycle period",
                grouped(CYCLES_WORST, 0),
                period_cycles
            ),
            format!(
                "the worst sample ({} cycles) exceeds the {:.0}-cycle sample period: the receive queue must absorb it (not measured)",
                grouped(CYCLES_WORST, 0),
                period_cycles
            ),
        );
    }
    let mut fit = FirmwareFit {
        fits: reasons.is_empty(),
        verdict: String::new(),
        reasons,
        setup_accepts: refusal.is_none(),
        refusal,
        sample_rate_hz,
        accepted_rate_hz: (MIN_RATE_HZ, MAX_RATE_HZ),
        decoder: "E-Core 2000 frames only",
        decoder_full_scale_dps: fs,
        image_full_scale_dps: full_scale_dps,
        measured_on: format!("the default image (100 Hz) by `{MEASURED_BY}`"),
        instructions_per_sample: (INSTRUCTIONS_MEAN, INSTRUCTIONS_WORST),
        cycles_per_sample: (CYCLES_MEAN, CYCLES_WORST),
        instructions_per_s: (INSTRUCTIONS_MEAN * hz, INSTRUCTIONS_WORST * hz),
        cycles_per_s: (CYCLES_MEAN * hz, CYCLES_WORST * hz),
        core_share: (CYCLES_MEAN * hz / CLOCK_HZ, CYCLES_WORST * hz / CLOCK_HZ),
        clock_hz: CLOCK_HZ,
        ram_bytes: (RAM_MPS2_BYTES, RAM_STM32_BYTES),
        ram_budget_bytes: RAM_BUDGET_BYTES,
        flash_bytes: FLASH_BYTES,
        uart_baud: UART_BAUD,
        uart_share,
    };
    fit.verdict = if fit.fits {
        "fits".to_string()
    } else {
        format!("does not fit: {}", fit.why())
    };
    fit
}

/// `x` with `decimals` decimals and thousands separated by commas (`1,327.8`).
pub fn grouped(x: f64, decimals: usize) -> String {
    let text = format!("{:.*}", decimals, x.abs());
    let (int, frac) = text.split_once('.').map_or((text.as_str(), ""), |p| p);
    let mut out = String::new();
    for (i, c) in int.chars().enumerate() {
        if i > 0 && (int.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    if !frac.is_empty() {
        out.push('.');
        out.push_str(frac);
    }
    if x < 0.0 && out.chars().any(|c| c.is_ascii_digit() && c != '0') {
        out.insert(0, '-');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn repo_file(rel: &str) -> String {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel);
        std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    }

    /// The measured figures are those `docs/STATUS.md` states (re-measured: change both).
    #[test]
    fn figures_are_the_status_pages() {
        let status = repo_file("docs/STATUS.md");
        for figure in [
            format!(
                "{} mean / {} max",
                grouped(INSTRUCTIONS_MEAN, 1),
                grouped(INSTRUCTIONS_WORST, 1)
            ),
            format!(
                "{} mean / {} worst",
                grouped(CYCLES_MEAN, 1),
                grouped(CYCLES_WORST, 0)
            ),
            format!(
                "`mps2-an386` {} B, {} B",
                grouped(f64::from(FLASH_BYTES), 0),
                grouped(f64::from(RAM_MPS2_BYTES), 0)
            ),
            format!("{} B (", grouped(f64::from(RAM_STM32_BYTES), 0)),
            format!("{} MHz", CLOCK_HZ / 1e6),
        ] {
            assert!(status.contains(&figure), "docs/STATUS.md lacks {figure:?}");
        }
    }

    /// Both boards' UART runs at [`UART_BAUD`].
    #[test]
    fn baud_is_the_boards() {
        for board in ["mps2_an386.rs", "stm32f4.rs"] {
            let text = repo_file(&format!("fog-firmware/src/board/{board}"));
            assert!(
                text.contains(&format!(
                    "const BAUD: u32 = {};",
                    grouped(UART_BAUD, 0).replace(',', "_")
                )),
                "{board}: BAUD is not {UART_BAUD}"
            );
        }
    }

    #[test]
    fn grouping() {
        assert_eq!(grouped(1327.8, 1), "1,327.8");
        assert_eq!(grouped(6312.0, 0), "6,312");
        assert_eq!(grouped(115_200.0, 0), "115,200");
        assert_eq!(grouped(999.96, 1), "1,000.0");
        assert_eq!(grouped(12.0, 0), "12");
        assert_eq!(grouped(-1234.5, 1), "-1,234.5");
    }

    /// The verdict follows the rate and the unit: 100 Hz at 60 deg/s fits, 1 kHz overfills
    /// the UART's records, a 100 deg/s unit is named; every reason in the verdict.
    #[test]
    fn the_verdict_follows_the_rate_and_unit() {
        let at100 = assess(100.0, 60.0, None);
        assert!(
            at100.fits && at100.reasons.is_empty(),
            "{:?}",
            at100.reasons
        );
        assert_eq!(at100.verdict, "fits");
        assert!((at100.core_share.0 - CYCLES_MEAN * 100.0 / 168e6).abs() < 1e-12);
        assert!((at100.uart_share.1 - 26.0 * 10.0 * 100.0 / 115_200.0).abs() < 1e-12);
        let at1k = assess(1000.0, 60.0, None);
        assert!(!at1k.fits);
        assert_eq!(at1k.reasons.len(), 1, "{:?}", at1k.reasons);
        assert!(at1k.reasons[0].detail.contains("at most 443 Hz fit"));
        assert_eq!(at1k.verdict, "does not fit: UART 226 % (records out)");
        let both = assess(1000.0, 100.0, None);
        assert_eq!(
            both.verdict,
            "does not fit: UART 226 % (records out), decoder full scale 60 deg/s < unit's 100 deg/s"
        );
        assert!(both.setup_accepts);
        let fs100 = assess(200.0, 100.0, None);
        assert_eq!(fs100.reasons.len(), 1, "{:?}", fs100.reasons);
        assert!(fs100.reasons[0]
            .detail
            .contains("beyond the decoder's 60 deg/s"));
        let refused = assess(5000.0, 60.0, Some("rate".into()));
        assert!(!refused.setup_accepts);
        assert!(refused
            .verdict
            .starts_with("does not fit: set-up refuses it (rate)"));
        // A core too slow for the rate (not reachable within the firmware's range at 168
        // MHz): named.
        let fast = assess(200_000.0, 60.0, None);
        assert!(fast
            .reasons
            .iter()
            .any(|w| w.detail.contains("the mean sample")));
        for f in [&at100, &at1k, &both, &fs100, &refused, &fast] {
            let text = f.text();
            assert!(
                text.starts_with(&format!("firmware: {}", f.verdict)),
                "{text}"
            );
            for r in &f.reasons {
                assert!(text.contains(&r.detail), "{text}");
            }
        }
    }
}
