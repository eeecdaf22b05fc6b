//! Output safety of every `host-sim` subcommand that writes: it never overwrites one of its
//! inputs (same path, a symbolic link, or a hard link: another name of the same file), and
//! it never leaves a half-written output (outputs are written to a temporary file and
//! renamed on success: a failure leaves the old file, or none, and no temporary file).

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// An interchange CSV of `n` rows at 100 Hz; row `bad_row` (0-based), if any, has a
/// non-numeric rate.
fn record(dir: &Path, name: &str, n: usize, bad_row: Option<usize>) -> PathBuf {
    let mut s = String::from("t_s,rate_dps\n");
    for i in 0..n {
        let rate = if Some(i) == bad_row {
            "oops".to_string()
        } else {
            format!("{:.6}", 0.01 + 0.002 * ((i * 7919) % 13) as f64 / 13.0)
        };
        s.push_str(&format!("{:.2},{rate}\n", i as f64 * 0.01));
    }
    let p = dir.join(name);
    fs::write(&p, s).expect("write record");
    p
}

fn model(dir: &Path) -> PathBuf {
    let p = dir.join("model.toml");
    fs::write(
        &p,
        "sample_rate_hz = 100.0\nfull_scale_dps = 60.0\narw_deg_per_rth = 0.06\n",
    )
    .expect("write model");
    p
}

/// Temporary files `write_atomic` would leave behind.
fn assert_no_tmp(dir: &Path) {
    for e in fs::read_dir(dir).expect("list").flatten() {
        let n = e.file_name().to_string_lossy().to_string();
        assert!(!n.ends_with(".tmp"), "temporary file left: {n}");
    }
}

/// The three other names an output can give to `input`: itself, a hard link, a symlink.
fn aliases(input: &Path) -> Vec<(&'static str, PathBuf)> {
    let dir = input.parent().expect("parent");
    let hard = dir.join("hard-link");
    let _ = fs::remove_file(&hard);
    fs::hard_link(input, &hard).expect("hard link");
    let mut v = vec![("same path", input.to_path_buf()), ("hard link", hard)];
    #[cfg(unix)]
    {
        let sym = dir.join("sym-link");
        let _ = fs::remove_file(&sym);
        std::os::unix::fs::symlink(input, &sym).expect("symlink");
        v.push(("symlink", sym));
    }
    // A path through `..`.
    let sub = dir.join("sub");
    fs::create_dir_all(&sub).expect("mkdir");
    v.push((
        "dot-dot",
        sub.join("..").join(input.file_name().expect("name")),
    ));
    v
}

/// Runs `args(output)` for every alias of `input` as the output: each run must fail with
/// the refusal, and `input` must keep its bytes.
fn refuses_every_alias(input: &Path, args: impl Fn(&Path) -> Vec<String>) {
    let before = fs::read(input).expect("read input");
    for (what, out) in aliases(input) {
        let a = host_sim().args(args(&out)).assert().failure();
        let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
        assert!(
            err.contains("refusing to overwrite the input file"),
            "{what}: {err}"
        );
        assert_eq!(
            fs::read(input).expect("read"),
            before,
            "{what}: input changed"
        );
    }
    assert_no_tmp(input.parent().expect("parent"));
}

fn s(p: &Path) -> String {
    p.to_string_lossy().to_string()
}

#[test]
fn denoise_refuses_its_input() {
    let d = tempfile::tempdir().expect("tmp");
    let input = record(d.path(), "in.csv", 256, None);
    refuses_every_alias(&input, |o| {
        vec![
            "denoise".into(),
            "--input".into(),
            s(&input),
            "--output".into(),
            s(o),
        ]
    });
}

#[test]
fn allan_refuses_its_input() {
    let d = tempfile::tempdir().expect("tmp");
    let input = record(d.path(), "in.csv", 256, None);
    let json = d.path().join("a.json");
    refuses_every_alias(&input, |o| {
        vec![
            "allan".into(),
            "--input".into(),
            s(&input),
            "--json".into(),
            s(o),
        ]
    });
    refuses_every_alias(&input, |o| {
        let v = [
            "allan",
            "--input",
            &s(&input),
            "--json",
            &s(&json),
            "--svg",
            &s(o),
        ];
        v.iter().map(|x| x.to_string()).collect()
    });
}

#[test]
fn simulate_refuses_its_model() {
    let d = tempfile::tempdir().expect("tmp");
    let m = model(d.path());
    refuses_every_alias(&m, |o| {
        let v = [
            "simulate",
            "--gyro",
            &s(&m),
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--output",
            &s(o),
        ];
        v.iter().map(|x| x.to_string()).collect()
    });
}

#[test]
fn identify_refuses_its_records() {
    let d = tempfile::tempdir().expect("tmp");
    let train = record(d.path(), "train.csv", 256, None);
    let validate = record(d.path(), "validate.csv", 256, None);
    for input in [&train, &validate] {
        refuses_every_alias(input, |o| {
            let v = [
                "identify",
                "--preset",
                "level-trend",
                "--train",
                &s(&train),
                "--validate",
                &s(&validate),
                "--block",
                "64",
                "--json",
                &s(o),
            ];
            v.iter().map(|x| x.to_string()).collect()
        });
    }
}

