//! Data per physical group of a Gmsh mesh: the shipped two-region mesh (data/meshes/two_regions.msh:
//! the surfaces "loaded" (x < 1) and "free" (x > 1) of the rectangle (0, 2) × (0, 1), the curves
//! "rim" (x = 2) and "clamped" (the other sides)). A table load is the load of the same function
//! written with `if`, integrated per triangle (no smearing across the interface), and the groups
//! follow the mesh through refinement, bisection and renumbering.

use membrane_contact::assembly::Quadrature;
use membrane_contact::case::Case;
use membrane_contact::datum::Datum;
use membrane_contact::expr::Expr;
use membrane_contact::mesh::{file, Curves, Mesh};
use membrane_contact::problem::{Data, DiscreteProblem};
use std::path::Path;

const MESH: &str = "data/meshes/two_regions.msh";

fn two_regions() -> Mesh {
    file::read(Path::new(MESH)).unwrap()
}

fn e(s: &str) -> Expr {
    Expr::parse(s).unwrap()
}

fn table(entries: &[(&str, &str)]) -> Datum {
    Datum::Table(entries.iter().map(|(k, v)| (k.to_string(), e(v))).collect())
}

fn centroid(mesh: &Mesh, t: usize) -> [f64; 2] {
    let [p, q, r] = mesh.corners(t);
    [(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0]
}

/// The groups of `mesh` are the geometric ones: "loaded" ⇔ the triangle lies in x < 1, "rim" ⇔
/// the boundary edge lies on x = 2.
fn assert_geometric_groups(mesh: &Mesh) {
    let groups = mesh.groups().expect("groups");
    assert_eq!(groups.surfaces, ["loaded", "free"]);
    assert_eq!(groups.curves, ["clamped", "rim"]);
    for t in 0..mesh.n_triangles() {
        let name = &groups.surfaces[groups.surface(t).expect("every triangle in a group")];
        let left = centroid(mesh, t)[0] < 1.0;
        assert_eq!(name == "loaded", left, "triangle {t} at {:?}", centroid(mesh, t));
    }
    let edges = mesh.boundary_edges();
    assert_eq!(groups.boundary_edges().len(), edges.len());
    for (a, b) in edges {
        let curve = &groups.curves[groups.curve(a, b).expect("every boundary edge on a curve")];
        let rim = mesh.points[a][0] == 2.0 && mesh.points[b][0] == 2.0;
        assert_eq!(
            curve == "rim",
            rim,
            "edge {:?}–{:?}",
            mesh.points[a],
            mesh.points[b]
        );
    }
}

fn loads(mesh: &Mesh, f1: impl Into<Datum>, degree: usize) -> Vec<f64> {
    let data = Data::new([1.0, 1.0], f1, e("0"), e("0"), Quadrature { degree }).unwrap();
    DiscreteProblem::new(mesh.clone(), &data).unwrap().load1
}

#[test]
fn the_shipped_mesh_has_its_groups() {
    let mesh = two_regions();
    assert_eq!((mesh.n_vertices(), mesh.n_triangles()), (153, 256));
    assert_geometric_groups(&mesh);
}

#[test]
fn a_table_load_is_the_load_of_the_same_function_by_if() {
    // The interface x = 1 lies on mesh edges: every quadrature point of a triangle is on its
    // triangle's side, so `if` picks the triangle's group's expression at every point.
    let mut mesh = two_regions();
    for level in 0..3 {
        for degree in [1, 4, 8] {
            let tabled = loads(
                &mesh,
                table(&[("loaded", "-20*(1 + y) + sin(3*x)"), ("free", "3*x*y")]),
                degree,
            );
            let by_if = loads(&mesh, e("if(x < 1, -20*(1 + y) + sin(3*x), 3*x*y)"), degree);
            let scale = by_if.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (a, (t, i)) in tabled.iter().zip(&by_if).enumerate() {
                assert!(
                    (t - i).abs() <= 1e-12 * scale,
                    "level {level}, degree {degree}, vertex {a}: {t} vs {i}"
                );
            }
        }
        mesh = mesh.refined(&Curves::default()).unwrap().renumbered();
    }
}

#[test]
fn a_piecewise_constant_load_is_integrated_per_group_without_smearing() {
    // (f, φ_a) = Σ_{T ∋ a} c_T |T| / 3 exactly for f = c_T on each triangle T: the vertices on the
    // interface x = 1 get −20 |T|/3 from their left triangles and 3 |T|/3 from their right ones.
    let mesh = two_regions().refined(&Curves::default()).unwrap();
    let groups = mesh.groups().unwrap();
    let value = |t: usize| match groups.surfaces[groups.surface(t).unwrap()].as_str() {
        "loaded" => -20.0,
        _ => 3.0,
    };
    let mut closed_form = vec![0.0; mesh.n_vertices()];
    for (t, tri) in mesh.triangles().enumerate() {
        for a in tri {
            closed_form[a] += value(t) * mesh.area(t) / 3.0;
        }
    }
    for degree in [0, 2, 5] {
        let tabled = loads(&mesh, table(&[("free", "3"), ("loaded", "-20")]), degree);
        for (a, (t, c)) in tabled.iter().zip(&closed_form).enumerate() {
            assert!(
                (t - c).abs() <= 1e-13 * 20.0,
                "degree {degree}, vertex {a}: {t} vs {c}"
            );
        }
        // ∫f = −20 |left| + 3 |right| = −17: nothing crosses the interface.
        let total: f64 = tabled.iter().sum();
        assert!((total + 17.0).abs() < 1e-12, "{total}");
    }
    // An interface vertex gets both sides' loads: it is neither −20 m_a nor 3 m_a.
    let on_interface = (0..mesh.n_vertices())
        .find(|&a| mesh.points[a][0] == 1.0 && !mesh.on_boundary[a])
        .unwrap();
    let tabled = loads(&mesh, table(&[("free", "3"), ("loaded", "-20")]), 2);
    let m: f64 = (mesh.triangles().enumerate())
        .filter(|(_, tri)| tri.contains(&on_interface))
        .map(|(t, _)| mesh.area(t) / 3.0)
        .sum();
    let l = tabled[on_interface];
    assert!(l > -20.0 * m * 0.9 && l < 3.0 * m * 0.9, "{l} vs m_a = {m}");
}

#[test]
fn groups_survive_refinement_bisection_and_renumbering() {
    let mesh = two_regions();
    let refined = mesh.refined(&Curves::default()).unwrap();
    assert_eq!(refined.n_triangles(), 4 * mesh.n_triangles());
    // Each child keeps its parent's group: the four children of t are 4t..4t+3.
    let (coarse, fine) = (mesh.groups().unwrap(), refined.groups().unwrap());
    for t in 0..refined.n_triangles() {
        assert_eq!(fine.surface(t), coarse.surface(t / 4), "child {t}");
    }
    assert_geometric_groups(&refined);
    assert_geometric_groups(&refined.renumbered());
    // Newest-vertex bisection of the triangles near the interface and near the rim, twice.
    let mut adapted = mesh.longest_edge_labelled();
    assert_geometric_groups(&adapted);
    for _ in 0..2 {
        let marked: Vec<bool> = (0..adapted.n_triangles())
            .map(|t| {
                let c = centroid(&adapted, t);
                (c[0] - 1.0).abs() < 0.2 || c[0] > 1.85
            })
            .collect();
        let before = adapted.n_triangles();
        adapted = adapted.bisected(&marked, &Curves::default()).unwrap();
        assert!(adapted.n_triangles() > before);
        assert_geometric_groups(&adapted);
    }
}

#[test]
fn the_shipped_case_solves_with_tables_through_refinement() {
    let case = Case::read(Path::new("data/cases/two_regions.toml")).unwrap();
    assert!(case.data.f1.is_table() && case.data.g.is_table());
    let (mesh, coarser) = case.hierarchy(true, Default::default()).unwrap();
    assert_geometric_groups(&mesh);
    for level in &coarser {
        if level.groups().is_some() {
            assert_geometric_groups(level);
        }
    }
    let problem = DiscreteProblem::new(mesh, &case.data).unwrap();
    // g_h: 0.05 on the clamped sides, 0.05 + 0.4 y (1 − y) on the rim.
    for (a, p) in problem.mesh.points.iter().enumerate() {
        if problem.mesh.on_boundary[a] {
            let g = if p[0] == 2.0 {
                0.05 + 0.4 * p[1] * (1.0 - p[1])
            } else {
                0.05
            };
            assert!((problem.g_h[a] - g).abs() < 1e-15, "{p:?}");
        }
    }
}

/// A case on the shipped mesh refined once, its data given as `body`.
fn on_two_regions(body: &str) -> Case {
    let text = format!("{body}\n[mesh]\nkind = \"file\"\npath = \"../meshes/two_regions.msh\"\nrefine = 1\n");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases");
    Case::parse(&text, "test case", dir).unwrap()
}

fn solved(case: &Case) -> membrane_contact::contact::Solution {
    let options = membrane_contact::run::Options::default();
    membrane_contact::run::run(case, &options).unwrap().solution
}

/// An obstacle ψ per surface (two planes meeting along x = 1) and u2's boundary height g2 per
/// curve give the solutions of the same functions written with `if`: the vertex values are taken
/// from each vertex's own groups (swapping the entries changes the solution).
#[test]
fn psi_and_g2_tables_give_the_solutions_of_their_functions() {
    let planes = ("-0.3 + 0.1*(x - 1)", "-0.3 + 0.2*(x - 1)");
    let obstacle =
        |psi: &str| on_two_regions(&format!("problem = \"obstacle\"\nmu = 1.0\nf = -5\ng = 0\n{psi}"));
    let by_if = solved(&obstacle(&format!(
        "psi = \"if(x < 1, {}, {})\"",
        planes.0, planes.1
    )));
    let table = |a: &str, b: &str| format!("psi = {{ loaded = \"{a}\", free = \"{b}\" }}");
    let by_table = solved(&obstacle(&table(planes.0, planes.1)));
    let swapped = solved(&obstacle(&table(planes.1, planes.0)));
    assert!(by_if.obstacle.contact.iter().any(|&c| c));
    let close = |a: &[f64], b: &[f64], tol: f64| a.iter().zip(b).all(|(a, b)| (a - b).abs() < tol);
    // Equal to round-off (the solves see the same vertex values; not bit for bit).
    assert!(close(&by_if.u1, &by_table.u1, 1e-13));
    assert!(!close(&by_if.u1, &swapped.u1, 1e-3));
    let membranes =
        |g2: &str| on_two_regions(&format!("mu1 = 1.0\nmu2 = 2.0\nf1 = -10\nf2 = 0\ng = 0.3\n{g2}"));
    let by_if = solved(&membranes("g2 = \"if(x > 1.999999, 0.05 + y*(1 - y), 0.05)\""));
    let by_table = solved(&membranes("g2 = { rim = \"0.05 + y*(1 - y)\", clamped = 0.05 }"));
    assert!(by_if.obstacle.contact.iter().any(|&c| c));
    // g2 enters through the v/w split: equal to round-off (not bit for bit).
    for (a, b) in by_if.u2.iter().zip(&by_table.u2) {
        assert!((a - b).abs() < 1e-13, "{a} vs {b}");
    }
    let swapped = solved(&membranes("g2 = { clamped = \"0.05 + y*(1 - y)\", rim = 0.05 }"));
    assert!(by_if
        .u2
        .iter()
        .zip(&swapped.u2)
        .any(|(a, b)| (a - b).abs() > 1e-3));
}

/// `adapt` on the shipped two-region case: the groups follow every bisection (each triangle's
/// group is still its side of x = 1), and the estimate falls.
#[test]
fn adapt_runs_with_tables_per_group() {
    let case = Case::read(Path::new("data/cases/two_regions.toml")).unwrap();
    let settings = membrane_contact::case::Adaptivity {
        theta: 0.5,
        target: None,
        max_vertices: 20_000,
        steps: 4,
    };
    let dir = tempfile::tempdir().unwrap();
    let a = membrane_contact::adapt::adapt(&case, &settings, true, &dir.path().join("adapt")).unwrap();
    let steps = &a.adaptive;
    assert_eq!(steps.len(), 5);
    assert!(steps
        .windows(2)
        .all(|w| w[1].estimator < w[0].estimator && w[1].vertices > w[0].vertices));
    let last = file::read(&dir.path().join("adapt/step-004/solution.h5")).unwrap();
    assert_geometric_groups(&last);
    // Read back through its XDMF file the result keeps them too.
    assert_geometric_groups(&file::read(&dir.path().join("adapt/step-004/solution.xdmf")).unwrap());
    // S_h asked for: in every step, with λ_h and the owner vertex of each cell; read as a mesh it
    // has no groups (it was refused: "the physical groups of the result: … groups for … triangles").
    assert!((0..5).all(|k| dir.path().join(format!("adapt/step-{k:03}/dual.xdmf")).exists()));
    let dual = file::read(&dir.path().join("adapt/step-004/dual.xdmf")).unwrap();
    assert!(dual.groups().is_none() && dual.n_triangles() == 6 * last.n_triangles());
    let h5 = hdf5::File::open(dir.path().join("adapt/step-004/solution.h5")).unwrap();
    let read = |name: &str| h5.dataset(name).unwrap().read_raw::<f64>().unwrap();
    let (vertex, lambda, lambda_a) = (read("dual/vertex"), read("dual/lambda"), read("mesh/lambda"));
    assert_eq!(vertex.len(), 6 * last.n_triangles());
    // Cell s of S_h lies in D_a of the vertex a = t[(s mod 6) / 2] of its triangle t, and λ_h = λ_a
    // there.
    for (s, (&a, &l)) in vertex.iter().zip(&lambda).enumerate() {
        let owner = last.triangle(s / 6)[(s % 6) / 2];
        assert_eq!(a, owner as f64, "cell {s}");
        assert_eq!(l, lambda_a[owner], "cell {s}");
    }
    assert!(lambda.iter().any(|&l| l > 0.0));
}

/// A Gmsh entity in two physical groups (surface 1 in "loaded" and "free", curve 1 in "clamped"
/// and "rim"): the mesh is read, and solves with data that do not depend on the groups; data per
/// group on that dimension are refused, naming the entity.
#[test]
fn an_entity_in_two_groups_is_refused_only_by_data_per_group() {
    let text = std::fs::read_to_string(MESH).unwrap();
    let text = (text.replacen(
        "\n1 0 0 0 1 1 0 1 3 4 1 7 5 6\n",
        "\n1 0 0 0 1 1 0 2 3 4 4 1 7 5 6\n",
        1,
    ))
    .replacen(
        "\n1 0 0 0 1 0 0 1 1 2 1 -2\n",
        "\n1 0 0 0 1 0 0 2 1 2 2 1 -2\n",
        1,
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("twice.msh"), text).unwrap();
    let case = |data: &str| {
        let text =
            format!("mu1 = 1.0\nmu2 = 2.0\nf2 = 5\n{data}\n[mesh]\nkind = \"file\"\npath = \"twice.msh\"\n");
        Case::parse(&text, "case.toml", dir.path().to_path_buf())
    };
    let plain = case("f1 = -20\ng = 0.05").unwrap();
    assert!(solved(&plain).u1.iter().all(|u| u.is_finite()));
    let error = |data: &str| match case(data) {
        Err(e) => e.0,
        Ok(c) => match DiscreteProblem::new(c.mesh().unwrap(), &c.data) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("{data}: accepted"),
        },
    };
    let surfaces = error("f1 = { loaded = -20, free = 0 }\ng = 0.05");
    assert!(
        surfaces.contains("the surface entity 1 belongs to the physical groups [3, 4]"),
        "{surfaces}"
    );
    let curves = error("f1 = -20\ng = { clamped = 0.05, rim = 0.05 }");
    assert!(
        curves.contains("the curve entity 1 belongs to the physical groups [1, 2]"),
        "{curves}"
    );
}

