//! A datum of the case: one expression on all of ω (or ∂ω), or one expression per physical group
//! of a Gmsh mesh ([`crate::mesh::Groups`]): per physical surface for the loads and ψ, per
//! physical curve for the boundary values g and g2.
//!
//! On a mesh, a datum resolves to its [`Pieces`]: the expression of every triangle (or boundary
//! edge). The loads are integrated triangle by triangle with the expression of the triangle's
//! group ([`visit`]), so a jump between groups on the edges of the mesh is integrated exactly as
//! the quadrature integrates each side: nothing is smeared across the interface. Vertex values
//! (g and g2 at the boundary vertices, ψ at every vertex) are taken from the groups around the
//! vertex, which must agree there ([`vertex_values`]).

use crate::assembly::{Quadrature, QuadraturePoint};
use crate::expr::Expr;
use crate::mesh::groups::{Groups, NONE};
use crate::mesh::{Mesh, Point};
use crate::problem::DataError;

/// One expression, or one per group name (in the order the case gives them).
#[derive(Debug, Clone)]
pub enum Datum {
    /// The same expression everywhere.
    Expr(Expr),
    /// An expression per physical group, by name.
    Table(Vec<(String, Expr)>),
}

impl From<Expr> for Datum {
    fn from(e: Expr) -> Self {
        Datum::Expr(e)
    }
}

/// Which kind of physical group a datum is given on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum On {
    /// Physical surfaces: one expression per triangle.
    Surfaces,
    /// Physical curves: one expression per boundary edge.
    Curves,
}

impl On {
    fn noun(self) -> &'static str {
        match self {
            On::Surfaces => "physical surface",
            On::Curves => "physical curve",
        }
    }
}

impl Datum {
    /// The value when the datum is one constant expression.
    pub fn constant(&self) -> Option<f64> {
        match self {
            Datum::Expr(e) => e.constant(),
            Datum::Table(_) => None,
        }
    }

    /// The expression, when the datum is one.
    pub fn expr(&self) -> Option<&Expr> {
        match self {
            Datum::Expr(e) => Some(e),
            Datum::Table(_) => None,
        }
    }

    /// The group whose entry a table gives on triangle t of `mesh` (for messages); `None` for one
    /// expression.
    pub fn group_of_triangle(&self, mesh: &Mesh, t: usize) -> Option<String> {
        let pieces = self.pieces("", mesh, On::Surfaces).ok()?;
        pieces
            .single()
            .is_none()
            .then(|| pieces.name_of(self, pieces.entry(t)))
    }

    /// Whether the datum is a table per group.
    pub fn is_table(&self) -> bool {
        matches!(self, Datum::Table(_))
    }

    /// The datum `name` on `mesh`: the expression of every triangle (`On::Surfaces`) or boundary
    /// edge (`On::Curves`). A table needs a mesh with groups, names that are groups of the mesh
    /// and an entry for the group of every triangle (boundary edge).
    pub fn pieces<'a>(&'a self, name: &'static str, mesh: &'a Mesh, on: On) -> Result<Pieces<'a>, DataError> {
        let table = match self {
            Datum::Expr(e) => {
                return Ok(Pieces {
                    exprs: vec![e],
                    of_group: Vec::new(),
                    mesh,
                    on,
                })
            }
            Datum::Table(table) => table,
        };
        let group_error = |why: String| DataError::Group { name, why };
        let groups = mesh.groups().ok_or_else(|| {
            group_error(
                "a table per physical group needs a mesh with physical groups (a Gmsh .msh file, an .xdmf file with dolfinx meshtags or with meshio's cell data gmsh:physical (or one cell attribute of whole numbers), or a result of this program read back); this mesh has none"
                    .into(),
            )
        })?;
        let names = group_names(groups, table, on).map_err(group_error)?;
        let of_group = entries(mesh, groups, names, table, on).map_err(group_error)?;
        if let Some(why) = unused_entry(table, &of_group, on, &groups.source) {
            return Err(group_error(why));
        }
        Ok(Pieces {
            exprs: table.iter().map(|(_, e)| e).collect(),
            of_group,
            mesh,
            on,
        })
    }
}

