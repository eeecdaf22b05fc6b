//! `host-sim replay` end to end: CSV, E-Core binary and DSP-3000 input, damaged captures
//! (counted exactly), bad CSV rows, and the output against fog-core's identifier fed
//! directly.

use assert_cmd::Command;
use fog_core::frame::{ecore, ByteStats, Decoder, EcoreDecoder};
use fog_core::identify::presets;
use fog_core::train::DrlsConfig;
use fog_core::wnn::Activation;
use std::fs;
use std::path::{Path, PathBuf};

const HEADER: &str = "index,t_s,rate_dps,denoised_dps,drift_dps,compensated_dps";

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// Deterministic pseudo-random numbers in [-0.5, 0.5).
struct Lcg(u32);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        f64::from(self.0 >> 8) / f64::from(1u32 << 24) - 0.5
    }
}

/// Rates of a static gyro: slow drift plus noise, deg/s.
fn rates(n: usize) -> Vec<f64> {
    let mut g = Lcg(11);
    (0..n)
        .map(|i| 0.002 + 0.001 * (i as f64 * 0.001).sin() + 0.02 * g.next())
        .collect()
}

/// One output row: index, t_s, rate, denoised (None when empty), drift, compensated.
struct Out {
    index: u64,
    t_s: f64,
    rate: f32,
    denoised: Option<f32>,
    drift: f32,
    comp: f32,
}

fn read_output(path: &Path) -> Vec<Out> {
    let text = fs::read_to_string(path).expect("output readable");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(HEADER));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 6, "{l}");
            Out {
                index: f[0].parse().expect("index"),
                t_s: f[1].parse().expect("t_s"),
                rate: f[2].parse().expect("rate"),
                denoised: (!f[3].is_empty()).then(|| f[3].parse().expect("denoised")),
                drift: f[4].parse().expect("drift"),
                comp: f[5].parse().expect("comp"),
            }
        })
        .collect()
}

/// (drift, compensated) of fog-core's identifier fed `x` directly, and its denoised blocks.
fn direct(x: &[f32], paper: bool) -> (Vec<(f32, f32)>, Vec<f32>) {
    let dt = 0.01f32;
    let mut est = Vec::new();
    let mut den = Vec::new();
    if paper {
        let mut id = presets::paper::<512>(
            Activation::MexicanHat,
            presets::PAPER_SCALING,
            DrlsConfig::PAPER,
            dt,
        )
        .expect("identifier");
        for &v in x {
            let e = id.push(v).expect("sample accepted");
            est.push((e.drift_dps, e.compensated_dps));
            if e.block_done {
                den.extend_from_slice(id.last_denoised_block());
            }
        }
    } else {
        let mut id =
            presets::level_trend::<512>(presets::LEVEL_TREND_SCALING, dt).expect("identifier");
        for &v in x {
            let e = id.push(v).expect("sample accepted");
            est.push((e.drift_dps, e.compensated_dps));
            if e.block_done {
                den.extend_from_slice(id.last_denoised_block());
            }
        }
    }
    (est, den)
}

/// Same bits, or both NaN (text keeps no NaN sign or payload).
fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// The output equals the direct identifier bit for bit; the tail has no denoised value.
/// Returns how many drift values were not finite.
fn check_against_direct(out: &[Out], x: &[f32], paper: bool) -> usize {
    assert_eq!(out.len(), x.len());
    let (est, den) = direct(x, paper);
    for (k, (o, &(d, c))) in out.iter().zip(&est).enumerate() {
        assert_eq!(o.rate.to_bits(), x[k].to_bits(), "rate at {k}");
        assert!(same(o.drift, d), "drift_dps at {k}: {} vs {d}", o.drift);
        assert!(same(o.comp, c), "compensated_dps at {k}: {} vs {c}", o.comp);
        match den.get(k) {
            Some(v) => assert_eq!(
                o.denoised.map(f32::to_bits),
                Some(v.to_bits()),
                "denoised at {k}"
            ),
            None => assert!(o.denoised.is_none(), "row {k} of the partial block"),
        }
    }
    assert_eq!(den.len(), x.len() / 512 * 512);
    est.iter().filter(|e| !e.0.is_finite()).count()
}

