//! One vocabulary of flags across host-sim's commands (issue 44): every command's `--help`
//! is parsed and its visible flags checked against one table (the vocabulary in README.md,
//! "Flags: one vocabulary"): the same concept has the same name everywhere, no visible flag
//! is outside the table, and every number with a physical unit carries it in its name (or
//! its help states it, for the few that also take words). The old names stay accepted as
//! hidden aliases for one release (CHANGELOG, Unreleased).

use assert_cmd::Command;
use std::collections::BTreeMap;

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").expect("binary built")
}

/// Every command with flags (`gyro show` takes a positional only).
const COMMANDS: &[&str] = &[
    "denoise",
    "simulate",
    "allan",
    "identify",
    "image",
    "reproduce",
    "replay",
    "demo",
    "gap",
    "gap-bench",
    "gyro convert",
    "gyro show",
];

/// What a flag's value is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// A file or folder read (`--input`, and the record sets named by their role).
    Read,
    /// A data file written (`--output`).
    Output,
    /// A report folder written (`--report`).
    Report,
    /// A JSON report written (`--json`; optional where a summary can go to stdout).
    Json,
    /// A figure written.
    Figure,
    /// A file a later command takes (`--save-*`).
    Save,
    /// A seed.
    Seed,
    /// A count of what the name says (plural noun, never `--seeds`).
    Count,
    /// A physical quantity: the name ends with its unit.
    Physical,
    /// A number without unit, or a word or a number whose unit the help states: the
    /// reason, checked in the help text.
    Documented(&'static str),
    /// A word from a list, a column name, a list of words, a gyro name or file.
    Word,
    /// A switch.
    Switch,
}

/// The vocabulary: each visible flag name and what it is (one meaning per name).
const VOCABULARY: &[(&str, Kind)] = &[
    ("--input", Kind::Read),
    ("--train", Kind::Read),
    ("--validate", Kind::Read),
    ("--tune-on", Kind::Read),
    ("--unit-runs", Kind::Read),
    ("--identifier", Kind::Read),
    ("--gyro", Kind::Word),
    ("--output", Kind::Output),
    ("--report", Kind::Report),
    ("--json", Kind::Json),
    ("--svg", Kind::Figure),
    ("--save-gyro", Kind::Save),
    ("--save-identifier", Kind::Save),
    ("--save-records", Kind::Save),
    ("--seed", Kind::Seed),
    ("--unit-seed", Kind::Seed),
    ("--first-seed", Kind::Seed),
    ("--records", Kind::Count),
    ("--train-records", Kind::Count),
    ("--records-per-class", Kind::Count),
    ("--simulations", Kind::Count),
    ("--rounds", Kind::Count),
    ("--hidden", Kind::Count),
    ("--levels", Kind::Count),
    ("--jobs", Kind::Count),
    ("--block", Kind::Documented("samples")),
    ("--bank-from", Kind::Documented("memory 3, 10, 30")),
    ("--duration-s", Kind::Physical),
    ("--rate-hz", Kind::Physical),
    ("--window-s", Kind::Physical),
    ("--bias-memory-s", Kind::Physical),
    ("--full-scale-dps", Kind::Physical),
    ("--baseline-q-dps2", Kind::Physical),
    ("--initial-c-range", Kind::Physical),
    (
        "--rate-scale",
        Kind::Documented("Factor from the rate column's unit to deg/s"),
    ),
    ("--unit-spread", Kind::Documented("Relative")),
    ("--sigma", Kind::Documented("a fixed sigma in deg/s")),
    ("--lambda", Kind::Documented("Forgetting factor")),
    ("--u0", Kind::Documented("DRLS `U(0)`")),
    ("--warmup-u0", Kind::Documented("`U(0)`")),
    ("--level", Kind::Documented("q/r")),
    ("--taus", Kind::Documented("octave")),
    ("--rate-column", Kind::Word),
    ("--still-column", Kind::Word),
    ("--reference-column", Kind::Word),
    ("--format", Kind::Word),
    ("--preset", Kind::Word),
    ("--trainer", Kind::Word),
    ("--drls-form", Kind::Word),
    ("--activation", Kind::Word),
    ("--rule", Kind::Word),
    ("--group", Kind::Word),
    ("--effects", Kind::Word),
    ("--classes", Kind::Word),
    ("--guard", Kind::Word),
    ("--known-inputs", Kind::Word),
    ("--markov", Kind::Switch),
    ("--force", Kind::Switch),
    ("--quick", Kind::Switch),
    ("--no-task", Kind::Switch),
    ("--no-colour", Kind::Switch),
    ("--undelayed-output", Kind::Switch),
    ("--help", Kind::Switch),
];

/// Units a physical flag's name ends with: s, Hz, deg/s, (deg/s)^2, deg C (a range).
const UNIT_SUFFIXES: &[&str] = &["-s", "-hz", "-dps", "-dps2", "-c-range"];