/// An entry for a physical curve with no boundary edge (a curve inside ω) is refused, not
/// silently ignored: boundary values are taken on ∂ω only.
#[test]
fn an_entry_for_a_curve_inside_the_domain_is_refused() {
    let mesh = two_regions();
    let mut groups = mesh.groups().unwrap().clone();
    groups.curves.push("interface".into());
    let mesh = mesh.with_groups(groups);
    let g = table(&[("clamped", "0.05"), ("rim", "0.05"), ("interface", "7")]);
    let e = g
        .pieces("g", &mesh, membrane_contact::datum::On::Curves)
        .unwrap_err();
    assert!(
        e.to_string().contains("the physical curve 'interface' of")
            && e.to_string().contains("has no boundary edge"),
        "{e}"
    );
    let g = table(&[("clamped", "0.05"), ("rim", "0.05")]);
    assert!(g.pieces("g", &mesh, membrane_contact::datum::On::Curves).is_ok());
}

/// A datum that is not finite in one group's entry is named with that group: the load of the
/// group on the triangle where a quadrature point saw it, the boundary value of the group whose
/// edge has the vertex.
#[test]
fn a_non_finite_entry_names_its_group() {
    let mesh = two_regions();
    let refused = |f1: Datum, g: Datum| {
        let data = Data::new([1.0, 1.0], f1, e("0"), g, Quadrature { degree: 2 }).unwrap();
        DiscreteProblem::new(mesh.clone(), &data).unwrap_err().to_string()
    };
    let zero = || table(&[("clamped", "0"), ("rim", "0")]);
    for (group, other) in [("free", "loaded"), ("loaded", "free")] {
        let f1 = table(&[(group, "log(x - 5)"), (other, "1")]);
        let message = refused(f1, zero());
        assert!(
            message.starts_with(&format!("f1.{group} is NaN at (")),
            "{message}"
        );
    }
    let g = table(&[("clamped", "0"), ("rim", "sqrt(y - 0.5)")]);
    let message = refused(e("1").into(), g);
    assert!(message.starts_with("g.rim is NaN at (2, "), "{message}");
}