#[test]
fn replay_refuses_its_input() {
    let d = tempfile::tempdir().expect("tmp");
    let input = record(d.path(), "in.csv", 256, None);
    refuses_every_alias(&input, |o| {
        vec![
            "replay".into(),
            "--input".into(),
            s(&input),
            "--output".into(),
            s(o),
        ]
    });
}

#[test]
fn gap_refuses_its_inputs() {
    let d = tempfile::tempdir().expect("tmp");
    let real = record(d.path(), "real.csv", 256, None);
    let m = model(d.path());
    refuses_every_alias(&real, |o| {
        vec![
            "gap".into(),
            "--input".into(),
            s(&real),
            "--json".into(),
            s(o),
        ]
    });
    refuses_every_alias(&m, |o| {
        let v = [
            "gap",
            "--input",
            &s(&real),
            "--gyro",
            &s(&m),
            "--json",
            &s(o),
        ];
        v.iter().map(|x| x.to_string()).collect()
    });
    // A report folder whose index.html is the real record (by hard link).
    let report = d.path().join("report");
    fs::create_dir_all(&report).expect("mkdir");
    fs::hard_link(&real, report.join("index.html")).expect("link");
    let before = fs::read(&real).expect("read");
    let a = host_sim()
        .args([
            "gap",
            "--input",
            &s(&real),
            "--json",
            &s(&d.path().join("g.json")),
        ])
        .args(["--report", &s(&report)])
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(
        err.contains("refusing to overwrite the input file"),
        "{err}"
    );
    assert_eq!(fs::read(&real).expect("read"), before);
}

/// A failure while the output is being streamed (replay writes one row per sample as it
/// reads) leaves the previous output file intact and no temporary file.
#[test]
fn replay_failing_midway_leaves_the_old_output() {
    let d = tempfile::tempdir().expect("tmp");
    let input = record(d.path(), "in.csv", 3000, Some(2500));
    let out = d.path().join("out.csv");
    fs::write(&out, "previous content\n").expect("write");
    let a = host_sim()
        .args(["replay", "--input", &s(&input), "--output", &s(&out)])
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(err.contains(":2502:"), "names the bad line: {err}");
    assert_eq!(
        fs::read_to_string(&out).expect("read"),
        "previous content\n"
    );
    assert_no_tmp(d.path());
    // Without an old file, none is created.
    fs::remove_file(&out).expect("rm");
    host_sim()
        .args(["replay", "--input", &s(&input), "--output", &s(&out)])
        .assert()
        .failure();
    assert!(!out.exists(), "half-written output left");
    assert_no_tmp(d.path());
}

/// A failing `identify` (bad row in a validation record, found after training) writes
/// nothing; a failing `simulate` into an existing file keeps it.
#[test]
fn failing_runs_write_nothing() {
    let d = tempfile::tempdir().expect("tmp");
    let train = record(d.path(), "train.csv", 600, None);
    let bad = record(d.path(), "bad.csv", 600, Some(500));
    let json = d.path().join("id.json");
    let a = host_sim()
        .args(["identify", "--preset", "level-trend", "--train", &s(&train)])
        .args(["--validate", &s(&bad)])
        .args(["--block", "256", "--json", &s(&json)])
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(err.contains("bad.csv:502:"), "{err}");
    assert!(!json.exists());
    assert_no_tmp(d.path());
}

/// SIGTERM and SIGINT (Ctrl-C) in the middle of a long `simulate`: the temporary file is
/// removed, no output appears, and the exit status is 130.
#[cfg(unix)]
#[test]
fn an_interrupted_command_leaves_no_temporary_file() {
    use std::time::{Duration, Instant};
    for signal in ["-TERM", "-INT"] {
        let d = tempfile::tempdir().expect("tmp");
        let out = d.path().join("long.csv");
        let bin = assert_cmd::cargo::cargo_bin("host-sim");
        let mut child = std::process::Command::new(bin)
            .args(["simulate", "--gyro", "ecore2000", "--seed", "1"])
            .args(["--duration-s", "2e5", "--output"])
            .arg(&out)
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("spawn");
        // Wait until the temporary file exists and grows.
        let start = Instant::now();
        let tmp_size = || {
            fs::read_dir(d.path())
                .expect("list")
                .flatten()
                .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
                .filter_map(|e| e.metadata().ok())
                .map(|m| m.len())
                .next()
        };
        while tmp_size().is_none_or(|n| n < 100_000) {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "no temporary file appeared"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let status = std::process::Command::new("kill")
            .arg(signal)
            .arg(child.id().to_string())
            .status()
            .expect("kill");
        assert!(status.success());
        let code = child.wait().expect("wait").code();
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().expect("stderr"), &mut err)
            .expect("stderr");
        assert_eq!(code, Some(130), "{signal}: exit status; stderr: {err}");
        assert!(err.contains("interrupted"), "{signal}: {err}");
        assert!(!out.exists(), "{signal}: no output");
        assert_no_tmp(d.path());
    }
}
