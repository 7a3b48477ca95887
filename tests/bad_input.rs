//! Bad input, as a user would give it on the command line: every case must fail with a message
//! naming the problem and a non-zero exit, leave no file behind, and leave an earlier result alone.

mod common;
use common::listing;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::Mutex;

/// Held while a test writes an HDF5 file or starts a process: a child forked while another test
/// has an HDF5 file open would inherit its descriptor and HDF5's lock on it.
static FILES: Mutex<()> = Mutex::new(());

fn run(cmd: &mut Command) -> Output {
    let child = {
        let _guard = FILES.lock().unwrap_or_else(|e| e.into_inner());
        cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap()
    };
    child.wait_with_output().unwrap()
}

const GOOD: &str = "mu1 = 1.0\nmu2 = 2.0\nf1 = -5\nf2 = 5\ng = \"0.1*x\"\n";
const SQUARE: &str = "[mesh]\nkind = \"rectangle\"\nn = [6, 6]\n";
const EARLIER: &[u8] = b"an earlier result";

/// An earlier result directory `out` in `dir`, as the program marks its results.
fn earlier_result(dir: &Path) -> PathBuf {
    let out = dir.join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(".membrane-contact"), "membrane-contact solution\n").unwrap();
    std::fs::write(out.join("solution.h5"), EARLIER).unwrap();
    out
}

/// Runs `solve` on `case_text` (with mesh files written by `setup`) into a directory holding an
/// earlier result `out`; checks the failure and returns stderr.
fn fails(case_text: &str, setup: impl Fn(&Path), extra: &[&str], output: Option<PathBuf>) -> String {
    command_fails("solve", case_text, setup, extra, output)
}

/// As [`fails`], for the subcommand `command`.
fn command_fails(
    command: &str,
    case_text: &str,
    setup: impl Fn(&Path),
    extra: &[&str],
    output: Option<PathBuf>,
) -> String {
    limited_command_fails(command, case_text, setup, extra, output, |_| {})
}

/// As [`command_fails`], with the command prepared by `prepare` before it runs.
fn limited_command_fails(
    command: &str,
    case_text: &str,
    setup: impl Fn(&Path),
    extra: &[&str],
    output: Option<PathBuf>,
    prepare: impl FnOnce(&mut Command),
) -> String {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    let case = dir.path().join("case.toml");
    std::fs::write(&case, case_text).unwrap();
    let earlier = earlier_result(dir.path());
    let out = output.unwrap_or_else(|| earlier.clone());
    let before = listing(dir.path());
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_membrane-contact"));
    // Quiet: stderr holds the error alone, no progress.
    cmd.arg(command)
        .arg("--quiet")
        .arg(&case)
        .arg("-o")
        .arg(&out)
        .args(extra);
    prepare(&mut cmd);
    let run = run(&mut cmd);
    let stderr = String::from_utf8_lossy(&run.stderr).to_string();
    assert_eq!(run.status.code(), Some(1), "exit status; stderr: {stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.is_empty(), "a failed run prints no summary: {stdout}");
    assert_eq!(listing(dir.path()), before, "files were left behind or removed");
    assert_eq!(listing(&earlier), [".membrane-contact", "solution.h5"]);
    assert_eq!(
        std::fs::read(earlier.join("solution.h5")).unwrap(),
        EARLIER,
        "the earlier result was touched"
    );
    stderr
}

fn case_fails(case_text: &str) -> String {
    fails(case_text, |_| {}, &[], None)
}

/// A case reading `mesh.h5`, written with the given points and triangles.
fn mesh_fails(points: &[[f64; 2]], cells: &[[i64; 3]]) -> String {
    let (points, cells) = (points.to_vec(), cells.to_vec());
    fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.h5\"\n"),
        move |dir| write_mesh(&dir.join("mesh.h5"), &points, &cells),
        &[],
        None,
    )
}

fn write_mesh(path: &Path, points: &[[f64; 2]], cells: &[[i64; 3]]) {
    let _guard = FILES.lock().unwrap_or_else(|e| e.into_inner());
    let f = hdf5::File::create(path).unwrap();
    let p = ndarray::Array2::from_shape_fn((points.len(), 2), |(i, k)| points[i][k]);
    let c = ndarray::Array2::from_shape_fn((cells.len(), 3), |(i, k)| cells[i][k]);
    f.new_dataset_builder()
        .with_data(&p)
        .create("/mesh/geometry")
        .unwrap();
    f.new_dataset_builder()
        .with_data(&c)
        .create("/mesh/topology")
        .unwrap();
}

/// The unit square cut into four triangles around its centre (vertex 4).
fn fan() -> (Vec<[f64; 2]>, Vec<[i64; 3]>) {
    (
        vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]],
        vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
    )
}

fn contains(stderr: &str, needle: &str) {
    assert!(stderr.contains(needle), "expected «{needle}» in: {stderr}");
}

#[test]
fn the_good_case_runs_and_file_meshes_work() {
    // The baseline the table perturbs: it must succeed, also with a mesh read from a file.
    let dir = tempfile::tempdir().unwrap();
    let (p, c) = fan();
    write_mesh(&dir.path().join("mesh.h5"), &p, &c);
    for mesh in [SQUARE, "[mesh]\nkind = \"file\"\npath = \"mesh.h5\"\n"] {
        std::fs::write(dir.path().join("case.toml"), format!("{GOOD}{mesh}")).unwrap();
        let out = dir.path().join("good");
        let run = run(Command::new(env!("CARGO_BIN_EXE_membrane-contact")).args([
            "solve",
            dir.path().join("case.toml").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]));
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        assert_eq!(
            listing(&out),
            [".membrane-contact", "solution.h5", "solution.xdmf"]
        );
    }
}

#[test]
fn unknown_key() {
    contains(
        &case_fails(&format!("{GOOD}bogus = 1\n{SQUARE}")),
        "unknown field `bogus`",
    );
}

#[test]
fn missing_key() {
    contains(
        &case_fails(&format!("mu1 = 1.0\nmu2 = 1.0\nf1 = 0\nf2 = 0\n{SQUARE}")),
        "missing field `g`",
    );
}

#[test]
fn wrong_type() {
    let e = case_fails(&format!("{}{SQUARE}", GOOD.replace("mu1 = 1.0", "mu1 = \"one\"")));
    contains(&e, "mu1");
    contains(&e, "invalid type");
    let e = case_fails(&format!(
        "{}{SQUARE}",
        GOOD.replace("g = \"0.1*x\"", "g = [1, 2]")
    ));
    contains(&e, "«g = [1, 2]»): expected an expression: a string such as");
}

/// An expression over several lines is quoted on the error's one line (it spanned three).
#[test]
fn a_multiline_expression_is_quoted_on_one_line() {
    let case = format!("{GOOD}{SQUARE}").replace("f1 = -5", "f1 = \"\"\"\n-1 +\n   x*^y\n\"\"\"");
    contains(
        &case_fails(&case),
        r#"key 'f1' = "-1 +\n   x*^y\n": unexpected '^' (at character 11)"#,
    );
}

/// Levels of 0 cells were accepted, and `study` then blamed a --levels never given.
#[test]
fn validation_levels_of_no_cells() {
    let e = case_fails(&format!("{GOOD}{SQUARE}[validation]\nsizes = [0, 8]\n"));
    contains(
        &e,
        "key 'validation.sizes' = [0, 8]: need 1 cell per side at least",
    );
}

#[test]
fn invalid_toml() {
    contains(&case_fails("mu1 = = 1\n"), "line 1, column 7 («mu1 = = 1»): ");
}

/// Thousands of threads are a slip of the keyboard, refused at once whether they come from
/// `--threads` or from `RAYON_NUM_THREADS` (a run once started 6 000 threads and ran for minutes).
#[test]
fn too_many_threads() {
    let case = format!("{GOOD}{SQUARE}");
    let err = fails(&case, |_| {}, &["--threads", "100000"], None);
    contains(&err, "--threads 100000: at most 1024 threads");
    let err = limited_command_fails(
        "solve",
        &case,
        |_| {},
        &[],
        None,
        |c| {
            c.env("RAYON_NUM_THREADS", "100000");
        },
    );
    contains(&err, "RAYON_NUM_THREADS=100000: at most 1024 threads");
    // None, and what rayon would ignore silently (a run on one per core), are errors too.
    let err = fails(&case, |_| {}, &["--threads", "0"], None);
    contains(&err, "--threads 0: need 1 thread at least");
    for value in ["abc", "-1", "1e3"] {
        let env = |c: &mut Command| {
            c.env("RAYON_NUM_THREADS", value);
        };
        let err = limited_command_fails("solve", &case, |_| {}, &[], None, env);
        contains(
            &err,
            &format!("RAYON_NUM_THREADS={value}: need a whole number of threads"),
        );
    }
}

#[test]
fn missing_case_file() {
    let dir = tempfile::tempdir().unwrap();
    let run = run(Command::new(env!("CARGO_BIN_EXE_membrane-contact")).args([
        "solve",
        dir.path().join("nope.toml").to_str().unwrap(),
        "-o",
        dir.path().join("out").to_str().unwrap(),
    ]));
    assert_eq!(run.status.code(), Some(1));
    contains(&String::from_utf8_lossy(&run.stderr), "cannot read the case file");
}

