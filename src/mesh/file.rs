//! Triangle meshes read from files: XDMF with HDF5 heavy data (as meshio and dolfinx write it,
//! dolfinx's meshtags of the cells and facets as groups named by their tags),
//! an HDF5 file with `/mesh/geometry` and `/mesh/topology` (a result of this program, or dolfinx's
//! `/Mesh/mesh/…`), or a Gmsh MSH 4.1 file (read by the private module `msh`). Every number is
//! checked: coordinates finite and planar, vertex indices whole numbers in range, the sizes an
//! XDMF file declares equal to the data.

use super::Mesh;
use crate::result::hdf5_error;
use std::io::Read;
use std::path::{Path, PathBuf};

message_error!(
    /// Why a mesh file could not be read, naming the file (and the dataset).
    FileError
);

/// The mesh file extensions read, for messages.
const ACCEPTED: &str = ".xdmf (with HDF5 heavy data, as meshio or dolfinx write it), .h5 \
                        (a result of this program or a dolfinx mesh file) and .msh (Gmsh, format 4.1)";

/// The most bytes of an XDMF file read: it is light XML (the heavy data are in HDF5).
const MAX_XDMF_BYTES: u64 = 64 << 20;

/// The bytes that [`read_capped`] reads before the rest: enough for a file's header.
pub(super) const HEAD_BYTES: u64 = 64;

/// The bytes of `path`, at most `cap` of them: a larger file is refused by its size, and a device
/// or a pipe (whose size says nothing: `/dev/zero`, `/dev/stdin`) once more than `cap` bytes have
/// arrived, for it is read through `take`. `head` checks the first [`HEAD_BYTES`] before the rest
/// is read, so that a file in another format is refused without reading it whole; `why` says
/// where the cap comes from. The error does not name the file: the caller does.
pub(super) fn read_capped(
    path: &Path,
    cap: u64,
    why: &str,
    head: impl FnOnce(&[u8]) -> Result<(), String>,
) -> Result<Vec<u8>, String> {
    let cannot = |e: std::io::Error| match e.kind() {
        std::io::ErrorKind::NotFound => "no such file".to_string(),
        _ => format!("cannot read: {e}"),
    };
    let mut file = std::fs::File::open(path).map_err(cannot)?;
    let size = file.metadata().map_err(cannot)?.len();
    if size > cap {
        return Err(format!(
            "the file has {size} bytes; at most {cap} are read ({why})"
        ));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0).saturating_add(1));
    (&mut file)
        .take(HEAD_BYTES)
        .read_to_end(&mut bytes)
        .map_err(cannot)?;
    head(&bytes)?;
    let rest = cap.saturating_add(1).saturating_sub(bytes.len() as u64);
    file.take(rest).read_to_end(&mut bytes).map_err(cannot)?;
    if bytes.len() as u64 > cap {
        return Err(format!(
            "the file has more than {cap} bytes; at most {cap} are read ({why})"
        ));
    }
    Ok(bytes)
}

/// The text of the XDMF file `path`, at most [`MAX_XDMF_BYTES`] of it.
fn read_xdmf_text(path: &Path) -> Result<String, String> {
    let why = "an XDMF file is light XML: its heavy data are in HDF5 files";
    let bytes = read_capped(path, MAX_XDMF_BYTES, why, |_| Ok(()))?;
    String::from_utf8(bytes).map_err(|_| "not valid XDMF (XML): the file is not UTF-8 text".into())
}

/// The XML document of an XDMF file's `text`, its DTD allowed (dolfinx and ParaView write one).
/// The parser descends the call stack once per level of nesting, so that a few hundred kilobytes
/// of nested elements overflowed it (an abort): deeper than 256 is refused first.
pub fn parse_xml(text: &str) -> Result<roxmltree::Document<'_>, String> {
    let depth = xml_depth(text)?;
    if depth > MAX_XML_DEPTH {
        return Err(format!(
            "not valid XDMF: its elements nest {depth} deep, an XDMF file about 8 (at most \
             {MAX_XML_DEPTH} are read)"
        ));
    }
    let options = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..Default::default()
    };
    roxmltree::Document::parse_with_options(text, options).map_err(|e| format!("not valid XDMF (XML): {e}"))
}

/// The deepest nesting of elements read by [`parse_xml`].
const MAX_XML_DEPTH: usize = 256;

/// How deep the elements of the XML `text` nest: a scan of its tags (quoted attribute values,
/// comments, CDATA, processing instructions and the DTD skipped). An entity whose value holds
/// markup is refused, as its elements nest where it is used; so is a construct left open, whose
/// rest the scan would not see.
fn xml_depth(text: &str) -> Result<usize, String> {
    let b = text.as_bytes();
    let (mut depth, mut deepest, mut i) = (0usize, 0usize, 0usize);
    while let Some(k) = text[i..].find('<') {
        i += k;
        let rest = &text[i..];
        i = if let Some(end) = skipped(text, i)? {
            end
        } else if rest.starts_with("<!") {
            dtd_end(text, i)?
        } else {
            let end = tag_end(b, i)?;
            if rest.starts_with("</") {
                depth = depth.saturating_sub(1);
            } else if b[end - 2] != b'/' {
                depth += 1;
                deepest = deepest.max(depth);
            }
            end
        };
    }
    Ok(deepest)
}

/// At a comment, CDATA section or processing instruction at `i`: the index after it.
fn skipped(text: &str, i: usize) -> Result<Option<usize>, String> {
    const KINDS: [(&str, &str, &str); 3] = [
        ("<!--", "-->", "a comment"),
        ("<![CDATA[", "]]>", "CDATA"),
        ("<?", "?>", "a processing instruction"),
    ];
    let rest = &text[i..];
    let Some(&(start, end, what)) = KINDS.iter().find(|(start, ..)| rest.starts_with(start)) else {
        return Ok(None);
    };
    (rest[start.len()..].find(end))
        .map(|k| Some(i + start.len() + k + end.len()))
        .ok_or_else(|| format!("not valid XDMF (XML): the file ends inside {what}"))
}

