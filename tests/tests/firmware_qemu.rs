//! Hardware-in-the-loop test of the firmware under QEMU (`-machine mps2-an386`, Cortex-M4F).
//!
//! A **recorded vehicle capture**: `host-sim simulate --model <ecore2000 preset with the
//! vehicle profile> --format ecore-bin` (E-Core 2000 frames: a still alignment period, then
//! drives with road curvature and turns, and stops), damaged in known ways (noise bytes, a cut
//! frame, a checksum error, a random burst), with in-band still-flag commands (still, moving,
//! back to the stillness test) at known places, followed by the end marker, sent to the
//! firmware's UART0. The firmware runs the drift filter **loaded from the drift image it
//! embeds** (`fog-firmware/identifier/default.fogi`, format 5). The host decodes the same bytes with the same
//! fog-core decoder and runs the same per-sample code (`fog-firmware/src/pipeline.rs`,
//! compiled here) with the same image. Every per-sample record must match bit for bit, and
//! the final statistics record must match the host's byte counters exactly. The record
//! format is parsed here independently, from `fog-firmware/README.md`.
//!
//! A second test builds the firmware with a corrupted image (`FOG_IDENTIFIER`) and checks
//! that it stops at setup with a non-zero exit and the error on defmt.

use std::time::{Duration, Instant};

use fog_core::frame::ecore;
use fog_system_tests::{default_firmware, firmware, host_sim, qemu_system_arm, FirmwareBuild};

mod hil;
use hil::{default_image, defmt_payloads, host_reference, parse_records, pipeline, run_qemu, Rng};

/// Length of the vehicle capture, s (100 Hz).
const DURATION_S: u32 = 70;

/// The ecore2000 gyro file with the vehicle profile: 20 s still alignment, drives of 15-30 s
/// with a turn every 8 s on average, stops of 8-15 s.
fn vehicle_model() -> String {
    let preset = std::fs::read_to_string(
        fog_system_tests::firmware_dir().join("../host-sim/gyros/ecore2000.toml"),
    )
    .expect("host-sim/gyros/ecore2000.toml");
    let preset = preset.replacen("[motion]\n", "[motion]\nprofile = \"vehicle\"\n", 1);
    assert!(preset.contains("profile = \"vehicle\""), "[motion] section");
    format!(
        "{preset}\n[motion.vehicle]\nalign_s = 20.0\nstop_min_s = 8.0\nstop_max_s = 15.0\n\
         drive_min_s = 15.0\ndrive_max_s = 30.0\nturn_interval_s = 8.0\n"
    )
}

/// The recorded capture: E-Core frames of a simulated vehicle record (8 bytes per sample),
/// and its true rate per sample (from the CSV of the same seed).
fn vehicle_capture(dir: &std::path::Path) -> (Vec<u8>, Vec<f64>) {
    let model = dir.join("vehicle.toml");
    std::fs::write(&model, vehicle_model()).expect("model written");
    let mut truth = Vec::new();
    let mut frames = Vec::new();
    for (format, file) in [("ecore-bin", "vehicle.bin"), ("csv", "vehicle.csv")] {
        let out = dir.join(file);
        let _ = std::fs::remove_file(&out);
        let st = host_sim()
            .args(["simulate", "--gyro"])
            .arg(&model)
            .args(["--duration-s", &DURATION_S.to_string(), "--seed", "4242"])
            .args(["--format", format, "--output"])
            .arg(&out)
            .status()
            .expect("host-sim runs");
        assert!(st.success(), "host-sim simulate --format {format}");
        if format == "csv" {
            let text = std::fs::read_to_string(&out).expect("csv");
            let mut lines = text.lines();
            let header: Vec<&str> = lines.next().expect("header").split(',').collect();
            let col = header
                .iter()
                .position(|h| *h == "true_rate_dps")
                .expect("true_rate_dps column");
            truth = lines
                .map(|l| {
                    l.split(',')
                        .nth(col)
                        .expect("field")
                        .parse()
                        .expect("number")
                })
                .collect();
        } else {
            frames = std::fs::read(&out).expect("capture");
        }
    }
    assert_eq!(frames.len() % 8, 0, "whole frames");
    assert_eq!(frames.len() / 8, truth.len(), "one frame per CSV row");
    (frames, truth)
}

