//! Adaptive refinement, the a posteriori estimator put to work:
//!
//! ```text
//! solve → estimate (η_K per triangle) → mark (Dörfler: the fewest triangles with Σ η_K² ≥ θ η²)
//!       → refine (conforming newest-vertex bisection, new boundary vertices on the curves of ∂ω)
//!       → solve, warm-started from the previous mesh's gap and active set → …
//! ```
//!
//! until η ≤ the target, the next mesh would exceed the vertex budget, or the steps run out. Each
//! step's result is a result directory of its own (T_h with its fields; the dual submesh S_h too
//! on request, four times the rest); `adapt.xdmf` shows them in ParaView as one time series,
//! `adapt.md`/`.csv`/`.json` tabulate the steps beside uniform refinement of the same case, and
//! `adapt.png` plots η and the error against N for both.

use crate::atomic::{OutputError, Staging};
use crate::case::{Adaptivity, Case, CaseError};
use crate::contact::Start;
use crate::mesh::{self, Postprocess};
use crate::result::{self, Describe};
use crate::run::{self, Run, RunError};
use crate::study::plot;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// One step of the adaptive loop (or one level of uniform refinement).
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// Vertices N.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Triangles marked for refinement; none on the last step and under uniform refinement
    /// (which refines every triangle).
    pub marked: Option<usize>,
    /// η.
    pub estimator: f64,
    /// Whether η is a guaranteed bound at this step: the loads resolved by the case's rule and the
    /// boundary data admissible ([`crate::estimator::Estimate::is_bound`]).
    pub bound: bool,
    /// |||u − u_h|||, for a case with an exact solution.
    pub error: Option<f64>,
    /// η / |||u − u_h|||.
    pub effectivity: Option<f64>,
    /// Whether u_h is the exact solution to round-off ([`Run::at_round_off`]): its error and η are
    /// round-off, left out of the rates and the plot.
    pub round_off: bool,
    /// Where the exact solution misses the boundary data on ∂ω_h (a curved ω) most, relative.
    pub mismatch: Option<crate::norms::Mismatch>,
    /// What the exact solution misses of its equations, in words, where it misses them at too
    /// many points: its errors are then not this problem's ([`crate::norms::Unsolved`]).
    pub unsolved: Option<String>,
    /// Active-set iterations.
    pub iterations: usize,
    /// Seconds of refinement, assembly, solve and estimate.
    pub seconds: f64,
}

impl Step {
    fn new(r: &Run, marked: Option<usize>, seconds: f64) -> Step {
        let (mesh, estimate) = (&r.problem.mesh, r.estimate.as_ref().expect("estimated"));
        Step {
            vertices: mesh.n_vertices(),
            triangles: mesh.n_triangles(),
            marked,
            estimator: estimate.total,
            bound: estimate.is_bound(),
            error: r.errors.as_ref().and_then(|e| e.energy),
            effectivity: r.effectivity(),
            round_off: r.at_round_off(),
            mismatch: r.errors.as_ref().and_then(|e| e.boundary),
            unsolved: (r.errors.as_ref()).and_then(|e| Some(e.unsolved?.describe(e.rigid))),
            iterations: r.solution.obstacle.stats.iterations,
            seconds,
        }
    }
}

/// The adaptive steps and the uniform levels of a run of `adapt`.
#[derive(Debug, Clone, Serialize)]
pub struct Adapted {
    /// The case, as its origin names it (a file's path).
    pub case: String,
    /// Dörfler's θ.
    pub theta: f64,
    /// The steps of the adaptive loop.
    pub adaptive: Vec<Step>,
    /// Uniform refinement of the initial mesh, up to about the final adaptive N.
    pub uniform: Vec<Step>,
    /// Why the adaptive loop stopped: the target, the step count or the vertex budget.
    pub stopped: String,
}

