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
        /// Print the built-in default case and exit.
        #[arg(long)]
        print_default: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Solve {
            case,
            output,
            n,
            cold,
            print_default,
        } => {
            if print_default {
                print!("{}", membrane_contact::case::DEFAULT_CASE);
                return ExitCode::SUCCESS;
            }
            match solve(case, output, n, cold) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}

fn solve(
    case_path: Option<PathBuf>,
    output: Option<PathBuf>,
    n: Option<usize>,
    cold: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut case = match &case_path {
        Some(p) => Case::read(p)?,
        None => Case::default_case(),
    };
    if let Some(n) = n {
        if n == 0 {
            return Err("--n must be at least 1".into());
        }
        case.set_cells(n);
    }
    let output = match output {
        Some(o) => o,
        None => {
            let stem = case_path
                .as_ref()
                .and_then(|p| p.file_stem())
                .map_or("default".to_string(), |s| s.to_string_lossy().to_string());
            std::fs::create_dir_all("results")?;
            PathBuf::from("results").join(format!("{stem}.h5"))
        }
    };
    println!("case        {} — {}", case.origin, case.file.title);
    let start = if cold { Start::Cold } else { Start::Nested };
    let mut result = run::solve(&case, start, None)?;
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
