//! Convergence studies: one case on a sequence of meshes — built-in meshes of more and more cells
//! per side, or any mesh refined uniformly more and more times — each level
//! warm-started from the previous one (nested iteration), with error norms, experimental orders of
//! convergence (EOC), iteration counts and timings, written as Markdown, CSV, JSON and PNG plots
//! into one result directory, whole or not at all.
//!
//! EOCs are computed against h (the largest triangle diameter) and against N^(−1/2) (N the number
//! of vertices); the second is the fair measure for graded meshes (Remark 10).

pub(crate) mod plot;

use crate::atomic::{OutputError, Staging};
use crate::case::{Case, CaseError, Levels};
use crate::contact::Start;
use crate::norms::Errors;
use crate::run::{self, RunError};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// One level of a study.
#[derive(Debug, Clone, Serialize)]
pub struct Level {
    /// Cells per side of a built-in mesh (along the longer side of a rectangle).
    pub cells: Option<usize>,
    /// Cells along the shorter side of a rectangle whose sides differ.
    pub cells_across: Option<usize>,
    /// Uniform refinements of the case's mesh, in a study by refinement.
    pub refine: Option<usize>,
    /// The mesh size.
    pub h: f64,
    /// The number of vertices N.
    pub vertices: usize,
    /// The errors, for a case with an exact solution.
    pub errors: Option<Errors>,
    /// The guaranteed bound η of the energy error (docs/a-posteriori.md).
    pub estimator: Option<f64>,
    /// η / |||u − u_h|||, when both are known and the error is not round-off ([`run::Run::effectivity`]).
    pub effectivity: Option<f64>,
    /// Whether η is a guaranteed bound on this level ([`crate::estimator::Estimate::is_bound`]),
    /// when it is computed.
    pub bound: Option<bool>,
    /// Whether u_h is the exact solution to round-off ([`run::Run::at_round_off`]): its errors
    /// and η are round-off, without EOCs.
    pub round_off: bool,
    /// Active-set iterations with nested iteration (warm start from the previous level).
    pub iterations: usize,
    /// Active-set iterations from a cold start (no contact), when asked for.
    pub cold_iterations: Option<usize>,
    /// Seconds of the level's run, as a user waits for it: mesh, assembly, contact solve, error
    /// norms and estimate (not the cold start beside it).
    pub seconds: f64,
}

impl Level {
    /// The level's first column: its refinements in a study by refinement, else its cells.
    fn column(&self) -> &'static str {
        if self.refine.is_some() {
            "refine"
        } else {
            "cells"
        }
    }

    /// The level in tables: `n²` or `n × m` cells, or its refinements.
    fn label(&self) -> String {
        match (self.refine, self.cells, self.cells_across) {
            (Some(k), _, _) => k.to_string(),
            (None, Some(n), Some(m)) => format!("{n} × {m}"),
            (None, Some(n), None) => format!("{n}²"),
            (None, None, _) => "—".into(),
        }
    }
}

/// The settings of a study.
#[derive(Debug, Clone)]
pub struct StudyOptions {
    /// Cells per side or refinements on each level, increasing.
    pub levels: Levels,
    /// Also solve each level from a cold start, to compare iteration counts.
    pub cold: bool,
    /// Largest level (cells per side; √N on other meshes) on which the H⁻¹ norm is computed (it
    /// costs a solve on S_h).
    pub hminus1_max: usize,
    /// Grading exponents of an L-shaped mesh to compare (none: the case's own mesh).
    pub grading: Option<Vec<f64>>,
}

/// A study of one mesh variant: its label and its levels.
pub type Series = (String, Vec<Level>);

/// Runs the study of `case` (named `name`) and writes it into the directory `target`. Everything
/// is checked first (the levels, every level's mesh and data, the target), so that a study that
/// cannot run writes nothing; a failed study leaves no new file.
///
/// ```
/// use membrane_contact::{case::Case, study};
/// let dir = tempfile::tempdir().unwrap();
/// let levels = membrane_contact::case::Levels::Cells(vec![8, 16]);
/// let options = study::StudyOptions { levels, cold: false, hminus1_max: 16, grading: None };
/// let series = study::study(&Case::default_case(), "default", &options, &dir.path().join("s")).unwrap();
/// assert_eq!(series[0].1.len(), 2);
/// assert!(dir.path().join("s/study.md").exists());
/// ```
pub fn study(
    case: &Case,
    name: &str,
    options: &StudyOptions,
    target: &Path,
) -> Result<Vec<Series>, RunError> {
    let variants = variants(case, options)?;
    let inputs = case.inputs();
    let staging = Staging::new(target, &inputs, "study")?;
    let series =
        (write_series(case, name, options, &variants, staging.path())).map_err(|e| e.in_target(&staging))?;
    staging.commit(&inputs)?;
    Ok(series)
}

