//! P1 assembly on T_h: the stiffness matrix K_ab = ∫∇φ_b·∇φ_a, the lumped pairing
//! m_a = ∫φ_a (Remark 11: ⟨χ_a, φ_a⟩_h = meas(D_a) = ∫φ_a), and the loads (f, φ_a).

use crate::expr::{Expr, Program};
use crate::mesh::{Mesh, Stars};
use crate::quadrature_tables::TRIANGLE_RULES;
use crate::sparse::{Csr, NEGLIGIBLE};

/// K_ab = ∫∇φ_b·∇φ_a on all vertices (no boundary condition applied): symmetric, by rows, with
/// the couplings that vanish left out — on right-angled triangles the two vertices facing the
/// right angles across an edge (the diagonals of built-in meshes with `diagonal = "right"` or
/// `"left"`: 2 of 7 entries per row) do not interact, and storing them would only cost memory
/// traffic in every sweep of the solvers.
#[derive(Debug, Clone)]
pub struct Stiffness {
    matrix: Csr,
}

impl Stiffness {
    /// K = ∫∇φ_b·∇φ_a over all vertices a, b (no boundary condition applied).
    pub fn assemble(mesh: &Mesh) -> Self {
        let n = mesh.n_vertices();
        let stars = Stars::new(mesh);
        // Row by row from the triangles around each vertex, in parallel (a triangle's local
        // matrix is computed for each of its three rows, so the rows share nothing); each entry
        // summed in the order of the triangles.
        let matrix = Csr::by_rows(n, n, 7, |rows, (ends, col, val)| {
            let mut entries: Vec<(u32, f64)> = Vec::new();
            for a in rows {
                entries.clear();
                for (t, k) in stars.around(a) {
                    let local = local_stiffness(mesh.corners(t));
                    entries.extend((0..3).map(|j| (mesh.triangle(t)[j] as u32, local[k][j])));
                }
                // Stable: the contributions to each entry stay in the order of the triangles.
                entries.sort_by_key(|e| e.0);
                let start = col.len();
                for group in entries.chunk_by(|x, y| x.0 == y.0) {
                    col.push(group[0].0);
                    val.push(group.iter().fold(0.0, |s, e| s + e.1));
                }
                let diagonal = val[start + col[start..].partition_point(|&b| (b as usize) < a)];
                let mut kept = start;
                for p in start..col.len() {
                    if val[p].abs() > NEGLIGIBLE * diagonal {
                        (col[kept], val[kept]) = (col[p], val[p]);
                        kept += 1;
                    }
                }
                col.truncate(kept);
                val.truncate(kept);
                ends.push(col.len() as u32);
            }
        });
        Stiffness {
            matrix: matrix.with_diagonal(),
        }
    }

    /// The matrix, for the solvers.
    pub fn matrix(&self) -> &Csr {
        &self.matrix
    }

    /// The number of rows.
    pub fn n(&self) -> usize {
        self.matrix.rows()
    }

    /// Row a of K as (column, value) pairs.
    #[inline]
    pub fn row(&self, a: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (cols, vals) = self.matrix.row(a);
        cols.iter().map(|&b| b as usize).zip(vals.iter().copied())
    }

    /// (K u)_a.
    #[inline]
    pub fn row_dot(&self, a: usize, u: &[f64]) -> f64 {
        self.matrix.row_dot(a, u)
    }

    /// The diagonal entry K_aa.
    #[inline]
    pub fn diagonal(&self, a: usize) -> f64 {
        self.matrix.diagonal(a)
    }
}

/// The 3×3 P1 stiffness matrix of a counter-clockwise triangle.
#[inline]
pub fn local_stiffness([p, q, r]: [[f64; 2]; 3]) -> [[f64; 3]; 3] {
    let g = gradients([p, q, r]);
    let area = 0.5 * crate::mesh::orient(p, q, r);
    let mut k = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            k[i][j] = area * (g[i][0] * g[j][0] + g[i][1] * g[j][1]);
        }
    }
    k
}

/// The gradients of the three barycentric (P1 basis) functions of a triangle.
#[inline]
pub fn gradients([p, q, r]: [[f64; 2]; 3]) -> [[f64; 2]; 3] {
    let d = crate::mesh::orient(p, q, r);
    [
        [(q[1] - r[1]) / d, (r[0] - q[0]) / d],
        [(r[1] - p[1]) / d, (p[0] - r[0]) / d],
        [(p[1] - q[1]) / d, (q[0] - p[0]) / d],
    ]
}