#[test]
fn zero_tension() {
    contains(
        &case_fails(&format!("{}{SQUARE}", GOOD.replace("mu1 = 1.0", "mu1 = 0.0"))),
        "key 'mu1' = 0",
    );
}

#[test]
fn negative_tension() {
    contains(
        &case_fails(&format!("{}{SQUARE}", GOOD.replace("mu2 = 2.0", "mu2 = -2.0"))),
        "key 'mu2' = -2",
    );
}

#[test]
fn negative_boundary_height() {
    let e = case_fails(&format!("{}{SQUARE}", GOOD.replace("0.1*x", "0.1*x - 0.05")));
    contains(&e, "g = -0.05 < g2 = 0 at the boundary vertex (0, 0)");
    contains(
        &e,
        "g_h, the interpolant of g, which must be ≥ g2 at every boundary vertex of the mesh",
    );
}

/// A good obstacle problem: μ, f, ψ and g, with ψ < g on ∂ω.
const OBSTACLE: &str = "problem = \"obstacle\"\nmu = 1.0\nf = -5\npsi = \"0.1 - x*x\"\ng = 0.2\n";

#[test]
fn the_obstacle_problem_and_g2_run_and_their_keys_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [
        ("obstacle", OBSTACLE.to_string()),
        ("g2", format!("{GOOD}g2 = \"-0.1 + 0.01*y\"\n")),
    ] {
        let case = dir.path().join(format!("{name}.toml"));
        std::fs::write(&case, format!("{text}{SQUARE}")).unwrap();
        let out = dir.path().join(name);
        let run = run(Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
            .args(["solve", "--quiet"])
            .arg(&case)
            .arg("-o")
            .arg(&out));
        assert!(
            run.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let key = |e: &str, needle: &str| contains(&case_fails(&format!("{e}{SQUARE}")), needle);
    key(
        &OBSTACLE.replace("obstacle", "obstacles"),
        "key 'problem' = \"obstacles\": expected \"membranes\" or \"obstacle\"",
    );
    key(
        &format!("{OBSTACLE}mu1 = 2.0\n"),
        "key 'mu1' belongs to problem = \"membranes\", not to problem = \"obstacle\"",
    );
    key(
        &format!("{GOOD}psi = 0\n"),
        "key 'psi' belongs to problem = \"obstacle\", not to problem = \"membranes\"",
    );
    key(
        &OBSTACLE.replace("psi = \"0.1 - x*x\"\n", ""),
        "key 'psi' is missing (problem = \"obstacle\")",
    );
    key(
        &OBSTACLE.replace("mu = 1.0", "mu = -1.0"),
        "key 'mu' = -1: the tension must be a positive number",
    );
    key(
        &OBSTACLE.replace("mu = 1.0", "mu = 1e-320"),
        "key 'mu' = 1e-320: the tension is below double precision's normal range (2.2250738585072014e-308)",
    );
    // g < ψ at (1, 0): ψ = 0.1 − x² there is −0.9, so lift ψ by 1.
    key(
        &OBSTACLE.replace("0.1 - x*x", "1.1 - x*x"),
        "g = 0.2 < psi = 1.1 at the boundary vertex (0, 0)",
    );
    key(
        &OBSTACLE.replace("0.1 - x*x", "1.1 - x*x"),
        "(the membrane may not lie below the obstacle)",
    );
    key(
        &format!("{GOOD}g2 = 0.05\n"),
        "g = 0 < g2 = 0.05 at the boundary vertex (0, 0)",
    );
    key(
        &format!("{GOOD}g2 = 0.05\n"),
        "(membrane 1 may not lie below membrane 2)",
    );
    key(
        &format!("{OBSTACLE}[exact]\nu1 = 0\nu2 = 0\nlambda = 0\n"),
        "key 'exact.u1' does not belong to this problem",
    );
    key(
        &format!("{OBSTACLE}[exact]\nlambda = 0\n"),
        "key 'exact.u' is missing",
    );
    let e = fails(
        &format!("{GOOD}g2 = -0.1\n{SQUARE}"),
        |_| {},
        &["--estimate"],
        None,
    );
    contains(&e, "with key 'g2' it is not available yet");
}

#[test]
fn malformed_expression() {
    contains(
        &case_fails(&format!("{}{SQUARE}", GOOD.replace("f1 = -5", "f1 = \"1 +\""))),
        "key 'f1' = \"1 +\"",
    );
}

#[test]
fn unknown_name_in_expression() {
    contains(
        &case_fails(&format!("{}{SQUARE}", GOOD.replace("f1 = -5", "f1 = \"z + 1\""))),
        "unknown name 'z'",
    );
}

/// A value of the wrong type is named in the case file's terms, not Rust's (usize, f64).
#[test]
fn a_wrong_type_is_named_in_the_case_file_s_terms() {
    let e = case_fails(&format!("{GOOD}{SQUARE}[solver]\nmax_iterations = 2.5\n"));
    contains(
        &e,
        "(«max_iterations = 2.5»): invalid type: floating point `2.5`, expected a whole number ≥ 0",
    );
    let e = case_fails(&format!("{}{SQUARE}", GOOD.replace("mu1 = 1.0", "mu1 = \"a\"")));
    contains(
        &e,
        "(«mu1 = \"a\"»): invalid type: string \"a\", expected a number",
    );
}

#[test]
fn toml_nan_and_inf_are_refused_as_numbers() {
    for (value, shown) in [("nan", "NaN"), ("-inf", "-inf"), ("+inf", "inf")] {
        let e = case_fails(&format!(
            "{}{SQUARE}",
            GOOD.replace("f1 = -5", &format!("f1 = {value}"))
        ));
        contains(&e, &format!("key 'f1' = {shown}: need a finite number"));
    }
}

#[test]
fn nan_in_the_domain() {
    let e = case_fails(&format!(
        "{}{SQUARE}",
        GOOD.replace("f1 = -5", "f1 = \"log(x - 0.5)\"")
    ));
    contains(&e, "f1 is NaN at (");
}

#[test]
fn infinity_in_the_domain() {
    let e = case_fails(&format!(
        "{}{SQUARE}",
        GOOD.replace("f2 = 5", "f2 = \"1/(x - x)\"")
    ));
    contains(&e, "f2 is inf at (");
}

#[test]
fn quadrature_degree_out_of_range() {
    contains(
        &case_fails(&format!("{GOOD}{SQUARE}[quadrature]\ndegree = 99\n")),
        "quadrature.degree",
    );
}

#[test]
fn iteration_cap() {
    let text =
        format!("mu1 = 1.0\nmu2 = 1.0\nf1 = -20\nf2 = 20\ng = 0.01\n{SQUARE}[solver]\nmax_iterations = 1\n");
    contains(
        &fails(&text, |_| {}, &["--cold"], None),
        "did not converge in 1 iterations",
    );
}

#[test]
fn mesh_too_large_for_memory() {
    let e = case_fails(&format!(
        "{GOOD}[mesh]\nkind = \"rectangle\"\nn = [200000, 200000]\n"
    ));
    // 800 bytes per vertex with multigrid (the default), 2700 with Cholesky.
    contains(&e, "40000400001 vertices need about 32000.3 GB");
    contains(&e, "use a coarser mesh");
    let e = case_fails(&format!(
        "{GOOD}[mesh]\nkind = \"rectangle\"\nn = [200000, 200000]\n[solver]\nlinear = \"direct\"\n"
    ));
    contains(&e, "40000400001 vertices need about 108001.1 GB");
}

#[test]
fn missing_mesh_file() {
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"absent.h5\"\n"),
        |_| {},
        &[],
        None,
    );
    contains(&e, "absent.h5: no such file");
}

#[test]
fn mesh_file_not_hdf5() {
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.h5\"\n"),
        |d| std::fs::write(d.join("mesh.h5"), "not hdf5").unwrap(),
        &[],
        None,
    );
    contains(&e, "not a readable HDF5 file");
}

#[test]
fn truncated_mesh_file() {
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.h5\"\n"),
        |d| {
            let (p, c) = fan();
            write_mesh(&d.join("full.h5"), &p, &c);
            let bytes = std::fs::read(d.join("full.h5")).unwrap();
            std::fs::write(d.join("mesh.h5"), &bytes[..bytes.len() / 2]).unwrap();
            std::fs::remove_file(d.join("full.h5")).unwrap();
        },
        &[],
        None,
    );
    assert!(
        e.contains("not a readable HDF5 file") || e.contains("cannot read"),
        "{e}"
    );
}

#[test]
fn non_triangle_cells() {
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.xdmf\"\n"),
        |d| {
            let (p, c) = fan();
            write_mesh(&d.join("mesh.h5"), &p, &c);
            let xdmf = "<Xdmf><Domain><Grid><Topology TopologyType=\"Quadrilateral\"><DataItem Format=\"HDF\">mesh.h5:/mesh/topology</DataItem></Topology><Geometry GeometryType=\"XY\"><DataItem Format=\"HDF\">mesh.h5:/mesh/geometry</DataItem></Geometry></Grid></Domain></Xdmf>";
            std::fs::write(d.join("mesh.xdmf"), xdmf).unwrap();
        },
        &[],
        None,
    );
    contains(&e, "cell type 'Quadrilateral' is not supported");
}

