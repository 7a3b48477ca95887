//! `membrane_contact._core`: the Rust side of the Python package `membrane_contact`. It runs the
//! library's own solve, study and adaptive loop (no second solver) on a case given as a path or
//! as TOML text, optionally on a mesh given as arrays, and hands out each result's fields and
//! attributes, the very ones the command line writes ([`run::Run::parts`]). The Python side
//! (`membrane_contact/__init__.py`) turns paths, dicts, meshio and dolfinx meshes into these
//! calls.
//!
//! Every computation runs on a thread of its own with the GIL released, while the calling thread
//! checks for Ctrl-C every [`POLL`]: on KeyboardInterrupt the run is told to stop
//! ([`progress::cancel`]), is waited for, and the KeyboardInterrupt is raised.

// pyo3 0.22's #[pyfunction] and #[pymethods] expand each `PyResult` return into a conversion to
// the same error type, which clippy reports at the signature.
#![allow(clippy::useless_conversion)]

use membrane_contact::adapt;
use membrane_contact::atomic;
use membrane_contact::case::{Case, CaseError, Levels};
use membrane_contact::contact::{LinearSolver, SolveError, Start};
use membrane_contact::mesh::{DualMesh, Edges, Mesh};
use membrane_contact::progress;
use membrane_contact::result::{hdf5_error, Attr, Attribute, Field, Place, Values, SOLUTION_H5};
use membrane_contact::run::{self, Parts, RunError};
use membrane_contact::study::{self, StudyOptions};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyList, PyLong, PyString, PyTuple};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

create_exception!(
    _core,
    InputError,
    PyValueError,
    "Bad input: a case, a mesh or an option; the message is the command line's."
);
create_exception!(
    _core,
    SolverError,
    PyRuntimeError,
    "The solver failed or a check of its solution did not pass."
);
create_exception!(
    _core,
    OutputError,
    PyOSError,
    "A result directory could not be written, or a result's files read back (a path that is no result directory is an InputError)."
);

/// How often the waiting thread checks for Ctrl-C.
const POLL: Duration = Duration::from_millis(50);

/// The Python exception of a run's error, with its one-line message.
fn run_error(e: RunError) -> PyErr {
    match &e {
        RunError::Case(_) => InputError::new_err(e.to_string()),
        RunError::Solve(_, SolveError::Cancelled) => PyKeyboardInterrupt::new_err(e.to_string()),
        RunError::Solve(..) | RunError::Check(..) => SolverError::new_err(e.to_string()),
        RunError::Output(_) => OutputError::new_err(e.to_string()),
    }
}

/// The thread pool of a run on `threads` threads, else on the `RAYON_NUM_THREADS` of the process
/// (checked as the command line checks it), else one thread per core. A pool of its own for
/// each run, never rayon's global pool: a process forked from one that used it (a
/// `multiprocessing` worker) has the pool but not its threads, and its runs waited forever.
fn pool(threads: Option<usize>) -> PyResult<rayon::ThreadPool> {
    let (t, from) = match threads {
        Some(t) => (t, format!("threads = {t}")),
        None => match membrane_contact::parallel::env_threads().map_err(InputError::new_err)? {
            Some(t) => (t, format!("RAYON_NUM_THREADS={t}")),
            // rayon's default: one thread per core.
            None => (0, "one thread per core".into()),
        },
    };
    if t > membrane_contact::parallel::MAX_THREADS {
        return Err(InputError::new_err(format!(
            "{from}: at most {} threads",
            membrane_contact::parallel::MAX_THREADS
        )));
    }
    built(t, &from)
}

/// A pool of `threads` threads (0: rayon's default), `from` naming them in an error.
fn built(threads: usize, from: &str) -> PyResult<rayon::ThreadPool> {
    (rayon::ThreadPoolBuilder::new().num_threads(threads).build())
        .map_err(|e| SolverError::new_err(format!("{from}: {e}")))
}

/// A pool of one thread per core for writing and reading results, whatever `RAYON_NUM_THREADS`
/// says (which the runs check), so that a result is written and read in any environment.
fn io_pool() -> PyResult<rayon::ThreadPool> {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    built(cores, "one thread per core")
}

