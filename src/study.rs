//! Convergence studies: one case on a sequence of uniformly refined meshes, each level
//! warm-started from the previous one (nested iteration), with error norms, experimental orders of
//! convergence (EOC), iteration counts and timings, written as Markdown, CSV, JSON and PNG plots.
//!
//! EOCs are computed against h (the largest triangle diameter) and against N^(−1/2) (N the number
//! of vertices); the second is the fair measure for graded meshes (Remark 10).

use crate::case::Case;
use crate::norms::Errors;
use crate::run::{self, RunError, Start};
use plotters::coord::ranged1d::Ranged;
use plotters::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// One level of a study.
#[derive(Debug, Clone, Serialize)]
pub struct Level {
    pub cells: usize,
    pub h: f64,
    pub vertices: usize,
    pub errors: Option<Errors>,
    /// Active-set iterations with nested iteration (warm start from the previous level).
    pub iterations: usize,
    /// Active-set iterations from a cold start (no contact), when asked for.
    pub cold_iterations: Option<usize>,
    pub seconds: f64,
}

/// The settings of a study.
#[derive(Debug, Clone)]
pub struct StudyOptions {
    /// Cells per side on each level, increasing.
    pub levels: Vec<usize>,
    /// Also solve each level from a cold start, to compare iteration counts.
    pub cold: bool,
    /// Largest level (cells per side) on which the H⁻¹ norm is computed (it costs a solve on S_h).
    pub h_minus_1_max: usize,
}

/// Runs the study, calling `progress(level index)` after each level.
pub fn run(
    case: &Case,
    options: &StudyOptions,
    mut progress: impl FnMut(usize, &Level),
) -> Result<Vec<Level>, RunError> {
    let mut levels = Vec::new();
    let mut previous: Option<run::Run> = None;
    for (i, &cells) in options.levels.iter().enumerate() {
        let mut c = case.clone();
        c.set_cells(cells);
        let warm = previous.as_ref().map(|r| (&r.problem.mesh, &r.solution));
        let mut r = run::solve(&c, Start::Cold, warm)?;
        if cells <= options.h_minus_1_max {
            r.compute_h_minus_1(&c);
        }
        let cold_iterations = if options.cold && warm.is_some() {
            // A cold start needs about one iteration per ring of vertices the contact set spans.
            let mut cold_case = c.clone();
            cold_case.options.max_iterations = cold_case.options.max_iterations.max(4 * cells);
            let cold = run::solve(&cold_case, Start::Cold, None)?;
            Some(cold.solution.obstacle.stats.iterations)
        } else if options.cold {
            Some(r.solution.obstacle.stats.iterations)
        } else {
            None
        };
        let level = Level {
            cells,
            h: r.problem.mesh.h(),
            vertices: r.problem.mesh.n_vertices(),
            errors: r.errors.clone(),
            iterations: r.solution.obstacle.stats.iterations,
            cold_iterations,
            seconds: r.timings.contact_solve + r.timings.assembly + r.timings.mesh,
        };
        progress(i, &level);
        levels.push(level);
        previous = Some(r);
    }
    Ok(levels)
}

/// The quantities tabulated for each level: (label, short name, value).
fn quantities(level: &Level) -> Vec<(&'static str, &'static str, Option<f64>)> {
    let e = level.errors.as_ref();
    let finite = |v: f64| v.is_finite().then_some(v);
    vec![
        ("|u1−u1h|_H1", "h1_u1", e.and_then(|e| finite(e.h1_u1))),
        ("|u2−u2h|_H1", "h1_u2", e.and_then(|e| finite(e.h1_u2))),
        ("energy", "energy", e.and_then(|e| finite(e.energy))),
        ("‖u1−u1h‖_L2", "l2_u1", e.map(|e| e.l2_u1)),
        ("‖u2−u2h‖_L2", "l2_u2", e.map(|e| e.l2_u2)),
        ("‖λ−λh‖_L2", "l2_lambda", e.map(|e| e.l2_lambda)),
        (
            "‖λ−λh‖_H⁻¹",
            "hm1_lambda",
            e.and_then(|e| finite(e.h_minus_1_lambda)),
        ),
    ]
}

/// EOC between two levels against h and against N^(−1/2); None when an error is negligible.
pub fn eoc(a: &Level, b: &Level, ea: f64, eb: f64) -> Option<(f64, f64)> {
    (ea > 1e-12 && eb > 1e-12).then(|| {
        let r = (ea / eb).ln();
        (
            r / (a.h / b.h).ln(),
            2.0 * r / (b.vertices as f64 / a.vertices as f64).ln(),
        )
    })
}

