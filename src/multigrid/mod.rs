//! Geometric multigrid for the Dirichlet P1 Laplacian on a hierarchy of meshes, as the
//! preconditioner of conjugate gradients: for K (the Poisson problem of v) and for
//! K_FF, the Laplacian on the free unknowns of the obstacle problem with the held (active) ones
//! fixed at zero (the linear solve of each primal–dual active-set step).
//!
//! ## Why
//! Sparse Cholesky costs O(n^1.5) time and O(n log n) memory on a 2-D mesh; a multigrid V-cycle
//! costs O(n) and reduces the error by a factor bounded away from 1 independently of h
//! (Hackbusch, *Multi-Grid Methods and Applications*, 1985, ch. 10; Bramble–Pasciak–Xu, *Math.
//! Comp.* 55, 1990, for V-cycles on nested P1 spaces without full regularity, e.g. the L-shape).
//! As the preconditioner of CG (the V-cycle is symmetric positive definite) the iterations to a
//! fixed reduction of the error are bounded independently of h, and CG's optimality makes them
//! fewer than the stationary iteration's.
//!
//! ## The V-cycle
//! Levels 0 (the mesh solved on) … L (the coarsest); `P_l` interpolates P1 functions of level
//! l + 1 onto level l (the [`Prolongation`] that nested iteration uses too). Everything works on
//! all vertices of each level, in the meshes' own numbering, with the boundary vertices skipped
//! like held ones (corrections vanish on ∂ω): level 0's operator is the problem's K itself, no
//! copy; the coarser ones are Galerkin products A_{l+1} = P_lᵀ A_l P_l. On nested P1 meshes
//! P_l is exact (every coarse hat function is a combination of fine ones), so the Galerkin
//! operator *is* the coarse stiffness matrix (rediscretisation; `galerkin_equals_rediscretisation`
//! checks it to round-off), and on meshes that are not nested (the coarse generated levels below a
//! disk) it is still the variational choice, which keeps the coarse correction an energy
//! projection. Galerkin products are also what truncation (below) needs. The coarsest level is
//! solved by sparse Cholesky ([`crate::linear::Cholesky`]).
//!
//! Smoothing: one forward Gauss–Seidel sweep before the coarse correction and one backward sweep
//! after (V(1,1)), so that the cycle is symmetric. Two sweeps each side, V(2,2), contract more
//! but cost more than they save under CG (measured, docs/performance.md). Each sweep is one pass
//! over the matrix: the forward sweep starts from zero and reads
//! each row up to its diagonal only, scattering the residual for the restriction as it goes; the
//! backward sweep also yields K z, so that CG needs no product of its own (K p = K z + β K p_old).
//! The sweeps work in blocks of about [`BLOCK_ROWS`] rows (hybrid Gauss–Seidel,
//! `smoother`), swept in parallel; the transfers (by the rows of P and of Pᵀ) and CG's
//! vector updates ([`crate::cg`]) run in parallel by rows too. The sweeps are bound by memory
//! traffic, and each core brings its own.
//!
//! ## The parts
//! As in a multigrid composed from its parts: the transfers ([`Prolongation`], with Pᵀ), the
//! truncated Galerkin operators (`galerkin`), the smoother (`smoother`), the coarsest
//! solve and the V-cycle (`cycle`), and CG ([`crate::cg::conjugate_gradients`]) preconditioned
//! by the cycle. [`Hierarchy`] makes the cycle of a held set.
//!
//! ## Truncation (the obstacle problem's K_FF)
//! The held unknowns are Dirichlet values on level 0: smoothing skips them, residuals there are
//! zero, and the interpolated corrections are cut off there. The coarse spaces are spanned by the
//! *truncated* coarse basis functions: P̃_0 = D_F P_0 E, with D_F zeroing the rows of held
//! unknowns, and the coarse operators are recomputed as Galerkin products Ã_1 = P̃_0ᵀ K P̃_0,
//! Ã_{l+1} = P̃_lᵀ Ã_l P̃_l for every held set (Kornhuber, *Numer. Math.* 69, 1994, monotone
//! multigrid; Gräser–Kornhuber, *J. Comput. Math.* 27, 2009, and truncated nonsmooth Newton
//! multigrid, DD XVIII, 2009). Then every coarse space is a subspace of the free space and the
//! coarse correction is the energy projection onto it: the cycle is a symmetric positive definite
//! preconditioner of K_FF. E keeps the coarse unknowns that give some live finer unknown a weight
//! above 1/2 — on nested meshes, the coarse vertices that are free fine vertices (the function `kept`):
//! this keeps P̃ of full rank, so that the coarse operators stay definite and the coarsest can be
//! factorized. The alternative of truncating the transfers but keeping the coarse operators of K
//! (no recomputation) is not variational, and its CG iterations grew with every refinement
//! (README). A hierarchy [`with_base`](Hierarchy::with_base) keeps the operators with the boundary
//! alone skipped (v's): those of a held set differ from them only in the coarse rows whose terms
//! reach a held fine unknown, and only those are computed again (the same numbers as a full
//! product).

