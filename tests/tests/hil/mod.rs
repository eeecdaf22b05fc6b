//! Helpers shared by the hardware-in-the-loop tests under QEMU (`firmware_qemu.rs`,
//! `firmware_faults.rs`): the seeded generator, the host's reference run of the firmware's
//! per-sample code, the record parser (written from `fog-firmware/README.md`) and the QEMU
//! runner with its pipes and deadline.
#![allow(dead_code)]

use std::io::{Read, Write};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use fog_core::frame::{ByteStats, Decoder, EcoreDecoder, EcoreFrame};

#[allow(dead_code)]
#[path = "../../../fog-firmware/src/pipeline.rs"]
pub mod pipeline;

/// A whole QEMU run, writing included, must end within this: a guard against a hang, not a
/// speed limit (speed is measured by `scripts/fw-budget.sh`, not asserted in tests). A run
/// takes 1-10 s alone; the debug and release runs of `scripts/test-firmware-parallel.sh`
/// on 2 cores with other work beside them took up to 50 s.
pub const DEADLINE: Duration = Duration::from_secs(300);

/// How long QEMU may take to exit once its output closed.
pub const EXIT_GRACE: Duration = Duration::from_secs(60);

/// xorshift64*: small, seeded, identical everywhere.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (sum of 12 uniforms, minus 6).
    pub fn normal(&mut self) -> f64 {
        (0..12).map(|_| self.uniform()).sum::<f64>() - 6.0
    }
}

pub use fog_system_tests::default_image;

/// What the host expects: one entry per good frame, then the flushed counters.
pub struct Expected {
    /// (rate, output, status) of each good frame, in order.
    pub samples: Vec<(f32, pipeline::Output, u8)>,
    /// The decoded frames themselves (their raw bytes tag them).
    pub frames: Vec<EcoreFrame>,
    /// Counters after the final flush.
    pub stats: ByteStats,
    /// Still-flag commands in the stream.
    pub still_commands: u32,
    /// The external still flag each good frame was processed with.
    pub external: Vec<Option<bool>>,
}

impl Expected {
    /// The four f32 fields of sample `k`'s record, as bits (rate, drift, compensated,
    /// denoised).
    pub fn bits(&self, k: usize) -> [u32; 4] {
        let (rate_dps, o, _) = &self.samples[k];
        [
            rate_dps.to_bits(),
            o.drift_dps.to_bits(),
            o.compensated_dps.to_bits(),
            o.denoised_dps.to_bits(),
        ]
    }

    /// The firmware's `records` are the host's, one per good frame: index, the four f32
    /// fields bit for bit, and the status (the first 5 differences printed).
    pub fn assert_records_match(&self, records: &[SampleRecord]) {
        assert_eq!(
            records.len(),
            self.samples.len(),
            "one record per good frame"
        );
        let mut mismatches = 0;
        for (k, (r, (_, _, status))) in records.iter().zip(&self.samples).enumerate() {
            let want = self.bits(k);
            if r.index as usize != k || r.bits != want || r.status != *status {
                mismatches += 1;
                if mismatches <= 5 {
                    eprintln!(
                        "sample {k}: firmware index {} bits {:08x?} status {}; host bits {want:08x?} status {status}",
                        r.index, r.bits, r.status
                    );
                }
            }
        }
        assert_eq!(mismatches, 0, "per-sample records differ from the host");
    }
}

/// [`host_reference_with`] and the default image.
pub fn host_reference(stream: &[u8]) -> Expected {
    host_reference_with(stream, &default_image())
}

/// The firmware's loop on the host: the same bytes through the command detector and the
/// decoder, each good frame through `pipeline::process` with the stage built from `image`
/// (no temperature sensor, no still input pin: the external flag comes from the in-band
/// commands only).
pub fn host_reference_with(stream: &[u8], image: &[u8]) -> Expected {
    host_reference_temps(stream, image, |_| None)
}

