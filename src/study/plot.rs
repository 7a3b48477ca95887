//! The plots of a study and of adaptive refinement: errors and η against N^(−1/2) on log-log axes
//! with the guides that mean something for them, and active-set iterations per level.
//!
//! The geometry is computed here, not left to the plotting library: the axes are drawn in
//! decades (log10 of the values, on linear coordinates), their ticks come from [`log_ticks`] and
//! a guide of slope s is the segment of [`guide`], cut where it leaves the frame (clamping its end
//! to the frame would change its slope).

use super::{quantities, Level};
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;

/// The size of the log-log pictures, in pixels.
const SIZE: (u32, u32) = (1000, 720);
/// Font sizes: caption, axis names, tick labels, legend.
const FONTS: (u32, u32, u32, u32) = (26, 19, 17, 16);

/// A rectangle of a log-log chart in decades: log10 of its x range and of its y range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Frame {
    /// log10 of the smallest and the largest x.
    pub x: (f64, f64),
    /// log10 of the smallest and the largest y.
    pub y: (f64, f64),
}

impl Frame {
    /// The frame around points given in decades, widened by `pad` decades on every side.
    fn around(points: impl Iterator<Item = (f64, f64)>, pad: f64) -> Frame {
        let (mut x, mut y) = ((f64::MAX, f64::MIN), (f64::MAX, f64::MIN));
        for (px, py) in points {
            x = (x.0.min(px), x.1.max(px));
            y = (y.0.min(py), y.1.max(py));
        }
        Frame {
            x: (x.0 - pad, x.1 + pad),
            y: (y.0 - pad, y.1 + pad),
        }
    }
}

/// The guide of slope `slope` (in decades per decade) through `anchor`, over the x interval
/// `span`, all in decades: the segment of the line y = y_a + slope (x − x_a) for x in `span`
/// that lies inside `frame`. The line is cut where it leaves the frame, so the segment keeps its
/// slope; None when no part of it is inside.
pub(crate) fn guide(
    frame: &Frame,
    anchor: (f64, f64),
    slope: f64,
    span: (f64, f64),
) -> Option<[(f64, f64); 2]> {
    let y = |x: f64| anchor.1 + slope * (x - anchor.0);
    let (mut lo, mut hi) = (span.0.max(frame.x.0), span.1.min(frame.x.1));
    if slope == 0.0 {
        if !(frame.y.0..=frame.y.1).contains(&anchor.1) {
            return None;
        }
    } else {
        // The x where the line crosses the bottom and the top of the frame.
        let (a, b) = (
            anchor.0 + (frame.y.0 - anchor.1) / slope,
            anchor.0 + (frame.y.1 - anchor.1) / slope,
        );
        lo = lo.max(a.min(b));
        hi = hi.min(a.max(b));
    }
    (lo < hi).then(|| [(lo, y(lo)), (hi, y(hi))])
}

/// The ticks of a log axis, in decades.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Ticks {
    /// The labelled ticks: every decade in range; also 2 and 5 times a decade when a decade is at
    /// least [`LABEL_PIXELS`] wide or fewer than two decades are in range; every integer multiple
    /// when that still gives fewer than two.
    pub labelled: Vec<f64>,
    /// The minor ticks (thin grid lines): 2, 3, …, 9 times each decade, when a decade is at least
    /// [`MINOR_PIXELS`] wide.
    pub minor: Vec<f64>,
}

/// The width of a decade, in pixels, from which its minor ticks are drawn.
pub(crate) const MINOR_PIXELS: f64 = 60.0;
/// The width of a decade, in pixels, from which 2 and 5 times it are labelled too.
pub(crate) const LABEL_PIXELS: f64 = 250.0;

