//! The `membrane-contact` command line.

use clap::builder::PossibleValuesParser;
use clap::{Parser, Subcommand};
use membrane_contact::case::{Case, CaseError, Levels};
use membrane_contact::contact::{LinearSolver, Start};
use membrane_contact::progress::print as say;
use membrane_contact::run;
use membrane_contact::study::{self, StudyOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Large allocations on huge pages (see [`membrane_contact::pages`]).
#[global_allocator]
static ALLOCATOR: membrane_contact::pages::HugePages = membrane_contact::pages::HugePages;

#[derive(Parser)]
#[command(
    version,
    about = "Unilateral contact between two elastic membranes: P1 finite elements, discrete action by local postprocessing"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Threads to compute on, at most 1024 (default: RAYON_NUM_THREADS, else one per core). The
    /// results are the same bit for bit on any number.
    #[arg(long, global = true)]
    threads: Option<usize>,
    /// Show no progress on stderr (by default the phases are shown as they happen: a live line
    /// on a terminal, one line per phase otherwise). Stdout holds the summary either way.
    #[arg(long, short, global = true)]
    quiet: bool,
    /// A longer summary: the solver's details (levels, local corrections, CG iterations per step).
    #[arg(long, short, global = true)]
    verbose: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Solve one case and write its result directory (solution.h5, and solution.xdmf for
    /// ParaView; dual.xdmf too with --dual or --flux).
    Solve {
        /// Case file (TOML); the built-in default case when omitted.
        case: Option<PathBuf>,
        /// The result directory; default results/<case name>. An existing one is replaced only by a
        /// complete new result, and only if it is a result of this program holding nothing else.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Cells per side of a built-in mesh (of a rectangle, along the side with more cells in the
        /// case's n, the other in the case's proportion; overrides the case; an error for other
        /// kinds).
        #[arg(long)]
        n: Option<usize>,
        /// Uniform refinements of the case's mesh, any kind (overrides `[mesh] refine`).
        #[arg(long)]
        refine: Option<usize>,
        /// Start the active-set method from no contact instead of nested iteration.
        #[arg(long)]
        cold: bool,
        /// The linear solver: multigrid (the default) or direct (sparse Cholesky); overrides the
        /// case's `[solver] linear`.
        #[arg(long, value_parser = PossibleValuesParser::new(LinearSolver::NAMES))]
        linear: Option<String>,
        /// With an exact solution, also compute ‖λ − λh‖_H⁻¹ (a solve on the dual submesh).
        #[arg(long)]
        hminus1: bool,
        /// Also reconstruct the fluxes t_ih (4.13) on the dual submesh, check their local
        /// conservation and write t_ih and div t_ih as its cell data.
        #[arg(long)]
        flux: bool,
        /// Also compute the guaranteed a posteriori bound η of the energy error and its
        /// indicators per triangle (cell data `estimator`, …; docs/a-posteriori.md).
        #[arg(long)]
        estimate: bool,
        /// Also write the dual submesh S_h with λ_h and the owner vertex of each cell as cell data
        /// (dual.xdmf; about 430 bytes per vertex of T_h, four times the rest; --flux writes it
        /// anyway).
        #[arg(long)]
        dual: bool,
        /// Print the built-in default case and exit.
        #[arg(long)]
        print_default: bool,
    },
    /// Convergence study: solve on refined meshes (each level warm-started from the previous one),
    /// tabulate errors, EOCs and iterations, and plot them.
    Study {
        /// Case file (TOML); the built-in default case when omitted.
        case: Option<PathBuf>,
        /// Cells per side on each level of a built-in mesh, e.g. 8,16,32,64 (default: the case's
        /// validation levels, else 8,16,32,64 for built-in meshes and --refine 0,1,2,3 for others).
        #[arg(long, value_delimiter = ',', conflicts_with = "refine")]
        levels: Option<Vec<usize>>,
        /// Uniform refinements of the case's mesh on each level, any kind, e.g. 0,1,2,3.
        #[arg(long, value_delimiter = ',')]
        refine: Option<Vec<usize>>,
        /// Also solve every level from a cold start, to compare active-set iterations.
        #[arg(long)]
        cold: bool,
        /// The linear solver: multigrid (the default) or direct (sparse Cholesky); overrides the
        /// case's `[solver] linear`.
        #[arg(long, value_parser = PossibleValuesParser::new(LinearSolver::NAMES))]
        linear: Option<String>,
        /// Grading exponents of an L-shaped mesh to compare, e.g. 1,2 (uniform and graded).
        #[arg(long, value_delimiter = ',')]
        grading: Option<Vec<f64>>,
        /// Largest level on which ‖λ − λh‖_H⁻¹ is computed, in cells per side (on a study by
        /// refinement √N, N the level's vertices: e.g. 40 takes meshes up to 1600 vertices).
        #[arg(long, default_value_t = 512)]
        hminus1_max: usize,
        /// The study's result directory; default study/<case name>.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
    /// Adaptive refinement: solve, estimate the error per triangle, refine where it is large
    /// (Dörfler marking, newest-vertex bisection), solve again warm-started, … (settings from the
    /// case's `[adapt]` table unless given here).
    Adapt {
        /// Case file (TOML); the built-in default case when omitted.
        case: Option<PathBuf>,
        /// Cells per side of a built-in initial mesh (of a rectangle, along the side with more cells
        /// in the case's n, the other in the case's proportion; overrides the case; an error for
        /// other kinds).
        #[arg(long)]
        n: Option<usize>,
        /// Uniform refinements of the case's initial mesh, any kind (overrides `[mesh] refine`).
        #[arg(long)]
        refine: Option<usize>,
        /// Dörfler's θ in (0, 1]: refine the fewest triangles carrying this share of η².
        #[arg(long)]
        theta: Option<f64>,
        /// Stop once the estimate η is at most this.
        #[arg(long)]
        target: Option<f64>,
        /// Stop before a mesh with more vertices than this.
        #[arg(long)]
        max_vertices: Option<usize>,
        /// Stop after this many refinements.
        #[arg(long)]
        steps: Option<usize>,
        /// Also write each step's dual submesh S_h with λ_h and the owner vertex of each cell
        /// (dual.xdmf in each step's directory; about 430 bytes per vertex, twice the rest of a
        /// step, which holds the estimator's fields)
        #[arg(long)]
        dual: bool,
        /// The result directory; default adapt/<case name>.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = membrane_contact::parallel::use_threads(cli.threads) {
        let _ = writeln!(std::io::stderr(), "error: {e}");
        return ExitCode::FAILURE;
    }
    if !cli.quiet {
        membrane_contact::progress::show();
    }
    let verbose = cli.verbose;
    let result = match cli.command {
        Command::Solve {
            print_default: true, ..
        } => {
            say(membrane_contact::case::DEFAULT_CASE);
            Ok(())
        }
        Command::Solve {
            case,
            output,
            n,
            refine,
            cold,
            linear,
            hminus1,
            flux,
            estimate,
            dual,
            ..
        } => solve(
            case,
            output,
            (n, refine),
            (cold, linear),
            [hminus1, flux, estimate, dual],
            verbose,
        ),
        Command::Study {
            case,
            levels,
            refine,
            cold,
            linear,
            grading,
            hminus1_max,
            output,
        } => {
            let levels = levels.map(Levels::Cells).or(refine.map(Levels::Refine));
            study(case, levels, (cold, linear), grading, hminus1_max, output)
        }
        Command::Adapt {
            case,
            n,
            refine,
            theta,
            target,
            max_vertices,
            steps,
            dual,
            output,
        } => adapt(
            case,
            (n, refine),
            (theta, target, max_vertices, steps),
            dual,
            output,
        ),
    };
    membrane_contact::atomic::exit_as_signalled();
    let result = result.and_then(|()| match membrane_contact::progress::stdout_error() {
        Some(e) => Err(format!("cannot write the summary to stdout: {e} (the result is written)").into()),
        None => Ok(()),
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            membrane_contact::progress::finish();
            let _ = writeln!(std::io::stderr(), "error: {e}");
            ExitCode::FAILURE
        }
    }
}

type Failure = Box<dyn std::error::Error>;

/// The case of `path` (the default case without one) and its name, with the linear solver
/// `linear` when given (a name of [`LinearSolver::NAMES`], checked by the argument parser).
fn read_case(path: &Option<PathBuf>, linear: Option<String>) -> Result<(Case, String), Failure> {
    let (mut case, name) = match path {
        Some(p) => {
            // The stem of "..toml" is ".": a name that is not one names "case"; that of
            // "beam.h5.toml" would be refused as a file's name, and names "beam".
            let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned());
            let name = (stem(p))
                .and_then(
                    |s| match membrane_contact::atomic::file_extension(Path::new(&s)) {
                        Some(_) => stem(Path::new(&s)),
                        None => Some(s),
                    },
                )
                .filter(|s| !matches!(s.as_str(), "" | "." | ".."))
                .unwrap_or_else(|| "case".into());
            (Case::read(p)?, name)
        }
        None => (Case::default_case(), "default".into()),
    };
    if let Some(solver) = linear.as_deref().and_then(LinearSolver::from_name) {
        case.solver.linear = solver;
    }
    Ok((case, name))
}

/// The given output directory, or `default/name` (`default` made with the result, and removed
/// again, if still empty, when the run fails: a failed study left an empty `study/`).
fn output_dir(output: Option<PathBuf>, default: &str, name: &str) -> PathBuf {
    output.unwrap_or_else(|| PathBuf::from(default).join(name))
}

/// The path of `file` in the result `dir` for a user to open: absolute (ParaView's Xdmf3 reader
/// crashes on a bare relative name), without `..` or doubled separators where the directory can
/// be resolved.
fn to_open(dir: &Path, file: &str) -> String {
    let resolved = std::fs::canonicalize(dir).or_else(|_| std::path::absolute(dir));
    resolved
        .unwrap_or_else(|_| dir.to_path_buf())
        .join(file)
        .display()
        .to_string()
}

fn solve(
    case_path: Option<PathBuf>,
    output: Option<PathBuf>,
    (n, refine): (Option<usize>, Option<usize>),
    (cold, linear): (bool, Option<String>),
    [hminus1, flux, estimate, dual]: [bool; 4],
    verbose: bool,
) -> Result<(), Failure> {
    let (mut case, name) = read_case(&case_path, linear)?;
    if let Some(n) = n {
        case.set_cells(n)
            .map_err(|e| CaseError(format!("--n {n}: {e}")))?;
    }
    if let Some(k) = refine {
        case.refine = k;
    }
    let output = output_dir(output, "results", &name);
    let start = if cold { Start::Cold } else { Start::Nested };
    let options = run::Options {
        start,
        hminus1,
        flux,
        estimate,
        dual,
    };
    let r = run::solve(&case, &options, &output)?;
    membrane_contact::progress::finish();
    // The summary on stdout, whole or (on a failure) not at all.
    say(&r.summary(verbose));
    let dual = if r.writes_dual {
        format!(" and {}", to_open(&output, "dual.xdmf"))
    } else {
        String::new()
    };
    say(&format!(
        "result      {} — open {}{dual} in ParaView (Xdmf3 reader)\n",
        output.display(),
        to_open(&output, "solution.xdmf")
    ));
    Ok(())
}

fn study(
    case_path: Option<PathBuf>,
    levels: Option<Levels>,
    (cold, linear): (bool, Option<String>),
    grading: Option<Vec<f64>>,
    hminus1_max: usize,
    output: Option<PathBuf>,
) -> Result<(), Failure> {
    let (case, name) = read_case(&case_path, linear)?;
    let levels = levels.unwrap_or_else(|| study::default_levels(&case));
    let dir = output_dir(output, "study", &name);
    let options = StudyOptions {
        levels,
        cold,
        hminus1_max,
        grading,
    };
    study::study(&case, &name, &options, &dir)?;
    membrane_contact::progress::finish();
    let plot = if dir.join("errors.png").exists() {
        ", errors.png"
    } else {
        ""
    };
    say(&format!(
        "study       {} (study.md, .csv, .json{plot}, iterations*.png)\n",
        dir.display()
    ));
    Ok(())
}

fn adapt(
    case_path: Option<PathBuf>,
    (n, refine): (Option<usize>, Option<usize>),
    (theta, target, max_vertices, steps): (Option<f64>, Option<f64>, Option<usize>, Option<usize>),
    dual: bool,
    output: Option<PathBuf>,
) -> Result<(), Failure> {
    let (mut case, name) = read_case(&case_path, None)?;
    if let Some(n) = n {
        case.set_cells(n)
            .map_err(|e| CaseError(format!("--n {n}: {e}")))?;
    }
    if let Some(k) = refine {
        case.refine = k;
    }
    let mut settings = case.adapt;
    settings.theta = theta.unwrap_or(settings.theta);
    settings.target = target.or(settings.target);
    settings.max_vertices = max_vertices.unwrap_or(settings.max_vertices);
    settings.steps = steps.unwrap_or(settings.steps);
    settings
        .check(|k| format!("--{}", k.replace('_', "-")))
        .map_err(CaseError)?;
    let dir = output_dir(output, "adapt", &name);
    let adapted = membrane_contact::adapt::adapt(&case, &settings, dual, &dir)?;
    membrane_contact::progress::finish();
    say(&format!("stopped     by {}\n", adapted.stopped));
    let plot = if dir.join("adapt.png").exists() {
        ", adapt.png"
    } else {
        ""
    };
    say(&format!(
        "adapt       {} (adapt.md, .csv, .json{plot}; open {} in ParaView (Xdmf3 reader): one time step per adapt step)\n",
        dir.display(),
        to_open(&dir, "adapt.xdmf")
    ));
    Ok(())
}
