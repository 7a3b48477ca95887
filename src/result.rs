//! Result files that ParaView opens. A result is a directory (put in place whole by
//! [`crate::atomic`]) holding
//! - `solution.h5`: the mesh T_h under `/mesh` (`geometry`, `topology` and the vertex and cell
//!   fields), when asked for the dual submesh S_h under `/dual` (its cell fields), and the case,
//!   the parameters, the solver statistics, the checks and the errors as attributes of `/`;
//! - `solution.xdmf` (and `dual.xdmf` with S_h): the grids and their fields, for ParaView's Xdmf3
//!   reader (float data with `Precision="8"`).
//!
//! S_h has six times the triangles of T_h and its points are the vertices, edge midpoints and
//! barycentres: written, it is about four fifths of the result. λ_h is on T_h anyway (`lambda`, its
//! nodal values λ_a, constant on each D_a), so S_h is written only on request.
//!
//! Each quantity describes itself ([`Describe`]); a result writes what its parts describe.
//!
//! The writer streams: grids and fields go to their datasets a million rows at a time, S_h is
//! computed as it is written, and a field constant on the dual cells is given per vertex
//! ([`Values::PerVertex`]), so writing costs no copy of a grid or a field; a field computed from
//! others (an expression at the vertices, flags as numbers) is computed as it is written
//! ([`Values::Computed`]).

use crate::mesh::{DualMesh, Mesh};
use hdf5::types::VarLenUnicode;
use hdf5::H5Type;
use ndarray::{ArrayView1, ArrayView2};
use std::borrow::Cow;
use std::fmt::Write as _;
use std::ops::Range;
use std::path::Path;
use std::sync::Arc;

/// The HDF5 file of a result directory.
pub const SOLUTION_H5: &str = "solution.h5";

/// Rows written to a dataset at a time (a few MB of buffer).
const CHUNK_ROWS: usize = 1 << 20;

/// Where a field lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// One value per vertex of T_h (a P1 field).
    Vertices,
    /// One value per triangle of T_h (e.g. an error indicator).
    Cells,
    /// One value per cell of S_h (constant on each, e.g. on each D_a).
    DualCells,
}

/// A named field of a result.
#[derive(Debug, Clone)]
pub struct Field<'a> {
    /// The dataset and ParaView name.
    pub name: &'static str,
    /// Where it lives.
    pub place: Place,
    /// Its values.
    pub values: Values<'a>,
}

/// The values of a field.
#[derive(Clone)]
pub enum Values<'a> {
    /// One per item of the field's place.
    Items(Cow<'a, [f64]>),
    /// One value v_a per vertex a of T_h, for the field Σ_a v_a χ_{D_a} on the cells of S_h
    /// (`Place::DualCells`), constant on each dual cell D_a: the writer expands it as it writes.
    PerVertex(Cow<'a, [f64]>),
    /// One per item of the field's place, computed as they are written.
    Computed {
        /// The number of items.
        len: usize,
        /// Appends the values of a range of items.
        items: Arc<Items<'a>>,
    },
}

/// What computes the values of a range of items ([`Values::Computed`]).
pub type Items<'a> = dyn Fn(Range<usize>, &mut Vec<f64>) + Send + Sync + 'a;

impl std::fmt::Debug for Values<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Values::Items(v) => f.debug_tuple("Items").field(&v.len()).finish(),
            Values::PerVertex(v) => f.debug_tuple("PerVertex").field(&v.len()).finish(),
            Values::Computed { len, .. } => f.debug_tuple("Computed").field(len).finish(),
        }
    }
}

impl<'a> Field<'a> {
    /// A field borrowing its values.
    pub fn new(name: &'static str, place: Place, values: &'a [f64]) -> Self {
        Field {
            name,
            place,
            values: Values::Items(Cow::Borrowed(values)),
        }
    }