/// Runs `work` on a thread of its own (its parallel parts in `pool`), the GIL released, checking
/// for Ctrl-C meanwhile when called from the main thread (only it receives signals). Another thread waits without the GIL until the run ends: one that took
/// it back every few milliseconds while the interpreter exits is ended by the interpreter
/// (`pthread_exit`), and unwinding through the extension aborts the process.
fn wait<T: Send + 'static>(
    py: Python<'_>,
    pool: rayon::ThreadPool,
    work: impl FnOnce() -> Result<T, RunError> + Send + 'static,
) -> PyResult<T> {
    progress::resume();
    let (send, mut receive) = mpsc::channel();
    let handle = std::thread::Builder::new()
        .name("membrane-contact".into())
        .spawn(move || {
            let result = pool.install(work);
            let _ = send.send(result);
        })
        .map_err(|e| SolverError::new_err(format!("cannot start the run's thread: {e}")))?;
    let panicked =
        || SolverError::new_err("the run failed on an internal error (a panic, printed on stderr)");
    let threading = py.import_bound("threading")?;
    let main = threading.call_method0("main_thread")?;
    if !threading.call_method0("current_thread")?.is(&main) {
        let result = py.allow_threads(move || receive.recv());
        let _ = handle.join();
        return result.map_err(|_| panicked())?.map_err(run_error);
    }
    loop {
        // The receiver goes in and out of the GIL-free closure (it is not Sync).
        let (got, back) = py.allow_threads(move || (receive.recv_timeout(POLL), receive));
        receive = back;
        match got {
            Ok(result) => {
                let _ = handle.join();
                return result.map_err(run_error);
            }
            Err(RecvTimeoutError::Timeout) => {
                if let Err(interrupt) = py.check_signals() {
                    // The run stops at its next check (before an active-set iteration, between
                    // phases, at the next block of the estimator's patches or round of the
                    // norms' cutting); it is waited for a second at most, then left to stop by
                    // itself (the next run's `resume` lets one still inside a long phase finish).
                    progress::cancel();
                    let _ = py.allow_threads(move || receive.recv_timeout(Duration::from_secs(1)));
                    return Err(interrupt);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                let _ = handle.join();
                return Err(panicked());
            }
        }
    }
}

/// A case as the Python side passes it.
struct CaseSource {
    /// "default", "path" or "text".
    kind: String,
    /// The path or the text.
    value: String,
    /// How text is named in messages ("case text", "case dict").
    origin: String,
}

/// A mesh given as arrays, copied: points and triangles (any vertex numbers, checked later).
type Arrays = (Vec<[f64; 2]>, Vec<[i64; 3]>, Option<GroupLists>);

/// The physical groups of a mesh given from Python as Gmsh numbers them (a meshio mesh read from
/// a .msh file): the names by (dimension, tag, name), the tag of each triangle (0 for none), the
/// lines (vertex numbers) and the tag of each.
type GroupLists = (Vec<(i32, i32, String)>, Vec<i64>, Vec<[i64; 2]>, Vec<i64>);

/// Where the groups of a mesh given from Python come from, for messages.
const GIVEN_GROUPS: &str = "the given mesh";

/// The placeholder `[mesh]` table of a case given beside a mesh without a table of its own:
/// replaced by the mesh at once, and left out of the case text the result stores.
const PLACEHOLDER_MESH: &str = "\n[mesh]\nkind = \"rectangle\"\nn = 1\n";

/// The text to parse of a case given beside a mesh, which replaces the mesh the case's `[mesh]`
/// names: the text itself where the table names a kind (the parse checks the table as a case
/// file's, without reading a file it names), else with a placeholder table of the table's
/// `refine` (where it holds `refine` alone, the text is written anew: a parse error elsewhere in
/// it would be placed in that text); the text itself where it is not TOML (the parse says why).
fn beside_mesh(text: &str) -> String {
    let Ok(mut table) = text.parse::<toml::Table>() else {
        return text.to_owned();
    };
    match table.get_mut("mesh") {
        None => text.to_owned() + PLACEHOLDER_MESH,
        Some(toml::Value::Table(mesh)) if mesh.keys().all(|k| k == "refine") => {
            mesh.insert("kind".into(), "rectangle".into());
            mesh.insert("n".into(), 1.into());
            toml::to_string(&table).expect("a TOML table serializes")
        }
        Some(_) => text.to_owned(),
    }
}

impl CaseSource {
    /// The case, on the given mesh if any, which replaces the mesh the case's `[mesh]` names (the
    /// table may then be left out, or hold `refine` alone); the table's `refine` refines it.
    fn case(&self, mesh: Option<Arrays>) -> Result<Case, CaseError> {
        let parsed = |text: &str| match mesh {
            Some(_) => beside_mesh(text),
            None => text.to_owned(),
        };
        let mut case = match self.kind.as_str() {
            "default" => Case::default_case(),
            "path" => {
                let path = Path::new(&self.value);
                let text = Case::read_text(path)?;
                let mut case = Case::parse_file(&parsed(&text), path)?;
                case.text = text;
                case
            }
            _ => {
                let mut case = Case::parse(&parsed(&self.value), &self.origin, PathBuf::new())?;
                case.text.clone_from(&self.value);
                case
            }
        };
        if let Some((points, triangles, groups)) = mesh {
            let n = points.len();
            let triangles = (triangles.iter().enumerate())
                .map(|(t, tri)| {
                    let mut out = [0usize; 3];
                    for (o, &v) in out.iter_mut().zip(tri) {
                        *o = usize::try_from(v).ok().filter(|&v| v < n).ok_or_else(|| {
                            CaseError(format!(
                                "{}: the given mesh is not valid: triangle {t} refers to vertex {v}, \
                                 which does not exist",
                                case.origin
                            ))
                        })?;
                    }
                    Ok(out)
                })
                .collect::<Result<Vec<_>, CaseError>>()?;
            let mesh = Mesh::new(points, triangles)
                .map_err(|e| CaseError(format!("{}: the given mesh is not valid: {e}", case.origin)))?;
            let mesh = match groups {
                None => mesh,
                Some(groups) => with_groups(mesh, groups)
                    .map_err(|e| CaseError(format!("{}: the given mesh's groups: {e}", case.origin)))?,
            };
            case.set_mesh(mesh);
        }
        Ok(case)
    }
}

/// `mesh` with the physical `groups` given from Python, checked against it.
fn with_groups(mesh: Mesh, (names, triangle, lines, line_tags): GroupLists) -> Result<Mesh, String> {
    if triangle.len() != mesh.n_triangles() || lines.len() != line_tags.len() {
        return Err(format!(
            "{} tags for {} triangles, {} for {} lines",
            triangle.len(),
            mesh.n_triangles(),
            line_tags.len(),
            lines.len()
        ));
    }
    let tag = |t: i64| i32::try_from(t).map_err(|_| format!("tag {t} is not a Gmsh physical tag"));
    let triangle = (triangle.iter())
        .map(|&t| Ok((t > 0).then_some(tag(t)?)))
        .collect::<Result<Vec<_>, String>>()?;
    let n = mesh.n_vertices();
    let vertex = |v: i64| {
        usize::try_from(v)
            .ok()
            .filter(|&v| v < n)
            .ok_or_else(|| format!("a line refers to vertex {v}, which does not exist"))
    };
    let lines = (lines.iter().zip(&line_tags))
        .filter(|(_, &t)| t > 0)
        .map(|(l, &t)| Ok(([vertex(l[0])?, vertex(l[1])?], tag(t)?)))
        .collect::<Result<Vec<_>, String>>()?;
    let names: Vec<((i32, i32), String)> = names.into_iter().map(|(d, t, n)| ((d, t), n)).collect();
    Ok(membrane_contact::mesh::file::with_physical_groups(
        mesh,
        &names,
        &triangle,
        &lines,
        GIVEN_GROUPS,
    ))
}

/// The case (kind and value, from Python's `_case`), its origin for messages and the mesh
/// arrays with their groups, if given: what `solve`, `study` and `adapt` take.
fn inputs(
    case: (String, String),
    origin: String,
    points: Option<PyReadonlyArray2<'_, f64>>,
    triangles: Option<PyReadonlyArray2<'_, i64>>,
    groups: Option<GroupLists>,
) -> PyResult<(CaseSource, Option<Arrays>)> {
    let source = CaseSource {
        kind: case.0,
        value: case.1,
        origin,
    };
    Ok((source, arrays(points, triangles, groups)?))
}

/// The arrays of a mesh given from Python, copied (the shapes are checked on the Python side).
fn arrays(
    points: Option<PyReadonlyArray2<'_, f64>>,
    triangles: Option<PyReadonlyArray2<'_, i64>>,
    groups: Option<GroupLists>,
) -> PyResult<Option<Arrays>> {
    let (Some(points), Some(triangles)) = (points, triangles) else {
        return Ok(None);
    };
    let (p, t) = (points.as_array(), triangles.as_array());
    if p.ncols() != 2 || t.ncols() != 3 {
        return Err(InputError::new_err(format!(
            "mesh: need points of shape (N, 2) and triangles of shape (M, 3), got {:?} and {:?}",
            p.shape(),
            t.shape()
        )));
    }
    let points = p.rows().into_iter().map(|r| [r[0], r[1]]).collect();
    let triangles = t.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
    Ok(Some((points, triangles, groups)))
}

/// The case's settings that the keyword arguments override.
fn override_case(
    case: &mut Case,
    n: Option<usize>,
    refine: Option<usize>,
    linear: Option<&str>,
) -> Result<(), CaseError> {
    if let Some(name) = linear {
        case.solver.linear = LinearSolver::from_name(name).ok_or_else(|| {
            CaseError(format!(
                "linear = \"{name}\": expected one of {}",
                LinearSolver::NAMES.map(|n| format!("\"{n}\"")).join(", ")
            ))
        })?;
    }
    if let Some(n) = n {
        case.set_cells(n)
            .map_err(|e| CaseError(format!("n = {n}: {e}")))?;
    }
    if let Some(k) = refine {
        case.refine = k;
    }
    Ok(())
}

/// A finished result: its mesh, fields and attributes, as the command line writes them.
#[pyclass(module = "membrane_contact._core", name = "Parts", frozen)]
struct PyParts {
    parts: Parts,
}

#[pymethods]
impl PyParts {
    /// The vertices, shape (N, 2).
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let flat: Vec<f64> = self.parts.mesh.points.concat();
        let n = self.parts.mesh.n_vertices();
        Ok(PyArray1::from_vec_bound(py, flat).reshape([n, 2])?.into_any())
    }

    /// The triangles, counter-clockwise, shape (M, 3).
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mesh = &self.parts.mesh;
        let flat: Vec<i64> = mesh.triangles().flatten().map(|v| v as i64).collect();
        Ok(PyArray1::from_vec_bound(py, flat)
            .reshape([mesh.n_triangles(), 3])?
            .into_any())
    }

    /// The fields of T_h: name → (place, values), place "vertices" or "cells", in the order
    /// written.
    fn fields<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty_bound(py);
        for f in &self.parts.fields {
            let place = match f.place {
                Place::Vertices => "vertices",
                Place::Cells => "cells",
                Place::DualCells => continue,
            };
            let values = PyArray1::from_slice_bound(py, &f.values());
            list.append((f.name, place, values))?;
        }
        Ok(list)
    }

    /// The dual submesh S_h when the result holds it (asked for by `dual` or `flux`), as
    /// `dual.xdmf` holds it: its points (P, 2), its triangles (S, 3), and its fields, name → one
    /// value per cell, in the order written; else None.
    #[allow(clippy::type_complexity)]
    fn dual<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyList>)>> {
        if !self.parts.writes_dual {
            return Ok(None);
        }
        let d = DualMesh::new(&self.parts.mesh, &self.parts.edges);
        let points: Vec<f64> = (0..d.n_points()).flat_map(|p| d.point(p)).collect();
        let cells: Vec<i64> = (0..d.n_cells())
            .flat_map(|s| d.cell(s))
            .map(|v| v as i64)
            .collect();
        let fields = PyList::empty_bound(py);
        for f in self.parts.fields.iter().filter(|f| f.place == Place::DualCells) {
            let per_cell: Vec<f64> = match &f.values {
                Values::PerVertex(v) => (0..d.n_cells()).map(|s| v[d.owner(s)]).collect(),
                _ => f.values().into_owned(),
            };
            fields.append((f.name, PyArray1::from_vec_bound(py, per_cell)))?;
        }
        let points = PyArray1::from_vec_bound(py, points).reshape([d.n_points(), 2])?;
        let cells = PyArray1::from_vec_bound(py, cells).reshape([d.n_cells(), 3])?;
        Ok(Some((points.into_any(), cells.into_any(), fields)))
    }

    /// The attributes of `solution.h5`'s root group: name → number, count, text or list.
    fn attributes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new_bound(py);
        for (name, value) in &self.parts.attributes {
            match value {
                Attr::Float(v) => dict.set_item(name, v)?,
                Attr::Int(v) => dict.set_item(name, v)?,
                Attr::Text(s) => dict.set_item(name, s)?,
                Attr::Floats(v) => dict.set_item(name, v.clone())?,
            }
        }
        Ok(dict)
    }

    /// The summary the command line prints.
    fn summary(&self) -> &str {
        &self.parts.summary
    }

    /// Writes the whole result directory `directory`, as the command line does (an earlier result
    /// there is replaced only once this one is complete).
    fn write(slf: Py<Self>, py: Python<'_>, directory: PathBuf) -> PyResult<()> {
        wait(py, io_pool()?, move || slf.get().parts.write(&directory))
    }
}