/// The index after the `>` that ends the tag at `i`, past quoted attribute values.
fn tag_end(b: &[u8], mut i: usize) -> Result<usize, String> {
    let mut quote = None;
    while i < b.len() {
        match (quote, b[i]) {
            (None, q @ (b'"' | b'\'')) => quote = Some(q),
            (Some(q), c) if c == q => quote = None,
            (None, b'>') => return Ok(i + 1),
            _ => {}
        }
        i += 1;
    }
    Err("not valid XDMF (XML): the file ends inside a tag".into())
}

/// The index after the declaration `<!…>` at `i` (a DOCTYPE with its internal subset in
/// brackets, comments and processing instructions in it skipped), or an error if a quoted value
/// in it holds markup.
fn dtd_end(text: &str, mut i: usize) -> Result<usize, String> {
    let b = text.as_bytes();
    let (mut quote, mut brackets) = (None, 0usize);
    i += 2;
    while i < b.len() {
        // At a '<' (a character boundary: the text is UTF-8 and the DTD may name elements é).
        if quote.is_none() && b[i] == b'<' {
            if let Some(end) = skipped(text, i)? {
                i = end;
                continue;
            }
        }
        match (quote, b[i]) {
            (None, q @ (b'"' | b'\'')) => quote = Some(q),
            (Some(q), c) if c == q => quote = None,
            (Some(_), b'<') => {
                return Err("not valid XDMF: an entity of its DTD holds markup (elements)".into())
            }
            (None, b'[') => brackets += 1,
            (None, b']') => brackets = brackets.saturating_sub(1),
            (None, b'>') if brackets == 0 => return Ok(i + 1),
            _ => {}
        }
        i += 1;
    }
    Err("not valid XDMF (XML): the file ends inside its DTD".into())
}

/// Reads and checks the mesh in `path`, by its extension.
///
/// ```
/// let mesh = membrane_contact::mesh::file::read(std::path::Path::new("tests/data/before-default-16.h5")).unwrap();
/// assert_eq!(mesh.n_vertices(), 17 * 17);
/// ```
pub fn read(path: &Path) -> Result<Mesh, FileError> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let checked = |(points, cells): RawMesh| {
        Mesh::new(points, cells).map_err(|e| FileError(format!("{}: {e}", path.display())))
    };
    let with = |mesh: Mesh, groups: Option<super::Groups>| match groups {
        None => mesh,
        Some(groups) => mesh.with_groups(groups),
    };
    match extension {
        "xdmf" => {
            let (raw, tags, topology) = read_xdmf(path)?;
            let mesh = checked(raw)?;
            if !tags.is_empty() {
                return with_meshtags(mesh, &tags, path);
            }
            // The XDMF of a result of this program: its groups are in the one HDF5 file it names,
            // and are T_h's (its dual.xdmf, S_h, has none).
            let mut heavy = inputs(path).split_off(1);
            heavy.sort();
            heavy.dedup();
            let groups = match &heavy[..] {
                [h5] if topology == RESULT_TOPOLOGY => read_h5_groups(h5, &mesh)?,
                _ => None,
            };
            Ok(with(mesh, groups))
        }
        "h5" | "hdf5" => {
            let tags = read_h5_meshtags(path)?;
            // As in an XDMF file: points no triangle uses are left aside, but for meshtags.
            let (points, triangles) = read_h5_mesh(path)?;
            let mesh = checked(match tags.is_empty() {
                true => used_points(points, triangles),
                false => (points, triangles),
            })?;
            if !tags.is_empty() {
                return with_meshtags(mesh, &tags, path);
            }
            let groups = read_h5_groups(path, &mesh)?;
            Ok(with(mesh, groups))
        }
        "msh" => {
            let (raw, groups, tags) = super::msh::read(path)?;
            let (points, cells) = raw;
            let mesh = Mesh::new(points, cells)
                .map_err(|e| FileError(format!("{}: {}", path.display(), e.with_tags(&tags))))?;
            Ok(match groups {
                None => mesh,
                Some(g) => with_msh_groups(mesh, g, path),
            })
        }
        _ => Err(FileError(format!(
            "{}: unknown mesh file extension '{extension}': the mesh files read are {ACCEPTED}",
            path.display()
        ))),
    }
}

/// `mesh` with physical groups given as Gmsh numbers them (a meshio mesh read from a .msh file:
/// the `gmsh:physical` tags of its triangles and lines, its `field_data` names): the names by
/// (dimension, tag), the tag of each triangle (`None` for none), the lines (vertex numbers of
/// `mesh`) with their tag. `source` names the groups in messages.
pub fn with_physical_groups(
    mesh: Mesh,
    names: &[((i32, i32), String)],
    triangle: &[Option<i32>],
    lines: &[([usize; 2], i32)],
    source: &str,
) -> Mesh {
    let n = mesh.n_vertices();
    let lines: Vec<([u64; 2], i32)> = lines.iter().map(|&(l, t)| (l.map(|v| v as u64), t)).collect();
    let raw = super::msh::raw_groups(names, triangle, &lines, |v| {
        usize::try_from(v).ok().filter(|&v| v < n)
    });
    with_msh_groups(mesh, raw, Path::new(source))
}

/// The mesh with the physical groups of its MSH file: the surface of each triangle, and the
/// curve of each boundary edge that a line element of a physical curve covers (lines inside ω
/// are not on a boundary edge and are left aside).
fn with_msh_groups(mesh: Mesh, raw: super::msh::RawGroups, path: &Path) -> Mesh {
    let mut lines: Vec<((usize, usize), u32)> = (raw.lines.iter())
        .map(|&([a, b], g)| ((a.min(b), a.max(b)), g))
        .collect();
    lines.sort_unstable();
    let edges = mesh.boundary_edges().into_iter().map(|e| {
        let i = lines.partition_point(|l| l.0 < e);
        let g = lines
            .get(i)
            .filter(|l| l.0 == e)
            .map_or(super::groups::NONE, |l| l.1);
        (e, g)
    });
    let mut groups = super::Groups::new(
        path.display().to_string(),
        raw.surfaces,
        raw.curves,
        raw.triangle,
        edges,
    );
    (groups.ambiguous, groups.unused) = (raw.ambiguous, raw.unused);
    mesh.with_groups(groups)
}