    /// A field owning its values.
    pub fn owned(name: &'static str, place: Place, values: Vec<f64>) -> Self {
        Field {
            name,
            place,
            values: Values::Items(Cow::Owned(values)),
        }
    }

    /// A field of `len` items whose values `items(range, out)` computes as they are written.
    pub fn computed(
        name: &'static str,
        place: Place,
        len: usize,
        items: impl Fn(Range<usize>, &mut Vec<f64>) + Send + Sync + 'a,
    ) -> Self {
        Field {
            name,
            place,
            values: Values::Computed {
                len,
                items: Arc::new(items),
            },
        }
    }

    /// The same field owning its values (a copy of borrowed ones, computed ones computed), free
    /// of what it borrowed: to hand a run's fields out once the run is gone (the Python package's
    /// `Result`).
    pub fn into_owned(self) -> Field<'static> {
        let values = match self.values {
            Values::PerVertex(v) => Values::PerVertex(Cow::Owned(v.into_owned())),
            v => Values::Items(Cow::Owned(v.whole().into_owned())),
        };
        Field {
            name: self.name,
            place: self.place,
            values,
        }
    }

    /// The values: one per item of the field's place, or for [`Values::PerVertex`] one per
    /// vertex of T_h (computed ones computed).
    pub fn values(&self) -> Cow<'_, [f64]> {
        self.values.whole()
    }

    /// The field Σ_a v_a χ_{D_a} of S_h, constant on each dual cell D_a, by its values v_a at the
    /// vertices of T_h.
    pub fn on_dual_cells(name: &'static str, per_vertex: impl Into<Cow<'a, [f64]>>) -> Self {
        Field {
            name,
            place: Place::DualCells,
            values: Values::PerVertex(per_vertex.into()),
        }
    }
}

/// An attribute value of a result.
#[derive(Debug, Clone, PartialEq)]
pub enum Attr {
    /// A number.
    Float(f64),
    /// A count.
    Int(i64),
    /// Text.
    Text(String),
    /// A list of numbers.
    Floats(Vec<f64>),
}

impl From<usize> for Attr {
    fn from(v: usize) -> Self {
        Attr::Int(v as i64)
    }
}

impl From<f64> for Attr {
    fn from(v: f64) -> Self {
        Attr::Float(v)
    }
}

/// A named attribute.
pub type Attribute = (&'static str, Attr);

/// What a quantity contributes to a result file.
pub trait Describe {
    /// Its fields.
    fn fields(&self) -> Vec<Field<'_>> {
        Vec::new()
    }
    /// Its attributes.
    fn attributes(&self) -> Vec<Attribute> {
        Vec::new()
    }
}

/// Writes `solution.h5` and `solution.xdmf` into `dir`, and with a `dual` submesh its grid, its
/// fields (those at [`Place::DualCells`]; without it they are left out) and `dual.xdmf`.
pub fn write(
    dir: &Path,
    mesh: &Mesh,
    dual: Option<&DualMesh>,
    fields: &[Field],
    attrs: &[Attribute],
) -> Result<(), String> {
    write_in_chunks(dir, mesh, dual, fields, attrs, CHUNK_ROWS)
}

/// [`write()`], `chunk` rows at a time.
fn write_in_chunks(
    dir: &Path,
    mesh: &Mesh,
    dual: Option<&DualMesh>,
    fields: &[Field],
    attrs: &[Attribute],
    chunk: usize,
) -> Result<(), String> {
    let mut grids = vec![Grid {
        name: "mesh",
        xdmf: "solution.xdmf",
        triangulation: Triangulation::Mesh(mesh),
        places: &[Place::Vertices, Place::Cells],
    }];
    grids.extend(dual.map(|d| Grid {
        name: "dual",
        xdmf: "dual.xdmf",
        triangulation: Triangulation::Dual(*d),
        places: &[Place::DualCells],
    }));
    check_space(dir, &grids, fields)?;
    write_hdf5(&dir.join(SOLUTION_H5), &grids, fields, attrs, chunk).map_err(|e| no_space_hint(dir, e))?;
    for g in &grids {
        let text = xdmf(g, g.fields(fields));
        std::fs::write(dir.join(g.xdmf), text).map_err(|e| format!("{}: {e}", g.xdmf))?;
    }
    Ok(())
}

