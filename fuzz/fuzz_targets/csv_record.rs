//! Fuzz target: host-sim's one interchange CSV reader (`host_sim::record`: [`Record`], read
//! by every subcommand, and [`Rows`], the streamed replay's) on any bytes, with the options
//! of `denoise` and `allan` (`t_s` and the rate only, rows kept), of `identify` and `replay`
//! (every optional column) and of a record without `t_s` (`--rate-hz`). The reader is
//! compiled here from host-sim's source file, so the fuzz build does not depend on the whole
//! host-sim crate.
//!
//! Invariants checked:
//! - no panic; an error names the file (`fuzz.csv`) and never says "line 0";
//! - on success: at least one row; every data row the CSV layer yields is kept (the count
//!   equals an independent `csv::Reader`'s); `t_s` finite and strictly increasing; the rate
//!   and every optional column finite in single precision, each as long as `t_s`;
//!   `Record::gaps` points at lines inside the file;
//! - the options agree: reading every optional column succeeds only where reading `t_s` and
//!   the rate does, with the same `t_s` and rate, and fails where that succeeds only on an
//!   optional column's value; the row by row reader gives the same rows as `Record`.
#![no_main]

use libfuzzer_sys::fuzz_target;

// The reader's own source file (no crate-internal path).
#[allow(dead_code)]
#[path = "../../host-sim/src/record.rs"]
mod record;

use record::{ReadOptions, Record, Rows};

const NAME: &str = "fuzz.csv";

fn check_error(e: &anyhow::Error) {
    let msg = format!("{e:#}");
    assert!(msg.starts_with(NAME), "error does not name the file: {msg}");
    assert!(
        !msg.starts_with(&format!("{NAME}:0:")),
        "error at line 0: {msg}"
    );
}

fn single(x: f64) -> bool {
    x.is_finite() && x.abs() <= f64::from(f32::MAX)
}

fn check_record(r: &Record, data: &[u8]) {
    let n = r.len();
    assert!(n > 0);
    assert_eq!(n, r.rate_dps.len());
    assert!(r.t_s.iter().all(|t| t.is_finite()));
    assert!(r.rate_dps.iter().all(|&x| single(x)));
    assert!(r.t_s.windows(2).all(|w| w[0] < w[1]), "t_s not increasing");
    for c in [&r.temp_c, &r.drift_dps, &r.true_rate_dps]
        .into_iter()
        .flatten()
    {
        assert_eq!(c.len(), n);
        assert!(c.iter().all(|&x| single(x)));
    }
    if let Some(m) = &r.moving {
        assert_eq!(m.len(), n);
    }
    let mut independent = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(data);
    let mut rows = 0usize;
    for rec in independent.records() {
        assert!(
            rec.is_ok(),
            "csv::Reader fails where Record succeeded: {rec:?}"
        );
        rows += 1;
    }
    assert_eq!(rows, n, "rows lost");
    let lines = data.iter().filter(|&&b| b == b'\n' || b == b'\r').count() as u64 + 1;
    let h = r.holes();
    assert!(h.count <= h.steps, "{} gaps in {} steps", h.count, h.steps);
    if let Some(g) = h.largest {
        assert!(g.line >= 2 && g.line <= lines, "gap at line {}", g.line);
        assert!(g.start_line >= 2 && g.start_line < g.line);
        assert!(g.dt_s.is_finite() && g.dt_s > 0.0);
    }
}

fuzz_target!(|data: &[u8]| {
    let plain = ReadOptions {
        optional_columns: false,
        keep_rows: true,
        ..ReadOptions::default()
    };
    let base = Record::from_reader(NAME, data, &plain);
    let full = Record::from_reader(NAME, data, &ReadOptions::default());
    match &base {
        Ok(r) => {
            check_record(r, data);
            assert_eq!(r.rows.len(), r.len());
        }
        Err(e) => check_error(e),
    }
    match (&full, &base) {
        (Ok(f), Ok(b)) => {
            check_record(f, data);
            assert_eq!(f.t_s, b.t_s);
            assert_eq!(f.rate_dps, b.rate_dps);
        }
        (Ok(_), Err(e)) => panic!("every column read where t_s and the rate were refused: {e:#}"),
        (Err(e), Ok(b)) => {
            check_error(e);
            assert!(
                b.header.iter().any(|h| matches!(
                    h.trim(),
                    "temp_c" | "drift_dps" | "true_rate_dps" | "moving"
                )),
                "refused on an optional column the header lacks: {e:#}"
            );
        }
        (Err(e), Err(_)) => check_error(e),
    }
    // Row by row: the same rows as the whole record.
    if let Ok(mut rows) = Rows::new(NAME, data, &ReadOptions::default()) {
        let mut t = Vec::new();
        let streamed = loop {
            match rows.next_row() {
                Ok(Some(row)) => t.push(row.t_s),
                Ok(None) => break Ok(()),
                Err(e) => break Err(e),
            }
        };
        match (&streamed, &full) {
            (Ok(()), Ok(f)) => assert_eq!(t, f.t_s),
            (Ok(()), Err(e)) => assert!(t.is_empty(), "{e:#}"),
            (Err(e), _) => {
                check_error(e);
                assert!(full.is_err());
            }
        }
    }
    // Without `t_s`: the rows' index over the rate.
    let timed = ReadOptions {
        rate_hz: Some(100.0),
        ..ReadOptions::default()
    };
    match Record::from_reader(NAME, data, &timed) {
        Ok(r) => {
            check_record(&r, data);
            if !r.t_s_from_rate {
                assert!(full.is_ok());
            }
        }
        Err(e) => check_error(&e),
    }
});
