//! Heading error over time for several estimators, the still periods shaded (SVG).
//!
//! Axis ticks are written with as many decimals as the tick spacing needs (at most 6
//! significant after the point), so a tick reads `0.25`, `-1.5` or `120`, never
//! `6.939e-18`: a value within a millionth of a tick step of 0 is written `0`. Time is in
//! s for records up to 20 min, in min beyond ([`time_axis`], every time plot of a report).

use super::decimate::MinMax;
use anyhow::{anyhow, Result};
use plotters::prelude::*;

/// One estimator's heading error.
pub struct HeadingSeries<'a> {
    /// Legend label, e.g. `gated Kalman (q 1e-10)`.
    pub label: &'a str,
    /// Heading error over time (s), deg, decimated.
    pub heading_deg: &'a MinMax,
}

/// Longest record whose time axis is in seconds, s; beyond, minutes.
pub const SECONDS_AXIS_MAX_S: f64 = 1200.0;

/// Time axis of a record ending at `t_end_s`: the factor from seconds and the unit's name
/// (s up to `SECONDS_AXIS_MAX_S`, 20 min, min beyond).
pub fn time_axis(t_end_s: f64) -> (f64, &'static str) {
    if t_end_s > SECONDS_AXIS_MAX_S {
        (1.0 / 60.0, "min")
    } else {
        (1.0, "s")
    }
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(120, 120, 120),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(214, 39, 40),
    RGBColor(255, 127, 14),
];

/// Tick label of `v` on an axis whose ticks are about `step` apart: decimals from the step,
/// `0` for values within 1e-6 step of zero.
pub fn tick_label(v: f64, step: f64) -> String {
    let step = step.abs();
    if !v.is_finite() {
        return String::new();
    }
    if step > 0.0 && v.abs() < 1e-6 * step {
        return "0".into();
    }
    let decimals = if step > 0.0 {
        (-step.log10()).ceil().clamp(0.0, 6.0) as usize
    } else {
        3
    };
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0".into()
    } else {
        s
    }
}

/// The y range `lo..hi` raised so that a legend of `entries` lines in an upper corner sits
/// above every curve: the data keep the lower part of the plot. ASSUMED: about 20 px per
/// legend line (plotters' default font) in the about 375-px plot area of a 480-px figure.
pub(super) fn with_legend_room(lo: f64, hi: f64, entries: usize) -> (f64, f64) {
    let frac = ((entries as f64 * 20.0 + 16.0) / 375.0).min(0.6);
    (lo, lo + (hi - lo) / (1.0 - frac))
}

/// Still spans `(start s, end s)` from a stream of times and still flags, in bounded memory:
/// a span runs from its first still sample to its last; when there would be more than
/// `capacity` spans, neighbours are joined in pairs (the gap between them shaded too), so a
/// detector that flickers on a long record still draws at most `capacity` rectangles.
#[derive(Debug, Clone)]
pub struct Spans {
    capacity: usize,
    spans: Vec<(f64, f64)>,
    open: Option<f64>,
    last_t: f64,
}

/// Default number of spans kept: [`super::decimate::DEFAULT_BUCKETS`].
impl Default for Spans {
    fn default() -> Self {
        Self::new(super::decimate::DEFAULT_BUCKETS)
    }
}

impl Spans {
    /// At most `capacity` (at least 2) spans.
    pub fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(2),
            spans: Vec::new(),
            open: None,
            last_t: f64::NAN,
        }
    }

    /// One sample at `t_s`, still or not.
    pub fn push(&mut self, t_s: f64, still: bool) {
        match (still, self.open) {
            (true, None) => self.open = Some(t_s),
            (false, Some(t0)) => {
                self.close((t0, self.last_t.max(t0)));
                self.open = None;
            }
            _ => {}
        }
        self.last_t = t_s;
    }

    fn close(&mut self, span: (f64, f64)) {
        if self.spans.len() == self.capacity {
            self.spans = self
                .spans
                .chunks(2)
                .map(|c| (c[0].0, c[c.len() - 1].1))
                .collect();
        }
        self.spans.push(span);
    }

    /// The spans so far, the open one closed at the last sample.
    pub fn spans(&self) -> Vec<(f64, f64)> {
        let mut out = self.spans.clone();
        if let Some(t0) = self.open {
            out.push((t0, self.last_t.max(t0)));
        }
        out
    }
}

/// Still spans of whole per-sample times and flags ([`Spans`]).
pub fn still_spans(t_s: &[f64], still: &[bool]) -> Vec<(f64, f64)> {
    let mut s = Spans::new(usize::MAX);
    for (&t, &f) in t_s.iter().zip(still) {
        s.push(t, f);
    }
    s.spans()
}

