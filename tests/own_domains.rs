//! A user's own domains: polygons of any number of vertices, with holes, and file meshes get
//! coarser levels for nested iteration and multigrid that end by construction, and they solve.

use membrane_contact::case::Case;
use membrane_contact::contact::Start;
use membrane_contact::mesh::{Domain, Mesh};
use membrane_contact::run::{self, Run};
use std::f64::consts::PI;
use std::path::PathBuf;
use std::time::Instant;

/// A small deterministic generator (xorshift), so that failures reproduce.
struct Random(u64);

impl Random {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A star-shaped ring of `n` vertices about `centre`, radii in [0.5, 1] × `radius` at jittered
/// angles: simple, and for n ≥ 16 it holds the disk of radius 0.47 × `radius`.
fn star(random: &mut Random, n: usize, centre: [f64; 2], radius: f64) -> Vec<[f64; 2]> {
    (0..n)
        .map(|k| {
            let t = 2.0 * PI * (k as f64 + 0.5 * random.next()) / n as f64;
            let r = radius * (0.5 + 0.5 * random.next());
            [centre[0] + r * t.cos(), centre[1] + r * t.sin()]
        })
        .collect()
}

fn toml_ring(ring: &[[f64; 2]]) -> String {
    let points: Vec<String> = ring.iter().map(|p| format!("[{:e}, {:e}]", p[0], p[1])).collect();
    format!("[{}]", points.join(", "))
}

fn polygon_case(boundary: &[[f64; 2]], holes: &[Vec<[f64; 2]>], h: f64) -> Case {
    let holes: Vec<String> = holes.iter().map(|h| toml_ring(h)).collect();
    let text = format!(
        "mu1 = 1.0\nmu2 = 1.0\nf1 = -10\nf2 = 0\ng = 0.05\n[mesh]\nkind = \"polygon\"\n\
         boundary = {}\nholes = [{}]\nh = {h}\n",
        toml_ring(boundary),
        holes.join(", ")
    );
    Case::parse(&text, "polygon case", PathBuf::new()).unwrap()
}

fn solve(case: &Case) -> Run<'_> {
    let options = run::Options {
        start: Start::Nested,
        hminus1: false,
        flux: false,
        estimate: false,
        dual: false,
    };
    run::run(case, &options).unwrap()
}

/// Each coarser level has at most half the vertices of the one above it.
fn assert_halving(mesh: &Mesh, coarser: &[Mesh]) {
    let mut above = mesh.n_vertices();
    for level in coarser {
        assert!(
            2 * level.n_vertices() <= above,
            "{} below {above}",
            level.n_vertices()
        );
        above = level.n_vertices();
    }
}

#[test]
fn polygons_with_many_vertices_solve_on_coarser_levels() {
    // The domains of the report: a regular 24-gon, an 18-vertex stadium, a rectangle with a
    // 17-gon hole (each hung before: its vertices kept every coarser mesh above the minimum).
    let ngon = |n: usize, c: [f64; 2], r: f64| -> Vec<[f64; 2]> {
        (0..n)
            .map(|k| {
                let t = 2.0 * PI * k as f64 / n as f64;
                [c[0] + r * t.cos(), c[1] + r * t.sin()]
            })
            .collect()
    };
    let mut stadium: Vec<[f64; 2]> = (0..9)
        .map(|k| {
            let t = -PI / 2.0 + PI * k as f64 / 8.0;
            [1.0 + 0.5 * t.cos(), 0.5 * t.sin()]
        })
        .collect();
    stadium.extend(stadium.clone().iter().map(|p| [-p[0], -p[1]]));
    let rectangle = vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    for (boundary, holes, h) in [
        (ngon(24, [0.0, 0.0], 1.0), vec![], 0.1),
        (stadium, vec![], 0.05),
        (rectangle, vec![ngon(17, [0.0, 0.0], 0.3)], 0.05),
    ] {
        let case = polygon_case(&boundary, &holes, h);
        let (mesh, coarser) = case.hierarchy(true, Default::default()).unwrap();
        assert!(
            !coarser.is_empty(),
            "no coarser levels below {} vertices",
            mesh.n_vertices()
        );
        assert_halving(&mesh, &coarser);
        // Membrane 1, pushed down, touches membrane 2.
        let r = solve(&case);
        assert!(r.action.total > 0.0 && r.action.contact_area > 0.0);
        let s = &r.solution.obstacle.stats;
        assert!(s.iterations <= 4, "{} active-set iterations", s.iterations);
    }
}

