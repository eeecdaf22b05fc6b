//! `index.html`: one self-contained page (inline SVG and CSS, no script, no external
//! resource), readable from `file://`.

use super::{AllanSummary, BytesSummary, Collector, Summary, TruthSummary};
use anyhow::Result;
use std::fmt::Write;

pub(super) fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

/// The SVG document without an XML declaration, ready to inline.
pub(super) fn inline_svg(svg: &str) -> &str {
    let s = svg.trim_start();
    match (s.starts_with("<?xml"), s.find("?>")) {
        (true, Some(i)) => s[i + 2..].trim_start(),
        _ => s,
    }
}

fn row(out: &mut String, k: &str, v: &str) -> std::fmt::Result {
    writeln!(out, "<tr><th>{}</th><td>{}</td></tr>", esc(k), esc(v))
}

/// The page.
pub fn page(s: &Summary, figures: &[(&str, String, &str)], c: &Collector) -> Result<String> {
    let mut o = String::new();
    head(&mut o, &format!("fog replay report: {}", s.input))?;
    record_section(&mut o, s)?;
    rejected_section(&mut o, s)?;
    if let Some(t) = &s.truth {
        truth_section(&mut o, t)?;
    }
    if let Some(a) = &s.allan {
        allan_section(&mut o, a)?;
    }
    figures_section(&mut o, figures, c)?;
    writeln!(
        o,
        "<p>Numbers: <a href=\"summary.json\">summary.json</a>.</p>\n</body>\n</html>"
    )?;
    Ok(o)
}

