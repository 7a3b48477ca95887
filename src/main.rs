//! The `membrane-contact` command line.

use clap::{Parser, Subcommand};
use membrane_contact::case::Case;
use membrane_contact::run::{self, Start};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    version,
    about = "Unilateral contact between two elastic membranes: P1 finite elements, discrete action by local postprocessing"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Solve one case and write NAME.h5 + NAME.xdmf (open the .xdmf in ParaView).
    Solve {
        /// Case file (TOML); the built-in default case when omitted.
        case: Option<PathBuf>,
        /// Result file (.h5); default results/<case name>.h5.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Cells per side of a built-in mesh (overrides the case).
        #[arg(long)]
        n: Option<usize>,
        /// Start the active-set method from no contact instead of nested iteration.
        #[arg(long)]
        cold: bool,
        /// With an exact solution, also compute ‖λ − λh‖_H⁻¹ (a solve on the dual submesh).
        #[arg(long)]
        hminus1: bool,
        /// Also reconstruct the fluxes t_ih (4.13) on the dual submesh, check their local
        /// conservation and write t_ih and div t_ih as its cell data.
        #[arg(long)]
        flux: bool,
        /// Print the built-in default case and exit.
        #[arg(long)]
        print_default: bool,
    },
    /// Convergence study: solve on refined meshes (each level warm-started from the previous one),
    /// tabulate errors, EOCs and iterations, and plot them.
    Study {
        /// Case file (TOML); the built-in default case when omitted.
        case: Option<PathBuf>,
        /// Cells per side on each level, e.g. 8,16,32,64 (default: the case's validation sizes).
        #[arg(long, value_delimiter = ',')]
        levels: Option<Vec<usize>>,
        /// Also solve every level from a cold start, to compare active-set iterations.
        #[arg(long)]
        cold: bool,
        /// Grading exponents of an L-shaped mesh to compare, e.g. 1,2 (uniform and graded).
        #[arg(long, value_delimiter = ',')]
        grading: Option<Vec<f64>>,
        /// Largest level on which ‖λ − λh‖_H⁻¹ is computed.
        #[arg(long, default_value_t = 512)]
        hminus1_max: usize,
        /// Output directory; default study/<case name>.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Solve {
            print_default: true, ..
        } => {
            print!("{}", membrane_contact::case::DEFAULT_CASE);
            Ok(())
        }
        Command::Solve {
            case,
            output,
            n,
            cold,
            hminus1,
            flux,
            ..
        } => solve(case, output, n, cold, hminus1, flux),
        Command::Study {
            case,
            levels,
            cold,
            grading,
            hminus1_max,
            output,
        } => study(case, levels, cold, grading, hminus1_max, output),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn read_case(path: &Option<PathBuf>) -> Result<Case, Box<dyn std::error::Error>> {
    Ok(match path {
        Some(p) => Case::read(p)?,
        None => Case::default_case(),
    })
}

fn case_name(path: &Option<PathBuf>) -> String {
    path.as_ref()
        .and_then(|p| p.file_stem())
        .map_or("default".to_string(), |s| s.to_string_lossy().to_string())
}

fn solve(
    case_path: Option<PathBuf>,
    output: Option<PathBuf>,
    n: Option<usize>,
    cold: bool,
    hminus1: bool,
    flux: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut case = read_case(&case_path)?;
    if let Some(n) = n {
        if n == 0 {
            return Err("--n must be at least 1".into());
        }
        case.set_cells(n);
    }
    let output = match output {
        Some(o) => o,
        None => {
            std::fs::create_dir_all("results")?;
            PathBuf::from("results").join(format!("{}.h5", case_name(&case_path)))
        }
    };
    match case.file.title.as_str() {
        "" => println!("case        {}", case.origin),
        title => println!("case        {} — {title}", case.origin),
    }
    let start = if cold { Start::Cold } else { Start::Nested };
    let mut result = run::solve(&case, start, None)?;
    if hminus1 {
        result.compute_h_minus_1(&case);
    }
    if flux {
        result.compute_flux();
    }
    let xdmf = result.write(&case, &output)?;
    print!("{}", result.summary());
    let sidecars: Vec<String> = xdmf.iter().map(|p| p.display().to_string()).collect();
    println!(
        "result      {} — open {} in ParaView (Xdmf3 reader)",
        output.display(),
        sidecars.join(" and ")
    );
    Ok(())
}