#[test]
fn random_polygons_with_holes_mesh_in_bounded_time() {
    let mut random = Random(0x2545_f491_4f6c_dd1d);
    for (k, n) in [3, 4, 7, 16, 17, 31, 64, 200, 700, 2000].into_iter().enumerate() {
        let boundary = star(&mut random, n, [10.0 * k as f64, -3.0], 1.0);
        // Holes on a ring inside the star's inner radius 1/2: apart and inside.
        let holes: Vec<Vec<[f64; 2]>> = (0..if n >= 16 { k % 4 } else { 0 })
            .map(|j| {
                let t = 2.0 * PI * j as f64 / 3.0;
                let c = [10.0 * k as f64 + 0.25 * t.cos(), -3.0 + 0.25 * t.sin()];
                star(&mut random, 3 + (n / 3) % 40, c, 0.08)
            })
            .collect();
        let h = 0.05;
        let case = polygon_case(&boundary, &holes, h);
        let clock = Instant::now();
        let (mesh, coarser) = case.hierarchy(true, Default::default()).unwrap();
        assert_halving(&mesh, &coarser);
        // Far below a hang: the fine mesh has a few thousand vertices.
        assert!(
            clock.elapsed().as_secs_f64() < 20.0,
            "{n} vertices: {:?}",
            clock.elapsed()
        );
        let r = solve(&case);
        assert!(r.solution.obstacle.stats.iterations <= 6, "{n} vertices");
    }
}

#[test]
fn a_file_mesh_gets_the_coarser_levels_of_its_boundary() {
    // An annulus meshed fine, as from a file: its domain is its boundary polygon with a hole.
    let annulus = Domain::Disk {
        centre: [0.5, 0.5],
        radius: 1.0,
        inner_radius: Some(0.3),
    };
    let fine = annulus.mesh(0.02).unwrap();
    let (domain, h) = Domain::of_mesh(&fine).unwrap();
    let Domain::Polygon { boundary, holes } = &domain else {
        panic!("a polygon")
    };
    let boundary_vertices = fine.on_boundary.iter().filter(|&&b| b).count();
    assert_eq!(holes.len(), 1);
    assert_eq!(boundary.len() + holes[0].len(), boundary_vertices);
    assert!((domain.area() - fine.measure()).abs() < 1e-12 * fine.measure());
    assert!((0.015..0.03).contains(&h), "{h}");
    // Coarsened, the rings keep their shape within a fraction of the size.
    let Domain::Polygon {
        boundary: coarse,
        holes: coarse_holes,
    } = domain.coarsened(0.32)
    else {
        panic!("a polygon")
    };
    assert!(
        coarse.len() < boundary.len() / 4 && coarse.len() >= 6,
        "{}",
        coarse.len()
    );
    assert!(coarse
        .iter()
        .all(|p| ((p[0] - 0.5).hypot(p[1] - 0.5) - 1.0).abs() < 1e-12));
    assert_eq!(coarse_holes.len(), 1);
}

#[test]
fn an_unrefined_file_mesh_takes_few_global_iterations() {
    // A disk of about 34 600 triangles (as the Gmsh disk of the report) written as a result, read
    // back as a file mesh.
    let dir = tempfile::tempdir().unwrap();
    let disk = "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-10*if(x < 0.2, 1, 0.3)\"\nf2 = 0\ng = 0.05\n\
                [mesh]\nkind = \"disk\"\nradius = 1.0\nh = 0.018\n";
    let case = Case::parse(disk, "disk", PathBuf::new()).unwrap();
    let options = run::Options {
        start: Start::Cold,
        hminus1: false,
        flux: false,
        estimate: false,
        dual: false,
    };
    let written = run::solve(&case, &options, &dir.path().join("disk")).unwrap();
    let triangles = written.problem.mesh.n_triangles();
    assert!((30_000..40_000).contains(&triangles), "{triangles}");
    let text = disk.replace(
        "kind = \"disk\"\nradius = 1.0\nh = 0.018",
        "kind = \"file\"\npath = \"disk/solution.h5\"",
    );
    let file = Case::parse(&text, "file", dir.path().to_path_buf()).unwrap();
    let (mesh, coarser) = file.hierarchy(true, Default::default()).unwrap();
    assert!(coarser.len() >= 3, "{} coarser levels", coarser.len());
    assert_halving(&mesh, &coarser);
    let r = solve(&file);
    let s = &r.solution.obstacle.stats;
    assert!(s.iterations <= 4, "{} global iterations", s.iterations);
    // Cholesky solves it: the levels, not nested in it, give the guess.
    assert_eq!(s.linear, membrane_contact::contact::LinearSolver::Direct);
    assert_eq!(s.coarse_iterations.len(), coarser.len());
    // The same solution as from the disk's own hierarchy, to the solvers' tolerance.
    let own = solve(&case);
    let diff = (r.solution.u1.iter().zip(&own.solution.u1)).fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff < 1e-10, "{diff}");
}