/// [`host_reference_with`] with a temperature: `temp_c(k)` is what the firmware's
/// `TemperatureSource::sample` is expected to give for good frame `k` (0-based).
pub fn host_reference_temps(
    stream: &[u8],
    image: &[u8],
    mut temp_c: impl FnMut(usize) -> Option<f32>,
) -> Expected {
    let mut decoder = EcoreDecoder::new(pipeline::FULL_SCALE_DPS).expect("valid full scale");
    let mut stage = pipeline::new_stage(image).expect("valid identifier image");
    let mut commands = pipeline::CommandDetector::default();
    let (mut still, mut still_commands, mut ended) = (None, 0, false);
    let mut samples = Vec::new();
    let mut frames = Vec::new();
    let mut external = Vec::new();
    for &b in stream {
        // The firmware stops reading at the end marker.
        if ended {
            break;
        }
        match commands.push(b) {
            Some(pipeline::Command::End) => ended = true,
            Some(c) => {
                still = c.still_flag();
                still_commands += 1;
            }
            None => {}
        }
        if let Some(frame) = decoder.push(b) {
            let t = temp_c(samples.len());
            let (out, status) = pipeline::process(&mut stage, frame.rate_dps, t, still);
            samples.push((frame.rate_dps, out, status));
            frames.push(frame);
            external.push(still);
        }
    }
    decoder.flush();
    Expected {
        samples,
        frames,
        stats: *decoder.stats(),
        still_commands,
        external,
    }
}

/// Fletcher-16 as README.md defines it (written again here on purpose).
pub fn fletcher16(bytes: &[u8]) -> u16 {
    let (mut a, mut b) = (0u32, 0u32);
    for &x in bytes {
        a = (a + u32::from(x)) % 255;
        b = (b + a) % 255;
    }
    (a | (b << 8)) as u16
}

#[derive(Debug)]
pub struct SampleRecord {
    pub index: u32,
    pub bits: [u32; 4],
    pub status: u8,
}

#[derive(Debug)]
pub struct StatsRecord {
    pub counters: [u64; 17],
    pub samples: u32,
    pub rejected: u32,
    pub serial_errors: u32,
    pub stack_bytes: u32,
    pub rx_overrun: u32,
    pub rx_queue_full: u32,
    pub still_commands: u32,
}

pub fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes(b.try_into().expect("4 bytes"))
}

/// Splits the UART output into records; panics on anything malformed.
pub fn parse_records(out: &[u8]) -> (Vec<SampleRecord>, Option<StatsRecord>) {
    let mut samples = Vec::new();
    let mut stats = None;
    let mut i = 0;
    while i < out.len() {
        assert!(stats.is_none(), "bytes after the statistics record at {i}");
        assert_eq!(out[i], 0xA5, "record sync at offset {i}");
        assert!(i + 3 <= out.len(), "truncated header at {i}");
        let (kind, len) = (out[i + 1], usize::from(out[i + 2]));
        let end = i + 3 + len + 2;
        assert!(end <= out.len(), "truncated record at {i}");
        let sum = u16::from_le_bytes([out[end - 2], out[end - 1]]);
        assert_eq!(
            sum,
            fletcher16(&out[i + 1..end - 2]),
            "checksum of record at {i}"
        );
        let p = &out[i + 3..i + 3 + len];
        match (kind, len) {
            (0x01, 21) => samples.push(SampleRecord {
                index: le_u32(&p[0..4]),
                bits: [
                    le_u32(&p[4..8]),
                    le_u32(&p[8..12]),
                    le_u32(&p[12..16]),
                    le_u32(&p[16..20]),
                ],
                status: p[20],
            }),
            (0x02, 164) => {
                let mut counters = [0u64; 17];
                for (c, chunk) in counters.iter_mut().zip(p[..136].chunks_exact(8)) {
                    *c = u64::from_le_bytes(chunk.try_into().expect("8 bytes"));
                }
                stats = Some(StatsRecord {
                    counters,
                    samples: le_u32(&p[136..140]),
                    rejected: le_u32(&p[140..144]),
                    serial_errors: le_u32(&p[144..148]),
                    stack_bytes: le_u32(&p[148..152]),
                    rx_overrun: le_u32(&p[152..156]),
                    rx_queue_full: le_u32(&p[156..160]),
                    still_commands: le_u32(&p[160..164]),
                });
            }
            other => panic!("unknown record (kind, len) {other:?} at {i}"),
        }
        i = end;
    }
    (samples, stats)
}

/// Kills QEMU whatever happens to the test.
pub struct KillOnDrop(pub Child);

