//! The result of a set of records with truth in one verdict (`host-sim demo` and its
//! `index.html`, `identify --validate`, and `replay` on its one record): the identifier's
//! mean heading-error RMS over every record against each baseline's (pooled: the mean of the
//! per-record RMS, [`pool`]), the difference in %, "fog wins" / "fog loses" against the best
//! baseline, and on how many records the identifier is below every baseline. Computed from
//! the per-record figures the JSON holds, written to the JSON, and printed from this struct
//! alone ([`Pooled::text`], [`Pooled::verdict_line`]).

use crate::nav;
use serde::Serialize;

/// The verdict's words.
pub const WINS: &str = "fog wins";
/// The verdict's words.
pub const LOSES: &str = "fog loses";
/// The verdict's words (the same pooled mean to the last bit).
pub const TIES: &str = "fog ties";

/// One baseline's pooled mean and the identifier's difference from it.
#[derive(Debug, Clone, Serialize)]
pub struct BaselineMean {
    /// The baseline.
    pub name: String,
    /// Its mean heading-error RMS over the records, deg.
    pub mean_heading_rms_deg: f64,
    /// `100 (identifier / baseline - 1)`, %: negative when the identifier's is lower.
    pub identifier_difference_pct: f64,
}

/// Per record (one [`nav::Comparison`] each), the heading-error RMS per estimator in the
/// table's order, deg: what [`pool`] takes.
pub fn heading_rms<'a>(
    tables: impl IntoIterator<Item = &'a nav::Comparison>,
) -> Vec<Vec<(String, f64)>> {
    tables
        .into_iter()
        .map(|t| {
            t.rows
                .iter()
                .map(|r| (r.name.clone(), r.scores.heading_rms_deg))
                .collect()
        })
        .collect()
}

/// Per record, the heading-error RMS per estimator (the identifier first, the same
/// estimators in the same order in every record), deg: the mean per estimator over the
/// records, and the records on which the identifier is below every baseline
/// ([`nav::NO_COMPENSATION`] aside).
pub fn pool(per: &[Vec<(String, f64)>]) -> (Vec<(String, f64)>, usize) {
    let n = per.len() as f64;
    let mean = per
        .first()
        .map(|f| {
            f.iter()
                .enumerate()
                .map(|(k, (name, _))| {
                    let sum: f64 = per.iter().filter_map(|r| r.get(k)).map(|p| p.1).sum();
                    (name.clone(), sum / n)
                })
                .collect()
        })
        .unwrap_or_default();
    let below = per
        .iter()
        .filter(|rec| {
            rec.split_first().is_some_and(|((_, id), rest)| {
                rest.iter()
                    .filter(|(n, _)| n != nav::NO_COMPENSATION)
                    .all(|(_, b)| id < b)
            })
        })
        .count();
    (mean, below)
}

/// The pooled result ([module docs](self)).
#[derive(Debug, Clone, Serialize)]
pub struct Pooled {
    /// Records pooled.
    pub records: usize,
    /// What they are, plural (`test vehicles`, `validation records`, `record`...).
    pub records_are: String,
    /// The identifier (fog's drift filter).
    pub identifier: String,
    /// Its mean heading-error RMS over the records, deg.
    pub identifier_mean_heading_rms_deg: f64,
    /// Every baseline, in the table's order.
    pub baselines: Vec<BaselineMean>,
    /// The baseline with the least mean ([`nav::NO_COMPENSATION`] is not a candidate).
    pub best_baseline: String,
    /// Its mean, deg.
    pub best_baseline_mean_heading_rms_deg: f64,
    /// `100 (identifier / best - 1)`, %.
    pub difference_pct: f64,
    /// [`WINS`] (the identifier's mean below the best baseline's), [`LOSES`] or [`TIES`].
    pub verdict: String,
    /// Records on which the identifier is below every baseline (no compensation aside).
    pub below_every_baseline: usize,
}

/// `100 (a / b - 1)`: fog's figure `a` against a baseline's `b`, in %.
pub fn pct(a: f64, b: f64) -> f64 {
    100.0 * (a / b - 1.0)
}

/// The verdict's words for fog's figure `fog` against the best baseline's `best` (lower is
/// better): [`WINS`], [`LOSES`] or [`TIES`].
pub fn verdict(fog: f64, best: f64) -> &'static str {
    if fog < best {
        WINS
    } else if fog > best {
        LOSES
    } else {
        TIES
    }
}

impl Pooled {
    /// From the means per estimator (the identifier first) over `records` records (what
    /// they are: `records_are`), of which the identifier is below every baseline on
    /// `below_every_baseline` ([`pool`]). `None` without a baseline other than no
    /// compensation.
    pub fn new(
        means: &[(String, f64)],
        records: usize,
        records_are: &str,
        below_every_baseline: usize,
    ) -> Option<Self> {
        let ((identifier, id_mean), rest) = means.split_first()?;
        let best = rest
            .iter()
            .filter(|(n, _)| n != nav::NO_COMPENSATION)
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        Some(Self {
            records,
            records_are: records_are.to_string(),
            identifier: identifier.clone(),
            identifier_mean_heading_rms_deg: *id_mean,
            baselines: rest
                .iter()
                .map(|(name, m)| BaselineMean {
                    name: name.clone(),
                    mean_heading_rms_deg: *m,
                    identifier_difference_pct: pct(*id_mean, *m),
                })
                .collect(),
            best_baseline: best.0.clone(),
            best_baseline_mean_heading_rms_deg: best.1,
            difference_pct: pct(*id_mean, best.1),
            verdict: verdict(*id_mean, best.1).to_string(),
            below_every_baseline,
        })
    }

