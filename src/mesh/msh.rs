//! Gmsh MSH files, format 4.1 (ASCII or binary, read by the `mshio` crate). ω is the union of
//! all linear triangles of the file, whatever their entity or physical group; points are ignored,
//! and ∂ω is the boundary of the triangulation itself. Other surface elements (quadrilaterals,
//! curved triangles) and volume elements are refused. The physical groups are kept
//! ([`RawGroups`]): the physical surface of each triangle and the physical curve of each line
//! (2-node) element, with the names of `$PhysicalNames` (or the tag, for a group without a name).

use super::file::{FileError, RawMesh};
use super::Tags;
use mshio::mshfile::ElementType;
use std::collections::HashMap;
use std::path::Path;

/// The only MSH version read (Gmsh's default since 4.1).
const VERSION: &str = "4.1";

/// The physical groups of a file as read: the names of the physical surfaces and curves, the
/// surface of each triangle ([`super::groups::NONE`] for none) and the line elements with
/// their curve (in the vertex numbers of the mesh).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RawGroups {
    pub surfaces: Vec<String>,
    pub curves: Vec<String>,
    pub triangle: Vec<u32>,
    pub lines: Vec<([usize; 2], u32)>,
    /// Of the surfaces and of the curves: why an element's group is ambiguous (an entity in
    /// several physical groups, kept in the first), if one is.
    pub ambiguous: [Option<String>; 2],
    /// Of the surfaces and of the curves: the names of `$PhysicalNames` that no element carries.
    pub unused: [Vec<String>; 2],
}

/// The section the file `bytes` ends in, if it ends before its `$End` line.
fn unclosed(bytes: &[u8]) -> Option<String> {
    let mut open: Option<&[u8]> = None;
    for line in bytes.split(|&b| b == b'\n') {
        let line = line.trim_ascii();
        match (line.strip_prefix(b"$End"), line.strip_prefix(b"$")) {
            (Some(_), _) => open = None,
            (None, Some(name)) if !name.is_empty() => open = Some(name),
            _ => {}
        }
    }
    open.map(|name| String::from_utf8_lossy(name).into_owned())
}

