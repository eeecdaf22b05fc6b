//! The report of a motion replay (`host-sim replay --report DIR` with the motion preset,
//! `host-sim demo`): in `DIR`, written atomically,
//! - `heading_error.svg` (records with truth): heading error over time of the drift filter
//!   and the five causal baselines, still periods shaded (the truth's `moving` when the
//!   record has it, else the filter's still flags);
//! - `drift.svg`: the drift estimate (and the true drift), deg/h;
//! - `heading_correction.svg`: the heading the compensation removes (the integral of the
//!   drift estimate, and of the true drift when the record has it), deg: the heading in
//!   sight without truth, where raw and compensated angles differ too little to see;
//! - `rate.svg`: measured and compensated rate, deg/s;
//! - `summary.json` ([`MotionSummary`]) and `index.html` (headline first: a test set's pooled
//!   result when there is one (`demo`), else the record's; the score table, the figures
//!   inlined).

use super::decimate::MinMax;
use super::heading::{heading_error_svg_labelled, HeadingSeries, Spans};
use super::html::{esc, inline_svg};
use super::plots::{time_plot, Line, GREY, RED_};
use super::{write_text, DPH_PER_DPS};
use crate::nav;
use crate::record;
use crate::replay::input::Sample;
use crate::replay::motion::{MotionOutcome, MotionSummary};
use anyhow::{Context, Result};
use plotters::style::{RGBColor, BLACK};
use std::fmt::Write;
use std::path::{Path, PathBuf};

const BLUE_: RGBColor = RGBColor(31, 119, 180);

/// Trapezoid integral of a stream of `(t_s, rate_dps)`, deg, over the actual steps of `t_s`:
/// a gap in `t_s` is bridged by one trapezoid over its whole length (rate x actual dt).
#[derive(Debug, Clone, Copy, Default)]
pub struct Angle {
    deg: f64,
    prev: Option<(f64, f64)>,
}

impl Angle {
    /// Adds one sample; returns the angle at it (0 at the first sample), deg.
    pub fn push(&mut self, t_s: f64, rate_dps: f64) -> f64 {
        if let Some((t0, r0)) = self.prev {
            self.deg += 0.5 * (r0 + rate_dps) * (t_s - t0);
        }
        self.prev = Some((t_s, rate_dps));
        self.deg
    }

    /// The angle at the last sample, deg.
    pub fn deg(&self) -> f64 {
        self.deg
    }
}

/// What the report's figures keep while a record streams through the motion replay:
/// min/max decimations ([`MinMax`]) and still spans ([`Spans`]), bounded whatever the
/// record's length.
#[derive(Debug, Clone, Default)]
pub struct MotionFigures {
    /// Heading error per scored row (no compensation left out), deg: label and series.
    heading: Vec<(String, MinMax)>,
    /// Still spans: the truth's `!moving` when known, else the filter's still flags.
    spans: Spans,
    spans_from_truth: bool,
    drift: MinMax,
    truth: MinMax,
    rate: MinMax,
    comp: MinMax,
    corr: MinMax,
    corr_truth: MinMax,
    corr_angle: Angle,
    corr_truth_angle: Angle,
}

impl MotionFigures {
    /// Empty figures; `scored_rows`: the score table's row labels (none without truth),
    /// `moving_known`: the record has a `moving` column.
    pub fn new(scored_rows: &[String], moving_known: bool) -> Self {
        Self {
            heading: scored_rows
                .iter()
                .map(|l| (l.clone(), MinMax::default()))
                .collect(),
            spans_from_truth: moving_known,
            ..Self::default()
        }
    }

    /// One sample of the record, the drift filter's estimate (deg/s) and still flag for
    /// it, and each scored row's heading error (deg, in the labels' order; empty without
    /// truth).
    pub fn push(&mut self, x: &Sample, drift_dps: f64, still: bool, heading_deg: &[f64]) {
        let t_s = x.t_s;
        for ((_, m), &h) in self.heading.iter_mut().zip(heading_deg) {
            m.push(t_s, h);
        }
        let shaded = match (self.spans_from_truth, x.moving) {
            (true, Some(m)) => !m,
            _ => still,
        };
        self.spans.push(t_s, shaded);
        self.drift.push(t_s, drift_dps);
        self.rate.push(t_s, x.rate_dps);
        self.comp.push(t_s, x.rate_dps - drift_dps);
        self.corr.push(t_s, self.corr_angle.push(t_s, drift_dps));
        if let Some(d) = x.drift_dps {
            self.truth.push(t_s, d);
            self.corr_truth
                .push(t_s, self.corr_truth_angle.push(t_s, d));
        }
    }
}

