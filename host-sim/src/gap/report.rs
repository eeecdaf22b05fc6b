//! `--report DIR`: the Allan deviation and PSD of the real record, the baseline and the
//! baseline plus the named (or best) effect; SVG with plotters, one self-contained HTML page.

use super::Diagnosis;
use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// One log-log plot of up to three curves sharing `x`.
fn loglog(
    title: &str,
    xd: &str,
    yd: &str,
    x: &[f64],
    curves: &[(&str, &[f64], RGBColor)],
) -> Result<String> {
    let err = |e: String| anyhow!("SVG plot {title}: {e}");
    let ok = |v: f64| v.is_finite() && v > 0.0;
    let xs: Vec<f64> = x.iter().copied().filter(|&v| ok(v)).collect();
    let ys: Vec<f64> = curves
        .iter()
        .flat_map(|c| c.1.iter().copied())
        .filter(|&v| ok(v))
        .collect();
    let (x_lo, x_hi) = (
        xs.iter().copied().fold(f64::INFINITY, f64::min),
        xs.iter().copied().fold(0.0, f64::max),
    );
    let (y_lo, y_hi) = (
        ys.iter().copied().fold(f64::INFINITY, f64::min) / 2.0,
        ys.iter().copied().fold(0.0, f64::max) * 2.0,
    );
    if !(x_lo < x_hi && y_lo < y_hi) {
        return Ok(String::new());
    }
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (860, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d((x_lo..x_hi).log_scale(), (y_lo..y_hi).log_scale())
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(xd)
            .y_desc(yd)
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for &(label, ys, c) in curves {
            let pts: Vec<(f64, f64)> = x
                .iter()
                .zip(ys)
                .filter(|(a, b)| ok(**a) && ok(**b))
                .map(|(a, b)| (*a, *b))
                .collect();
            if pts.is_empty() {
                continue;
            }
            chart
                .draw_series(LineSeries::new(pts, c.stroke_width(2)))
                .map_err(|e| err(e.to_string()))?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(out)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The files [`write()`] writes into its folder.
pub const FILES: [&str; 3] = ["adev.svg", "psd.svg", "index.html"];

/// Writes `adev.svg`, `psd.svg` and `index.html` into `dir`; returns the page's path.
pub fn write(dir: &Path, d: &Diagnosis) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let c = &d.curves;
    // The third curve is the best candidate's: labelled as named only when it was.
    let after = match d.best_candidate {
        Some(e) if d.effect == e.name() => format!("baseline + {} (named)", e.name()),
        Some(e) => format!("baseline + {} (best candidate, not named)", e.name()),
        None => "no candidate".to_string(),
    };
    let blue = RGBColor(31, 119, 180);
    let grey = RGBColor(90, 90, 90);
    let red = RGBColor(214, 39, 40);
    let adev = loglog(
        "Allan deviation (all blocks pooled; simulations: median)",
        "tau (s)",
        "ADEV (deg/s)",
        &c.tau_s,
        &[
            ("real", &c.adev_real, blue),
            ("baseline", &c.adev_base, grey),
            (&after, &c.adev_after, red),
        ],
    )?;
    let psd = loglog(
        "Welch PSD (all blocks; simulations: median)",
        "frequency (Hz)",
        "PSD ((deg/s)^2/Hz)",
        &c.freq_hz,
        &[
            ("real", &c.psd_real, blue),
            ("baseline", &c.psd_base, grey),
            (&after, &c.psd_after, red),
        ],
    )?;
    for (name, svg) in [("adev.svg", &adev), ("psd.svg", &psd)] {
        let p = dir.join(name);
        crate::record::write_atomic(&p, |w| {
            use std::io::Write;
            w.write_all(svg.as_bytes())
                .with_context(|| format!("{}: write failed", p.display()))
        })?;
    }
    let mut rows = String::new();
    for k in &d.candidates {
        rows.push_str(&format!(
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            k.effect.name(),
            k.gap_after.map_or("-".into(), |g| format!("{g:.3}")),
            k.shrink.map_or("-".into(), |g| format!("{g:.3}")),
            esc(&k
                .params
                .as_ref()
                .map(|p| p
                    .iter()
                    .map(|(a, b)| format!("{a} = {b:.4e}"))
                    .collect::<Vec<_>>()
                    .join(", "))
                .or(k.skipped.clone())
                .unwrap_or_default())
        ));
    }
    let html = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>gap: {rec}</title>\
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}td,th{{padding:2px 8px;border-bottom:1px solid #ddd}}</style></head><body>\
<h1>Sim-to-real gap: {rec}</h1><p><b>effect: {effect}</b> {params}</p><p><b>In plain units:</b> {plain}</p><p>Held-out gap score (mean squared z of the worst feature group; about 1 when the record is one more draw of the model) {gb:.3} &rarr; {ga:.3} (shrink {sh:.3}); null gap median {g50:.3}, 95 % {g95:.3}.</p>\
<p>{dec}</p><p>Baseline: {src}.</p><p>Where: tau {tau}, frequency {fr}, time {tm}; distribution: {dist}</p>\
<h2>Allan deviation</h2>{adev}<h2>PSD</h2>{psd}<h2>Candidates (held-out)</h2><table><tr><th>effect</th><th>gap after</th><th>shrink</th><th>parameters</th></tr>{rows}</table>\
<p><small>{defs}</small></p></body></html>\n",
        rec = esc(&d.record),
        effect = d.effect,
        plain = esc(&d.plain.summary),
        params = esc(&d
            .params
            .iter()
            .flat_map(|m| m.iter())
            .map(|(k, v)| {
                let ci = d.params_ci95.as_ref().and_then(|c| c.get(k));
                match (ci, d.params_sigma.as_ref().and_then(|s| s.get(k))) {
                    (Some([lo, hi]), _) => format!("{k} = {v:.4e} (95 %: {lo:.4e} to {hi:.4e})"),
                    (None, Some(e)) => format!("{k} = {v:.4e} +- {e:.1e}"),
                    (None, None) => format!("{k} = {v:.4e}"),
                }
            })
            .collect::<Vec<_>>()
            .join(", ")),
        gb = d.gap_before,
        ga = d.gap_after,
        sh = d.shrink,
        g50 = d.null_gap_median,
        g95 = d.null_gap_95,
        dec = esc(&d.decision),
        src = esc(&d.baseline_source),
        tau = fmt_range(d.where_.tau_s, "s"),
        fr = fmt_range(d.where_.freq_hz, "Hz"),
        tm = fmt_range(d.where_.time_s, "s"),
        dist = esc(&d.where_.distribution.join(", ")),
        defs = esc(d.definitions),
    );
    let page = dir.join("index.html");
    crate::record::write_atomic(&page, |w| {
        use std::io::Write;
        w.write_all(html.as_bytes())
            .with_context(|| format!("{}: write failed", page.display()))
    })?;
    Ok(page)
}

fn fmt_range(r: Option<[f64; 2]>, unit: &str) -> String {
    r.map_or("-".into(), |[a, b]| format!("{a:.3e}..{b:.3e} {unit}"))
}