/// Solves the levels of each of the `variants` and writes their tables and plots into `dir`.
fn write_series(
    case: &Case,
    name: &str,
    options: &StudyOptions,
    variants: &[(String, Vec<Case>)],
    dir: &Path,
) -> Result<Vec<Series>, RunError> {
    let mut markdown = format!("# Convergence study: {} ({})\n\n", case.title, case.origin);
    let mut series = Vec::new();
    for (label, levels) in variants {
        let suffix = label
            .strip_prefix("grading ")
            .map_or(String::new(), |g| format!("-g{g}"));
        let title = if label.is_empty() {
            name.to_string()
        } else {
            format!("{name}, {label}")
        };
        let result = run_levels(levels, options, |k, l, _| {
            crate::progress::phase(|| {
                format!(
                    "study {title}: level {}/{} ({}) solved, {} active-set iterations",
                    k + 1,
                    levels.len(),
                    l.label(),
                    l.iterations
                )
            });
        })?;
        let table = markdown_table(&title, &result);
        crate::progress::suspend(|| crate::progress::print(&format!("{table}\n")));
        markdown += &table;
        markdown += "\n";
        write_text(&dir.join(format!("study{suffix}.csv")), &csv(&result))?;
        let json = serde_json::to_string_pretty(&result).expect("levels serialise");
        write_text(&dir.join(format!("study{suffix}.json")), &json)?;
        plot::iterations(
            &dir.join(format!("iterations{suffix}.png")),
            &format!("{title}: active-set iterations"),
            &result,
        )
        .map_err(OutputError)?;
        series.push((
            if label.is_empty() {
                name.to_string()
            } else {
                label.clone()
            },
            result,
        ));
    }
    let drawn: Vec<(String, &[Level])> = series.iter().map(|(l, r)| (l.clone(), r.as_slice())).collect();
    let plotted =
        plot::errors(&dir.join("errors.png"), &format!("{name}: errors"), &drawn).map_err(OutputError)?;
    markdown += "EOCs against h, and in parentheses against N^(−1/2) (N vertices). ‖λ−λh‖_H⁻¹ is the dual \
                 norm over P1 functions on the dual submesh S_h (a lower bound converging to the true norm).\n\n";
    markdown += match plotted {
        true => "![errors](errors.png)\n",
        false => "No plot: no error or η above round-off (nothing to show on a log axis).\n",
    };
    write_text(&dir.join("study.md"), &markdown)?;
    Ok(series)
}

/// The levels of a study of `case` when none are given: the case's `[validation]` levels, else
/// 8, 16, 32, 64 cells per side of a built-in mesh and 0, 1, 2, 3 refinements of any other.
pub fn default_levels(case: &Case) -> Levels {
    case.validation.clone().unwrap_or_else(|| match case.cells() {
        Some(_) => Levels::Cells(vec![8, 16, 32, 64]),
        None => Levels::Refine(vec![0, 1, 2, 3]),
    })
}

/// The cases of each variant (its label: empty, or `grading g`) and level, after checking every
/// level's mesh and data.
pub fn variants(case: &Case, options: &StudyOptions) -> Result<Vec<(String, Vec<Case>)>, CaseError> {
    let (option, levels) = match &options.levels {
        Levels::Cells(l) => ("--levels", l),
        Levels::Refine(l) => ("--refine", l),
    };
    let cells = matches!(options.levels, Levels::Cells(_));
    if levels.is_empty() || (cells && levels.contains(&0)) || levels.windows(2).any(|w| w[1] <= w[0]) {
        return Err(CaseError(format!(
            "{option} must be increasing{} levels, got {levels:?}",
            if cells { " positive" } else { "" }
        )));
    }
    if cells && case.cells().is_none() {
        return Err(CaseError(format!(
            "{}: levels of cells per side (--levels; levels= in Python) apply to built-in meshes \
             (kind = \"rectangle\" or \"lshape\"), not to {}: give refinements instead (--refine \
             0,1,2,3; refine=[0, 1, 2, 3] in Python)",
            case.origin,
            case.kind_named()
        )));
    }
    let gradings: Vec<Option<f64>> = match &options.grading {
        None => vec![None],
        Some(gs) => gs.iter().map(|&g| Some(g)).collect(),
    };
    let mut variants = Vec::new();
    for grading in gradings {
        let mut base = case.clone();
        if let Some(g) = grading {
            base.set_grading(g)?;
        }
        let cases = (levels.iter())
            .map(|&k| {
                let mut c = base.clone();
                if cells {
                    c.set_cells(k)?;
                } else {
                    c.refine = k;
                }
                c.check_on(&c.mesh()?)?;
                Ok(c)
            })
            .collect::<Result<Vec<_>, CaseError>>()?;
        variants.push((grading.map_or(String::new(), |g| format!("grading {g}")), cases));
    }
    Ok(variants)
}