/// Dörfler marking: the fewest triangles (largest indicators first) whose η_K² sum to at least
/// θ Σ η_K².
pub fn dorfler(indicator: &[f64], theta: f64) -> Vec<bool> {
    let mut order: Vec<usize> = (0..indicator.len()).collect();
    order.sort_unstable_by(|&a, &b| indicator[b].total_cmp(&indicator[a]).then(a.cmp(&b)));
    let total: f64 = indicator.iter().map(|x| x * x).sum();
    let mut marked = vec![false; indicator.len()];
    let mut sum = 0.0;
    for t in order {
        if sum >= theta * total {
            break;
        }
        marked[t] = true;
        sum += indicator[t] * indicator[t];
    }
    marked
}

/// Runs the adaptive loop on `case` with `settings` and writes everything into the directory
/// `target`, whole or not at all; with `dual`, each step's result holds S_h with λ_h as well.
pub fn adapt(case: &Case, settings: &Adaptivity, dual: bool, target: &Path) -> Result<Adapted, RunError> {
    check_memory(case, settings)?;
    let inputs = case.inputs();
    let staging = Staging::new(target, &inputs, "adapt")?;
    let adapted = (write_adapted(case, settings, dual, staging.path())).map_err(|e| e.in_target(&staging))?;
    staging.commit(&inputs)?;
    Ok(adapted)
}

/// Runs the adaptive loop and the uniform refinement beside it, and writes their steps, tables
/// and plot into `root`.
fn write_adapted(case: &Case, settings: &Adaptivity, dual: bool, root: &Path) -> Result<Adapted, RunError> {
    let mut grids = Vec::new();
    let adaptive = steps(case, settings, |step, r, steps| {
        progress(steps);
        let dir = format!("step-{step:03}");
        crate::progress::phase(|| format!("writing {dir}"));
        write_step(root, &dir, r, dual)?;
        grids.push(result::step_grid(&dir, step as f64, &r.problem.mesh, &r.fields()));
        Ok(())
    })?;
    let last = adaptive.last().map_or(0, |s| s.vertices);
    crate::progress::phase(|| "uniform refinement, for comparison".into());
    let uniform = uniform(case, (2 * last).min(settings.max_vertices))?;
    crate::progress::phase(|| "writing adapt.xdmf, the tables and the plot".into());
    result::time_series(&root.join("adapt.xdmf"), &grids).map_err(OutputError)?;
    let stopped = stopped(settings, &adaptive);
    let adapted = Adapted {
        case: case.origin.clone(),
        theta: settings.theta,
        adaptive,
        uniform,
        stopped,
    };
    write_text(&root.join("adapt.csv"), &csv(&adapted))?;
    let json = serde_json::to_string_pretty(&adapted).expect("steps serialise");
    write_text(&root.join("adapt.json"), &json)?;
    let plotted = plot(&root.join("adapt.png"), settings, &adapted)?;
    write_text(
        &root.join("adapt.md"),
        &markdown(case, settings, &adapted, plotted),
    )?;
    Ok(adapted)
}

/// The plot of η (and the error) against N of both refinements; whether it was drawn (not when
/// every value is round-off or 0, as on a solution exact in P1).
fn plot(path: &Path, settings: &Adaptivity, adapted: &Adapted) -> Result<bool, OutputError> {
    let exact = adapted.adaptive.iter().any(|s| s.error.is_some());
    let (title, y_name) = if exact {
        ("η and error", "η and the energy error |||u − u_h|||")
    } else {
        ("η", "η (bound of the energy error)")
    };
    let series = series(adapted);
    plot::loglog(
        path,
        &format!(
            "{title}: adaptive (θ = {}) and uniform refinement",
            settings.theta
        ),
        y_name,
        &series,
        &[plot::Guide {
            slope: 1.0,
            label: "slope 1, N^(−1/2): the best rate of P1".into(),
            beside: usize::from(exact),
        }],
    )
    .map_err(OutputError)
}

/// The adapted meshes have no coarser levels (Cholesky solves them) and are estimated: the
/// largest one allowed must fit, before anything is built.
fn check_memory(case: &Case, settings: &Adaptivity) -> Result<(), RunError> {
    let after = Postprocess {
        flux: false,
        estimate: true,
        hminus1: false,
    };
    let price = mesh::DIRECT_BYTES_PER_VERTEX.max(after.bytes_per_vertex());
    mesh::check_memory(settings.max_vertices, price).map_err(|e| {
        CaseError(format!(
            "{}: adapt's vertex budget of {} ([adapt] max_vertices or --max-vertices): {e}",
            case.origin, settings.max_vertices
        ))
    })?;
    Ok(())
}