/// Solves a case: the `Parts` of its result.
#[pyfunction]
#[pyo3(signature = (case, origin, points=None, triangles=None, groups=None, *, estimate=false, flux=false,
    dual=false, hminus1=false, linear=None, refine=None, n=None, start=None, verbose=false, threads=None))]
#[allow(clippy::too_many_arguments)]
fn solve(
    py: Python<'_>,
    case: (String, String),
    origin: String,
    points: Option<PyReadonlyArray2<'_, f64>>,
    triangles: Option<PyReadonlyArray2<'_, i64>>,
    groups: Option<GroupLists>,
    estimate: bool,
    flux: bool,
    dual: bool,
    hminus1: bool,
    linear: Option<String>,
    refine: Option<usize>,
    n: Option<usize>,
    start: Option<String>,
    verbose: bool,
    threads: Option<usize>,
) -> PyResult<PyParts> {
    let (source, mesh) = inputs(case, origin, points, triangles, groups)?;
    let start = match start.as_deref() {
        None | Some("nested") => Start::Nested,
        Some("cold") => Start::Cold,
        Some(other) => {
            return Err(InputError::new_err(format!(
                "start = \"{other}\": expected \"nested\" or \"cold\""
            )))
        }
    };
    let parts = wait(py, pool(threads)?, move || {
        let mut case = source.case(mesh)?;
        override_case(&mut case, n, refine, linear.as_deref())?;
        let options = run::Options {
            start,
            hminus1,
            flux,
            estimate,
            dual,
        };
        Ok(run::run(&case, &options)?.parts(verbose, false))
    })?;
    Ok(PyParts { parts })
}