/// Solves the `levels` (one case per level, finer and finer), each warm-started from the
/// previous one, calling `progress(level index, level, its run)` after each.
pub fn run_levels(
    levels: &[Case],
    options: &StudyOptions,
    mut progress: impl FnMut(usize, &Level, &run::Run),
) -> Result<Vec<Level>, RunError> {
    let mut out = Vec::new();
    let mut previous: Option<run::Run> = None;
    let by_refinement = matches!(options.levels, Levels::Refine(_));
    for (i, c) in levels.iter().enumerate() {
        // About √N: cells per side, or the root of the estimated vertices; for a file's mesh
        // (none estimated) of 4 times the level before's (0 on the first).
        let estimated = match c.estimated_vertices() {
            0 => previous.as_ref().map_or(0, |r| 4 * r.problem.mesh.n_vertices()),
            n => n,
        };
        let side = (c.cells()).unwrap_or_else(|| (estimated as f64).sqrt() as usize);
        // The first level by nested iteration on its coarser meshes, as `solve` starts it.
        let start = previous.as_ref().map_or(Start::Nested, |r| Start::From {
            mesh: &r.problem.mesh,
            obstacle: &r.solution.obstacle,
        });
        let hminus1 = side <= options.hminus1_max && c.exact.is_some();
        let clock = std::time::Instant::now();
        let r = run::run(
            c,
            &run::Options {
                start,
                hminus1,
                flux: false,
                // Where the problem has one (not above a rigid obstacle).
                estimate: c.check_options(true).is_ok(),
                dual: false,
            },
        )?;
        let seconds = clock.elapsed().as_secs_f64();
        let cold_iterations = match options.cold {
            false => None,
            true => {
                // A cold start needs about one iteration per ring of vertices the contact set spans.
                let mut cold_case = c.clone();
                cold_case.solver.max_iterations = cold_case.solver.max_iterations.max(4 * side);
                let options = run::Options {
                    start: Start::Cold,
                    hminus1: false,
                    flux: false,
                    estimate: false,
                    dual: false,
                };
                Some(run::run(&cold_case, &options)?.solution.obstacle.stats.iterations)
            }
        };
        let stats = &r.solution.obstacle.stats;
        let level = Level {
            cells: c.cells(),
            cells_across: c.cells_across(),
            refine: by_refinement.then_some(c.refine),
            h: r.problem.mesh.h(),
            vertices: r.problem.mesh.n_vertices(),
            errors: r.errors.clone(),
            estimator: r.estimate.as_ref().map(|e| e.total),
            effectivity: r.effectivity(),
            bound: r.estimate.as_ref().map(|e| e.is_bound()),
            round_off: r.at_round_off(),
            iterations: stats.iterations,
            cold_iterations,
            seconds,
        };
        progress(i, &level, &r);
        out.push(level);
        previous = Some(r);
    }
    Ok(out)
}

fn write_text(path: &Path, text: &str) -> Result<(), OutputError> {
    std::fs::write(path, text).map_err(|e| OutputError(format!("{}: {e}", path.display())))
}