/// Frame `k` of the capture.
fn frame(capture: &[u8], k: usize) -> [u8; 8] {
    capture[8 * k..8 * k + 8].try_into().expect("8 bytes")
}

/// Frame indices where the in-band still-flag commands go (before that frame).
const CMD_STILL_AT: usize = 3000;
const CMD_MOVING_AT: usize = 4000;
const CMD_AUTO_AT: usize = 5000;

/// The byte stream sent to the UART: the capture's frames with known damage and the still
/// commands, then the end marker.
fn wire_stream(capture: &[u8], seed: u64) -> Vec<u8> {
    let mut rng = Rng(seed);
    // Starts mid-frame: the tail of a frame the firmware never saw the start of.
    let mut s = Vec::from(&ecore::encode(123, [0; 4])[3..]);
    for k in 0..capture.len() / 8 {
        let mut f = frame(capture, k);
        match k {
            // Line noise between frames (no sync flag).
            100 | 2500 => s.extend([0x00, 0x13, 0x7F, 0x42, 0x01]),
            // A frame cut short by the next one's sync byte.
            700 => {
                s.extend(&f[..5]);
                continue;
            }
            // A corrupted bit: the checksum catches it.
            1300 => f[3] ^= 0x01,
            // A random burst of any bytes (may contain sync bytes).
            2000 => s.extend((0..20).map(|_| rng.next_u64() as u8)),
            CMD_STILL_AT => s.extend(pipeline::STILL_MARKER),
            CMD_MOVING_AT => s.extend(pipeline::MOVING_MARKER),
            CMD_AUTO_AT => s.extend(pipeline::AUTO_MARKER),
            _ => {}
        }
        s.extend(f);
    }
    s.extend(pipeline::END_MARKER);
    s
}