/// On a mesh with physical groups, the cell field `group`: the index of each triangle's physical
/// surface in the attribute `surface_groups` (−1 for none).
pub(crate) fn group_field(mesh: &Mesh) -> Option<Field<'static>> {
    let groups = mesh.groups()?;
    let index = (groups.triangle_groups().iter())
        .map(|&g| match g {
            crate::mesh::groups::NONE => -1.0,
            g => f64::from(g),
        })
        .collect();
    Some(Field::owned("group", Place::Cells, index))
}

/// On a mesh with physical groups, `surface_groups` and `curve_groups`: the names of the groups in
/// the order of their indices (a JSON list), and `groups_source`, the mesh file.
pub(crate) fn group_attributes(mesh: &Mesh) -> Vec<Attribute> {
    let Some(groups) = mesh.groups() else {
        return Vec::new();
    };
    let list = |names: &[String]| Attr::Text(serde_json::to_string(names).expect("strings"));
    vec![
        ("surface_groups", list(&groups.surfaces)),
        ("curve_groups", list(&groups.curves)),
        ("groups_source", Attr::Text(groups.source.clone())),
    ]
}

/// Writes `/mesh/boundary_edges` (the boundary edges of T_h, two vertices each, sorted) and
/// `/mesh/boundary_group` (the index of each one's physical curve in `curve_groups`, −1 for none).
fn write_boundary_groups(group: &hdf5::Group, mesh: &Mesh, chunk: usize) -> hdf5::Result<()> {
    let Some(groups) = mesh.groups() else {
        return Ok(());
    };
    let edges: Vec<((usize, usize), u32)> = groups.boundary_edges().collect();
    let ends = Dataset {
        name: "boundary_edges",
        rows: edges.len(),
        columns: 2,
    };
    ends.write(group, chunk, |rows, out: &mut Vec<i32>| {
        out.extend(edges[rows].iter().flat_map(|((a, b), _)| [*a as i32, *b as i32]))
    })?;
    let curve = Dataset {
        name: "boundary_group",
        rows: edges.len(),
        columns: 1,
    };
    curve.write(group, chunk, |rows, out: &mut Vec<i32>| {
        let index = |g: u32| {
            if g == crate::mesh::groups::NONE {
                -1
            } else {
                g as i32
            }
        };
        out.extend(edges[rows].iter().map(|(_, g)| index(*g)))
    })
}

/// A triangle grid as written to one HDF5 group and one XDMF file.
struct Grid<'a> {
    name: &'static str,
    xdmf: &'static str,
    triangulation: Triangulation<'a>,
    /// Where the fields of this grid live.
    places: &'static [Place],
}