/// The files a mesh file reads: itself and, for XDMF, the HDF5 files its data items name.
pub fn inputs(path: &Path) -> Vec<PathBuf> {
    let mut files = vec![path.to_path_buf()];
    if path.extension().is_some_and(|e| e == "xdmf") {
        let text = read_xdmf_text(path).unwrap_or_default();
        if let Ok(doc) = parse_xml(&text) {
            let items = doc.descendants().filter(|n| n.has_tag_name("DataItem"));
            files.extend(items.filter_map(|n| Some(heavy(path, n.parent()?).ok()?.file)));
        }
    }
    files
}

/// Points and triangles as read, before the checks of [`Mesh::new`].
pub(super) type RawMesh = (Vec<[f64; 2]>, Vec<[usize; 3]>);

/// A heavy-data reference of an XDMF `DataItem`: the HDF5 file, the dataset and the declared
/// dimensions.
struct Heavy {
    file: PathBuf,
    dataset: String,
    dimensions: Vec<usize>,
}

/// dolfinx's meshtags in an XDMF file (`XDMFFile.write_meshtags`): a grid on the mesh's geometry
/// whose cells are tagged entities, of the triangles (`nodes` 3) or of the edges (`nodes` 2).
struct MeshTags {
    /// The attribute's name (e.g. "cell_tags"), for messages.
    name: String,
    nodes: usize,
    /// The entities' vertices (`nodes` per entity), numbered as the mesh's.
    entities: Vec<usize>,
    /// Each entity's tag.
    values: Vec<i32>,
}

/// The mesh of an XDMF file (its one grid with a topology and a geometry of its own) and the
/// meshtags of its triangles and edges (grids on that geometry, `xi:include`d, with a cell
/// attribute), as dolfinx writes them; grids of other entities (vertex tags) are left aside.
fn read_xdmf(path: &Path) -> Result<(RawMesh, Vec<MeshTags>, String), FileError> {
    let err = |m: String| FileError(format!("{}: {m}", path.display()));
    let text = read_xdmf_text(path).map_err(err)?;
    let doc = parse_xml(&text).map_err(err)?;
    let has = |n: &roxmltree::Node, tag: &str| n.children().any(|c| c.tag_name().name() == tag);
    let with_topology = |n: &roxmltree::Node| n.has_tag_name("Grid") && has(n, "Topology");
    let grids: Vec<roxmltree::Node> = (doc.descendants())
        .filter(|n| with_topology(n) && has(n, "Geometry"))
        .collect();
    // dolfinx's meshtags: grids of the domain itself on the mesh's geometry (`xi:include`).
    let others = (doc.descendants()).filter(|n| {
        with_topology(n)
            && has(n, "include")
            && !has(n, "Geometry")
            && n.parent().is_some_and(|d| d.has_tag_name("Domain"))
    });
    let grid = match grids[..] {
        [] => {
            return Err(err(
                "no <Grid> with a <Topology> and a <Geometry> in the XDMF file".into(),
            ))
        }
        [grid] => grid,
        [.., last] => return Err(err(several_meshes(path, grids.len(), last))),
    };
    let tags = others
        .filter_map(|g| meshtags(path, g).transpose())
        .collect::<Result<Vec<_>, _>>()?;
    let (points, cells, topology) = xdmf_grid(path, grid)?;
    // Meshtags number the points as the file does: with them every point must be used.
    if !tags.is_empty() {
        return Ok(((points, cells.triangles), tags, topology));
    }
    let kept = kept_points(points.len(), &cells.triangles);
    let tags = match topology == RESULT_TOPOLOGY {
        // A result's groups are in its HDF5 file (`read_h5_groups`).
        true => Vec::new(),
        false => cell_data_tags(path, grid, &cells, &kept)?,
    };
    Ok((renumbered(points, cells.triangles, &kept), tags, topology))
}

/// The cells of an XDMF topology that groups are made of: its triangles and its lines of two
/// vertices, each with its place among all the topology's cells, which a cell attribute follows
/// (a `Mixed` topology's points and longer lines have values too).
struct Cells {
    triangles: Vec<[usize; 3]>,
    /// The place of each triangle among the cells.
    triangle_at: Vec<usize>,
    lines: Vec<[usize; 2]>,
    line_at: Vec<usize>,
    /// The cells of every kind.
    count: usize,
}

impl Cells {
    /// The cells of a `Triangle` topology.
    fn triangles(triangles: Vec<[usize; 3]>) -> Cells {
        Cells {
            triangle_at: (0..triangles.len()).collect(),
            count: triangles.len(),
            triangles,
            lines: Vec::new(),
            line_at: Vec::new(),
        }
    }
}

/// The groups that meshio writes as cell data (`meshio convert mesh.msh mesh.xdmf`, or a mesh
/// made by hand with `cell_data={"name_to_read": [...]}`): the grid's cell attribute
/// `gmsh:physical`, or else its only cell attribute if it is a scalar of whole numbers, as
/// meshtags of the triangles and of the lines of `cells` on the points `kept`; none otherwise (a
/// field of the cells is no group). Named by their tags, as dolfinx's meshtags are. A line that
/// is no edge of the triangles, or one repeated (meshio writes a curve's lines once per group of
/// a Gmsh 2 file), is left aside, as the .msh reader leaves it, the first of a repeated one kept.
fn cell_data_tags(
    path: &Path,
    grid: roxmltree::Node,
    cells: &Cells,
    kept: &[usize],
) -> Result<Vec<MeshTags>, FileError> {
    let attributes: Vec<roxmltree::Node> = (grid.children())
        .filter(|c| c.has_tag_name("Attribute") && c.attribute("Center") == Some("Cell"))
        .collect();
    let physical = attributes
        .iter()
        .find(|a| a.attribute("Name") == Some("gmsh:physical"));
    let values = match (physical, &attributes[..]) {
        (Some(&a), _) => Some(physical_values(path, a, cells.count)?),
        (None, [one]) => only_attribute_values(path, *one, cells.count),
        _ => None,
    };
    let Some((name, values)) = values else {
        return Ok(Vec::new());
    };
    let on_kept = |v: &[usize]| v.iter().all(|&v| kept.get(v).is_some_and(|&k| k != usize::MAX));
    let tags = |nodes: usize, entities: Vec<&[usize]>, at: &[usize]| {
        let (entities, values): (Vec<&[usize]>, Vec<i32>) = (entities.into_iter().zip(at))
            .filter(|(v, _)| on_kept(v))
            .map(|(v, &k)| (v, values[k]))
            .unzip();
        MeshTags {
            name: name.clone(),
            nodes,
            entities: entities.into_iter().flatten().map(|&v| kept[v]).collect(),
            values,
        }
    };
    let triangles = (cells.triangles.iter()).map(|t| &t[..]).collect();
    let mut all = vec![tags(3, triangles, &cells.triangle_at)];
    let (lines, line_at) = edges_once(cells);
    if !lines.is_empty() {
        all.push(tags(2, lines, &line_at));
    }
    Ok(all)
}