/// A key for a name the file declares twice (two tags, one name), for a name declared in
/// `$PhysicalNames` that no element carries, and for a group of a mesh that has none of its kind:
/// each message says which, instead of merging the groups or listing the groups that exist.
#[test]
fn keys_of_repeated_unused_and_missing_names_are_told_apart() {
    let text = std::fs::read_to_string(MESH).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let refused = |text: String, data: &str| {
        std::fs::write(dir.path().join("m.msh"), text).unwrap();
        let case =
            format!("mu1 = 1.0\nmu2 = 2.0\nf2 = 5\n{data}\n[mesh]\nkind = \"file\"\npath = \"m.msh\"\n");
        match Case::parse(&case, "case.toml", dir.path().to_path_buf()) {
            Err(e) => e.0,
            Ok(c) => DiscreteProblem::new(c.mesh().unwrap(), &c.data)
                .unwrap_err()
                .to_string(),
        }
    };
    let twice = text.replacen("2 4 \"free\"", "2 4 \"loaded\"", 1);
    let e = refused(twice, "f1 = { loaded = -20 }\ng = 0.05");
    assert!(e.contains("'loaded' names 2 physical surfaces of"), "{e}");
    // Surface entity 2 without its physical tag 4 ("free").
    let untagged = text.replacen(
        "\n2 1 0 0 2 1 0 1 4 4 2 3 4 -7\n",
        "\n2 1 0 0 2 1 0 0 4 2 3 4 -7\n",
        1,
    );
    let e = refused(untagged, "f1 = { loaded = -20, free = 0 }\ng = 0.05");
    assert!(
        e.contains("'free' is a name")
            && e.contains("declares (in $PhysicalNames")
            && e.contains("no element carries it"),
        "{e}"
    );
    // No $Entities (meshio writes a MSH 4.1 file so): names declared that no element carries (it
    // said "this mesh has none" of a file that declares them).
    let (start, end) = (
        text.find("$Entities").unwrap(),
        text.find("$EndEntities\n").unwrap() + 13,
    );
    let bare = format!("{}{}", &text[..start], &text[end..]);
    let e = refused(bare, "f1 = { loaded = -20, free = 0 }\ng = 0.05");
    assert!(
        e.contains("'loaded' is a name") && e.contains("no element carries it"),
        "{e}"
    );
    let mesh = two_regions();
    let mut groups = mesh.groups().unwrap().clone();
    groups.curves.clear();
    let e = table(&[("rim", "0")])
        .pieces(
            "g",
            &mesh.with_groups(groups),
            membrane_contact::datum::On::Curves,
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("(it has no physical curves)"), "{e}");
}

