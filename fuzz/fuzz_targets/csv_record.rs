//! Fuzz target: host-sim's interchange CSV readers (`host_sim::record::Record::from_reader`,
//! used by `denoise` and `allan`, and `host_sim::identify::series::Series::from_reader`, used
//! by `identify`, `reproduce` and `gap`) on any bytes. Both are compiled here from host-sim's
//! source files, so the fuzz build does not depend on the whole host-sim crate.
//!
//! Invariants checked:
//! - no panic; an error names the file (`fuzz.csv`) and never says "line 0";
//! - on success: at least one row; every data row the CSV layer yields is kept (the count
//!   equals an independent `csv::Reader`'s); `t_s` and `rate_dps` finite; `t_s` strictly
//!   increasing; `Record::gaps` points at lines inside the file;
//! - the two readers agree: `Series` succeeds only where `Record` does, with the same
//!   columns, and `Record` succeeds where `Series` does unless a `drift_dps` column failed.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

// The readers' own source files (their only crate-internal path is `crate::record`).
#[allow(dead_code)]
#[path = "../../host-sim/src/record.rs"]
mod record;
#[allow(dead_code)]
#[path = "../../host-sim/src/identify/series.rs"]
mod series;

use record::Record;
use series::Series;

const NAME: &str = "fuzz.csv";

fn check_error(e: &anyhow::Error) {
    let msg = format!("{e:#}");
    assert!(msg.starts_with(NAME), "error does not name the file: {msg}");
    assert!(
        !msg.starts_with(&format!("{NAME}:0:")),
        "error at line 0: {msg}"
    );
}

fuzz_target!(|data: &[u8]| {
    let path = Path::new(NAME);
    let record = Record::from_reader(path, data);
    let series = Series::from_reader(path, data, "rate_dps");
    match &record {
        Ok(r) => {
            assert!(!r.rows.is_empty());
            assert_eq!(r.rows.len(), r.t_s.len());
            assert_eq!(r.rows.len(), r.rate_dps.len());
            assert!(r.t_s.iter().all(|t| t.is_finite()));
            assert!(r.rate_dps.iter().all(|x| x.is_finite()));
            assert!(r.t_s.windows(2).all(|w| w[0] < w[1]), "t_s not increasing");
            let mut independent = csv::ReaderBuilder::new()
                .has_headers(true)
                .from_reader(data);
            let mut n = 0usize;
            for rec in independent.records() {
                assert!(
                    rec.is_ok(),
                    "csv::Reader fails where Record succeeded: {rec:?}"
                );
                n += 1;
            }
            assert_eq!(n, r.rows.len(), "rows lost");
            let lines = data.iter().filter(|&&b| b == b'\n' || b == b'\r').count() as u64 + 1;
            for g in r.gaps() {
                assert!(g.line >= 2 && g.line <= lines, "gap at line {}", g.line);
                assert!(g.dt_s.is_finite() && g.dt_s > 0.0);
            }
        }
        Err(e) => check_error(e),
    }
    match (&series, &record) {
        (Ok(s), Ok(r)) => {
            assert_eq!(s.t_s, r.t_s);
            assert_eq!(s.rate_dps, r.rate_dps);
            if let Some(d) = &s.drift_dps {
                assert_eq!(d.len(), s.t_s.len());
                assert!(d.iter().all(|x| x.is_finite()));
            }
            assert!(s.sample_period_s().is_finite() && s.sample_period_s() > 0.0);
        }
        (Ok(_), Err(e)) => panic!("Series read what Record refused: {e:#}"),
        (Err(e), Ok(r)) => {
            check_error(e);
            // Series (identify) also parses the optional numeric columns that Record
            // (denoise) passes through unchanged: drift_dps and temp_c.
            assert!(
                r.header
                    .iter()
                    .any(|h| matches!(h.trim(), "drift_dps" | "temp_c")),
                "Series refused what Record read, without a drift_dps or temp_c column: {e:#}"
            );
        }
        (Err(e), Err(_)) => check_error(e),
    }
});
