//! Gmsh MSH files, format 4.1 (ASCII or binary, read by the `mshio` crate). ω is the union of
//! all linear triangles of the file, whatever their entity or physical group; points and lines
//! (physical or not) are ignored, since ∂ω is the boundary of the triangulation itself. Other
//! surface elements (quadrilaterals, curved triangles) and volume elements are refused.

use super::file::{FileError, RawMesh};
use mshio::mshfile::ElementType;
use std::collections::HashMap;
use std::path::Path;

/// The only MSH version read (Gmsh's default since 4.1).
const VERSION: &str = "4.1";

/// Reads the triangles of a MSH 4.1 file and the nodes they use (in the order of their tags).
pub(super) fn read(path: &Path) -> Result<RawMesh, FileError> {
    let err = |m: String| FileError(format!("{}: {m}", path.display()));
    let bytes = std::fs::read(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => err("no such file".into()),
        _ => err(format!("cannot read: {e}")),
    })?;
    check_version(&bytes).map_err(err)?;
    let msh = mshio::parse_msh_bytes(&bytes).map_err(|e| {
        let trace = e.filtered_backtrace();
        let kinds: Vec<String> = trace.iter().rev().map(|(_, k)| k.to_string()).collect();
        err(format!("not a readable MSH {VERSION} file: {}", kinds.join(": ")))
    })?;
    let mut triangles = Vec::new();
    for block in msh.data.elements.iter().flat_map(|e| &e.element_blocks) {
        match (block.entity_dim, block.element_type) {
            (0 | 1, _) => {}
            (2, ElementType::Tri3) => triangles.extend(
                block
                    .elements
                    .iter()
                    .map(|e| [e.nodes[0], e.nodes[1], e.nodes[2]]),
            ),
            (2, ElementType::Qua4 | ElementType::Qua8 | ElementType::Qua9) => {
                return Err(err(format!(
                    "quadrilateral elements ({:?}, surface {}): the mesh must be made of triangles",
                    block.element_type, block.entity_tag
                )))
            }
            (dim, kind) => {
                return Err(err(format!(
                    "elements of type {kind:?} (dimension {dim}): only linear triangles (3 nodes) are read"
                )))
            }
        }
    }
    if triangles.is_empty() {
        return Err(err(
            "the file has no triangles: the mesh must be made of triangles".into(),
        ));
    }
    let coordinates = nodes(&msh).map_err(err)?;
    super::check_memory(coordinates.len()).map_err(|e| err(e.to_string()))?;
    // Number the nodes the triangles use by increasing tag; ignore the others.
    let mut used: Vec<u64> = triangles.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let index: HashMap<u64, usize> = used.iter().enumerate().map(|(i, &t)| (t, i)).collect();
    let points = (used.iter())
        .map(|tag| match coordinates.get(tag) {
            Some(p) if p[2] != 0.0 => Err(err(format!(
                "node {tag} has z = {}: the mesh must be planar",
                p[2]
            ))),
            Some(p) => Ok([p[0], p[1]]),
            None => Err(err(format!(
                "a triangle refers to node {tag}, which the file does not define"
            ))),
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok((
        points,
        triangles.iter().map(|t| t.map(|tag| index[&tag])).collect(),
    ))
}

/// Refuses files that are not MSH 4.1, naming their version.
fn check_version(bytes: &[u8]) -> Result<(), String> {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(64)]).to_string();
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

/// Node tag → (x, y, z). Without explicit sparse tags, the nodes are numbered from the smallest
/// tag on, in file order.
fn nodes(msh: &mshio::MshFile<u64, i32, f64>) -> Result<HashMap<u64, [f64; 3]>, String> {
    let nodes = msh.data.nodes.as_ref().ok_or("the file has no $Nodes section")?;
    let mut out = HashMap::new();
    let mut next = nodes.min_node_tag;
    for block in &nodes.node_blocks {
        let mut tags = vec![0; block.nodes.len()];
        match &block.node_tags {
            Some(map) => map.iter().for_each(|(&tag, &i)| tags[i] = tag),
            None => tags.iter_mut().for_each(|t| {
                *t = next;
                next += 1;
            }),
        }
        out.extend(tags.into_iter().zip(block.nodes.iter().map(|n| [n.x, n.y, n.z])));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_and_binary_files_give_the_same_mesh() {
        let (p, t) = read(Path::new("data/meshes/square.msh")).unwrap();
        let (q, s) = read(Path::new("tests/data/square-binary.msh")).unwrap();
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
        let old = read(Path::new("tests/data/square-v22.msh")).unwrap_err().0;
        assert!(old.contains("MSH format version 2.2 is not read"), "{old}");
    }
}