/// A convergence study: per variant (its label, "" or "grading g"), the levels as JSON and the
/// `Parts` of each level.
#[pyfunction]
#[pyo3(signature = (case, origin, points=None, triangles=None, groups=None, *, levels=None, refine=None,
    cold=false, grading=None, hminus1_max=512, linear=None, threads=None))]
#[pyo3(name = "study")]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn run_study(
    py: Python<'_>,
    case: (String, String),
    origin: String,
    points: Option<PyReadonlyArray2<'_, f64>>,
    triangles: Option<PyReadonlyArray2<'_, i64>>,
    groups: Option<GroupLists>,
    levels: Option<Vec<usize>>,
    refine: Option<Vec<usize>>,
    cold: bool,
    grading: Option<Vec<f64>>,
    hminus1_max: usize,
    linear: Option<String>,
    threads: Option<usize>,
) -> PyResult<Vec<(String, String, Vec<PyParts>)>> {
    let (source, mesh) = inputs(case, origin, points, triangles, groups)?;
    if levels.is_some() && refine.is_some() {
        return Err(InputError::new_err("give levels or refine, not both"));
    }
    let series = wait(py, pool(threads)?, move || {
        let mut case = source.case(mesh)?;
        override_case(&mut case, None, None, linear.as_deref())?;
        let levels = (levels.map(Levels::Cells))
            .or(refine.map(Levels::Refine))
            .unwrap_or_else(|| study::default_levels(&case));
        let options = StudyOptions {
            levels,
            cold,
            hminus1_max,
            grading,
        };
        let mut out = Vec::new();
        for (label, cases) in study::variants(&case, &options)? {
            let mut parts = Vec::new();
            let levels = study::run_levels(&cases, &options, |_, _, r| {
                parts.push(PyParts {
                    parts: r.parts(false, false),
                })
            })?;
            let json = serde_json::to_string(&levels).expect("levels serialise");
            out.push((label, json, parts));
        }
        Ok(out)
    })?;
    Ok(series)
}