/// The figures: `(file name, SVG, caption)`.
pub fn figures(
    f: &MotionFigures,
    summary: &MotionSummary,
) -> Result<Vec<(&'static str, String, String)>> {
    let name = &summary.input;
    let mut figs = Vec::new();
    if summary.scores.is_some() {
        let series: Vec<HeadingSeries<'_>> = f
            .heading
            .iter()
            // No compensation is in the table; drawn, its error (degrees) would flatten
            // the others (tenths of a degree) to the axis.
            .filter(|(label, _)| label != nav::NO_COMPENSATION)
            .map(|(label, h)| HeadingSeries {
                label,
                heading_deg: h,
            })
            .collect();
        let label = if f.spans_from_truth {
            "still (truth)"
        } else {
            "still (detector)"
        };
        figs.push((
            "heading_error.svg",
            heading_error_svg_labelled(
                &format!("Heading error: {name}"),
                &series,
                &f.spans.spans(),
                label,
            )?,
            "Heading error = integral of (compensated - true rate), deg, for the identifier \
             and the causal baselines (same still flags; no compensation is in the table \
             only); shaded: still periods."
                .to_string(),
        ));
    }
    let has_truth = !f.truth.is_empty();
    let mut lines = Vec::new();
    if has_truth {
        lines.push(Line {
            label: "true drift",
            colour: BLACK,
            width: 1,
            data: &f.truth,
            scale: DPH_PER_DPS,
        });
    }
    lines.push(Line {
        label: "drift estimate (motion identifier)",
        colour: RED_,
        width: 2,
        data: &f.drift,
        scale: DPH_PER_DPS,
    });
    figs.push((
        "drift.svg",
        time_plot(&format!("Drift estimate: {name}"), "drift (deg/h)", &lines)?,
        format!(
            "The drift the identifier subtracts, deg/h (bound +-{:.1} deg/h from the sensor configuration).",
            summary.sensor.drift_bound_dph
        ),
    ));
    let mut lines = Vec::new();
    if has_truth {
        lines.push(Line {
            label: "integral of the true drift",
            colour: BLACK,
            width: 1,
            data: &f.corr_truth,
            scale: 1.0,
        });
    }
    lines.push(Line {
        label: "heading correction (motion identifier)",
        colour: RED_,
        width: 2,
        data: &f.corr,
        scale: 1.0,
    });
    figs.push((
        "heading_correction.svg",
        time_plot(
            &format!("Heading the compensation removes: {name}"),
            "heading correction (deg)",
            &lines,
        )?,
        format!(
            "The integral of the drift estimate, deg: raw angle minus compensated angle ({:.4} deg at the end).",
            summary.raw_angle_end_deg - summary.compensated_angle_end_deg
        ),
    ));
    figs.push((
        "rate.svg",
        time_plot(
            &format!("Measured and compensated rate: {name}"),
            "rate (deg/s)",
            &[
                Line {
                    label: "measured",
                    colour: GREY,
                    width: 1,
                    data: &f.rate,
                    scale: 1.0,
                },
                Line {
                    label: "compensated",
                    colour: BLUE_,
                    width: 1,
                    data: &f.comp,
                    scale: 1.0,
                },
            ],
        )?,
        "Measured and compensated rate, deg/s (min and max per bucket).".to_string(),
    ));
    Ok(figs)
}

/// Writes the report into `dir` (created if missing); returns the path of `index.html`.
/// Refused when the replay kept no figures ([`MotionOutcome::figures`]).
pub fn write(dir: &Path, out: &MotionOutcome) -> Result<PathBuf> {
    let Some(f) = &out.figures else {
        anyhow::bail!("the replay kept no figures (MotionOptions::figures): no report");
    };
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the report folder", dir.display()))?;
    let input = Path::new(&out.summary.input);
    let figs = figures(f, &out.summary)?;
    for (f, svg, _) in &figs {
        let p = dir.join(f);
        record::refuse_overwrite(input, &p)?;
        write_text(&p, svg)?;
    }
    let json_path = dir.join("summary.json");
    record::refuse_overwrite(input, &json_path)?;
    write_text(&json_path, &serde_json::to_string_pretty(&out.summary)?)?;
    let index = dir.join("index.html");
    record::refuse_overwrite(input, &index)?;
    write_text(&index, &page(&out.summary, &figs)?)?;
    Ok(index)
}

/// The score table as HTML: the headline, one row per estimator (numbers right-aligned, the
/// best heading RMS in bold), then the detector's rates and the baselines' setup as
/// paragraphs (they wrap with the page instead of widening it).
/// `lead`: the record's headline leads the page (a replay); else it is one example record's
/// (`demo`, after the pooled result).
fn score_table_html(c: &nav::Comparison, lead: bool) -> Result<String> {
    let mut o = String::new();
    let text = nav::table(c);
    let mut lines = text.lines();
    if let Some(head) = lines.next() {
        if lead {
            writeln!(o, "<p><strong>{}</strong></p>", esc(head))?;
        } else {
            writeln!(o, "<p>{}</p>", esc(head))?;
        }
    }
    writeln!(
        o,
        "<h2>Scores against the truth</h2>\n<table class=\"scores\">\n<tr><th>estimator</th>\
         <th>heading RMS (deg)</th><th>heading at the end (deg)</th><th>e_truth (deg/h)</th>\
         <th>e still (deg/h)</th><th>e moving (deg/h)</th></tr>"
    )?;
    let best = c
        .rows
        .iter()
        .map(|r| r.scores.heading_rms_deg)
        .fold(f64::INFINITY, f64::min);
    let cell = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.3}"));
    for r in &c.rows {
        let s = &r.scores;
        let rms = format!("{:.4}", s.heading_rms_deg);
        writeln!(
            o,
            "<tr><td>{}</td><td>{}</td><td>{:.4}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&r.name),
            if s.heading_rms_deg == best {
                format!("<b>{rms}</b>")
            } else {
                rms
            },
            s.heading_final_deg,
            cell(s.e_truth_dph),
            cell(s.e_truth_still_dph),
            cell(s.e_truth_moving_dph)
        )?;
    }
    writeln!(o, "</table>")?;
    // The table's text lines are already above; the detector and baselines lines follow it.
    for line in lines.filter(|l| l.starts_with("detector:") || l.starts_with("baselines:")) {
        writeln!(o, "<p>{}</p>", esc(line))?;
    }
    Ok(o)
}