#[test]
fn firmware_under_qemu_matches_host_bit_for_bit() {
    let t0 = Instant::now();
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let fw = default_firmware("hil-vehicle");
    let built = t0.elapsed();

    let (capture, truth) = vehicle_capture(fw.dir());
    let samples = truth.len();
    assert_eq!(samples, DURATION_S as usize * 100);
    let stream = wire_stream(&capture, 0xBADB_17E5);
    let expected = host_reference(&stream);

    let log = fw.file("hil-defmt.bin");
    let t_run = Instant::now();
    let (out, code) = run_qemu(&qemu, &fw.elf, stream.clone(), &log);
    let ran = t_run.elapsed();
    let (records, stats) = parse_records(&out);

    assert_eq!(code, Some(0), "QEMU's exit code (semihosting)");
    let stats = stats.expect("final statistics record");
    expected.assert_records_match(&records);

    // A second reference, fog-core called directly (not through pipeline.rs): the drift
    // filter from the parsed image, and the paper's denoiser on the first block.
    matches_drift_filter(&records, &expected, &default_image());
    let mut block: Vec<f32> = records[..pipeline::BLOCK]
        .iter()
        .map(|r| f32::from_bits(r.bits[0]))
        .collect();
    let mut scratch = vec![0.0f32; pipeline::BLOCK];
    fog_core::denoise::denoise_in_place(
        &mut block,
        &mut scratch,
        &fog_core::denoise::DenoiseConfig::PAPER,
    )
    .expect("denoised");
    for (i, d) in block.iter().enumerate() {
        let k = pipeline::DENOISED_DELAY_SAMPLES + i;
        assert_eq!(
            records[k].bits[3],
            d.to_bits(),
            "record {k}: denoised field"
        );
    }

    let want = expected.stats.counters();
    assert_eq!(
        stats.counters, want,
        "byte counters (ByteStats field order)"
    );
    assert_eq!(stats.samples as usize, expected.samples.len());
    assert_eq!(stats.rejected, 0);
    assert_eq!(stats.serial_errors, 0);
    assert_eq!(stats.still_commands, 3, "still, moving, auto");
    assert_eq!(stats.still_commands, expected.still_commands);
    // QEMU's UART waits for the guest (flow control): the receive queue never overflows.
    assert_eq!(
        (stats.rx_overrun, stats.rx_queue_full),
        (0, 0),
        "bytes lost"
    );
    assert!(expected.stats.is_consistent());

    // The damage was seen as intended.
    let s = &expected.stats;
    assert_eq!(s.bytes_total, stream.len() as u64);
    assert_eq!(s.skipped.checksum, 8, "one checksum error");
    assert!(s.skipped.cut_short >= 5 + 7, "cut frame and end marker");
    assert!(
        s.skipped.no_sync >= 5 + 10,
        "noise bytes and the mid-frame start"
    );
    assert!(s.frames_good >= samples as u64 - 3);

    // What the records say: the still flag, the external flag's span, filter updates, the
    // denoised field one block late, the drift within the image's bound.
    let image = fog_core::image::Image::parse(&default_image()).expect("default.fogi parses");
    let window = image.filter().expect("filter").window_samples() as usize;
    let status = |k: usize| expected.samples[k].2;
    let external: Vec<usize> = (0..expected.samples.len())
        .filter(|&k| status(k) & pipeline::STATUS_EXTERNAL != 0)
        .collect();
    // Frames lost to the damage (3 before the commands) shift the indices by at most 3.
    let (first, last) = (external[0], *external.last().expect("external span"));
    assert!(
        (CMD_STILL_AT - 3..=CMD_STILL_AT).contains(&first)
            && (CMD_AUTO_AT - 4..CMD_AUTO_AT).contains(&last)
            && external.len() == last - first + 1,
        "external flag on frames {first}..={last}"
    );
    // Bit 0 is the sample's external flag where it has one (the flag also decides the
    // stillness of the filter's window it falls in).
    for k in first..=last {
        let still = status(k) & pipeline::STATUS_STILL != 0;
        assert_eq!(
            still,
            k < first + (CMD_MOVING_AT - CMD_STILL_AT),
            "frame {k}"
        );
    }
    let detector_still = (0..expected.samples.len())
        .filter(|&k| {
            status(k) & (pipeline::STATUS_STILL | pipeline::STATUS_EXTERNAL)
                == pipeline::STATUS_STILL
        })
        .count();
    let level_updates = (0..expected.samples.len())
        .filter(|&k| status(k) & pipeline::STATUS_LEVEL_UPDATE != 0)
        .count();
    assert!(
        detector_still > 500,
        "the detector found the stops: {detector_still}"
    );
    assert!(
        level_updates > 5,
        "filter updates (still windows): {level_updates}"
    );
    let truly_moving_called_still = (0..expected.samples.len())
        .filter(|&k| {
            status(k) & (pipeline::STATUS_STILL | pipeline::STATUS_EXTERNAL) == pipeline::STATUS_STILL
                && // Frame k of the output is frame k..=k+3 of the capture (3 damaged before).
                truth.get(k..k + 4).is_some_and(|t| t.iter().all(|r| r.abs() > 0.5))
        })
        .count();
    eprintln!(
        "HIL vehicle: {detector_still} samples still by the stillness test ({truly_moving_called_still} of \
         them turning faster than 0.5 deg/s: the one-window lag at a drive's start), {level_updates} filter updates \
         (still windows of {window} samples)"
    );
    // The image's model's drift bound.
    let bound_dps = image.model.drift_bound_dps;
    for (k, (_, o, _)) in expected.samples.iter().enumerate() {
        assert!(o.drift_dps.abs() <= bound_dps, "drift bound at {k}");
        assert_eq!(
            o.denoised_dps.is_nan(),
            k < pipeline::DENOISED_DELAY_SAMPLES,
            "denoised field at {k}"
        );
    }

    eprintln!(
        "HIL: {} bytes in (vehicle capture, loaded identifier), {} records bit-identical, counters identical; frames good {} bad {}; \
         stack high-water {} bytes; build {:.1} s, QEMU run {:.2} s, total {:.1} s",
        stream.len(),
        records.len(),
        s.frames_good,
        s.frames_bad,
        stats.stack_bytes,
        built.as_secs_f64(),
        ran.as_secs_f64(),
        t0.elapsed().as_secs_f64()
    );
}