/// An XDMF mesh of `topology` on `mesh.h5`, whose datasets are `points` and `/mesh/cells` (1D for
/// a `Mixed` topology, else rows of 3); the mesh read, or the error.
fn read_xdmf(
    topology: &str,
    cells: &[i64],
    points: &[[f64; 3]],
) -> Result<membrane_contact::mesh::Mesh, String> {
    let mixed = topology == "Mixed";
    let dir = tempfile::tempdir().unwrap();
    {
        let _guard = FILES.lock().unwrap_or_else(|e| e.into_inner());
        let f = hdf5::File::create(dir.path().join("mesh.h5")).unwrap();
        let p = ndarray::Array2::from_shape_fn((points.len(), 3), |(i, k)| points[i][k]);
        f.new_dataset_builder()
            .with_data(&p)
            .create("/mesh/geometry")
            .unwrap();
        let c = ndarray::Array1::from_vec(cells.to_vec());
        let builder = f.new_dataset_builder();
        match mixed {
            true => builder.with_data(&c).create("/mesh/cells"),
            false => (builder.with_data(&c.into_shape_with_order((cells.len() / 3, 3)).unwrap()))
                .create("/mesh/cells"),
        }
        .unwrap();
    }
    let dimensions = match mixed {
        true => cells.len().to_string(),
        false => format!("{} 3", cells.len() / 3),
    };
    let xdmf = format!(
        "<Xdmf><Domain><Grid><Topology TopologyType=\"{topology}\"><DataItem Dimensions=\"{dimensions}\" Format=\"HDF\">mesh.h5:/mesh/cells</DataItem></Topology><Geometry GeometryType=\"XYZ\"><DataItem Dimensions=\"{} 3\" Format=\"HDF\">mesh.h5:/mesh/geometry</DataItem></Geometry></Grid></Domain></Xdmf>",
        points.len()
    );
    std::fs::write(dir.path().join("mesh.xdmf"), xdmf).unwrap();
    membrane_contact::mesh::file::read(&dir.path().join("mesh.xdmf")).map_err(|e| e.to_string())
}

/// meshio writes a mesh of several cell blocks (a Gmsh file's surfaces, its lines) as an XDMF
/// `Mixed` topology: its triangles are the mesh, and points and lines are left aside, as the .msh
/// reader leaves them (it was refused: "cell type 'Mixed' is not supported"), and so are points
/// that no triangle of a `Triangle` topology uses; a quadrilateral in
/// it is named. A mesh in a plane z = 5, or at z = 0 up to round-off, is the plane's (it was
/// refused: "the mesh must lie in the plane z = 0"); a tilted one is not.
#[test]
fn meshio_s_mixed_topologies_and_planes_off_z_0_are_read() {
    // Triangles in two blocks (XDMF type 4), between them a line (2, with its count of vertices)
    // and a vertex (1, with its count).
    let mixed = [
        4, 0, 1, 4, 4, 1, 2, 4, 2, 2, 0, 1, 1, 1, 3, 4, 2, 3, 4, 4, 3, 0, 4,
    ];
    let (points, triangles) = fan();
    let at = |z: [f64; 5]| -> Vec<[f64; 3]> { (0..5).map(|i| [points[i][0], points[i][1], z[i]]).collect() };
    let flat = &at([0.0; 5]);
    let mesh = read_xdmf("Mixed", &mixed, flat).unwrap();
    assert_eq!(mesh.points, points);
    let read: Vec<[i64; 3]> = mesh.triangles().map(|t| t.map(|v| v as i64)).collect();
    assert_eq!(read, triangles);
    // A point that only a vertex cell uses is left aside; a cell cut short is named.
    let beyond = [flat.clone(), vec![[3.0, 3.0, 0.0]]].concat();
    let fewer = read_xdmf("Mixed", &[&mixed[..], &[1, 1, 5]].concat(), &beyond).unwrap();
    assert_eq!(fewer.points, points);
    // So is a point no triangle of a Triangle topology uses (the centre of a circle arc, which
    // meshio keeps): it was refused as "belongs to no triangle". The others keep their order.
    let centre = [&flat[..2], &[[9.0, 9.0, 0.0]], &flat[2..]].concat();
    let shifted: Vec<i64> = (triangles.iter().flatten())
        .map(|&v| if v >= 2 { v + 1 } else { v })
        .collect();
    let mesh = read_xdmf("Triangle", &shifted, &centre).unwrap();
    assert_eq!(
        (&mesh.points, mesh.triangles().count()),
        (&points, triangles.len())
    );
    let read: Vec<[i64; 3]> = mesh.triangles().map(|t| t.map(|v| v as i64)).collect();
    assert_eq!(read, triangles);
    // And in an .h5 mesh given alone.
    let dir = tempfile::tempdir().unwrap();
    let plane: Vec<[f64; 2]> = centre.iter().map(|p| [p[0], p[1]]).collect();
    let cells: Vec<[i64; 3]> = shifted.chunks(3).map(|t| [t[0], t[1], t[2]]).collect();
    write_mesh(&dir.path().join("mesh.h5"), &plane, &cells);
    let mesh = membrane_contact::mesh::file::read(&dir.path().join("mesh.h5")).unwrap();
    assert_eq!(mesh.points, points);
    let e = read_xdmf("Mixed", &[4, 0, 1, 4, 2, 9, 0], flat).unwrap_err();
    assert!(e.contains("the mixed topology ends within a cell"), "{e}");
    let e = read_xdmf("Mixed", &[4, 0, 1, 4, 5, 0, 1, 2, 3], flat).unwrap_err();
    assert!(
        e.contains("the mixed topology holds a cell of XDMF type 5 (entry 4)"),
        "{e}"
    );
    for z in [[5.0; 5], [0.0, 1.2e-16, 0.0, -1e-16, 0.0], [1e15; 5]] {
        assert_eq!(
            read_xdmf("Mixed", &mixed, &at(z)).unwrap().points,
            points,
            "{z:?}"
        );
    }
    // Far from z = 0 a tilt is still a tilt (the tolerance was relative to |z|).
    let tilted = at([1e15, 1e15 + 100.0, 1e15 + 100.0, 1e15, 1e15 + 50.0]);
    let e = read_xdmf("Mixed", &mixed, &tilted).unwrap_err();
    assert!(e.contains("vertex 1 has z = 1000000000000100"), "{e}");
    let e = read_xdmf("Mixed", &mixed, &at([0.0, 0.5, 0.5, 0.0, 0.25])).unwrap_err();
    assert!(
        e.contains("vertex 1 has z = 0.5, the first z = 0: the mesh must lie in a plane z = constant"),
        "{e}"
    );
}

/// A Gmsh file with a view written into it (its sections repeated) and an HDF5 file of neither
/// layout read alone say what to do (they gave the parser's and HDF5's own words).
#[test]
fn a_gmsh_file_with_a_view_and_a_foreign_h5_say_what_to_do() {
    let case = |path: &str| format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"{path}\"\n");
    let repeated = |d: &Path| {
        let text = std::fs::read_to_string("data/meshes/square.msh").unwrap();
        let entities = &text[text.find("$Entities").unwrap()..text.find("$Nodes").unwrap()];
        std::fs::write(d.join("view.msh"), text.clone() + entities).unwrap();
    };
    contains(
        &fails(&case("view.msh"), repeated, &[], None),
        "view.msh: not a readable MSH 4.1 file: the file holds its sections twice (a view written \
         into it with PostProcessing.SaveMesh = 1?): save the mesh alone",
    );
    let foreign = |d: &Path| {
        let _guard = FILES.lock().unwrap_or_else(|e| e.into_inner());
        let f = hdf5::File::create(d.join("mesh.h5")).unwrap();
        f.new_dataset_builder()
            .with_data(&[0.0, 1.0])
            .create("/data0")
            .unwrap();
    };
    contains(
        &fails(&case("mesh.h5"), foreign, &[], None),
        "mesh.h5: neither a result of this program (/mesh/geometry) nor dolfinx's mesh \
         (/Mesh/mesh/geometry): another layout (meshio's) is read through its .xdmf file",
    );
}

/// A time series (adapt.xdmf) names its meshes' count and the last one's file instead of reading
/// the first step's mesh without a word.
#[test]
fn a_time_series_is_not_one_mesh() {
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"steps.xdmf\"\n"),
        |d| {
            let (p, c) = fan();
            for step in ["a.h5", "b.h5"] {
                write_mesh(&d.join(step), &p, &c);
            }
            let grid = |h5: &str| {
                format!(
                    "<Grid GridType=\"Uniform\"><Topology TopologyType=\"Triangle\"><DataItem Format=\"HDF\">{h5}:/mesh/topology</DataItem></Topology><Geometry GeometryType=\"XY\"><DataItem Format=\"HDF\">{h5}:/mesh/geometry</DataItem></Geometry></Grid>"
                )
            };
            let xdmf = format!(
                "<Xdmf><Domain><Grid GridType=\"Collection\" CollectionType=\"Temporal\">{}{}</Grid></Domain></Xdmf>",
                grid("a.h5"),
                grid("b.h5")
            );
            std::fs::write(d.join("steps.xdmf"), xdmf).unwrap();
        },
        &[],
        None,
    );
    contains(
        &e,
        "steps.xdmf: a time series (or collection) of 2 meshes, not one mesh",
    );
    contains(&e, "e.g. the last: ");
    contains(&e, "b.h5");
}