/// The lines of `cells` that are edges of its triangles, each once (the first), with their places.
fn edges_once(cells: &Cells) -> (Vec<&[usize]>, Vec<usize>) {
    let sorted = |[a, b]: [usize; 2]| [a.min(b), a.max(b)];
    let mut edges: std::collections::HashSet<[usize; 2]> = (cells.triangles.iter())
        .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]].map(sorted))
        .collect();
    (cells.lines.iter().zip(&cells.line_at))
        .filter(|(l, _)| edges.remove(&sorted(**l)))
        .map(|(l, &at)| (&l[..], at))
        .unzip()
}

/// The values of the cell attribute `gmsh:physical`, checked: one whole number of 32 bits per cell.
fn physical_values(
    path: &Path,
    attribute: roxmltree::Node,
    count: usize,
) -> Result<(String, Vec<i32>), FileError> {
    let err = |m: String| FileError(format!("{}: cell attribute 'gmsh:physical': {m}", path.display()));
    let item = heavy(path, attribute)?;
    let values = read_column(&item.file, &item.dataset)?;
    if values.len() != count {
        return Err(err(format!(
            "{} has {} values for {count} cells",
            item.dataset,
            values.len()
        )));
    }
    let tags = values
        .iter()
        .map(|&x| whole_tag(x).ok_or(x))
        .collect::<Result<Vec<i32>, f64>>();
    let tags = tags.map_err(|x| {
        err(format!(
            "the tag {} is not a whole number of 32 bits",
            super::Number(x)
        ))
    })?;
    Ok(("gmsh:physical".into(), tags))
}

/// The values of a grid's only cell attribute if it is a scalar with one whole number of 32 bits
/// per cell, read from HDF5; `None` for any other (a field, not groups).
fn only_attribute_values(
    path: &Path,
    attribute: roxmltree::Node,
    count: usize,
) -> Option<(String, Vec<i32>)> {
    let scalar = attribute
        .attribute("AttributeType")
        .is_none_or(|t| t.eq_ignore_ascii_case("scalar"));
    let item = heavy(path, attribute).ok().filter(|_| scalar)?;
    let values = read_column(&item.file, &item.dataset).ok()?;
    let tags = values.into_iter().map(whole_tag).collect::<Option<Vec<i32>>>()?;
    let name = attribute.attribute("Name").unwrap_or("?").to_string();
    (tags.len() == count).then_some((name, tags))
}

/// `x` as a tag: a whole number of 32 bits.
fn whole_tag(x: f64) -> Option<i32> {
    (x.fract() == 0.0 && x.abs() <= f64::from(i32::MAX)).then_some(x as i32)
}

/// The dataset of T_h's triangles in a result of this program.
const RESULT_TOPOLOGY: &str = "/mesh/topology";

/// The points and cells of the XDMF grid `grid`, checked against the sizes it declares, and the
/// dataset of its triangles.
fn xdmf_grid(path: &Path, grid: roxmltree::Node) -> Result<(Vec<[f64; 2]>, Cells, String), FileError> {
    let err = |m: String| FileError(format!("{}: {m}", path.display()));
    let child = |tag: &str| {
        grid.children()
            .find(|c| c.has_tag_name(tag))
            .ok_or_else(|| err(format!("no <{tag}> in the XDMF grid")))
    };
    let topology = child("Topology")?;
    let kind = topology_type(topology);
    let mixed = kind.eq_ignore_ascii_case("mixed");
    if !(mixed || kind.eq_ignore_ascii_case("triangle")) {
        return Err(err(format!(
            "cell type '{kind}' is not supported: the mesh must be made of triangles"
        )));
    }
    let geometry = heavy(path, child("Geometry")?)?;
    let topology = heavy(path, topology)?;
    let points = read_points(&geometry.file, &geometry.dataset)?;
    geometry.holds(points.len(), 2).map_err(err)?;
    if mixed {
        // A mixed stream's Dimensions count its entries, not its cells.
        let cells = read_mixed(&topology.file, &topology.dataset)?;
        return Ok((points, cells, topology.dataset));
    }
    let cells = read_cells(&topology.file, &topology.dataset)?;
    topology.holds(cells.len(), 3).map_err(err)?;
    Ok((points, Cells::triangles(cells), topology.dataset))
}

impl Heavy {
    /// Whether the declared dimensions are `rows` × `cols` (or 3 columns, as XYZ geometry has).
    fn holds(&self, rows: usize, cols: usize) -> Result<(), String> {
        let declared = &self.dimensions;
        if declared.first() != Some(&rows) || (declared.len() > 1 && declared[1] != cols && declared[1] != 3)
        {
            return Err(format!(
                "the DataItem of {} declares Dimensions {declared:?}, but the dataset has {rows} rows",
                self.dataset
            ));
        }
        Ok(())
    }
}

/// The points the triangles use, renumbered in their order, and the triangles on them: points
/// no triangle uses (a mixed topology's points and lines, the centre of a circle that meshio
/// keeps) are left aside, as the .msh reader leaves unused nodes.
fn used_points(points: Vec<[f64; 2]>, triangles: Vec<[usize; 3]>) -> RawMesh {
    let kept = kept_points(points.len(), &triangles);
    renumbered(points, triangles, &kept)
}