/// A second reference, fog-core called directly (not through pipeline.rs): the drift
/// filter from the parsed `image` gives each record's drift and compensated rate (same bits)
/// and still flag. Returns the still records.
fn matches_drift_filter(
    records: &[hil::SampleRecord],
    expected: &hil::Expected,
    image: &[u8],
) -> usize {
    let image = fog_core::image::Image::parse(image).expect("image");
    let mut filter = image.filter().expect("drift filter");
    let mut still = 0;
    for (k, r) in records.iter().enumerate() {
        let rate_dps = f32::from_bits(r.bits[0]);
        let m = filter
            .push(rate_dps, f32::NAN, expected.external[k])
            .expect("finite rate");
        assert_eq!(
            [r.bits[1], r.bits[2]],
            [m.drift_dps.to_bits(), m.compensated_dps.to_bits()],
            "record {k}: drift, compensated vs DriftFilter"
        );
        assert_eq!(
            r.status & pipeline::STATUS_STILL != 0,
            m.still,
            "record {k}: still"
        );
        still += usize::from(m.still);
    }
    still
}

/// Builds the firmware with `image` embedded (`FOG_IDENTIFIER`, built in `target/badimg`),
/// runs it with only the end marker on its UART; returns (UART output, defmt bytes, exit
/// code).
fn run_with_image(
    qemu: &std::path::Path,
    name: &str,
    image: &[u8],
) -> (Vec<u8>, Vec<u8>, Option<i32>) {
    let fw = firmware(
        &FirmwareBuild {
            target_subdir: "target/badimg",
            input_files: &[("FOG_IDENTIFIER", image)],
            ..FirmwareBuild::DEFAULT
        },
        &format!("badimg-{name}"),
    );
    let log = fw.file("defmt.bin");
    let (out, code) = run_qemu(qemu, &fw.elf, pipeline::END_MARKER.to_vec(), &log);
    (out, std::fs::read(&log).expect("defmt log"), code)
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

#[test]
fn a_corrupt_or_wrong_rate_image_stops_the_firmware_at_setup() {
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let good = default_image();
    // One bit flipped in the middle: the CRC-32 catches it.
    let mut corrupt = good.clone();
    corrupt[good.len() / 2] ^= 0x10;
    // A valid image (checksum and all) for 5 kHz: the firmware runs 10 Hz to 2 kHz.
    let mut image = fog_core::image::Image::parse(&good).expect("the default image parses");
    image.model.sample_rate_hz = 5000.0;
    let mut wrong_rate = vec![0u8; fog_core::image::IMAGE_LEN];
    let n = image.to_bytes(&mut wrong_rate).expect("image written");
    wrong_rate.truncate(n);
    assert!(fog_core::image::Image::parse(&wrong_rate).is_ok());
    // A format-3 header (the retired estimators' image): refused by name.
    let mut retired = good.clone();
    retired[4..6].copy_from_slice(&3u16.to_le_bytes());
    assert_eq!(
        fog_core::image::Image::parse(&retired),
        Err(fog_core::image::ImageError::RetiredFormat(3))
    );

    for (name, bytes, reason) in [
        ("corrupt", corrupt, &b"checksum mismatch"[..]),
        ("wrong-rate", wrong_rate, &b"sample rate mismatch"[..]),
        ("truncated", good[..100].to_vec(), &b"truncated"[..]),
        ("retired", retired, &b"retired format"[..]),
    ] {
        let (out, log, code) = run_with_image(&qemu, name, &bytes);
        assert!(
            matches!(code, Some(c) if c != 0),
            "{name}: non-zero exit expected, got {code:?}"
        );
        assert!(
            out.is_empty(),
            "{name}: no record written ({} bytes)",
            out.len()
        );
        assert!(
            contains(&defmt_payloads(&log), reason),
            "{name}: reason in the defmt log: {}",
            log.escape_ascii()
        );
        eprintln!(
            "{name} image: exit {code:?}, reason {:?} on defmt",
            std::str::from_utf8(reason)
        );
    }
}

/// The read-back that proves an ELF carries its image can fail: the default build checked
/// against the default image with one byte changed, and against its first 100 bytes.
#[test]
fn an_elf_that_does_not_carry_the_image_asked_for_is_refused() {
    let fw = default_firmware("carries-control");
    let good = default_image();
    fw.assert_carries("FOG_IDENTIFIER", &good);
    let mut changed = good.clone();
    changed[good.len() / 2] ^= 0x01;
    for (what, image) in [
        ("one byte changed", changed),
        ("truncated", good[..100].to_vec()),
    ] {
        let refused = std::panic::catch_unwind(|| fw.assert_carries("FOG_IDENTIFIER", &image));
        assert!(refused.is_err(), "{what}: accepted as the embedded image");
    }
}

#[test]
fn the_default_image_parses_and_says_how_it_was_made() {
    let bytes = default_image();
    let image = fog_core::image::Image::parse(&bytes).expect("default.fogi parses");
    image
        .check_rate(pipeline::SAMPLE_RATE_HZ)
        .expect("default.fogi is for the firmware's rate");
    assert_eq!(bytes.len(), fog_core::image::IMAGE_LEN, "format 5");
    assert_eq!(image.full_scale_dps, pipeline::FULL_SCALE_DPS);
    assert!(image.filter().is_ok(), "builds its drift filter");
    // A model fitted on calibration runs, not the sensor specification's alone.
    assert!(
        image.trained_runs >= 12,
        "fitted on >= 12 calibration runs: {}",
        image.trained_runs
    );
    assert_ne!(
        image.model,
        fog_core::gyro_model::GyroModel::for_sensor(&fog_core::sensor::SensorConfig::ECORE_2000),
        "a fitted model, not the specification's"
    );
    let readme =
        std::fs::read_to_string(fog_system_tests::firmware_dir().join("identifier/README.md"))
            .expect("identifier/README.md");
    let script = fog_system_tests::firmware_dir().join("../scripts/train-default-identifier.sh");
    assert!(script.is_file(), "the script that makes it");
    assert!(readme.contains("scripts/train-default-identifier.sh"));
    // The README names the bytes it describes.
    let crc = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().expect("4 bytes"));
    assert!(
        readme.contains(&format!("{crc:#010x}")),
        "identifier/README.md names the image's CRC-32 {crc:#010x}"
    );
}