#[test]
fn zero_area_triangle() {
    let (p, mut c) = fan();
    c[0] = [0, 1, 0];
    contains(
        &mesh_fails(&p, &c),
        "triangle 0 (near (0.3333333333333333, 0)) has zero area to round-off",
    );
}

/// A feature of a polygon too small for double precision at its size, and a size h too coarse
/// for a thin domain, are said as such (they were "triangle 395 has zero area" and "no interior
/// vertex").
#[test]
fn a_polygon_too_fine_or_an_h_too_coarse_is_named() {
    let e = polygon_fails("boundary = [[0, 0], [1, 0], [1, 1], [0.999999999999, 1], [0, 1]]\nh = 0.01\n");
    contains(
        &e,
        "h = 0.01: the mesh could not be generated: the domain has a feature near (0.99999",
    );
    contains(&e, "too small to mesh at its size");
    let e = polygon_fails("boundary = [[0, 0], [1, 0], [1, 0.001], [0, 0.001]]\nh = 0.01\n");
    contains(
        &e,
        "h is too coarse for the domain: its mesh has no interior vertex; use a smaller h",
    );
}

#[test]
fn inverted_triangle() {
    let (mut p, c) = fan();
    p[4] = [1.3, 0.5];
    contains(&mesh_fails(&p, &c), "inverted");
}

#[test]
fn duplicate_vertices() {
    let (mut p, mut c) = fan();
    p.push([0.5, 0.5]);
    c[3] = [3, 0, 5];
    contains(
        &mesh_fails(&p, &c),
        "vertex 4 and vertex 5 have the same coordinates",
    );
}

#[test]
fn hanging_node() {
    let p = [
        [0.0, 0.0],
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [2.0, 0.5],
        [1.0, 0.5],
        [0.5, 0.5],
    ];
    let c = [[0, 1, 6], [1, 2, 6], [2, 3, 6], [3, 0, 6], [1, 4, 5], [5, 4, 2]];
    contains(&mesh_fails(&p, &c), "hanging node");
}

#[test]
fn several_components() {
    let (mut p, mut c) = fan();
    p.extend([[3.0, 0.0], [4.0, 0.0], [4.0, 1.0], [3.0, 1.0], [3.5, 0.5]]);
    c.extend([[5, 6, 9], [6, 7, 9], [7, 8, 9], [8, 5, 9]]);
    contains(&mesh_fails(&p, &c), "2 separate components");
    // Two squares meeting at a corner (vertex 2): named where they meet.
    let (mut p, mut c) = fan();
    p.extend([[2.0, 1.0], [2.0, 2.0], [1.0, 2.0], [1.5, 1.5]]);
    c.extend([[2, 5, 8], [5, 6, 8], [6, 7, 8], [7, 2, 8]]);
    contains(
        &mesh_fails(&p, &c),
        "2 components that share no edge, two of them meeting only at vertex 2;",
    );
}

#[test]
fn no_interior_vertex() {
    let p = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    contains(&mesh_fails(&p, &[[0, 1, 2], [0, 2, 3]]), "no interior vertex");
}

#[test]
fn vertex_index_out_of_range() {
    let (p, mut c) = fan();
    c[1] = [1, 2, 7];
    contains(&mesh_fails(&p, &c), "refers to vertex 7, which does not exist");
}

/// A file where the result's parent directory should be is named (a missing parent is made).
#[test]
fn output_directory_under_a_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("afile"), "x").unwrap();
    let out = dir.path().join("afile").join("out");
    let e = fails(&format!("{GOOD}{SQUARE}"), |_| {}, &[], Some(out));
    contains(&e, "afile is not a directory");
}

#[test]
fn output_not_writable() {
    // /proc refuses new files even to root.
    let e = fails(
        &format!("{GOOD}{SQUARE}"),
        |_| {},
        &[],
        Some(PathBuf::from("/proc/membrane-contact")),
    );
    contains(&e, "/proc/membrane-contact");
}

#[test]
fn two_runs_write_identical_datasets() {
    // The second run is pinned to one core, where v and w are solved one after the other.
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    let bin = env!("CARGO_BIN_EXE_membrane-contact");
    for (name, pin) in [("a", &[][..]), ("b", &["taskset", "-c", "0"][..])] {
        let out = dir.path().join(name);
        let args = [bin, "solve", "--n", "24", "--dual", "-o", out.to_str().unwrap()];
        let command: Vec<&str> = pin.iter().chain(&args).copied().collect();
        let run = run(Command::new(command[0]).args(&command[1..]));
        assert!(run.status.success());
        files.push(hdf5::File::open(out.join("solution.h5")).unwrap());
    }
    let mut compared = 0;
    for group in ["mesh", "dual"] {
        let (ga, gb) = (files[0].group(group).unwrap(), files[1].group(group).unwrap());
        let names = ga.member_names().unwrap();
        assert!(names.len() >= 3);
        for name in names {
            let a = ga.dataset(&name).unwrap().read_raw::<f64>().unwrap();
            let b = gb.dataset(&name).unwrap().read_raw::<f64>().unwrap();
            assert!(
                a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{group}/{name} differs"
            );
            compared += 1;
        }
    }
    assert!(compared >= 12);
}

// Reproductions of issue 10: each a clear error or a correct result.

#[test]
fn output_named_like_a_file_is_refused() {
    let e = fails(
        &format!("{GOOD}{SQUARE}"),
        |_| {},
        &[],
        Some(PathBuf::from("out.xdmf")),
    );
    contains(&e, "a result is a directory");
    // adapt and study too (adapt made a directory out.h5 holding adapt.xdmf).
    for command in ["adapt", "study"] {
        let out = Some(PathBuf::from("out.h5"));
        let e = command_fails(command, &format!("{GOOD}{SQUARE}"), |_| {}, &[], out);
        contains(&e, "out.h5: a result is a directory");
    }
}

#[test]
fn an_input_is_never_an_output() {
    // The case file itself: it exists and is not a result.
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("case.toml");
    std::fs::write(&case, format!("{GOOD}{SQUARE}")).unwrap();
    let e = fails(&format!("{GOOD}{SQUARE}"), |_| {}, &[], Some(case.clone()));
    contains(&e, "is not a result of membrane-contact");
    // A mesh file inside the earlier result the run would replace.
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"out/solution.h5\"\n"),
        |_| {},
        &[],
        None,
    );
    assert!(
        e.contains("an input of this run") || e.contains("not a readable HDF5"),
        "{e}"
    );
}

#[test]
fn a_case_inside_the_result_it_would_replace_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = earlier_result(dir.path());
    let case = out.join("case.toml");
    std::fs::write(&case, format!("{GOOD}{SQUARE}")).unwrap();
    let run = run(Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .arg("solve")
        .arg(&case)
        .arg("-o")
        .arg(&out));
    assert_eq!(run.status.code(), Some(1));
    contains(&String::from_utf8_lossy(&run.stderr), "an input of this run");
    assert!(case.exists() && std::fs::read(out.join("solution.h5")).unwrap() == EARLIER);
}

#[test]
fn data_beyond_double_precision_fail() {
    for data in [
        GOOD.replace("mu1 = 1.0", "mu1 = 1e300"),
        GOOD.replace("\"0.1*x\"", "1e300"),
    ] {
        contains(
            &case_fails(&format!("{data}{SQUARE}")),
            "not resolved in double precision",
        );
    }
}

#[test]
fn a_mesh_covering_its_domain_twice_is_refused() {
    // Sixteen triangles around vertex 0 winding 4π: the second turn at radius 2.
    let mut p = vec![[0.0, 0.0]];
    for k in 0..16 {
        let (r, t) = (
            if k < 8 { 1.0 } else { 2.0 },
            k as f64 * std::f64::consts::FRAC_PI_4,
        );
        p.push([r * t.cos(), r * t.sin()]);
    }
    let c: Vec<[i64; 3]> = (0..16).map(|k| [0, 1 + k, 1 + (k + 1) % 16]).collect();
    contains(
        &mesh_fails(&p, &c),
        "turn 2.000 times around it: the mesh overlaps itself",
    );
}

#[test]
fn crossing_boundaries_are_refused() {
    // A spiral strip of three rings of vertices, turning 2.2π: every vertex turns once, but the
    // end of the strip lies over its start, so its boundary edges cross.
    let (rings, steps) = (3, 14);
    let mut p = Vec::new();
    for k in 0..=steps {
        let t = k as f64 * std::f64::consts::PI / 6.3;
        for j in 0..rings {
            let r = (1.0 + 0.5 * j as f64) * (1.0 + 0.02 * t);
            p.push([r * t.cos(), r * t.sin()]);
        }
    }
    let mut c = Vec::new();
    for k in 0..steps as i64 {
        for j in 0..rings as i64 - 1 {
            let (a, b) = (k * 3 + j, (k + 1) * 3 + j);
            c.extend([[a, b, b + 1], [a, b + 1, a + 1]]);
        }
    }
    contains(
        &mesh_fails(&p, &c),
        "meet away from a shared vertex: the mesh overlaps itself",
    );
}