/// SVG of the heading error (deg) of each series over time, `still_spans_s` shaded
/// (legend `still (truth)`).
pub fn heading_error_svg(
    title: &str,
    series: &[HeadingSeries<'_>],
    still_spans_s: &[(f64, f64)],
) -> Result<String> {
    heading_error_svg_labelled(title, series, still_spans_s, "still (truth)")
}

/// [`heading_error_svg`] with the shading's legend `still_label` (e.g. `still (detector)`).
pub fn heading_error_svg_labelled(
    title: &str,
    series: &[HeadingSeries<'_>],
    still_spans_s: &[(f64, f64)],
    still_label: &str,
) -> Result<String> {
    let err = |e: String| anyhow!("SVG plot `{title}`: {e}");
    let t_end = series
        .iter()
        .filter_map(|s| s.heading_deg.points().last().map(|p| p.0))
        .fold(0.0f64, f64::max);
    let (t_scale, t_unit) = time_axis(t_end);
    let pts: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.heading_deg
                .points()
                .into_iter()
                .map(|(t, h)| (t * t_scale, h))
                .collect()
        })
        .collect();
    let all = || pts.iter().flatten();
    let t_lo = all().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let t_hi = all().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let y_lo = all().map(|p| p.1).fold(0.0f64, f64::min);
    let y_hi = all().map(|p| p.1).fold(0.0f64, f64::max);
    let (t_lo, t_hi) = if t_lo < t_hi {
        (t_lo, t_hi)
    } else {
        (0.0, 1.0)
    };
    let m = 0.05 * (y_hi - y_lo);
    let (y_lo, y_hi) = if m > 0.0 {
        (y_lo - m, y_hi + m)
    } else {
        (-1.0, 1.0)
    };
    let (y_lo, y_hi) = with_legend_room(y_lo, y_hi, series.len() + 1);
    let (x_step, y_step) = ((t_hi - t_lo) / 10.0, (y_hi - y_lo) / 10.0);
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (900, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(t_lo..t_hi, y_lo..y_hi)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(format!("time since power-on ({t_unit})"))
            .y_desc("heading error (deg)")
            .x_label_formatter(&|v| tick_label(*v, x_step))
            .y_label_formatter(&|v| tick_label(*v, y_step))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        let shade = RGBColor(200, 230, 200).mix(0.6).filled();
        chart
            .draw_series(
                still_spans_s.iter().map(|&(a, b)| {
                    Rectangle::new([(a * t_scale, y_lo), (b * t_scale, y_hi)], shade)
                }),
            )
            .map_err(|e| err(e.to_string()))?
            .label(still_label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], shade));
        for (i, (s, p)) in series.iter().zip(pts).enumerate() {
            let c = COLOURS[i % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(p, c.stroke_width(2)))
                .map_err(|e| err(e.to_string()))?
                .label(s.label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_readable() {
        assert_eq!(tick_label(6.939e-18, 0.1), "0");
        assert_eq!(tick_label(0.25, 0.05), "0.25");
        assert_eq!(tick_label(-1.5, 0.5), "-1.5");
        assert_eq!(tick_label(120.0, 20.0), "120");
        assert_eq!(tick_label(0.0012, 0.0002), "0.0012");
        assert_eq!(tick_label(-1e-9, 0.5), "0");
    }

    #[test]
    fn still_spans_from_flags() {
        let t = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let s = [true, true, false, false, true, true];
        assert_eq!(still_spans(&t, &s), vec![(0.0, 1.0), (4.0, 5.0)]);
    }

    #[test]
    fn spans_stay_bounded_and_cover_every_still_sample() {
        let mut sp = Spans::new(8);
        let flags: Vec<bool> = (0..1000).map(|i| i % 7 < 3).collect();
        for (i, &f) in flags.iter().enumerate() {
            sp.push(i as f64, f);
        }
        let spans = sp.spans();
        assert!(spans.len() <= 9, "{}", spans.len());
        assert!(spans.windows(2).all(|w| w[0].1 < w[1].0), "{spans:?}");
        for (i, &f) in flags.iter().enumerate() {
            let t = i as f64;
            if f {
                assert!(spans.iter().any(|&(a, b)| a <= t && t <= b), "{t}");
            }
        }
    }

    #[test]
    fn svg_has_readable_axes_legend_and_shading() {
        let t: Vec<f64> = (0..3000).map(|i| i as f64).collect(); // 50 min -> minutes
        let a: Vec<f64> = t.iter().map(|x| 1e-3 * x).collect();
        let b: Vec<f64> = t.iter().map(|x| -2e-4 * x + 1e-17).collect();
        let decimated = |v: &[f64]| {
            let mut m = MinMax::default();
            for (&t, &h) in t.iter().zip(v) {
                m.push(t, h);
            }
            m
        };
        let (a, b) = (decimated(&a), decimated(&b));
        let series = [
            HeadingSeries {
                label: "none",
                heading_deg: &a,
            },
            HeadingSeries {
                label: "gated Kalman",
                heading_deg: &b,
            },
        ];
        let svg = heading_error_svg("Heading error: test", &series, &[(0.0, 300.0)]).expect("svg");
        for want in [
            "time since power-on (min)",
            "heading error (deg)",
            "none",
            "gated Kalman",
            "still (truth)",
            "<rect",
        ] {
            assert!(svg.contains(want), "missing {want}");
        }
        let labels: Vec<&str> = svg
            .split("<text")
            .skip(1)
            .filter_map(|s| s.split('>').nth(1))
            .map(|s| s.split('<').next().unwrap_or("").trim())
            .collect();
        assert!(labels.iter().all(|l| !l.contains("e-")), "{labels:?}");
        let numeric: Vec<f64> = labels.iter().filter_map(|l| l.parse().ok()).collect();
        assert!(numeric.len() >= 8, "{labels:?}");
        assert!(labels.contains(&"0"), "{labels:?}");
        // Minutes axis reaches 49.98; heading axis spans -0.6 .. 3.
        assert!(
            numeric.iter().any(|&v| (40.0..=50.0).contains(&v)),
            "{labels:?}"
        );
        assert!(labels.iter().any(|l| l.contains('.')), "{labels:?}");
    }
}