/// The new number of each of `n` points once those no triangle uses are left aside (`usize::MAX`
/// for those).
fn kept_points(n: usize, triangles: &[[usize; 3]]) -> Vec<usize> {
    let mut index = vec![usize::MAX; n];
    for &v in triangles.iter().flatten() {
        if let Some(i) = index.get_mut(v) {
            *i = 0;
        }
    }
    for (next, i) in index.iter_mut().filter(|i| **i == 0).enumerate() {
        *i = next;
    }
    index
}

/// The points `kept` (their new numbers) and the triangles on them.
fn renumbered(points: Vec<[f64; 2]>, triangles: Vec<[usize; 3]>, kept: &[usize]) -> RawMesh {
    let points = (points.into_iter().zip(kept))
        .filter(|(_, &k)| k != usize::MAX)
        .map(|(p, _)| p)
        .collect();
    // An index beyond the points stays as it is (beyond them still), for the mesh's check to name.
    let triangles = (triangles.into_iter())
        .map(|t| t.map(|v| kept.get(v).copied().unwrap_or(v)))
        .collect();
    (points, triangles)
}

/// The meshtags of the XDMF grid `grid` (a topology on another grid's geometry), if it tags
/// triangles or edges: its topology's entities and its cell attribute's values, checked against
/// the sizes the file declares.
fn meshtags(path: &Path, grid: roxmltree::Node) -> Result<Option<MeshTags>, FileError> {
    let topology = (grid.children().find(|c| c.has_tag_name("Topology"))).expect("a grid with a topology");
    let nodes = match topology_type(topology).to_ascii_lowercase().as_str() {
        "triangle" => 3,
        "polyline" if topology.attribute("NodesPerElement") == Some("2") => 2,
        _ => return Ok(None),
    };
    let Some(attribute) =
        (grid.children()).find(|c| c.has_tag_name("Attribute") && c.attribute("Center") == Some("Cell"))
    else {
        return Ok(None);
    };
    let name = attribute.attribute("Name").unwrap_or("?").to_string();
    let err = |m: String| FileError(format!("{}: meshtags '{name}': {m}", path.display()));
    let (topology, values_item) = (heavy(path, topology)?, heavy(path, attribute)?);
    let entities = read_table::<f64>(&topology.file, &topology.dataset, "entities")?;
    let values = read_column(&values_item.file, &values_item.dataset)?;
    for (item, rows) in [(&topology, entities.nrows()), (&values_item, values.len())] {
        if item.dimensions.first().is_some_and(|&d| d != rows) {
            return Err(err(format!(
                "the DataItem of {} declares Dimensions {:?}, but the dataset has {rows} rows",
                item.dataset, item.dimensions
            )));
        }
    }
    MeshTags::new(name.clone(), nodes, &entities, &values)
        .map(Some)
        .map_err(|m| FileError(format!("{}: {m}", path.display())))
}

impl MeshTags {
    /// The meshtags `name` of entities of `nodes` vertices, each row of `entities` with its tag in
    /// `values`, checked: whole vertex indices from 0, whole tags of 32 bits, one per entity.
    fn new(
        name: String,
        nodes: usize,
        entities: &ndarray::Array2<f64>,
        values: &[f64],
    ) -> Result<Self, String> {
        let err = |m: String| format!("meshtags '{name}': {m}");
        if entities.ncols() != nodes || values.len() != entities.nrows() {
            return Err(err(format!(
                "{} entities of {} vertices and {} tags, need {nodes} vertices and one tag per entity",
                entities.nrows(),
                entities.ncols(),
                values.len(),
            )));
        }
        let entities = (entities.iter().map(|&x| vertex_index(x).ok_or(x)))
            .collect::<Result<Vec<usize>, f64>>()
            .map_err(|x| {
                err(format!(
                    "the vertex index {} is not a whole number from 0",
                    super::Number(x)
                ))
            })?;
        let values = (values.iter())
            .map(|&x| whole_tag(x).ok_or(x))
            .collect::<Result<Vec<i32>, f64>>()
            .map_err(|x| {
                err(format!(
                    "the tag {} is not a whole number of 32 bits",
                    super::Number(x)
                ))
            })?;
        Ok(MeshTags {
            name,
            nodes,
            entities,
            values,
        })
    }
}

/// dolfinx's meshtags of the cells and of the facets in its HDF5 mesh file (`/MeshTags/NAME/topology`
/// and `Values`, as `XDMFFile.write_meshtags` writes them beside its XDMF file); other entities
/// (vertex tags) are left aside.
fn read_h5_meshtags(path: &Path) -> Result<Vec<MeshTags>, FileError> {
    let file = open_h5(path)?;
    let Ok(group) = file.group("/MeshTags") else {
        return Ok(Vec::new());
    };
    let names = (group.member_names())
        .map_err(|e| FileError(format!("{}:/MeshTags: {}", path.display(), hdf5_error(&e))))?;
    drop(file);
    let mut tags = Vec::new();
    for name in names {
        let entities = read_table::<f64>(path, &format!("/MeshTags/{name}/topology"), "entities")?;
        if !(2..=3).contains(&entities.ncols()) {
            continue;
        }
        let values = read_column(path, &format!("/MeshTags/{name}/Values"))?;
        let nodes = entities.ncols();
        tags.push(
            MeshTags::new(name, nodes, &entities, &values)
                .map_err(|m| FileError(format!("{}: {m}", path.display())))?,
        );
    }
    Ok(tags)
}