/// One concept, its one name, and the commands that have it.
const CONCEPTS: &[(&str, &str, &[&str])] = &[
    (
        "the one file read",
        "--input",
        &["denoise", "allan", "image", "replay", "gap", "gyro convert"],
    ),
    (
        "a data file written",
        "--output",
        &["denoise", "simulate", "replay", "gyro convert"],
    ),
    ("a report folder", "--report", &["replay", "demo", "gap"]),
    (
        "a JSON report",
        "--json",
        &[
            "allan",
            "identify",
            "image",
            "reproduce",
            "replay",
            "gap",
            "gap-bench",
        ],
    ),
    (
        "the gyro (a built-in or a gyro file)",
        "--gyro",
        &["simulate", "identify", "image", "replay", "gap"],
    ),
    (
        "the gyro file written",
        "--save-gyro",
        &["allan", "identify", "gap"],
    ),
    (
        "simulations of a model (a count)",
        "--simulations",
        &["gap", "gap-bench"],
    ),
    (
        "the baselines' gated Kalman q",
        "--baseline-q-dps2",
        &["identify", "replay"],
    ),
    (
        "the sample rate",
        "--rate-hz",
        &[
            "denoise",
            "simulate",
            "allan",
            "identify",
            "replay",
            "gap",
            "gap-bench",
        ],
    ),
    (
        "a record's length",
        "--duration-s",
        &["simulate", "reproduce", "gap-bench"],
    ),
];

/// Old names: no longer shown by any command's help, still accepted (hidden aliases, one
/// release) by the commands listed.
const OLD_NAMES: &[(&str, &str, &[&str])] = &[
    ("--real", "--input", &["gap"]),
    ("--seeds", "--simulations", &["gap", "gap-bench"]),
    ("--per-effect", "--records-per-class", &["gap-bench"]),
    ("--write-records", "--save-records", &["gap-bench"]),
    ("--out", "--report", &["demo"]),
    ("--baseline-q", "--baseline-q-dps2", &["identify", "replay"]),
    ("--sim", "--gyro", &["gap"]),
    ("--model", "--gyro", &["simulate"]),
    ("--sensor", "--gyro", &["identify", "replay"]),
    ("--save-model", "--save-gyro", &["allan", "gap"]),
];

/// `host-sim CMD --help`: each visible flag and its help text.
fn flags(cmd: &str) -> BTreeMap<String, String> {
    let out = host_sim()
        .args(cmd.split_whitespace())
        .arg("--help")
        .assert()
        .success();
    let text = String::from_utf8_lossy(&out.get_output().stdout).to_string();
    let mut map = BTreeMap::new();
    let mut current: Option<String> = None;
    for line in text.lines() {
        let t = line.trim_start();
        let indent = line.len() - t.len();
        let t = t.strip_prefix("-h, ").unwrap_or(t);
        if indent <= 6 && t.starts_with("--") {
            let name: String = t
                .chars()
                .take_while(|c| !c.is_whitespace() && *c != '=')
                .collect();
            // Short help format: the text on the same line, after the value name.
            let rest = t[name.len()..].trim_start();
            let rest = match rest.strip_prefix('<') {
                Some(r) => r.split_once('>').map_or("", |(_, after)| after),
                None => rest,
            };
            map.insert(name.clone(), rest.trim().to_string());
            current = Some(name);
        } else if let Some(c) = &current {
            let h = map.get_mut(c).expect("current flag");
            h.push(' ');
            h.push_str(t);
        }
    }
    assert!(map.contains_key("--help"), "{cmd}: help parsed: {text}");
    map
}

fn kind(name: &str) -> Option<Kind> {
    VOCABULARY.iter().find(|v| v.0 == name).map(|v| v.1)
}

#[test]
fn every_visible_flag_is_in_the_vocabulary() {
    let mut outside = Vec::new();
    for cmd in COMMANDS {
        for (name, help) in flags(cmd) {
            match kind(&name) {
                None => outside.push(format!("{cmd} {name}")),
                Some(Kind::Physical) => assert!(
                    UNIT_SUFFIXES.iter().any(|u| name.ends_with(u)),
                    "{cmd} {name}: a physical quantity without its unit in the name"
                ),
                Some(Kind::Documented(why)) => assert!(
                    help.contains(why),
                    "{cmd} {name}: its help must state {why:?} (the reason it has no unit in its name): {help}"
                ),
                Some(_) => {}
            }
        }
    }
    assert!(
        outside.is_empty(),
        "flags outside the vocabulary (add them to VOCABULARY and README's table, or use a name in it): {outside:?}"
    );
}

