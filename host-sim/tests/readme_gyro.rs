//! The README's gyro-file example runs as written: its `mygyro.toml` block is written to a
//! folder and every command of the `sh` block after it runs there (`host-sim` is the built
//! binary; the old files `gyro convert` reads are the former built-ins), then what the text
//! says of them is checked.

use std::fs;
use std::path::Path;
use std::process::{Command, Stdio};

/// The first fenced block of `lang` after `from` in `text`.
fn block<'a>(text: &'a str, from: &str, lang: &str) -> &'a str {
    let at = text.find(from).expect("the README section");
    let rest = &text[at..];
    let open = format!("```{lang}\n");
    let start = rest.find(&open).expect("a block") + open.len();
    let len = rest[start..].find("```").expect("a closed block");
    &rest[start..start + len]
}

/// The block's commands: continuation lines joined, comments and blank lines left out.
fn commands(sh: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for line in sh.lines() {
        let code = match line.find(" #") {
            Some(i) => &line[..i],
            None if line.trim_start().starts_with('#') => "",
            None => line,
        };
        let code = code.trim_end();
        if let Some(head) = code.strip_suffix('\\') {
            cur.push_str(head);
            cur.push(' ');
            continue;
        }
        cur.push_str(code);
        if !cur.trim().is_empty() {
            out.push(cur.trim().to_string());
        }
        cur.clear();
    }
    out
}

#[test]
fn the_readme_gyro_file_example_runs_as_written() {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = fs::read_to_string(manifest.join("../README.md")).expect("README.md");
    let section = "### The gyro file: `--gyro NAME|FILE`";
    let toml = block(&readme, section, "toml");
    let sh = block(&readme, section, "sh");
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    fs::write(d.join("mygyro.toml"), toml).expect("mygyro.toml");
    let old = manifest.join("tests/data/old-format");
    fs::copy(old.join("sensor-ecore2000.toml"), d.join("old-sensor.toml")).expect("copy");
    fs::copy(old.join("model-ecore2000.toml"), d.join("old-model.toml")).expect("copy");
    let bin = assert_cmd::cargo::cargo_bin("host-sim");
    let cmds = commands(sh);
    assert!(cmds.len() >= 10, "{cmds:?}");
    for c in &cmds {
        let (c, redirect) = match c.split_once(" > ") {
            Some((a, f)) => (a, Some(f.trim())),
            None => (c.as_str(), None),
        };
        let mut words = c.split_whitespace();
        assert_eq!(words.next(), Some("host-sim"), "{c}");
        let mut cmd = Command::new(&bin);
        cmd.args(words).current_dir(d).stderr(Stdio::piped());
        if let Some(f) = redirect {
            cmd.stdout(fs::File::create(d.join(f)).expect("redirect"));
        } else {
            cmd.stdout(Stdio::piped());
        }
        let out = cmd.output().expect("runs");
        let err = String::from_utf8_lossy(&out.stderr);
        // mygyro is a 100 deg/s unit: beyond the firmware's E-Core decoder (60 deg/s), so
        // identify writes its image only with --force and `image` exits 1 with the verdict.
        if c.starts_with("host-sim image") {
            assert_eq!(out.status.code(), Some(1), "{c}: {err}");
            assert!(
                err.contains(
                    "firmware: does not fit: decoder full scale 60 deg/s < unit's 100 deg/s"
                ),
                "{c}: {err}"
            );
        } else {
            assert!(out.status.success(), "{c}: {err}");
        }
    }
    // What the text says: replay --gyro unit.toml is replay --identifier unit.fogi.
    let st = Command::new(&bin)
        .args(["replay", "--identifier", "unit.fogi", "--input", "run2.csv"])
        .args(["--output", "out-image.csv"])
        .current_dir(d)
        .stderr(Stdio::null())
        .status()
        .expect("runs");
    assert!(st.success());
    assert_eq!(
        fs::read(d.join("out.csv")).expect("out"),
        fs::read(d.join("out-image.csv")).expect("out")
    );
    // The shown built-in is the built-in; the merged file is the built-in's model.
    assert_eq!(
        fs::read_to_string(d.join("ecore2000.toml")).expect("shown"),
        host_sim::gyro::BUILTIN[0].2
    );
    let merged = host_sim::gyro::Gyro::load(&d.join("merged.toml")).expect("merged");
    assert_eq!(
        merged.model,
        host_sim::sim::preset("ecore2000").expect("built-in")
    );
    // No hand conversion: the README's gyro example holds no deg/s noise key.
    for bad in ["dps_per_rthz", "noise_density", "/ 60", "x 60", "* 60"] {
        assert!(!toml.contains(bad) && !sh.contains(bad), "{bad}");
    }
}