/// `mesh` with the groups of dolfinx's meshtags `tags` (the first of its triangles and the first of
/// its edges; with another of the same kind, data per group of that kind are refused as
/// ambiguous), named by their tags as Gmsh's groups without a name are.
fn with_meshtags(mesh: Mesh, tags: &[MeshTags], path: &Path) -> Result<Mesh, FileError> {
    let err = |m: String| FileError(format!("{}: {m}", path.display()));
    // The first meshtags of each kind; a second makes data per group of that kind ambiguous.
    let of = |nodes: usize| {
        let all: Vec<&MeshTags> = tags.iter().filter(|t| t.nodes == nodes).collect();
        let ambiguous = (all.len() > 1).then(|| {
            let names: Vec<String> = all.iter().map(|t| format!("'{}'", t.name)).collect();
            format!(
                "meshtags {} all tag the {}: data per group take one meshtags of each kind \
                 (write the others to another file)",
                names.join(", "),
                ["edges", "triangles"][nodes - 2]
            )
        });
        (all.first().copied(), ambiguous)
    };
    let (cell_tags, surfaces) = of(3);
    let (facet_tags, curves) = of(2);
    let mut triangle = vec![None; mesh.n_triangles()];
    if let Some(t) = cell_tags {
        let cells: Vec<[usize; 3]> = mesh.triangles().collect();
        for (k, tag) in tagged_entities(t, &cells).map_err(err)? {
            triangle[k] = Some(tag);
        }
    }
    let mut lines = Vec::new();
    if let Some(t) = facet_tags {
        let mut edges: Vec<[usize; 2]> = (mesh.triangles())
            .flat_map(|[a, b, c]| [[a, b], [b, c], [c, a]])
            .collect();
        edges.iter_mut().for_each(|e| e.sort_unstable());
        edges.sort_unstable();
        edges.dedup();
        for (k, tag) in tagged_entities(t, &edges).map_err(err)? {
            lines.push((edges[k].map(|v| v as u64), tag));
        }
    }
    let n = mesh.n_vertices();
    let mut raw = super::msh::raw_groups(&[], &triangle, &lines, |v| {
        usize::try_from(v).ok().filter(|&v| v < n)
    });
    raw.ambiguous = [surfaces, curves];
    Ok(with_msh_groups(mesh, raw, path))
}

/// The entities of `tags` as indices into `entities` (the mesh's, each by its vertices) with their
/// tags; an entity that is not one of the mesh's, or one tagged twice, is an error.
fn tagged_entities<const N: usize>(
    tags: &MeshTags,
    entities: &[[usize; N]],
) -> Result<Vec<(usize, i32)>, String> {
    let sorted = |mut v: [usize; N]| {
        v.sort_unstable();
        v
    };
    let mut index: Vec<([usize; N], usize)> = (entities.iter().enumerate())
        .map(|(k, &v)| (sorted(v), k))
        .collect();
    index.sort_unstable();
    let mut seen = vec![false; entities.len()];
    let kind = ["", "", "an edge", "a triangle"][N];
    (tags.entities.chunks(N).zip(&tags.values).enumerate())
        .map(|(e, (vertices, &tag))| {
            let v = sorted(std::array::from_fn(|j| vertices[j]));
            let i = (index.binary_search_by(|p| p.0.cmp(&v))).map_err(|_| {
                format!(
                    "meshtags '{}': entity {e} (vertices {vertices:?}) is not {kind} of the mesh",
                    tags.name
                )
            })?;
            let k = index[i].1;
            if std::mem::replace(&mut seen[k], true) {
                return Err(format!(
                    "meshtags '{}': entity {e} (vertices {vertices:?}) is tagged twice",
                    tags.name
                ));
            }
            Ok((k, tag))
        })
        .collect()
}

/// Why an XDMF file of `count` meshes (a time series such as `adapt.xdmf`) is not one mesh, naming
/// the heavy-data file of the `last` one where it is known.
fn several_meshes(path: &Path, count: usize, last: roxmltree::Node) -> String {
    let file = (last.children().find(|c| c.has_tag_name("Topology")))
        .and_then(|t| heavy(path, t).ok())
        .map_or(String::new(), |h| {
            format!(", e.g. the last: {}", h.file.display())
        });
    format!(
        "a time series (or collection) of {count} meshes, not one mesh: give the file of one of \
         them{file}"
    )
}

