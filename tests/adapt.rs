//! Adaptive refinement as a user runs it: the L-shaped case with its corner singularity, from a
//! coarse mesh, checked against the exact solution (not against the estimator's own figures).

use membrane_contact::adapt::{adapt, rate};
use membrane_contact::case::{Adaptivity, Case};
use membrane_contact::mesh::file;
use std::path::Path;

#[test]
fn adaptivity_on_the_l_shape_reaches_the_optimal_rate_with_a_guaranteed_bound() {
    let mut case =
        Case::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases/lshape_corner.toml")).unwrap();
    case.set_cells(8).unwrap();
    let settings = Adaptivity {
        theta: 0.5,
        target: None,
        max_vertices: 4000,
        steps: 40,
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("adapt");
    let a = adapt(&case, &settings, &out).unwrap();
    let steps = &a.adaptive;
    assert!(steps.len() >= 10, "{} steps", steps.len());
    for (k, s) in steps.iter().enumerate() {
        let error = s.error.unwrap();
        assert!(
            s.estimator >= error,
            "step {k}: η = {} < error {error}",
            s.estimator
        );
        assert!(
            s.estimator <= 1.4 * error,
            "step {k}: effectivity {}",
            s.estimator / error
        );
        assert!(
            s.iterations <= 4,
            "step {k}: {} active-set iterations",
            s.iterations
        );
    }
    assert!(steps.last().unwrap().vertices <= 4000);
    // Adaptive refinement converges like N^(−1/2), and beats uniform refinement at the same N.
    let adaptive = rate(steps, |s| s.error).unwrap();
    assert!(adaptive >= 0.45, "adaptive rate {adaptive}");
    let last = steps.last().unwrap();
    let uniform = a.uniform.iter().rfind(|s| s.vertices <= last.vertices).unwrap();
    assert!(
        last.error.unwrap() < 0.8 * uniform.error.unwrap(),
        "adaptive {:?} at N = {} against uniform {:?} at N = {}",
        last.error,
        last.vertices,
        uniform.error,
        uniform.vertices
    );
    // The smallest triangles of the last mesh sit at the re-entrant corner (0, 0).
    let last = out.join(format!("step-{:03}/solution.h5", steps.len() - 1));
    let mesh = file::read(&last).unwrap();
    let smallest = (0..mesh.triangles.len())
        .min_by(|&s, &t| mesh.area(s).total_cmp(&mesh.area(t)))
        .unwrap();
    let c = mesh.corners(smallest);
    let centroid = [0, 1].map(|k| (c[0][k] + c[1][k] + c[2][k]) / 3.0);
    assert!(
        centroid[0].hypot(centroid[1]) < 0.01,
        "smallest triangle at {centroid:?}"
    );
    // One time series for ParaView: a grid per step, each reading its own step's file.
    let xdmf = std::fs::read_to_string(out.join("adapt.xdmf")).unwrap();
    assert_eq!(xdmf.matches("<Time Value=").count(), steps.len());
    for k in 0..steps.len() {
        assert!(
            xdmf.contains(&format!("step-{k:03}/solution.h5:/mesh/estimator")),
            "step {k}"
        );
    }
    for name in ["adapt.md", "adapt.csv", "adapt.json", "adapt.png"] {
        assert!(out.join(name).exists(), "{name}");
    }
}