/// How [`write_dolfinx_xdmf`] departs from what dolfinx writes.
#[derive(Clone, Copy, PartialEq)]
enum Variant {
    AsDolfinx,
    /// The values of the tags in a dataset of one dimension (dolfinx writes (n, 1)).
    Flat,
    CellTagsTwice,
    CellTaggedTwice,
    FacetNotAnEdge,
}

/// Writes `mesh` as dolfinx 0.5 writes a mesh and its meshtags (`XDMFFile.write_mesh`, then
/// `write_meshtags` of the cells, of the facets and of some vertices): the groups of
/// two_regions.msh as tags (loaded 1, free 2; clamped 5, rim 7), the cells tagged in reverse order
/// and reoriented, an interior edge tagged 9 as well; or with the `variant`'s departure.
fn write_dolfinx_xdmf(dir: &Path, mesh: &Mesh, variant: Variant) -> std::path::PathBuf {
    let groups = mesh.groups().unwrap();
    let f = hdf5::File::create(dir.join("mesh.h5")).unwrap();
    let write_f64 = |name: &str, rows: Vec<Vec<f64>>| {
        let a = ndarray::Array2::from_shape_fn((rows.len(), rows[0].len()), |(i, k)| rows[i][k]);
        f.new_dataset_builder().with_data(&a).create(name).unwrap();
    };
    let write_i64 = |name: &str, rows: Vec<Vec<i64>>| {
        let a = ndarray::Array2::from_shape_fn((rows.len(), rows[0].len()), |(i, k)| rows[i][k]);
        f.new_dataset_builder().with_data(&a).create(name).unwrap();
    };
    let write_values = |name: &str, values: Vec<i64>| match variant {
        Variant::Flat => {
            let a = ndarray::Array1::from(values);
            f.new_dataset_builder().with_data(&a).create(name).unwrap();
        }
        _ => write_i64(name, values.into_iter().map(|v| vec![v]).collect()),
    };
    write_f64(
        "/Mesh/mesh/geometry",
        mesh.points.iter().map(|p| p.to_vec()).collect(),
    );
    let cells: Vec<[usize; 3]> = mesh.triangles().collect();
    write_i64(
        "/Mesh/mesh/topology",
        cells.iter().map(|c| c.map(|v| v as i64).to_vec()).collect(),
    );
    let mut tagged: Vec<usize> = (0..cells.len()).rev().collect();
    if variant == Variant::CellTaggedTwice {
        tagged.push(tagged[0]);
    }
    let cell_tag = |t: usize| [1, 2][groups.surface(t).unwrap()];
    write_i64(
        "/MeshTags/cell_tags/topology",
        (tagged.iter())
            .map(|&t| [cells[t][1], cells[t][0], cells[t][2]].map(|v| v as i64).to_vec())
            .collect(),
    );
    write_values(
        "/MeshTags/cell_tags/Values",
        tagged.iter().map(|&t| cell_tag(t)).collect(),
    );
    let mut facets: Vec<([usize; 2], i64)> = (mesh.boundary_edges().into_iter())
        .map(|(a, b)| ([b, a], [5, 7][groups.curve(a, b).unwrap()]))
        .collect();
    let boundary = mesh.boundary_edges();
    let interior = (cells.iter())
        .map(|c| (c[0].min(c[1]), c[0].max(c[1])))
        .find(|e| !boundary.contains(e))
        .unwrap();
    facets.push(([interior.0, interior.1], 9));
    if variant == Variant::FacetNotAnEdge {
        // The corners (0, 0) and (2, 1) of the rectangle: no edge joins them.
        let corner = |q: [f64; 2]| mesh.points.iter().position(|p| *p == q).unwrap();
        facets.push(([corner([0.0, 0.0]), corner([2.0, 1.0])], 5));
    }
    write_i64(
        "/MeshTags/facet_tags/topology",
        facets.iter().map(|(e, _)| e.map(|v| v as i64).to_vec()).collect(),
    );
    write_values(
        "/MeshTags/facet_tags/Values",
        facets.iter().map(|(_, t)| *t).collect(),
    );
    write_i64("/MeshTags/vertex_tags/topology", vec![vec![0], vec![1]]);
    write_values("/MeshTags/vertex_tags/Values", vec![3, 3]);
    let (n, m, k) = (mesh.n_vertices(), tagged.len(), facets.len());
    let values = |count: usize| match variant {
        Variant::Flat => format!("{count}"),
        _ => format!("{count} 1"),
    };
    let tags = |name: &str, kind: &str, count: usize, nodes: usize| {
        format!(
            r#"<Grid Name="{name}" GridType="Uniform"><xi:include xpointer="xpointer(/Xdmf/Domain/Grid/Geometry)" />
      <Topology TopologyType="{kind}" NumberOfElements="{count}" NodesPerElement="{nodes}"><DataItem Dimensions="{count} {nodes}" NumberType="Int" Format="HDF">mesh.h5:/MeshTags/{name}/topology</DataItem></Topology>
      <Attribute Name="{name}" AttributeType="Scalar" Center="Cell"><DataItem Dimensions="{}" Format="HDF">mesh.h5:/MeshTags/{name}/Values</DataItem></Attribute></Grid>"#,
            values(count)
        )
    };
    let xdmf = format!(
        r#"<?xml version="1.0"?>
<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>
<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude"><Domain>
    <Grid Name="mesh" GridType="Uniform">
      <Topology TopologyType="Triangle" NumberOfElements="{}" NodesPerElement="3"><DataItem Dimensions="{} 3" NumberType="Int" Format="HDF">mesh.h5:/Mesh/mesh/topology</DataItem></Topology>
      <Geometry GeometryType="XY"><DataItem Dimensions="{n} 2" Format="HDF">mesh.h5:/Mesh/mesh/geometry</DataItem></Geometry>
    </Grid>
    {}{}{}{}
</Domain></Xdmf>"#,
        cells.len(),
        cells.len(),
        tags("cell_tags", "Triangle", m, 3),
        tags("facet_tags", "PolyLine", k, 2),
        tags("vertex_tags", "Polyvertex", 2, 1),
        match variant {
            Variant::CellTagsTwice => tags("cell_tags", "Triangle", m, 3),
            _ => String::new(),
        },
    );
    let path = dir.join("mesh.xdmf");
    std::fs::write(&path, xdmf).unwrap();
    path
}