/// The triangles of a grid: T_h as stored, or S_h computed as it is written.
#[derive(Clone, Copy)]
enum Triangulation<'a> {
    Mesh(&'a Mesh),
    Dual(DualMesh<'a>),
}

impl Grid<'_> {
    fn n_points(&self) -> usize {
        match self.triangulation {
            Triangulation::Mesh(m) => m.n_vertices(),
            Triangulation::Dual(d) => d.n_points(),
        }
    }

    fn n_cells(&self) -> usize {
        match self.triangulation {
            Triangulation::Mesh(m) => m.n_triangles(),
            Triangulation::Dual(d) => d.n_cells(),
        }
    }

    /// Values per field at `place`, and XDMF's name for it.
    fn layout(&self, place: Place) -> (usize, &'static str) {
        match place {
            Place::Vertices => (self.n_points(), "Node"),
            Place::Cells | Place::DualCells => (self.n_cells(), "Cell"),
        }
    }

    /// The fields of `fields` that live on this grid.
    fn fields<'f>(&self, fields: &'f [Field<'f>]) -> impl Iterator<Item = &'f Field<'f>> + use<'f, '_> {
        fields.iter().filter(|f| self.places.contains(&f.place))
    }

    /// The coordinates of the points `rows`, appended row by row to `out`.
    fn geometry(&self, rows: Range<usize>, out: &mut Vec<f64>) {
        match self.triangulation {
            Triangulation::Mesh(m) => out.extend(m.points[rows].iter().flatten()),
            Triangulation::Dual(d) => out.extend(rows.flat_map(|p| d.point(p))),
        }
    }

    /// The points of the cells `rows`, appended row by row to `out` (32-bit: [`write_hdf5`] checks
    /// that they fit).
    fn topology(&self, rows: Range<usize>, out: &mut Vec<i32>) {
        match self.triangulation {
            Triangulation::Mesh(m) => out.extend(rows.flat_map(|t| m.triangle(t)).map(|v| v as i32)),
            Triangulation::Dual(d) => out.extend(rows.flat_map(|s| d.cell(s)).map(|v| v as i32)),
        }
    }

    /// The values of `f` on the items `rows`, appended to `out`.
    fn values(&self, f: &Field, rows: Range<usize>, out: &mut Vec<f64>) {
        match (&f.values, self.triangulation) {
            (Values::Items(v), _) => out.extend_from_slice(&v[rows]),
            (Values::Computed { items, .. }, _) => items(rows, out),
            (Values::PerVertex(v), Triangulation::Dual(d)) => out.extend(rows.map(|s| v[d.owner(s)])),
            (Values::PerVertex(_), Triangulation::Mesh(_)) => {
                panic!("field {}: values per vertex describe a field of S_h", f.name)
            }
        }
    }

    /// How many values `f` holds when it is whole: one per item, or one per vertex of T_h.
    fn stored_len(&self, f: &Field) -> usize {
        match (&f.values, self.triangulation) {
            (Values::PerVertex(_), Triangulation::Dual(d)) => d.mesh().n_vertices(),
            _ => self.layout(f.place).0,
        }
    }
}

impl Values<'_> {
    /// The number of values.
    fn len(&self) -> usize {
        match self {
            Values::Items(v) | Values::PerVertex(v) => v.len(),
            Values::Computed { len, .. } => *len,
        }
    }

    /// All the values, borrowed where they are held.
    fn whole(&self) -> Cow<'_, [f64]> {
        match self {
            Values::Items(v) | Values::PerVertex(v) => Cow::Borrowed(v),
            Values::Computed { len, items } => {
                let mut out = Vec::with_capacity(*len);
                items(0..*len, &mut out);
                Cow::Owned(out)
            }
        }
    }
}

/// Fails early, naming both sizes, when the result would not fit on its device.
fn check_space(dir: &Path, grids: &[Grid], fields: &[Field]) -> Result<(), String> {
    let bytes: usize = (grids.iter())
        .map(|g| {
            let data: usize = g.fields(fields).map(|f| 8 * g.layout(f.place).0).sum();
            16 * g.n_points() + 12 * g.n_cells() + data
        })
        .sum();
    match free_bytes(dir) {
        Some(free) if (bytes as f64) * 1.05 > free as f64 => Err(format!(
            "the result needs about {:.1} MB, but only {:.1} MB are free on its device",
            bytes as f64 / 1e6,
            free as f64 / 1e6
        )),
        _ => Ok(()),
    }
}

/// The bytes free for this user on the device holding `dir`.
fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let path = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: a valid path and a statvfs to fill.
    (unsafe { libc::statvfs(path.as_ptr(), &mut s) } == 0).then(|| s.f_bavail * s.f_frsize)
}

