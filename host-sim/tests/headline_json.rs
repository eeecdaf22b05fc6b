//! Every headline agrees with the command's own JSON: `replay` on a record with truth (the
//! record's result, printed first, then the summary line; `index.html`'s lead) and
//! `identify --preset motion --validate` (the result pooled over every validation record,
//! printed before each record's table, and its last line), and `identify` with a network
//! preset (its one line: the verdict on e_truth, the figures). Each number is parsed from what
//! is printed and compared with the JSON at the printed precision; the verdicts and the best
//! baseline are recomputed here from the JSON's per-record figures. (`demo`'s:
//! `demo_cli.rs`, `demo_leads_with_the_pooled_result_of_its_json`.)

use serde_json::Value;
use std::fs;
use std::path::Path;

mod common;
use common::{host_sim, simulate, vehicle_gyro};

fn stderr(a: &assert_cmd::assert::Assert) -> String {
    String::from_utf8_lossy(&a.get_output().stderr).to_string()
}

fn json(p: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(p).expect("JSON written")).expect("valid JSON")
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// `printed` is `exact` at `decimals` decimals.
fn agrees(printed: f64, exact: f64, decimals: i32, what: &str) {
    let half = 0.5 * 10f64.powi(-decimals) + 1e-9;
    assert!(
        (printed - exact).abs() <= half,
        "{what}: printed {printed}, JSON {exact}"
    );
}

/// What the per-record figures of the JSON say (one `scores` table per record, the
/// identifier first): the mean heading-error RMS per estimator, the best baseline (no
/// compensation is not one) and the verdict against it, and on how many records the
/// identifier is below every baseline.
struct Expected {
    names: Vec<String>,
    means: Vec<f64>,
    best: usize,
    verdict: &'static str,
    below: u64,
    records: u64,
}

fn expected(tables: &[&Value]) -> Expected {
    let rows: Vec<&Vec<Value>> = tables
        .iter()
        .map(|t| t["rows"].as_array().expect("rows"))
        .collect();
    let names: Vec<String> = rows[0]
        .iter()
        .map(|r| r["name"].as_str().expect("name").to_string())
        .collect();
    let rms = |r: &Vec<Value>, k: usize| num(&r[k]["scores"]["heading_rms_deg"]);
    let n = rows.len();
    let means: Vec<f64> = (0..names.len())
        .map(|k| rows.iter().map(|r| rms(r, k)).sum::<f64>() / n as f64)
        .collect();
    let baselines: Vec<usize> = (1..names.len())
        .filter(|&k| names[k] != "no compensation")
        .collect();
    let best = *baselines
        .iter()
        .min_by(|&&a, &&b| means[a].total_cmp(&means[b]))
        .expect("a baseline");
    let below = rows
        .iter()
        .filter(|r| baselines.iter().all(|&k| rms(r, 0) < rms(r, k)))
        .count() as u64;
    Expected {
        verdict: if means[0] < means[best] {
            "fog wins"
        } else {
            "fog loses"
        },
        names,
        means,
        best,
        below,
        records: n as u64,
    }
}

impl Expected {
    fn pct(&self, k: usize) -> f64 {
        100.0 * (self.means[0] / self.means[k] - 1.0)
    }

    /// A verdict line, `fog loses: X deg against Y deg for the best baseline (P %), NAME`,
    /// against these figures.
    fn check_verdict(&self, line: &str, what: &str) {
        let (verdict, rest) = line.trim().split_once(": ").expect("VERDICT: ...");
        assert_eq!(verdict, self.verdict, "{what}: {line}");
        let w: Vec<&str> = rest.split_whitespace().collect();
        assert_eq!(
            (w[1], w[2], w[4]),
            ("deg", "against", "deg"),
            "{what}: {line}"
        );
        let x: f64 = w[0].parse().expect("X");
        let y: f64 = w[3].parse().expect("Y");
        let (_, after) = rest.split_once(" (").expect("(P %)");
        let (pct, name) = after.split_once(" %), ").expect("P %), NAME");
        agrees(x, self.means[0], 4, what);
        agrees(y, self.means[self.best], 4, what);
        agrees(pct.parse().expect("P"), self.pct(self.best), 1, what);
        assert_eq!(name, self.names[self.best], "{what}: {line}");
    }