/// The names of the mesh's groups `on` which the datum is given, once every key of `table` is
/// found among them (and they name their elements unambiguously).
fn group_names<'g>(groups: &'g Groups, table: &[(String, Expr)], on: On) -> Result<&'g [String], String> {
    let k = usize::from(on == On::Curves);
    let (names, noun, source) = ([&groups.surfaces, &groups.curves][k], on.noun(), &groups.source);
    if let Some(why) = &groups.ambiguous[k] {
        return Err(format!("{source}: {why}"));
    }
    for (key, _) in table {
        let count = names.iter().filter(|n| *n == key).count();
        if count > 1 {
            return Err(format!(
                "'{key}' names {count} {noun}s of {source} (groups of different tags): data per \
                 group need each group's name to be its own"
            ));
        }
        if count == 0 && groups.unused[k].contains(key) {
            return Err(format!(
                "'{key}' is a name {source} declares (in $PhysicalNames, or a meshio mesh's \
                 field_data), but no element carries it (an entity without its physical tag?)"
            ));
        }
        if count == 0 {
            let listed: Vec<String> = names.iter().map(|n| format!("'{n}'")).collect();
            let theirs = match listed.is_empty() {
                true => format!("it has no {noun}s"),
                false => format!("its {noun}s: {}", listed.join(", ")),
            };
            return Err(format!("'{key}' is not a {noun} of {source} ({theirs})"));
        }
    }
    Ok(names)
}

/// The entry of `table` of every triangle (`On::Surfaces`) or boundary edge (`On::Curves`), by
/// its group among `names`; the first element whose group has none is named in the error.
fn entries(
    mesh: &Mesh,
    groups: &Groups,
    names: &[String],
    table: &[(String, Expr)],
    on: On,
) -> Result<Vec<u32>, String> {
    // Group index → entry of the table.
    let entry: Vec<u32> = (names.iter())
        .map(|n| table.iter().position(|(k, _)| k == n).map_or(NONE, |i| i as u32))
        .collect();
    let missing = |g: u32, what: String| match g {
        NONE => format!(
            "{what} belongs to no {} of {}: with a table, every one must belong to one",
            on.noun(),
            groups.source
        ),
        g => format!(
            "the table has no entry for the {} '{}' of {} ({what} belongs to it)",
            on.noun(),
            names[g as usize],
            groups.source
        ),
    };
    let of = |g: u32, what: &dyn Fn() -> String| match entry.get(g as usize) {
        Some(&e) if e != NONE => Ok(e),
        _ => Err(missing(g, what())),
    };
    match on {
        On::Surfaces => (groups.triangle_groups().iter().enumerate())
            .map(|(t, &g)| {
                of(g, &|| {
                    format!("the triangle at {}", Point(centroid(mesh.corners(t))))
                })
            })
            .collect(),
        On::Curves => (groups.boundary_edges())
            .map(|((a, b), g)| {
                let (p, q) = (mesh.points[a], mesh.points[b]);
                of(g, &|| format!("the boundary edge {}–{}", Point(p), Point(q)))
            })
            .collect(),
    }
}

/// Why an entry of `table` is of no use, if one is: no element takes it (`of_group`: the entry
/// of each element), as a physical curve inside ω, whose boundary values would be ignored.
fn unused_entry<T>(table: &[(String, T)], of_group: &[u32], on: On, source: &str) -> Option<String> {
    let mut used = vec![false; table.len()];
    of_group.iter().for_each(|&e| used[e as usize] = true);
    let key = &table[used.iter().position(|u| !u)?].0;
    let element = match on {
        On::Surfaces => "triangle",
        On::Curves => "boundary edge: values on curves are taken on ∂ω only",
    };
    Some(format!("the {} '{key}' of {source} has no {element}", on.noun()))
}

fn centroid([p, q, r]: [[f64; 2]; 3]) -> [f64; 2] {
    [(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0]
}

/// A datum resolved on a mesh: the expression of every triangle or boundary edge.
#[derive(Debug, Clone)]
pub struct Pieces<'a> {
    /// The distinct expressions.
    exprs: Vec<&'a Expr>,
    /// The entry of `exprs` of each triangle (or boundary edge, in the order of
    /// [`crate::mesh::Groups::boundary_edges`]); empty for one expression.
    of_group: Vec<u32>,
    mesh: &'a Mesh,
    on: On,
}

impl<'a> Pieces<'a> {
    /// The one expression, when there is no table.
    pub fn single(&self) -> Option<&'a Expr> {
        self.of_group.is_empty().then(|| self.exprs[0])
    }

    /// The distinct expressions, in the order of [`Pieces::entry`].
    pub(crate) fn exprs(&self) -> &[&'a Expr] {
        &self.exprs
    }

    /// The entry of [`Pieces::exprs`] on triangle t (surfaces).
    #[inline]
    pub(crate) fn entry(&self, t: usize) -> usize {
        self.of_group.get(t).map_or(0, |&e| e as usize)
    }

    /// The expression on triangle t.
    pub fn on_triangle(&self, t: usize) -> &'a Expr {
        debug_assert_eq!(self.on, On::Surfaces);
        self.exprs[self.entry(t)]
    }

    /// The expression on the boundary edge (a, b) (either order).
    pub fn on_edge(&self, a: usize, b: usize) -> &'a Expr {
        self.exprs[self.edge_entry(a, b)]
    }

    /// The entry of [`Pieces::exprs`] on the boundary edge (a, b) (either order).
    pub(crate) fn edge_entry(&self, a: usize, b: usize) -> usize {
        debug_assert_eq!(self.on, On::Curves);
        if self.of_group.is_empty() {
            return 0;
        }
        let groups = self
            .mesh
            .groups()
            .expect("a table is resolved on a mesh with groups");
        let i = groups.edge_index(a, b).expect("a boundary edge");
        self.of_group[i] as usize
    }

    /// The group name of entry e of a table (for messages), or "" for one expression.
    fn name_of(&self, datum: &Datum, e: usize) -> String {
        match datum {
            Datum::Table(t) => t[e].0.clone(),
            Datum::Expr(_) => String::new(),
        }
    }
}