/// The groups of two_regions.msh by their tags: surface 1 left of x = 1, curve 7 the rim x = 2.
fn assert_tagged_as_two_regions(mesh: &Mesh) {
    let groups = mesh.groups().expect("groups");
    for t in 0..mesh.n_triangles() {
        let named = groups.surfaces[groups.surface(t).unwrap()] == "1";
        assert_eq!(named, centroid(mesh, t)[0] < 1.0, "triangle {t}");
    }
    for (a, b) in mesh.boundary_edges() {
        let rim = mesh.points[a][0] == 2.0 && mesh.points[b][0] == 2.0;
        assert_eq!(groups.curves[groups.curve(a, b).unwrap()] == "7", rim);
    }
}

/// A dolfinx XDMF file with meshtags (cells, facets, vertices) is one mesh, not a collection of
/// three: its cell and facet tags are its groups, named by their tags, as on the .msh file; tags
/// that are not the mesh's, or ambiguous, are refused.
#[test]
fn dolfinx_meshtags_are_groups_named_by_their_tags() {
    let msh = two_regions();
    let read = |variant: Variant| {
        let dir = tempfile::tempdir().unwrap();
        file::read(&write_dolfinx_xdmf(dir.path(), &msh, variant))
    };
    for variant in [Variant::AsDolfinx, Variant::Flat] {
        let mesh = read(variant).unwrap();
        // Its HDF5 file read alone holds the same mesh and groups.
        let dir = tempfile::tempdir().unwrap();
        write_dolfinx_xdmf(dir.path(), &msh, variant);
        let h5 = file::read(&dir.path().join("mesh.h5")).unwrap();
        let (a, b) = (
            mesh.groups().unwrap(),
            h5.groups().expect("groups from /MeshTags"),
        );
        assert_eq!((&a.surfaces, &a.curves), (&b.surfaces, &b.curves));
        assert!((0..mesh.n_triangles()).all(|t| a.surface(t) == b.surface(t)));
        assert_eq!(mesh.points, msh.points);
        let groups = mesh.groups().expect("groups from the meshtags");
        assert_eq!(groups.surfaces, ["1", "2"]);
        // The interior edge's tag is a curve as an interior physical curve of a .msh file is.
        assert_eq!(groups.curves, ["5", "7", "9"]);
        assert_tagged_as_two_regions(&mesh);
        // The tables keyed by tags give the .msh file's loads by name.
        let by_tag = loads(&mesh, table(&[("1", "-20"), ("2", "3*x")]), 4);
        let by_name = loads(&msh, table(&[("loaded", "-20"), ("free", "3*x")]), 4);
        assert_eq!(by_tag, by_name);
    }
    // Two meshtags of the cells: data without groups solve, tables of the surfaces are refused.
    let twice = read(Variant::CellTagsTwice).unwrap();
    assert_eq!(loads(&twice, e("-20"), 4), loads(&msh, e("-20"), 4));
    let data = Data::new(
        [1.0, 1.0],
        table(&[("1", "-20"), ("2", "0")]),
        e("0"),
        e("0"),
        Quadrature { degree: 4 },
    )
    .unwrap();
    let Err(refused) = DiscreteProblem::new(twice, &data).map(|p| p.load1.len()) else {
        panic!("a table on two meshtags of the cells")
    };
    let refused = refused.to_string();
    assert!(
        refused.contains("meshtags 'cell_tags', 'cell_tags' all tag the triangles"),
        "{refused}"
    );
    for (variant, message) in [
        (
            Variant::CellTaggedTwice,
            "meshtags 'cell_tags': entity 256 (vertices",
        ),
        (Variant::FacetNotAnEdge, "is not an edge of the mesh"),
    ] {
        let Err(e) = read(variant).map(|m| m.n_vertices()) else {
            panic!("{message}: read")
        };
        assert!(e.to_string().contains(message), "{e}");
    }
}