/// The ticks of a log axis from 10^`lo` to 10^`hi` drawn over `pixels` pixels.
pub(crate) fn log_ticks(lo: f64, hi: f64, pixels: f64) -> Ticks {
    let inside = |v: &f64| *v >= lo - 1e-9 && *v <= hi + 1e-9;
    let multiples = |ks: &[f64]| -> Vec<f64> {
        let (first, last) = (lo.floor() as i32, hi.ceil() as i32);
        (first..=last)
            .flat_map(|d| ks.iter().map(move |k| f64::from(d) + k.log10()))
            .filter(inside)
            .collect()
    };
    let decade = pixels / (hi - lo);
    let mut labelled = multiples(&[1.0]);
    if labelled.len() < 2 || decade >= LABEL_PIXELS {
        labelled = multiples(&[1.0, 2.0, 5.0]);
    }
    if labelled.len() < 2 {
        labelled = multiples(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    }
    let minor = if decade >= MINOR_PIXELS {
        multiples(&[2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
    } else {
        Vec::new()
    };
    Ticks { labelled, minor }
}

/// The label of the tick at 10^`v`: 10⁻², 1, 10, 10³, or 2×10⁻² between decades.
pub(crate) fn log_label(v: f64) -> String {
    let decade = (v + 1e-9).floor();
    let mantissa = 10f64.powf(v - decade).round();
    let d = decade as i32;
    let power = match d {
        0 => "1".to_string(),
        1 => "10".to_string(),
        _ => {
            const SUPERSCRIPT: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
            let digits: String = (d.unsigned_abs().to_string().bytes())
                .map(|b| SUPERSCRIPT[usize::from(b - b'0')])
                .collect();
            format!("10{}{digits}", if d < 0 { "⁻" } else { "" })
        }
    };
    match (mantissa as i32, d) {
        (1, _) => power,
        (m, 0) => m.to_string(),
        (m, 1) => (m * 10).to_string(),
        (m, _) => format!("{m}×{power}"),
    }
}

/// A linear axis with the ticks given: the decades of a log axis ([`log_ticks`]), or whole
/// numbers.
struct Axis {
    /// The range drawn.
    range: Range<f64>,
    /// The ticks, labelled and minor.
    ticks: Ticks,
}

impl Ranged for Axis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let r = (value - self.range.start) / (self.range.end - self.range.start);
        limit.0 + (r * f64::from(limit.1 - limit.0)).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.ticks.minor.clone()
        } else {
            self.ticks.labelled.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

/// The slope of the last two points of a series in decades (the EOC of the two finest levels);
/// None for a single point.
fn last_slope(points: &[(f64, f64)]) -> Option<f64> {
    let [.., a, b] = points else { return None };
    Some((b.1 - a.1) / (b.0 - a.0))
}

/// Draws a polyline with its points marked.
fn marked_line<'a, DB: DrawingBackend + 'a, X: Ranged<ValueType = f64>, Y: Ranged<ValueType = f64>>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    points: &[(f64, f64)],
    color: RGBAColor,
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("cannot draw the plot: {e}");
    chart
        .draw_series(LineSeries::new(points.to_vec(), color.stroke_width(2)))
        .map_err(err)?;
    chart
        .draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))
        .map_err(err)?;
    Ok(())
}

/// One entry of a legend: its text, its colour, and whether its line is dashed (a guide).
type Entry = (String, RGBAColor, bool);

/// The width of the legend beside a chart, in pixels.
const LEGEND_WIDTH: u32 = 380;

/// Draws the legend in `area`, beside the chart (never over its data), and writes the picture.
fn legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    entries: &[Entry],
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("cannot draw the plot: {e}");
    let font = ("sans-serif", FONTS.3).into_font();
    let (row, top) = (24, 60);
    for (k, (text, color, dashed)) in entries.iter().enumerate() {
        let y = top + row * k as i32;
        let style = color.stroke_width(2);
        let pieces: Vec<(i32, i32)> = if *dashed {
            vec![(0, 8), (14, 22), (28, 34)]
        } else {
            vec![(0, 34)]
        };
        for (a, b) in pieces {
            area.draw(&PathElement::new(vec![(8 + a, y), (8 + b, y)], style))
                .map_err(err)?;
        }
        if !dashed {
            area.draw(&Circle::new((25, y), 3, color.filled())).map_err(err)?;
        }
        area.draw(&Text::new(text.clone(), (50, y - 9), font.clone()))
            .map_err(err)?;
    }
    area.present().map_err(|e| format!("cannot write the plot: {e}"))
}