/// The quantities tabulated for each level: (label, short name, value).
pub(crate) fn quantities(level: &Level) -> Vec<(&'static str, &'static str, Option<f64>)> {
    let e = level.errors.as_ref();
    if e.is_some_and(|e| e.rigid) {
        return vec![
            ("|u−uh|_H1", "h1_u", e.and_then(|e| e.h1_u1)),
            ("energy", "energy", e.and_then(|e| e.energy)),
            ("η (bound of energy)", "estimator", level.estimator),
            ("‖u−uh‖_L2", "l2_u", e.map(|e| e.l2_u1)),
            ("‖λ−λh‖_L2", "l2_lambda", e.map(|e| e.l2_lambda)),
            ("‖λ−λh‖_H⁻¹", "hminus1_lambda", e.and_then(|e| e.hminus1_lambda)),
        ];
    }
    vec![
        ("|u1−u1h|_H1", "h1_u1", e.and_then(|e| e.h1_u1)),
        ("|u2−u2h|_H1", "h1_u2", e.and_then(|e| e.h1_u2)),
        ("energy", "energy", e.and_then(|e| e.energy)),
        ("η (bound of energy)", "estimator", level.estimator),
        ("‖u1−u1h‖_L2", "l2_u1", e.map(|e| e.l2_u1)),
        ("‖u2−u2h‖_L2", "l2_u2", e.map(|e| e.l2_u2)),
        ("‖λ−λh‖_L2", "l2_lambda", e.map(|e| e.l2_lambda)),
        ("‖λ−λh‖_H⁻¹", "hminus1_lambda", e.and_then(|e| e.hminus1_lambda)),
    ]
}

/// Whether `value`, the quantity `short` of [`quantities`], is more than round-off on `level`:
/// an error of u_i above what the round-off of u_h's values makes of it
/// ([`crate::norms::RoundOff`]: u2h = 0 computed from membranes of 10⁶ is not), the energy error
/// and η where u_h is not the exact solution to round-off ([`Level::round_off`]), ‖λ − λ_h‖ above
/// λ_h's round-off. EOCs and plots leave the others out.
pub(crate) fn resolved(level: &Level, short: &str, value: f64) -> bool {
    let e = level.errors.as_ref();
    match short {
        "l2_lambda" | "hminus1_lambda" => !e.is_some_and(Errors::lambda_at_round_off),
        "h1_u1" | "h1_u2" | "h1_u" => e.is_none_or(|e| value > e.round_off.h1),
        "l2_u1" | "l2_u2" | "l2_u" => e.is_none_or(|e| value > e.round_off.l2),
        _ => !level.round_off,
    }
}

/// The EOC of the quantity `k` of [`quantities`] from level i − 1 to level i, where it is resolved
/// on both.
fn eoc_from_previous(levels: &[Level], i: usize, k: usize) -> Option<(f64, f64)> {
    let (a, b) = (levels.get(i.checked_sub(1)?)?, &levels[i]);
    let (qa, qb) = (quantities(a).swap_remove(k), quantities(b).swap_remove(k));
    let (ea, eb) = (qa.2?, qb.2?);
    if !(resolved(a, qa.1, ea) && resolved(b, qb.1, eb)) {
        return None;
    }
    eoc(a, b, ea, eb)
}

/// EOC between two levels against h and against N^(−1/2) of errors `ea`, `eb`; None unless
/// both are positive.
pub fn eoc(a: &Level, b: &Level, ea: f64, eb: f64) -> Option<(f64, f64)> {
    (ea > 0.0 && eb > 0.0).then(|| {
        let r = (ea / eb).ln();
        (
            r / (a.h / b.h).ln(),
            2.0 * r / (b.vertices as f64 / a.vertices as f64).ln(),
        )
    })
}