/// The adaptive loop: its steps as JSON, the `Parts` of each step and why it stopped.
#[pyfunction]
#[pyo3(signature = (case, origin, points=None, triangles=None, groups=None, *, n=None, refine=None, theta=None,
    target=None, max_vertices=None, steps=None, dual=false, threads=None))]
#[pyo3(name = "adapt")]
#[allow(clippy::too_many_arguments)]
fn run_adapt(
    py: Python<'_>,
    case: (String, String),
    origin: String,
    points: Option<PyReadonlyArray2<'_, f64>>,
    triangles: Option<PyReadonlyArray2<'_, i64>>,
    groups: Option<GroupLists>,
    n: Option<usize>,
    refine: Option<usize>,
    theta: Option<f64>,
    target: Option<f64>,
    max_vertices: Option<usize>,
    steps: Option<usize>,
    dual: bool,
    threads: Option<usize>,
) -> PyResult<(String, Vec<PyParts>, String)> {
    let (source, mesh) = inputs(case, origin, points, triangles, groups)?;
    wait(py, pool(threads)?, move || {
        let mut case = source.case(mesh)?;
        override_case(&mut case, n, refine, None)?;
        let mut settings = case.adapt;
        settings.theta = theta.unwrap_or(settings.theta);
        settings.target = target.or(settings.target);
        settings.max_vertices = max_vertices.unwrap_or(settings.max_vertices);
        settings.steps = steps.unwrap_or(settings.steps);
        settings.check(str::to_string).map_err(CaseError)?;
        let mut parts = Vec::new();
        let steps = adapt::steps(&case, &settings, |_, r, _| {
            parts.push(PyParts {
                parts: r.parts(false, dual),
            });
            Ok(())
        })?;
        let json = serde_json::to_string(&steps).expect("steps serialise");
        Ok((json, parts, adapt::stopped(&settings, &steps)))
    })
}