/// The heavy-data reference `FILE:/PATH` of the `DataItem` of `node`, relative to the XDMF file.
fn heavy(path: &Path, node: roxmltree::Node) -> Result<Heavy, FileError> {
    let err = |m: String| FileError(format!("{}: {m}", path.display()));
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
    // The dataset path starts at the last ':' followed by '/', so file names may hold colons.
    let (file, dataset) = location
        .rfind(":/")
        .map(|i| (&location[..i], &location[i + 1..]))
        .ok_or_else(|| err(format!("DataItem '{location}' is not FILE:/PATH")))?;
    let dims = item.attribute("Dimensions").unwrap_or("");
    let dimensions = dims
        .split_whitespace()
        .map(|d| d.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()
        .map_err(|_| err(format!("DataItem Dimensions \"{dims}\" are not whole numbers")))?;
    let base = path.parent().unwrap_or(Path::new(""));
    Ok(Heavy {
        file: base.join(file),
        dataset: dataset.to_string(),
        dimensions,
    })
}

fn read_h5_mesh(path: &Path) -> Result<RawMesh, FileError> {
    let file = open_h5(path)?;
    let (g, t) = match ["/mesh/geometry", "/Mesh/mesh/geometry"].map(|d| file.link_exists(d)) {
        [true, _] => ("/mesh/geometry", "/mesh/topology"),
        [false, true] => ("/Mesh/mesh/geometry", "/Mesh/mesh/topology"),
        [false, false] => {
            return Err(FileError(format!(
                "{}: neither a result of this program (/mesh/geometry) nor dolfinx's mesh \
                 (/Mesh/mesh/geometry): another layout (meshio's) is read through its .xdmf file",
                path.display()
            )))
        }
    };
    drop(file);
    Ok((read_points(path, g)?, read_cells(path, t)?))
}

/// The physical groups a result of this program holds (the cell field `group`, the datasets
/// `boundary_edges` and `boundary_group`, the names in the attributes `surface_groups` and
/// `curve_groups`), so that a result read back as a mesh keeps them; `None` for a file without.
fn read_h5_groups(path: &Path, mesh: &Mesh) -> Result<Option<super::Groups>, FileError> {
    let file = open_h5(path)?;
    let all = ["/mesh/group", "/mesh/boundary_edges", "/mesh/boundary_group"];
    if !all.iter().all(|d| file.link_exists(d))
        || !file
            .attr_names()
            .is_ok_and(|a| a.iter().any(|n| n == "surface_groups"))
    {
        return Ok(None);
    }
    let err = |m: String| {
        FileError(format!(
            "{}: the physical groups of the result: {m}",
            path.display()
        ))
    };
    let names = |attr: &str| -> Result<Vec<String>, FileError> {
        let text = (file
            .attr(attr)
            .and_then(|a| a.read_scalar::<hdf5::types::VarLenUnicode>()))
        .map_err(|e| err(format!("attribute {attr}: {}", hdf5_error(&e))))?;
        serde_json::from_str(text.as_str()).map_err(|e| err(format!("attribute {attr}: {e}")))
    };
    let (surfaces, curves) = (names("surface_groups")?, names("curve_groups")?);
    let index = |v: i64, count: usize, what: &str| match v {
        -1 => Ok(super::groups::NONE),
        v if (0..count as i64).contains(&v) => Ok(v as u32),
        v => Err(err(format!("{what} {v} is not a group index"))),
    };
    let column = |name: &str| {
        (file.dataset(name).and_then(|d| d.read_raw::<f64>()))
            .map_err(|e| err(format!("{name}: {}", hdf5_error(&e))))
    };
    let group = column("/mesh/group")?;
    if group.len() != mesh.n_triangles() {
        return Err(err(format!(
            "{} groups for {} triangles",
            group.len(),
            mesh.n_triangles()
        )));
    }
    let triangle = (group.iter())
        .map(|&g| index(g as i64, surfaces.len(), "surface"))
        .collect::<Result<Vec<_>, _>>()?;
    let ends = read_table::<i32>(path, "/mesh/boundary_edges", "the boundary edges")?;
    let curve = (file
        .dataset("/mesh/boundary_group")
        .and_then(|d| d.read_raw::<i32>()))
    .map_err(|e| err(format!("/mesh/boundary_group: {}", hdf5_error(&e))))?;
    let boundary = mesh.boundary_edges();
    if ends.nrows() != boundary.len() || curve.len() != boundary.len() || ends.ncols() != 2 {
        return Err(err(format!(
            "{} boundary edges listed for {}",
            ends.nrows(),
            boundary.len()
        )));
    }
    let mut edges = Vec::with_capacity(boundary.len());
    for (row, c) in ends.rows().into_iter().zip(curve.iter()) {
        let (a, b) = (row[0].min(row[1]) as usize, row[0].max(row[1]) as usize);
        if boundary.binary_search(&(a, b)).is_err() {
            return Err(err(format!("({a}, {b}) is not a boundary edge of the mesh")));
        }
        edges.push(((a, b), index(i64::from(*c), curves.len(), "curve")?));
    }
    let source = (file
        .attr("groups_source")
        .and_then(|a| a.read_scalar::<hdf5::types::VarLenUnicode>()))
    .map_or_else(|_| path.display().to_string(), |s| s.as_str().to_string());
    Ok(Some(super::Groups::new(
        source, surfaces, curves, triangle, edges,
    )))
}

fn open_h5(path: &Path) -> Result<hdf5::File, FileError> {
    if !path.exists() {
        return Err(FileError(format!("{}: no such file", path.display())));
    }
    hdf5::File::open(path).map_err(|e| {
        FileError(format!(
            "{}: not a readable HDF5 file ({}); the mesh files read are {ACCEPTED}",
            path.display(),
            hdf5_error(&e)
        ))
    })
}

/// A two-dimensional dataset, after the memory check on its number of rows.
fn read_table<T: hdf5::H5Type>(
    path: &Path,
    dataset: &str,
    what: &str,
) -> Result<ndarray::Array2<T>, FileError> {
    let err = |m: String| FileError(format!("{}:{dataset}: {m}", path.display()));
    let file = open_h5(path)?;
    let data = file
        .dataset(dataset)
        .map_err(|e| err(format!("no such dataset: {}", hdf5_error(&e))))?;
    super::check_memory(
        data.shape().first().copied().unwrap_or(0),
        super::MULTIGRID_BYTES_PER_VERTEX,
    )
    .map_err(|e| err(e.to_string()))?;
    data.read_2d::<T>()
        .map_err(|e| err(format!("cannot read {what}: {}", hdf5_error(&e))))
}

fn read_points(path: &Path, dataset: &str) -> Result<Vec<[f64; 2]>, FileError> {
    let err = |m: String| FileError(format!("{}:{dataset}: {m}", path.display()));
    let a = read_table::<f64>(path, dataset, "coordinates")?;
    let dim = a.ncols();
    if !(dim == 2 || dim == 3) {
        return Err(err(format!(
            "coordinates have {dim} columns, need 2 (or 3 in a plane z = constant)"
        )));
    }
    let xyz: Vec<[f64; 3]> = (a.rows().into_iter())
        .map(|r| [r[0], r[1], if dim == 3 { r[2] } else { 0.0 }])
        .collect();
    super::planar(&xyz, |i| format!("vertex {i}")).map_err(err)
}

/// The cells, read as numbers and checked to be whole and non-negative (a float dataset is
/// accepted when every entry is a whole number).
fn read_cells(path: &Path, dataset: &str) -> Result<Vec<[usize; 3]>, FileError> {
    let err = |m: String| FileError(format!("{}:{dataset}: {m}", path.display()));
    let a = read_table::<f64>(path, dataset, "cells")?;
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
            match v.iter().find(|x| vertex_index(**x).is_none()) {
                Some(x) => Err(err(format!(
                    "cell {i} has the vertex index {}: indices are whole numbers from 0",
                    super::Number(*x)
                ))),
                None => Ok(v.map(|x| x as usize)),
            }
        })
        .collect()
}