/// The study as a Markdown table (EOCs against h, and against N^(−1/2) in parentheses; no EOC
/// columns for a single level).
pub fn markdown_table(title: &str, levels: &[Level]) -> String {
    let mut s = format!("## {title}\n\n");
    let (eoc_header, eoc_columns) = if levels.len() > 1 {
        (" EOC h (N) |", 2)
    } else {
        ("", 1)
    };
    let names: Vec<&str> = levels.first().map_or(vec![], |l| {
        quantities(l)
            .into_iter()
            .filter(|q| q.2.is_some())
            .map(|q| q.0)
            .collect()
    });
    let first = levels.first().map_or("cells", Level::column);
    let _ = write!(s, "| {first} | h | vertices |");
    for n in &names {
        // A norm's bars would end its cell.
        let _ = write!(s, " {} |{eoc_header}", n.replace('|', "\\|"));
    }
    s += " effectivity η/energy | bound | iterations (nested) | iterations (cold) | seconds |\n|";
    s += &"---|".repeat(3 + eoc_columns * names.len() + 5);
    s += "\n";
    for (i, l) in levels.iter().enumerate() {
        let _ = write!(s, "| {} | {:.4e} | {} |", l.label(), l.h, l.vertices);
        for (k, (label, _, value)) in quantities(l).into_iter().enumerate() {
            if !names.contains(&label) {
                continue;
            }
            let previous = eoc_from_previous(levels, i, k);
            let _ = write!(s, " {} |", value.map_or("—".into(), |v| format!("{v:.4e}")));
            if eoc_columns == 2 {
                let _ = write!(
                    s,
                    " {} |",
                    previous.map_or("—".into(), |(h, n)| format!("{h:.3} ({n:.3})"))
                );
            }
        }
        let _ = writeln!(
            s,
            " {} | {} | {} | {} | {:.3} |",
            l.effectivity.map_or("—".into(), |x| format!("{x:.3}")),
            l.bound.map_or("—", |b| if b { "yes" } else { "NO" }),
            l.iterations,
            l.cold_iterations.map_or("—".into(), |c| c.to_string()),
            l.seconds
        );
    }
    if levels.iter().any(|l| l.bound == Some(false)) {
        s += "\nη is a guaranteed bound of the energy error **only on the levels with \"yes\" under \
              \"bound\"**: on the others the case's rule does not resolve the loads, or the boundary \
              data admit no solution (each level's `solve --estimate` summary says which).\n";
    }
    let mismatches = levels.iter().filter_map(|l| l.errors.as_ref()?.boundary);
    if let Some(note) = crate::norms::Mismatch::note(mismatches) {
        s += &format!("\n{note}");
    }
    let unsolved: Vec<(String, crate::norms::Unsolved, bool)> = (levels.iter())
        .filter_map(|l| {
            l.errors
                .as_ref()
                .and_then(|e| Some((l.label(), e.unsolved?, e.rigid)))
        })
        .collect();
    if let Some((_, u, rigid)) = unsolved.first() {
        let named: Vec<&str> = unsolved.iter().map(|(label, _, _)| label.as_str()).collect();
        let on = match named.len() {
            n if n == levels.len() => "On every level".to_string(),
            1 => format!("On the level {}", named[0]),
            _ => format!("On the levels {}", named.join(", ")),
        };
        s += &format!(
            "\n{on}, [exact] {} (figures of {}).\n",
            u.describe(*rigid),
            named[0]
        );
    }
    s
}

/// The study as CSV, one row per level: the level (refinements or cells per side, and across on
/// a rectangle of unequal sides), h, N, each quantity with its EOCs against h and against N^(−1/2)
/// (`eoc_X`, `eoc_n_X`), the effectivity, whether η is a bound (1/0), the norms' estimated
/// quadrature error, the exact solution's mismatches, iterations and seconds; empty where none.
pub fn csv(levels: &[Level]) -> String {
    let mut s = format!(
        "{},cells_across,h,vertices",
        levels.first().map_or("cells", Level::column)
    );
    if let Some(l) = levels.first() {
        for (_, name, _) in quantities(l) {
            let _ = write!(s, ",{name},eoc_{name},eoc_n_{name}");
        }
    }
    s += ",effectivity,bound,quadrature,exact_boundary_mismatch,exact_equation_mismatch,iterations,\
          cold_iterations,seconds\n";
    let text = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
    for (i, l) in levels.iter().enumerate() {
        let size = l.refine.or(l.cells).map_or(String::new(), |k| k.to_string());
        let across = l.cells_across.map_or(String::new(), |k| k.to_string());
        let _ = write!(s, "{size},{across},{:e},{}", l.h, l.vertices);
        for (k, (_, _, value)) in quantities(l).into_iter().enumerate() {
            let e = eoc_from_previous(levels, i, k);
            let _ = write!(
                s,
                ",{},{},{}",
                text(value),
                text(e.map(|e| e.0)),
                text(e.map(|e| e.1))
            );
        }
        let cold = l.cold_iterations.map_or(String::new(), |c| c.to_string());
        let bound = l.bound.map_or("", |b| if b { "1" } else { "0" });
        // The exact solution's mismatches: of the boundary data on ∂ω_h (relative), and the share
        // of the sample points where it misses its equations; 0 where there is none.
        let e = l.errors.as_ref();
        let _ = writeln!(
            s,
            ",{},{bound},{},{},{},{},{cold},{:e}",
            text(l.effectivity),
            text(e.map(|e| e.quadrature)),
            text(e.map(|e| e.boundary.map_or(0.0, |m| m.relative))),
            text(e.map(|e| e.unsolved.map_or(0.0, |u| u.share))),
            l.iterations,
            l.seconds
        );
    }
    s
}