    /// `fog is below every baseline on K of N ...`.
    fn check_count(&self, line: &str, what: &str) {
        let w: Vec<&str> = line.split_whitespace().collect();
        let i = w.iter().position(|x| *x == "on").expect("on K of N");
        assert_eq!(w[i + 2], "of", "{what}: {line}");
        let k: u64 = w[i + 1].parse().expect("K");
        let n: u64 = w[i + 3].parse().expect("N");
        assert_eq!((k, n), (self.below, self.records), "{what}: {line}");
    }

    /// The JSON's own result (`Pooled`) says the same.
    fn check_json(&self, h: &Value) {
        assert_eq!(h["verdict"], self.verdict);
        assert_eq!(h["best_baseline"], self.names[self.best].as_str());
        assert_eq!(h["records"].as_u64(), Some(self.records));
        assert_eq!(h["below_every_baseline"].as_u64(), Some(self.below));
        agrees(
            num(&h["identifier_mean_heading_rms_deg"]),
            self.means[0],
            12,
            "JSON",
        );
        agrees(
            num(&h["best_baseline_mean_heading_rms_deg"]),
            self.means[self.best],
            12,
            "JSON",
        );
        agrees(num(&h["difference_pct"]), self.pct(self.best), 9, "JSON");
    }
}

/// The word after `marker` in `line`, without the punctuation that follows it.
fn after<'a>(line: &'a str, marker: &str) -> &'a str {
    let i = line
        .find(marker)
        .unwrap_or_else(|| panic!("no {marker:?} in {line}"));
    line[i + marker.len()..]
        .split_whitespace()
        .next()
        .expect("a word")
        .trim_end_matches([';', ',', ')'])
}

/// `replay` on a vehicle record: the result leads stderr (and `index.html`), from the JSON's
/// scores; the summary line after it states the JSON's figures.
#[test]
fn replay_leads_with_the_result_of_its_json() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let model = vehicle_gyro(d, "vehicle.toml");
    let rec = d.join("vehicle.csv");
    simulate(&model, 300, 31, &rec);
    let (j, rep) = (d.join("replay.json"), d.join("report"));
    let a = host_sim()
        .args(["replay", "--input"])
        .arg(&rec)
        .arg("--output")
        .arg(d.join("out.csv"))
        .arg("--json")
        .arg(&j)
        .arg("--report")
        .arg(&rep)
        .assert()
        .success();
    let err = stderr(&a);
    let s = json(&j);
    let e = expected(&[&s["scores"]]);
    e.check_json(&s["result"]);
    let lines: Vec<&str> = err.lines().collect();
    // First: the record's result.
    let head = lines[0]
        .strip_prefix(&format!("{}: heading error RMS: ", rec.display()))
        .unwrap_or_else(|| panic!("the result first:\n{err}"));
    e.check_verdict(head, "stderr");
    // Then what the replay did, with the JSON's figures.
    let l = lines[1];
    assert_eq!(
        after(l, ": ").parse::<u64>().ok(),
        s["rows"].as_u64(),
        "{l}"
    );
    let part = |end: &str| {
        l.split("; ")
            .find(|p| p.ends_with(end))
            .unwrap_or_else(|| panic!("no \"... {end}\" in {l}"))
    };
    let still = part(" still").split_whitespace().next().expect("N still");
    assert_eq!(still.parse::<u64>().ok(), s["still_rows"].as_u64(), "{l}");
    let f = |m: &str| {
        after(l, m)
            .parse::<f64>()
            .unwrap_or_else(|_| panic!("{m} in {l}"))
    };
    agrees(f("learned "), num(&s["noise_learned_deg_rth"]), 4, l);
    agrees(f("(image "), num(&s["noise_image_deg_rth"]), 4, l);
    agrees(f("max |drift| "), num(&s["max_abs_drift_dph"]), 2, l);
    agrees(f("end raw "), num(&s["raw_angle_end_deg"]), 4, l);
    agrees(
        f("compensated "),
        num(&s["compensated_angle_end_deg"]),
        4,
        l,
    );
    agrees(
        f("drift bound "),
        num(&s["sensor"]["drift_bound_dph"]),
        1,
        l,
    );
    let w: Vec<&str> = part("updates undone").split_whitespace().collect();
    assert_eq!(w[0].parse::<u64>().ok(), s["level_updates"].as_u64(), "{l}");
    assert_eq!(
        w[3].parse::<u64>().ok(),
        s["updates_undone"].as_u64(),
        "{l}"
    );
    // The table's own headline names the same figures.
    let table = lines
        .iter()
        .find(|l| l.starts_with("heading error RMS: motion identifier "))
        .expect("the table's headline");
    agrees(
        after(table, "motion identifier ").parse().expect("X"),
        e.means[0],
        4,
        table,
    );
    assert!(
        table.contains(&format!("best causal baseline ({})", e.names[e.best])),
        "{table}"
    );
    // index.html leads with the same verdict.
    let html = fs::read_to_string(rep.join("index.html")).expect("index.html");
    let start = html
        .find("<p class=\"headline\"><strong>heading error RMS: ")
        .expect("headline paragraph");
    let end = start + html[start..].find("</strong>").expect("end");
    let text = html[start..end]
        .replace("<p class=\"headline\"><strong>heading error RMS: ", "")
        .replace("&amp;", "&")
        .replace("&#39;", "'");
    e.check_verdict(&text, "index.html");
    assert!(
        start < html.find("<table").expect("table"),
        "headline first"
    );
}

