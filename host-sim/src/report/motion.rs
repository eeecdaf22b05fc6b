//! The report of a motion replay (`host-sim replay --report DIR` with the motion preset,
//! `host-sim demo`): in `DIR`, written atomically,
//! - `heading_error.svg` (records with truth): heading error over time of the identifier
//!   and the five causal baselines, still periods shaded (the truth's `moving` when the
//!   record has it, else the detector's calls);
//! - `drift.svg`: the drift estimate (and the true drift), deg/h;
//! - `heading_correction.svg`: the heading the compensation removes (the integral of the
//!   drift estimate, and of the true drift when the record has it), deg: the heading in
//!   sight without truth, where raw and compensated angles differ too little to see;
//! - `rate.svg`: measured and compensated rate, deg/s;
//! - `summary.json` ([`MotionSummary`]) and `index.html` (headline first, the score table,
//!   the figures inlined).

use super::decimate::MinMax;
use super::heading::{heading_error_svg_labelled, still_spans, HeadingSeries};
use super::html::{esc, inline_svg};
use super::plots::{time_plot, Line, GREY, RED_};
use super::{write_text, DPH_PER_DPS};
use crate::nav;
use crate::record;
use crate::replay::motion::{running_angle_deg, MotionOutcome, MotionSummary};
use anyhow::{Context, Result};
use plotters::style::{RGBColor, BLACK};
use std::fmt::Write;
use std::path::{Path, PathBuf};

const BLUE_: RGBColor = RGBColor(31, 119, 180);

/// The figures: `(file name, SVG, caption)`.
pub fn figures(out: &MotionOutcome) -> Result<Vec<(&'static str, String, String)>> {
    let s = &out.input.record;
    let name = &out.summary.input;
    let mut figs = Vec::new();
    if let (Some(c), Some(t)) = (&out.compared, &out.input.truth) {
        let series: Vec<HeadingSeries<'_>> = c
            .table
            .rows
            .iter()
            .zip(&c.heading_deg)
            // No compensation is in the table; drawn, its error (degrees) would flatten
            // the others (tenths of a degree) to the axis.
            .filter(|(r, _)| r.name != nav::NO_COMPENSATION)
            .map(|(r, h)| HeadingSeries {
                label: &r.name,
                t_s: &t.t_s,
                heading_deg: h,
            })
            .collect();
        let (spans, label) = if c.table.moving_known {
            (still_spans(&t.t_s, &t.still_truth()), "still (truth)")
        } else {
            (still_spans(&t.t_s, &out.still), "still (detector)")
        };
        figs.push((
            "heading_error.svg",
            heading_error_svg_labelled(&format!("Heading error: {name}"), &series, &spans, label)?,
            "Heading error = integral of (compensated - true rate), deg, for the identifier \
             and the causal baselines (same still flags; no compensation is in the table \
             only); shaded: still periods."
                .to_string(),
        ));
    }
    let (mut drift, mut truth, mut rate, mut comp) = (
        MinMax::default(),
        MinMax::default(),
        MinMax::default(),
        MinMax::default(),
    );
    for (k, &t) in s.t_s.iter().enumerate() {
        let d = out.drift_dps.get(k).copied().unwrap_or(0.0);
        drift.push(t, d);
        let r = f64::from(s.rate_dps[k]);
        rate.push(t, r);
        comp.push(t, r - d);
        if let Some(tr) = s.drift_dps.as_ref().and_then(|v| v.get(k)) {
            truth.push(t, f64::from(*tr));
        }
    }
    // Heading the compensation removes (and the true drift's), deg.
    let (mut corr, mut corr_truth) = (MinMax::default(), MinMax::default());
    let drift_k = |k: usize| out.drift_dps.get(k).copied().unwrap_or(0.0);
    for (&t, a) in s
        .t_s
        .iter()
        .zip(running_angle_deg(&s.t_s, (0..s.t_s.len()).map(drift_k)))
    {
        corr.push(t, a);
    }
    if let Some(tr) = &s.drift_dps {
        for (&t, a) in s
            .t_s
            .iter()
            .zip(running_angle_deg(&s.t_s, tr.iter().map(|&x| f64::from(x))))
        {
            corr_truth.push(t, a);
        }
    }
    let mut lines = Vec::new();
    if s.drift_dps.is_some() {
        lines.push(Line {
            label: "true drift",
            colour: BLACK,
            width: 1,
            data: &truth,
            scale: DPH_PER_DPS,
        });
    }
    lines.push(Line {
        label: "drift estimate (motion identifier)",
        colour: RED_,
        width: 2,
        data: &drift,
        scale: DPH_PER_DPS,
    });
    figs.push((
        "drift.svg",
        time_plot(&format!("Drift estimate: {name}"), "drift (deg/h)", &lines)?,
        format!(
            "The drift the identifier subtracts, deg/h (bound +-{:.1} deg/h from the sensor configuration).",
            out.summary.sensor.drift_bound_dph
        ),
    ));
    let mut lines = Vec::new();
    if s.drift_dps.is_some() {
        lines.push(Line {
            label: "integral of the true drift",
            colour: BLACK,
            width: 1,
            data: &corr_truth,
            scale: 1.0,
        });
    }
    lines.push(Line {
        label: "heading correction (motion identifier)",
        colour: RED_,
        width: 2,
        data: &corr,
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
            out.summary.raw_angle_end_deg - out.summary.compensated_angle_end_deg
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
                    data: &rate,
                    scale: 1.0,
                },
                Line {
                    label: "compensated",
                    colour: BLUE_,
                    width: 1,
                    data: &comp,
                    scale: 1.0,
                },
            ],
        )?,
        "Measured and compensated rate, deg/s (min and max per bucket).".to_string(),
    ));
    Ok(figs)
}