/// The cells of a `Mixed` topology (meshio writes one wherever a mesh has several cell blocks,
/// as a Gmsh file of several surfaces has): each cell its XDMF type code, then its vertices —
/// triangles (4) and polylines of two vertices (2, their count first) kept, polyvertices (1) and
/// longer polylines counted; any other type refused.
fn read_mixed(path: &Path, dataset: &str) -> Result<Cells, FileError> {
    let err = |m: String| FileError(format!("{}:{dataset}: {m}", path.display()));
    let stream = read_column(path, dataset)?;
    let index = |k: usize| {
        let x = *stream
            .get(k)
            .ok_or_else(|| err("the mixed topology ends within a cell".into()))?;
        vertex_index(x).ok_or_else(|| err(format!("entry {k} is {x}: need a whole number from 0")))
    };
    let mut cells = Cells::triangles(Vec::new());
    let mut k = 0;
    while k < stream.len() {
        let at = cells.count;
        cells.count += 1;
        match index(k)? {
            4 => {
                cells
                    .triangles
                    .push([index(k + 1)?, index(k + 2)?, index(k + 3)?]);
                cells.triangle_at.push(at);
                k += 4;
            }
            2 if index(k + 1)? == 2 => {
                cells.lines.push([index(k + 2)?, index(k + 3)?]);
                cells.line_at.push(at);
                k += 4;
            }
            1 | 2 => {
                k += 2 + index(k + 1)?;
                if k > stream.len() {
                    return Err(err("the mixed topology ends within a cell".into()));
                }
            }
            code => {
                return Err(err(format!(
                    "the mixed topology holds a cell of XDMF type {code} (entry {k}): the mesh must be \
                     made of triangles (with points and lines beside them)"
                )))
            }
        }
    }
    Ok(cells)
}

/// A vertex index read as a number: a whole number from 0 (below 9e15, exact in f64).
fn vertex_index(x: f64) -> Option<usize> {
    (x.fract() == 0.0 && (0.0..9.0e15).contains(&x)).then_some(x as usize)
}

/// The cell type of an XDMF `Topology` (its `TopologyType`, or `Type`).
fn topology_type<'a>(topology: roxmltree::Node<'a, '_>) -> &'a str {
    (topology.attribute("TopologyType").or(topology.attribute("Type"))).unwrap_or("?")
}

/// A dataset of one column, of shape (n) or (n, 1) (dolfinx writes meshtags' values as (n, 1)),
/// after the memory check on its rows.
fn read_column(path: &Path, dataset: &str) -> Result<Vec<f64>, FileError> {
    let err = |m: String| FileError(format!("{}:{dataset}: {m}", path.display()));
    let file = open_h5(path)?;
    let data = (file.dataset(dataset)).map_err(|e| err(format!("no such dataset: {}", hdf5_error(&e))))?;
    let shape = data.shape();
    if !(shape.len() == 1 || (shape.len() == 2 && shape[1] == 1)) {
        return Err(err(format!("of shape {shape:?}, need one column")));
    }
    super::check_memory(shape[0], super::MULTIGRID_BYTES_PER_VERTEX).map_err(|e| err(e.to_string()))?;
    data.read_raw::<f64>()
        .map_err(|e| err(format!("cannot read: {}", hdf5_error(&e))))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The nesting is counted past what is not an element; 30 000 nested elements (an abort
    /// of the parser's stack) are refused, and entities of markup too.
    #[test]
    fn xml_nested_too_deep_is_refused_before_parsing() {
        let dtd = "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" [<!ENTITY h \"m.h5\">]>";
        let text = format!(
            "<?xml version=\"1.0\"?>{dtd}<Xdmf><!-- <a><b> --><D x='>' y=\"/>\"><G/><![CDATA[<c>]]>\
             <G><T>&h;</T></G></D></Xdmf>"
        );
        assert_eq!(xml_depth(&text), Ok(4));
        assert!(parse_xml(&text).is_ok());
        let deep = format!("<Xdmf>{}{}</Xdmf>", "<a>".repeat(30_000), "</a>".repeat(30_000));
        let e = parse_xml(&deep).unwrap_err();
        assert!(e.contains("its elements nest 30001 deep"), "{e}");
        let markup = "<!DOCTYPE X [<!ENTITY e \"<a><a></a></a>\">]><X>&e;</X>";
        let e = parse_xml(markup).unwrap_err();
        assert!(e.contains("an entity of its DTD holds markup"), "{e}");
        // Comments and instructions in the DTD are skipped (an apostrophe in one was taken for
        // a quoted value, a bracket in one hid the nesting that follows), and what is left open
        // is refused.
        let dtd = "<!DOCTYPE X [<!-- don't [ --><?note it's [?><!ENTITY h \"m.h5\">]>";
        assert_eq!(xml_depth(&format!("{dtd}<X><D/></X>")), Ok(1));
        // Letters beyond ASCII in the DTD (it sliced the text inside one: a panic).
        for dtd in ["<!DOCTYPE Xé>", "<!DOCTYPE X [<!ELEMENT é ANY>]>"] {
            assert_eq!(xml_depth(&format!("{dtd}<X><D/></X>")), Ok(1), "{dtd}");
        }
        let e = parse_xml(&format!("{dtd}{deep}")).unwrap_err();
        assert!(e.contains("its elements nest 30001 deep"), "{e}");
        for open in ["<X><!-- ", "<X a='>", "<!DOCTYPE X [", "<X><![CDATA[", "<X><?p"] {
            let e = xml_depth(open).unwrap_err();
            assert!(
                e.starts_with("not valid XDMF (XML): the file ends inside"),
                "{open}: {e}"
            );
        }
    }

    #[test]
    fn reads_stop_at_the_cap() {
        let none = |_: &[u8]| Ok(());
        // A device without end, and a file larger than the cap: refused, naming the cap.
        let e = read_capped(Path::new("/dev/zero"), 1000, "a test", none).unwrap_err();
        assert_eq!(
            e,
            "the file has more than 1000 bytes; at most 1000 are read (a test)"
        );
        let square = Path::new("data/meshes/square.msh");
        let size = std::fs::metadata(square).unwrap().len();
        let e = read_capped(square, 1000, "a test", none).unwrap_err();
        assert_eq!(
            e,
            format!("the file has {size} bytes; at most 1000 are read (a test)")
        );
        // At the cap, the file is read whole; the header is checked on its first bytes.
        let whole = read_capped(square, size, "a test", |head| {
            assert_eq!(head.len() as u64, HEAD_BYTES);
            Ok(())
        });
        assert_eq!(whole.unwrap(), std::fs::read(square).unwrap());
        let refused = read_capped(Path::new("/dev/zero"), u64::MAX, "", |_| Err("no header".into()));
        assert_eq!(refused.unwrap_err(), "no header");
        assert_eq!(
            read_capped(Path::new("absent.msh"), 1000, "", none).unwrap_err(),
            "no such file"
        );
    }
}
