//! Results as HDF5 + XDMF that ParaView opens, and triangle meshes read from XDMF/HDF5.
//!
//! A result `NAME.h5` holds `/mesh/{geometry,topology}`, the vertex fields under `/fields`, the
//! dual submesh S_h under `/dual` with λ_h as cell data, and the case, parameters and solver
//! statistics as attributes of `/`. `NAME.xdmf` describes the mesh and its fields, `NAME-dual.xdmf`
//! the dual submesh (float data with `Precision="8"`). Both are written to temporary files and renamed, so a failure leaves no partial
//! file and never replaces an earlier result.

use crate::mesh::Mesh;
use hdf5::types::VarLenUnicode;
use ndarray::{Array2, ArrayView1};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A named field on the vertices or cells of a grid.
pub struct Field<'a> {
    pub name: &'a str,
    pub values: &'a [f64],
}

/// A triangle grid with fields, as written to one HDF5 group and one XDMF grid.
pub struct Grid<'a> {
    pub name: &'a str,
    pub points: &'a [[f64; 2]],
    pub triangles: &'a [[usize; 3]],
    pub point_fields: Vec<Field<'a>>,
    pub cell_fields: Vec<Field<'a>>,
}

/// An attribute value of the result file.
pub enum Attr {
    Float(f64),
    Int(i64),
    Text(String),
    Floats(Vec<f64>),
}

/// An I/O error naming the file.
#[derive(Debug)]
pub struct IoError(pub String);

impl std::fmt::Display for IoError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for IoError {}

/// Writes a file through a temporary file in the same directory and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let result = std::fs::write(&tmp, bytes).and_then(|_| std::fs::rename(&tmp, path));
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        IoError(format!("{}: {e}", path.display()))
    })
}

/// Writes `h5_path` and one XDMF sidecar per grid (`NAME.xdmf` for the first, `NAME-GRID.xdmf`
/// for the others, so that ParaView shows them as separate datasets), atomically: everything is
/// written to temporary files first and renamed at the end. Returns the XDMF paths.
pub fn write_result(h5_path: &Path, grids: &[Grid], attrs: &[(&str, Attr)]) -> Result<Vec<PathBuf>, IoError> {
    let dir = match h5_path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(IoError(format!(
            "{}: the output directory {} does not exist",
            h5_path.display(),
            dir.display()
        )));
    }
    let (Some(file_name), Some(stem)) = (h5_path.file_name(), h5_path.file_stem()) else {
        return Err(IoError(format!("{}: not a file name", h5_path.display())));
    };
    let (file_name, stem) = (file_name.to_string_lossy(), stem.to_string_lossy());
    let tmp = |p: &Path| {
        dir.join(format!(
            ".{}.tmp-{}",
            p.file_name().unwrap().to_string_lossy(),
            std::process::id()
        ))
    };
    // (temporary, final) pairs, the HDF5 file first.
    let mut files = vec![(tmp(h5_path), h5_path.to_path_buf())];
    for (i, g) in grids.iter().enumerate() {
        let name = if i == 0 {
            format!("{stem}.xdmf")
        } else {
            format!("{stem}-{}.xdmf", g.name)
        };
        let path = dir.join(name);
        files.push((tmp(&path), path));
    }
    let result = write_hdf5(&files[0].0, h5_path, grids, attrs)
        .and_then(|_| {
            for (g, (tmp, path)) in grids.iter().zip(&files[1..]) {
                std::fs::write(tmp, xdmf(&file_name, g))
                    .map_err(|e| IoError(format!("{}: {e}", path.display())))?;
            }
            Ok(())
        })
        .and_then(|_| {
            for (tmp, path) in &files {
                std::fs::rename(tmp, path).map_err(|e| IoError(format!("{}: {e}", path.display())))?;
            }
            Ok(())
        });
    if let Err(e) = result {
        for (tmp, _) in &files {
            let _ = std::fs::remove_file(tmp);
        }
        return Err(e);
    }
    Ok(files.into_iter().skip(1).map(|(_, p)| p).collect())
}