#[test]
fn g_is_checked_where_it_enters_the_problem() {
    // cos(16πx) ≥ 0 at the boundary vertices of 8 × 8 cells, not of 12 × 12: the message says that
    // the vertex values of g_h are what is checked.
    let case = format!("{}{SQUARE}", GOOD.replace("\"0.1*x\"", "\"cos(16*pi*x)\""));
    let e = fails(&case, |_| {}, &["--n", "12"], None);
    contains(&e, "at the boundary vertex");
    contains(&e, "g_h, the interpolant of g");
    // On the mesh refined once, whose vertices the case's mesh does not have, the message says
    // so (it named a vertex the user's mesh has not).
    let e = fails(&case, |_| {}, &["--refine", "1"], None);
    contains(&e, "case.toml (on the mesh refined once): ");
    contains(&e, "at the boundary vertex (0.08333333333333333, 0)");
}

#[test]
fn fractional_vertex_indices_are_refused() {
    // 1e300 is shown as such, not in 301 digits.
    for (bad, shown) in [(4.7, "4.7"), (1e300, "1e300")] {
        let dir = tempfile::tempdir().unwrap();
        let (p, c) = fan();
        let _guard = FILES.lock().unwrap_or_else(|e| e.into_inner());
        let f = hdf5::File::create(dir.path().join("mesh.h5")).unwrap();
        let pa = ndarray::Array2::from_shape_fn((p.len(), 2), |(i, k)| p[i][k]);
        let mut ca = ndarray::Array2::from_shape_fn((c.len(), 3), |(i, k)| c[i][k] as f64);
        ca[[0, 2]] = bad;
        f.new_dataset_builder()
            .with_data(&pa)
            .create("/mesh/geometry")
            .unwrap();
        f.new_dataset_builder()
            .with_data(&ca)
            .create("/mesh/topology")
            .unwrap();
        drop(f);
        drop(_guard);
        let bytes = std::fs::read(dir.path().join("mesh.h5")).unwrap();
        let e = fails(
            &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.h5\"\n"),
            move |d| std::fs::write(d.join("mesh.h5"), &bytes).unwrap(),
            &[],
            None,
        );
        contains(&e, &format!("cell 0 has the vertex index {shown}:"));
    }
}

#[test]
fn xdmf_dimensions_must_match_the_data() {
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.xdmf\"\n"),
        |d| {
            let (p, c) = fan();
            write_mesh(&d.join("mesh.h5"), &p, &c);
            let xdmf = "<Xdmf><Domain><Grid><Topology TopologyType=\"Triangle\"><DataItem Dimensions=\"4 3\" Format=\"HDF\">mesh.h5:/mesh/topology</DataItem></Topology><Geometry GeometryType=\"XY\"><DataItem Dimensions=\"9 2\" Format=\"HDF\">mesh.h5:/mesh/geometry</DataItem></Geometry></Grid></Domain></Xdmf>";
            std::fs::write(d.join("mesh.xdmf"), xdmf).unwrap();
        },
        &[],
        None,
    );
    contains(&e, "declares Dimensions [9, 2], but the dataset has 5 rows");
}

#[test]
fn unknown_mesh_file_extension_names_the_accepted_ones() {
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.stl\"\n"),
        |d| std::fs::write(d.join("mesh.stl"), "solid").unwrap(),
        &[],
        None,
    );
    contains(&e, "unknown mesh file extension 'stl'");
    contains(&e, ".xdmf");
    contains(&e, ".msh (Gmsh, format 4.1)");
}

#[test]
fn cells_per_side_do_not_apply_to_a_mesh_file() {
    let (p, c) = fan();
    let e = fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.h5\"\n"),
        move |d| write_mesh(&d.join("mesh.h5"), &p, &c),
        &["--n", "8"],
        None,
    );
    contains(&e, "--n 8:");
    contains(&e, "not to kind = \"file\": refine it instead (--refine K");
}

#[test]
fn a_nan_exact_solution_is_refused() {
    let exact = "[exact]\nu1 = \"sqrt(x - 0.5)\"\nu2 = 0\nlambda = 0\n";
    contains(
        &case_fails(&format!("{GOOD}{exact}{SQUARE}")),
        "key 'exact.u1' is NaN at the vertex",
    );
}

#[test]
fn extreme_mesh_keys_are_named() {
    let e = case_fails(&format!(
        "{GOOD}[mesh]\nkind = \"rectangle\"\nn = [6, 6]\ncorners = [[0.0, 0.0], [1e-300, 1e-300]]\n"
    ));
    contains(&e, "[mesh] corners = ");
    let e = case_fails(&format!(
        "{GOOD}[mesh]\nkind = \"lshape\"\nn = 8\ngrading = 2000\n"
    ));
    contains(&e, "grading = 2000");
}

/// ‖λ − λh‖_H⁻¹ is an error against the exact λ: asked for on a case without one, the run fails
/// (it was silently left out).
#[test]
fn hminus1_without_an_exact_solution_is_refused() {
    let e = fails(&format!("{GOOD}{SQUARE}"), |_| {}, &["--hminus1"], None);
    contains(
        &e,
        "--hminus1 is the error ‖λ − λh‖_H⁻¹ against the exact λ, and the case has no [exact] table",
    );
}

/// The L-shape's re-entrant corner is a vertex only for an even n: an odd one, in the file or by
/// `--n`, is refused (it was solved silently on n + 1 cells per side).
#[test]
fn an_odd_l_shape_is_refused() {
    let e = case_fails(&format!("{GOOD}[mesh]\nkind = \"lshape\"\nn = 15\n"));
    contains(
        &e,
        "key 'mesh.n' = 15: the L-shape takes an even number of cells per side",
    );
    let lshape = format!("{GOOD}[mesh]\nkind = \"lshape\"\nn = 16\n");
    let e = fails(&lshape, |_| {}, &["--n", "7"], None);
    contains(&e, "7 cells per side: the L-shape takes an even number");
}

#[test]
fn oversized_case_files_are_refused() {
    let title = "x".repeat(2 << 20);
    contains(
        &case_fails(&format!("title = \"{title}\"\n{GOOD}{SQUARE}")),
        "at most 1048576 are read",
    );
}

/// A polygon case with the given `[mesh]` keys (after kind = "polygon").
fn polygon_fails(keys: &str) -> String {
    case_fails(&format!("{GOOD}[mesh]\nkind = \"polygon\"\n{keys}"))
}

/// A needle (a vertex 1e-9 off the opposite side) meshes into a vertex on another triangle's edge
/// in double precision: said as a feature of the polygon, not as "a hanging node" of a mesh the
/// user never gave.
#[test]
fn a_needle_is_a_feature_too_small() {
    let e = polygon_fails("boundary = [[0, 0], [1, 0], [0.5, 1e-9]]\nh = 0.01\n");
    contains(&e, "the domain has a feature near (");
    contains(
        &e,
        "remove the polygon's vertex nearest it, (0, 0), or widen the feature",
    );
    contains(
        &e,
        "too small to mesh at its size (a vertex there lies on another triangle's edge",
    );
}

/// A vertex repeated within a ring is named (a ring closed by its first vertex is not: own_domains),
/// and a closed ring of too few vertices says it was closed.
#[test]
fn a_repeated_vertex_is_named() {
    contains(
        &polygon_fails("boundary = [[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]]\nh = 0.25\n"),
        "the vertex [1.0, 0.0] is repeated",
    );
    contains(
        &polygon_fails("boundary = [[0, 0], [1, 0], [0, 0]]\nh = 0.25\n"),
        "key 'mesh.boundary' has 2 vertices besides its last, which repeats the first to close it",
    );
}

#[test]
fn bad_polygons() {
    let e = polygon_fails("boundary = [[0, 0], [1, 1], [1, 0], [0, 1]]\nh = 0.1\n");
    contains(&e, "key 'mesh.boundary': the edges");
    contains(&e, "must not intersect or touch itself");
    contains(
        &polygon_fails("boundary = [[0, 0], [1, 0]]\nh = 0.1\n"),
        "key 'mesh.boundary' has 2 vertices: a polygon needs at least 3",
    );
    let square = "boundary = [[0, 0], [1, 0], [1, 1], [0, 1]]\nh = 0.1\n";
    contains(
        &polygon_fails(&format!("{square}holes = [[[2, 2], [3, 2], [2, 3]]]\n")),
        "key 'mesh.holes' (hole 1) lies outside key 'mesh.boundary'",
    );
    contains(
        &polygon_fails(&format!("{square}holes = [[[0, 0.5], [0.5, 0.4], [0.5, 0.6]]]\n")),
        "key 'mesh.holes' (hole 1) touches or crosses key 'mesh.boundary'",
    );
    contains(
        &polygon_fails("boundary = [[0, 0], [1, 0], [1, 1]]\nh = 0\n"),
        "key 'mesh.h' = 0: need a positive mesh size",
    );
    contains(
        &polygon_fails("boundary = [[0, 0], [1, 0], [1, 1]]\nh = -1\n"),
        "key 'mesh.h' = -1",
    );
    contains(
        &polygon_fails(&format!("{square}radius = 1\n")),
        "key 'mesh.radius' does not apply to kind = \"polygon\"",
    );
}

