//! `host-sim demo --quick` (the CI variant: 12 static training records and a vehicle record
//! of 600 s instead of 1800 s): the report folder it writes, and that its page loads in a
//! browser.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const SVGS: [&str; 4] = [
    "heading_error.svg",
    "drift.svg",
    "heading_correction.svg",
    "rate.svg",
];

/// Runs the demo once for every test of this file; returns its folder and stdout.
fn demo() -> &'static (PathBuf, String, String) {
    static DEMO: OnceLock<(PathBuf, String, String)> = OnceLock::new();
    DEMO.get_or_init(|| {
        // A folder of this run's own under target/tmp (`demo_cli-XXXXXX`; a debug and a
        // release run share target/tmp), kept for inspection: `cargo clean` removes it.
        let out = tempfile::Builder::new()
            .prefix("demo_cli-")
            .tempdir_in(env!("CARGO_TARGET_TMPDIR"))
            .expect("a folder under target/tmp")
            .keep();
        let a = Command::cargo_bin("host-sim")
            .expect("binary built")
            .args(["demo", "--quick", "--out"])
            .arg(&out)
            .assert()
            .success();
        let stdout = String::from_utf8_lossy(&a.get_output().stdout).to_string();
        let stderr = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        (out, stdout, stderr)
    })
}

fn finite(v: &serde_json::Value, path: &str) -> f64 {
    let x = path
        .split('.')
        .fold(v, |v, k| &v[k])
        .as_f64()
        .unwrap_or(f64::NAN);
    assert!(x.is_finite(), "{path} = {x}");
    x
}

#[test]
fn demo_writes_the_report() {
    let (dir, stdout, stderr) = demo();
    let index = dir.join("index.html");
    assert_eq!(
        stdout.trim(),
        index.display().to_string(),
        "prints index.html"
    );
    for f in SVGS {
        let svg = fs::read_to_string(dir.join(f)).expect(f);
        assert!(svg.contains("<svg") && svg.contains("</svg>"), "{f}");
    }
    assert_eq!(
        fs::metadata(dir.join("identifier.fogi"))
            .expect("image")
            .len(),
        fog_core::image::IMAGE_LEN as u64
    );
    let s: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.join("summary.json")).expect("summary"))
            .expect("json");
    assert_eq!(s["rows"], 60_000);
    // The model's two scales, tuned on the validation vehicles.
    let tuning = &s["level_tuning"];
    assert_eq!(tuning["grid"].as_array().expect("grid").len(), 16);
    finite(&tuning["picked"], "heading_rms_deg");
    assert!(
        stderr.contains("demo: tuned on 2 vehicle records:"),
        "{stderr}"
    );
    assert!(fs::read_to_string(dir.join("index.html"))
        .expect("index.html")
        .contains("tuned on validation vehicles"));
    assert_eq!(s["trained_runs"], 12, "12 calibration runs");
    // The test set: the identifier and the five baselines over 2 vehicles (--quick).
    let t = &s["test_set"];
    assert_eq!(
        t["heading_rms_deg"].as_array().expect("per record").len(),
        2
    );
    let mean = t["mean_heading_rms_deg"].as_array().expect("mean");
    assert_eq!(mean.len(), 6);
    assert_eq!(mean[0][0], "motion identifier");
    assert!(mean
        .iter()
        .all(|m| m[1].as_f64().is_some_and(|v| v.is_finite() && v > 0.0)));
    assert!(t["identifier_best"].as_u64().is_some_and(|n| n <= 2));
    let rows = s["scores"]["rows"].as_array().expect("scores");
    assert_eq!(rows.len(), 6, "identifier and five baselines");
    assert_eq!(rows[0]["name"], "motion identifier");
    for (i, r) in rows.iter().enumerate() {
        finite(r, "scores.heading_rms_deg");
        finite(r, "scores.heading_final_deg");
        if i != 1 {
            // Every compensation beats none on a vehicle record.
            assert!(
                r["scores"]["heading_rms_deg"].as_f64()
                    < rows[1]["scores"]["heading_rms_deg"].as_f64(),
                "{r}"
            );
        }
    }
    let det = &s["scores"]["detector"];
    assert!(
        det["moving_samples"].as_u64().expect("n") > 10_000,
        "a vehicle that moves"
    );
    finite(det, "false_still_rate");
    finite(det, "missed_still_rate");
    let html = fs::read_to_string(&index).expect("index.html");
    assert_eq!(html.matches("<svg").count(), SVGS.len(), "SVGs inlined");
    let head = html
        .find("heading error RMS: motion identifier")
        .expect("headline");
    assert!(head < html.find("<svg").expect("svg"), "headline first");
    assert!(!html.contains("<script"));
}

