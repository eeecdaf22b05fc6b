//! The firmware's temperature sensor under QEMU (`-machine mps2-an386`): the bit-banged SBCon
//! I2C master on the Shield1 port (`fog-firmware/src/board/sbcon_i2c.rs`) talks to what QEMU
//! models on that bus.
//!
//! - Nothing on the bus (the default): the address byte is not acknowledged, the firmware logs
//!   "no TMP117 ... (no acknowledge)" and runs without temperature.
//! - QEMU's TMP105 model at 0x48 (`-device tmp105,address=0x48`, which QEMU puts on the
//!   Shield1 port, the first free I2C bus): the TMP117 probe fails its id check (QEMU's model
//!   decodes only pointer bits 1:0, so register 0x0F reads as T_HIGH, 0x5000: "wrong device
//!   id"), then the TMP105 probe finds it (configuration 0x60, 12 bits, reads back).
//! - **Temperature in the loop** (`a_temperature_profile_over_qmp_reaches_the_estimator_bit_for_bit`):
//!   the TMP105's temperature is set over QMP while frames arrive; every record must be
//!   bit-identical with the host's run of the same code fed the same temperatures.
//!
//! The firmware must run to the end marker and exit 0 with its statistics record. The refresh
//! and hold policy (`fog-firmware/src/temperature_hold.rs`, compiled here) is tested on the
//! host. The defmt log is not decoded with the ELF's table (no decoder here): a `{=str}`
//! argument is written verbatim in defmt's frames, so the tests look for the probe's strings
//! in the frames' payloads.