/// Writes `mesh` as meshio writes a mesh of several cell blocks read from a Gmsh file (`meshio
/// convert two_regions.msh mesh.xdmf`): one `Mixed` topology of its boundary lines, a vertex and
/// its triangles, on points with an unused one first (the centre of a circle arc, which meshio
/// keeps), the lines `extra` after the boundary's, and the cell attributes `attributes` (name,
/// values over all cells: lines, vertex, triangles; a name `vector:…` three columns of them);
/// with `mixed` false a `Triangle` topology of the triangles alone.
fn write_meshio_xdmf(
    dir: &Path,
    mesh: &Mesh,
    (mixed, extra): (bool, &[(usize, usize)]),
    attributes: &[(&str, Vec<f64>)],
) -> std::path::PathBuf {
    let f = hdf5::File::create(dir.join("mesh.h5")).unwrap();
    let mut points = vec![[9.0, 9.0]];
    points.extend(&mesh.points);
    let geometry = ndarray::Array2::from_shape_fn((points.len(), 2), |(i, k)| points[i][k]);
    f.new_dataset_builder()
        .with_data(&geometry)
        .create("data0")
        .unwrap();
    let cells: Vec<[i64; 3]> = mesh.triangles().map(|t| t.map(|v| v as i64 + 1)).collect();
    let stream: Vec<i64> = (mesh.boundary_edges().into_iter().chain(extra.iter().copied()))
        .flat_map(|(a, b)| [2, 2, a as i64 + 1, b as i64 + 1])
        .chain([1, 1, 1])
        .chain(cells.iter().flat_map(|t| [4, t[0], t[1], t[2]]))
        .collect();
    let (topology, dimensions) = match mixed {
        true => {
            f.new_dataset_builder()
                .with_data(&ndarray::Array1::from(stream.clone()))
                .create("data1")
                .unwrap();
            ("TopologyType=\"Mixed\"".to_string(), stream.len().to_string())
        }
        false => {
            let a = ndarray::Array2::from_shape_fn((cells.len(), 3), |(i, k)| cells[i][k]);
            f.new_dataset_builder().with_data(&a).create("data1").unwrap();
            (
                "TopologyType=\"Triangle\" NodesPerElement=\"3\"".to_string(),
                format!("{} 3", cells.len()),
            )
        }
    };
    let mut xml = String::new();
    for (k, (name, values)) in attributes.iter().enumerate() {
        let data = format!("data{}", k + 2);
        let (kind, dimensions) = match name.strip_prefix("vector:") {
            Some(_) => {
                let a = ndarray::Array2::from_shape_fn((values.len() / 3, 3), |(i, j)| values[3 * i + j]);
                f.new_dataset_builder()
                    .with_data(&a)
                    .create(data.as_str())
                    .unwrap();
                ("Vector", format!("{} 3", values.len() / 3))
            }
            None => {
                let a = ndarray::Array1::from(values.clone());
                f.new_dataset_builder()
                    .with_data(&a)
                    .create(data.as_str())
                    .unwrap();
                ("Scalar", values.len().to_string())
            }
        };
        xml += &format!(
            r#"<Attribute Name="{name}" AttributeType="{kind}" Center="Cell"><DataItem DataType="Int" Dimensions="{dimensions}" Format="HDF" Precision="8">mesh.h5:/{data}</DataItem></Attribute>"#
        );
    }
    let xdmf = format!(
        r#"<Xdmf Version="3.0"><Domain><Grid Name="Grid"><Geometry GeometryType="XY"><DataItem DataType="Float" Dimensions="{} 2" Format="HDF" Precision="8">mesh.h5:/data0</DataItem></Geometry><Topology {topology}><DataItem DataType="Int" Dimensions="{dimensions}" Format="HDF" Precision="8">mesh.h5:/data1</DataItem></Topology>{xml}</Grid></Domain></Xdmf>"#,
        points.len()
    );
    let path = dir.join("mesh.xdmf");
    std::fs::write(&path, xdmf).unwrap();
    path
}