/// Why the adaptive loop that made `steps` with `settings` stopped.
pub fn stopped(settings: &Adaptivity, steps: &[Step]) -> String {
    let (first, last) = (&steps[0], &steps[steps.len() - 1]);
    match settings.target {
        Some(t) if last.estimator <= t => {
            let caveat = match last.bound {
                true => "",
                false => ", but η is NOT a guaranteed bound at that step (its summary says why)",
            };
            return format!("η = {:.4e} ≤ the target {t:e}{caveat}", last.estimator);
        }
        _ if steps.len() > settings.steps => return format!("the step count, {}", settings.steps),
        _ => {}
    }
    let budget = settings.max_vertices;
    match first.vertices > budget {
        true => format!(
            "the vertex budget, {budget}: the initial mesh has {} vertices already, and was not refined",
            first.vertices
        ),
        false => format!("the vertex budget, {budget}: the next mesh would have had more vertices"),
    }
}

/// The adaptive loop on `case` with `settings`, writing nothing: solve → estimate → mark →
/// refine → solve …, calling `each(step, its run, the steps so far)` after each step (the last of
/// the steps is that step's); the steps.
pub fn steps(
    case: &Case,
    settings: &Adaptivity,
    mut each: impl FnMut(usize, &Run, &[Step]) -> Result<(), RunError>,
) -> Result<Vec<Step>, RunError> {
    check_memory(case, settings)?;
    let curves = case.curves();
    let mut clock = Instant::now();
    let mut r = run::run(case, &estimating(Start::Nested))?;
    let mut adaptive = Vec::new();
    for step in 0.. {
        let eta = r.estimate.as_ref().expect("estimated").total;
        let done = step == settings.steps || settings.target.is_some_and(|t| eta <= t);
        let marked = if done {
            None
        } else {
            crate::progress::phase(|| format!("adapt step {step}: marking and refining"));
            let marks = dorfler(&r.estimate.as_ref().expect("estimated").indicator, settings.theta);
            // Meshes made by bisection carry their labels; the first one gets them here.
            let labelled;
            let mesh = if step == 0 {
                labelled = r.problem.mesh.longest_edge_labelled();
                &labelled
            } else {
                &r.problem.mesh
            };
            let fine = mesh.bisected(&marks, &curves).map_err(|e| mesh_error(case, &e))?;
            let count = marks.iter().filter(|&&m| m).count();
            (fine.n_vertices() <= settings.max_vertices).then_some((fine, count))
        };
        let seconds = clock.elapsed().as_secs_f64();
        adaptive.push(Step::new(&r, marked.as_ref().map(|m| m.1), seconds));
        each(step, &r, &adaptive)?;
        let Some((fine, _)) = marked else { break };
        clock = Instant::now();
        let start = Start::From {
            mesh: &r.problem.mesh,
            obstacle: &r.solution.obstacle,
        };
        r = run::on_mesh(case, fine, Vec::new(), &estimating(start), 0.0).map_err(|e| {
            named(
                case,
                e,
                &format!("adapt step {}, on the mesh refined from step {step}", step + 1),
            )
        })?;
    }
    Ok(adaptive)
}

/// `e`, from a run on a refined mesh, its origin followed by `which` mesh: a datum or the solver
/// may fail only there (at a boundary vertex new on that mesh, say).
fn named(case: &Case, e: RunError, which: &str) -> RunError {
    let origin = format!("{} ({which})", case.origin);
    match e {
        RunError::Case(CaseError(message)) => match message.strip_prefix(&case.origin) {
            Some(rest) => RunError::Case(CaseError(format!("{origin}{rest}"))),
            None => RunError::Case(CaseError(message)),
        },
        RunError::Solve(_, e) => RunError::Solve(origin, e),
        RunError::Check(_, e) => RunError::Check(origin, e),
        RunError::Output(e) => RunError::Output(e),
    }
}