#[test]
fn one_concept_has_one_name_in_every_command() {
    for (concept, name, commands) in CONCEPTS {
        for cmd in *commands {
            assert!(flags(cmd).contains_key(*name), "{cmd}: {concept} is {name}");
        }
    }
    // No command shows another name of the same kind for the one file it reads, writes or
    // reports to.
    for cmd in COMMANDS {
        let f = flags(cmd);
        let reports: Vec<&String> = f.keys().filter(|n| kind(n) == Some(Kind::Report)).collect();
        assert!(reports.len() <= 1, "{cmd}: {reports:?}");
        let outputs: Vec<&String> = f.keys().filter(|n| kind(n) == Some(Kind::Output)).collect();
        assert!(outputs.len() <= 1, "{cmd}: {outputs:?}");
    }
}

#[test]
fn old_names_are_hidden_and_still_accepted() {
    for (old, new, commands) in OLD_NAMES {
        assert!(kind(old).is_none(), "{old} is not in the vocabulary");
        for cmd in COMMANDS {
            assert!(!flags(cmd).contains_key(*old), "{cmd} shows {old}");
        }
        for cmd in *commands {
            assert!(flags(cmd).contains_key(*new), "{cmd}: {new}");
            // Parsed as the new name: clap's error for the old name is never "unexpected
            // argument" (the run fails later, on the missing required flags or file).
            let out = host_sim()
                .args(cmd.split_whitespace())
                .args([*old, "1"])
                .arg("--no-such-flag-vocabulary-test")
                .assert()
                .failure();
            let err = String::from_utf8_lossy(&out.get_output().stderr).to_string();
            assert!(
                err.contains("--no-such-flag-vocabulary-test")
                    && !err.contains(&format!("'{old}'")),
                "{cmd} {old}: {err}"
            );
        }
    }
    // `reproduce --train` (a count) is now `--train-records`: `--train` means records to
    // read (identify) wherever it is shown.
    assert!(!flags("reproduce").contains_key("--train"));
    assert!(flags("identify").contains_key("--train"));
}

// Behaviour of the renamed flags and of the defaults: each test fails on the old main.

fn stdout(a: &assert_cmd::assert::Assert) -> String {
    String::from_utf8_lossy(&a.get_output().stdout).to_string()
}

fn stderr(a: &assert_cmd::assert::Assert) -> String {
    String::from_utf8_lossy(&a.get_output().stderr).to_string()
}

/// `simulate --gyro ecore2000 --duration-s D --output P` plus `extra`.
fn simulate(out: &std::path::Path, duration_s: &str, extra: &[&str]) -> assert_cmd::assert::Assert {
    host_sim()
        .args([
            "simulate",
            "--gyro",
            "ecore2000",
            "--duration-s",
            duration_s,
        ])
        .args(extra)
        .arg("--output")
        .arg(out)
        .assert()
        .success()
}

#[test]
fn simulate_seeds_1_by_default() {
    let d = tempfile::tempdir().expect("tmp");
    let (a, b) = (d.path().join("default.csv"), d.path().join("seed1.csv"));
    let e = stderr(&simulate(&a, "5", &[]));
    assert!(e.contains("seed 1"), "{e}");
    simulate(&b, "5", &["--seed", "1"]);
    let c = d.path().join("seed2.csv");
    simulate(&c, "5", &["--seed", "2"]);
    let read = |p: &std::path::Path| std::fs::read(p).expect("read");
    assert_eq!(read(&a), read(&b), "no --seed is --seed 1");
    assert_ne!(read(&a), read(&c));
}

#[test]
fn negative_values_where_they_mean_something() {
    let d = tempfile::tempdir().expect("tmp");
    // A start temperature below zero: `--initial-c-range -10,-5` (was "unexpected argument").
    let rec = d.path().join("cold.csv");
    simulate(&rec, "20", &["--initial-c-range", "-10,-5"]);
    let text = std::fs::read_to_string(&rec).expect("read");
    let first = text.lines().nth(1).expect("a row");
    let temp_c: f64 = first
        .split(',')
        .nth(2)
        .expect("temp_c")
        .parse()
        .expect("num");
    assert!((-10.0..=-5.0).contains(&temp_c), "{first}");
    // An axis mounted the other way round: `--rate-scale -1` negates the rate.
    let denoised = |scale: &str, name: &str| -> Vec<f64> {
        let out = d.path().join(name);
        host_sim()
            .args(["denoise", "--input"])
            .arg(&rec)
            .args(["--rate-scale", scale, "--output"])
            .arg(&out)
            .assert()
            .success();
        let text = std::fs::read_to_string(&out).expect("read");
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().expect("header").split(',').collect();
        let k = header
            .iter()
            .position(|h| *h == "denoised_dps")
            .expect("denoised_dps");
        lines
            .map(|l| l.split(',').nth(k).expect("cell").parse().expect("num"))
            .collect()
    };
    let plus = denoised("1", "plus.csv");
    let minus = denoised("-1", "minus.csv");
    assert_eq!(plus.len(), 2000);
    assert!(plus.iter().any(|v| *v != 0.0));
    for (p, m) in plus.iter().zip(&minus) {
        assert_eq!(*p, -*m);
    }
}