fn page(s: &MotionSummary, figs: &[(&str, String, String)]) -> Result<String> {
    let mut o = String::new();
    let title = format!("fog motion replay: {}", s.input);
    writeln!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{t}</title>\n\
         <style>body{{font-family:sans-serif;max-width:960px;margin:1em auto;padding:0 1em;color:#222}}\
         pre{{background:#f7f7f7;padding:0.5em;overflow-x:auto;white-space:pre-wrap}}\
         table.scores{{border-collapse:collapse;width:100%;font-size:90%}}\
         table.scores td,table.scores th{{border-bottom:1px solid #ddd;padding:2px 6px}}\
         table.scores td:not(:first-child){{text-align:right;font-variant-numeric:tabular-nums}}figure{{margin:1em 0}}\
         figcaption{{font-size:90%;color:#444}}svg{{max-width:100%;height:auto}}</style>\n</head>\n<body>\n<h1>{t}</h1>",
        t = esc(&title)
    )?;
    // A test set's pooled result leads (`demo`); the replayed record is one example after it.
    if let Some(t) = &s.test_set {
        if let Some(h) = &t.headline {
            writeln!(
                o,
                "<p class=\"headline\">Result over {} {}, pooled mean heading error RMS:<br><strong>{}</strong><br>{}</p>",
                h.records,
                esc(&h.records_are),
                esc(&h.verdict_line()),
                esc(&h.count_line())
            )?;
        }
        writeln!(
            o,
            "<h2>Over the test records</h2>\n<pre>{}</pre>",
            esc(&t.text())
        )?;
        writeln!(
            o,
            "<h2>Example record: {}</h2>\n<p>One draw of the test set (the first test vehicle); the result is above.</p>",
            esc(&s.input)
        )?;
    }
    // A replay with truth: its result leads (the verdict printed first on stderr).
    if let (None, Some(r)) = (&s.test_set, &s.result) {
        writeln!(
            o,
            "<p class=\"headline\"><strong>heading error RMS: {}</strong></p>",
            esc(&r.verdict_line())
        )?;
    }
    if let Some(c) = &s.scores {
        o.push_str(&score_table_html(
            c,
            s.test_set.is_none() && s.result.is_none(),
        )?);
    } else {
        writeln!(
            o,
            "<p>The record carries no truth (`true_rate_dps` and `drift_dps`): no scores.</p>"
        )?;
    }
    if let Some(t) = &s.level_tuning {
        writeln!(
            o,
            "<h2>The gyro model's two scales, tuned on the tune vehicles</h2>\n<pre>{}</pre>",
            esc(&crate::motion::tune::describe(t))
        )?;
    }
    writeln!(
        o,
        "<h2>Record and identifier</h2>\n<pre>{}</pre>",
        esc(&format!(
            "input      {} ({}, t_s from {})\nrate       column {:?} x {}\nimage      {} (fitted on {} calibration runs)\nsensor     full scale {} deg/s, quantum {} deg/s, {} Hz, drift bound {:.1} deg/h\nrows       {} ({} still, {} still windows, {} at full scale)\nangle end  raw {:.4} deg, compensated {:.4} deg\noutput     {}",
            s.input,
            s.format,
            s.t_s_source,
            s.rate_column.as_deref().unwrap_or("-"),
            s.rate_scale,
            s.identifier,
            s.trained_runs,
            s.sensor.full_scale_dps,
            s.sensor.quantum_dps,
            s.sensor.sample_rate_hz,
            s.sensor.drift_bound_dph,
            s.rows,
            s.still_rows,
            s.level_updates,
            s.at_full_scale,
            s.raw_angle_end_deg,
            s.compensated_angle_end_deg,
            s.output
        ))
    )?;
    for (f, svg, cap) in figs {
        writeln!(
            o,
            "<figure id=\"{}\">{}<figcaption>{}</figcaption></figure>",
            esc(f),
            inline_svg(svg),
            esc(cap)
        )?;
    }
    writeln!(o, "</body>\n</html>")?;
    Ok(o)
}