/// A run with the estimator.
fn estimating(start: Start) -> run::Options {
    run::Options {
        start,
        hminus1: false,
        flux: false,
        estimate: true,
        dual: false,
    }
}

/// A mesh refinement refused, named with the case.
fn mesh_error(case: &Case, e: &dyn std::fmt::Display) -> RunError {
    crate::case::CaseError(format!("{}: cannot refine the mesh: {e}", case.origin)).into()
}

/// Writes one step's result directory `dir` inside `root`, with S_h if `dual`.
fn write_step(root: &Path, dir: &str, r: &Run, dual: bool) -> Result<(), RunError> {
    let path = root.join(dir);
    std::fs::create_dir(&path).map_err(|e| OutputError(format!("{}: {e}", path.display())))?;
    let fields = r.fields_with_dual(dual);
    let dual = dual.then(|| r.dual());
    result::write(&path, &r.problem.mesh, dual.as_ref(), &fields, &r.attributes())
        .map_err(|e| OutputError(format!("{}: {e}", path.display())))?;
    Ok(())
}

/// Uniform refinement of the case's mesh, each level warm-started from the one before, up to
/// `vertices` vertices (twice the adaptive series' last mesh, within the budget the memory guard
/// priced).
fn uniform(case: &Case, vertices: usize) -> Result<Vec<Step>, RunError> {
    let curves = case.curves();
    let clock = Instant::now();
    let mut r = run::run(case, &estimating(Start::Nested))?;
    let mut out = vec![Step::new(&r, None, clock.elapsed().as_secs_f64())];
    loop {
        let clock = Instant::now();
        let fine = r
            .problem
            .mesh
            .refined(&curves)
            .map_err(|e| mesh_error(case, &e))?;
        if fine.n_vertices() > vertices {
            return Ok(out);
        }
        let start = Start::From {
            mesh: &r.problem.mesh,
            obstacle: &r.solution.obstacle,
        };
        let which = format!("adapt's uniform comparison, refinement {}", out.len());
        let next = run::on_mesh(case, fine, Vec::new(), &estimating(start), 0.0)
            .map_err(|e| named(case, e, &which))?;
        out.push(Step::new(&next, None, clock.elapsed().as_secs_f64()));
        r = next;
    }
}

/// Prints a step as it finishes.
fn progress(steps: &[Step]) {
    let s = steps.last().expect("a step");
    crate::progress::suspend(|| {
        crate::progress::print(&format!(
            "step {:3}  N = {:8}  η = {:.4e}{}{}{}  iterations {}  marked {}  {:.2} s\n",
            steps.len() - 1,
            s.vertices,
            s.estimator,
            if s.bound { "" } else { " (NOT a bound)" },
            (s.error.zip(s.effectivity))
                .map_or(String::new(), |(e, x)| format!("  error {e:.4e}  η/error {x:.3}")),
            match s.unsolved.as_deref() {
                Some(u) if u.starts_with("grad_") => " ([exact]'s gradient is not ∇u: adapt.md)",
                Some(_) => " ([exact] is no solution of this case: adapt.md)",
                None => "",
            },
            s.iterations,
            s.marked.map_or("—".into(), |m| m.to_string()),
            s.seconds
        ))
    });
}

/// The steps a rate is fitted over: those of the last two decades of N (with the step before
/// them), all steps if they span less.
fn last_decades(steps: &[Step]) -> &[Step] {
    let last = steps.last().map_or(0.0, |s| s.vertices as f64);
    let from = steps
        .iter()
        .position(|s| (s.vertices as f64) * 100.0 >= last)
        .unwrap_or(0);
    &steps[from.saturating_sub(1)..]
}