/// The document's start up to the `<h1>` title (the `<title>` too), with the style sheet.
fn head(o: &mut String, title: &str) -> std::fmt::Result {
    writeln!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n\
         <style>body{{font-family:sans-serif;max-width:960px;margin:1em auto;padding:0 1em;color:#222}}\
         table{{border-collapse:collapse;margin:0.5em 0 1em}}th,td{{border:1px solid #ccc;padding:2px 8px;text-align:left}}\
         th{{background:#f4f4f4;font-weight:normal}}figure{{margin:1em 0}}figcaption{{font-size:90%;color:#444}}\
         svg{{max-width:100%;height:auto}}</style>\n</head>\n<body>\n<h1>{}</h1>",
        esc(title),
        esc(title)
    )
}

/// "Record and pipeline": input, output, identifier, time span, sample and block counts.
fn record_section(o: &mut String, s: &Summary) -> std::fmt::Result {
    writeln!(o, "<h2>Record and pipeline</h2>\n<table>")?;
    row(o, "input", &format!("{} ({})", s.input, s.format))?;
    row(o, "per-sample output", &s.output)?;
    row(
        o,
        "identifier",
        &format!(
            "fog-core preset {}, denoising blocks of {} samples, sample period {} s",
            s.preset, s.block_samples, s.sample_period_s
        ),
    )?;
    row(o, "t_s", s.t_s_source)?;
    if let (Some(a), Some(b)) = (s.t_first_s, s.t_last_s) {
        row(o, "time span", &format!("{a} s to {b} s"))?;
    }
    row(o, "samples read", &s.samples_read.to_string())?;
    row(o, "samples identified", &s.samples_identified.to_string())?;
    row(o, "denoising blocks", &s.blocks.to_string())?;
    row(
        o,
        "rows without denoised_dps",
        &format!(
            "{} (the final partial block is never denoised)",
            s.rows_without_denoised
        ),
    )?;
    if let Some(r) = s.rms_train_error_dps {
        row(
            o,
            "RMS training error (a priori)",
            &format!("{r:.4e} deg/s"),
        )?;
    }
    writeln!(o, "</table>")
}

/// "Rejected input": refused samples, fault lines, and the byte counts of a capture or the
/// row and gap counts of a CSV.
fn rejected_section(o: &mut String, s: &Summary) -> std::fmt::Result {
    writeln!(o, "<h2>Rejected input</h2>\n<table>")?;
    row(
        o,
        "samples refused by the identifier",
        &s.samples_rejected.to_string(),
    )?;
    row(o, "DSP-3000 fault lines", &s.fault_lines.to_string())?;
    if let Some(b) = &s.bytes {
        bytes_rows(o, b)?;
    }
    if let Some(k) = &s.csv {
        row(o, "CSV rows", &k.rows.to_string())?;
        row(o, "gaps in t_s", &k.gaps.to_string())?;
        if let (Some(g), Some(l)) = (k.largest_gap_s, k.largest_gap_line) {
            row(o, "largest gap", &format!("{g} s before line {l}"))?;
        }
    }
    writeln!(o, "</table>")
}

/// The byte and frame counts of a binary or ASCII capture, as table rows.
fn bytes_rows(o: &mut String, b: &BytesSummary) -> std::fmt::Result {
    row(o, "bytes read", &b.bytes_total.to_string())?;
    row(o, "bytes in good frames", &b.bytes_good.to_string())?;
    row(o, "bytes dropped", &b.bytes_dropped.to_string())?;
    let k = &b.skipped;
    for (name, v) in [
        ("  no sync", k.no_sync),
        ("  checksum", k.checksum),
        ("  cut short", k.cut_short),
        ("  UART errors", k.uart),
        ("  malformed line", k.malformed),
        ("  too long", k.too_long),
        ("  incomplete (end of capture)", k.incomplete),
    ] {
        row(o, name, &v.to_string())?;
    }
    row(o, "frames dropped", &b.frames_bad.to_string())?;
    if let Some(at) = b.first_drop_at_byte {
        row(o, "first drop detected at byte", &at.to_string())?;
    }
    if let Some(t) = b.tail {
        row(
            o,
            "capture ends mid-frame",
            &format!("{} bytes from byte offset {} dropped", t.bytes, t.offset),
        )?;
    }
    Ok(())
}

/// "Against the true drift": RMS error (deg/h) and `e_truth` of each estimator.
fn truth_section(o: &mut String, t: &TruthSummary) -> std::fmt::Result {
    writeln!(
        o,
        "<h2>Against the true drift</h2>\n<p>True drift from {}; {} samples; RMS of the \
         true drift {:.4} deg/h. <code>e_truth = RMS(y - drift) / RMS(drift)</code>; \
         lower is better. Best here: <b>{}</b>.</p>\n<table>\n<tr><th>estimator</th>\
         <th>RMS error (deg/h)</th><th>e_truth</th></tr>",
        esc(&t.source),
        t.samples,
        t.rms_true_drift_dph,
        esc(t.best)
    )?;
    for (name, r, e) in [
        (
            "on-line identifier",
            t.rms_error_dph.identifier,
            t.e_truth.identifier,
        ),
        (
            "10-s causal moving average",
            t.rms_error_dph.moving_average_10s,
            t.e_truth.moving_average_10s,
        ),
        (
            "random-walk Kalman filter (q = 1e-6, r = 1)",
            t.rms_error_dph.kalman_random_walk,
            t.e_truth.kalman_random_walk,
        ),
    ] {
        writeln!(
            o,
            "<tr><td>{}</td><td>{r:.4}</td><td>{e:.4}</td></tr>",
            esc(name)
        )?;
    }
    writeln!(o, "</table>")
}

/// "Allan deviation": the samples analysed (or why there is no analysis) and the active
/// fitted terms.
fn allan_section(o: &mut String, a: &AllanSummary) -> std::fmt::Result {
    write!(
        o,
        "<h2>Allan deviation</h2>\n<p>Measured rate, first {} samples (tau0 = {} s){}.",
        a.samples_used,
        a.tau0_s,
        if a.truncated {
            "; the record is longer, the rest is not analysed"
        } else {
            ", the whole record"
        }
    )?;
    if let Some(e) = &a.error {
        write!(o, " Not computed: {}.", esc(e))?;
    }
    writeln!(o, "</p>")?;
    if let Some(f) = &a.fit {
        writeln!(
            o,
            "<table>\n<tr><th>term</th><th>value</th><th>also</th></tr>"
        )?;
        for t in f.terms.iter().filter(|t| t.active) {
            writeln!(
                o,
                "<tr><td>{}</td><td>{:.4e} {}</td><td>{:.4e} {}</td></tr>",
                esc(t.symbol),
                t.value,
                esc(t.unit),
                t.value_alt,
                esc(t.unit_alt)
            )?;
        }
        writeln!(o, "</table>")?;
    }
    Ok(())
}

/// "Figures": how the series are decimated, then each figure (file name, SVG document,
/// caption) inlined with a link to its file.
fn figures_section(
    o: &mut String,
    figures: &[(&str, String, &str)],
    c: &Collector,
) -> std::fmt::Result {
    writeln!(
        o,
        "<h2>Figures</h2>\n<p>Series are decimated to at most {} buckets (min and max of \
         each, {} samples per bucket for the measured rate), so the noise shows as its \
         envelope.</p>",
        super::decimate::DEFAULT_BUCKETS,
        c.measured.width()
    )?;
    for (name, svg, caption) in figures {
        writeln!(
            o,
            "<figure id=\"{}\">\n{}\n<figcaption>{} (<a href=\"{}\">{}</a>)</figcaption>\n</figure>",
            esc(name.trim_end_matches(".svg")),
            inline_svg(svg),
            esc(caption),
            esc(name),
            esc(name)
        )?;
    }
    Ok(())
}
