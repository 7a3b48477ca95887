//! The plots of a study: errors against N^(−1/2) with reference slopes, and iterations per level;
//! the log-log plot is shared with adaptive refinement.

use super::{quantities, Level};
use plotters::coord::ranged1d::Ranged;
use plotters::prelude::*;
use std::path::Path;

/// Draws a labelled polyline with its points marked.
fn marked_line<'a, DB: DrawingBackend + 'a, X: Ranged<ValueType = f64>, Y: Ranged<ValueType = f64>>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    name: &str,
    points: &[(f64, f64)],
    color: RGBAColor,
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("cannot draw the plot: {e}");
    chart
        .draw_series(LineSeries::new(points.to_vec(), color.stroke_width(2)))
        .map_err(err)?
        .label(name)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    chart
        .draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))
        .map_err(err)?;
    Ok(())
}

/// Draws the legend and writes the picture.
fn finish<'a, DB: DrawingBackend + 'a, X: Ranged<ValueType = f64>, Y: Ranged<ValueType = f64>>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    position: SeriesLabelPosition,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(position)
        .draw()
        .map_err(|e| format!("cannot draw the plot: {e}"))?;
    chart
        .plotting_area()
        .present()
        .map_err(|e| format!("cannot write the plot: {e}"))
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

/// A log-log plot of the errors against N^(−1/2) for one or more studies (labelled series), with
/// reference slopes 1 and 2.
pub fn errors(path: &Path, title: &str, studies: &[(String, &[Level])]) -> Result<(), String> {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (label, levels) in studies {
        let Some(first) = levels.first() else { continue };
        for (k, (name, _, _)) in quantities(first).into_iter().enumerate() {
            let points: Vec<(f64, f64)> = levels
                .iter()
                .filter_map(|l| Some(((l.vertices as f64).powf(-0.5), quantities(l)[k].2?)))
                .filter(|p| p.1 > 1e-12)
                .collect();
            if !points.is_empty() {
                let prefix = if studies.len() > 1 {
                    format!("{label}: ")
                } else {
                    String::new()
                };
                series.push((format!("{prefix}{name}"), points));
            }
        }
    }
    loglog(path, title, &series, &[1.0, 2.0])
}

/// A log-log plot of labelled series of (N^(−1/2), value) with reference lines of the given slopes.
pub(crate) fn loglog(
    path: &Path,
    title: &str,
    series: &[(String, Vec<(f64, f64)>)],
    slopes: &[f64],
) -> Result<(), String> {
    register_font()?;
    if series.is_empty() {
        return Ok(());
    }
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.1.iter().copied()).collect();
    let (x0, x1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (y0, y1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    let err = |e: &dyn std::fmt::Display| format!("{}: cannot draw the plot: {e}", path.display());
    let root = BitMapBackend::new(path, (900, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0 / 1.3..x1 * 1.3).log_scale(), (y0 / 3.0..y1 * 3.0).log_scale())
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("N^(-1/2)  (N = number of vertices)")
        .y_desc("error")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, (name, points)) in series.iter().enumerate() {
        marked_line(&mut chart, name, points, Palette99::pick(i).to_rgba())?;
    }
    for (k, &slope) in slopes.iter().enumerate() {
        let style = BLACK
            .mix(1.0 - 0.5 * k as f64 / slopes.len() as f64)
            .stroke_width(1);
        let anchor = y1;
        let line = vec![(x1, anchor), (x0, anchor * (x0 / x1).powf(slope))];
        chart
            .draw_series(LineSeries::new(line, style))
            .map_err(|e| err(&e))?
            .label(format!("slope {slope:.3}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    finish(&mut chart, SeriesLabelPosition::LowerRight).map_err(|e| format!("{}: {e}", path.display()))
}

/// Iterations per level, nested and (when computed) cold.
pub fn iterations(path: &Path, title: &str, levels: &[Level]) -> Result<(), String> {
    register_font()?;
    let err = |e: &dyn std::fmt::Display| format!("{}: cannot draw the plot: {e}", path.display());
    let max = levels
        .iter()
        .map(|l| l.cold_iterations.unwrap_or(0).max(l.iterations))
        .max()
        .unwrap_or(1);
    let root = BitMapBackend::new(path, (700, 450)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(
            (root_n(&levels[0]) / 1.5..root_n(&levels[levels.len() - 1]) * 1.5).log_scale(),
            0.0..(max as f64 * 1.15 + 1.0),
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("√N (N vertices)")
        .y_desc("active-set iterations")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(|e| err(&e))?;
    let nested: Vec<(f64, f64)> = levels.iter().map(|l| (root_n(l), l.iterations as f64)).collect();
    let cold: Vec<(f64, f64)> = levels
        .iter()
        .filter_map(|l| Some((root_n(l), l.cold_iterations? as f64)))
        .collect();
    for (name, points, color) in [("nested iteration", nested, BLUE), ("cold start", cold, RED)] {
        if points.is_empty() {
            continue;
        }
        marked_line(&mut chart, name, &points, color.to_rgba())?;
    }
    finish(&mut chart, SeriesLabelPosition::UpperLeft).map_err(|e| format!("{}: {e}", path.display()))
}

/// √N, N the vertices of a level: the x axis of the iteration plot, for every kind of mesh.
fn root_n(level: &Level) -> f64 {
    (level.vertices as f64).sqrt()
}