    /// The verdict line: `fog loses: 0.1694 deg against 0.1451 deg for the best baseline
    /// (+16.7 %), NAME`.
    pub fn verdict_line(&self) -> String {
        format!(
            "{}: {:.4} deg against {:.4} deg for the best baseline ({:+.1} %), {}",
            self.verdict,
            self.identifier_mean_heading_rms_deg,
            self.best_baseline_mean_heading_rms_deg,
            self.difference_pct,
            self.best_baseline
        )
    }

    /// The count line: `fog is below every baseline on 7 of 32 test vehicles`.
    pub fn count_line(&self) -> String {
        format!(
            "fog is below every baseline on {} of {} {}",
            self.below_every_baseline, self.records, self.records_are
        )
    }

    /// The headline, a few lines: what is pooled, the verdict, the count, then each
    /// estimator's mean and the identifier's difference from it.
    pub fn text(&self) -> String {
        let mut s = format!(
            "result over {} {} (pooled: the mean of each record's heading error RMS):\n",
            self.records, self.records_are
        );
        s += &format!("  {}\n", self.verdict_line());
        s += &format!("  {}\n", self.count_line());
        s += &format!(
            "  {:<50} {:>10} {:>12}\n",
            "estimator", "mean (deg)", "fog vs it"
        );
        s += &format!(
            "  {:<50} {:>10.4}\n",
            format!("{} (fog)", self.identifier),
            self.identifier_mean_heading_rms_deg
        );
        for b in &self.baselines {
            s += &format!(
                "  {:<50} {:>10.4} {:>+10.1} %\n",
                b.name, b.mean_heading_rms_deg, b.identifier_difference_pct
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn means(id: f64) -> Vec<(String, f64)> {
        vec![
            ("motion identifier".into(), id),
            (nav::NO_COMPENSATION.into(), 1.6),
            ("gated".into(), 0.1461),
            ("own detector".into(), 0.1451),
        ]
    }

    #[test]
    fn the_verdict_is_against_the_best_baseline() {
        let p = Pooled::new(&means(0.1694), 32, "test vehicles", 7).expect("pooled");
        assert_eq!(p.verdict, LOSES);
        assert_eq!(p.best_baseline, "own detector");
        assert!((p.difference_pct - 100.0 * (0.1694 / 0.1451 - 1.0)).abs() < 1e-12);
        assert_eq!(
            p.verdict_line(),
            "fog loses: 0.1694 deg against 0.1451 deg for the best baseline (+16.7 %), own detector"
        );
        assert_eq!(p.baselines.len(), 3);
        assert!(p.baselines[0].identifier_difference_pct < -80.0);
        let w = Pooled::new(&means(0.1), 2, "test vehicles", 2).expect("pooled");
        assert_eq!(w.verdict, WINS);
        assert!(w.text().contains("fog wins: 0.1000 deg"));
        assert!(w.text().starts_with("result over 2 test vehicles"));
        assert_eq!(
            w.count_line(),
            "fog is below every baseline on 2 of 2 test vehicles"
        );
        assert_eq!(
            Pooled::new(&means(0.1451), 2, "records", 0)
                .expect("p")
                .verdict,
            TIES
        );
        // No compensation is never the best baseline, even when it is the least.
        let mut m = means(0.2);
        m[1].1 = 0.01;
        assert_eq!(
            Pooled::new(&m, 2, "records", 0).expect("p").best_baseline,
            "own detector"
        );
        assert!(Pooled::new(&m[..2], 2, "records", 0).is_none());
    }

    #[test]
    fn pool_takes_the_mean_of_every_record_and_counts_the_wins() {
        let rec = |id: f64, none: f64, gated: f64| {
            vec![
                ("motion identifier".to_string(), id),
                (nav::NO_COMPENSATION.to_string(), none),
                ("gated".to_string(), gated),
            ]
        };
        // Record 1: fog below the gated filter (no compensation is lower, and does not
        // count); record 2: above it.
        let (mean, below) = pool(&[rec(0.2, 0.1, 0.3), rec(0.6, 1.0, 0.5)]);
        assert_eq!(below, 1);
        assert_eq!(mean.len(), 3);
        assert_eq!(mean[0].0, "motion identifier");
        assert!((mean[0].1 - 0.4).abs() < 1e-15);
        assert!((mean[2].1 - 0.4).abs() < 1e-15);
        assert_eq!(pool(&[]), (Vec::new(), 0));
    }
}