fn find_browser() -> Option<PathBuf> {
    let names = [
        "chromium",
        "chromium-browser",
        "google-chrome",
        "google-chrome-stable",
    ];
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .flat_map(|d| names.iter().map(move |n| d.join(n)))
        .find(|p| p.is_file())
}

/// Runs the browser with its output in files (a pipe would fill up and block it); returns
/// stdout and stderr.
fn headless(browser: &Path, profile: &Path, extra: &[&str], url: &str) -> (String, String) {
    let out_path = profile.with_extension("stdout");
    let err_path = profile.with_extension("stderr");
    let mut child = std::process::Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        // Its HOME too (certificate store, crash reports): nothing shared with another run.
        .env("HOME", profile)
        .args(extra)
        .arg(url)
        .stdin(Stdio::null())
        .stdout(fs::File::create(&out_path).expect("stdout file"))
        .stderr(fs::File::create(&err_path).expect("stderr file"))
        .spawn()
        .expect("browser starts");
    let start = Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{} did not finish in 30 s", browser.display());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let read = |p: &Path| String::from_utf8_lossy(&fs::read(p).unwrap_or_default()).to_string();
    let r = (read(&out_path), read(&err_path));
    let _ = fs::remove_file(&out_path);
    let _ = fs::remove_file(&err_path);
    r
}

#[test]
fn index_html_loads_in_headless_chromium() {
    let Some(browser) = find_browser() else {
        eprintln!(
            "SKIPPED: no chromium / chrome on PATH (scripts/setup.sh installs Debian's chromium)"
        );
        return;
    };
    let (dir, _, _) = demo();
    let index = dir.join("index.html").canonicalize().expect("path");
    let url = format!("file://{}", index.display());
    let profile = tempfile::tempdir().expect("tmp");
    let (dom, log) = headless(&browser, profile.path(), &["--dump-dom"], &url);
    assert!(
        dom.contains("<h1>"),
        "page rendered: {}",
        &dom[..dom.len().min(500)]
    );
    assert_eq!(
        dom.matches("<svg").count(),
        SVGS.len(),
        "every figure in the DOM"
    );
    assert!(
        dom.contains("<polyline") || dom.contains("<path"),
        "plots drawn"
    );
    for line in log.lines() {
        let l = line.to_ascii_lowercase();
        assert!(
            !(l.contains("uncaught") || (l.contains("console") && l.contains("error"))),
            "browser console: {line}"
        );
        assert!(
            !l.contains("err_file_not_found"),
            "missing resource: {line}"
        );
    }
    let png = profile.path().join("shot.png");
    let shot = format!("--screenshot={}", png.display());
    let profile2 = tempfile::tempdir().expect("tmp");
    let _ = headless(
        &browser,
        profile2.path(),
        &[&shot, "--window-size=1000,3000"],
        &url,
    );
    let bytes = fs::read(&png).expect("screenshot written");
    assert!(bytes.starts_with(b"\x89PNG"), "a PNG");
    assert!(bytes.len() > 20_000, "not blank: {} bytes", bytes.len());
}