fn square_at(offset: f64, side: f64, h: f64) -> Case {
    let s = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
        .map(|p| [offset + side * p[0], offset + side * p[1]]);
    let text = format!(
        "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-10/{side:e}^2\"\nf2 = 0\ng = 0.05\n[mesh]\nkind = \"polygon\"\n\
         boundary = {}\nh = {h:e}\n",
        toml_ring(&s)
    );
    Case::parse(&text, "square", PathBuf::new()).unwrap()
}

#[test]
fn a_domain_far_from_the_origin_or_scaled_solves_the_same_or_is_refused() {
    let reference = square_at(0.0, 1.0, 0.1);
    let r0 = solve(&reference);
    // Moved (the mesh is made relative to the domain) or scaled by powers of two: the same mesh
    // and solution.
    for (offset, side) in [
        (1.0, 1.0),
        (1e3, 1.0),
        (1e6, 1.0),
        (1e9, 1.0),
        (0.0, 2f64.powi(-333)),
        (0.0, 2f64.powi(333)),
    ] {
        let case = square_at(offset * side, side, 0.1 * side);
        let r = solve(&case);
        let (m, m0) = (&r.problem.mesh, &r0.problem.mesh);
        assert_eq!(
            m.triangles().collect::<Vec<_>>(),
            m0.triangles().collect::<Vec<_>>(),
            "{offset:e}"
        );
        let far = m.points.iter().zip(&m0.points).fold(0.0_f64, |d, (p, q)| {
            d.max(
                (p[0] - offset * side - side * q[0])
                    .abs()
                    .max((p[1] - offset * side - side * q[1]).abs()),
            )
        });
        assert!(far <= 1e-6 * side, "{offset:e} {side:e}: {far:e}");
        assert_eq!(
            r.solution.obstacle.contact, r0.solution.obstacle.contact,
            "{offset:e} {side:e}"
        );
        let du = (r.solution.u1.iter().zip(&r0.solution.u1)).fold(0.0_f64, |d, (a, b)| d.max((a - b).abs()));
        // Interior vertices far out are rounded to f64's resolution there, ε |offset|.
        let resolution = f64::EPSILON * offset / 0.1;
        assert!(du < 1e-10 + 10.0 * resolution, "{offset:e} {side:e}: {du:e}");
    }
    // Where double precision cannot resolve h (spade panicked at 1e15; 1e14 was refused with
    // 4.4e14 vertices from a shoelace about the origin): a refusal that says why.
    for offset in [1e12, 1e14, 1e15] {
        let e = square_at(offset, 1.0, 0.1)
            .hierarchy(true, Default::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("too small for coordinates as large as"), "{e}");
    }
    let far = Domain::Polygon {
        boundary: vec![
            [1e14, 1e14],
            [1e14 + 1.0, 1e14],
            [1e14 + 1.0, 1e14 + 1.0],
            [1e14, 1e14 + 1.0],
        ],
        holes: vec![],
    };
    assert_eq!(far.area(), 1.0);
}

#[test]
fn the_memory_guard_of_domains_runs_before_any_allocation() {
    // h = 1e-9 on a unit disk or a polygon: the boundary alone would hold about 6e9 points.
    for kind in [
        "kind = \"disk\"\nradius = 1.0",
        "kind = \"polygon\"\nboundary = [[0, 0], [3, 0], [0, 2]]",
    ] {
        let text = format!("mu1 = 1.0\nmu2 = 1.0\nf1 = -1\nf2 = 0\ng = 0\n[mesh]\n{kind}\nh = 1e-9\n");
        let case = Case::parse(&text, "tiny h", PathBuf::new()).unwrap();
        let clock = Instant::now();
        let e = case.hierarchy(true, Default::default()).unwrap_err().to_string();
        assert!(e.contains("of memory"), "{e}");
        assert!(clock.elapsed().as_secs_f64() < 1.0, "{:?}", clock.elapsed());
    }
}