/// An HDF5 error on one line. The library's text for a failed read or write of the file goes on
/// with a ctime stamp, which ends in a line break, and the call's descriptor, buffer address and
/// sizes: it is cut before them, keeping the system's message (`file write failed: File too
/// large`). The caller names the file.
pub fn hdf5_error(e: &hdf5::Error) -> String {
    let text = e.to_string();
    let shown = match text.find(": time = ") {
        Some(cut) => {
            let (head, details) = text.split_at(cut);
            let system = (details.split_once("error message = '"))
                .and_then(|(_, m)| m.split_once('\''))
                .map(|(m, _)| m)
                .filter(|m| !head.contains(&format!("'{m}'")));
            match system {
                Some(m) => format!("{head}: {m}"),
                None => head.to_string(),
            }
        }
        None => text,
    };
    shown.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// HDF5 reports a full disk as "file write failed": say what it is.
fn no_space_hint(dir: &Path, e: String) -> String {
    match free_bytes(dir) {
        Some(free) if free < 1 << 20 => format!("{e} (no space left on device)"),
        _ => e,
    }
}

/// Writes the grids, their fields and the attributes to the HDF5 file `path`, `chunk` rows at a
/// time.
fn write_hdf5(
    path: &Path,
    grids: &[Grid],
    fields: &[Field],
    attrs: &[Attribute],
    chunk: usize,
) -> Result<(), String> {
    let named = |e: hdf5::Error| format!("{SOLUTION_H5}: cannot write HDF5: {}", hdf5_error(&e));
    let file = hdf5::File::create(path).map_err(named)?;
    for grid in grids {
        let group = file.create_group(grid.name).map_err(named)?;
        // 32-bit vertex indices (XDMF `Int`, `Precision="4"`): the memory guard stops meshes
        // long before 2³¹ vertices.
        if i32::try_from(grid.n_points()).is_err() {
            return Err(format!("{SOLUTION_H5}: more than 2³¹ vertices"));
        }
        let geometry = Dataset {
            name: "geometry",
            rows: grid.n_points(),
            columns: 2,
        };
        geometry
            .write(&group, chunk, |rows, out| grid.geometry(rows, out))
            .map_err(named)?;
        let topology = Dataset {
            name: "topology",
            rows: grid.n_cells(),
            columns: 3,
        };
        topology
            .write(&group, chunk, |rows, out| grid.topology(rows, out))
            .map_err(named)?;
        if let Triangulation::Mesh(mesh) = grid.triangulation {
            write_boundary_groups(&group, mesh, chunk).map_err(named)?;
        }
        for f in grid.fields(fields) {
            assert_eq!(
                f.values.len(),
                grid.stored_len(f),
                "field {} has one value per item",
                f.name
            );
            let values = Dataset {
                name: f.name,
                rows: grid.layout(f.place).0,
                columns: 1,
            };
            values
                .write(&group, chunk, |rows, out| grid.values(f, rows, out))
                .map_err(named)?;
        }
    }
    for (name, value) in attrs {
        match value {
            Attr::Float(v) => file
                .new_attr::<f64>()
                .create(*name)
                .and_then(|a| a.write_scalar(v)),
            Attr::Int(v) => file
                .new_attr::<i64>()
                .create(*name)
                .and_then(|a| a.write_scalar(v)),
            Attr::Text(s) => {
                let s: VarLenUnicode = s.replace('\0', "").parse().expect("no NUL bytes");
                file.new_attr::<VarLenUnicode>()
                    .create(*name)
                    .and_then(|a| a.write_scalar(&s))
            }
            Attr::Floats(v) => file
                .new_attr_builder()
                .with_data(ArrayView1::from(v.as_slice()))
                .create(*name)
                .map(|_| ()),
        }
        .map_err(named)?;
    }
    file.close().map_err(named)
}

/// A dataset of `rows` rows of `columns` values (one column: a 1-D dataset).
struct Dataset {
    name: &'static str,
    rows: usize,
    columns: usize,
}

impl Dataset {
    /// Creates the dataset in `group` with its full shape and writes it `chunk` rows at a time,
    /// `fill(rows, out)` appending the values of `rows` to `out`.
    fn write<T: H5Type>(
        &self,
        group: &hdf5::Group,
        chunk: usize,
        mut fill: impl FnMut(Range<usize>, &mut Vec<T>),
    ) -> hdf5::Result<()> {
        let builder = group.new_dataset::<T>();
        let dataset = match self.columns {
            1 => builder.shape(self.rows),
            c => builder.shape((self.rows, c)),
        }
        .create(self.name)?;
        let mut buffer = Vec::with_capacity(chunk.min(self.rows) * self.columns);
        for start in (0..self.rows).step_by(chunk) {
            let rows = start..self.rows.min(start + chunk);
            buffer.clear();
            fill(rows.clone(), &mut buffer);
            match self.columns {
                1 => dataset.write_slice(ArrayView1::from(&buffer[..]), rows),
                c => {
                    let view = ArrayView2::from_shape((rows.len(), c), &buffer).expect("whole rows");
                    dataset.write_slice(view, (rows, ..))
                }
            }?;
        }
        Ok(())
    }
}

/// The XDMF description of a grid and its fields; the heavy data are in `solution.h5` beside it.
fn xdmf<'a>(g: &Grid, fields: impl Iterator<Item = &'a Field<'a>>) -> String {
    let grid = grid_element(g, fields, SOLUTION_H5, "");
    format!("<?xml version=\"1.0\"?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n{grid}  </Domain>\n</Xdmf>\n")
}

