//! Result files that ParaView opens. A result is a directory (put in place whole by
//! [`crate::atomic`]) holding
//! - `solution.h5`: the mesh T_h under `/mesh` (`geometry`, `topology` and the vertex fields), the
//!   dual submesh S_h under `/dual` (its cell fields), and the case, the parameters, the solver
//!   statistics, the checks and the errors as attributes of `/`;
//! - `solution.xdmf` and `dual.xdmf`: the two grids and their fields, for ParaView's Xdmf3 reader
//!   (float data with `Precision="8"`).
//!
//! Each quantity describes itself ([`Describe`]); a result writes what its parts describe.

use crate::mesh::{DualMesh, Mesh};
use hdf5::types::VarLenUnicode;
use ndarray::{Array2, ArrayView1};
use std::borrow::Cow;
use std::fmt::Write as _;
use std::path::Path;

/// The HDF5 file of a result directory.
pub const SOLUTION_H5: &str = "solution.h5";

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
    pub values: Cow<'a, [f64]>,
}

impl<'a> Field<'a> {
    /// A field borrowing its values.
    pub fn new(name: &'static str, place: Place, values: &'a [f64]) -> Self {
        Field {
            name,
            place,
            values: Cow::Borrowed(values),
        }
    }

    /// A field owning its values.
    pub fn owned(name: &'static str, place: Place, values: Vec<f64>) -> Self {
        Field {
            name,
            place,
            values: Cow::Owned(values),
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

/// Writes `solution.h5`, `solution.xdmf` and `dual.xdmf` into `dir`.
pub fn write(
    dir: &Path,
    mesh: &Mesh,
    dual: &DualMesh,
    fields: &[Field],
    attrs: &[Attribute],
) -> Result<(), String> {
    let grids = [
        Grid {
            name: "mesh",
            xdmf: "solution.xdmf",
            points: &mesh.points,
            triangles: &mesh.triangles,
            places: &[Place::Vertices, Place::Cells],
        },
        Grid {
            name: "dual",
            xdmf: "dual.xdmf",
            points: &dual.points,
            triangles: &dual.triangles,
            places: &[Place::DualCells],
        },
    ];
    check_space(dir, &grids, fields)?;
    write_hdf5(&dir.join(SOLUTION_H5), &grids, fields, attrs).map_err(|e| no_space_hint(dir, e))?;
    for g in &grids {
        let text = xdmf(g, fields.iter().filter(|f| g.places.contains(&f.place)));
        std::fs::write(dir.join(g.xdmf), text).map_err(|e| format!("{}: {e}", g.xdmf))?;
    }
    Ok(())
}

/// A triangle grid as written to one HDF5 group and one XDMF file.
struct Grid<'a> {
    name: &'static str,
    xdmf: &'static str,
    points: &'a [[f64; 2]],
    triangles: &'a [[usize; 3]],
    /// Where the fields of this grid live.
    places: &'static [Place],
}

impl Grid<'_> {
    /// Values per field at `place`, and XDMF's name for it.
    fn layout(&self, place: Place) -> (usize, &'static str) {
        match place {
            Place::Vertices => (self.points.len(), "Node"),
            Place::Cells | Place::DualCells => (self.triangles.len(), "Cell"),
        }
    }
}

/// Fails early, naming both sizes, when the result would not fit on its device.
fn check_space(dir: &Path, grids: &[Grid], fields: &[Field]) -> Result<(), String> {
    let bytes: usize = grids
        .iter()
        .map(|g| 16 * g.points.len() + 12 * g.triangles.len())
        .sum::<usize>()
        + fields.iter().map(|f| 8 * f.values.len()).sum::<usize>();
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

/// HDF5 reports a full disk as "file write failed": say what it is.
fn no_space_hint(dir: &Path, e: String) -> String {
    match free_bytes(dir) {
        Some(free) if free < 1 << 20 => format!("{e} (no space left on device)"),
        _ => e,
    }
}

fn write_hdf5(path: &Path, grids: &[Grid], fields: &[Field], attrs: &[Attribute]) -> Result<(), String> {
    let named = |e: hdf5::Error| format!("{SOLUTION_H5}: cannot write HDF5: {e}");
    let file = hdf5::File::create(path).map_err(named)?;
    for grid in grids {
        let group = file.create_group(grid.name).map_err(named)?;
        let points = Array2::from_shape_fn((grid.points.len(), 2), |(i, k)| grid.points[i][k]);
        // 32-bit vertex indices (XDMF `Int`, `Precision="4"`): the memory guard stops meshes
        // long before 2³¹ vertices.
        if i32::try_from(grid.points.len()).is_err() {
            return Err(format!("{SOLUTION_H5}: more than 2³¹ vertices"));
        }
        let cells = Array2::from_shape_fn((grid.triangles.len(), 3), |(i, k)| grid.triangles[i][k] as i32);
        group
            .new_dataset_builder()
            .with_data(&points)
            .create("geometry")
            .map_err(named)?;
        group
            .new_dataset_builder()
            .with_data(&cells)
            .create("topology")
            .map_err(named)?;
        for f in fields.iter().filter(|f| grid.places.contains(&f.place)) {
            assert_eq!(
                f.values.len(),
                grid.layout(f.place).0,
                "field {} has one value per item",
                f.name
            );
            group
                .new_dataset_builder()
                .with_data(ArrayView1::from(&f.values[..]))
                .create(f.name)
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
    let (np, nc) = (g.points.len(), g.triangles.len());
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
        points: &mesh.points,
        triangles: &mesh.triangles,
        places: &[Place::Vertices, Place::Cells],
    };
    let time = format!("      <Time Value=\"{time}\"/>\n");
    let fields = fields.iter().filter(|f| g.places.contains(&f.place));
    grid_element(&g, fields, &format!("{dir}/{SOLUTION_H5}"), &time)
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