#[test]
fn a_file_mesh_whose_boundary_touches_itself_has_no_domain() {
    // A grid with two cells cut out that meet at a corner: its boundary passes twice through that
    // vertex (two rings could be read from it in either order).
    let n = 8;
    let index = |i: usize, j: usize| j * (n + 1) + i;
    let points = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| [i as f64, j as f64]))
        .collect();
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            if (i, j) == (3, 3) || (i, j) == (4, 4) {
                continue;
            }
            let (a, b, c, d) = (index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    let mesh = Mesh::new(points, triangles).unwrap();
    assert!(Domain::of_mesh(&mesh).is_none());
}

#[test]
fn a_hole_the_simplification_would_cut_keeps_the_coarser_levels() {
    // A boundary bump narrower than the tolerance beside a hole that reaches into it: simplified,
    // the hole would cross the boundary, so the level is meshed from the polygon as it is.
    let boundary = [
        [0.0, 0.0],
        [2.0, 0.0],
        [2.0, 1.0],
        [1.2, 1.0],
        [1.2, 1.0009],
        [0.8, 1.0009],
        [0.8, 1.0],
        [0.0, 1.0],
    ];
    let hole = vec![[0.9, 0.99], [1.1, 0.99], [1.1, 1.0005], [0.9, 1.0005]];
    let case = polygon_case(&boundary, &[hole], 0.02);
    let (mesh, coarser) = case.hierarchy(true, Default::default()).unwrap();
    assert!(coarser.len() >= 2, "{} coarser levels", coarser.len());
    assert_halving(&mesh, &coarser);
}

#[test]
fn given_vertices_stay_as_given_and_refined_circles_stay_round_far_out() {
    // A polygon whose coordinates span more than a factor 2: meshed without moving it.
    let corners = [[0.12, 0.12], [1.2, 0.12], [1.2, 1.3], [0.12, 1.3]];
    let (mesh, _) = polygon_case(&corners, &[], 0.1)
        .hierarchy(false, Default::default())
        .unwrap();
    assert!(corners.iter().all(|c| mesh.points.contains(c)), "corners moved");
    // A disk at (1e7, 1e7), refined twice: new boundary vertices go onto the circle (its points
    // are rounded there by about 2e-9, more than the 1e-9 r tolerance of a point on it).
    let text = "mu1 = 1.0\nmu2 = 1.0\nf1 = -1\nf2 = 0\ng = 0\n[mesh]\nkind = \"disk\"\n\
                centre = [1e7, 1e7]\nradius = 1.0\nh = 0.05\nrefine = 2\n";
    let case = Case::parse(text, "far disk", PathBuf::new()).unwrap();
    let mesh = case.mesh().unwrap();
    let off = (0..mesh.n_vertices())
        .filter(|&a| mesh.on_boundary[a])
        .map(|a| ((mesh.points[a][0] - 1e7).hypot(mesh.points[a][1] - 1e7) - 1.0).abs())
        .fold(0.0_f64, f64::max);
    assert!(off < 1e-8, "{off:e}");
}

/// A long strip as a built-in rectangle (100 × 1, 2560 × 8 cells): its coarser levels keep its
/// proportion (they were square grids of 1280², 640², … cells, 70 times the strip's vertices, and
/// the smoother then failed), each at most half the one above with 2 cells across at least, and
/// multigrid gives Cholesky's solution; `--n` sets the longer side, the other in proportion.
#[test]
fn a_strip_keeps_its_proportion_on_every_level() {
    let text = "mu1 = 1.0\nmu2 = 2.0\nf1 = -10\nf2 = 2\ng = 0.1\n[mesh]\nkind = \"rectangle\"\n\
                corners = [[0.0, 0.0], [100.0, 1.0]]\nn = [2560, 8]\n";
    let mut case = Case::parse(text, "strip", PathBuf::new()).unwrap();
    let (mesh, coarser) = case.hierarchy(true, Default::default()).unwrap();
    assert_eq!(mesh.n_vertices(), 2561 * 9);
    assert_halving(&mesh, &coarser);
    assert_eq!(
        coarser.iter().map(Mesh::n_vertices).collect::<Vec<_>>(),
        [1281 * 5, 641 * 3]
    );
    let multigrid = solve(&case).solution.u1.clone();
    case.solver.linear = membrane_contact::contact::LinearSolver::Direct;
    let direct = solve(&case).solution.u1.clone();
    let diff = multigrid
        .iter()
        .zip(&direct)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(diff < 1e-12, "{diff}");
    case.set_cells(640).unwrap();
    assert_eq!(case.mesh().unwrap().n_vertices(), 641 * 3);
}