fn study(
    case_path: Option<PathBuf>,
    levels: Option<Vec<usize>>,
    cold: bool,
    grading: Option<Vec<f64>>,
    hminus1_max: usize,
    output: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    use membrane_contact::io::write_atomic;
    use membrane_contact::study::{self, StudyOptions};
    let case = read_case(&case_path)?;
    let name = case_name(&case_path);
    let levels = levels
        .or_else(|| case.file.validation.as_ref().map(|v| v.sizes.clone()))
        .unwrap_or_else(|| vec![8, 16, 32, 64]);
    if levels.is_empty() || levels.contains(&0) || levels.windows(2).any(|w| w[1] <= w[0]) {
        return Err(format!("--levels must be increasing positive sizes, got {levels:?}").into());
    }
    if case.cells().is_none() {
        return Err("a study needs a built-in mesh (rectangle or lshape), not a mesh file".into());
    }
    let dir = output.unwrap_or_else(|| PathBuf::from("study").join(&name));
    std::fs::create_dir_all(&dir)
        .map_err(|e| format!("{}: cannot create the directory: {e}", dir.display()))?;
    let options = StudyOptions {
        levels: levels.clone(),
        cold,
        h_minus_1_max: hminus1_max,
    };
    let variants: Vec<(String, Case)> = match grading {
        None => vec![(String::new(), case.clone())],
        Some(gs) => gs
            .iter()
            .map(|&g| {
                let mut c = case.clone();
                c.set_grading(g)?;
                Ok((format!("grading {g}"), c))
            })
            .collect::<Result<_, membrane_contact::case::CaseError>>()?,
    };
    let mut markdown = format!("# Convergence study: {} ({})\n\n", case.file.title, case.origin);
    let mut results = Vec::new();
    for (label, c) in &variants {
        let suffix = label
            .strip_prefix("grading ")
            .map_or(String::new(), |g| format!("-g{g}"));
        let bar = indicatif::ProgressBar::new(levels.len() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} levels {msg}")
                .expect("a valid template"),
        );
        bar.set_prefix(format!("study {name} {label}"));
        let result = study::run(c, &options, |_, l| {
            bar.set_message(format!("{}²: {} iterations", l.cells, l.iterations));
            bar.inc(1);
        })?;
        bar.finish_and_clear();
        let title = if label.is_empty() {
            name.clone()
        } else {
            format!("{name}, {label}")
        };
        let table = study::markdown(&title, &result);
        println!("{table}");
        markdown += &table;
        markdown += "\n";
        write_atomic(
            &dir.join(format!("study{suffix}.csv")),
            study::csv(&result).as_bytes(),
        )?;
        write_atomic(
            &dir.join(format!("study{suffix}.json")),
            serde_json::to_string_pretty(&result)?.as_bytes(),
        )?;
        write_drawn(&dir.join(format!("iterations{suffix}.png")), |p| {
            study::plot_iterations(p, &format!("{title}: active-set iterations"), &result)
        })?;
        results.push((
            if label.is_empty() {
                name.clone()
            } else {
                label.clone()
            },
            result,
        ));
    }
    let series: Vec<(String, &[study::Level])> =
        results.iter().map(|(l, r)| (l.clone(), r.as_slice())).collect();
    write_drawn(&dir.join("errors.png"), |p| {
        study::plot_errors(p, &format!("{name}: errors"), &series)
    })?;
    markdown += "EOCs against h, and in parentheses against N^(−1/2) (N vertices). ‖λ−λh‖_H⁻¹ is the dual \
                 norm over P1 functions on the dual submesh S_h (a lower bound converging to the true norm).\n\n\
                 ![errors](errors.png)\n";
    write_atomic(&dir.join("study.md"), markdown.as_bytes())?;
    println!(
        "study       {} (study.md, .csv, .json, errors.png, iterations*.png)",
        dir.display()
    );
    Ok(())
}

/// Draws a file through a temporary path with the same extension, then renames it.
fn write_drawn(
    path: &std::path::Path,
    draw: impl FnOnce(&std::path::Path) -> Result<(), String>,
) -> Result<(), Box<dyn std::error::Error>> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".tmp-{}-{name}", std::process::id()));
    let result =
        draw(&tmp).and_then(|_| std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display())));
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.into());
    }
    Ok(())
}