/// m_a = ∫φ_a = Σ_{K ∋ a} |K|/3, which is also meas(D_a) (Section 4.2).
pub fn lumped_mass(mesh: &Mesh) -> Vec<f64> {
    let mut m = vec![0.0; mesh.n_vertices()];
    for (t, tri) in mesh.triangles().enumerate() {
        let third = mesh.area(t) / 3.0;
        for a in tri {
            m[a] += third;
        }
    }
    m
}

/// A quadrature rule on triangles: basix's default rule of the given degree, so that the reference
/// (`ufl.dx(metadata={"quadrature_degree": q})`) integrates at the very same points.
#[derive(Debug, Clone, Copy)]
pub struct Quadrature {
    /// Polynomials up to this degree are integrated exactly.
    pub degree: usize,
}

impl Quadrature {
    /// The highest degree available.
    pub const MAX_DEGREE: usize = TRIANGLE_RULES.len() - 1;

    /// Reference points (ξ, η, weight), weights summing to 1/2.
    pub fn rule(&self) -> &'static [[f64; 3]] {
        TRIANGLE_RULES[self.degree.min(Self::MAX_DEGREE)]
    }

    /// The barycentric coordinates of the rule's points, in the order of [`Quadrature::rule`].
    pub fn barycentric(&self) -> impl Iterator<Item = [f64; 3]> {
        self.rule().iter().map(|&[xi, eta, _]| [1.0 - xi - eta, xi, eta])
    }

    /// Visits the triangles `range` (corners given by `corners`) with the E `fields` evaluated at
    /// their quadrature points: `visit(t, points, values)`, `values[e][q]` the field e at `points[q]`.
    /// The fields are evaluated together for `TRIANGLES_PER_BLOCK` triangles at a time, what
    /// they share once ([`Program`]).
    pub fn visit<const E: usize>(
        &self,
        corners: impl Fn(usize) -> [[f64; 2]; 3],
        range: std::ops::Range<usize>,
        fields: [&Expr; E],
        mut visit: impl FnMut(usize, &[QuadraturePoint], [&[f64]; E]),
    ) {
        let rule = self.rule();
        let np = rule.len();
        let mut points = Vec::with_capacity(TRIANGLES_PER_BLOCK * np);
        let mut xs = Vec::with_capacity(TRIANGLES_PER_BLOCK * np);
        let mut values = [(); E].map(|_| vec![0.0; TRIANGLES_PER_BLOCK * np]);
        let (program, mut scratch) = (Program::new(&fields), Vec::new());
        let mut start = range.start;
        while start < range.end {
            let block = start..range.end.min(start + TRIANGLES_PER_BLOCK);
            points.clear();
            for t in block.clone() {
                let [p, q, r] = corners(t);
                let jac = crate::mesh::orient(p, q, r);
                for (&[_, _, w], l) in rule.iter().zip(self.barycentric()) {
                    points.push(QuadraturePoint {
                        x: [
                            l[0] * p[0] + l[1] * q[0] + l[2] * r[0],
                            l[0] * p[1] + l[1] * q[1] + l[2] * r[1],
                        ],
                        weight: w * jac,
                        barycentric: l,
                    });
                }
            }
            xs.clear();
            xs.extend(points.iter().map(|p| p.x));
            let mut out = values.each_mut().map(|v| &mut v[..xs.len()]);
            program.eval_with(&xs, &mut out, &mut scratch);
            for (k, t) in block.clone().enumerate() {
                let q = k * np..(k + 1) * np;
                visit(
                    t,
                    &points[q.clone()],
                    std::array::from_fn(|e| &values[e][q.clone()]),
                );
            }
            start = block.end;
        }
    }
}

/// A physical quadrature point: its position, weight × |J| and barycentric coordinates.
#[derive(Debug, Clone, Copy)]
pub struct QuadraturePoint {
    /// Its position.
    pub x: [f64; 2],
    /// Its weight times |J|.
    pub weight: f64,
    /// Its barycentric coordinates in the triangle.
    pub barycentric: [f64; 3],
}

/// Triangles whose quadrature points are evaluated together.
const TRIANGLES_PER_BLOCK: usize = 16;