/// The `<Grid>` element of a grid and its fields, the heavy data in the HDF5 file `h5`; `time`
/// is an optional `<Time>` line.
fn grid_element<'a>(g: &Grid, fields: impl Iterator<Item = &'a Field<'a>>, h5: &str, time: &str) -> String {
    let item = |dims: String, number: &str, path: String| {
        let precision = if number == "Int" { 4 } else { 8 };
        format!("<DataItem Dimensions=\"{dims}\" NumberType=\"{number}\" Precision=\"{precision}\" Format=\"HDF\">{h5}:{path}</DataItem>")
    };
    let (np, nc) = (g.n_points(), g.n_cells());
    let mut s = format!("    <Grid Name=\"{}\" GridType=\"Uniform\">\n{time}", g.name);
    let _ = writeln!(
        s,
        "      <Topology TopologyType=\"Triangle\" NumberOfElements=\"{nc}\" NodesPerElement=\"3\">\n        {}\n      </Topology>",
        item(format!("{nc} 3"), "Int", format!("/{}/topology", g.name))
    );
    let _ = writeln!(
        s,
        "      <Geometry GeometryType=\"XY\">\n        {}\n      </Geometry>",
        item(format!("{np} 2"), "Float", format!("/{}/geometry", g.name))
    );
    for f in fields {
        let (len, center) = g.layout(f.place);
        let _ = writeln!(
            s,
            "      <Attribute Name=\"{}\" AttributeType=\"Scalar\" Center=\"{center}\">\n        {}\n      </Attribute>",
            f.name,
            item(len.to_string(), "Float", format!("/{}/{}", g.name, f.name))
        );
    }
    s.push_str("    </Grid>\n");
    s
}

/// The `<Grid>` element of T_h and its fields of a result written by [`write()`] into the
/// directory `dir` (relative to the time series file), at time `time`.
pub fn step_grid(dir: &str, time: f64, mesh: &Mesh, fields: &[Field]) -> String {
    let g = Grid {
        name: "mesh",
        xdmf: "",
        triangulation: Triangulation::Mesh(mesh),
        places: &[Place::Vertices, Place::Cells],
    };
    let time = format!("      <Time Value=\"{time}\"/>\n");
    grid_element(&g, g.fields(fields), &format!("{dir}/{SOLUTION_H5}"), &time)
}