/// `identify --preset motion --validate` on two vehicles: the result printed before the
/// records' tables is the mean over both (not either record's figure), with the verdict
/// and each estimator's mean as the JSON's per-record figures give them; its last line
/// repeats the verdict.
#[test]
fn identify_validation_result_is_the_pooled_result_of_its_json() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let (runs, vehicles) = (d.join("runs"), d.join("vehicles"));
    fs::create_dir(&runs).expect("mkdir");
    fs::create_dir(&vehicles).expect("mkdir");
    for seed in [1, 2] {
        simulate("ecore2000", 120, seed, &runs.join(format!("run{seed}.csv")));
    }
    let model = vehicle_gyro(d, "vehicle.toml");
    for seed in [21, 22] {
        simulate(&model, 300, seed, &vehicles.join(format!("v{seed}.csv")));
    }
    let j = d.join("identify.json");
    let a = host_sim()
        .args(["identify", "--preset", "motion", "--input"])
        .arg(&runs)
        .arg("--validate")
        .arg(&vehicles)
        .arg("--json")
        .arg(&j)
        .assert()
        .success();
    let err = stderr(&a);
    let v = json(&j);
    let recs = v["validation"]["records"].as_array().expect("records");
    assert_eq!(recs.len(), 2);
    let tables: Vec<&Value> = recs.iter().map(|r| &r["scores"]).collect();
    let e = expected(&tables);
    // The test can tell the pooled mean from either record's figure at the printed
    // precision.
    for t in &tables {
        let one = num(&t["rows"][0]["scores"]["heading_rms_deg"]);
        assert!((one - e.means[0]).abs() > 2e-4, "{one} vs {}", e.means[0]);
    }
    e.check_json(&v["validation"]["headline"]);
    for (k, m) in v["validation"]["mean_heading_rms_deg"]
        .as_array()
        .expect("means")
        .iter()
        .enumerate()
    {
        assert_eq!(m[0].as_str(), Some(e.names[k].as_str()));
        agrees(num(&m[1]), e.means[k], 12, "mean_heading_rms_deg");
    }
    let lines: Vec<&str> = err.lines().collect();
    let at = |p: &str| lines.iter().position(|l| l.starts_with(p));
    let result = at("result over 2 validation records").unwrap_or_else(|| panic!("{err}"));
    let first_table = at("heading error RMS: motion identifier").expect("a record's table");
    assert!(
        result < first_table,
        "the result before the records:\n{err}"
    );
    e.check_verdict(lines[result + 1], "stderr");
    e.check_count(lines[result + 2], "stderr");
    // Each estimator's mean and fog's difference from it.
    let id_row = lines[result..first_table]
        .iter()
        .find(|l| l.trim_start().starts_with("motion identifier (fog)"))
        .expect("identifier's row");
    let w: Vec<&str> = id_row.split_whitespace().collect();
    agrees(w[w.len() - 1].parse().expect("mean"), e.means[0], 4, id_row);
    for k in 1..e.names.len() {
        let row = lines[result..first_table]
            .iter()
            .find(|l| l.trim_start().starts_with(&e.names[k]))
            .unwrap_or_else(|| panic!("{} in the result:\n{err}", e.names[k]));
        let w: Vec<&str> = row.split_whitespace().collect();
        agrees(w[w.len() - 3].parse().expect("mean"), e.means[k], 4, row);
        agrees(w[w.len() - 2].parse().expect("pct"), e.pct(k), 1, row);
    }
    // The last line says it again.
    let last = lines.last().expect("a last line");
    let (_, verdict) = last
        .split_once("over the 2 validation records: ")
        .unwrap_or_else(|| panic!("{last}"));
    e.check_verdict(verdict, "last line");
}