/// The rate s of value ∝ N^(−s): the least-squares slope of −log value against log N over
/// the steps of the last two decades of N (with the step before them; all if they span less).
pub fn rate(steps: &[Step], value: impl Fn(&Step) -> Option<f64>) -> Option<f64> {
    let points: Vec<(f64, f64)> = (last_decades(steps).iter())
        .filter(|s| !s.round_off)
        .filter_map(|s| Some(((s.vertices as f64).ln(), -value(s)?.ln())))
        .collect();
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |a, p| {
        (a.0 + (p.0 - mx) * (p.1 - my), a.1 + (p.0 - mx).powi(2))
    });
    Some(sxy / sxx)
}

fn markdown(case: &Case, settings: &Adaptivity, a: &Adapted, plotted: bool) -> String {
    let bound = match a.adaptive.iter().chain(&a.uniform).all(|st| st.bound) {
        true => "η is the guaranteed bound of the energy error (docs/a-posteriori.md)",
        false => {
            "η is the guaranteed bound of the energy error (docs/a-posteriori.md) **only at the \
             steps with \"yes\" under \"bound\"**: at the others the case's rule does not resolve \
             the loads, or the boundary data admit no solution (each step's summary says which)"
        }
    };
    let mut s = format!(
        "# Adaptive refinement: {} ({})\n\nDörfler marking with θ = {}, newest-vertex bisection; \
         {bound}. Stopped by {}.\n\n",
        case.title, case.origin, settings.theta, a.stopped
    );
    for (title, steps) in [("Adaptive", &a.adaptive), ("Uniform", &a.uniform)] {
        let _ = writeln!(
            s,
            "## {title}\n\n| step | vertices | triangles | marked | η | bound | error | η/error | iterations | seconds |\n|---|---|---|---|---|---|---|---|---|---|"
        );
        for (k, st) in steps.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {k} | {} | {} | {} | {:.4e} | {} | {} | {} | {} | {:.3} |",
                st.vertices,
                st.triangles,
                st.marked.map_or("—".into(), |m| m.to_string()),
                st.estimator,
                if st.bound { "yes" } else { "NO" },
                st.error.map_or("—".into(), |e| format!("{e:.4e}")),
                st.effectivity.map_or("—".into(), |x| format!("{x:.3}")),
                st.iterations,
                st.seconds
            );
        }
        let total: f64 = steps.iter().map(|st| st.seconds).sum();
        let last = steps.last().map_or(0.0, |st| st.seconds);
        let _ = writeln!(
            s,
            "\nSeconds, all steps: {total:.2}, {:.2}× the last step's (refinement, assembly, solve, estimate).",
            total / last.max(f64::MIN_POSITIVE)
        );
        let slope = |v: Option<f64>| v.map_or("—".into(), |v| format!("{v:.3}"));
        let fitted = last_decades(steps);
        let (first, last) = (fitted[0].vertices, fitted[fitted.len() - 1].vertices);
        let _ = writeln!(
            s,
            "Rate s of ∝ N^(−s), least squares over the steps with N in the last two decades and \
             the step before them (N = {first} … {last}, {:.2} decades): η {}, error {} (optimal \
             for P1: 0.5).\n",
            (last as f64 / first as f64).log10(),
            slope(rate(steps, |st| Some(st.estimator))),
            slope(rate(steps, |st| st.error))
        );
    }
    if let Some(note) =
        crate::norms::Mismatch::note(a.adaptive.iter().chain(&a.uniform).filter_map(|st| st.mismatch))
    {
        s += &note;
    }
    let unsolved: Vec<(usize, &str)> = (a.adaptive.iter().enumerate())
        .filter_map(|(k, st)| Some((k, st.unsolved.as_deref()?)))
        .collect();
    if let Some((k, why)) = unsolved.first() {
        let _ = writeln!(
            s,
            "**At {} of the {} adaptive steps (first at step {k}), [exact] {why}.**\n",
            unsolved.len(),
            a.adaptive.len()
        );
    }
    s += match plotted {
        true => "![η and error against N](adapt.png)\n\n",
        false => "No plot: no η or error above round-off (nothing to show on a log axis).\n\n",
    };
    s += "Open `adapt.xdmf` in ParaView (Xdmf3 reader) for the meshes and fields of every step.\n";
    s
}