mod cycle;
mod galerkin;
mod smoother;

pub use crate::cg::{NotConverged, Tolerance};
pub use cycle::Multigrid;
pub use smoother::{BLOCK_ROWS, INTERFACE_SHARE};

use crate::assembly::Stiffness;
use crate::linear::NotPositiveDefinite;
use crate::mesh::Prolongation;
use crate::sparse::Csr;
use cycle::Operators;
use galerkin::{dirty_rows, galerkin, kept};
use smoother::{Blocks, Level};
use std::borrow::Cow;
use std::sync::OnceLock;

/// Gauss–Seidel sweeps before and after the coarse correction (forward, backward, … before; the
/// reverse after, so that the cycle is symmetric).
const SWEEPS: usize = 1;

/// The multigrid hierarchy below one mesh: its stiffness matrix K and the interpolations below it,
/// all in the vertex numbering of their meshes. [`Hierarchy::preconditioner`] makes the V-cycle
/// for a set of skipped (boundary and held) vertices.
#[derive(Clone)]
pub struct Hierarchy<'h> {
    fine: &'h Csr,
    mass: &'h [f64],
    p: &'h [Prolongation],
    block_rows: usize,
    interface_share: f64,
    /// The boundary, and the coarse operators with it alone skipped (v's), made once when first
    /// needed, each with the coarse unknowns it skips.
    base: Option<(Vec<bool>, OnceLock<BaseLevels>)>,
    /// With a base: the blocks of the finest level's smoother, made once.
    fine_blocks: OnceLock<Blocks>,
}

/// The coarse operators of a set of skipped unknowns, each with the coarse unknowns it skips.
type BaseLevels = Vec<(Csr, Vec<bool>)>;

impl<'h> Hierarchy<'h> {
    /// The hierarchy of the mesh of stiffness matrix `k` and masses m_a = ∫φ_a `mass` (which
    /// weigh CG's residual), with `p[l]` interpolating from level l + 1 onto level l (level 0:
    /// this mesh).
    pub fn new(k: &'h Stiffness, mass: &'h [f64], p: &'h [Prolongation]) -> Self {
        assert!(
            mass.len() == k.n() && mass.iter().all(|&m| m > 0.0),
            "a mass m_a > 0 at every vertex"
        );
        if let Some(p0) = p.first() {
            assert_eq!(
                p0.matrix().rows(),
                k.n(),
                "the first interpolation is onto this mesh"
            );
        }
        Hierarchy {
            fine: k.matrix(),
            mass,
            p,
            block_rows: BLOCK_ROWS,
            interface_share: INTERFACE_SHARE,
            base: None,
            fine_blocks: OnceLock::new(),
        }
    }