/// The names read from result files, each leaked once (a field's and an attribute's name is
/// `&'static str`): at most the few names a result holds.
fn intern(name: &str) -> &'static str {
    static NAMES: Mutex<Vec<&'static str>> = Mutex::new(Vec::new());
    let mut names = NAMES.lock().unwrap_or_else(|e| e.into_inner());
    match names.iter().find(|n| **n == name) {
        Some(n) => n,
        None => {
            let leaked: &'static str = Box::leak(name.to_owned().into_boxed_str());
            names.push(leaked);
            leaked
        }
    }
}

/// The (name, center) of each attribute of the grids of an XDMF file, in order.
fn xdmf_attributes(path: &Path) -> Result<Vec<(String, String)>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let doc =
        membrane_contact::mesh::file::parse_xml(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(doc
        .descendants()
        .filter(|n| n.has_tag_name("Attribute"))
        .map(|n| {
            let get = |k| n.attribute(k).unwrap_or("").to_string();
            (get("Name"), get("Center"))
        })
        .collect())
}

/// Why `dir` is not a result directory to read, if it is not one: missing, a file, an adapt
/// run's directory (whose steps are), a directory without a solution file.
fn not_a_result(dir: &Path) -> Option<String> {
    let shown = dir.display();
    if !dir.exists() {
        return Some(format!("{shown}: no such directory"));
    }
    if !dir.is_dir() {
        return Some(format!(
            "{shown} is a file: give the result directory (the one holding {SOLUTION_H5})"
        ));
    }
    if dir.join("adapt.xdmf").exists() {
        let last = (std::fs::read_dir(dir).ok()?)
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| n.starts_with("step-"))
            .max()
            .unwrap_or_else(|| "step-000".into());
        return Some(format!(
            "{shown} is an adapt run: read one of its step directories, e.g. {}",
            dir.join(last).display()
        ));
    }
    (!dir.join(SOLUTION_H5).exists())
        .then(|| format!("{shown}: no {SOLUTION_H5}: not a result directory of this program"))
}