/// `identify --preset level-trend`: its line states the JSON's figures (over every
/// validation sample) and the verdict on e_truth against the baseline with the least.
#[test]
fn identify_network_preset_line_states_its_json() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let recs: Vec<_> = (1..=3)
        .map(|seed| {
            let p = d.join(format!("r{seed}.csv"));
            simulate("ecore2000", 120, seed, &p);
            p
        })
        .collect();
    let j = d.join("level.json");
    let a = host_sim()
        .args(["identify", "--preset", "level-trend", "--train"])
        .arg(&recs[0])
        .arg(&recs[1])
        .arg("--validate")
        .arg(&recs[2])
        .arg("--json")
        .arg(&j)
        .assert()
        .success();
    let err = stderr(&a);
    let v = json(&j);
    let line = err.lines().last().expect("a line");
    let (verdict, rest) = line.split_once(": e_truth ").expect("VERDICT: e_truth ...");
    let id = num(&v["e_truth"]);
    let (best_name, best) = v["baselines"]
        .as_array()
        .expect("baselines")
        .iter()
        .filter_map(|b| Some((b["name"].as_str()?, b["e_truth"].as_f64()?)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("a baseline with e_truth");
    assert_eq!(
        verdict,
        if id < best { "fog wins" } else { "fog loses" },
        "{line}"
    );
    let w: Vec<&str> = rest.split_whitespace().collect();
    assert_eq!(w[1], "against", "{line}");
    agrees(w[0].parse().expect("e_truth"), id, 4, line);
    agrees(w[2].parse().expect("best"), best, 4, line);
    let (_, after_pct) = rest.split_once(" (").expect("(P %)");
    let (pct, tail) = after_pct.split_once(" %), ").expect("P %), NAME");
    agrees(pct.parse().expect("P"), 100.0 * (id / best - 1.0), 1, line);
    let (name, figures) = tail.split_once("; ").expect("NAME; figures");
    assert_eq!(name, best_name, "{line}");
    let f = |m: &str| after(figures, m).parse::<f64>().unwrap_or(f64::NAN);
    agrees(f("e_rel "), num(&v["e_rel"]), 4, line);
    agrees(f("e_truth "), id, 4, line);
    agrees(f("rms_err_truth "), num(&v["rms_err_truth_dph"]), 4, line);
    assert_eq!(
        after(figures, "over ").parse::<u64>().ok(),
        v["train_records"].as_u64()
    );
    assert_eq!(
        after(figures, "/ ").parse::<u64>().ok(),
        v["validate_records"].as_u64()
    );
}