/// meshio writes a Gmsh file's physical groups into an XDMF file as the cell data `gmsh:physical`
/// (beside `gmsh:geometrical`), and a mesh made by hand with one cell attribute of whole numbers
/// (`cell_data={"name_to_read": ...}`): they are groups named by their tags, as dolfinx's
/// meshtags are (a table on such a file was refused: "this mesh has none"). A cell attribute of
/// other numbers is a field, not groups; one of the wrong length is named.
#[test]
fn meshio_s_cell_data_are_groups_named_by_their_tags() {
    let msh = two_regions();
    let groups = msh.groups().unwrap();
    let edges = msh.boundary_edges();
    let physical: Vec<f64> = (edges.iter())
        .map(|&(a, b)| [5.0, 7.0][groups.curve(a, b).unwrap()])
        .chain([3.0])
        .chain((0..msh.n_triangles()).map(|t| [1.0, 2.0][groups.surface(t).unwrap()]))
        .collect();
    let geometrical: Vec<f64> = (0..physical.len()).map(|k| k as f64).collect();
    let read_with = |mixed: bool, extra: &[(usize, usize)], attributes: &[(&str, Vec<f64>)]| {
        let dir = tempfile::tempdir().unwrap();
        file::read(&write_meshio_xdmf(dir.path(), &msh, (mixed, extra), attributes))
    };
    let read = |mixed: bool, attributes: &[(&str, Vec<f64>)]| read_with(mixed, &[], attributes);
    let both = [
        ("gmsh:geometrical", geometrical.clone()),
        ("gmsh:physical", physical.clone()),
    ];
    let mesh = read(true, &both).unwrap();
    assert_eq!(mesh.points, msh.points);
    let g = mesh.groups().expect("groups from gmsh:physical");
    assert_eq!(
        (g.surfaces.clone(), g.curves.clone()),
        (
            vec!["1".to_string(), "2".into()],
            vec!["5".to_string(), "7".into()]
        )
    );
    assert_tagged_as_two_regions(&mesh);
    let by_tag = loads(&mesh, table(&[("1", "-20"), ("2", "3*x")]), 4);
    assert_eq!(
        by_tag,
        loads(&msh, table(&[("loaded", "-20"), ("free", "3*x")]), 4)
    );
    // The only cell attribute of a Triangle topology, whatever its name: surfaces alone.
    let surfaces = physical[edges.len() + 1..].to_vec();
    let mesh = read(false, &[("name_to_read", surfaces.clone())]).unwrap();
    let g = mesh.groups().expect("groups from the only cell attribute");
    assert_eq!(
        (g.surfaces.clone(), g.curves.len()),
        (vec!["1".to_string(), "2".into()], 0)
    );
    assert_eq!(loads(&mesh, table(&[("1", "-20"), ("2", "3*x")]), 4), by_tag);
    // A field of the cells, or two attributes neither of which is gmsh:physical: no groups.
    let field: Vec<f64> = surfaces.iter().map(|v| v + 0.5).collect();
    assert!(read(false, &[("pressure", field)]).unwrap().groups().is_none());
    let two = [("a", surfaces.clone()), ("b", surfaces.clone())];
    assert!(read(false, &two).unwrap().groups().is_none());
    // A vector of whole numbers per cell is a field too (it was refused: "need one column").
    let vectors: Vec<f64> = surfaces.iter().flat_map(|&v| [v, v, v]).collect();
    assert!(read(false, &[("vector:grad", vectors)])
        .unwrap()
        .groups()
        .is_none());
    // A line repeated with another tag (meshio writes a curve's lines once per group of a Gmsh 2
    // file) keeps its first; a line that is no edge of the triangles is left aside (both were
    // refused as meshtags are: "tagged twice", "not an edge").
    let (a, b) = edges[0];
    let corner = |q: [f64; 2]| msh.points.iter().position(|p| *p == q).unwrap();
    let across = (corner([0.0, 0.0]), corner([2.0, 1.0]));
    let n = edges.len();
    let with_extra: Vec<f64> = [&physical[..n], &[9.0, 9.0], &physical[n..]].concat();
    let mesh = read_with(true, &[(b, a), across], &[("gmsh:physical", with_extra)]).unwrap();
    assert_eq!(mesh.groups().unwrap().curves, ["5", "7"]);
    assert_tagged_as_two_regions(&mesh);
    let mut fractional = physical.clone();
    fractional[n + 3] = 1.5;
    let e = read(true, &[("gmsh:physical", fractional)])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cell attribute 'gmsh:physical': the tag 1.5 is not a whole number"),
        "{e}"
    );
    let e = read(true, &[("gmsh:physical", surfaces)])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!(
            "cell attribute 'gmsh:physical': /data2 has {} values for {} cells",
            msh.n_triangles(),
            physical.len()
        )),
        "{e}"
    );
}