    /// Keeps the coarse operators with only the `boundary` skipped (v's): those of a held set
    /// (w's) are then computed again only near it, in the rows whose terms the held set changes,
    /// and v's borrow them. A hierarchy used for one or two sets of skipped unknowns does without
    /// (the kept operators would cost memory for no time).
    pub fn with_base(self, boundary: Vec<bool>) -> Self {
        Hierarchy {
            base: Some((boundary, OnceLock::new())),
            ..self
        }
    }

    /// Smooths the levels in blocks of about `rows` rows (see [`BLOCK_ROWS`]), however many of
    /// them couple across.
    pub fn with_block_rows(self, rows: usize) -> Self {
        Hierarchy {
            block_rows: rows,
            interface_share: 1.0,
            ..self
        }
    }

    /// The number of levels.
    pub fn levels(&self) -> usize {
        self.p.len() + 1
    }

    /// The V-cycle for K_FF, F the vertices not `skip`ped (the boundary vertices and the held
    /// ones): the truncated coarse operators (Galerkin products) and the Cholesky factorization
    /// of the coarsest one.
    pub fn preconditioner(&self, skip: Vec<bool>) -> Result<Multigrid<'_>, NotPositiveDefinite> {
        assert_eq!(skip.len(), self.fine.rows());
        let blocks = |a: &Csr| Blocks::new(a, self.block_rows, self.interface_share);
        let (operators, fine_blocks) = match &self.base {
            None => {
                let full = self.full(skip.clone()).into_iter();
                (full.map(|(a, s)| (Cow::Owned(a), s)).collect(), blocks(self.fine))
            }
            Some((boundary, base)) => {
                let base = base.get_or_init(|| self.full(boundary.clone()));
                let fine_blocks = self.fine_blocks.get_or_init(|| blocks(self.fine)).clone();
                (self.near_base(&skip, boundary, base), fine_blocks)
            }
        };
        let fine = Level {
            a: Cow::Borrowed(self.fine),
            skip,
            blocks: fine_blocks,
        };
        let coarse = operators.into_iter().map(|(a, skip)| Level {
            blocks: blocks(&a),
            a,
            skip,
        });
        Multigrid::new(Operators {
            levels: std::iter::once(fine).chain(coarse).collect(),
            p: self.p,
            mass: self.mass,
            sweeps: SWEEPS,
        })
    }

    /// The coarse operators for `skip` from the `base` ones (those of the `boundary` alone),
    /// each with the coarse unknowns it skips: the base's own where nothing differs from it,
    /// else its rows but where the held set changes them ([`dirty_rows`]), computed again.
    fn near_base<'b>(
        &'b self,
        skip: &[bool],
        boundary: &[bool],
        base: &'b BaseLevels,
    ) -> Vec<(Cow<'b, Csr>, Vec<bool>)> {
        // The finer level's rows that may differ from the base's, and its live unknowns.
        let mut dirty: Vec<bool> = skip.iter().zip(boundary).map(|(s, b)| s != b).collect();
        let mut alive: Vec<bool> = skip.iter().map(|&s| !s).collect();
        let mut out: Vec<(Cow<'b, Csr>, Vec<bool>)> = Vec::with_capacity(self.p.len());
        for (l, (p, (b, b_skip))) in self.p.iter().zip(base).enumerate() {
            let kept = kept(p.transposed(), &alive);
            let p = p.matrix();
            let same = !dirty.iter().any(|&d| d) && kept.iter().zip(b_skip).all(|(&k, &s)| k != s);
            let a = if same {
                // The base's skipped set (v's): its operators themselves.
                dirty = vec![false; kept.len()];
                Cow::Borrowed(b)
            } else {
                let (finer, finer_base) = match l {
                    0 => (self.fine, self.fine),
                    _ => (&*out[l - 1].0, &base[l - 1].0),
                };
                let pt = self.p[l].transposed();
                dirty = dirty_rows(finer_base, p, pt, &dirty, &kept, b_skip);
                Cow::Owned(galerkin(finer, p, pt, &alive, &kept, Some((b, &dirty))))
            };
            out.push((a, kept.iter().map(|&k| !k).collect()));
            alive = kept;
        }
        out
    }

    /// The coarse operators for `skip` built in full, each with the coarse unknowns it skips.
    fn full(&self, mut skip: Vec<bool>) -> BaseLevels {
        let mut out: BaseLevels = Vec::with_capacity(self.p.len());
        for p in self.p {
            let (pt, p, finer) = (
                p.transposed(),
                p.matrix(),
                out.last().map_or(self.fine, |(c, _)| c),
            );
            let alive: Vec<bool> = skip.iter().map(|&s| !s).collect();
            let kept = kept(pt, &alive);
            let a = galerkin(finer, p, pt, &alive, &kept, None);
            skip = kept.iter().map(|&k| !k).collect();
            out.push((a, skip.clone()));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linear::InteriorSystem;
    use crate::mesh::{Diagonal, Mesh};

    fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    /// Meshes of n, n/2, … down to 4 cells per side, finest first, the interpolations between
    /// them, and K and the masses of the finest.
    struct Levels {
        meshes: Vec<Mesh>,
        prolongations: Vec<Prolongation>,
        k: Stiffness,
        mass: Vec<f64>,
    }

    impl Levels {
        fn hierarchy(&self) -> Hierarchy<'_> {
            Hierarchy::new(&self.k, &self.mass, &self.prolongations)
        }
    }

    /// [`Levels`] of the unit square.
    fn square(n: usize, diagonal: Diagonal) -> Levels {
        rectangle([1.0, 1.0], n, diagonal)
    }

    /// [`Levels`] of the rectangle (0, 0)–`corner`.
    fn rectangle(corner: [f64; 2], n: usize, diagonal: Diagonal) -> Levels {
        let meshes: Vec<Mesh> = std::iter::successors(Some(n), |&m| (m > 4).then_some(m / 2))
            .map(|m| Mesh::rectangle([0.0, 0.0], corner, m, m, diagonal).unwrap())
            // As the program numbers them: crossed meshes along a Z-order curve, so that the
            // smoother's blocks are parts of the square.
            .map(|m| {
                if diagonal == Diagonal::Crossed {
                    m.renumbered()
                } else {
                    m
                }
            })
            .collect();
        let prolongations = meshes
            .windows(2)
            .map(|w| Prolongation::new(&w[0], &w[1]))
            .collect();
        let (k, mass) = (
            Stiffness::assemble(&meshes[0]),
            crate::assembly::lumped_mass(&meshes[0]),
        );
        Levels {
            meshes,
            prolongations,
            k,
            mass,
        }
    }

    /// A deterministic pseudo-random vector in [−1, 1].
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    /// With nothing held, the coarse operators are the coarse meshes' stiffness matrices on their
    /// interior vertices (and empty rows on their boundary), on the unit square and on a rectangle
    /// of sides 0.3 and 0.7, where the couplings that vanish come out of the sums as round-off.
    #[test]
    fn galerkin_equals_rediscretisation() {
        let kinds = [Diagonal::Right, Diagonal::Left, Diagonal::Crossed];
        for (corner, diagonal) in [[1.0, 1.0], [0.3, 0.7]]
            .into_iter()
            .flat_map(|c| kinds.map(|d| (c, d)))
        {
            let levels = rectangle(corner, 16, diagonal);
            let (meshes, h) = (&levels.meshes, levels.hierarchy());
            let mg = h.preconditioner(meshes[0].on_boundary.clone()).unwrap();
            assert_eq!(mg.levels().len(), 3);
            for (level, a) in mg.levels()[1..].iter().map(|l| &*l.a).enumerate() {
                let mesh = &meshes[level + 1];
                let direct = Stiffness::assemble(mesh);
                assert_eq!(a.rows(), mesh.n_vertices());
                let interior = |i: usize| !mesh.on_boundary[i];
                // The same pattern: the couplings that vanish (across the diagonals of the
                // right-angled meshes) are left out as K leaves them out.
                let entries = (0..a.rows())
                    .filter(|&i| interior(i))
                    .map(|i| direct.row(i).filter(|&(j, _)| interior(j)).count())
                    .sum::<usize>();
                assert_eq!(a.nnz(), entries, "{diagonal:?} level {level}");
                for i in 0..a.rows() {
                    for j in 0..a.rows() {
                        let expected = if interior(i) && interior(j) {
                            direct.matrix().get(i, j)
                        } else {
                            0.0
                        };
                        let d = (a.get(i, j) - expected).abs();
                        assert!(d < 1e-13, "{diagonal:?} level {level} ({i}, {j}): {d}");
                    }
                }
            }
        }
    }

    /// With a base (the operators with the boundary alone skipped), the truncated coarse operators
    /// of a held set are the base's rows away from it and recomputed rows near it: the same
    /// numbers as computed in full, on nested squares and on the disk's hierarchy (whose coarsest
    /// levels are not nested); with the boundary alone skipped, they are the base's own.
    #[test]
    fn operators_recomputed_near_the_held_set_equal_the_full_ones() {
        let disk = crate::case::Case::read(std::path::Path::new("data/cases/disk_contact.toml")).unwrap();
        let (mesh, coarser) = disk.hierarchy(true, Default::default()).unwrap();
        let meshes: Vec<Mesh> = std::iter::once(mesh).chain(coarser).collect();
        let disk = Levels {
            k: Stiffness::assemble(&meshes[0]),
            mass: crate::assembly::lumped_mass(&meshes[0]),
            prolongations: meshes
                .windows(2)
                .map(|w| Prolongation::new(&w[0], &w[1]))
                .collect(),
            meshes,
        };
        for levels in [square(32, Diagonal::Right), square(32, Diagonal::Crossed), disk] {
            let mesh = &levels.meshes[0];
            let boundary = mesh.on_boundary.clone();
            let system = InteriorSystem::numbering(&boundary);
            let scattered: Vec<bool> = noise(system.n(), 4).iter().map(|&v| v > 0.3).collect();
            let (full, based) = (levels.hierarchy(), levels.hierarchy().with_base(boundary.clone()));
            for held in [vec![false; system.n()], held_disk(mesh, &system), scattered] {
                let skip = system.skipped(&held);
                let (a, b) = (
                    full.preconditioner(skip.clone()).unwrap(),
                    based.preconditioner(skip.clone()).unwrap(),
                );
                assert!(a.levels().len() >= 3);
                let mut recomputed = 0;
                for (a, b) in (a.levels()[1..].iter().map(|l| &l.a)).zip(b.levels()[1..].iter().map(|l| &l.a))
                {
                    assert_eq!((&a.row_ptr, &a.col, &a.val), (&b.row_ptr, &b.col, &b.val));
                    recomputed += matches!(b, Cow::Owned(_)) as usize;
                }
                let nothing_held = held.iter().all(|&h| !h);
                assert_eq!(recomputed == 0, nothing_held, "{recomputed} levels recomputed");
                let mut levels = (a.levels().iter()).zip(b.levels());
                assert!(levels.all(|(a, b)| a.skip == b.skip));
            }
        }
    }

    /// Below a held disk of radius 0.3 on the square, the coarse rows computed again are the held
    /// ones (empty rows) and a band around the disk's edge: far fewer than all.
    #[test]
    fn only_rows_near_the_held_set_are_computed_again() {
        let levels = square(64, Diagonal::Right);
        let boundary = levels.meshes[0].on_boundary.clone();
        let h = levels.hierarchy().with_base(boundary.clone());
        let skip = skip_boundary_and_disk(&levels);
        h.preconditioner(skip.clone()).unwrap();
        let (b1, skip1) = &h.base.as_ref().unwrap().1.get().unwrap()[0];
        let p = levels.prolongations[0].matrix();
        let alive: Vec<bool> = skip.iter().map(|&s| !s).collect();
        let held: Vec<bool> = skip.iter().zip(&boundary).map(|(s, b)| s != b).collect();
        let dirty = dirty_rows(
            levels.k.matrix(),
            p,
            &p.transpose(),
            &held,
            &kept(&p.transpose(), &alive),
            skip1,
        );
        let (count, rows) = (dirty.iter().filter(|&&d| d).count(), b1.rows());
        // The disk covers 28 % of the square; its edge's band a few coarse rows more.
        assert!(count < rows / 2, "{count} of {rows} rows computed again");
    }

    /// The energy-norm contraction of the stationary iteration x ← x + B(b − K x), measured
    /// from a random error after `cycles` cycles (the asymptotic rate).
    fn contraction(mg: &mut Multigrid, cycles: usize) -> f64 {
        let n = mg.n();
        let mut e: Vec<f64> = noise(n, 7);
        for (i, e) in e.iter_mut().enumerate() {
            if mg.held(i) {
                *e = 0.0;
            }
        }
        let energy = |mg: &Multigrid, e: &[f64]| {
            let mut ke = vec![0.0; n];
            mg.apply(e, &mut ke);
            dot(e, &ke).sqrt()
        };
        let (mut ke, mut z) = (vec![0.0; n], vec![0.0; n]);
        let mut rate = 0.0;
        for _ in 0..cycles {
            let before = energy(mg, &e);
            mg.apply(&e, &mut ke);
            let r: Vec<f64> = ke.iter().map(|v| -v).collect();
            mg.precondition(&r, &mut z);
            for (e, z) in e.iter_mut().zip(&z) {
                *e += z;
            }
            rate = energy(mg, &e) / before;
        }
        rate
    }

    /// On the unit square (n = 32, 64, 128 cells down to 4): the asymptotic energy-norm
    /// contraction of the stationary V-cycle iteration is ≤ 0.2 with two Gauss–Seidel sweeps on
    /// each side, V(2,2), and ≤ 0.4 with one, V(1,1) (the default: it makes CG faster, see the
    /// module's documentation); CG preconditioned by V(1,1) reduces the residual by ≤ 0.2 per
    /// iteration; none of them grows with 1/h.
    #[test]
    fn v_cycle_convergence_factors_on_the_square() {
        for diagonal in [Diagonal::Right, Diagonal::Crossed] {
            let mut rates: Vec<[f64; 3]> = Vec::new();
            for n in [32, 64, 128] {
                let levels = square(n, diagonal);
                let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
                let mut mg = h.preconditioner(meshes[0].on_boundary.clone()).unwrap();
                let v11 = contraction(&mut mg, 12);
                mg.set_sweeps(2);
                let v22 = contraction(&mut mg, 12);
                mg.set_sweeps(1);
                let b = noise(k.n(), 5);
                let mut x = vec![0.0; k.n()];
                let iterations = mg.solve(b, &mut x, 1e-10, 100).unwrap();
                let cg = 1e-10_f64.powf(1.0 / iterations as f64);
                rates.push([v22, v11, cg]);
            }
            let worst = |k: usize| rates.iter().map(|r| r[k]).fold(0.0, f64::max);
            assert!(
                worst(0) <= 0.2 && worst(1) <= 0.4 && worst(2) <= 0.2,
                "{diagonal:?}: {rates:?}"
            );
            for k in 0..3 {
                assert!(
                    rates[2][k] <= rates[0][k] + 0.03,
                    "{diagonal:?} grows with 1/h: {rates:?}"
                );
            }
        }
    }

    /// A held disk of radius 0.3 about (0.45, 0.52) on the unknowns of `mesh`.
    fn held_disk(mesh: &Mesh, system: &InteriorSystem) -> Vec<bool> {
        (system.vertices.iter())
            .map(|&a| {
                let p = mesh.points[a];
                (p[0] - 0.45).hypot(p[1] - 0.52) < 0.3
            })
            .collect()
    }

    /// The finest level's boundary and [`held_disk`], skipped.
    fn skip_boundary_and_disk(levels: &Levels) -> Vec<bool> {
        let mesh = &levels.meshes[0];
        let system = InteriorSystem::numbering(&mesh.on_boundary);
        system.skipped(&held_disk(mesh, &system))
    }

    /// The V-cycle is symmetric positive definite, with one block per level and with blocks of
    /// 64 rows (the hybrid smoother).
    #[test]
    fn the_v_cycle_is_symmetric() {
        let levels = square(32, Diagonal::Left);
        let (k, skip) = (&levels.k, skip_boundary_and_disk(&levels));
        for block_rows in [usize::MAX, 64] {
            let h = levels.hierarchy().with_block_rows(block_rows);
            let mut mg = h.preconditioner(skip.clone()).unwrap();
            let n = k.n();
            let (mut u, mut v) = (noise(n, 1), noise(n, 2));
            for i in 0..n {
                if skip[i] {
                    u[i] = 0.0;
                    v[i] = 0.0;
                }
            }
            let (mut bu, mut bv) = (vec![0.0; n], vec![0.0; n]);
            mg.precondition(&u, &mut bu);
            mg.precondition(&v, &mut bv);
            let (a, b) = (dot(&v, &bu), dot(&u, &bv));
            assert!((a - b).abs() < 1e-12 * a.abs().max(b.abs()), "{a} vs {b}");
            assert!(dot(&u, &bu) > 0.0 && dot(&v, &bv) > 0.0);
        }
    }

    /// Blocks of 64 rows split the levels of the square along lines of the mesh; swept on 1, 2,
    /// 3 or 8 threads, CG computes the same numbers.
    #[test]
    fn blocks_on_any_number_of_threads_give_the_same_numbers() {
        let levels = square(64, Diagonal::Right);
        let (k, skip) = (&levels.k, skip_boundary_and_disk(&levels));
        let h = levels.hierarchy().with_block_rows(64);
        let mut results = Vec::new();
        for threads in [1, 2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            results.push(pool.install(|| {
                let mut mg = h.preconditioner(skip.clone()).unwrap();
                let blocks = mg.fine_blocks();
                assert_eq!(blocks.starts.len(), k.n() / 64);
                // Rows numbered by rows of the mesh: about one mesh line of rows coupled across
                // each cut, on both sides.
                let cuts = blocks.starts.len() - 1;
                assert!(
                    (cuts * 64..=cuts * 2 * 65).contains(&blocks.interface.len()),
                    "{}",
                    blocks.interface.len()
                );
                let mut x = vec![0.0; k.n()];
                let iterations = mg.solve(noise(k.n(), 3), &mut x, 1e-12, 100).unwrap();
                (iterations, x.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
            }));
        }
        assert!(results.iter().all(|r| *r == results[0]));
    }

    /// Blocks of 65 rows on the 65 × 65 grid numbered by rows are strips of one grid line, all
    /// of whose rows couple across: they grow (doubling) until at most 1/8 do, 16 lines or more.
    #[test]
    fn blocks_grow_until_few_rows_couple_across() {
        let levels = square(64, Diagonal::Right);
        let blocks = Blocks::new(levels.k.matrix(), 65, INTERFACE_SHARE);
        let share = blocks.interface.len() as f64 / levels.k.n() as f64;
        assert!(share <= INTERFACE_SHARE, "{share}");
        let rows = blocks.starts[1] - blocks.starts[0];
        assert!((16 * 65..4 * 16 * 65).contains(&rows), "{rows} rows per block");
        let fixed = Blocks::new(levels.k.matrix(), 65, 1.0);
        assert_eq!(fixed.starts.len(), 65);
    }

    /// One free fine vertex amid held ones, the midpoint of a coarse edge: both coarse hat
    /// functions of the edge truncate to half its fine hat function. Keeping them both would make
    /// the coarse matrix singular; the rule keeps neither, and CG solves the 1 × 1 system.
    #[test]
    fn a_lone_free_midpoint_keeps_no_coarse_unknown() {
        let levels = square(8, Diagonal::Right);
        let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
        let midpoint = (meshes[0].points.iter())
            .position(|&p| p == [0.375, 0.5])
            .unwrap();
        let skip: Vec<bool> = (0..k.n()).map(|i| i != midpoint).collect();
        let alive: Vec<bool> = skip.iter().map(|&h| !h).collect();
        let p = levels.prolongations[0].matrix();
        assert_eq!(p.row(midpoint).1, &[0.5, 0.5], "the midpoint of a coarse edge");
        let mut mg = h.preconditioner(skip).unwrap();
        let b = vec![1.0; k.n()];
        let mut x = vec![0.0; k.n()];
        assert_eq!(mg.solve(b, &mut x, 1e-12, 10), Ok(1));
        assert!((x[midpoint] - 1.0 / k.diagonal(midpoint)).abs() < 1e-15);
        assert!(kept(&p.transpose(), &alive).iter().all(|&k| !k));
    }

    /// CG returns x = 0 at once for b = 0 (whatever the start), and does not stop on a NaN.
    #[test]
    fn cg_on_a_zero_or_nan_right_hand_side() {
        let levels = square(8, Diagonal::Right);
        let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
        let mut mg = h.preconditioner(meshes[0].on_boundary.clone()).unwrap();
        let mut x = noise(k.n(), 1);
        assert_eq!(mg.solve(vec![0.0; k.n()], &mut x, 1e-13, 10), Ok(0));
        assert!(x.iter().all(|&x| x == 0.0));
        let mut b = vec![1.0; k.n()];
        let inside = meshes[0].on_boundary.iter().position(|&e| !e).unwrap();
        b[inside] = f64::NAN;
        assert!(mg.solve(b, &mut x, 1e-13, 10).is_err());
    }

    #[test]
    fn truncated_cg_reaches_the_cholesky_solution_in_few_iterations() {
        let mut iterations = Vec::new();
        for n in [32, 64, 128, 256] {
            let levels = square(n, Diagonal::Right);
            let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
            let system = InteriorSystem::new(k, &meshes[0].on_boundary);
            let held = held_disk(&meshes[0], &system);
            let b: Vec<f64> = noise(system.n(), 3).iter().map(|v| 1.0 + v).collect();
            let mut factor = system.factorization();
            // Also a scattered held set, with free vertices amid held ones: the truncated coarse
            // basis functions of two coarse vertices can reduce to one fine hat function there.
            let scattered = noise(system.n(), 4).iter().map(|&v| v > -0.6).collect();
            for held in [vec![false; system.n()], held, scattered] {
                factor.factorize(&held).unwrap();
                let mut direct = b.clone();
                factor.solve(&mut direct);
                // The blocks of the program, and blocks of 2048 rows (8 lines of the mesh at n = 256).
                for h in [h.clone(), h.clone().with_block_rows(2048)] {
                    let mut mg = h.preconditioner(system.skipped(&held)).unwrap();
                    let mut x = vec![0.0; k.n()];
                    iterations.push(mg.solve(system.extended(&b), &mut x, 1e-12, 100).unwrap());
                    let x = system.gather(&x);
                    let scale = direct.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                    let error = x
                        .iter()
                        .zip(&direct)
                        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
                    assert!(error <= 1e-10 * scale, "n = {n}: {error} / {scale}");
                    assert!(x.iter().zip(&held).all(|(x, &h)| !h || *x == 0.0));
                }
            }
        }
        assert!(iterations.iter().all(|&i| i <= 15), "{iterations:?}");
    }
}
