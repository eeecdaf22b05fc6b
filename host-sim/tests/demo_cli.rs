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
            .args(["demo", "--quick", "--report"])
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
    // The model's two scales and the Gauss-Markov correlation time, tuned on the tune
    // vehicles (never "validation": they are not the records the result is scored on).
    let tuning = &s["level_tuning"];
    assert_eq!(tuning["grid"].as_array().expect("grid").len(), 32);
    finite(&tuning["picked"], "heading_rms_deg");
    assert!(
        stderr.contains("demo: tuned on 2 vehicle records:"),
        "{stderr}"
    );
    let html = fs::read_to_string(dir.join("index.html")).expect("index.html");
    assert!(html.contains("tuned on the tune vehicles"));
    assert!(!html.contains("validation vehicle"), "index.html");
    assert!(!stderr.contains("validation vehicle"), "{stderr}");
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

/// A verdict line, `fog loses: X deg against Y deg for the best baseline (P %), NAME`:
/// (verdict, X, Y, P, NAME).
fn parse_verdict(line: &str) -> (String, f64, f64, f64, String) {
    let (verdict, rest) = line.trim().split_once(": ").expect("verdict: ...");
    let words: Vec<&str> = rest.split_whitespace().collect();
    assert_eq!(
        (words[1], words[2], words[4]),
        ("deg", "against", "deg"),
        "{line}"
    );
    let num = |w: &str| {
        w.parse::<f64>()
            .unwrap_or_else(|_| panic!("{w:?} in {line}"))
    };
    let (_, after) = rest.split_once(" (").expect("(P %)");
    let (pct, name) = after.split_once(" %), ").expect("P %), NAME");
    (
        verdict.to_string(),
        num(words[0]),
        num(words[3]),
        num(pct),
        name.to_string(),
    )
}

/// `fog is below every baseline on K of N test vehicles`: (K, N).
fn parse_count(line: &str) -> (u64, u64) {
    let w: Vec<&str> = line.split_whitespace().collect();
    let i = w.iter().position(|x| *x == "on").expect("on K of N");
    assert_eq!(w[i + 2], "of", "{line}");
    (w[i + 1].parse().expect("K"), w[i + 3].parse().expect("N"))
}

/// What the JSON's per-record figures say: (identifier's mean, best baseline and its
/// mean, verdict, records below every baseline, records), recomputed here.
fn pooled_from_json(t: &serde_json::Value) -> (f64, String, f64, &'static str, u64, u64) {
    let per = t["heading_rms_deg"].as_array().expect("per record");
    let n = per.len();
    let names: Vec<String> = per[0]
        .as_array()
        .expect("row")
        .iter()
        .map(|p| p[0].as_str().expect("name").to_string())
        .collect();
    let v = |r: &serde_json::Value, k: usize| r[k][1].as_f64().expect("value");
    let mean: Vec<f64> = (0..names.len())
        .map(|k| per.iter().map(|r| v(r, k)).sum::<f64>() / n as f64)
        .collect();
    // The JSON's means are these.
    for (k, m) in t["mean_heading_rms_deg"]
        .as_array()
        .expect("mean")
        .iter()
        .enumerate()
    {
        assert_eq!(m[0].as_str(), Some(names[k].as_str()));
        assert!((m[1].as_f64().expect("mean") - mean[k]).abs() < 1e-12);
    }
    let baselines: Vec<usize> = (1..names.len())
        .filter(|&k| names[k] != "no compensation")
        .collect();
    let best = *baselines
        .iter()
        .min_by(|&&a, &&b| mean[a].total_cmp(&mean[b]))
        .expect("a baseline");
    let below = per
        .iter()
        .filter(|r| baselines.iter().all(|&k| v(r, 0) < v(r, k)))
        .count() as u64;
    let verdict = if mean[0] < mean[best] {
        "fog wins"
    } else {
        "fog loses"
    };
    (
        mean[0],
        names[best].clone(),
        mean[best],
        verdict,
        below,
        n as u64,
    )
}