/// The same damaged vehicle capture through a firmware built with another model and
/// configuration than the default image's: all three Gauss-Markov terms present, a
/// temperature link and a temperature-rate link in the prior, a warm-up of nonzero mean, a
/// 1-s window and 4 learning windows. Every record bit-identical with the host's pipeline
/// given the same image and with `DriftFilter` from the parsed image; prints the stack
/// high-water mark with that image.
#[test]
fn another_model_runs_bit_for_bit() {
    use fog_core::gyro_model::{MarkovTerm, Spread};
    use fog_core::image::Image;
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let dph = 1.0 / 3600.0;
    let mut image = Image::parse(&default_image()).expect("default image");
    image.model.markov = [
        MarkovTerm {
            sigma_dps: 1.0 * dph,
            tau_s: 30.0,
        },
        MarkovTerm {
            sigma_dps: 2.0 * dph,
            tau_s: 300.0,
        },
        MarkovTerm {
            sigma_dps: 1.5 * dph,
            tau_s: 3000.0,
        },
    ];
    image.model.warmup_dps.mean = 3.0 * dph;
    image.model.temp_dps_per_c = Spread {
        mean: 0.2 * dph,
        sigma: 1.0 * dph,
    };
    image.model.temp_rate_dps_per_c_per_s = Spread {
        mean: 0.0,
        sigma: 10.0 * dph,
    };
    image.config.window_s = 1.0;
    image.config.learn_windows = 4;
    let (still, verified) = image_runs_bit_for_bit(&qemu, "other-model", &image);
    assert!(still > 500, "still samples: {still}");
    assert!(verified > 0, "a verified sample");
}