/// Writes the HDF5 file at `path`; errors name `shown`, the file the user asked for.
fn write_hdf5(path: &Path, shown: &Path, grids: &[Grid], attrs: &[(&str, Attr)]) -> Result<(), IoError> {
    let named = |e: hdf5::Error| IoError(format!("{}: cannot write HDF5: {e}", shown.display()));
    let file = hdf5::File::create(path).map_err(named)?;
    for grid in grids {
        let group = file.create_group(grid.name).map_err(named)?;
        let points = Array2::from_shape_fn((grid.points.len(), 2), |(i, k)| grid.points[i][k]);
        // 32-bit vertex indices (XDMF `Int`, `Precision="4"`): the memory guard stops meshes
        // long before 2³¹ vertices.
        if i32::try_from(grid.points.len()).is_err() {
            return Err(IoError(format!("{}: more than 2³¹ vertices", shown.display())));
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
        for f in grid.point_fields.iter().chain(&grid.cell_fields) {
            group
                .new_dataset_builder()
                .with_data(ArrayView1::from(f.values))
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

fn xdmf(h5_name: &str, g: &Grid) -> String {
    let item = |dims: String, number: &str, path: String| {
        let precision = if number == "Int" { 4 } else { 8 };
        format!("<DataItem Dimensions=\"{dims}\" NumberType=\"{number}\" Precision=\"{precision}\" Format=\"HDF\">{h5_name}:{path}</DataItem>")
    };
    let mut s = String::from("<?xml version=\"1.0\"?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n");
    {
        let (np, nc) = (g.points.len(), g.triangles.len());
        let _ = writeln!(s, "    <Grid Name=\"{}\" GridType=\"Uniform\">", g.name);
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
        for (fields, center, n) in [(&g.point_fields, "Node", np), (&g.cell_fields, "Cell", nc)] {
            for f in fields {
                let _ = writeln!(
                    s,
                    "      <Attribute Name=\"{}\" AttributeType=\"Scalar\" Center=\"{center}\">\n        {}\n      </Attribute>",
                    f.name,
                    item(n.to_string(), "Float", format!("/{}/{}", g.name, f.name))
                );
            }
        }
        s.push_str("    </Grid>\n");
    }
    s.push_str("  </Domain>\n</Xdmf>\n");
    s
}

/// Reads a triangle mesh from XDMF (with HDF5 heavy data, as meshio and dolfinx write it) or from
/// an HDF5 file with `/mesh/geometry` and `/mesh/topology` (a result of this program, or dolfinx's
/// `/Mesh/mesh/…`), and checks it.
pub fn read_mesh(path: &Path) -> Result<Mesh, IoError> {
    let (points, cells) = match path.extension().and_then(|e| e.to_str()) {
        Some("xdmf") => read_xdmf(path)?,
        _ => read_h5_mesh(path)?,
    };
    Mesh::new(points, cells).map_err(|e| IoError(format!("{}: {e}", path.display())))
}

type RawMesh = (Vec<[f64; 2]>, Vec<[usize; 3]>);

fn read_xdmf(path: &Path) -> Result<RawMesh, IoError> {
    let err = |m: String| IoError(format!("{}: {m}", path.display()));
    let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
    let options = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..Default::default()
    };
    let doc = roxmltree::Document::parse_with_options(&text, options)
        .map_err(|e| err(format!("not valid XDMF (XML): {e}")))?;
    let grid = doc
        .descendants()
        .find(|n| n.has_tag_name("Grid") && n.children().any(|c| c.has_tag_name("Topology")))
        .ok_or_else(|| err("no <Grid> with a <Topology> in the XDMF file".into()))?;
    let topology = grid.children().find(|c| c.has_tag_name("Topology")).unwrap();
    let kind = topology
        .attribute("TopologyType")
        .or(topology.attribute("Type"))
        .unwrap_or("?");
    if !kind.eq_ignore_ascii_case("triangle") {
        return Err(err(format!(
            "cell type '{kind}' is not supported: the mesh must be made of triangles"
        )));
    }
    let geometry = grid
        .children()
        .find(|c| c.has_tag_name("Geometry"))
        .ok_or_else(|| err("no <Geometry> in the XDMF grid".into()))?;
    let heavy = |node: roxmltree::Node| -> Result<(PathBuf, String), IoError> {
        let item = node
            .children()
            .find(|c| c.has_tag_name("DataItem"))
            .ok_or_else(|| err(format!("<{}> has no <DataItem>", node.tag_name().name())))?;
        if item.attribute("Format") != Some("HDF") {
            return Err(err(
                "only HDF heavy data is supported (DataItem Format=\"HDF\")".into()
            ));
        }
        let location = item.text().unwrap_or("").trim();
        let (file, dataset) = location
            .split_once(':')
            .ok_or_else(|| err(format!("DataItem '{location}' is not FILE:/PATH")))?;
        let base = path.parent().unwrap_or(Path::new(""));
        Ok((base.join(file), dataset.to_string()))
    };
    let (gfile, gpath) = heavy(geometry)?;
    let (tfile, tpath) = heavy(topology)?;
    let points = read_points(&gfile, &gpath)?;
    let cells = read_cells(&tfile, &tpath)?;
    Ok((points, cells))
}

fn read_h5_mesh(path: &Path) -> Result<RawMesh, IoError> {
    let file = open_h5(path)?;
    let (g, t) = if file.link_exists("/mesh/geometry") {
        ("/mesh/geometry", "/mesh/topology")
    } else {
        ("/Mesh/mesh/geometry", "/Mesh/mesh/topology")
    };
    drop(file);
    Ok((read_points(path, g)?, read_cells(path, t)?))
}

fn open_h5(path: &Path) -> Result<hdf5::File, IoError> {
    if !path.exists() {
        return Err(IoError(format!("{}: no such file", path.display())));
    }
    hdf5::File::open(path).map_err(|e| IoError(format!("{}: not a readable HDF5 file: {e}", path.display())))
}

/// A two-dimensional dataset, after the memory check on its number of rows.
fn read_table<T: hdf5::H5Type>(
    path: &Path,
    dataset: &str,
    what: &str,
) -> Result<ndarray::Array2<T>, IoError> {
    let err = |m: String| IoError(format!("{}:{dataset}: {m}", path.display()));
    let file = open_h5(path)?;
    let data = file
        .dataset(dataset)
        .map_err(|e| err(format!("no such dataset: {e}")))?;
    crate::mesh::check_memory(data.shape().first().copied().unwrap_or(0)).map_err(|e| err(e.to_string()))?;
    data.read_2d::<T>()
        .map_err(|e| err(format!("cannot read {what}: {e}")))
}

fn read_points(path: &Path, dataset: &str) -> Result<Vec<[f64; 2]>, IoError> {
    let err = |m: String| IoError(format!("{}:{dataset}: {m}", path.display()));
    let a = read_table::<f64>(path, dataset, "coordinates")?;
    let dim = a.ncols();
    if !(dim == 2 || dim == 3) {
        return Err(err(format!(
            "coordinates have {dim} columns, need 2 (or 3 with z = 0)"
        )));
    }
    a.rows()
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            if dim == 3 && r[2] != 0.0 {
                Err(err(format!(
                    "vertex {i} has z = {}: the mesh must be planar",
                    r[2]
                )))
            } else {
                Ok([r[0], r[1]])
            }
        })
        .collect()
}

fn read_cells(path: &Path, dataset: &str) -> Result<Vec<[usize; 3]>, IoError> {
    let err = |m: String| IoError(format!("{}:{dataset}: {m}", path.display()));
    let a = read_table::<i64>(path, dataset, "cells")?;
    if a.ncols() != 3 {
        return Err(err(format!(
            "cells have {} vertices, need 3 (triangles)",
            a.ncols()
        )));
    }
    a.rows()
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            let v = [r[0], r[1], r[2]];
            if v.iter().any(|&x| x < 0) {
                Err(err(format!("cell {i} has a negative vertex index")))
            } else {
                Ok(v.map(|x| x as usize))
            }
        })
        .collect()
}