#[test]
fn gap_reads_input_and_prints_its_json_without_json() {
    let d = tempfile::tempdir().expect("tmp");
    let rec = d.path().join("static.csv");
    simulate(&rec, "600", &["--rate-hz", "25"]);
    let run = |flag: &str, count_flag: &str| {
        let a = host_sim()
            .args(["gap", flag])
            .arg(&rec)
            .args([count_flag, "4", "--rounds", "1", "--no-task"])
            .args(["--effects", "white_noise"])
            .assert()
            .success();
        let v: serde_json::Value = serde_json::from_str(&stdout(&a)).expect("JSON on stdout");
        assert!(v["gap_before"].is_number(), "{v}");
        v
    };
    let new = run("--input", "--simulations");
    let old = run("--real", "--seeds");
    assert_eq!(new, old, "the old names are the same flags");
    assert_eq!(
        std::fs::read_dir(d.path()).expect("dir").count(),
        1,
        "nothing written"
    );
}

#[test]
fn gap_bench_without_json_and_with_its_new_names() {
    let d = tempfile::tempdir().expect("tmp");
    let recs = d.path().join("recs");
    let a = host_sim()
        .args(["gap-bench", "--classes", "none", "--records-per-class", "1"])
        .args([
            "--simulations",
            "4",
            "--duration-s",
            "600",
            "--rate-hz",
            "25",
        ])
        .arg("--save-records")
        .arg(&recs)
        .assert()
        .success();
    assert!(stdout(&a).contains("none"), "{}", stdout(&a));
    assert!(recs.join("baseline.toml").exists());
    assert!(recs.join("none_1.csv").exists());
}

#[test]
fn reproduce_counts_train_records_and_prints_its_json_without_json() {
    let run = |flag: &str| {
        let a = host_sim()
            .args([
                "reproduce",
                "--records",
                "3",
                flag,
                "2",
                "--duration-s",
                "60",
            ])
            .args(["--preset", "level-trend"])
            .assert()
            .success();
        let v: serde_json::Value = serde_json::from_str(&stdout(&a)).expect("JSON on stdout");
        assert_eq!(v["records"], 3);
        assert_eq!(v["train_records"], 2, "{v}");
        let mut v = v;
        v.as_object_mut().expect("object").remove("samples_per_s"); // a timing
        v
    };
    assert_eq!(run("--train-records"), run("--train"));
    host_sim()
        .args(["reproduce", "--records", "3", "--train-records", "5"])
        .assert()
        .failure()
        .stderr(predicates::str::contains("--train-records must be between"));
}

#[test]
fn identify_defaults_to_the_motion_preset() {
    let d = tempfile::tempdir().expect("tmp");
    let runs: Vec<_> = (1..=2)
        .map(|k| {
            let p = d.path().join(format!("run{k}.csv"));
            simulate(&p, "120", &["--seed", &k.to_string()]);
            p
        })
        .collect();
    let img = d.path().join("unit.fogi");
    let a = host_sim()
        .args(["identify", "--input"])
        .args(&runs)
        .arg("--save-identifier")
        .arg(&img)
        .assert()
        .success();
    assert!(img.exists(), "{}", stderr(&a));
    assert!(stderr(&a).contains("drift filter: model fitted on 2 calibration runs"));
    // Without --save-identifier: fitted and described, nothing written.
    let look = d.path().join("look.fogi");
    let a = host_sim()
        .args(["identify", "--input"])
        .args(&runs)
        .assert()
        .success();
    assert!(stderr(&a).contains("no image written"), "{}", stderr(&a));
    assert!(!look.exists());
    assert_eq!(std::fs::read_dir(d.path()).expect("dir").count(), 3);
}

#[test]
fn baseline_q_dps2_and_its_old_name() {
    let d = tempfile::tempdir().expect("tmp");
    let rec = d.path().join("rec.csv");
    simulate(&rec, "120", &[]);
    for (k, flag) in ["--baseline-q-dps2", "--baseline-q"].iter().enumerate() {
        let json = d.path().join(format!("s{k}.json"));
        host_sim()
            .args(["replay", "--input"])
            .arg(&rec)
            .arg("--output")
            .arg(d.path().join(format!("o{k}.csv")))
            .args([*flag, "1e-12", "--json"])
            .arg(&json)
            .assert()
            .success();
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
        assert_eq!(
            s["scores"]["baselines"]["q_source"], "--baseline-q-dps2",
            "{flag}"
        );
        assert_eq!(s["scores"]["baselines"]["q_dps2"], 1e-12, "{flag}");
    }
}