impl KillOnDrop {
    /// QEMU's exit code once its output has closed: it is exiting, so it is waited for up to
    /// [`EXIT_GRACE`]; `None` if it has not exited by then (it is killed on drop).
    pub fn exit_code(&mut self) -> Option<i32> {
        let wait_until = Instant::now() + EXIT_GRACE;
        while Instant::now() < wait_until {
            if let Ok(Some(status)) = self.0.try_wait() {
                return status.code();
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }
}

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// What a QEMU run gave: UART0's output with the time each piece arrived, the exit code, and
/// when the writer resumed after each pause.
pub struct QemuRun {
    pub out: Vec<u8>,
    pub code: Option<i32>,
    /// (time since start, output bytes received so far), one entry per read.
    pub arrivals: Vec<(Duration, usize)>,
    /// Time since start at which the writer resumed after each pause.
    pub resumed: Vec<Duration>,
}

impl QemuRun {
    /// Output bytes received before `t` (since start).
    pub fn bytes_before(&self, t: Duration) -> usize {
        self.arrivals
            .iter()
            .take_while(|(at, _)| *at < t)
            .last()
            .map_or(0, |(_, n)| *n)
    }
}

/// Starts `qemu-system-arm -machine mps2-an386` with `elf`: UART0 on stdin/stdout (stdout
/// piped), semihosting on, defmt (semihosting stderr) into `defmt_log`, `extra` arguments
/// (e.g. `-icount`) before the kernel.
pub fn spawn_qemu(
    qemu: &Path,
    elf: &Path,
    extra: &[&str],
    stdin: Stdio,
    defmt_log: &Path,
) -> KillOnDrop {
    let log = std::fs::File::create(defmt_log).expect("defmt log file");
    let child = Command::new(qemu)
        .args(["-machine", "mps2-an386", "-nographic", "-monitor", "none"])
        .args(["-serial", "stdio"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(extra)
        .arg("-kernel")
        .arg(elf)
        .stdin(stdin)
        .stdout(Stdio::piped())
        .stderr(Stdio::from(log))
        .spawn()
        .expect("qemu-system-arm starts");
    KillOnDrop(child)
}

/// Runs the firmware under QEMU with `input` on UART0; returns (UART0 output, exit code).
/// defmt's frames (semihosting stderr) go to `defmt_log`.
pub fn run_qemu(
    qemu: &Path,
    elf: &Path,
    input: Vec<u8>,
    defmt_log: &Path,
) -> (Vec<u8>, Option<i32>) {
    let piece = Piece {
        bytes: input,
        pause: Duration::ZERO,
        resume_after_output: 0,
    };
    let r = run_qemu_paced(qemu, elf, vec![piece], defmt_log);
    (r.out, r.code)
}

/// One piece of a paced input: its bytes, then a pause of at least `pause` that lasts until
/// UART0 has put out `resume_after_output` bytes in all (or [`DEADLINE`]).
pub struct Piece {
    pub bytes: Vec<u8>,
    pub pause: Duration,
    pub resume_after_output: usize,
}

/// [`run_qemu`] with the input in pieces, the writer pausing after each piece (a UART that
/// stalls: the firmware sees no byte meanwhile).
pub fn run_qemu_paced(qemu: &Path, elf: &Path, pieces: Vec<Piece>, defmt_log: &Path) -> QemuRun {
    let start = Instant::now();
    let mut qemu_proc = spawn_qemu(qemu, elf, &[], Stdio::piped(), defmt_log);
    let mut stdin = qemu_proc.0.stdin.take().expect("piped stdin");
    let mut stdout = qemu_proc.0.stdout.take().expect("piped stdout");

    // Writer and reader on their own threads: neither pipe can block the other.
    let (done_tx, done_rx) = mpsc::channel();
    let out_bytes = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let out_seen = std::sync::Arc::clone(&out_bytes);
    let writer = std::thread::spawn(move || {
        let mut resumed = Vec::new();
        for piece in pieces {
            stdin.write_all(&piece.bytes).and_then(|()| stdin.flush())?;
            if !piece.pause.is_zero() {
                std::thread::sleep(piece.pause);
                while out_seen.load(std::sync::atomic::Ordering::SeqCst) < piece.resume_after_output
                    && start.elapsed() < DEADLINE
                {
                    std::thread::sleep(Duration::from_millis(10));
                }
                resumed.push(start.elapsed());
            }
        }
        // Keep stdin open until the run is over (EOF is not the end-of-input signal).
        let _ = done_rx.recv_timeout(DEADLINE);
        Ok::<_, std::io::Error>(resumed)
    });
    let (out_tx, out_rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut out = Vec::new();
        let mut arrivals = Vec::new();
        let mut buf = [0u8; 4096];
        let r = loop {
            match stdout.read(&mut buf) {
                Ok(0) => break Ok(()),
                Ok(n) => {
                    out.extend_from_slice(&buf[..n]);
                    arrivals.push((start.elapsed(), out.len()));
                    out_bytes.store(out.len(), std::sync::atomic::Ordering::SeqCst);
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => break Err(e),
            }
        };
        let _ = out_tx.send((out, arrivals, r));
    });

    let remaining = DEADLINE.saturating_sub(start.elapsed());
    let received = out_rx.recv_timeout(remaining);
    let _ = done_tx.send(());
    let (out, arrivals, read_result) = match received {
        Ok(v) => v,
        Err(_) => {
            drop(qemu_proc);
            panic!("QEMU did not finish within {DEADLINE:?}");
        }
    };
    read_result.expect("reading QEMU's stdout");
    // stdout closed: QEMU is exiting; give it a moment, then kill.
    let code = qemu_proc.exit_code();
    let resumed = writer
        .join()
        .expect("writer thread")
        .expect("writing QEMU's stdin");
    QemuRun {
        out,
        code,
        arrivals,
        resumed,
    }
}

/// The payloads of defmt's frames in `log` (rzCOBS-encoded frames, each ended by a zero
/// byte), concatenated: a `{=str}` argument appears there verbatim. Written here from the
/// rzCOBS format (the encoding is read from the end: a byte 0x01..=0x7F is a mask of 7
/// bytes, bit set = zero byte; 0x80..=0xFE is a zero byte after `(b & 0x7F) + 7` non-zero
/// bytes; 0xFF is 134 non-zero bytes).
pub fn defmt_payloads(log: &[u8]) -> Vec<u8> {
    let mut text = Vec::new();
    for frame in log.split(|&b| b == 0).filter(|f| !f.is_empty()) {
        let mut out = Vec::new();
        let mut it = frame.iter().rev().copied();
        while let Some(x) = it.next() {
            match x {
                0x01..=0x7F => {
                    for i in 0..7 {
                        if x & (1 << (6 - i)) == 0 {
                            out.extend(it.next());
                        } else {
                            out.push(0);
                        }
                    }
                }
                0x80..=0xFE => {
                    out.push(0);
                    for _ in 0..usize::from(x & 0x7F) + 7 {
                        out.extend(it.next());
                    }
                }
                _ => {
                    for _ in 0..134 {
                        out.extend(it.next());
                    }
                }
            }
        }
        out.reverse();
        text.extend(out);
    }
    text
}

/// A QMP client (QEMU `-qmp unix:PATH,server=on,wait=off`), line-delimited JSON written and
/// matched as text (no JSON crate here).
pub struct Qmp {
    reader: std::io::BufReader<std::os::unix::net::UnixStream>,
    writer: std::os::unix::net::UnixStream,
}

impl Qmp {
    /// Connects (retrying while QEMU starts, up to 60 s), reads the greeting and leaves the
    /// capabilities negotiation mode.
    pub fn connect(path: &Path) -> Qmp {
        let start = Instant::now();
        let stream = loop {
            match std::os::unix::net::UnixStream::connect(path) {
                Ok(s) => break s,
                // Not listening yet: QEMU is starting.
                Err(_) if start.elapsed() < Duration::from_secs(60) => {
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => panic!("QMP socket {}: {e}", path.display()),
            }
        };
        stream
            .set_read_timeout(Some(DEADLINE))
            .expect("QMP read timeout");
        let writer = stream.try_clone().expect("QMP socket clone");
        let mut qmp = Qmp {
            reader: std::io::BufReader::new(stream),
            writer,
        };
        // QEMU may queue an event (seen: `RESUME`, the guest starting) on the socket ahead
        // of the greeting when the client connects while the machine starts.
        let greeting = qmp.line_past_events();
        assert!(greeting.contains("\"QMP\""), "QMP greeting: {greeting}");
        qmp.execute(r#"{"execute": "qmp_capabilities"}"#);
        qmp
    }

    fn line(&mut self) -> String {
        use std::io::BufRead;
        let mut l = String::new();
        self.reader.read_line(&mut l).expect("QMP reply");
        assert!(!l.is_empty(), "QMP socket closed");
        l
    }

    /// The next line that is not an event (`{"event": ...}`: nothing this client needs).
    fn line_past_events(&mut self) -> String {
        loop {
            let l = self.line();
            if !l.starts_with("{\"event\"") {
                return l;
            }
        }
    }

    /// Sends one command; returns its reply line (`{"return": ...}`), events skipped.
    /// Panics on an `{"error": ...}` reply.
    pub fn execute(&mut self, command: &str) -> String {
        let reply = self.try_execute(command);
        assert!(reply.starts_with("{\"return\""), "QMP {command}: {reply}");
        reply
    }

    /// Sends one command; returns its reply line, error or not (events skipped).
    pub fn try_execute(&mut self, command: &str) -> String {
        self.writer
            .write_all(command.as_bytes())
            .and_then(|()| self.writer.write_all(b"\n"))
            .expect("QMP command written");
        self.line_past_events().trim().to_string()
    }

    /// `qom-set PATH PROPERTY VALUE` (an integer).
    pub fn qom_set_int(&mut self, path: &str, property: &str, value: i64) {
        self.execute(&format!(
            r#"{{"execute": "qom-set", "arguments": {{"path": "{path}", "property": "{property}", "value": {value}}}}}"#
        ));
    }

    /// `qom-get PATH PROPERTY` of an integer property.
    pub fn qom_get_int(&mut self, path: &str, property: &str) -> i64 {
        let reply = self.execute(&format!(
            r#"{{"execute": "qom-get", "arguments": {{"path": "{path}", "property": "{property}"}}}}"#
        ));
        reply
            .trim_start_matches("{\"return\":")
            .trim_end_matches('}')
            .trim()
            .parse()
            .unwrap_or_else(|e| panic!("qom-get {path} {property}: {reply}: {e}"))
    }

    /// A 32-bit word of the guest's physical address space, read by the monitor (HMP `xp`;
    /// an MMIO register is read through its device model).
    pub fn read_word(&mut self, address: u32) -> u32 {
        let reply = self.execute(&format!(
            r#"{{"execute": "human-monitor-command", "arguments": {{"command-line": "xp /1wx {address:#x}"}}}}"#
        ));
        // {"return": "0000000040004400: 0x0000200c\r\n"}
        let hex = reply
            .rsplit("0x")
            .next()
            .map(|h| h.trim_start_matches("0x"))
            .and_then(|h| h.get(..8))
            .unwrap_or_else(|| panic!("xp reply: {reply}"));
        u32::from_str_radix(hex, 16).unwrap_or_else(|e| panic!("xp reply {reply}: {e}"))
    }
}

/// One step of a QMP-driven run: wait until UART output has `wait_output` bytes in all, run
/// the step's QMP action, then write `bytes`.
pub struct Step {
    pub wait_output: usize,
    pub bytes: Vec<u8>,
}

/// Whether `out` holds a complete statistics record (the firmware's last output), records
/// walked by their headers. Malformed output also ends the run (the parser then says why).
pub fn stats_record_complete(out: &[u8]) -> bool {
    let mut i = 0;
    while i + 3 <= out.len() {
        if out[i] != 0xA5 {
            return true;
        }
        let end = i + 3 + usize::from(out[i + 2]) + 2;
        if end > out.len() {
            return false;
        }
        if out[i + 1] == 0x02 {
            return true;
        }
        i = end;
    }
    false
}

/// Runs `qemu args... -qmp unix:QMP -kernel ELF` (stdin = the UART's input, stdout piped,
/// stderr into `log`), feeding `steps` from a writer thread: before each step's bytes it
/// waits for the step's output count, then calls `action(qmp, step index)`. The run ends
/// at EOF on stdout (QEMU exited: semihosting) or, when `end` says so, as soon as the output
/// is complete (a board that sleeps at the end); QEMU is then killed.
pub fn run_qemu_steps(
    qemu: &Path,
    args: &[&str],
    elf: &Path,
    steps: Vec<Step>,
    mut action: impl FnMut(&mut Qmp, usize) + Send + 'static,
    end: Option<fn(&[u8]) -> bool>,
    log: &Path,
) -> QemuRun {
    let start = Instant::now();
    // A Unix socket path must fit in sun_path (108 bytes): beside the log, under a deep
    // checkout's target directory, it did not (110 bytes in a worktree). A folder of this
    // run's own in the temporary directory (`/tmp/fog-qmp-XXXXXX/qmp.sock`): no other run,
    // in this process or another, names the same socket.
    let qmp_dir = tempfile::Builder::new()
        .prefix("fog-qmp-")
        .tempdir()
        .expect("a folder for the QMP socket");
    let qmp_path = qmp_dir.path().join("qmp.sock");
    let log_file = std::fs::File::create(log).expect("log file");
    let child = Command::new(qemu)
        .args(args)
        .arg("-qmp")
        .arg(format!("unix:{},server=on,wait=off", qmp_path.display()))
        .arg("-kernel")
        .arg(elf)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(log_file))
        .spawn()
        .expect("qemu-system-arm starts");
    let mut qemu_proc = KillOnDrop(child);
    let mut stdin = qemu_proc.0.stdin.take().expect("piped stdin");
    let mut stdout = qemu_proc.0.stdout.take().expect("piped stdout");

    let (done_tx, done_rx) = mpsc::channel();
    let out_bytes = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let out_seen = std::sync::Arc::clone(&out_bytes);
    let writer = std::thread::spawn(move || {
        let mut qmp = Qmp::connect(&qmp_path);
        let mut resumed = Vec::new();
        for (i, step) in steps.into_iter().enumerate() {
            while out_seen.load(std::sync::atomic::Ordering::SeqCst) < step.wait_output {
                assert!(
                    start.elapsed() < DEADLINE,
                    "step {i}: waiting for {} output bytes",
                    step.wait_output
                );
                std::thread::sleep(Duration::from_millis(2));
            }
            action(&mut qmp, i);
            resumed.push(start.elapsed());
            stdin.write_all(&step.bytes).and_then(|()| stdin.flush())?;
        }
        let _ = done_rx.recv_timeout(DEADLINE);
        Ok::<_, std::io::Error>(resumed)
    });
    let (out_tx, out_rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut out = Vec::new();
        let mut arrivals = Vec::new();
        let mut buf = [0u8; 4096];
        let r = loop {
            match stdout.read(&mut buf) {
                Ok(0) => break Ok(false),
                Ok(n) => {
                    out.extend_from_slice(&buf[..n]);
                    arrivals.push((start.elapsed(), out.len()));
                    out_bytes.store(out.len(), std::sync::atomic::Ordering::SeqCst);
                    if end.is_some_and(|f| f(&out)) {
                        break Ok(true);
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => break Err(e),
            }
        };
        let _ = out_tx.send((out, arrivals, r));
    });

    // Waits for the output; a writer that panicked (QMP refused, a step's output never
    // came) ends the run at once with its own message instead of at the deadline (the
    // guest, waiting for input that will never come, would never finish).
    let mut writer = Some(writer);
    let mut written = None;
    let received = loop {
        match out_rx.recv_timeout(Duration::from_millis(100)) {
            Ok(r) => break Some(r),
            Err(mpsc::RecvTimeoutError::Disconnected) => break None,
            Err(mpsc::RecvTimeoutError::Timeout) => {}
        }
        if writer.as_ref().is_some_and(|w| w.is_finished()) {
            match writer.take().map(|w| w.join()) {
                Some(Err(panic)) => {
                    drop(qemu_proc);
                    std::panic::resume_unwind(panic)
                }
                Some(Ok(result)) => written = Some(result),
                None => {}
            }
        }
        if start.elapsed() >= DEADLINE {
            break None;
        }
    };
    let _ = done_tx.send(());
    let Some((out, arrivals, read_result)) = received else {
        drop(qemu_proc);
        panic!("QEMU did not finish within {DEADLINE:?}");
    };
    let ended_by_output = read_result.expect("reading QEMU's stdout");
    let code = if ended_by_output {
        None
    } else {
        qemu_proc.exit_code()
    };
    drop(qemu_proc);
    drop(qmp_dir);
    let resumed = match (written, writer) {
        (Some(result), _) => result,
        (None, Some(w)) => w.join().expect("writer thread"),
        (None, None) => unreachable!("the writer is either joined or kept"),
    }
    .expect("writing QEMU's stdin");
    QemuRun {
        out,
        code,
        arrivals,
        resumed,
    }
}