/// Reads a result directory written by [`run::Parts::write`] (or the command line).
fn read_parts(dir: &Path) -> Result<Parts, String> {
    let h5 = dir.join(SOLUTION_H5);
    let named = |e: hdf5::Error| format!("{}: {}", h5.display(), hdf5_error(&e));
    // As a mesh file: with its physical groups (the boundary edges' curves are in no field).
    let mesh = membrane_contact::mesh::file::read(&h5).map_err(|e| format!("its mesh: {e}"))?;
    let file = hdf5::File::open(&h5).map_err(named)?;
    let mut fields = Vec::new();
    let dual_xdmf = dir.join("dual.xdmf");
    let writes_dual = dual_xdmf.exists();
    let mut grids = vec![("mesh", dir.join("solution.xdmf"))];
    if writes_dual {
        grids.push(("dual", dual_xdmf));
    }
    for (group, xdmf) in grids {
        for (name, center) in xdmf_attributes(&xdmf)? {
            let place = match (group, center.as_str()) {
                ("mesh", "Node") => Place::Vertices,
                ("mesh", _) => Place::Cells,
                _ => Place::DualCells,
            };
            let dataset = file.dataset(&format!("{group}/{name}")).map_err(named)?;
            let values = dataset.read_raw::<f64>().map_err(named)?;
            fields.push(Field::owned(intern(&name), place, values));
        }
    }
    let mut attributes: Vec<Attribute> = Vec::new();
    for name in file.attr_names().map_err(named)? {
        let attr = file.attr(&name).map_err(named)?;
        let dtype = attr.dtype().map_err(named)?;
        let value = if dtype.is::<f64>() && attr.ndim() == 0 {
            Attr::Float(attr.read_scalar::<f64>().map_err(named)?)
        } else if dtype.is::<f64>() {
            Attr::Floats(attr.read_raw::<f64>().map_err(named)?)
        } else if dtype.is::<i64>() {
            Attr::Int(attr.read_scalar::<i64>().map_err(named)?)
        } else {
            let text = attr.read_scalar::<hdf5::types::VarLenUnicode>().map_err(named)?;
            Attr::Text(text.as_str().to_string())
        };
        attributes.push((intern(&name), value));
    }
    let printed = attributes.iter().find_map(|(name, value)| match (*name, value) {
        ("summary", Attr::Text(text)) => Some(text.clone()),
        _ => None,
    });
    let summary = format!(
        "{}result      {} (read back: {} vertices, {} triangles)\n",
        printed.unwrap_or_default(),
        dir.display(),
        mesh.n_vertices(),
        mesh.n_triangles()
    );
    Ok(Parts {
        edges: Edges::new(&mesh),
        mesh,
        fields,
        attributes,
        summary,
        inputs: Vec::new(),
        writes_dual,
    })
}

