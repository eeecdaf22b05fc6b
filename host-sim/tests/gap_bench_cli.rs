//! `host-sim gap-bench`: the accuracy it prints is its confusion matrix's (the diagonal over
//! every record, `none` included), stated in the output, the same as in its JSON.

use assert_cmd::Command;
use std::fs;

#[test]
fn printed_accuracy_is_the_matrix_in_the_json() {
    let dir = tempfile::tempdir().expect("tmp");
    let json = dir.path().join("bench.json");
    // A small benchmark with `none` records beside an effect (the old figure left them out).
    let a = Command::cargo_bin("host-sim")
        .expect("binary built")
        .args([
            "gap-bench",
            "--records-per-class",
            "1",
            "--classes",
            "none,spikes",
            "--duration-s",
            "600",
            "--rate-hz",
            "25",
            "--simulations",
            "6",
            "--jobs",
            "2",
            "--json",
        ])
        .arg(&json)
        .assert()
        .success();
    let out = String::from_utf8_lossy(&a.get_output().stdout).to_string();
    let v: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&json).expect("json")).expect("parse");
    // The matrix, counted here.
    let m = v["confusion"].as_object().expect("confusion");
    let mut diagonal = 0;
    let mut total = 0;
    for (truth, row) in m {
        for (named, n) in row.as_object().expect("row") {
            let n = n.as_u64().expect("count");
            total += n;
            if named == truth {
                diagonal += n;
            }
        }
    }
    assert_eq!(total, 2, "{m:?}");
    let line = out
        .lines()
        .find(|l| l.starts_with("right effect named: "))
        .unwrap_or_else(|| panic!("no accuracy line: {out}"));
    let w: Vec<&str> = line.split_whitespace().collect();
    // right effect named: K of N records = P % (definition; goal ...)
    assert_eq!(
        (w[4], w[6], w[7], w[9]),
        ("of", "records", "=", "%"),
        "{line}"
    );
    let k: u64 = w[3].parse().expect("K");
    let n: u64 = w[5].parse().expect("N");
    let pct: f64 = w[8].parse().expect("P");
    assert_eq!((k, n), (diagonal, total), "{line}");
    let rate = diagonal as f64 / total as f64;
    assert!((pct - 100.0 * rate).abs() <= 0.05, "{line}");
    assert!(
        line.contains("the confusion matrix's diagonal over all its records, `none` included"),
        "{line}"
    );
    assert_eq!(v["right"].as_u64(), Some(diagonal));
    assert_eq!(v["total"].as_u64(), Some(total));
    assert!((v["right_rate"].as_f64().expect("rate") - rate).abs() < 1e-12);
    // The per-class `right` column adds up to the same.
    let classes = v["classes"].as_object().expect("classes");
    let correct: u64 = classes
        .values()
        .map(|c| c["correct"].as_u64().expect("correct"))
        .sum();
    assert_eq!(correct, diagonal);
}