/// Tables per group on a file's mesh solved as it is: no coarser mesh of its boundary takes the
/// tables, so the solve starts cold, and the summary says that, not that the coarser levels
/// "give the guess only" (there were none); the same load as one expression has them. Started
/// otherwise (cold, or from another mesh's solution as adapt's steps are), neither is said.
#[test]
fn a_cold_start_for_tables_is_said_as_such() {
    let summary = |f1: &str, start: membrane_contact::contact::Start| {
        let text = format!(
            "mu1 = 1.0\nmu2 = 1.0\nf1 = {f1}\nf2 = \"0\"\ng = \"0.05\"\n[mesh]\nkind = \"file\"\n\
             path = \"../meshes/two_regions.msh\"\n"
        );
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases");
        let case = Case::parse(&text, "test case", dir).unwrap();
        let options = membrane_contact::run::Options {
            start,
            ..membrane_contact::run::Options::default()
        };
        let r = membrane_contact::run::run(&case, &options).unwrap();
        (
            r.solution.obstacle.stats.coarse_iterations.len(),
            r.summary(false),
        )
    };
    use membrane_contact::contact::Start;
    let tables = "{ loaded = \"-20\", free = \"0\" }";
    let (_, cold) = summary(tables, Start::Cold);
    assert!(
        cold.contains("not multigrid: a mesh read from a file or given, unrefined, has no coarser levels"),
        "{cold}"
    );
    let (levels, tables) = summary(tables, Start::Nested);
    assert!(
        levels == 0 && tables.contains("and from a cold start: no coarser mesh"),
        "{tables}"
    );
    let (levels, one) = summary("\"if(x < 1, -20, 0)\"", Start::Nested);
    assert!(levels > 0 && one.contains("give the guess only"), "{one}");
}