fn write_csv(dir: &Path, x: &[f64], with_truth: bool) -> PathBuf {
    let mut s = String::from(if with_truth {
        "t_s,rate_dps,temp_c,drift_dps\n"
    } else {
        "t_s,rate_dps\n"
    });
    for (i, v) in x.iter().enumerate() {
        if with_truth {
            s.push_str(&format!("{:.2},{v},25,0.002\n", i as f64 * 0.01));
        } else {
            s.push_str(&format!("{:.2},{v}\n", i as f64 * 0.01));
        }
    }
    let p = dir.join("in.csv");
    fs::write(&p, s).expect("write");
    p
}

fn summary(dir: &Path) -> serde_json::Value {
    let text = fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    serde_json::from_str(&text).expect("JSON")
}

#[test]
fn csv_replay_matches_the_identifier_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tmp");
    let x = rates(1700);
    let input = write_csv(dir.path(), &x, false);
    let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    for paper in [false, true] {
        let output = dir.path().join(format!("out_{paper}.csv"));
        let mut cmd = host_sim();
        cmd.args(["replay", "--input"])
            .arg(&input)
            .arg("--output")
            .arg(&output);
        cmd.args(["--preset", if paper { "paper" } else { "level-trend" }]);
        let a = cmd.assert().success();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        assert!(err.contains("1700 samples (csv)"), "{err}");
        assert!(err.contains("164 rows of the final partial block"), "{err}");
        let out = read_output(&output);
        let nan = check_against_direct(&out, &xf, paper);
        if paper {
            // The paper's unguarded DRLS diverges on this noisy record: said, not hidden.
            assert!(
                nan == 0 || err.contains(&format!("{nan} identified drift values are not finite")),
                "{err}"
            );
        } else {
            assert_eq!(nan, 0, "level-trend stays finite");
        }
        for (k, o) in out.iter().enumerate() {
            assert_eq!(o.index, k as u64);
            assert_eq!(
                o.t_s,
                format!("{:.2}", k as f64 * 0.01).parse::<f64>().expect("t")
            );
        }
    }
}