#[test]
fn bad_disks() {
    let disk = |keys: &str| case_fails(&format!("{GOOD}[mesh]\nkind = \"disk\"\n{keys}"));
    contains(
        &disk("radius = 0\nh = 0.1\n"),
        "key 'mesh.radius' = 0: need a positive radius",
    );
    contains(&disk("radius = -2\nh = 0.1\n"), "key 'mesh.radius' = -2");
    contains(&disk("radius = 1\nh = 0\n"), "key 'mesh.h' = 0");
    contains(
        &disk("radius = 1\ninner_radius = 1.5\nh = 0.1\n"),
        "key 'mesh.inner_radius' = 1.5: need 0 < inner_radius < radius = 1",
    );
    // Estimated from the area before meshing: nothing is built.
    let e = disk("radius = 1\nh = 1e-6\n");
    contains(&e, "[mesh] kind = \"disk\", h = 1e-6");
    contains(&e, "use a coarser mesh");
    let e = disk("radius = 1\nh = 0.1\nrefine = 12\n");
    contains(&e, "h = 0.1, refine = 12:");
    contains(&e, "use a coarser mesh");
}

#[test]
fn options_that_do_not_apply_to_the_mesh() {
    let disk = format!("{GOOD}[mesh]\nkind = \"disk\"\nradius = 1\nh = 0.2\n");
    let e = fails(&disk, |_| {}, &["--n", "8"], None);
    contains(&e, "--n 8:");
    contains(&e, "not to kind = \"disk\": refine it instead (--refine K");
}

/// A case reading `mesh.msh` with the given text.
fn msh_fails(text: &'static str) -> String {
    fails(
        &format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"mesh.msh\"\n"),
        move |dir| std::fs::write(dir.join("mesh.msh"), text).unwrap(),
        &[],
        None,
    )
}

/// Four nodes of the unit square and one element block (`{BLOCK}` replaced by the caller).
const MSH_NODES: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n\
                         0 0 0\n1 0 0\n1 1 0\n0 1 0\n$EndNodes\n";

#[test]
fn gmsh_files_without_triangles_or_of_old_versions() {
    const QUADS: &str = concat!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n",
        "0 0 0\n1 0 0\n1 1 0\n0 1 0\n$EndNodes\n",
        "$Elements\n1 1 1 1\n2 1 3 1\n1 1 2 3 4\n$EndElements\n"
    );
    const LINES: &str = concat!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n",
        "0 0 0\n1 0 0\n1 1 0\n0 1 0\n$EndNodes\n",
        "$Elements\n1 2 1 2\n1 1 1 2\n1 1 2\n2 3 4\n$EndElements\n"
    );
    assert!(QUADS.starts_with(MSH_NODES) && LINES.starts_with(MSH_NODES));
    let e = msh_fails(QUADS);
    contains(
        &e,
        "mesh.msh: quadrilateral elements (Qua4, surface 1): the mesh must be made of triangles",
    );
    contains(&msh_fails(LINES), "mesh.msh: the file has no triangles");
    contains(
        &msh_fails("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"),
        "mesh.msh: MSH format version 2.2 is not read: only version 4.1",
    );
    contains(
        &msh_fails("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2"),
        "mesh.msh: not a readable MSH 4.1 file: node section",
    );
    // Gmsh's parametric nodes (u, v after x, y, z), which mshio does not read: said how to save.
    contains(
        &msh_fails(concat!(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 1 4\n1\n2\n3\n4\n",
            "0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n$EndNodes\n"
        )),
        "parametric nodes (Mesh.SaveParametric = 1) are not read: save the mesh without them",
    );
    // Cut before its last line: the parser gave no reason ("not a readable MSH 4.1 file: ").
    let cut = QUADS.strip_suffix("$EndElements\n").unwrap();
    contains(
        &msh_fails(cut),
        "not a readable MSH 4.1 file: the file ends inside $Elements, before $EndElements (cut short?)",
    );
    contains(&msh_fails("solid cube\n"), "mesh.msh: not a Gmsh MSH file");
}

/// A Gmsh file's mesh errors name its node and element tags, not the mesh's numbers from 0.
#[test]
fn gmsh_mesh_errors_name_node_and_element_tags() {
    // The fan of the unit square about its centre (nodes 11–15), with a sixth node 16 on the
    // centre that element 24 uses in place of 15.
    const DUPLICATE: &str = concat!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 6 11 16\n2 1 0 6\n11\n12\n13\n14\n15\n16\n",
        "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 0\n0.5 0.5 0\n$EndNodes\n",
        "$Elements\n1 4 21 24\n2 1 2 4\n21 11 12 15\n22 12 13 15\n23 13 14 15\n24 14 11 16\n$EndElements\n"
    );
    contains(
        &msh_fails(DUPLICATE),
        "mesh.msh: node 15 and node 16 have the same coordinates",
    );
    const REPEATED: &str = concat!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 5 11 15\n2 1 0 5\n11\n12\n13\n14\n15\n",
        "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 0\n$EndNodes\n",
        "$Elements\n1 4 21 24\n2 1 2 4\n21 11 12 15\n22 12 13 12\n23 13 14 15\n24 14 11 15\n$EndElements\n"
    );
    contains(&msh_fails(REPEATED), "mesh.msh: triangle element 22 (near");
    // Coordinates about 1e300: the area overflows, and the point is shown in scientific notation.
    const HUGE: &str = concat!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 5 11 15\n2 1 0 5\n11\n12\n13\n14\n15\n",
        "0 0 0\n1e300 0 0\n1e300 1e300 0\n0 1e300 0\n5e299 5e299 0\n$EndNodes\n",
        "$Elements\n1 4 21 24\n2 1 2 4\n21 11 12 15\n22 12 13 15\n23 13 14 15\n24 14 11 15\n$EndElements\n"
    );
    let e = msh_fails(HUGE);
    contains(
        &e,
        "mesh.msh: triangle element 21 (near (5e299, 1.6666666666666668e299)) has an area that overflows",
    );
    assert!(e.len() < 250, "{e}");
}

#[test]
fn a_refined_file_mesh_too_large_for_memory() {
    // 98 vertices refined 14 times: about 2.6e10 vertices, refused after reading the file.
    let case = format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"square.msh\"\nrefine = 14\n");
    let e = fails(
        &case,
        |d| {
            std::fs::copy("data/meshes/square.msh", d.join("square.msh"))
                .map(|_| ())
                .unwrap()
        },
        &[],
        None,
    );
    contains(&e, "square.msh, refine = 14: 26306674688 vertices need about");
    contains(&e, "use a coarser mesh");
    // 30 refinements: a count past any integer is said so, not printed as a wrapped number.
    // 2³² refinements: too many vertices, before their areas are out of range.
    for refine in [30u64, 1 << 32] {
        let e =
            case_fails(&format!("{GOOD}{SQUARE}").replace("[mesh]", &format!("[mesh]\nrefine = {refine}")));
        contains(
            &e,
            "the mesh would have more than 1.8e19 vertices: use a coarser mesh",
        );
    }
}

#[test]
fn a_nan_exact_gradient_is_refused() {
    // Gradients are checked through the norms they give (they may be singular at a vertex).
    let exact = "[exact]\nu1 = 0\nu2 = 0\nlambda = 0\ngrad_u1 = [\"sqrt(x - 0.5)\", \"0\"]\n";
    contains(
        &case_fails(&format!("{GOOD}{exact}{SQUARE}")),
        "the error norm of exact.grad_u1 is not finite",
    );
}

/// Data whose estimate overflows double precision (e^700 squared) are refused, not reported as η = ∞.
#[test]
fn an_estimate_beyond_double_precision_is_refused() {
    let case = format!("{}{SQUARE}", GOOD.replace("f1 = -5", "f1 = \"-exp(700*x)\""));
    let e = fails(&case, |_| {}, &["--estimate"], None);
    contains(&e, "the error estimate is not finite (η = inf, ");
}

/// An estimate whose squares overflow into inf − inf = NaN says NaN: it was reported as η = 0
/// (`f64::max(NaN, 0)`) beside a bound of λ that was NaN.
#[test]
fn an_estimate_that_overflows_to_nan_is_not_reported_as_zero() {
    let e = fails(
        "mu1 = 1.0\nmu2 = 1.0\nf1 = -10\nf2 = 5\ng = 0.01\n[mesh]\nkind = \"rectangle\"\ncorners = [[0, 0], [1e150, 1e150]]\nn = 8\n",
        |_| {},
        &["--estimate"],
        None,
    );
    contains(&e, "the error estimate is not finite (η = NaN, ");
}

/// Cells per side that are neither a number nor two say what is expected, not serde's words.
#[test]
fn cells_per_side_of_another_shape() {
    for n in ["[8, 8, 8]", "-4", "\"8\""] {
        let case = format!("{GOOD}[mesh]\nkind = \"rectangle\"\nn = {n}\n");
        let e = case_fails(&case);
        contains(
            &e,
            "expected the cells per side: a whole number, n = 64, or two, n = [64, 32]",
        );
        assert!(!e.contains("untagged"), "{e}");
    }
}