/// Registers a TrueType font for plot labels (plotters draws text with ab_glyph).
fn register_font() -> Result<(), String> {
    const FONTS: [&str; 2] = [
        "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/TTF/DejaVuSans.ttf",
    ];
    let bytes = FONTS
        .iter()
        .find_map(|p| std::fs::read(p).ok())
        .ok_or("plots need the DejaVu Sans font (Debian package fonts-dejavu-core)")?;
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        Box::leak(bytes.into_boxed_slice()),
    )
    .map_err(|_| "the DejaVu Sans font file is not a valid font".to_string())
}

/// A reference line of a log-log plot, drawn beside one of its series.
#[derive(Debug, Clone)]
pub(crate) struct Guide {
    /// Its slope on the plot's axes.
    pub slope: f64,
    /// What it stands for, for the legend.
    pub label: String,
    /// The index of the series it is drawn beside: through twice the series' value at its largest
    /// x (its coarsest mesh), over the series' x range.
    pub beside: usize,
}

/// The x axis of the log-log plots, and which way the finer meshes lie on it.
const X_NAME: &str = "N^(−1/2), N = number of vertices   (← finer meshes)";

/// A log-log plot of the errors (and η) of one or more studies (labelled series) against
/// N^(−1/2), each labelled with its EOC over the two finest levels, with the guides of the rates
/// of P1 elements for a smooth solution: slope 1 beside the energy error (H¹ rate), slope 2 beside
/// ‖u1 − u1h‖_L² (L² rate). Whether it was drawn (see [`loglog`]).
pub fn errors(path: &Path, title: &str, studies: &[(String, &[Level])]) -> Result<bool, String> {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    let mut guides = Vec::new();
    let mut estimator = false;
    for (label, levels) in studies {
        let Some(first) = levels.first() else { continue };
        for (k, (name, short, _)) in quantities(first).into_iter().enumerate() {
            let points: Vec<(f64, f64)> = levels
                .iter()
                .filter_map(|l| Some((l, quantities(l)[k].2?)))
                .filter(|&(l, value)| super::resolved(l, short, value))
                .map(|(l, value)| ((l.vertices as f64).powf(-0.5), value))
                .collect();
            if points.is_empty() {
                continue;
            }
            let prefix = if studies.len() > 1 {
                format!("{label}: ")
            } else {
                String::new()
            };
            let decades: Vec<(f64, f64)> = points.iter().map(|p| (p.0.log10(), p.1.log10())).collect();
            let eoc =
                last_slope(&decades).map_or(String::new(), |s| format!("  (EOC of the finest two {s:.2})"));
            estimator |= short == "estimator";
            if guides.len() < 2 && series.len() < 8 {
                let theory = match short {
                    "energy" => Some((1.0, "slope 1: H¹ rate of P1 (smooth u)")),
                    "l2_u1" | "l2_u" => Some((2.0, "slope 2: L² rate of P1 (smooth u)")),
                    _ => None,
                };
                if let Some((slope, text)) = theory.filter(|_| points.len() > 1) {
                    guides.push(Guide {
                        slope,
                        label: text.to_string(),
                        beside: series.len(),
                    });
                }
            }
            series.push((format!("{prefix}{name}{eoc}"), points));
        }
    }
    let y_name = if estimator {
        "error, and η (bound of the energy error)"
    } else {
        "error"
    };
    loglog(path, title, y_name, &series, &guides)
}

