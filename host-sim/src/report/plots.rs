//! Time plots of the report (plotters, SVG backend only): each series is drawn from its
//! min/max decimation ([`super::decimate::MinMax`]), so noise shows as its envelope.

use super::decimate::MinMax;
use super::Collector;
use anyhow::{anyhow, Result};
use plotters::prelude::*;

pub(super) const GREY: RGBColor = RGBColor(175, 175, 175);
const BLUE_: RGBColor = RGBColor(31, 119, 180);
pub(super) const RED_: RGBColor = RGBColor(214, 39, 40);
const GREEN_: RGBColor = RGBColor(44, 160, 44);
const PURPLE: RGBColor = RGBColor(148, 103, 189);

/// One line of a plot: label, colour, stroke width, data, value factor.
pub(super) struct Line<'a> {
    pub(super) label: &'a str,
    pub(super) colour: RGBColor,
    pub(super) width: u32,
    pub(super) data: &'a MinMax,
    pub(super) scale: f64,
}

pub(super) fn time_plot(title: &str, y_desc: &str, lines: &[Line<'_>]) -> Result<String> {
    let err = |e: String| anyhow!("SVG plot `{title}`: {e}");
    let t_end = lines
        .iter()
        .filter_map(|l| l.data.points().last().map(|p| p.0))
        .fold(0.0f64, f64::max);
    let (t_scale, t_unit) = super::heading::time_axis(t_end);
    let pts: Vec<Vec<(f64, f64)>> = lines
        .iter()
        .map(|l| {
            l.data
                .points()
                .into_iter()
                .map(|(t, v)| (t * t_scale, v * l.scale))
                .collect()
        })
        .collect();
    let all = || pts.iter().flatten();
    let t_lo = all().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let t_hi = all().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let y_lo = all().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let y_hi = all().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let (t_lo, t_hi) = if t_lo < t_hi {
        (t_lo, t_hi)
    } else if t_lo.is_finite() {
        (t_lo - 1.0, t_lo + 1.0)
    } else {
        (0.0, 1.0)
    };
    let (y_lo, y_hi) = if y_lo < y_hi {
        let m = 0.05 * (y_hi - y_lo);
        (y_lo - m, y_hi + m)
    } else if y_lo.is_finite() {
        (
            y_lo - 1e-6 - y_lo.abs() * 0.1,
            y_lo + 1e-6 + y_lo.abs() * 0.1,
        )
    } else {
        (-1.0, 1.0)
    };
    let (y_lo, y_hi) = super::heading::with_legend_room(y_lo, y_hi, lines.len());
    // Tick labels with the decimals the spacing needs (plotters draws about 10 per axis).
    let (x_step, y_step) = ((t_hi - t_lo) / 10.0, (y_hi - y_lo) / 10.0);
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (900, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(85)
            .build_cartesian_2d(t_lo..t_hi, y_lo..y_hi)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(format!("time since power-on ({t_unit})"))
            .y_desc(y_desc)
            .x_label_formatter(&|v| super::tick_label(*v, x_step))
            .y_label_formatter(&|v| super::tick_label(*v, y_step))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (l, p) in lines.iter().zip(pts) {
            if p.is_empty() {
                continue;
            }
            let c = l.colour;
            let w = l.width;
            chart
                .draw_series(LineSeries::new(p, c.stroke_width(w)))
                .map_err(|e| err(e.to_string()))?
                .label(l.label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(w.max(2)))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(out)
}

/// Paper figure 3: measured and denoised rate.
pub fn fig3(c: &Collector, name: &str) -> Result<String> {
    time_plot(
        &format!("Measured and denoised rate: {name}"),
        "rate (deg/s)",
        &[
            Line {
                label: "measured",
                colour: GREY,
                width: 1,
                data: &c.measured,
                scale: 1.0,
            },
            Line {
                label: "denoised (db4, 3 levels)",
                colour: BLUE_,
                width: 1,
                data: &c.denoised,
                scale: 1.0,
            },
        ],
    )
}

/// Paper figure 5: measured rate and identified drift (and the true drift when known).
pub fn fig5(c: &Collector, name: &str, with_truth: bool) -> Result<String> {
    let mut lines = vec![
        Line {
            label: "measured",
            colour: GREY,
            width: 1,
            data: &c.measured,
            scale: 1.0,
        },
        Line {
            label: "identified drift",
            colour: RED_,
            width: 2,
            data: &c.drift,
            scale: 1.0,
        },
    ];
    if with_truth {
        lines.push(Line {
            label: "true drift",
            colour: BLACK,
            width: 1,
            data: &c.truth,
            scale: 1.0,
        });
    }
    time_plot(
        &format!("Measured rate and identified drift: {name}"),
        "rate (deg/s)",
        &lines,
    )
}

/// Figure 5 without the measured rate, in deg/h: the identified drift (and the true one).
pub fn drift_detail(c: &Collector, name: &str, with_truth: bool) -> Result<String> {
    let mut lines = Vec::new();
    if with_truth {
        lines.push(Line {
            label: "true drift",
            colour: BLACK,
            width: 1,
            data: &c.truth,
            scale: super::DPH_PER_DPS,
        });
    }
    lines.push(Line {
        label: "identified drift",
        colour: RED_,
        width: 1,
        data: &c.drift,
        scale: super::DPH_PER_DPS,
    });
    time_plot(
        &format!("Identified drift: {name}"),
        "drift (deg/h)",
        &lines,
    )
}

/// Estimate minus true drift over time, deg/h.
pub fn error_vs_truth(c: &Collector, name: &str) -> Result<String> {
    time_plot(
        &format!("Drift estimate minus true drift: {name}"),
        "error (deg/h)",
        &[
            Line {
                label: "10-s moving average",
                colour: GREEN_,
                width: 1,
                data: &c.err_moving_average,
                scale: 1.0,
            },
            Line {
                label: "random-walk Kalman (q 1e-6, r 1)",
                colour: PURPLE,
                width: 1,
                data: &c.err_kalman,
                scale: 1.0,
            },
            Line {
                label: "identifier",
                colour: RED_,
                width: 1,
                data: &c.err_identifier,
                scale: 1.0,
            },
        ],
    )
}
