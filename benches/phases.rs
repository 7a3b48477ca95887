//! `make bench`: time of each phase (writing the result included) and peak memory of the contact
//! solve, beside one scalar Poisson factorization + solve on the same mesh: the default case on the
//! unit square with N × N cells (`N`), or the disk case `data/cases/disk_contact.toml` with h = 0.14
//! refined K times (`disk-K`: about 1.1M vertices at K = 6).
//!
//! Usage: `cargo bench --bench phases -- contact MESH` or `-- poisson MESH` (one process per figure,
//! so that the peak resident memory is that of one run), both by Cholesky (`[solver] linear =
//! "direct"`); `contact-mg` and `poisson-mg` solve with multigrid (the default; `poisson-mg`: one
//! MG-preconditioned CG solve from zero, setup included).

use membrane_contact::assembly::Stiffness;
use membrane_contact::case::{Case, MeshSpec};
use membrane_contact::contact::{LinearSolver, Start};
use membrane_contact::linear::InteriorSystem;
use membrane_contact::mesh::{Mesh, Prolongation};
use membrane_contact::multigrid::Hierarchy;
use membrane_contact::run;
use std::time::Instant;

/// Large allocations on huge pages (see [`membrane_contact::pages`]).
#[global_allocator]
static ALLOCATOR: membrane_contact::pages::HugePages = membrane_contact::pages::HugePages;

/// Peak resident set size of this process, in MB.
fn peak_mb() -> f64 {
    membrane_contact::pages::peak_resident_bytes().map_or(f64::NAN, |b| b as f64 / (1 << 20) as f64)
}

/// The case of a bench mesh: `N` (the default case on N × N cells) or `disk-K`.
fn case(mesh: &str) -> Case {
    let mut case = match mesh.strip_prefix("disk-") {
        Some(k) => {
            let mut c =
                Case::read(std::path::Path::new("data/cases/disk_contact.toml")).expect("the disk case");
            if let MeshSpec::Domain { h, .. } = &mut c.mesh {
                *h = 0.14;
            }
            c.refine = k.parse().expect("disk-K");
            c
        }
        None => {
            let mut c = Case::default_case();
            c.set_cells(mesh.parse().expect("N or disk-K"))
                .expect("a built-in mesh");
            c
        }
    };
    case.exact = None;
    case
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    let [what, mesh] = args.as_slice() else {
        eprintln!("usage: phases contact|poisson N|disk-K");
        std::process::exit(2);
    };
    let mut case = case(mesh);
    let (what, linear) = match what.strip_suffix("-mg") {
        Some(w) => (w, LinearSolver::Multigrid),
        None => (what.as_str(), LinearSolver::Direct),
    };
    case.solver.linear = linear;
    match (what, case.solver.linear) {
        ("contact", _) => {
            let dir = tempfile::tempdir().expect("a temporary directory");
            let options = run::Options {
                start: Start::Nested,
                hminus1: false,
                flux: false,
                estimate: false,
                dual: false,
            };
            let t = Instant::now();
            let r = run::solve(&case, &options, &dir.path().join("bench")).expect("solve");
            let total = t.elapsed().as_secs_f64();
            let (tm, st) = (&r.timings, &r.solution.obstacle.stats);
            println!(
                "{}{mesh} threads={} vertices={} mesh={:.3} assembly={:.3} coarse={:.3} symbolic={:.3} numeric={:.3} solve={:.3} postprocess={:.3} write={:.3} contact_solve={:.3} total={:.3} iterations={} local_iterations={} coarse_iterations={} factorizations={} cg_v={} cg={} coarse_cg_max={} peak_mb={:.0}",
                if st.linear == LinearSolver::Multigrid { "contact-mg " } else { "contact " },
                membrane_contact::parallel::threads(),
                r.problem.mesh.n_vertices(),
                tm.mesh,
                tm.assembly,
                st.coarse_seconds,
                st.symbolic_seconds,
                st.numeric_seconds,
                st.solve_seconds,
                tm.postprocess,
                tm.write,
                st.wall_seconds,
                total,
                st.iterations,
                st.local_iterations,
                join(&st.coarse_iterations),
                st.factorizations,
                st.v_cg_iterations,
                join(&st.cg_iterations),
                join(&(st.coarse_cg_iterations.iter()).map(|l| l.iter().copied().max().unwrap_or(0)).collect::<Vec<_>>()),
                peak_mb()
            );
        }
        ("poisson", LinearSolver::Multigrid) => poisson_mg(&case, mesh),
        ("poisson", LinearSolver::Direct) => {
            let mesh_built = case.mesh().expect("the mesh");
            let k = Stiffness::assemble(&mesh_built);
            let t = Instant::now();
            let sys = InteriorSystem::new(&k, &mesh_built.on_boundary);
            let symbolic = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let mut factor = sys.factorization();
            factor.factorize(&vec![false; sys.n()]).unwrap();
            let numeric = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let mut x = vec![1.0; sys.n()];
            factor.solve(&mut x);
            let solve = t.elapsed().as_secs_f64();
            println!(
                "poisson {mesh} symbolic={symbolic:.3} numeric={numeric:.3} solve={solve:.3} total={:.3} peak_mb={:.0}",
                symbolic + numeric + solve,
                peak_mb()
            );
        }
        _ => panic!("unknown benchmark {what}"),
    }
}

fn join(v: &[usize]) -> String {
    v.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(",")
}

/// One Poisson solve by CG preconditioned by V-cycles: K u = 1 inside, from zero.
fn poisson_mg(case: &Case, name: &str) {
    let t = Instant::now();
    let (mesh, coarser) = case.hierarchy(true, Default::default()).expect("the meshes");
    let k = Stiffness::assemble(&mesh);
    let mesh_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let meshes: Vec<&Mesh> = std::iter::once(&mesh).chain(&coarser).collect();
    let prolongations: Vec<Prolongation> = meshes.windows(2).map(|w| Prolongation::new(w[0], w[1])).collect();
    let mass = membrane_contact::assembly::lumped_mass(&mesh);
    let hierarchy = Hierarchy::new(&k, &mass, &prolongations);
    let transfer = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut mg = hierarchy.preconditioner(mesh.on_boundary.clone()).expect("SPD");
    let setup = t.elapsed().as_secs_f64();
    let b: Vec<f64> = mesh
        .on_boundary
        .iter()
        .map(|&e| if e { 0.0 } else { 1.0 })
        .collect();
    let (mut solve, mut iterations) = (f64::INFINITY, 0);
    for _ in 0..3 {
        let t = Instant::now();
        let mut x = vec![0.0; b.len()];
        iterations = mg.solve(b.clone(), &mut x, 1e-12, 200).expect("converges");
        solve = solve.min(t.elapsed().as_secs_f64());
    }
    println!(
        "poisson-mg {name} threads={} levels={} mesh={mesh_seconds:.3} transfers={transfer:.3} setup={setup:.3} solve={solve:.3} total={:.3} cg={iterations} peak_mb={:.0}",
        membrane_contact::parallel::threads(),
        hierarchy.levels(),
        transfer + setup + solve,
        peak_mb()
    );
}