/// A non-finite value of an expression at a point.
#[derive(Debug, Clone, PartialEq)]
pub struct NotFinite {
    /// Where.
    pub point: [f64; 2],
    /// The triangle the point lies in.
    pub triangle: usize,
    /// The value there.
    pub value: f64,
}

/// The load vector F_a = (f, φ_a) over all vertices, by the quadrature rule: each triangle's
/// three contributions in parallel, then each vertex's sum over the triangles around it, in
/// their order.
pub fn load(mesh: &Mesh, f: &Expr, quad: Quadrature) -> Result<Vec<f64>, NotFinite> {
    if let Some(c) = f.constant() {
        if !c.is_finite() {
            return Err(NotFinite {
                point: mesh.points[0],
                triangle: 0,
                value: c,
            });
        }
        // Exact for constants: (c, φ_a) = c m_a.
        return Ok(lumped_mass(mesh).into_iter().map(|m| c * m).collect());
    }
    let [load] = load_by(mesh, |triangles, each| {
        quad.visit(|t| mesh.corners(t), triangles, [f], each)
    })
    .map_err(|(_, e)| e)?;
    Ok(load)
}

/// The load vectors (f_e, φ_a) of E data resolved on `mesh` ([`crate::datum::Pieces`]), in one
/// pass of the quadrature, so that what their expressions share is evaluated once per point; for a
/// table per group each triangle by the expression of its own group (the load jumps where the
/// groups meet). A constant datum's load is exact, c m_a, as [`load`]'s. The error names the datum
/// by its index.
pub fn loads<const E: usize>(
    mesh: &Mesh,
    f: [&crate::datum::Pieces; E],
    quad: Quadrature,
) -> Result<[Vec<f64>; E], (usize, NotFinite)> {
    let constant = f.map(|p| p.single().and_then(Expr::constant));
    if let Some((e, c)) =
        (constant.iter().enumerate()).find_map(|(e, c)| c.filter(|c| !c.is_finite()).map(|c| (e, c)))
    {
        return Err((
            e,
            NotFinite {
                point: mesh.points[0],
                triangle: 0,
                value: c,
            },
        ));
    }
    let exact = |c: f64| lumped_mass(mesh).into_iter().map(|m| c * m).collect();
    if constant.iter().all(Option::is_some) {
        return Ok(constant.map(|c| exact(c.expect("all constant"))));
    }
    let mut out = load_by(mesh, |triangles, each| {
        crate::datum::visit(&quad, |t| mesh.corners(t), |t| t, triangles, f, each)
    })?;
    for (out, c) in out.iter_mut().zip(constant) {
        if let Some(c) = c {
            *out = exact(c);
        }
    }
    Ok(out)
}

/// The visit of E loads' values at the quadrature points of a range of triangles.
type Each<'a, const E: usize> = &'a mut dyn FnMut(usize, &[QuadraturePoint], [&[f64]; E]);