/// The README's example, as shipped (examples/plate: the Gmsh mesh of plate.geo, and the same
/// domain with a square hole as a polygon): both solve, on meshes of the plate's area, with
/// contact mostly on the left half, where membrane 1 is pressed down.
#[test]
fn the_readme_s_plate_solves_as_shipped() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/plate");
    let hole = [PI * 0.2 * 0.2, 0.4 * 0.4];
    for (file, hole) in [("plate.toml", hole[0]), ("poly.toml", hole[1])] {
        let case = Case::read(&dir.join(file)).unwrap();
        let r = solve(&case);
        let mesh = &r.problem.mesh;
        let area: f64 = (0..mesh.n_triangles()).map(|t| mesh.area(t)).sum();
        assert!((area - (2.0 - hole)).abs() < 2e-2 * hole, "{file}: area {area}");
        let contact = r
            .solution
            .obstacle
            .contact
            .iter()
            .enumerate()
            .filter(|&(_, &c)| c);
        let (touching, left) = contact.fold((0, 0), |(n, l), (a, _)| {
            (n + 1, l + usize::from(mesh.points[a][0] < 1.0))
        });
        assert!(
            touching > 0 && 5 * left >= 4 * touching,
            "{file}: {left} of {touching} in x < 1"
        );
    }
}

/// Disks far below the unit: their vertex count is estimated in units of h (the area π r² of a
/// radius of 1e-180 underflowed to 0, and 0/0 estimated 1e18 vertices), a radius of 1e-150 meshes
/// as the unit disk does, and where the triangles' areas leave the range of double precision the
/// refusal says so, with h in scientific notation (it was "the mesh overlaps itself" at 1e-160,
/// and h printed with 180 zeros).
#[test]
fn disks_far_below_the_unit_mesh_or_say_why_not() {
    let disk = |r: f64| {
        let text = format!(
            "mu1 = 1.0\nmu2 = 1.0\nf1 = -1\nf2 = 0\ng = 0\n[mesh]\nkind = \"disk\"\nradius = {r:e}\nh = {:e}\n",
            r / 10.0
        );
        Case::parse(&text, "disk", PathBuf::new()).unwrap()
    };
    // Radii scaled by powers of two, which the mesher's unit takes out exactly.
    let (unit, tiny) = (disk(1.0).mesh().unwrap(), 2f64.powi(-500));
    for r in [tiny, 2f64.powi(-600)] {
        let estimated = disk(r).estimated_vertices();
        assert!(
            (unit.n_vertices()..=2 * unit.n_vertices()).contains(&estimated),
            "{r:e}: {estimated}"
        );
    }
    let small = disk(tiny).mesh().unwrap();
    assert_eq!(
        small.triangles().collect::<Vec<_>>(),
        unit.triangles().collect::<Vec<_>>()
    );
    assert!((small.points.iter().zip(&unit.points)).all(|(p, q)| p.map(|x| x / tiny) == *q));
    for r in [2f64.powi(-530), 2f64.powi(-600)] {
        let e = disk(r).mesh().unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "h = {:e}: the areas of triangles of this size (about h²) lie outside",
                r / 10.0
            )),
            "{e}"
        );
    }
}