/// Reads the triangles of a MSH 4.1 file and the nodes they use (in the order of their tags), the
/// physical groups, if the file has any, and the tags of the nodes and triangles, for messages.
pub(super) fn read(path: &Path) -> Result<(RawMesh, Option<RawGroups>, Tags), FileError> {
    let err = |m: String| FileError(format!("{}: {m}", path.display()));
    // A file larger than the memory available could not be read, let alone solved on; the header
    // is checked first, so that a file of another format is not read whole.
    let cap = super::available_memory().map_or(u64::MAX, |(bytes, _)| bytes / 2);
    let why = "half the memory available: a mesh from a larger file would not fit in memory";
    let bytes = super::file::read_capped(path, cap, why, check_version).map_err(err)?;
    let msh = mshio::parse_msh_bytes(&bytes).map_err(|e| {
        let trace = e.filtered_backtrace();
        let kinds: Vec<String> = trace.iter().rev().map(|(_, k)| k.to_string()).collect();
        let why = match kinds.is_empty() {
            // The parser says no more where a section is cut short.
            true => unclosed(&bytes).map_or("a malformed section".into(), |s| {
                format!("the file ends inside ${s}, before $End{s} (cut short?)")
            }),
            false if kinds.iter().any(|k| k.contains("parametric")) => {
                "Gmsh's parametric nodes (Mesh.SaveParametric = 1) are not read: save the mesh \
                 without them (Mesh.SaveParametric = 0, the default)"
                    .into()
            }
            // A post-processing view written into the mesh's file repeats its sections.
            false if kinds.iter().any(|k| k.contains("Multiple entity sections")) => {
                "the file holds its sections twice (a view written into it with \
                 PostProcessing.SaveMesh = 1?): save the mesh alone"
                    .into()
            }
            false => kinds.join(": "),
        };
        err(format!("not a readable MSH {VERSION} file: {why}"))
    })?;
    let Elements {
        triangles,
        triangle_tags,
        physical: triangle_tag,
        lines,
        ambiguous,
    } = elements(&msh, &err)?;
    if triangles.is_empty() {
        return Err(err(
            "the file has no triangles: the mesh must be made of triangles".into(),
        ));
    }
    let coordinates = nodes(&msh, &node_tags(&bytes).map_err(err)?).map_err(err)?;
    super::check_memory(coordinates.len(), super::MULTIGRID_BYTES_PER_VERTEX)
        .map_err(|e| err(e.to_string()))?;
    // Number the nodes the triangles use by increasing tag; ignore the others.
    let mut used: Vec<u64> = triangles.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let index: HashMap<u64, usize> = used.iter().enumerate().map(|(i, &t)| (t, i)).collect();
    let xyz = (used.iter())
        .map(|tag| {
            (coordinates.get(tag).copied()).ok_or_else(|| {
                err(format!(
                    "a triangle refers to node {tag}, which the file does not define"
                ))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let points = super::planar(&xyz, |i| format!("node {}", used[i])).map_err(err)?;
    let names = super::groups::physical_names(&bytes).map_err(err)?;
    // Names alone (meshio writes $PhysicalNames without the elements' tags) are groups no
    // element carries, which a table naming one is told.
    let has_groups = triangle_tag.iter().any(Option::is_some) || !lines.is_empty() || !names.is_empty();
    // A partitioned file's elements lie on the partitions' entities, whose physical tags are in
    // $PartitionedEntities, which is not read: tables are refused saying so (they were told that
    // no element carries the group).
    let marker = b"$PartitionedEntities";
    let partitioned = has_groups && bytes.windows(marker.len()).any(|w| w == marker);
    let ambiguous = match partitioned {
        false => ambiguous,
        true => [(); 2].map(|_| Some(PARTITIONED.to_string())),
    };
    let groups = has_groups.then(|| RawGroups {
        ambiguous,
        ..raw_groups(&names, &triangle_tag, &lines, |tag| index.get(&tag).copied())
    });
    let triangles = triangles.iter().map(|t| t.map(|tag| index[&tag])).collect();
    let tags = Tags {
        nodes: used,
        triangles: triangle_tags,
    };
    Ok(((points, triangles), groups, tags))
}

/// Why a partitioned file's groups take no data.
const PARTITIONED: &str = "the file is partitioned (gmsh.model.mesh.partition): its physical \
    groups are on the partitions' entities ($PartitionedEntities), which are not read; for data per \
    group save the mesh unpartitioned";

/// The elements of a file that make the mesh and its groups.
struct Elements {
    /// The triangles (their node tags).
    triangles: Vec<[u64; 3]>,
    /// The element tag of each triangle.
    triangle_tags: Vec<u64>,
    /// The physical tag of each triangle, if it has one.
    physical: Vec<Option<i32>>,
    /// The lines of a physical group, with its tag.
    lines: Vec<([u64; 2], i32)>,
    /// Of the surfaces and of the curves, why a group is ambiguous.
    ambiguous: [Option<String>; 2],
}

/// The triangles and the lines of physical groups of the file.
fn elements(
    msh: &mshio::MshFile<u64, i32, f64>,
    err: &dyn Fn(String) -> FileError,
) -> Result<Elements, FileError> {
    let mut ambiguous: [Option<String>; 2] = [None, None];
    // The physical tag of each triangle and each line, by its entity: the first of its groups,
    // and the entity named in `ambiguous` if it has several (an error only for data per group).
    let mut physical = |dim: i32, entity: i32| -> Option<i32> {
        let tags: &[i32] = match (&msh.data.entities, dim) {
            (Some(e), 1) => (e.curves.iter().find(|c| c.tag == entity)).map_or(&[], |c| &c.physical_tags),
            (Some(e), _) => (e.surfaces.iter().find(|c| c.tag == entity)).map_or(&[], |c| &c.physical_tags),
            (None, _) => &[],
        };
        let noun = if dim == 1 { "curve" } else { "surface" };
        if tags.len() > 1 {
            ambiguous[usize::from(dim == 1)].get_or_insert_with(|| {
                format!(
                    "the {noun} entity {entity} belongs to the physical groups {tags:?}: data per \
                     group need each element in one physical {noun} only"
                )
            });
        }
        tags.first().copied()
    };
    let (mut triangles, mut triangle_tags) = (Vec::new(), Vec::new());
    let (mut triangle_tag, mut lines) = (Vec::new(), Vec::new());
    for block in msh.data.elements.iter().flat_map(|e| &e.element_blocks) {
        match (block.entity_dim, block.element_type) {
            (1, ElementType::Lin2) => {
                if let Some(tag) = physical(1, block.entity_tag) {
                    lines.extend(block.elements.iter().map(|e| ([e.nodes[0], e.nodes[1]], tag)));
                }
            }
            (0 | 1, _) => {}
            (2, ElementType::Tri3) => {
                let tag = physical(2, block.entity_tag);
                triangle_tag.extend(std::iter::repeat_n(tag, block.elements.len()));
                triangle_tags.extend(block.elements.iter().map(|e| e.element_tag));
                triangles.extend(
                    block
                        .elements
                        .iter()
                        .map(|e| [e.nodes[0], e.nodes[1], e.nodes[2]]),
                )
            }
            (2, ElementType::Qua4 | ElementType::Qua8 | ElementType::Qua9) => {
                return Err(err(format!(
                    "quadrilateral elements ({:?}, surface {}): the mesh must be made of triangles \
                     (mesh without recombination: Mesh.RecombineAll = 0, no Recombine)",
                    block.element_type, block.entity_tag
                )))
            }
            (dim, kind) => {
                let hint = match dim {
                    2 => "; mesh with triangles of Gmsh's default -order 1",
                    _ => "",
                };
                return Err(err(format!(
                    "elements of type {kind:?} (dimension {dim}): only linear triangles (3 nodes) are read{hint}"
                )));
            }
        }
    }
    Ok(Elements {
        triangles,
        triangle_tags,
        physical: triangle_tag,
        lines,
        ambiguous,
    })
}

/// The physical groups of the triangles and lines, numbered by increasing tag and named by
/// $PhysicalNames (`names`) or by their tag; `index` numbers the nodes the triangles use (`None`
/// for another node).
pub(super) fn raw_groups(
    names: &[((i32, i32), String)],
    triangle_tag: &[Option<i32>],
    lines: &[([u64; 2], i32)],
    index: impl Fn(u64) -> Option<usize>,
) -> RawGroups {
    // Groups numbered by increasing tag, named by $PhysicalNames or by their tag.
    let numbering = |dim: i32, tags: &mut dyn Iterator<Item = i32>| {
        let mut tags: Vec<i32> = tags.collect();
        tags.sort_unstable();
        tags.dedup();
        let name = |t: i32| {
            (names.iter().find(|((d, tag), _)| *d == dim && *tag == t))
                .map_or_else(|| t.to_string(), |(_, n)| n.clone())
        };
        let names: Vec<String> = tags.iter().map(|&t| name(t)).collect();
        (tags, names)
    };
    let (surface_tags, surfaces) = numbering(2, &mut triangle_tag.iter().flatten().copied());
    let (curve_tags, curves) = numbering(1, &mut lines.iter().map(|l| l.1));
    let group = |tags: &[i32], t: i32| tags.binary_search(&t).expect("a tag numbered") as u32;
    let unused = |dim: i32, tags: &[i32]| -> Vec<String> {
        (names.iter())
            .filter(|((d, t), _)| *d == dim && tags.binary_search(t).is_err())
            .map(|(_, n)| n.clone())
            .collect()
    };
    RawGroups {
        ambiguous: [None, None],
        unused: [unused(2, &surface_tags), unused(1, &curve_tags)],
        surfaces,
        curves,
        triangle: (triangle_tag.iter())
            .map(|t| t.map_or(super::groups::NONE, |t| group(&surface_tags, t)))
            .collect(),
        // Lines on nodes that no triangle uses are not on ω.
        lines: (lines.iter())
            .filter_map(|(l, t)| {
                let [a, b] = l.map(&index);
                Some(([a?, b?], group(&curve_tags, *t)))
            })
            .collect(),
    }
}

/// Refuses files that are not MSH 4.1, naming their version, by their first bytes.
fn check_version(bytes: &[u8]) -> Result<(), String> {
    let head =
        String::from_utf8_lossy(&bytes[..bytes.len().min(super::file::HEAD_BYTES as usize)]).to_string();
    let mut lines = head.lines();
    if lines.next().map(str::trim) != Some("$MeshFormat") {
        return Err("not a Gmsh MSH file (it does not start with $MeshFormat)".into());
    }
    let version = lines
        .next()
        .and_then(|l| l.split_whitespace().next())
        .unwrap_or("?");
    if version != VERSION {
        return Err(format!(
            "MSH format version {version} is not read: only version {VERSION} (ASCII or binary) is; \
             convert it with `gmsh FILE -save -format msh41 -o NEW.msh`"
        ));
    }
    Ok(())
}

/// Node tag → (x, y, z): the coordinates mshio read, with the `tags` of the file in its order.
fn nodes(msh: &mshio::MshFile<u64, i32, f64>, tags: &[u64]) -> Result<HashMap<u64, [f64; 3]>, String> {
    let nodes = msh.data.nodes.as_ref().ok_or("the file has no $Nodes section")?;
    let coordinates = nodes.node_blocks.iter().flat_map(|b| &b.nodes);
    let map: HashMap<u64, [f64; 3]> = tags
        .iter()
        .copied()
        .zip(coordinates.map(|n| [n.x, n.y, n.z]))
        .collect();
    if map.len() != tags.len() || tags.len() != nodes.node_blocks.iter().map(|b| b.nodes.len()).sum::<usize>()
    {
        return Err("the $Nodes section repeats a node tag".into());
    }
    Ok(map)
}

/// The node tags of the `$Nodes` section, in file order. mshio keeps them only when they are
/// sparse, and otherwise takes the file order for the order of the tags, which Gmsh does not
/// promise (a mesh saved again lists each entity's nodes, its end points included, in a block).
fn node_tags(bytes: &[u8]) -> Result<Vec<u64>, String> {
    let find = |what: &[u8], from: usize| {
        (bytes.get(from..).unwrap_or_default().windows(what.len()))
            .position(|w| w == what)
            .map(|i| from + i + what.len())
    };
    // The end of the line `name` (LF or CRLF, as a file saved on Windows has) at or after `from`.
    let section = |name: &[u8], from: usize| {
        let mut at = from;
        loop {
            let end = find(name, at)?;
            let start = end - name.len();
            let line_start = start == 0 || bytes[start - 1] == b'\n';
            let rest = &bytes[end..];
            match (rest.first(), rest.get(1)) {
                (Some(b'\n'), _) if line_start => return Some(end + 1),
                (Some(b'\r'), Some(b'\n')) if line_start => return Some(end + 2),
                _ => at = end,
            }
        }
    };
    let format = section(b"$MeshFormat", 0).ok_or("no $MeshFormat section")?;
    let line_end = find(b"\n", format).ok_or("no $MeshFormat line")?;
    let fields: Vec<String> = (String::from_utf8_lossy(&bytes[format..line_end]).split_whitespace())
        .map(String::from)
        .collect();
    let start = section(b"$Nodes", line_end).ok_or("the file has no $Nodes section")?;
    let mut cursor = if fields.get(1).map(String::as_str) == Some("1") {
        let size_t = fields
            .get(2)
            .and_then(|s| s.parse().ok())
            .filter(|&s| s == 4 || s == 8);
        Cursor::Binary {
            bytes,
            at: start,
            size_t: size_t.ok_or("the size of size_t is not 4 or 8")?,
            // The header's binary 1 tells the byte order.
            little: bytes.get(line_end..line_end + 4) == Some(&[1, 0, 0, 0][..]),
        }
    } else {
        Cursor::Ascii(
            std::str::from_utf8(&bytes[start..])
                .map_err(|_| "the $Nodes section is not text")?
                .split_ascii_whitespace(),
        )
    };
    let blocks = cursor.next(true)?;
    for _ in 0..3 {
        cursor.next(true)?; // the number of nodes, the smallest and the largest tag
    }
    let mut tags = Vec::new();
    for _ in 0..blocks {
        for _ in 0..3 {
            cursor.next(false)?; // dimension, entity, parametric (refused by mshio)
        }
        let count = cursor.next(true)?;
        for _ in 0..count {
            tags.push(cursor.next(true)?);
        }
        cursor.skip_coordinates(count)?;
    }
    Ok(tags)
}

/// Reads the numbers of a `$Nodes` section, ASCII or binary.
enum Cursor<'a> {
    Ascii(std::str::SplitAsciiWhitespace<'a>),
    Binary {
        bytes: &'a [u8],
        at: usize,
        size_t: usize,
        little: bool,
    },
}

impl Cursor<'_> {
    /// The next whole number: a `size_t` or an `int` (4 bytes) in a binary file.
    fn next(&mut self, size_t: bool) -> Result<u64, String> {
        let truncated = || "the $Nodes section is truncated".to_string();
        match self {
            Cursor::Ascii(words) => {
                let word = words.next().ok_or_else(truncated)?;
                word.parse()
                    .map_err(|_| format!("'{word}' in the $Nodes section is not a whole number"))
            }
            Cursor::Binary {
                bytes,
                at,
                size_t: size,
                little,
            } => {
                let width = if size_t { *size } else { 4 };
                let chunk = bytes.get(*at..*at + width).ok_or_else(truncated)?;
                *at += width;
                let mut buffer = [0u8; 8];
                Ok(if *little {
                    buffer[..width].copy_from_slice(chunk);
                    u64::from_le_bytes(buffer)
                } else {
                    buffer[8 - width..].copy_from_slice(chunk);
                    u64::from_be_bytes(buffer)
                })
            }
        }
    }

    /// Skips the coordinates (x, y, z) of `count` nodes.
    fn skip_coordinates(&mut self, count: u64) -> Result<(), String> {
        let values = usize::try_from(count.saturating_mul(3)).map_err(|_| "too many nodes")?;
        match self {
            _ if values == 0 => Ok(()),
            Cursor::Ascii(words) => match words.nth(values - 1) {
                Some(_) => Ok(()),
                None => Err("the $Nodes section is truncated".into()),
            },
            Cursor::Binary { at, .. } => {
                *at = at.saturating_add(values.saturating_mul(8));
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_and_binary_files_give_the_same_mesh() {
        let (p, t) = read(Path::new("data/meshes/square.msh")).unwrap().0;
        let (q, s) = read(Path::new("tests/data/square-binary.msh")).unwrap().0;
        assert_eq!((p.len(), t.len()), (98, 162));
        // Gmsh writes 16 significant digits in ASCII, the full double in binary.
        assert_eq!(t, s);
        let worst = (p.iter().zip(&q))
            .map(|(a, b)| (a[0] - b[0]).abs().max((a[1] - b[1]).abs()))
            .fold(0.0, f64::max);
        assert!(worst < 1e-15, "{worst}");
        // All triangles of the surface, and no node of the physical lines left over.
        let mesh = crate::mesh::Mesh::new(p, t).unwrap();
        assert!((mesh.measure() - 1.0).abs() < 1e-14);
        let boundary = mesh.on_boundary.iter().filter(|&&b| b).count();
        assert_eq!(boundary, 32, "8 edges per side of length 0.125");
        // Saved again by Gmsh, the nodes are listed by entity, not by tag: the same mesh.
        for again in [
            "tests/data/square-resaved.msh",
            "tests/data/square-resaved-binary.msh",
        ] {
            let (r, u) = read(Path::new(again)).unwrap().0;
            let triangles = |points: &[[f64; 2]], t: &[[usize; 3]]| {
                let mut k: Vec<[[u64; 2]; 3]> = (t.iter())
                    .map(|t| t.map(|a| points[a].map(|x| (x * 1e12).round() as u64)))
                    .map(|mut v| {
                        v.sort_unstable();
                        v
                    })
                    .collect();
                k.sort_unstable();
                k
            };
            assert_eq!(triangles(&r, &u), triangles(&q, &s), "{again}");
        }
        let old = read(Path::new("tests/data/square-v22.msh")).unwrap_err().0;
        assert!(old.contains("MSH format version 2.2 is not read"), "{old}");
    }

    #[test]
    fn crlf_line_ends_give_the_same_mesh() {
        // As a file saved on Windows, with and without a line end after $EndElements, and without
        // one in Unix.
        let lf = std::fs::read_to_string("data/meshes/square.msh").unwrap();
        let crlf = lf.replace('\n', "\r\n");
        let dir = tempfile::tempdir().unwrap();
        for text in [crlf.as_str(), crlf.trim_end(), lf.trim_end()] {
            let path = dir.path().join("square.msh");
            std::fs::write(&path, text).unwrap();
            assert_eq!(
                read(&path).unwrap(),
                read(Path::new("data/meshes/square.msh")).unwrap()
            );
        }
    }
}