/// Writes the XDMF time series of the `grids` of [`step_grid`] to `path`: ParaView opens the
/// sequence of meshes and fields as one dataset with a time slider.
pub fn time_series(path: &Path, grids: &[String]) -> Result<(), String> {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n  <Grid Name=\"steps\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
    );
    for g in grids {
        s += g;
    }
    s += "  </Grid>\n  </Domain>\n</Xdmf>\n";
    std::fs::write(path, s).map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Diagonal, Edges};

    #[test]
    fn a_result_written_a_few_rows_at_a_time_holds_the_values_in_memory() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 4, Diagonal::Crossed).unwrap();
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        let u: Vec<f64> = (0..mesh.n_vertices()).map(|a| (a as f64).sin()).collect();
        let on_cells: Vec<f64> = (0..mesh.n_triangles()).map(|t| t as f64 / 7.0).collect();
        let on_dual: Vec<f64> = (0..dual.n_cells()).map(|s| s as f64 / 3.0).collect();
        let fields = [
            Field::new("u", Place::Vertices, &u),
            Field::owned("k", Place::Cells, on_cells.clone()),
            Field::on_dual_cells("u_dual", &u[..]),
            Field::new("s", Place::DualCells, &on_dual),
            // Computed as written, chunk by chunk: the item's index times 3.
            Field::computed("c", Place::Vertices, u.len(), |rows, out| {
                out.extend(rows.map(|a| 3.0 * a as f64));
            }),
        ];
        let chunk = 5;
        assert!([u.len(), on_cells.len(), dual.n_points()]
            .iter()
            .all(|n| n % chunk != 0 && *n > chunk));
        let dir = tempfile::tempdir().unwrap();
        write_in_chunks(dir.path(), &mesh, Some(&dual), &fields, &[], chunk).unwrap();
        let file = hdf5::File::open(dir.path().join(SOLUTION_H5)).unwrap();
        let read = |path: &str, shape: &[usize]| {
            let d = file.dataset(path).unwrap();
            assert_eq!(d.shape(), shape, "{path}");
            d
        };
        let f64s = |path: &str, shape: &[usize]| {
            let d = read(path, shape);
            assert!(d.dtype().unwrap().is::<f64>(), "{path}");
            d.read_raw::<f64>().unwrap()
        };
        let i32s = |path: &str, shape: &[usize]| {
            let d = read(path, shape);
            assert!(d.dtype().unwrap().is::<i32>(), "{path}");
            d.read_raw::<i32>().unwrap()
        };
        let (n, nt) = (mesh.n_vertices(), mesh.n_triangles());
        let (np, ns) = (dual.n_points(), dual.n_cells());
        let flat = |v: &[[usize; 3]]| v.iter().flatten().map(|&i| i as i32).collect::<Vec<_>>();
        assert_eq!(f64s("mesh/geometry", &[n, 2]), mesh.points.concat());
        assert_eq!(
            i32s("mesh/topology", &[nt, 3]),
            flat(&mesh.triangles().collect::<Vec<_>>())
        );
        let points: Vec<[f64; 2]> = (0..np).map(|p| dual.point(p)).collect();
        let cells: Vec<[usize; 3]> = (0..ns).map(|s| dual.cell(s)).collect();
        assert_eq!(f64s("dual/geometry", &[np, 2]), points.concat());
        assert_eq!(i32s("dual/topology", &[ns, 3]), flat(&cells));
        assert_eq!(f64s("mesh/u", &[n]), u);
        assert_eq!(f64s("mesh/k", &[nt]), on_cells);
        let expanded: Vec<f64> = (0..ns).map(|s| u[dual.owner(s)]).collect();
        assert_eq!(f64s("dual/u_dual", &[ns]), expanded);
        assert_eq!(f64s("dual/s", &[ns]), on_dual);
        let thrice: Vec<f64> = (0..n).map(|a| 3.0 * a as f64).collect();
        assert_eq!(f64s("mesh/c", &[n]), thrice);
        assert_eq!(fields[4].values(), &thrice[..], "the values computed whole");
    }
}