/// The printed headline and index.html's lead with the pooled result over every test
/// vehicle, and say what the JSON's per-record figures say; the example record comes after.
#[test]
fn demo_leads_with_the_pooled_result_of_its_json() {
    let (dir, _, stderr) = demo();
    let s: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.join("summary.json")).expect("summary"))
            .expect("json");
    let t = &s["test_set"];
    let (id_mean, best, best_mean, verdict, below, n) = pooled_from_json(t);
    let check = |verdict_line: &str, count_line: &str, what: &str| {
        let (v, x, y, pct, name) = parse_verdict(verdict_line);
        assert_eq!(v, verdict, "{what}: {verdict_line}");
        assert!((x - id_mean).abs() <= 5e-5, "{what}: {x} vs {id_mean}");
        assert!((y - best_mean).abs() <= 5e-5, "{what}: {y} vs {best_mean}");
        assert_eq!(name, best, "{what}");
        let p = 100.0 * (id_mean / best_mean - 1.0);
        assert!((pct - p).abs() <= 0.05 + 1e-9, "{what}: {pct} vs {p}");
        assert_eq!(parse_count(count_line), (below, n), "{what}: {count_line}");
    };
    // Printed: the result before the example record (and before any score of it).
    let lines: Vec<&str> = stderr.lines().collect();
    let at = |p: &str| lines.iter().position(|l| l.contains(p));
    let result = at("demo: result over ").expect("result line");
    assert!(lines[result].contains(&format!("over {n} test vehicles")));
    let example = at("demo: example record:").expect("example line");
    let record = at("heading error RMS: motion identifier").expect("record's headline");
    assert!(result < example && example < record, "{stderr}");
    let verdict_line = lines[result + 1].trim_start_matches("demo:");
    let count_line = lines[result + 2];
    check(verdict_line, count_line, "stderr");
    // Each estimator's mean and fog's difference from it, as in the JSON.
    for m in t["mean_heading_rms_deg"]
        .as_array()
        .expect("mean")
        .iter()
        .skip(1)
    {
        let name = m[0].as_str().expect("name");
        let mean = m[1].as_f64().expect("mean");
        let row = lines[result..example]
            .iter()
            .find(|l| l.trim_start_matches("demo:").trim_start().starts_with(name))
            .unwrap_or_else(|| panic!("{name} in the result"));
        let w: Vec<&str> = row.split_whitespace().collect();
        let printed: f64 = w[w.len() - 3].parse().expect("mean");
        let pct: f64 = w[w.len() - 2].parse().expect("pct");
        assert!((printed - mean).abs() <= 5e-5, "{row}");
        assert!(
            (pct - 100.0 * (id_mean / mean - 1.0)).abs() <= 0.05 + 1e-9,
            "{row}"
        );
    }
    // The JSON states the same verdict.
    let h = &t["headline"];
    assert_eq!(h["verdict"], verdict);
    assert_eq!(h["best_baseline"], best.as_str());
    assert_eq!(h["below_every_baseline"].as_u64(), Some(below));
    assert_eq!(h["records"].as_u64(), Some(n));
    // index.html: the same two lines lead the page, before the example record's scores.
    let html = fs::read_to_string(dir.join("index.html")).expect("index.html");
    let start = html
        .find("<p class=\"headline\">")
        .expect("headline paragraph");
    let end = start + html[start..].find("</p>").expect("end");
    let text = html[start..end]
        .replace("<p class=\"headline\">", "")
        .replace("<strong>", "")
        .replace("</strong>", "")
        .replace("&amp;", "&")
        .replace("&#39;", "'")
        .replace("&quot;", "\"");
    let parts: Vec<&str> = text.split("<br>").collect();
    assert_eq!(parts.len(), 3, "{text}");
    assert!(
        parts[0].contains(&format!("over {n} test vehicles")),
        "{text}"
    );
    check(parts[1], parts[2], "index.html");
    let example = html.find("Example record").expect("example record");
    let record = html
        .find("heading error RMS: motion identifier")
        .expect("record's headline");
    assert!(start < example && example < record, "headline first");
    assert!(start < html.find("<svg").expect("svg"));
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
