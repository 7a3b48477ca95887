//! A run asked to stop (`progress::cancel`, which the Python package calls on Ctrl-C) stops the
//! estimator's patches at their next block and the error norms' refinement at their next round,
//! rather than finishing them. Alone in its own test binary: the request is process-wide.

use membrane_contact::case::Case;
use membrane_contact::estimator::Estimate;
use membrane_contact::mesh::{DualMesh, Edges};
use membrane_contact::progress;
use membrane_contact::run;

#[test]
fn a_cancelled_estimate_solves_no_patch() {
    let mut case = Case::default_case();
    case.set_cells(256).unwrap();
    let options = run::Options::default();
    let r = run::run(&case, &options).unwrap();
    let mesh = &r.problem.mesh;
    let edges = Edges::new(mesh);
    let dual = DualMesh::new(mesh, &edges);
    let flux_terms = |e: &Estimate| e.flux.iter().flatten().filter(|&&x| x != 0.0).count();
    let whole = Estimate::compute(&r.problem, &dual, &r.solution, &r.action);
    assert_eq!(flux_terms(&whole), 2 * mesh.n_triangles());
    progress::cancel();
    let cut = Estimate::compute(&r.problem, &dual, &r.solution, &r.action);
    let stopped = run::run(&case, &options);
    progress::resume();
    assert_eq!(flux_terms(&cut), 0);
    assert!(stopped.is_err());
}
