//! Log-log SVG plot of the Allan deviation, its error bars and the fitted terms (plotters,
//! SVG backend only; text is SVG `<text>`, no font files).

use super::fit::{Fit, Kind};
use super::AdevPoint;
use anyhow::{anyhow, Result};
use plotters::prelude::*;

/// Colours of the fitted terms, in [`Kind`] order, then the total.
const COLOURS: [RGBColor; 8] = [
    RGBColor(148, 103, 189),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
    RGBColor(0, 0, 0),
];

fn colour(kind: Kind) -> RGBColor {
    let i = match kind {
        Kind::Quantization => 0,
        Kind::Arw => 1,
        Kind::BiasInstability => 2,
        Kind::Rrw => 3,
        Kind::RateRamp => 4,
        Kind::GaussMarkov => 5,
        Kind::Band => 6,
    };
    COLOURS[i]
}

/// The SVG document, as a string.
pub fn svg(points: &[AdevPoint], fit: &Fit, title: &str) -> Result<String> {
    let err = |e: String| anyhow!("SVG plot: {e}");
    let tau_lo = points.first().map_or(1.0, |p| p.tau_s) / 1.5;
    let tau_hi = points.last().map_or(10.0, |p| p.tau_s) * 1.5;
    let ys = points
        .iter()
        .flat_map(|p| [p.adev_lower_dps, p.adev_upper_dps, p.adev_dps])
        .filter(|v| v.is_finite() && *v > 0.0);
    let y_lo = ys.clone().fold(f64::INFINITY, f64::min) / 2.0;
    let y_hi = ys.fold(0.0, f64::max) * 2.0;
    let (y_lo, y_hi) = if y_lo < y_hi {
        (y_lo, y_hi)
    } else {
        (1e-6, 1.0)
    };
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (900, 640)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d((tau_lo..tau_hi).log_scale(), (y_lo..y_hi).log_scale())
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("tau (s)")
            .y_desc("Allan deviation (deg/s)")
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        let n = 200;
        let taus: Vec<f64> = (0..=n)
            .map(|i| tau_lo * (tau_hi / tau_lo).powf(f64::from(i) / f64::from(n)))
            .collect();
        let clip = |v: f64| (v.is_finite() && v >= y_lo && v <= y_hi).then_some(v);
        for t in fit.terms.iter().filter(|t| t.active) {
            let c = colour(t.term);
            let mut label = format!(
                "{} = {:.3e} {} ({:.3e} {})",
                t.symbol, t.value, t.unit, t.value_alt, t.unit_alt
            );
            if let (Kind::GaussMarkov, Some(tau)) = (t.term, fit.gm_tau_s) {
                label.push_str(&format!(", T = {tau:.3e} s"));
            }
            if let (Kind::Band, Some([lo, hi])) = (t.term, fit.band_hz) {
                label.push_str(&format!(", {lo:.3}-{hi:.3} Hz"));
            }
            let pts: Vec<(f64, f64)> = taus
                .iter()
                .filter_map(|&x| clip(fit.term_avar(t.term, x).sqrt()).map(|y| (x, y)))
                .collect();
            chart
                .draw_series(LineSeries::new(pts, c.stroke_width(1)))
                .map_err(|e| err(e.to_string()))?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
        }
        let total: Vec<(f64, f64)> = taus
            .iter()
            .filter_map(|&x| clip(fit.avar(x).sqrt()).map(|y| (x, y)))
            .collect();
        chart
            .draw_series(LineSeries::new(total, BLACK.stroke_width(2)))
            .map_err(|e| err(e.to_string()))?
            .label("fit (sum)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
        chart
            .draw_series(points.iter().filter_map(|p| {
                let lo = clip(p.adev_lower_dps)?;
                let hi = clip(p.adev_upper_dps)?;
                Some(PathElement::new(vec![(p.tau_s, lo), (p.tau_s, hi)], BLUE))
            }))
            .map_err(|e| err(e.to_string()))?;
        chart
            .draw_series(
                points
                    .iter()
                    .filter(|p| p.adev_dps > 0.0 && super::supported(p))
                    .map(|p| Circle::new((p.tau_s, p.adev_dps), 3, BLUE.filled())),
            )
            .map_err(|e| err(e.to_string()))?
            .label("overlapping ADEV, 68 % bounds")
            .legend(|(x, y)| Circle::new((x + 10, y), 3, BLUE.filled()));
        if points.iter().any(|p| !super::supported(p)) {
            chart
                .draw_series(
                    points
                        .iter()
                        .filter(|p| p.adev_dps > 0.0 && !super::supported(p))
                        .map(|p| Circle::new((p.tau_s, p.adev_dps), 3, BLUE)),
                )
                .map_err(|e| err(e.to_string()))?
                .label(format!(
                    "fewer than {} clusters: not fitted",
                    super::MIN_CLUSTERS
                ))
                .legend(|(x, y)| Circle::new((x + 10, y), 3, BLUE));
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
