//! Mesh checks: arbitrary points and triangles are accepted as a valid mesh or rejected with a
//! reason, never a panic; an accepted mesh supports interpolation and the dual submesh.
#![no_main]
use libfuzzer_sys::fuzz_target;
use membrane_contact::mesh::DualMesh;
use membrane_contact::mesh::{Mesh, Prolongation};

fuzz_target!(|data: &[u8]| {
    let Some((&count, rest)) = data.split_first() else { return };
    let count = usize::from(count % 24) + 1;
    if rest.len() < 2 * count {
        return;
    }
    // Points on a small grid (so that coincidences, collinearity and folds happen).
    let points: Vec<[f64; 2]> = rest[..2 * count]
        .chunks(2)
        .map(|c| [f64::from(c[0] % 16) / 4.0, f64::from(c[1] % 16) / 4.0])
        .collect();
    let triangles: Vec<[usize; 3]> = rest[2 * count..]
        .chunks_exact(3)
        .map(|c| [0, 1, 2].map(|k| usize::from(c[k]) % (count + 1)))
        .collect();
    if let Ok(mesh) = Mesh::new(points, triangles) {
        let ones = vec![1.0; mesh.n_vertices()];
        let back = Prolongation::new(&mesh, &mesh).apply(&ones);
        assert!(back.iter().all(|v| (v - 1.0).abs() < 1e-9));
        let dual = DualMesh::new(&mesh);
        assert_eq!(dual.triangles.len(), 6 * mesh.triangles.len());
    }
});