/// An exact solution that breaks the problem's conditions is refused at the first vertex where
/// it does: λ < 0, u1 < u2 (the membranes crossing), u below the obstacle.
#[test]
fn an_exact_solution_against_the_conditions_is_refused() {
    let exact = |u1: &str, u2: &str, lambda: &str| {
        format!("{GOOD}[exact]\nu1 = \"{u1}\"\nu2 = \"{u2}\"\nlambda = \"{lambda}\"\n{SQUARE}")
    };
    let e = case_fails(&exact("0.1*x", "0", "-1"));
    contains(&e, "key 'exact.lambda' is -1 at the vertex");
    contains(&e, "the contact pressure λ must be ≥ 0");
    let e = case_fails(&exact("0.1*x", "0.1*x + 0.5", "0"));
    contains(&e, "the exact u1 − u2 is -5e-1 at the vertex");
    contains(&e, "the membranes must not cross, u1 ≥ u2");
    let e = case_fails(&format!("{OBSTACLE}[exact]\nu = \"-1\"\nlambda = 0\n{SQUARE}"));
    contains(&e, "u must lie above the obstacle ψ");
}

/// A gradient has two components: more (a third was dropped, "((( bogus" too) or fewer are
/// refused, naming the key.
#[test]
fn an_exact_gradient_of_other_than_two_entries_is_refused() {
    for (grad, n) in [("[\"0\", \"0\", \"((( bogus\"]", 3), ("[\"0\"]", 1)] {
        let exact = format!("[exact]\nu1 = 0\nu2 = 0\nlambda = 0\ngrad_u1 = {grad}\n");
        contains(
            &case_fails(&format!("{GOOD}{exact}{SQUARE}")),
            &format!("key 'exact.grad_u1' has {n} entries: a gradient has two"),
        );
    }
    // An entry that does not parse is named with its index.
    let exact = "[exact]\nu1 = 0\nu2 = 0\nlambda = 0\ngrad_u1 = [\"0\", \"1 +\"]\n";
    contains(
        &case_fails(&format!("{GOOD}{exact}{SQUARE}")),
        "key 'exact.grad_u1[1]' = \"1 +\"",
    );
}

/// `adapt` with settings it cannot use, from the case file or the command line.
#[test]
fn adapt_settings_out_of_range() {
    let adapt = |table: &str, extra: &[&str]| {
        command_fails("adapt", &format!("{GOOD}{SQUARE}{table}"), |_| {}, extra, None)
    };
    contains(
        &adapt("[adapt]\ntheta = 0.0\n", &[]),
        "key 'adapt.theta' = 0: θ must lie in (0, 1]",
    );
    contains(
        &adapt("[adapt]\ntheta = 1.5\n", &[]),
        "key 'adapt.theta' = 1.5: θ must lie in (0, 1]",
    );
    contains(
        &adapt("", &["--theta=-0.2"]),
        "--theta = -0.2: θ must lie in (0, 1]",
    );
    // A largest mesh that could not be solved and estimated in the memory there is: refused
    // before the first solve.
    contains(
        &adapt("", &["--max-vertices=1000000000000"]),
        "adapt's vertex budget of 1000000000000 ([adapt] max_vertices or --max-vertices): \
         1000000000000 vertices need about",
    );
    contains(
        &adapt("[adapt]\ntarget = -1.0\n", &[]),
        "key 'adapt.target' = -1: the target estimate must be a positive number",
    );
    contains(
        &adapt("", &["--target", "0"]),
        "--target = 0: the target estimate must be a positive number",
    );
    contains(
        &adapt("", &["--max-vertices", "0"]),
        "--max-vertices must be positive",
    );
    contains(
        &adapt("[adapt]\nsteps = 0\n", &[]),
        "key 'adapt.steps' must be at least 1",
    );
    contains(
        &adapt("[adapt]\ntheta = 0.5\nbulk = 1\n", &[]),
        "unknown field `bulk`",
    );
}

// Reproductions of issue 24.

/// Runs `solve CASE -o out` in a fresh directory prepared by `setup` (`case` relative to it, or a
/// path such as /dev/zero), with `stdin` piped in and at most 4 GiB of address space, so that a
/// read without bound fails instead of filling the machine. Checks that the run is refused
/// within seconds, with one line of error and exit status 1, leaving nothing behind; returns
/// stderr.
fn refused_quickly(case: &str, setup: impl Fn(&Path), stdin: &[u8]) -> String {
    use std::io::Write;
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    let before = listing(dir.path());
    let mut command = Command::new(env!("CARGO_BIN_EXE_membrane-contact"));
    command
        .arg("solve")
        .arg("--quiet")
        .arg(dir.path().join(case))
        .arg("-o")
        .arg(dir.path().join("out"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    // SAFETY: setrlimit is async-signal-safe.
    unsafe {
        command.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: 4 << 30,
                rlim_max: 4 << 30,
            };
            match libc::setrlimit(libc::RLIMIT_AS, &limit) {
                0 => Ok(()),
                _ => Err(std::io::Error::last_os_error()),
            }
        });
    }
    let start = std::time::Instant::now();
    let mut child = {
        let _guard = FILES.lock().unwrap_or_else(|e| e.into_inner());
        command.spawn().unwrap()
    };
    let (mut input, stdin) = (child.stdin.take().unwrap(), stdin.to_vec());
    // The run may stop reading at any point: a broken pipe is expected.
    let writer = std::thread::spawn(move || drop(input.write_all(&stdin)));
    let run = child.wait_with_output().unwrap();
    writer.join().unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&run.stderr).to_string();
    assert_eq!(run.status.code(), Some(1), "exit status; stderr: {stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(seconds < 30.0, "refused after {seconds:.1} s: {stderr}");
    assert_eq!(listing(dir.path()), before, "files were left behind or removed");
    stderr
}

#[test]
fn endless_case_files_are_refused() {
    // A valid case followed by 2 MB of comments, through a pipe (whose size says nothing).
    let mut text = format!("{GOOD}{SQUARE}");
    while text.len() < 2_000_000 {
        text.push_str("# a comment line, of which there are far too many in this case file\n");
    }
    contains(
        &refused_quickly("/dev/stdin", |_| {}, text.as_bytes()),
        "/dev/stdin: the case file has more than 1048576 bytes; at most 1048576 are read",
    );
    // A device without end.
    contains(
        &refused_quickly("/dev/zero", |_| {}, b""),
        "/dev/zero: the case file has more than 1048576 bytes; at most 1048576 are read",
    );
}

#[test]
fn endless_mesh_files_are_refused() {
    // The mesh file is /dev/zero under the name of each kind of mesh file.
    for (name, error) in [
        ("zero.msh", "zero.msh: not a Gmsh MSH file"),
        (
            "zero.xdmf",
            "zero.xdmf: the file has more than 67108864 bytes; at most 67108864 are read",
        ),
        ("zero.h5", "zero.h5: not a readable HDF5 file"),
    ] {
        let setup = |dir: &Path| {
            std::os::unix::fs::symlink("/dev/zero", dir.join(name)).unwrap();
            let case = format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"{name}\"\n");
            std::fs::write(dir.join("case.toml"), case).unwrap();
        };
        contains(&refused_quickly("case.toml", setup, b""), error);
    }
}

/// Outputs the run could not put in place, refused before it as `-o .` is: the rename into
/// "out/." or "new/." or to a name of 256 bytes failed after the whole solve (EBUSY, ENOENT,
/// ENAMETOOLONG), and "../out" run from inside out replaced the current directory under the user.
#[test]
fn an_output_the_run_could_not_put_in_place_is_refused_before_it() {
    let long = "n".repeat(256);
    for (cwd, out, error) in [
        ("", "out/.", "out/.: not a directory name"),
        ("", "new/.", "new/.: not a directory name"),
        ("", "out/..", "out/..: not a directory name"),
        ("", "out/.//", "out/.//: not a directory name"),
        ("", &long[..], "a name of 256 bytes: at most 255"),
        ("out", "../out", "the current directory is inside it"),
    ] {
        let dir = Mutex::new(PathBuf::new());
        let setup = |d: &Path| *dir.lock().unwrap() = d.join(cwd);
        let inside = |cmd: &mut Command| {
            cmd.current_dir(&*dir.lock().unwrap());
        };
        let case = format!("{GOOD}{SQUARE}");
        let e = limited_command_fails("solve", &case, setup, &[], Some(PathBuf::from(out)), inside);
        contains(&e, error);
    }
}

/// A process limited to 1.5 GB of address space (`ulimit -v`, as a batch job or a shell may set)
/// is refused a mesh of 4.2 M vertices by the memory guard, which read only the machine's free
/// memory: the run aborted on an allocation, with no error line.
#[test]
fn the_memory_guard_knows_the_process_limit() {
    use std::os::unix::process::CommandExt;
    let limit = |cmd: &mut Command| {
        // SAFETY: setrlimit is async-signal-safe.
        unsafe {
            cmd.pre_exec(|| {
                let limit = libc::rlimit {
                    rlim_cur: 1_500_000_000,
                    rlim_max: 1_500_000_000,
                };
                match libc::setrlimit(libc::RLIMIT_AS, &limit) {
                    0 => Ok(()),
                    _ => Err(std::io::Error::last_os_error()),
                }
            });
        }
    };
    let case = format!("{GOOD}[mesh]\nkind = \"rectangle\"\nn = 2048\n");
    let e = limited_command_fails("solve", &case, |_| {}, &[], None, limit);
    contains(&e, "4198401 vertices need about");
    contains(&e, "GB are available (ulimit -v): use a coarser mesh");
}