/// Reads a result directory.
#[pyfunction]
fn read(py: Python<'_>, directory: PathBuf) -> PyResult<PyParts> {
    if let Some(why) = not_a_result(&directory) {
        return Err(InputError::new_err(why));
    }
    let pool = io_pool()?;
    let parts = py
        .allow_threads(|| pool.install(|| read_parts(&directory)))
        .map_err(|e| OutputError::new_err(format!("cannot read the result: {e}")))?;
    Ok(PyParts { parts })
}

/// A TOML value of a Python value (`key` names it in errors); `None` for a value left out.
fn toml_value(v: &Bound<'_, PyAny>, key: &str) -> PyResult<Option<toml::Value>> {
    use toml::Value;
    if v.is_none() {
        return Ok(None);
    }
    if v.is_instance_of::<PyBool>() {
        return Ok(Some(Value::Boolean(v.extract()?)));
    }
    if v.is_instance_of::<PyLong>() {
        // Beyond 64 bits TOML has no integer: the number as a float, which a key that needs an
        // integer names.
        if let Ok(i) = v.extract::<i64>() {
            return Ok(Some(Value::Integer(i)));
        }
        return match v.extract::<f64>() {
            Ok(x) => Ok(Some(Value::Float(x))),
            Err(_) => Err(InputError::new_err(format!(
                "case key '{key}': an integer of {} bits is beyond any number a case takes",
                v.call_method0("bit_length")?
            ))),
        };
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(Some(Value::Float(v.extract()?)));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(Some(Value::String(v.extract()?)));
    }
    if let Ok(d) = v.downcast::<PyDict>() {
        return Ok(Some(Value::Table(toml_table(d, key)?)));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut out = Vec::new();
        for (i, item) in v.iter()?.enumerate() {
            let item = item?;
            let value = toml_value(&item, &format!("{key}[{i}]"))?
                .ok_or_else(|| InputError::new_err(format!("case key '{key}[{i}]' is None")))?;
            out.push(value);
        }
        return Ok(Some(Value::Array(out)));
    }
    // numpy scalars and arrays.
    if v.hasattr("tolist")? {
        let plain = v.call_method0("tolist")?;
        if !plain.is(v) {
            return toml_value(&plain, key);
        }
    }
    Err(InputError::new_err(format!(
        "case key '{key}': a value of type {} is not a case value (a number, a string, a list or a dict)",
        v.get_type().name()?
    )))
}

fn toml_table(d: &Bound<'_, PyDict>, prefix: &str) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (k, v) in d.iter() {
        let k: String = k
            .extract()
            .map_err(|_| InputError::new_err(format!("case keys are strings, got {k} in '{prefix}'")))?;
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        if let Some(value) = toml_value(&v, &key)? {
            table.insert(k, value);
        }
    }
    Ok(table)
}

/// The TOML text of a case given as a dict (keys in the dict's order, `None` values left out).
#[pyfunction]
fn dict_to_toml(case: &Bound<'_, PyDict>) -> PyResult<String> {
    let table = toml_table(case, "")?;
    toml::to_string(&table).map_err(|e| InputError::new_err(format!("case dict: {e}")))
}

/// The built-in default case, as a case file.
#[pyfunction]
fn default_case() -> &'static str {
    membrane_contact::case::DEFAULT_CASE
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // The interpreter handles SIGINT, SIGTERM and SIGHUP: none of the command line's handlers.
    atomic::leave_signals_alone();
    m.add("InputError", m.py().get_type_bound::<InputError>())?;
    m.add("SolverError", m.py().get_type_bound::<SolverError>())?;
    m.add("OutputError", m.py().get_type_bound::<OutputError>())?;
    m.add_class::<PyParts>()?;
    m.add_function(wrap_pyfunction!(solve, m)?)?;
    m.add_function(wrap_pyfunction!(run_study, m)?)?;
    m.add_function(wrap_pyfunction!(run_adapt, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(dict_to_toml, m)?)?;
    m.add_function(wrap_pyfunction!(default_case, m)?)?;
    m.add("version", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
