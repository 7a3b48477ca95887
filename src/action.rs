//! The discrete action λ_h by local postprocessing (4.5), and the dual mesh D_h it lives on.
//!
//! At each interior vertex a, with m_a = ∫φ_a = meas(D_a) (Remark 11, Section 4.2):
//!   λ1_a m_a =  μ1 ∫∇u1h·∇φ_a − ∫f1 φ_a,
//!   λ2_a m_a = −μ2 ∫∇u2h·∇φ_a + ∫f2 φ_a,
//! which coincide (Proposition 12); λ_a ≥ 0 and λ_a (u1h − u2h)(a) = 0 (4.8). λ_h = Σ λ_a χ_{D_a} is
//! piecewise constant on the barycentric dual cells D_a.

use crate::contact::{DiscreteProblem, Solution};
use crate::mesh::Mesh;

/// λ_h from each membrane and the checks of Proposition 12 and (4.8).
#[derive(Debug, Clone)]
pub struct Action {
    /// λ_a from membrane 1 at each vertex (0 on ∂ω, where no D_a is defined).
    pub lambda: Vec<f64>,
    /// λ_a from membrane 2.
    pub lambda2: Vec<f64>,
    /// max_a |λ1_a − λ2_a| (Proposition 12).
    pub membrane_difference: f64,
    /// min_a λ_a (≥ 0 up to round-off).
    pub min_lambda: f64,
    /// max_a |λ_a (u1h − u2h)(a)| (4.8).
    pub complementarity: f64,
    /// ∫_ω λ_h = Σ_a λ_a meas(D_a): the total contact force.
    pub total: f64,
    /// Σ_{a in contact} meas(D_a): the measure of the contact region on the dual mesh.
    pub contact_area: f64,
}

impl Action {
    /// Computes (4.5) from both membranes.
    pub fn compute(problem: &DiscreteProblem, solution: &Solution) -> Action {
        let mesh = &problem.mesh;
        let k = &problem.stiffness;
        let n = mesh.n_vertices();
        let (mut lambda, mut lambda2) = (vec![0.0; n], vec![0.0; n]);
        let (mut diff, mut min_lambda, mut compl, mut total, mut area) =
            (0.0f64, f64::INFINITY, 0.0f64, 0.0, 0.0);
        for a in 0..n {
            if mesh.on_boundary[a] {
                continue;
            }
            let m = problem.mass[a];
            let l1 = (problem.mu1 * k.row_dot(a, &solution.u1) - problem.load1[a]) / m;
            let l2 = (-problem.mu2 * k.row_dot(a, &solution.u2) + problem.load2[a]) / m;
            lambda[a] = l1;
            lambda2[a] = l2;
            diff = diff.max((l1 - l2).abs());
            min_lambda = min_lambda.min(l1);
            compl = compl.max((l1 * solution.obstacle.gap[a]).abs());
            total += l1 * m;
            if solution.obstacle.contact[a] {
                area += m;
            }
        }
        Action {
            lambda,
            lambda2,
            membrane_difference: diff,
            min_lambda,
            complementarity: compl,
            total,
            contact_area: area,
        }
    }
}

/// The submesh S_h: each triangle cut into six by its medians; the two sub-triangles at vertex a
/// form D_a ∩ K, so a field constant on each D_a is cell data here.
#[derive(Debug, Clone)]
pub struct DualMesh {
    /// Vertices of T_h, then edge midpoints, then barycentres.
    pub points: Vec<[f64; 2]>,
    pub triangles: Vec<[usize; 3]>,
    /// The vertex a of T_h whose cell D_a contains each sub-triangle.
    pub owner: Vec<usize>,
}

impl DualMesh {
    pub fn new(mesh: &Mesh) -> Self {
        let edges = mesh.edges();
        let n = mesh.n_vertices();
        let mut points = mesh.points.clone();
        points.extend(edges.iter().map(|&(a, b)| {
            let (p, q) = (mesh.points[a], mesh.points[b]);
            [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
        }));
        let midpoint = |a: usize, b: usize| n + edges.binary_search(&(a.min(b), a.max(b))).unwrap();
        let mut triangles = Vec::with_capacity(6 * mesh.triangles.len());
        let mut owner = Vec::with_capacity(6 * mesh.triangles.len());
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let [p, q, r] = mesh.corners(t);
            let centre = points.len();
            points.push([(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0]);
            for k in 0..3 {
                let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                triangles.push([a, midpoint(a, b), centre]);
                triangles.push([a, centre, midpoint(c, a)]);
                owner.extend([a, a]);
            }
        }
        DualMesh {
            points,
            triangles,
            owner,
        }
    }

    /// A vertex field of T_h as cell data on S_h (NaN on the cells of boundary vertices).
    pub fn cell_field(&self, mesh: &Mesh, values: &[f64]) -> Vec<f64> {
        self.owner
            .iter()
            .map(|&a| if mesh.on_boundary[a] { f64::NAN } else { values[a] })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{orient, Diagonal};

    #[test]
    fn dual_cells_have_the_lumped_masses() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 5, Diagonal::Right).unwrap();
        let dual = DualMesh::new(&mesh);
        assert_eq!(dual.triangles.len(), 6 * mesh.triangles.len());
        let mass = crate::assembly::lumped_mass(&mesh);
        let mut area = vec![0.0; mesh.n_vertices()];
        for (t, &a) in dual.triangles.iter().zip(&dual.owner) {
            let s = 0.5 * orient(dual.points[t[0]], dual.points[t[1]], dual.points[t[2]]);
            assert!(s > 0.0, "sub-triangles are counter-clockwise");
            area[a] += s;
        }
        for (a, m) in area.iter().zip(mass) {
            assert!((a - m).abs() < 1e-15);
        }
    }
}