/// Visits the triangles (or cells) `range` with the fields evaluated at their quadrature points,
/// as [`Quadrature::visit`], each field by the expression of the triangle `triangle(s)` the cell
/// s lies in: runs of cells with the same expressions are evaluated together.
pub fn visit<const E: usize>(
    quadrature: &Quadrature,
    corners: impl Fn(usize) -> [[f64; 2]; 3],
    triangle: impl Fn(usize) -> usize,
    range: std::ops::Range<usize>,
    fields: [&Pieces; E],
    mut visit: impl FnMut(usize, &[QuadraturePoint], [&[f64]; E]),
) {
    if let Some(single) = fields.iter().map(|p| p.single()).collect::<Option<Vec<_>>>() {
        let exprs: [&Expr; E] = std::array::from_fn(|e| single[e]);
        return quadrature.visit(corners, range, exprs, visit);
    }
    let key = |s: usize| fields.map(|p| p.entry(triangle(s)));
    let mut start = range.start;
    while start < range.end {
        let k = key(start);
        let mut end = start + 1;
        while end < range.end && key(end) == k {
            end += 1;
        }
        let exprs: [&Expr; E] = std::array::from_fn(|e| fields[e].exprs[k[e]]);
        quadrature.visit(&corners, start..end, exprs, &mut visit);
        start = end;
    }
}

/// The values of `datum` (named `name`) at the vertices: at every vertex for surfaces (ψ), at the
/// boundary vertices for curves (g, g2; `None` inside). Each value must be finite; with a table, a
/// vertex shared by two groups takes their common value, which must agree to
/// 1e-12 · max(1, |value|).
pub fn vertex_values(
    name: &'static str,
    datum: &Datum,
    mesh: &Mesh,
    on: On,
) -> Result<Vec<Option<f64>>, DataError> {
    let pieces = datum.pieces(name, mesh, on)?;
    let finite = |entry: usize, p: [f64; 2]| {
        let value = pieces.exprs[entry].eval(p[0], p[1]);
        match value.is_finite() {
            true => Ok(value),
            false => Err(DataError::NotFinite {
                name,
                group: pieces.single().is_none().then(|| pieces.name_of(datum, entry)),
                point: p,
                value,
            }),
        }
    };
    let n = mesh.n_vertices();
    if pieces.single().is_some() {
        return (0..n)
            .map(|a| match on == On::Surfaces || mesh.on_boundary[a] {
                true => finite(0, mesh.points[a]).map(Some),
                false => Ok(None),
            })
            .collect();
    }
    // The first group seen at each vertex and its value.
    let mut first: Vec<Option<(usize, f64)>> = vec![None; n];
    let mut at = |a: usize, entry: usize| -> Result<(), DataError> {
        let p = mesh.points[a];
        match first[a] {
            Some((e, _)) if e == entry => Ok(()),
            Some((e, v)) => {
                let w = finite(entry, p)?;
                match (w - v).abs() <= 1e-12 * v.abs().max(1.0) {
                    true => Ok(()),
                    false => Err(DataError::Jump {
                        name,
                        point: p,
                        groups: [pieces.name_of(datum, e), pieces.name_of(datum, entry)],
                        values: [v, w],
                    }),
                }
            }
            None => {
                first[a] = Some((entry, finite(entry, p)?));
                Ok(())
            }
        }
    };
    match on {
        On::Surfaces => {
            for (t, tri) in mesh.triangles().enumerate() {
                for a in tri {
                    at(a, pieces.entry(t))?;
                }
            }
        }
        On::Curves => {
            let groups = mesh.groups().expect("a table is resolved on a mesh with groups");
            for (i, ((a, b), _)) in groups.boundary_edges().enumerate() {
                let entry = pieces.of_group[i] as usize;
                at(a, entry)?;
                at(b, entry)?;
            }
        }
    }
    Ok(first.into_iter().map(|f| f.map(|(_, v)| v)).collect())
}