/// A log-log plot of labelled series of (N^(−1/2), value), with `guides`; `y_name` says what the
/// values are. Whether it was drawn: not when no value has a place on a log axis (every one 0 or
/// not finite), and then no file is written.
pub(crate) fn loglog(
    path: &Path,
    title: &str,
    y_name: &str,
    series: &[(String, Vec<(f64, f64)>)],
    guides: &[Guide],
) -> Result<bool, String> {
    register_font()?;
    let decades: Vec<Vec<(f64, f64)>> = series.iter().map(|s| decades(&s.1)).collect();
    if decades.iter().all(Vec::is_empty) {
        return Ok(false);
    }
    let guides: Vec<Guide> = (guides.iter())
        .filter(|g| !decades[g.beside].is_empty())
        .cloned()
        .collect();
    let anchors = guide_anchors(&decades, &guides);
    let frame = Frame::around(
        decades
            .iter()
            .flatten()
            .copied()
            .chain(anchors.iter().map(|a| a.0)),
        0.12,
    );
    let err = |e: &dyn std::fmt::Display| format!("{}: cannot draw the plot: {e}", path.display());
    let root = BitMapBackend::new(path, (SIZE.0 + LEGEND_WIDTH, SIZE.1)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (plot, side) = root.split_horizontally(SIZE.0);
    let (margin, x_area, y_area) = (16, 60, 90);
    let xt = log_ticks(frame.x.0, frame.x.1, f64::from(SIZE.0 - 2 * margin - y_area));
    let yt = log_ticks(frame.y.0, frame.y.1, f64::from(SIZE.1 - 2 * margin - x_area - 40));
    let mut chart = ChartBuilder::on(&plot)
        .caption(title, ("sans-serif", FONTS.0))
        .margin(margin)
        .x_label_area_size(x_area)
        .y_label_area_size(y_area)
        .build_cartesian_2d(
            Axis {
                range: frame.x.0..frame.x.1,
                ticks: xt,
            },
            Axis {
                range: frame.y.0..frame.y.1,
                ticks: yt,
            },
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(X_NAME)
        .y_desc(y_name)
        .axis_desc_style(("sans-serif", FONTS.1))
        .label_style(("sans-serif", FONTS.2))
        .x_label_formatter(&|v| log_label(*v))
        .y_label_formatter(&|v| log_label(*v))
        .draw()
        .map_err(|e| err(&e))?;
    let mut entries: Vec<Entry> = Vec::new();
    for (i, ((name, _), points)) in series.iter().zip(&decades).enumerate() {
        if points.is_empty() {
            continue;
        }
        let color = Palette99::pick(i).to_rgba();
        marked_line(&mut chart, points, color)?;
        entries.push((name.clone(), color, false));
    }
    for (k, (g, &(anchor, finest))) in guides.iter().zip(&anchors).enumerate() {
        let Some(segment) = guide(&frame, anchor, g.slope, (finest, anchor.0)) else {
            continue;
        };
        let color = BLACK.mix(1.0 - 0.35 * k as f64);
        chart
            .draw_series(DashedLineSeries::new(segment, 10, 6, color.stroke_width(2)))
            .map_err(|e| err(&e))?;
        entries.push((g.label.clone(), color, true));
    }
    legend(&side, &entries).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(true)
}

/// The points (x, y) at their decades (log10), but those a log axis has no place for: 0 (η of a
/// solution exact in P1) and what is not finite.
fn decades(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    (points.iter())
        .filter(|p| [p.0, p.1].iter().all(|v| v.is_finite() && *v > 0.0))
        .map(|p| (p.0.log10(), p.1.log10()))
        .collect()
}

/// Where each guide starts, and the x at which it ends (in decades): over its series' x range,
/// from twice the series' value at its coarsest mesh.
fn guide_anchors(decades: &[Vec<(f64, f64)>], guides: &[Guide]) -> Vec<((f64, f64), f64)> {
    (guides.iter())
        .map(|g| {
            let points = &decades[g.beside];
            let coarsest =
                (points.iter().copied()).fold((f64::MIN, 0.0), |a, p| if p.0 > a.0 { p } else { a });
            let finest = points.iter().map(|p| p.0).fold(f64::MAX, f64::min);
            ((coarsest.0, coarsest.1 + 2f64.log10()), finest)
        })
        .collect()
}

/// Iterations per level, nested and (when computed) cold, against √N.
pub fn iterations(path: &Path, title: &str, levels: &[Level]) -> Result<(), String> {
    register_font()?;
    let err = |e: &dyn std::fmt::Display| format!("{}: cannot draw the plot: {e}", path.display());
    let max = levels
        .iter()
        .map(|l| l.cold_iterations.unwrap_or(0).max(l.iterations))
        .max()
        .unwrap_or(1);
    let size = (800, 500);
    let (margin, x_area, y_area) = (16, 55, 60);
    let root = BitMapBackend::new(path, (size.0 + LEGEND_WIDTH / 2 + 20, size.1)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (plot, side) = root.split_horizontally(size.0);
    let x = |l: &Level| root_n(l).log10();
    let (x0, x1) = (x(&levels[0]) - 0.1, x(&levels[levels.len() - 1]) + 0.1);
    let xt = log_ticks(x0, x1, f64::from(size.0 - 2 * margin - y_area));
    let top = max + 1;
    let step = (top / 8).max(1);
    let whole: Vec<f64> = (0..=top).step_by(step).map(|k| k as f64).collect();
    let mut chart = ChartBuilder::on(&plot)
        .caption(title, ("sans-serif", FONTS.0 - 4))
        .margin(margin)
        .x_label_area_size(x_area)
        .y_label_area_size(y_area)
        .build_cartesian_2d(
            Axis {
                range: x0..x1,
                ticks: xt,
            },
            Axis {
                range: 0.0..top as f64 + 0.3,
                ticks: Ticks {
                    labelled: whole,
                    minor: Vec::new(),
                },
            },
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("√N, N = number of vertices   (finer meshes →)")
        .y_desc("active-set iterations")
        .axis_desc_style(("sans-serif", FONTS.1 - 2))
        .label_style(("sans-serif", FONTS.2 - 2))
        .x_label_formatter(&|v| format!("{:.0}", 10f64.powf(*v)))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(|e| err(&e))?;
    let nested: Vec<(f64, f64)> = levels.iter().map(|l| (x(l), l.iterations as f64)).collect();
    let cold: Vec<(f64, f64)> = levels
        .iter()
        .filter_map(|l| Some((x(l), l.cold_iterations? as f64)))
        .collect();
    let mut entries: Vec<Entry> = Vec::new();
    for (name, points, color) in [("nested iteration", nested, BLUE), ("cold start", cold, RED)] {
        if !points.is_empty() {
            marked_line(&mut chart, &points, color.to_rgba())?;
            entries.push((name.to_string(), color.to_rgba(), false));
        }
    }
    legend(&side, &entries).map_err(|e| format!("{}: {e}", path.display()))
}

/// √N, N the vertices of a level: the x axis of the iteration plot, for every kind of mesh.
fn root_n(level: &Level) -> f64 {
    (level.vertices as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Zeros and what is not finite are left out of a log axis (a zero η made its range start at
    /// 10^-∞, a tick per decade, and an `adapt` run took all the machine's memory).
    #[test]
    fn a_log_axis_leaves_out_what_it_cannot_show() {
        let points = [
            (1.0, 0.0),
            (0.1, 1e-3),
            (f64::NAN, 1.0),
            (0.01, f64::INFINITY),
            (0.5, -1.0),
        ];
        assert_eq!(decades(&points), [(-1.0, -3.0)]);
    }

    /// With no value a log axis can show (every η 0 on a patch test), no plot is drawn and no
    /// file written, and the caller is told so (adapt.md linked a plot that did not exist).
    #[test]
    fn with_nothing_to_show_no_plot_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plot.png");
        let series = [("η".to_string(), vec![(0.1, 0.0), (0.05, 0.0)])];
        assert_eq!(loglog(&path, "title", "η", &series, &[]), Ok(false));
        assert!(!path.exists());
        let series = [("η".to_string(), vec![(0.1, 1e-3), (0.05, 0.0)])];
        assert_eq!(loglog(&path, "title", "η", &series, &[]), Ok(true));
        assert!(path.is_file());
    }

    fn slope(s: [(f64, f64); 2]) -> f64 {
        (s[1].1 - s[0].1) / (s[1].0 - s[0].0)
    }

    fn inside(frame: &Frame, p: (f64, f64)) -> bool {
        let e = 1e-12;
        p.0 >= frame.x.0 - e && p.0 <= frame.x.1 + e && p.1 >= frame.y.0 - e && p.1 <= frame.y.1 + e
    }

    #[test]
    fn a_guide_leaving_the_frame_is_cut_and_keeps_its_slope() {
        // Slope 2 from (−1, −0.5) over x in [−2, −1] would reach y = −2.5, below the frame's −2.
        let frame = Frame {
            x: (-2.1, -0.9),
            y: (-2.0, 0.0),
        };
        let s = guide(&frame, (-1.0, -0.5), 2.0, (-2.0, -1.0)).unwrap();
        assert!((slope(s) - 2.0).abs() < 1e-12, "slope {}", slope(s));
        assert!(inside(&frame, s[0]) && inside(&frame, s[1]), "{s:?}");
        assert!(
            (s[0].0 + 1.75).abs() < 1e-12 && (s[0].1 + 2.0).abs() < 1e-12,
            "cut at y = −2: {s:?}"
        );
        assert_eq!(s[1], (-1.0, -0.5));
    }

    #[test]
    fn guides_inside_outside_and_through_the_top() {
        let frame = Frame {
            x: (0.0, 3.0),
            y: (0.0, 1.0),
        };
        // Wholly inside: the span as given.
        assert_eq!(
            guide(&frame, (1.0, 0.5), 0.25, (0.5, 1.5)),
            Some([(0.5, 0.375), (1.5, 0.625)])
        );
        // Wholly above: nothing.
        assert_eq!(guide(&frame, (1.0, 2.0), 0.0, (0.0, 3.0)), None);
        assert_eq!(guide(&frame, (0.0, 5.0), 1.0, (0.0, 3.0)), None);
        // Negative slope through the top and the bottom: both ends cut, slope kept.
        let s = guide(&frame, (1.0, 0.5), -1.0, (-5.0, 5.0)).unwrap();
        assert!((slope(s) + 1.0).abs() < 1e-12 && inside(&frame, s[0]) && inside(&frame, s[1]));
        assert_eq!(s, [(0.5, 1.0), (1.5, 0.0)]);
        // Every slope and anchor: the segment is in the frame and has the slope asked for.
        for k in 0..200 {
            let (a, m) = (f64::from(k % 17) / 4.0 - 1.0, f64::from(k % 13) / 3.0 - 2.0);
            if let Some(s) = guide(&frame, (a, 0.3 * a), m, (-1.0, 4.0)) {
                assert!(inside(&frame, s[0]) && inside(&frame, s[1]), "{s:?}");
                assert!((slope(s) - m).abs() < 1e-9, "slope {} for {m}", slope(s));
            }
        }
    }

    #[test]
    fn every_decade_is_labelled_once() {
        // 1.3e-3 … 0.4: the decades 1e-2 and 1e-1, minor ticks on a wide axis, none on a narrow.
        let t = log_ticks(-2.9, -0.4, 500.0);
        assert_eq!(t.labelled, vec![-2.0, -1.0]);
        assert_eq!(t.minor.len(), 8 + 8 + 2, "{:?}", t.minor);
        assert!(t
            .minor
            .iter()
            .all(|m| (-2.9..=-0.4).contains(m) && m.fract() != 0.0));
        assert!(log_ticks(-8.0, 0.0, 300.0).minor.is_empty());
        assert_eq!(log_ticks(-8.0, 0.0, 300.0).labelled.len(), 9);
        // Less than a decade: 2 and 5 times a decade as well; inside one: every multiple.
        let labels = |t: Ticks| t.labelled.iter().map(|v| log_label(*v)).collect::<Vec<_>>();
        assert_eq!(labels(log_ticks(-1.5, -0.8, 500.0)), ["5×10⁻²", "10⁻¹"]);
        assert_eq!(labels(log_ticks(0.35, 0.8, 500.0)), ["3", "4", "5", "6"]);
        // Wide decades: 2 and 5 times each labelled too.
        assert_eq!(
            labels(log_ticks(-2.0, -0.5, 560.0)),
            ["10⁻²", "2×10⁻²", "5×10⁻²", "10⁻¹", "2×10⁻¹"]
        );
        for (lo, hi) in [(-5.3, 0.2), (-1.5, -0.8), (0.35, 0.8), (1.0, 3.0)] {
            let t = labels(log_ticks(lo, hi, 600.0));
            let mut unique = t.clone();
            unique.dedup();
            assert_eq!(t, unique, "no label twice");
            assert!(t.len() >= 2, "{lo} … {hi}: {t:?}");
        }
    }

    #[test]
    fn labels_name_the_decades() {
        let l: Vec<String> = [-3.0, -1.0, 0.0, 1.0, 2.0, 2f64.log10() - 2.0, 5f64.log10() + 1.0]
            .into_iter()
            .map(log_label)
            .collect();
        assert_eq!(l, ["10⁻³", "10⁻¹", "1", "10", "10²", "2×10⁻²", "50"]);
    }
}