/// Writes the report into `dir` (created if missing); returns the path of `index.html`.
pub fn write(dir: &Path, out: &MotionOutcome) -> Result<PathBuf> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the report folder", dir.display()))?;
    let input = Path::new(&out.summary.input);
    let figs = figures(out)?;
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

fn page(s: &MotionSummary, figs: &[(&str, String, String)]) -> Result<String> {
    let mut o = String::new();
    let title = format!("fog motion replay: {}", s.input);
    writeln!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{t}</title>\n\
         <style>body{{font-family:sans-serif;max-width:960px;margin:1em auto;padding:0 1em;color:#222}}\
         pre{{background:#f7f7f7;padding:0.5em;overflow-x:auto}}figure{{margin:1em 0}}\
         figcaption{{font-size:90%;color:#444}}svg{{max-width:100%;height:auto}}</style>\n</head>\n<body>\n<h1>{t}</h1>",
        t = esc(&title)
    )?;
    if let Some(c) = &s.scores {
        let text = nav::table(c);
        let mut lines = text.lines();
        if let Some(head) = lines.next() {
            writeln!(o, "<p><strong>{}</strong></p>", esc(head))?;
        }
        writeln!(
            o,
            "<h2>Scores against the truth</h2>\n<pre>{}</pre>",
            esc(&lines.collect::<Vec<_>>().join("\n"))
        )?;
    } else {
        writeln!(
            o,
            "<p>The record carries no truth (`true_rate_dps` and `drift_dps`): no scores.</p>"
        )?;
    }
    if let Some(t) = &s.test_set {
        writeln!(
            o,
            "<h2>Over the test records</h2>\n<pre>{}</pre>",
            esc(&t.text())
        )?;
    }
    if let Some(t) = &s.level_tuning {
        writeln!(
            o,
            "<h2>The identifier's level, tuned on validation vehicles</h2>\n<pre>{}</pre>",
            esc(&t.lines().join("\n"))
        )?;
    }
    writeln!(
        o,
        "<h2>Record and identifier</h2>\n<pre>{}</pre>",
        esc(&format!(
            "input      {} ({}, t_s from {})\nrate       column {:?} x {}\nidentifier {} ({} record passes trained)\nsensor     full scale {} deg/s, quantum {} deg/s, {} Hz, drift bound {:.1} deg/h\nrows       {} ({} still, {} level updates, {} at full scale)\nangle end  raw {:.4} deg, compensated {:.4} deg\noutput     {}",
            s.input,
            s.format,
            s.t_s_source,
            s.rate_column.as_deref().unwrap_or("-"),
            s.rate_scale,
            s.identifier,
            s.record_passes_trained,
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