#[test]
fn csv_with_truth_column_gives_a_report() {
    let dir = tempfile::tempdir().expect("tmp");
    let x = rates(3000);
    let input = write_csv(dir.path(), &x, true);
    let output = dir.path().join("out.csv");
    let rep = dir.path().join("rep");
    host_sim()
        .args(["replay", "--preset", "level-trend", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&output)
        .arg("--report")
        .arg(&rep)
        .assert()
        .success();
    let s = summary(&rep);
    assert_eq!(s["format"], "csv");
    assert_eq!(s["csv"]["rows"], 3000);
    assert_eq!(s["csv"]["gaps"], 0);
    assert_eq!(s["truth"]["samples"], 3000);
    assert!(s["truth"]["e_truth"]["identifier"]
        .as_f64()
        .is_some_and(f64::is_finite));
    assert_eq!(s["allan"]["samples_used"], 3000);
    for f in [
        "index.html",
        "fig3_denoised.svg",
        "fig5_drift.svg",
        "allan.svg",
        "error_vs_truth.svg",
    ] {
        assert!(rep.join(f).is_file(), "{f}");
    }
}

/// E-Core frames of `counts`, raw bytes varying.
fn frames(counts: &[i16]) -> Vec<u8> {
    counts
        .iter()
        .enumerate()
        .flat_map(|(i, &c)| ecore::encode(c, [i as u8 & 0x7f, 1, 2, 3]))
        .collect()
}

fn counts_of(x: &[f64]) -> Vec<i16> {
    x.iter()
        .map(|&v| (v * 32768.0 / 60.0).round() as i16)
        .collect()
}

fn replay_bin(dir: &Path, bytes: &[u8], extra: &[&str]) -> (Vec<Out>, serde_json::Value, String) {
    let input = dir.join("cap.bin");
    fs::write(&input, bytes).expect("write");
    let output = dir.join("out.csv");
    let rep = dir.join("rep");
    let a = host_sim()
        .args(["replay", "--preset", "level-trend", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&output)
        .arg("--report")
        .arg(&rep)
        .args(extra)
        .assert()
        .success();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    (read_output(&output), summary(&rep), err)
}

#[test]
fn ecore_binary_replay_matches_the_identifier() {
    let dir = tempfile::tempdir().expect("tmp");
    let c = counts_of(&rates(1200));
    let (out, s, err) = replay_bin(dir.path(), &frames(&c), &[]);
    assert_eq!(s["format"], "ecore-bin", "auto-detected");
    let x: Vec<f32> = c.iter().map(|&k| f32::from(k) * (60.0 / 32768.0)).collect();
    assert_eq!(check_against_direct(&out, &x, false), 0);
    for (k, o) in out.iter().enumerate() {
        assert_eq!(o.t_s, k as f64 / 100.0, "t_s = index / rate_hz");
    }
    assert_eq!(s["bytes"]["bytes_total"], 9600);
    assert_eq!(s["bytes"]["bytes_dropped"], 0);
    assert!(s["bytes"]["tail"].is_null());
    assert!(
        err.contains("9600 read, 9600 in good frames, 0 dropped"),
        "{err}"
    );
}

#[test]
fn capture_cut_mid_frame_is_counted_with_its_offset() {
    let dir = tempfile::tempdir().expect("tmp");
    let c = counts_of(&rates(700));
    let mut bytes = frames(&c);
    bytes.extend_from_slice(&ecore::encode(123, [0; 4])[..5]);
    let (out, s, err) = replay_bin(dir.path(), &bytes, &["--format", "ecore-bin"]);
    assert_eq!(out.len(), 700);
    assert_eq!(s["bytes"]["tail"]["bytes"], 5);
    assert_eq!(s["bytes"]["tail"]["offset"], 5600);
    assert_eq!(s["bytes"]["skipped"]["incomplete"], 5);
    assert_eq!(s["bytes"]["frames_bad"], 1);
    assert!(
        err.contains("ends inside a frame: 5 bytes from byte offset 5600 dropped (incomplete)"),
        "{err}"
    );
    let html = fs::read_to_string(dir.path().join("rep/index.html")).expect("html");
    assert!(html.contains("5 bytes from byte offset 5600 dropped"));
}

#[test]
fn corrupted_bytes_are_counted_exactly() {
    let dir = tempfile::tempdir().expect("tmp");
    let c = counts_of(&rates(600));
    let good = frames(&c);
    let f = |i: usize| good[8 * i..8 * i + 8].to_vec();
    let mut bytes = Vec::new();
    // Frames 0..100 good; 3 noise bytes (no sync); frame 100 with a payload bit flipped
    // (checksum, 8 bytes); frame 101 cut after 4 bytes by frame 102 (cut short, 4 bytes);
    // the rest good.
    for i in 0..100 {
        bytes.extend(f(i));
    }
    let noise_at = bytes.len() as u64;
    bytes.extend([0x11, 0x22, 0x33]);
    let mut bad = f(100);
    bad[3] ^= 0x04;
    bytes.extend(bad);
    bytes.extend(&f(101)[..4]);
    for i in 102..600 {
        bytes.extend(f(i));
    }
    let (out, s, err) = replay_bin(dir.path(), &bytes, &[]);
    // What the decoder itself counts on the same bytes.
    let mut d = EcoreDecoder::new(60.0).expect("decoder");
    for &b in &bytes {
        let _ = d.push(b);
    }
    d.flush();
    let st: ByteStats = *d.stats();
    assert_eq!(st.skipped.no_sync, 3);
    assert_eq!(st.skipped.checksum, 8);
    assert_eq!(st.skipped.cut_short, 4);
    assert_eq!(st.frames_good, 598);
    assert_eq!(st.frames_bad, 2);
    let b = &s["bytes"];
    assert_eq!(b["bytes_total"], st.bytes_total);
    assert_eq!(b["bytes_total"], bytes.len() as u64);
    assert_eq!(b["bytes_good"], st.bytes_good);
    assert_eq!(b["bytes_dropped"], 15);
    assert_eq!(b["skipped"]["no_sync"], st.skipped.no_sync);
    assert_eq!(b["skipped"]["checksum"], st.skipped.checksum);
    assert_eq!(b["skipped"]["cut_short"], st.skipped.cut_short);
    assert_eq!(b["skipped"]["incomplete"], 0);
    assert_eq!(b["frames_good"], st.frames_good);
    assert_eq!(b["frames_bad"], st.frames_bad);
    assert_eq!(b["first_drop_at_byte"], noise_at);
    assert_eq!(out.len(), 598);
    assert_eq!(out[100].index, 100, "the damaged frames take no index");
    assert!(
        err.contains("15 dropped (no sync 3, checksum 8, cut short 4,"),
        "{err}"
    );
}

fn dsp_line(v: f64, status: char) -> String {
    let l = format!("{v:>15.6}   {status}\r\n");
    assert_eq!(l.len(), 21);
    l
}

#[test]
fn dsp3000_lines_with_faults() {
    let dir = tempfile::tempdir().expect("tmp");
    let x = rates(1100);
    let mut text = String::new();
    let mut fed = Vec::new();
    let faults = [10usize, 600, 601];
    for (i, &v) in x.iter().enumerate() {
        if faults.contains(&i) {
            text.push_str(&dsp_line(v, '0'));
        } else {
            text.push_str(&dsp_line(v, '1'));
            let printed = format!("{v:.6}");
            fed.push((i, printed.parse::<f32>().expect("f32")));
        }
    }
    let (out, s, err) = replay_bin(dir.path(), text.as_bytes(), &[]);
    assert_eq!(s["format"], "dsp3000");
    assert_eq!(s["fault_lines"], 3);
    assert_eq!(s["bytes"]["frames_fault"], 3);
    assert_eq!(s["bytes"]["frames_good"], 1097);
    assert_eq!(s["bytes"]["bytes_dropped"], 0);
    assert!(err.contains("3 DSP-3000 fault lines"), "{err}");
    let xs: Vec<f32> = fed.iter().map(|p| p.1).collect();
    assert_eq!(check_against_direct(&out, &xs, false), 0);
    for (o, &(i, _)) in out.iter().zip(&fed) {
        assert_eq!(o.index, i as u64, "fault lines keep their slot");
        assert_eq!(o.t_s, i as f64 / 100.0);
    }
}

#[test]
fn nan_in_csv_is_a_one_line_error_and_leaves_nothing() {
    let dir = tempfile::tempdir().expect("tmp");
    let x = rates(100);
    let mut s = String::from("t_s,rate_dps\n");
    for (i, v) in x.iter().enumerate() {
        if i == 40 {
            s.push_str(&format!("{:.2},NaN\n", i as f64 * 0.01));
        } else {
            s.push_str(&format!("{:.2},{v}\n", i as f64 * 0.01));
        }
    }
    let input = dir.path().join("nan.csv");
    fs::write(&input, s).expect("write");
    let output = dir.path().join("out.csv");
    let rep = dir.path().join("rep");
    let a = host_sim()
        .args(["replay", "--preset", "level-trend", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&output)
        .arg("--report")
        .arg(&rep)
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("nan.csv:42:"), "{err}");
    assert!(err.contains("not finite"), "{err}");
    assert!(!output.exists(), "no output file");
    assert!(!rep.exists(), "no report");
    let left: Vec<_> = fs::read_dir(dir.path())
        .expect("dir")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(left.len(), 1, "only the input remains: {left:?}");
}

#[test]
fn refuses_to_overwrite_the_input() {
    let dir = tempfile::tempdir().expect("tmp");
    let input = write_csv(dir.path(), &rates(100), false);
    let before = fs::read(&input).expect("read");
    host_sim()
        .args(["replay", "--preset", "level-trend", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&input)
        .assert()
        .failure();
    assert_eq!(fs::read(&input).expect("read"), before);
}

/// A `.csv.gz` record is a CSV for `replay` in both paths (the motion preset and the
/// streaming references): the same output as the plain CSV, byte for byte. Gzip data not
/// named `*.gz` is refused with one line, not taken for a binary capture.
#[test]
fn a_gzipped_csv_replays_as_the_csv() {
    use std::io::Write;
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let csv = write_csv(d, &rates(3000), false);
    let text = fs::read(&csv).expect("test");
    let gz = d.join("rec.csv.gz");
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(&text).expect("test");
    fs::write(&gz, e.finish().expect("test")).expect("test");
    for preset in [None, Some("level-trend")] {
        let run = |input: &Path, out: &Path| {
            let mut c = host_sim();
            c.arg("replay");
            if let Some(p) = preset {
                c.args(["--preset", p]);
            }
            c.arg("--input").arg(input).arg("--output").arg(out);
            c.assert().success();
            fs::read(out).expect("test")
        };
        let plain = run(&csv, &d.join("plain.csv"));
        let zipped = run(&gz, &d.join("zipped.csv"));
        assert!(plain.len() > 3000 * 10, "{preset:?}");
        assert_eq!(plain, zipped, "{preset:?}");
    }
    let misnamed = d.join("rec.bin");
    fs::copy(&gz, &misnamed).expect("test");
    host_sim()
        .args(["replay", "--input"])
        .arg(&misnamed)
        .arg("--output")
        .arg(d.join("bad.csv"))
        .assert()
        .failure()
        .stderr(predicates::str::contains(
            "gzip data: only a compressed CSV is read",
        ));
    assert!(!d.join("bad.csv").exists());
}

/// Without truth the motion report still shows the heading: `heading_correction.svg`, the
/// integral of the drift estimate, whose end the caption states and which equals the raw
/// minus the compensated angle of the summary.
#[test]
fn the_report_shows_the_heading_without_truth() {
    let dir = tempfile::tempdir().expect("test");
    let d = dir.path();
    let csv = write_csv(d, &rates(6000), false);
    let rep = d.join("report");
    host_sim()
        .args(["replay", "--input"])
        .arg(&csv)
        .arg("--output")
        .arg(d.join("out.csv"))
        .arg("--report")
        .arg(&rep)
        .assert()
        .success();
    let svg = fs::read_to_string(rep.join("heading_correction.svg")).expect("svg");
    assert!(svg.contains("heading correction (deg)"));
    assert!(
        !svg.contains("integral of the true drift"),
        "no truth in the record"
    );
    let s: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(rep.join("summary.json")).expect("json"))
            .expect("json");
    let end = s["raw_angle_end_deg"].as_f64().expect("raw")
        - s["compensated_angle_end_deg"]
            .as_f64()
            .expect("compensated");
    assert!(end.abs() > 1e-3, "the record drifts: {end}");
    let html = fs::read_to_string(rep.join("index.html")).expect("html");
    assert!(
        html.contains(&format!("({end:.4} deg at the end)")),
        "caption states {end:.4}"
    );
}

/// The motion replay streams: it takes the rate from the first 2^16 samples (the
/// look-ahead) and checks the whole record's mean step at the end. A record whose stamps
/// slow down after the look-ahead (100 Hz, then one sample a second: 13.7 Hz over the whole
/// record) is refused, naming both rates, and no output is left.
#[test]
fn a_rate_that_changes_after_the_look_ahead_is_refused_at_the_end() {
    let dir = tempfile::tempdir().expect("tempdir");
    let n = 70_000usize;
    let x = rates(n);
    let mut text = String::from("t_s,rate_dps\n");
    for (k, r) in x.iter().enumerate() {
        let t = if k < 1 << 16 {
            k as f64 * 0.01
        } else {
            655.36 + (k - (1 << 16)) as f64
        };
        text += &format!("{t},{r}\n");
    }
    let input = dir.path().join("slowing.csv");
    fs::write(&input, text).expect("write");
    let out = dir.path().join("out.csv");
    host_sim()
        .args(["replay", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&out)
        .assert()
        .failure()
        .stderr(predicates::str::contains("over the whole record"))
        .stderr(predicates::str::contains(
            "the first 65536 samples gave 100 Hz",
        ));
    assert!(!out.exists(), "no output after the refusal");
    let left: Vec<_> = fs::read_dir(dir.path())
        .expect("dir")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
}
