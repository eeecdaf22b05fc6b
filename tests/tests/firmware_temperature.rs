//! The firmware's TMP117 probe under QEMU (`-machine mps2-an386`): the bit-banged SBCon I2C
//! master on the Shield1 port (`fog-firmware/src/board/sbcon_i2c.rs`) talks to what QEMU
//! models on that bus.
//!
//! - Nothing on the bus (the default): the address byte is not acknowledged, the firmware logs
//!   "no TMP117 ... (no acknowledge)" and runs without temperature.
//! - QEMU's TMP105 model at 0x48 (`-device tmp105,address=0x48`, which QEMU puts on the
//!   Shield1 port, the first free I2C bus): the address is acknowledged and two register
//!   bytes come back (the TMP105 has no register 0x0F, so the id check fails: "wrong device
//!   id" path, no "no acknowledge" in the log).
//!
//! Either way the firmware must run to the end marker and exit 0 with its statistics record.
//! The refresh and hold policy (`fog-firmware/src/temperature_hold.rs`, compiled here) is
//! tested on the host.
//! The defmt log is not decoded (no decoder here): a `{=str}` argument is written verbatim in
//! defmt's frames, so the test looks for the probe's reason string in the raw bytes.

use std::io::{Read, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use fog_system_tests::{firmware_elf, qemu_system_arm};

#[path = "../../fog-firmware/src/temperature_hold.rs"]
mod temperature_hold;
use temperature_hold::Hold;

/// The firmware's end-of-input marker (`pipeline::END_MARKER`).
const END_MARKER: [u8; 8] = [0xC6, 0xCF, 0xC7, 0xAD, 0xC5, 0xCE, 0xC4, 0xA1];

/// Statistics record: sync, kind 0x02, len, payload, checksum (the firmware's constants).
#[allow(dead_code)]
#[path = "../../fog-firmware/src/pipeline.rs"]
mod pipeline;
use pipeline::{STATS_PAYLOAD_LEN, STATS_RECORD_LEN};

/// Runs the firmware with only the end marker on its UART and `extra` QEMU arguments;
/// returns (UART output, defmt bytes, exit code).
fn run(name: &str, extra: &[&str]) -> Option<(Vec<u8>, Vec<u8>, Option<i32>)> {
    let qemu = qemu_system_arm()?;
    let elf = firmware_elf(&[]);
    // To a file, as in the HIL test (through a pipe, the first frames got lost).
    let log_path = elf.with_file_name(format!("temperature-{name}-defmt.bin"));
    let log_file = std::fs::File::create(&log_path).expect("defmt log file");
    let mut child = Command::new(qemu)
        .args(["-machine", "mps2-an386", "-nographic", "-monitor", "none"])
        .args(["-serial", "stdio"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(extra)
        .env_clear()
        .arg("-kernel")
        .arg(&elf)
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
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("QEMU did not exit within 30 s");
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
fn a_device_that_answers_is_not_taken_for_a_tmp117() {
    let Some((out, log, code)) = run("tmp105", &["-device", "tmp105,address=0x48"]) else {
        return;
    };
    assert_eq!(code, Some(0), "QEMU's exit code (semihosting)");
    assert_eq!(out.len(), STATS_RECORD_LEN, "only the statistics record");
    assert!(
        !contains(&log, b"no acknowledge"),
        "the TMP105 acknowledged its address"
    );
    assert!(!log.is_empty());
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