use std::io::{Read, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use fog_system_tests::{default_firmware, host_sim, qemu_system_arm};

#[path = "../../fog-firmware/src/temperature_hold.rs"]
mod temperature_hold;
use temperature_hold::Hold;

mod hil;
use hil::{defmt_payloads, pipeline};

/// The firmware's end-of-input marker (`pipeline::END_MARKER`).
const END_MARKER: [u8; 8] = [0xC6, 0xCF, 0xC7, 0xAD, 0xC5, 0xCE, 0xC4, 0xA1];

// Statistics record: sync, kind 0x02, len, payload, checksum (the firmware's constants).
use pipeline::{STATS_PAYLOAD_LEN, STATS_RECORD_LEN};

/// Runs the firmware with only the end marker on its UART and `extra` QEMU arguments;
/// returns (UART output, defmt bytes, exit code).
fn run(name: &str, extra: &[&str]) -> Option<(Vec<u8>, Vec<u8>, Option<i32>)> {
    let qemu = qemu_system_arm()?;
    let fw = default_firmware(&format!("temperature-{name}"));
    // To a file, as in the HIL test (through a pipe, the first frames got lost).
    let log_path = fw.file("defmt.bin");
    let log_file = std::fs::File::create(&log_path).expect("defmt log file");
    let mut child = Command::new(qemu)
        .args(["-machine", "mps2-an386", "-nographic", "-monitor", "none"])
        .args(["-serial", "stdio"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(extra)
        .env_clear()
        .arg("-kernel")
        .arg(&fw.elf)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(log_file))
        .spawn()
        .expect("qemu-system-arm starts");
    let mut stdin = child.stdin.take().expect("piped stdin");
    let mut stdout = child.stdout.take().expect("piped stdout");
    stdin.write_all(&END_MARKER).expect("write the end marker");
    stdin.flush().expect("flush");
    let out = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = stdout.read_to_end(&mut v);
        v
    });
    let start = Instant::now();
    let code = loop {
        if let Some(status) = child.try_wait().expect("wait for QEMU") {
            break status.code();
        }
        if start.elapsed() > hil::DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            panic!("QEMU did not exit within {:?}", hil::DEADLINE);
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    drop(stdin);
    Some((
        out.join().expect("reader"),
        std::fs::read(&log_path).expect("defmt log"),
        code,
    ))
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

#[test]
fn no_sensor_on_the_bus_is_reported_and_the_firmware_runs() {
    let Some((out, log, code)) = run("none", &[]) else {
        return;
    };
    assert_eq!(code, Some(0), "QEMU's exit code (semihosting)");
    assert_eq!(out.len(), STATS_RECORD_LEN, "only the statistics record");
    assert_eq!(&out[..3], &[0xA5, 0x02, STATS_PAYLOAD_LEN as u8]);
    assert!(
        contains(&log, b"no acknowledge"),
        "the probe's NACK reason in the defmt log: {}",
        log.escape_ascii()
    );
}

#[test]
fn qemus_tmp105_fails_the_tmp117_id_check_and_is_found_as_a_tmp105() {
    let Some((out, log, code)) = run("tmp105", &["-device", "tmp105,address=0x48"]) else {
        return;
    };
    assert_eq!(code, Some(0), "QEMU's exit code (semihosting)");
    assert_eq!(out.len(), STATS_RECORD_LEN, "only the statistics record");
    let text = defmt_payloads(&log);
    assert!(
        !contains(&text, b"no acknowledge"),
        "the TMP105 acknowledged its address"
    );
    assert!(
        contains(&text, b"wrong device id"),
        "the TMP117 probe refused it: {}",
        text.escape_ascii()
    );
    assert!(
        contains(&text, b"TMP105") && !contains(&text, b"configuration does not read back"),
        "found as a TMP105: {}",
        text.escape_ascii()
    );
}

/// The TMP105's QOM path: `-device tmp105,...,id=tsens` is `/machine/peripheral/tsens`
/// (QEMU 7.2: `qom-list /machine/peripheral` lists it as `child<tmp105>`, with an `int`
/// property `temperature` in milli-degrees C, range [-128000, 128000)).
const TSENS: &str = "/machine/peripheral/tsens";

/// What the firmware reads from QEMU's TMP105 after `qom-set temperature MILLI` at 12 bits
/// (written here from QEMU 7.2's `hw/sensor/tmp105.c`): the model keeps `(int16)(milli * 256
/// / 1000)` (8.8 fixed point, C division: towards zero), and a temperature read masks the low
/// byte with `0xF0 << (3 - R)` (R = the resolution field: 0xF0 at 12 bits). `bits` is the
/// resolution the firmware is expected to set (9 gives a control that must differ).
fn tmp105_reading(milli: i64, bits: u32) -> f32 {
    let fixed = (milli * 256 / 1000) as i16 as u16;
    let mask = 0xFF00 | (0xF0u16 << (12 - bits)) & 0xFF;
    f32::from((fixed & mask) as i16) / 256.0
}

/// The profile played into the sensor: (first frame it applies to, milli-degrees C). The
/// firmware reads the sensor at samples 0, 100, 200, ... (`REFRESH_SAMPLES`); the changes fall
/// between reads and, at frame 1200 and 2400, exactly on one (the read at that sample must
/// see the new value). Values whose 12-bit reading differs from the 9-bit one.
const PROFILE: [(usize, i64); 9] = [
    (0, 23_810),
    (450, 24_110),
    (1200, 26_470),
    (1650, 28_925),
    (2100, 31_337),
    (2400, 33_190),
    (2950, 30_190),
    (3320, 27_380),
    (3700, 26_655),
];

/// Frames of the capture (40 s at 100 Hz).
const FRAMES: usize = 4000;

/// The per-sample temperatures the firmware is expected to use, given the profile and the
/// reading model: its own refresh/hold policy (`temperature_hold.rs`, the same file) with
/// every read good.
fn expected_temperatures(bits: u32) -> Vec<Option<f32>> {
    let refresh = (pipeline::SAMPLE_RATE_HZ + 0.5) as u32;
    let mut hold = Hold::new(refresh, 5 * refresh);
    (0..FRAMES)
        .map(|k| {
            if hold.tick() {
                let milli = PROFILE
                    .iter()
                    .rev()
                    .find(|(from, _)| *from <= k)
                    .map_or(0, |&(_, m)| m);
                hold.good(tmp105_reading(milli, bits));
            }
            hold.expire();
            hold.value()
        })
        .collect()
}

#[test]
fn the_reading_model_matches_qemus_fixed_point() {
    // 23.810 C: 6095.36 -> 6095 (0x17CF) -> 12 bits 0x17C0 = 23.75, 9 bits 0x1780 = 23.5.
    assert_eq!(tmp105_reading(23_810, 12), 23.75);
    assert_eq!(tmp105_reading(23_810, 9), 23.5);
    // A multiple of 0.5 C reads the same at both resolutions.
    assert_eq!(tmp105_reading(23_530, 12), tmp105_reading(23_530, 9));
    // Negative: -5.210 C: -1333.76 -> -1333 (towards zero) = 0xFACB -> 0xFAC0 = -5.25.
    assert_eq!(tmp105_reading(-5_210, 12), -5.25);
    assert_eq!(tmp105_reading(-5_210, 9), -5.5);
    assert_eq!(tmp105_reading(127_999, 12), 127.9375);
    // The profile's readings differ between 12 and 9 bits (the control can fail).
    for (_, m) in PROFILE {
        assert_ne!(tmp105_reading(m, 12), tmp105_reading(m, 9), "{m}");
    }
}

/// Temperature in the loop. A still-then-moving capture (host-sim, ecore2000 preset) is fed
/// to UART0 in steps; before each step the test sets the TMP105's temperature over QMP
/// (`qom-set /machine/peripheral/tsens temperature MILLI`) **only when the firmware is
/// waiting for input**: all frames sent so far have their records on UART0 and the next
/// frame's bytes are not sent yet. The firmware reads the sensor in the main loop when a
/// frame completes, so the value each read sees is fixed by the frame index alone, whatever
/// the host's or QEMU's timing. The host replays the same frames through `pipeline.rs` with
/// the temperatures computed from the profile, QEMU's fixed-point model and the firmware's
/// refresh policy; every record must match bit for bit, and the counters too.
///
/// Controls: the same records differ from the host run without temperature and from the run
/// with 9-bit readings (the firmware's resolution setting is seen).
#[test]
fn a_temperature_profile_over_qmp_reaches_the_estimator_bit_for_bit() {
    let Some(qemu) = qemu_system_arm() else {
        return;
    };
    let fw = default_firmware("hil-temperature");
    let capture = fw.file("capture.bin");
    let preset = fog_system_tests::firmware_dir().join("../host-sim/gyros/ecore2000.toml");
    let st = host_sim()
        .args(["simulate", "--gyro"])
        .arg(&preset)
        .args(["--duration-s", &(FRAMES / 100).to_string(), "--seed", "105"])
        .args(["--format", "ecore-bin", "--output"])
        .arg(&capture)
        .status()
        .expect("host-sim runs");
    assert!(st.success(), "host-sim simulate");
    let frames = std::fs::read(&capture).expect("capture");
    assert_eq!(frames.len(), 8 * FRAMES, "whole frames");

    // Steps: the frames from one profile point to the next; the end marker last.
    let mut steps = Vec::new();
    for (j, &(from, _)) in PROFILE.iter().enumerate() {
        let to = PROFILE.get(j + 1).map_or(FRAMES, |p| p.0);
        let mut bytes = frames[8 * from..8 * to].to_vec();
        if to == FRAMES {
            bytes.extend(END_MARKER);
        }
        steps.push(hil::Step {
            wait_output: from * pipeline::SAMPLE_RECORD_LEN,
            bytes,
        });
    }
    let mut stream = frames.clone();
    stream.extend(END_MARKER);

    let held = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let held_in = std::sync::Arc::clone(&held);
    let log = fw.file("defmt.bin");
    let args = [
        "-machine",
        "mps2-an386",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "stdio",
        "-semihosting-config",
        "enable=on,target=native",
        "-device",
        "tmp105,address=0x48,id=tsens",
    ];
    let t_run = std::time::Instant::now();
    let run = hil::run_qemu_steps(
        &qemu,
        &args,
        &fw.elf,
        steps,
        move |qmp, j| {
            let milli = PROFILE[j].1;
            qmp.qom_set_int(TSENS, "temperature", milli);
            // QEMU's own view of what it holds: the 8.8 value back in milli-degrees.
            let back = qmp.qom_get_int(TSENS, "temperature");
            held_in.lock().expect("lock").push((milli, back));
        },
        None,
        &log,
    );
    let ran = t_run.elapsed();
    assert_eq!(run.code, Some(0), "QEMU's exit code (semihosting)");
    let (records, stats) = hil::parse_records(&run.out);
    let stats = stats.expect("final statistics record");

    // QEMU holds what the reading model says (8.8, towards zero), before the 12-bit mask.
    for &(milli, back) in held.lock().expect("lock").iter() {
        assert_eq!(
            back,
            (milli * 256 / 1000) * 1000 / 256,
            "qom-get after {milli}"
        );
    }

    let image = hil::default_image();
    let temps = expected_temperatures(12);
    let expected = hil::host_reference_temps(&stream, &image, |k| temps[k]);
    assert_eq!(records.len(), FRAMES, "one record per frame");
    assert_eq!(expected.samples.len(), FRAMES);
    let mut mismatches = 0;
    for (k, (r, (_, _, status))) in records.iter().zip(&expected.samples).enumerate() {
        if r.index as usize != k || r.bits != expected.bits(k) || r.status != *status {
            mismatches += 1;
            if mismatches <= 5 {
                eprintln!(
                    "sample {k} (temperature {:?}): firmware {:08x?} status {:#04x}; host {:08x?} status {status:#04x}",
                    temps[k],
                    r.bits,
                    r.status,
                    expected.bits(k)
                );
            }
        }
    }
    assert_eq!(
        mismatches, 0,
        "records differ from the host fed the profile"
    );
    assert!(
        records
            .iter()
            .all(|r| r.status & pipeline::STATUS_TEMPERATURE != 0),
        "every sample had a reading (status bit 4)"
    );
    assert_eq!(stats.counters, expected.stats.counters(), "byte counters");
    assert_eq!(stats.samples as usize, FRAMES);

    // Controls: the temperature changed the estimates, at the firmware's resolution.
    let differing = |other: &hil::Expected| {
        (0..FRAMES)
            .filter(|&k| records[k].bits != other.bits(k))
            .count()
    };
    let without = differing(&hil::host_reference(&stream));
    let temps9 = expected_temperatures(9);
    let at_9_bits = differing(&hil::host_reference_temps(&stream, &image, |k| temps9[k]));
    assert!(without > 0, "no record depends on the temperature");
    assert!(
        at_9_bits > 0,
        "12-bit and 9-bit readings give the same records"
    );

    let text = defmt_payloads(&std::fs::read(&log).expect("defmt log"));
    assert!(contains(&text, b"TMP105"), "{}", text.escape_ascii());
    let distinct: std::collections::BTreeSet<u32> =
        temps.iter().flatten().map(|t| t.to_bits()).collect();
    eprintln!(
        "HIL temperature: {} records bit-identical with the host fed the profile ({} distinct readings, {:.4} to {:.4} C, set over QMP at {} points); \
         records that differ from the host without temperature: {without}, with 9-bit readings: {at_9_bits}; QEMU run {:.2} s",
        records.len(),
        distinct.len(),
        temps.iter().flatten().fold(f32::INFINITY, |a, &b| a.min(b)),
        temps.iter().flatten().fold(f32::NEG_INFINITY, |a, &b| a.max(b)),
        PROFILE.len(),
        ran.as_secs_f64()
    );
}

/// Drives a `Hold` as the firmware does; `read(k)` is the sensor at sample `k`.
fn drive(hold: &mut Hold, n: usize, read: impl Fn(usize) -> Option<f32>) -> Vec<Option<f32>> {
    (0..n)
        .map(|k| {
            if hold.tick() {
                match read(k) {
                    Some(t) => {
                        hold.good(t);
                    }
                    None => hold.failed(),
                }
            }
            hold.expire();
            hold.value()
        })
        .collect()
}

#[test]
fn hold_reads_once_per_refresh_period() {
    let mut hold = Hold::new(100, 500);
    let reads = std::cell::Cell::new(Vec::new());
    let got = drive(&mut hold, 350, |k| {
        let mut v = reads.take();
        v.push(k);
        reads.set(v);
        Some(k as f32)
    });
    assert_eq!(reads.take(), [0, 100, 200, 300]);
    assert_eq!(got[0], Some(0.0));
    assert_eq!(got[99], Some(0.0));
    assert_eq!(got[100], Some(100.0));
    assert_eq!(got[349], Some(300.0));
    assert_eq!(hold.failures(), 0);
}

#[test]
fn hold_keeps_a_reading_for_a_bounded_time_after_failures() {
    // Good reads at samples 0 and 100, then the sensor fails from sample 200 to 1099.
    let mut hold = Hold::new(100, 500);
    let sensor = |k: usize| (!(200..1100).contains(&k)).then_some(20.0 + k as f32 / 1000.0);
    let got = drive(&mut hold, 1200, sensor);
    // Held while the last good read (sample 100) is at most 500 samples old.
    assert!(
        got[100..=600].iter().all(|v| *v == Some(20.1)),
        "{:?}",
        &got[590..610]
    );
    assert!(got[601..1100].iter().all(Option::is_none));
    // Back at the first good read.
    assert_eq!(got[1100], Some(21.1));
    assert_eq!(got[1199], Some(21.1));
    // Reads at 200, 300, ..., 1000 failed.
    assert_eq!(hold.failures(), 9);
    // The last good read was at sample 1100, 99 samples before the last one.
    assert_eq!(hold.age_samples(), 99);
}

#[test]
fn hold_without_a_good_read_gives_none() {
    let mut hold = Hold::new(100, 500);
    let got = drive(&mut hold, 1000, |_| None);
    assert!(got.iter().all(Option::is_none));
    assert_eq!(hold.failures(), 10);
    // A refresh period of 0 reads every sample.
    let mut every = Hold::new(0, 0);
    assert!((0..5).all(|_| every.tick()));
}

#[test]
fn hold_reports_the_transitions() {
    let mut hold = Hold::new(1, 2);
    assert!(hold.tick());
    assert!(!hold.good(25.0), "first reading is not a return");
    hold.failed();
    for _ in 0..2 {
        hold.tick();
        hold.failed();
        assert!(!hold.expire());
    }
    hold.tick();
    assert!(hold.expire(), "dropped at age 3 > 2");
    assert_eq!(hold.value(), None);
    hold.tick();
    assert!(hold.good(24.0), "back after a drop");
    assert_eq!(hold.value(), Some(24.0));
}