/// Runs the good case with every file it writes limited to `bytes` (RLIMIT_FSIZE; SIGXFSZ as a
/// shell leaves it, which ended the process with its temporary left behind until the program
/// ignored it): a write beyond the limit fails with EFBIG, as one on a full disk fails with
/// ENOSPC. Checks the failure as [`fails`] does (one line, nothing left, the earlier result
/// untouched).
fn fails_writing_beyond(bytes: u64) -> String {
    use std::os::unix::process::CommandExt;
    let limit = move |cmd: &mut Command| {
        // SAFETY: setrlimit and signal are async-signal-safe.
        unsafe {
            cmd.pre_exec(move || {
                let limit = libc::rlimit {
                    rlim_cur: bytes,
                    rlim_max: bytes,
                };
                libc::signal(libc::SIGXFSZ, libc::SIG_DFL);
                match libc::setrlimit(libc::RLIMIT_FSIZE, &limit) {
                    0 => Ok(()),
                    _ => Err(std::io::Error::last_os_error()),
                }
            });
        }
    };
    // With S_h, so that the file has many datasets to fail at.
    limited_command_fails(
        "solve",
        &format!("{GOOD}{SQUARE}"),
        |_| {},
        &["--dual"],
        None,
        limit,
    )
}

#[test]
fn a_failed_write_leaves_no_temporary() {
    // Not even the marker of the temporary directory can be written.
    contains(&fails_writing_beyond(0), "cannot write: File too large");
}

#[test]
fn hdf5_failures_are_one_line() {
    // HDF5's text for a failed read or write holds a ctime stamp and its line break.
    let case = |path: &str| format!("{GOOD}[mesh]\nkind = \"file\"\npath = \"{path}\"\n");
    let directory = |d: &Path| std::fs::create_dir(d.join("mesh.h5")).unwrap();
    let e = fails(&case("mesh.h5"), directory, &[], None);
    contains(
        &e,
        "mesh.h5: not a readable HDF5 file (H5Fopen(): unable to open file: ",
    );
    contains(&e, "Is a directory); the mesh files read are");
    // The heavy data of an XDMF mesh are a directory.
    let xdmf = |d: &Path| {
        directory(d);
        let xdmf = "<Xdmf><Domain><Grid><Topology TopologyType=\"Triangle\"><DataItem Format=\"HDF\">mesh.h5:/mesh/topology</DataItem></Topology><Geometry GeometryType=\"XY\"><DataItem Format=\"HDF\">mesh.h5:/mesh/geometry</DataItem></Geometry></Grid></Domain></Xdmf>";
        std::fs::write(d.join("mesh.xdmf"), xdmf).unwrap();
    };
    contains(
        &fails(&case("mesh.xdmf"), xdmf, &[], None),
        "mesh.h5: not a readable HDF5 file",
    );
    // The disk fills at stages of writing solution.h5 (about 33 kB for this case with S_h): creating the
    // file, its datasets, closing it.
    for bytes in [26, 100, 1000, 4096, 16384, 30000] {
        let e = fails_writing_beyond(bytes);
        contains(&e, "solution.h5: cannot write HDF5: ");
        contains(&e, "File too large");
    }
}

#[test]
fn numerical_failures_name_the_case_file() {
    // Each message starts with the case file, as those about its keys do.
    let named = |e: &str, message: &str| {
        let first = e.strip_prefix("error: ").and_then(|e| e.split(": ").next());
        assert!(first.is_some_and(|f| f.ends_with("/case.toml")), "{e}");
        contains(e, &format!("/case.toml: {message}"));
    };
    // A check of the solution: λ_h below the round-off of (4.5).
    let e = case_fails(&format!("{}{SQUARE}", GOOD.replace("mu1 = 1.0", "mu1 = 1e300")));
    named(&e, "λ_h is not resolved in double precision");
    contains(&e, "(the data span too many orders of magnitude: rescale them)");
    // An obstacle a million times farther below than the membrane's deflection.
    let far = "problem = \"obstacle\"\nmu = 1.0\nf = 1e-3\npsi = -1e6\ng = 0\n";
    let e = case_fails(&format!("{far}{SQUARE}"));
    named(&e, "λ_h is not resolved in double precision");
    contains(
        &e,
        "is computed from terms up to 3.0e6, its gap to the other membrane or the obstacle",
    );
    // The solver: the active-set method's cap.
    let text =
        format!("mu1 = 1.0\nmu2 = 1.0\nf1 = -20\nf2 = 20\ng = 0.01\n{SQUARE}[solver]\nmax_iterations = 1\n");
    let e = fails(&text, |_| {}, &["--cold"], None);
    named(&e, "the active-set method did not converge in 1 iterations");
}

/// A case on a copy of the shipped two-region mesh (surfaces "loaded", "free"; curves "clamped",
/// "rim") with `f1` and `g` as given.
fn two_regions_fails(f1: &str, g: &str) -> String {
    let text = format!(
        "mu1 = 1.0\nmu2 = 1.0\nf1 = {f1}\nf2 = 5\ng = {g}\n[mesh]\nkind = \"file\"\npath = \"two.msh\"\n"
    );
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/data/meshes/two_regions.msh");
    fails(
        &text,
        move |dir| {
            std::fs::copy(mesh, dir.join("two.msh")).unwrap();
        },
        &[],
        None,
    )
}

/// A Gmsh file partitioned into 3 (`gmsh.model.mesh.partition(3)`, Gmsh 4.15; a square whose
/// surface and boundary are the groups "steel"): its groups are on the partitions' entities,
/// which are not read. A table says so (it was told that no element carries "steel"); plain data
/// solve on it.
#[test]
fn a_partitioned_gmsh_file_says_why_its_groups_take_no_data() {
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/partitioned.msh");
    let case = |f1: &str| {
        format!("mu1 = 1.0\nmu2 = 1.0\nf1 = {f1}\nf2 = 5\ng = 0\n[mesh]\nkind = \"file\"\npath = \"p.msh\"\n")
    };
    let e = fails(
        &case("{ steel = -10 }"),
        move |dir| {
            std::fs::copy(mesh, dir.join("p.msh")).unwrap();
        },
        &[],
        None,
    );
    contains(&e, "key 'f1': ");
    contains(
        &e,
        "p.msh: the file is partitioned (gmsh.model.mesh.partition): its physical groups",
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(mesh, dir.path().join("p.msh")).unwrap();
    std::fs::write(dir.path().join("case.toml"), case("-10")).unwrap();
    let solved = run(Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args(["solve", "--quiet"])
        .arg(dir.path().join("case.toml"))
        .arg("-o")
        .arg(dir.path().join("out")));
    assert!(
        solved.status.success(),
        "{}",
        String::from_utf8_lossy(&solved.stderr)
    );
}

#[test]
fn tables_per_group_name_the_group_that_does_not_fit() {
    let good_g = "{ clamped = 0.05, rim = \"0.05 + y*(1 - y)\" }";
    let e = two_regions_fails("{ lodaed = -20, free = 0 }", good_g);
    contains(&e, "key 'f1': 'lodaed' is not a physical surface of ");
    contains(&e, "two.msh (its physical surfaces: 'loaded', 'free')");
    let e = two_regions_fails("{ loaded = -20 }", good_g);
    contains(
        &e,
        "key 'f1': the table has no entry for the physical surface 'free' of ",
    );
    let e = two_regions_fails("{ loaded = -20, free = 0 }", "{ clamped = 0.05 }");
    contains(
        &e,
        "key 'g': the table has no entry for the physical curve 'rim' of ",
    );
    let e = two_regions_fails("{ loaded = -20, free = 0 }", "{ clamped = 0.05, rimm = 0 }");
    contains(&e, "key 'g': 'rimm' is not a physical curve of ");
    // The rim meets the clamped sides at (2, 0) and (2, 1): g must agree there.
    let e = two_regions_fails("{ loaded = -20, free = 0 }", "{ clamped = 0.05, rim = 0.1 }");
    contains(
        &e,
        "key 'g': the groups 'clamped' and 'rim' meet at the vertex (2, 0) with g = 0.05 and 0.1",
    );
    // A table needs a mesh with groups: not the built-in square.
    let e = case_fails(&format!(
        "{}{SQUARE}",
        GOOD.replace("f1 = -5", "f1 = { loaded = -5 }")
    ));
    contains(
        &e,
        "key 'f1': a table per physical group needs a mesh with physical groups (a Gmsh .msh file",
    );
    // Only the data may be tables.
    let e = case_fails(&format!(
        "{GOOD}[exact]\nu1 = {{ a = 1 }}\nu2 = 0\nlambda = 0\n{SQUARE}"
    ));
    contains(&e, "key 'exact.u1' is a table");
    let e = case_fails(&format!(
        "{}{SQUARE}",
        GOOD.replace("f1 = -5", "f1 = { loaded = [1] }")
    ));
    contains(&e, "key 'f1.loaded' = [1]: need an expression");
}
