//! Times meshing (spade) and uniform refinement of the unit disk and of a polygon with a hole at
//! growing sizes: `cargo run --release --example mesh_timing`.

use membrane_contact::mesh::{Domain, Mesh};
use std::time::Instant;

fn main() {
    let disk = Domain::Disk {
        centre: [0.0, 0.0],
        radius: 1.0,
        inner_radius: None,
    };
    let polygon = Domain::Polygon {
        boundary: vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 0.6], [0.0, 1.0]],
        holes: vec![vec![[0.4, 0.3], [0.8, 0.3], [0.8, 0.6], [0.4, 0.6]]],
    };
    for (name, domain) in [("disk", &disk), ("polygon", &polygon)] {
        for h in [0.01, 0.005, 0.0025] {
            let t = Instant::now();
            let mesh = domain.mesh(h).unwrap();
            let seconds = t.elapsed().as_secs_f64();
            let ratio = mesh.n_vertices() as f64 * h * h / domain.area();
            // The checks of Mesh::new, part of the time above, timed again on their own.
            let t = Instant::now();
            Mesh::new(mesh.points.clone(), mesh.triangles().collect()).unwrap();
            let checks = t.elapsed().as_secs_f64();
            println!(
                "{name} h = {h}: {} vertices in {seconds:.2} s ({:.2} µs per vertex; checks {checks:.2} s), \
                 vertices·h²/area = {ratio:.2}, estimate {}",
                mesh.n_vertices(),
                1e6 * seconds / mesh.n_vertices() as f64,
                domain.estimated_vertices(h)
            );
        }
        let coarse = domain.mesh(0.01).unwrap();
        let t = Instant::now();
        let fine = coarse
            .refined(&domain.curves())
            .unwrap()
            .refined(&domain.curves())
            .unwrap();
        println!(
            "{name}: refining {} vertices twice to {} took {:.2} s",
            coarse.n_vertices(),
            fine.n_vertices(),
            t.elapsed().as_secs_f64()
        );
    }
}