/// The study as a Markdown table (EOCs against h, and against N^(−1/2) in parentheses).
pub fn markdown(title: &str, levels: &[Level]) -> String {
    let mut s = format!("## {title}\n\n");
    let names: Vec<&str> = levels.first().map_or(vec![], |l| {
        quantities(l)
            .into_iter()
            .filter(|q| q.2.is_some())
            .map(|q| q.0)
            .collect()
    });
    s += "| cells | h | vertices |";
    for n in &names {
        let _ = write!(s, " {n} | EOC h (N) |");
    }
    s += " iterations (nested) | iterations (cold) | seconds |\n|";
    s += &"---|".repeat(3 + 2 * names.len() + 3);
    s += "\n";
    for (i, l) in levels.iter().enumerate() {
        let _ = write!(s, "| {}² | {:.4e} | {} |", l.cells, l.h, l.vertices);
        for (label, _, value) in quantities(l) {
            if !names.contains(&label) {
                continue;
            }
            let previous = i.checked_sub(1).and_then(|j| {
                let p = quantities(&levels[j]).into_iter().find(|q| q.0 == label)?.2?;
                eoc(&levels[j], l, p, value?)
            });
            let _ = write!(
                s,
                " {} | {} |",
                value.map_or("—".into(), |v| format!("{v:.4e}")),
                previous.map_or("—".into(), |(h, n)| format!("{h:.3} ({n:.3})"))
            );
        }
        let _ = writeln!(
            s,
            " {} | {} | {:.3} |",
            l.iterations,
            l.cold_iterations.map_or("—".into(), |c| c.to_string()),
            l.seconds
        );
    }
    s
}

/// The study as CSV, one row per level, with EOCs against h.
pub fn csv(levels: &[Level]) -> String {
    let mut s = String::from("cells,h,vertices");
    if let Some(l) = levels.first() {
        for (_, name, _) in quantities(l) {
            let _ = write!(s, ",{name},eoc_{name}");
        }
    }
    s += ",iterations,cold_iterations,seconds\n";
    for (i, l) in levels.iter().enumerate() {
        let _ = write!(s, "{},{:e},{}", l.cells, l.h, l.vertices);
        for (k, (_, _, value)) in quantities(l).into_iter().enumerate() {
            let e = i
                .checked_sub(1)
                .and_then(|j| eoc(&levels[j], l, quantities(&levels[j])[k].2?, value?));
            let _ = write!(
                s,
                ",{},{}",
                value.map_or(String::new(), |v| format!("{v:e}")),
                e.map_or(String::new(), |e| format!("{:.4}", e.0))
            );
        }
        let cold = l.cold_iterations.map_or(String::new(), |c| c.to_string());
        let _ = writeln!(s, ",{},{cold},{:.4}", l.iterations, l.seconds);
    }
    s
}

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
pub fn plot_errors(path: &Path, title: &str, studies: &[(String, &[Level])]) -> Result<(), String> {
    register_font()?;
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (label, levels) in studies {
        let Some(first) = levels.first() else { continue };
        for (k, (name, _, _)) in quantities(first).into_iter().enumerate() {
            let points: Vec<(f64, f64)> = levels
                .iter()
                .filter_map(|l| Some(((l.vertices as f64).powf(-0.5), quantities(l)[k].2?)))
                .filter(|p| p.1 > 1e-12)
                .collect();
            if points.len() >= 2 {
                let prefix = if studies.len() > 1 {
                    format!("{label}: ")
                } else {
                    String::new()
                };
                series.push((format!("{prefix}{name}"), points));
            }
        }
    }
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
    for (slope, style) in [
        (1.0, BLACK.stroke_width(1)),
        (2.0, BLACK.mix(0.5).stroke_width(1)),
    ] {
        let anchor = y1;
        let line = vec![(x1, anchor), (x0, anchor * (x0 / x1).powf(slope))];
        chart
            .draw_series(LineSeries::new(line, style))
            .map_err(|e| err(&e))?
            .label(format!("slope {slope}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    finish(&mut chart, SeriesLabelPosition::LowerRight).map_err(|e| format!("{}: {e}", path.display()))
}

/// Iterations per level, nested and (when computed) cold.
pub fn plot_iterations(path: &Path, title: &str, levels: &[Level]) -> Result<(), String> {
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
            (levels[0].cells as f64 / 1.5..levels[levels.len() - 1].cells as f64 * 1.5).log_scale(),
            0.0..(max as f64 * 1.15 + 1.0),
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("cells per side")
        .y_desc("active-set iterations")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(|e| err(&e))?;
    let nested: Vec<(f64, f64)> = levels
        .iter()
        .map(|l| (l.cells as f64, l.iterations as f64))
        .collect();
    let cold: Vec<(f64, f64)> = levels
        .iter()
        .filter_map(|l| Some((l.cells as f64, l.cold_iterations? as f64)))
        .collect();
    for (name, points, color) in [("nested iteration", nested, BLUE), ("cold start", cold, RED)] {
        if points.is_empty() {
            continue;
        }
        marked_line(&mut chart, name, &points, color.to_rgba())?;
    }
    finish(&mut chart, SeriesLabelPosition::UpperLeft).map_err(|e| format!("{}: {e}", path.display()))
}