/// The firmware runs at its image's rate: the default image made for 20 Hz and for 2 kHz
/// (the sensor file's range; its model's steps, warm-up clock and windows follow the rate),
/// fed the vehicle capture's frames as that rate's samples, bit-identical with the host.
/// The window is set to 200 samples at each rate (10 s at 20 Hz, 0.1 s at 2 kHz; the
/// default's 2 s at 100 Hz), so that the capture's stops span whole windows there too.
#[test]
fn an_image_at_another_rate_runs_bit_for_bit() {
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    for rate_hz in [20.0f32, 2000.0] {
        let mut image = fog_core::image::Image::parse(&default_image()).expect("default image");
        image.model.sample_rate_hz = rate_hz;
        image.config.window_s = 200.0 / rate_hz;
        let name = format!("rate{rate_hz}");
        let (still, verified) = image_runs_bit_for_bit(&qemu, &name, &image);
        assert!(verified > 0, "{name}: a verified sample");
        eprintln!("HIL {name}: {still} still samples, {verified} verified");
    }
}

/// Builds the firmware with `image`, feeds it the damaged vehicle capture under QEMU and
/// checks every record bit for bit, its status and the counters against the host's pipeline
/// with the same image, and the records against `DriftFilter`. Returns the samples still and
/// the samples verified (status bit 5 clear: a window found still since power-on).
fn image_runs_bit_for_bit(
    qemu: &std::path::Path,
    name: &str,
    image: &fog_core::image::Image,
) -> (usize, usize) {
    let mut bytes = vec![0u8; fog_core::image::IMAGE_LEN];
    let n = image.to_bytes(&mut bytes).expect("image written");
    bytes.truncate(n);
    let fw = firmware(
        &FirmwareBuild {
            target_subdir: "target/otherimg",
            input_files: &[("FOG_IDENTIFIER", &bytes)],
            ..FirmwareBuild::DEFAULT
        },
        &format!("hil-{name}"),
    );
    let (capture, _) = vehicle_capture(fw.dir());
    let stream = wire_stream(&capture, 0xBADB_17E5);
    let expected = hil::host_reference_with(&stream, &bytes);
    let log = fw.file("defmt.bin");
    let (out, code) = run_qemu(qemu, &fw.elf, stream, &log);
    let (records, stats) = parse_records(&out);
    assert_eq!(code, Some(0), "{name}: QEMU's exit code (semihosting)");
    let stats = stats.expect("final statistics record");
    assert_eq!(
        records.len(),
        expected.samples.len(),
        "{name}: one record per good frame"
    );
    assert_eq!(
        fog_core::image::Image::parse(&bytes).as_ref(),
        Ok(image),
        "{name}: the image as written"
    );
    let mut verified = 0;
    for (k, (r, (_, _, status))) in records.iter().zip(&expected.samples).enumerate() {
        assert_eq!(r.index as usize, k);
        assert_eq!(
            r.bits,
            expected.bits(k),
            "{name}: record {k} vs the host's pipeline"
        );
        assert_eq!(r.status, *status, "{name}: record {k}: status");
        verified += usize::from(r.status & pipeline::STATUS_UNVERIFIED == 0);
    }
    let still = matches_drift_filter(&records, &expected, &bytes);
    assert_eq!(stats.counters, expected.stats.counters());
    eprintln!(
        "HIL {name} image: {} records bit-identical, {still} still; stack high-water {} bytes",
        records.len(),
        stats.stack_bytes
    );
    (still, verified)
}

/// USART2 control register 1 of the STM32F4 (RM0090: USART2 at 0x4000_4400, CR1 at 0x0C).
const USART2_CR1: u32 = 0x4000_440C;
/// CR1: UE (bit 13), RE (bit 2), RXNEIE (bit 5).
const CR1_READY: u32 = (1 << 13) | (1 << 2) | (1 << 5);
/// Exception number of USART2's interrupt (16 + IRQ 38), as QEMU's `-d int` log names it.
const USART2_EXCEPTION: &str = "element 54 of";