/// The load vectors from `visit`, which evaluates E loads on a range of triangles: the
/// contributions (f_e, φ_k)_T at corner 3 t + k of triangle t, in parallel pieces, then each
/// vertex's sum over the triangles around it, in their order. The first value that is not finite
/// is an error, with the index of its load.
fn load_by<const E: usize>(
    mesh: &Mesh,
    visit: impl Fn(std::ops::Range<usize>, Each<E>) + Sync,
) -> Result<[Vec<f64>; E], (usize, NotFinite)> {
    // Corner c's contribution to load e at c E + e.
    let mut local = vec![0.0; 3 * E * mesh.n_triangles()];
    let piece = crate::parallel::PIECE;
    let parts = crate::parallel::map_mut(&mut local, 3 * E * piece, |base, local| {
        let first = base / (3 * E);
        let mut bad = None;
        visit(first..first + local.len() / (3 * E), &mut |t, points, values| {
            for (q, p) in points.iter().enumerate() {
                for (e, v) in values.iter().map(|v| v[q]).enumerate() {
                    if !v.is_finite() && bad.is_none() {
                        bad = Some((
                            e,
                            NotFinite {
                                point: p.x,
                                triangle: t,
                                value: v,
                            },
                        ));
                    }
                    for (k, b) in p.barycentric.iter().enumerate() {
                        local[(3 * (t - first) + k) * E + e] += p.weight * v * b;
                    }
                }
            }
        });
        bad.map_or(Ok(()), Err)
    });
    parts.into_iter().collect::<Result<(), (usize, NotFinite)>>()?;
    let stars = Stars::new(mesh);
    Ok(std::array::from_fn(|e| {
        crate::parallel::collect(mesh.n_vertices(), |a| {
            stars.corners(a).map(|c| local[c * E + e]).sum()
        })
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Diagonal, Mesh};

    /// Loads in one pass are each the load of its own pass, bit for bit: an expression and a
    /// constant (exact, c m_a), alone, together and twice; a value that is not finite, at a point
    /// or as a constant, names its load.
    #[test]
    fn loads_in_one_pass_are_the_loads_one_by_one() {
        use crate::datum::{Datum, On};
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 6, 5, Diagonal::Left).unwrap();
        let quad = Quadrature { degree: 4 };
        let datum = |s: &str| Datum::from(Expr::parse(s).unwrap());
        let (f, c) = (datum("sin(3*x)*y + x^2"), datum("2.5"));
        fn pieces<'a>(d: &'a Datum, mesh: &'a Mesh) -> crate::datum::Pieces<'a> {
            d.pieces("f", mesh, On::Surfaces).unwrap()
        }
        let (pf, pc) = (pieces(&f, &mesh), pieces(&c, &mesh));
        let [a, b] = loads(&mesh, [&pf, &pc], quad).unwrap();
        assert_eq!(a, load(&mesh, f.expr().unwrap(), quad).unwrap());
        let mass = lumped_mass(&mesh);
        assert_eq!(b, mass.iter().map(|m| 2.5 * m).collect::<Vec<_>>());
        let [one] = loads(&mesh, [&pf], quad).unwrap();
        assert_eq!(one, a);
        assert_eq!(loads(&mesh, [&pc, &pc], quad).unwrap(), [b.clone(), b]);
        let (inf, nan) = (datum("1/0"), datum("sqrt(x - 2)"));
        let (pinf, pnan) = (pieces(&inf, &mesh), pieces(&nan, &mesh));
        assert_eq!(loads(&mesh, [&pf, &pinf], quad).unwrap_err().0, 1);
        assert_eq!(loads(&mesh, [&pnan, &pf], quad).unwrap_err().0, 0);
    }

    #[test]
    fn stiffness_rows_sum_to_zero_and_masses_to_the_area() {
        for d in [Diagonal::Right, Diagonal::Left, Diagonal::Crossed] {
            let m = Mesh::rectangle([0.0, -1.0], [3.0, 1.0], 5, 4, d).unwrap();
            let k = Stiffness::assemble(&m);
            for a in 0..k.n() {
                let s: f64 = k.row(a).map(|(_, v)| v).sum();
                assert!(s.abs() < 1e-13, "row {a} sums to {s}");
                assert!(k.diagonal(a) > 0.0);
            }
            // Symmetric.
            for a in 0..k.n() {
                for (b, v) in k.row(a) {
                    assert!((k.matrix().get(b, a) - v).abs() < 1e-15);
                }
            }
            let total: f64 = lumped_mass(&m).iter().sum();
            assert!((total - 6.0).abs() < 1e-13);
        }
    }

    #[test]
    fn stiffness_energy_of_a_linear_function() {
        // |∇(2x + 3y)|² |ω| = 13 * 2.
        let m = Mesh::rectangle([0.0, 0.0], [2.0, 1.0], 3, 4, Diagonal::Crossed).unwrap();
        let k = Stiffness::assemble(&m);
        let u: Vec<f64> = m.points.iter().map(|p| 2.0 * p[0] + 3.0 * p[1]).collect();
        let e: f64 = (0..k.n()).map(|a| u[a] * k.row_dot(a, &u)).sum();
        assert!((e - 26.0).abs() < 1e-12);
    }

    #[test]
    fn loads_integrate_polynomials_exactly() {
        let m = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 4, 3, Diagonal::Right).unwrap();
        // Σ_a (f, φ_a) = ∫f, and Σ_a x_a (f, φ_a) = ∫ f x for f of degree 2 with a degree-3 rule.
        let f = Expr::parse("x^2 + x*y").unwrap();
        let l = load(&m, &f, Quadrature { degree: 3 }).unwrap();
        let total: f64 = l.iter().sum();
        assert!((total - (1.0 / 3.0 + 0.25)).abs() < 1e-14);
        let moment: f64 = l.iter().zip(&m.points).map(|(l, p)| l * p[0]).sum();
        assert!((moment - (0.25 + 1.0 / 6.0)).abs() < 1e-14);
        let c = load(&m, &Expr::parse("2").unwrap(), Quadrature { degree: 3 }).unwrap();
        assert!((c.iter().sum::<f64>() - 2.0).abs() < 1e-14);
        let bad = load(&m, &Expr::parse("1/(x - 0.5)").unwrap(), Quadrature { degree: 0 });
        assert!(
            bad.is_ok(),
            "no quadrature point sits on x = 0.5 with the centroid rule on 4x3"
        );
        let nan = load(
            &m,
            &Expr::parse("log(x - 0.5)").unwrap(),
            Quadrature { degree: 2 },
        )
        .unwrap_err();
        assert!(nan.value.is_nan() && nan.point[0] < 0.5);
    }

    /// Asserts |a − b| ≤ tol · max(1, |b|).
    fn close(a: f64, b: f64, tol: f64, what: &str) {
        assert!((a - b).abs() <= tol * b.abs().max(1.0), "{what}: {a} against {b}");
    }

    #[test]
    fn every_rule_integrates_its_degree_exactly() {
        // ∫ ξ^i η^j over the reference triangle = i! j! / (i + j + 2)!.
        let factorial = |n: i32| (1..=n).map(f64::from).product::<f64>();
        for degree in 0..=Quadrature::MAX_DEGREE {
            let rule = Quadrature { degree }.rule();
            let d = i32::try_from(degree).unwrap();
            for i in 0..=d {
                for j in 0..=d - i {
                    let q: f64 = rule.iter().map(|&[x, y, w]| w * x.powi(i) * y.powi(j)).sum();
                    let exact = factorial(i) * factorial(j) / factorial(i + j + 2);
                    assert!(
                        (q - exact).abs() <= 1e-12 * exact,
                        "degree {degree}, ξ^{i} η^{j}: {q} against {exact}"
                    );
                }
            }
        }
        // A degree beyond the tables takes the highest rule, degree 20.
        assert_eq!(Quadrature::MAX_DEGREE, 20);
        let highest = Quadrature {
            degree: Quadrature::MAX_DEGREE,
        };
        assert_eq!(Quadrature { degree: 21 }.rule(), highest.rule());
    }

    #[test]
    fn element_matrices_of_two_triangles_by_hand() {
        // The reference triangle: ∇λ = (−1, −1), (1, 0), (0, 1) and K = ½ [[2, −1, −1], [−1, 1, 0],
        // [−1, 0, 1]].
        let reference = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert_eq!(gradients(reference), [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]);
        assert_eq!(
            local_stiffness(reference),
            [[1.0, -0.5, -0.5], [-0.5, 0.5, 0.0], [-0.5, 0.0, 0.5]]
        );
        // (1, 1), (4, 2), (2, 5): 2|K| = 11, ∇λ = (−3, −2)/11, (4, −1)/11, (−1, 3)/11, and
        // K = |K| ∇λ_i·∇λ_j = [[13, −10, −3], [−10, 17, −7], [−3, −7, 10]]/22.
        let t = [[1.0, 1.0], [4.0, 2.0], [2.0, 5.0]];
        let (g, k) = (gradients(t), local_stiffness(t));
        let g_exact = [[-3.0, -2.0], [4.0, -1.0], [-1.0, 3.0]];
        let k_exact = [[13.0, -10.0, -3.0], [-10.0, 17.0, -7.0], [-3.0, -7.0, 10.0]];
        for i in 0..3 {
            for c in 0..2 {
                close(g[i][c], g_exact[i][c] / 11.0, 1e-15, &format!("∇λ_{i}[{c}]"));
            }
            for j in 0..3 {
                close(k[i][j], k_exact[i][j] / 22.0, 1e-15, &format!("K_{i}{j}"));
            }
        }
    }

    #[test]
    fn stiffness_and_masses_on_square_cells_in_closed_form() {
        // Each square cell of a right-diagonal mesh is two right isosceles triangles, which add 1 to
        // the diagonal entries of its four corners, −½ on each of its four sides and 0 across its
        // diagonal: K_aa = (cells at a), K_ab = −½ (cells along the side ab), 0 across a diagonal,
        // and nothing else in the pattern. m_a = |K|/3 = h²/6 for each triangle at a: two of the
        // cell of which a is the lower left or upper right corner, one of the other two.
        let (nx, ny, h) = (4_i64, 3_i64, 0.5);
        let m = Mesh::rectangle([1.0, -1.0], [3.0, 0.5], 4, 3, Diagonal::Right).unwrap();
        let (k, mass) = (Stiffness::assemble(&m), lumped_mass(&m));
        let n = m.n_vertices();
        assert_eq!(k.n(), n);
        let grid = |a: usize| {
            let p = m.points[a];
            (
                ((p[0] - 1.0) / h).round() as i64,
                ((p[1] + 1.0) / h).round() as i64,
            )
        };
        let cell = |i: i64, j: i64| f64::from(u8::from((0..nx).contains(&i) && (0..ny).contains(&j)));
        let u: Vec<f64> = m.points.iter().map(|p| p[0] * p[0] - 3.0 * p[1]).collect();
        let mut entries = 0;
        for (a, &m_a) in mass.iter().enumerate() {
            let (i, j) = grid(a);
            let expected: Vec<(usize, f64)> = (0..n)
                .filter_map(|b| {
                    let (p, q) = grid(b);
                    let value = match (p - i, q - j) {
                        (0, 0) => cell(i, j) + cell(i - 1, j) + cell(i - 1, j - 1) + cell(i, j - 1),
                        (1 | -1, 0) => -0.5 * (cell(i.min(p), j) + cell(i.min(p), j - 1)),
                        (0, 1 | -1) => -0.5 * (cell(i, j.min(q)) + cell(i - 1, j.min(q))),
                        // Across the diagonals the coupling vanishes and is not stored.
                        (1, 1) | (-1, -1) => return None,
                        _ => return None,
                    };
                    Some((b, value))
                })
                .collect();
            let row: Vec<(usize, f64)> = k.row(a).collect();
            assert_eq!(
                row.iter().map(|e| e.0).collect::<Vec<_>>(),
                expected.iter().map(|e| e.0).collect::<Vec<_>>(),
                "the pattern of row {a}"
            );
            for (r, (b, v)) in expected.iter().enumerate() {
                close(row[r].1, *v, 1e-15, &format!("K_{a}{b}"));
            }
            close(
                k.diagonal(a),
                expected.iter().find(|e| e.0 == a).unwrap().1,
                1e-15,
                "K_aa",
            );
            let ku: f64 = expected.iter().map(|&(b, v)| v * u[b]).sum();
            close(k.row_dot(a, &u), ku, 1e-14, "(K u)_a");
            let triangles = 2.0 * cell(i, j) + cell(i - 1, j) + 2.0 * cell(i - 1, j - 1) + cell(i, j - 1);
            close(m_a, triangles * h * h / 6.0, 1e-15, &format!("m_{a}"));
            entries += expected.len();
        }
        assert_eq!(k.matrix().nnz(), entries);
    }

    #[test]
    fn loads_of_a_linear_function_at_every_vertex() {
        // For f linear, ∫_K f λ_a = |K|/12 (f(a) + f(p) + f(q) + f(r)) over each triangle K = pqr
        // at a. On 60 triangles, so that each half spans a full block of 16 and part of another.
        let m = Mesh::rectangle([0.0, 0.0], [1.0, 0.75], 5, 3, Diagonal::Crossed).unwrap();
        assert_eq!(m.n_triangles(), 60);
        let f = |p: [f64; 2]| 1.0 + 2.0 * p[0] - 3.0 * p[1];
        let mut exact = vec![0.0; m.n_vertices()];
        for tri in m.triangles() {
            let [p, q, r] = tri.map(|v| m.points[v]);
            let area = 0.5 * ((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]));
            for a in tri {
                exact[a] += area / 12.0 * (f(m.points[a]) + f(p) + f(q) + f(r));
            }
        }
        let expr = Expr::parse("1 + 2*x - 3*y").unwrap();
        for degree in [2, 5] {
            let l = load(&m, &expr, Quadrature { degree }).unwrap();
            for (a, (l, e)) in l.iter().zip(&exact).enumerate() {
                close(*l, *e, 1e-15, &format!("(f, φ_{a}) with degree {degree}"));
            }
        }
    }
}