fn csv(a: &Adapted) -> String {
    let mut s = String::from(
        "refinement,step,vertices,triangles,marked,estimator,bound,error,effectivity,mismatch,iterations,seconds\n",
    );
    for (name, steps) in [("adaptive", &a.adaptive), ("uniform", &a.uniform)] {
        for (k, st) in steps.iter().enumerate() {
            let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
            let _ = writeln!(
                s,
                "{name},{k},{},{},{},{:e},{},{},{},{},{},{:.4}",
                st.vertices,
                st.triangles,
                st.marked.map_or(String::new(), |m| m.to_string()),
                st.estimator,
                u8::from(st.bound),
                opt(st.error),
                opt(st.effectivity),
                opt(st.mismatch.map(|m| m.relative)),
                st.iterations,
                st.seconds
            );
        }
    }
    s
}

/// The plotted series: η and the error (when exact) of the adaptive steps, then of uniform
/// refinement, as (N^(−1/2), value), each named with its fitted slope on the plot (2 × [`rate`]).
fn series(a: &Adapted) -> Vec<(String, Vec<(f64, f64)>)> {
    let mut out = Vec::new();
    for (name, steps) in [("adaptive", &a.adaptive), ("uniform", &a.uniform)] {
        let x = |s: &Step| (s.vertices as f64).powf(-0.5);
        let slope = |value: fn(&Step) -> Option<f64>| {
            rate(steps, value).map_or(String::new(), |r| format!("  (slope {:.2})", 2.0 * r))
        };
        let resolved = || steps.iter().filter(|s| !s.round_off);
        out.push((
            format!("{name}: η{}", slope(|s| Some(s.estimator))),
            resolved().map(|s| (x(s), s.estimator)).collect(),
        ));
        let errors: Vec<(f64, f64)> = resolved().filter_map(|s| Some((x(s), s.error?))).collect();
        if !errors.is_empty() {
            out.push((format!("{name}: error{}", slope(|s| s.error)), errors));
        }
    }
    out
}

fn write_text(path: &Path, text: &str) -> Result<(), OutputError> {
    std::fs::write(path, text).map_err(|e| OutputError(format!("{}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dorfler_marks_the_fewest_largest() {
        let eta = [1.0, 3.0, 2.0, 0.5];
        // η² = 1, 9, 4, 0.25 (sum 14.25): θ = 0.5 needs 7.125 → {3.0}; θ = 0.7 → {3.0, 2.0}.
        assert_eq!(dorfler(&eta, 0.5), [false, true, false, false]);
        assert_eq!(dorfler(&eta, 0.7), [false, true, true, false]);
        assert_eq!(dorfler(&eta, 1.0), [true; 4]);
    }

    #[test]
    fn the_rate_of_a_power_law_is_its_exponent() {
        let steps: Vec<Step> = (0..12)
            .map(|k| {
                let vertices = 10 * 2_usize.pow(k);
                Step {
                    vertices,
                    triangles: 2 * vertices,
                    marked: None,
                    estimator: 3.0 * (vertices as f64).powf(-0.4),
                    bound: true,
                    error: Some((vertices as f64).powf(-0.5)),
                    effectivity: Some(3.0 * (vertices as f64).powf(0.1)),
                    round_off: false,
                    mismatch: None,
                    unsolved: None,
                    iterations: 1,
                    seconds: 0.0,
                }
            })
            .collect();
        assert!((rate(&steps, |s| Some(s.estimator)).unwrap() - 0.4).abs() < 1e-12);
        assert!((rate(&steps, |s| s.error).unwrap() - 0.5).abs() < 1e-12);
        assert_eq!(rate(&steps[..1], |s| s.error), None);
        // Steps where u_h is exact to round-off are left out (their values are noise).
        let mut noisy = steps.clone();
        for s in &mut noisy[10..] {
            (s.round_off, s.estimator, s.error) = (true, 1e-14 * s.vertices as f64, Some(1e-15));
        }
        assert!((rate(&noisy, |s| Some(s.estimator)).unwrap() - 0.4).abs() < 1e-12);
    }
}