/// The STM32 build on QEMU `-machine netduinoplus2` (STM32F405): `fog-firmware` with
/// feature `qemu-netduinoplus2` (the STM32F407 build minus the clock-tree set-up and the I2C1
/// probe, which QEMU 7.2 does not model; `src/board/stm32f4.rs`), the damaged vehicle capture
/// on USART2 (QEMU's second serial port), records back on it.
///
/// QEMU's STM32 USART drops what arrives before the firmware sets UE and RE, so the test
/// sends nothing until USART2's CR1, read over QMP (`xp`), shows UE, RE and RXNEIE. The board
/// does not exit (it sleeps after the statistics record), so the run ends when that record
/// is complete. Every record bit-identical with the host's, counters identical, no byte lost;
/// the receive interrupt path is the only one (the main loop reads the queue that USART2's
/// interrupt fills), and QEMU's interrupt log (`-d int`) counts its entries.
#[test]
fn stm32_build_under_netduinoplus2_matches_host_bit_for_bit() {
    let t0 = Instant::now();
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let fw = firmware(&FirmwareBuild::NETDUINO, "hil-netduino");
    let built = t0.elapsed();
    let (capture, _) = vehicle_capture(fw.dir());
    let stream = wire_stream(&capture, 0xBADB_17E5);
    let expected = host_reference(&stream);

    let log = fw.file("qemu.log");
    let int_log = fw.file("int.log");
    let int_log_arg = int_log.display().to_string();
    let args = [
        "-machine",
        "netduinoplus2",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "null",
        "-serial",
        "stdio",
        "-d",
        "int",
        "-D",
        &int_log_arg,
    ];
    let polls = std::sync::Arc::new(std::sync::atomic::AtomicU32::new(0));
    let polls_in = std::sync::Arc::clone(&polls);
    let t_run = Instant::now();
    let run = hil::run_qemu_steps(
        &qemu,
        &args,
        &fw.elf,
        vec![hil::Step {
            wait_output: 0,
            bytes: stream.clone(),
        }],
        move |qmp, _| loop {
            polls_in.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            if qmp.read_word(USART2_CR1) & CR1_READY == CR1_READY {
                break;
            }
            assert!(
                t_run.elapsed() < hil::DEADLINE,
                "USART2 not enabled within {:?} (CR1 {:#x})",
                hil::DEADLINE,
                qmp.read_word(USART2_CR1)
            );
            std::thread::sleep(Duration::from_millis(5));
        },
        Some(hil::stats_record_complete),
        &log,
    );
    let ran = t_run.elapsed();
    let (records, stats) = parse_records(&run.out);
    let stats = stats.expect("final statistics record");
    expected.assert_records_match(&records);
    assert_eq!(stats.counters, expected.stats.counters(), "byte counters");
    assert_eq!(stats.samples as usize, expected.samples.len());
    assert_eq!((stats.rejected, stats.serial_errors), (0, 0));
    assert_eq!(stats.still_commands, 3, "still, moving, auto");
    assert_eq!(
        (stats.rx_overrun, stats.rx_queue_full),
        (0, 0),
        "bytes lost"
    );
    assert_eq!(stats.counters[0], stream.len() as u64, "every byte arrived");
    let interrupts = std::fs::read_to_string(&int_log)
        .expect("QEMU's interrupt log")
        .lines()
        .filter(|l| l.contains(USART2_EXCEPTION))
        .count();
    assert!(interrupts > 0, "USART2's interrupt never taken");
    eprintln!(
        "HIL netduinoplus2: {} bytes in, {} records bit-identical, counters identical; USART2 interrupt entries {interrupts} \
         (for {} bytes); CR1 polled {} times before sending; stack high-water {} bytes; build {:.1} s, QEMU run {:.2} s",
        stream.len(),
        records.len(),
        stream.len(),
        polls.load(std::sync::atomic::Ordering::SeqCst),
        stats.stack_bytes,
        built.as_secs_f64(),
        ran.as_secs_f64()
    );
}