/// A rectangle (and its refinements) whose triangles' areas leave the range of double precision
/// is refused for that reason before it is built (it was "triangle 0 has zero area to round-off"
/// at a side of 1e-170), and one just inside it solves.
#[test]
fn rectangles_far_from_the_unit_say_why_not() {
    // The rectangle of the [mesh] keys `mesh`, meshed, or why not.
    let rectangle = |mesh: &str| {
        let text =
            format!("mu1 = 1.0\nmu2 = 1.0\nf1 = -1\nf2 = 0\ng = 0\n[mesh]\nkind = \"rectangle\"\n{mesh}\n");
        let mesh = Case::parse(&text, "rectangle", PathBuf::new()).unwrap().mesh();
        mesh.map(|m| m.n_vertices()).map_err(|e| e.to_string())
    };
    let square = |side: &str, refine: usize| {
        format!("corners = [[0.0, 0.0], [{side}, {side}]]\nn = [8, 8]\nrefine = {refine}")
    };
    let refusals = [
        (
            square("1e-170", 0),
            "the triangles' areas (about 1e-343) lie outside the range",
        ),
        (
            square("1e170", 0),
            "the triangles' areas (about 1e337) lie outside the range",
        ),
        (
            square("1e-150", 7),
            "the triangles' areas (about 1e-307) lie outside the range",
        ),
        (
            "corners = [[-1e300, 0.0], [1e300, 1.0]]\nn = [8, 8]".into(),
            "the square of the rectangle's diameter (about 1e600) lies outside the range",
        ),
        // Crossed diagonals cut a cell into four triangles, not two.
        (
            "corners = [[0.0, 0.0], [1.732e-153, 1.732e-153]]\nn = [1, 1]\ndiagonal = \"crossed\"".into(),
            "the triangles' areas (about 1e-307) lie outside the range",
        ),
    ];
    for (mesh, message) in refusals {
        match rectangle(&mesh) {
            Ok(n) => panic!("{mesh}: meshed, {n} vertices"),
            Err(e) => assert!(e.contains(message), "{mesh}: {e}"),
        }
    }
    for (side, refine) in [("1e-150", 3), ("1e150", 0)] {
        assert!(
            rectangle(&square(side, refine)).is_ok(),
            "{side}, refine {refine}"
        );
    }
}

/// A polygon moved by any translation that keeps its coordinates exact (here, across the axes,
/// where the first vertex's coordinates are not within a factor 2 of the others) gets the same
/// mesh, moved: it was meshed as given near the origin, so that moving a square of side 2 by
/// (−1, −1) gave 2970 vertices instead of 2983.
#[test]
fn a_polygon_moved_across_the_axes_keeps_its_mesh() {
    let ring = [
        [0.0, 0.0],
        [2.0, 0.0],
        [2.0, 1.25],
        [1.0, 1.25],
        [1.0, 2.0],
        [0.0, 2.0],
    ];
    let mesh = |offset: [f64; 2]| {
        let boundary: Vec<[f64; 2]> = ring
            .iter()
            .map(|p| [p[0] + offset[0], p[1] + offset[1]])
            .collect();
        let domain = Domain::Polygon {
            boundary,
            holes: vec![],
        };
        domain.mesh(0.05).unwrap()
    };
    let base = mesh([0.0, 0.0]);
    for offset in [
        [-1.0, -1.0],
        [-0.5, 0.75],
        [1.5, -3.0],
        [-2.0, 1.0],
        [1000.0, -1024.0],
    ] {
        let moved = mesh(offset);
        assert_eq!(
            moved.triangles().collect::<Vec<_>>(),
            base.triangles().collect::<Vec<_>>(),
            "{offset:?}"
        );
        for (p, q) in moved.points.iter().zip(&base.points) {
            for k in 0..2 {
                assert!(
                    (p[k] - offset[k] - q[k]).abs() <= 4.0 * f64::EPSILON * (offset[k].abs() + 2.0),
                    "{offset:?}"
                );
            }
        }
    }
}

/// A ring closed by repeating its first vertex (as GeoJSON and shapely write it), holes too, is
/// the same polygon (it was refused: "the vertex [0.0, 0.0] is repeated").
#[test]
fn a_closed_ring_is_the_same_polygon() {
    let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let hole = vec![[0.4, 0.4], [0.6, 0.4], [0.5, 0.6]];
    let close = |r: &[[f64; 2]]| [r, &r[..1]].concat();
    let open = polygon_case(&square, std::slice::from_ref(&hole), 0.1);
    let closed = polygon_case(&close(&square), &[close(&hole)], 0.1);
    let (a, b) = (open.mesh().unwrap(), closed.mesh().unwrap());
    assert_eq!((a.n_triangles(), a.points), (b.n_triangles(), b.points));
}
