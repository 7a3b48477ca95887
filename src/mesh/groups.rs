//! Physical groups of a Gmsh file kept by a mesh: the physical surface of every triangle and the
//! physical curve of every boundary edge, with their names (`$PhysicalNames`; a group without a
//! name is named by its tag). They follow the mesh through uniform refinement (each child keeps
//! its parent's surface, each half of a boundary edge its curve), bisection and renumbering, so
//! that data given per group ([`crate::datum::Datum`]) mean the same on every level.

use super::Mesh;

/// No group: a triangle outside every physical surface, a boundary edge on no physical curve.
pub const NONE: u32 = u32::MAX;

/// The physical groups of a mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Groups {
    /// The file they were read from, for messages.
    pub source: String,
    /// The names of the physical surfaces (group index → name).
    pub surfaces: Vec<String>,
    /// The names of the physical curves.
    pub curves: Vec<String>,
    /// The surface of each triangle, or [`NONE`].
    triangle: Vec<u32>,
    /// Every boundary edge (smaller vertex first), sorted, with its curve or [`NONE`].
    edge: Vec<((u32, u32), u32)>,
    /// Of the surfaces and of the curves: why the group of an element is ambiguous (a Gmsh
    /// entity in several physical groups, its elements kept in the first), if one is: data per
    /// group are then refused, data without groups take the mesh as it is.
    pub ambiguous: [Option<String>; 2],
    /// Of the surfaces and of the curves: the names the file declares (`$PhysicalNames`) that no
    /// element carries, for messages.
    pub unused: [Vec<String>; 2],
}

impl Groups {
    /// Groups from their names, the surface of each triangle and the curve of each boundary edge
    /// (any order of the ends; every boundary edge of the mesh must be listed).
    pub fn new(
        source: String,
        surfaces: Vec<String>,
        curves: Vec<String>,
        triangle: Vec<u32>,
        edges: impl IntoIterator<Item = ((usize, usize), u32)>,
    ) -> Self {
        let mut edge: Vec<((u32, u32), u32)> = (edges.into_iter())
            .map(|((a, b), g)| ((a.min(b) as u32, a.max(b) as u32), g))
            .collect();
        edge.sort_unstable();
        Groups {
            source,
            surfaces,
            curves,
            triangle,
            edge,
            ambiguous: [None, None],
            unused: [Vec::new(), Vec::new()],
        }
    }

    /// The surface group of triangle t.
    #[inline]
    pub fn surface(&self, t: usize) -> Option<usize> {
        let g = self.triangle[t];
        (g != NONE).then_some(g as usize)
    }

    /// The curve group of the boundary edge (a, b), either order; `None` if it is on no curve or
    /// not a boundary edge.
    pub fn curve(&self, a: usize, b: usize) -> Option<usize> {
        let key = (a.min(b) as u32, a.max(b) as u32);
        let i = self.edge.binary_search_by_key(&key, |e| e.0).ok()?;
        let g = self.edge[i].1;
        (g != NONE).then_some(g as usize)
    }

    /// The position of the boundary edge (a, b), either order, in [`Groups::boundary_edges`].
    pub fn edge_index(&self, a: usize, b: usize) -> Option<usize> {
        let key = (a.min(b) as u32, a.max(b) as u32);
        self.edge.binary_search_by_key(&key, |e| e.0).ok()
    }

    /// The surface group index of every triangle, [`NONE`] outside every group.
    pub fn triangle_groups(&self) -> &[u32] {
        &self.triangle
    }

    /// The boundary edges (smaller vertex first, sorted) with their curve group or [`NONE`].
    pub fn boundary_edges(&self) -> impl ExactSizeIterator<Item = ((usize, usize), u32)> + '_ {
        (self.edge.iter()).map(|&((a, b), g)| ((a as usize, b as usize), g))
    }

    /// The same groups on a mesh whose triangle t' comes from triangle `parent[t']` and whose
    /// boundary edges are `edges`, each with the boundary edge of `self` it lies in (by its ends).
    pub(crate) fn derived(
        &self,
        parent: impl Iterator<Item = usize>,
        edges: impl Iterator<Item = ((usize, usize), (usize, usize))>,
    ) -> Groups {
        let triangle = parent.map(|t| self.triangle[t]).collect();
        let edges = edges.map(|(e, (a, b))| {
            let key = (a.min(b) as u32, a.max(b) as u32);
            let g = (self.edge.binary_search_by_key(&key, |e| e.0)).map_or(NONE, |i| self.edge[i].1);
            (e, g)
        });
        self.on(triangle, edges)
    }

    /// The groups with the vertices renumbered (`new[a]`) and the triangles reordered
    /// (triangle i of the result is `order[i]` of `self`).
    pub(crate) fn renumbered(&self, new: &[usize], order: &[usize]) -> Groups {
        self.on(
            order.iter().map(|&t| self.triangle[t]).collect(),
            (self.boundary_edges()).map(|((a, b), g)| ((new[a], new[b]), g)),
        )
    }

    /// These groups (their names, source and ambiguity) on other triangles and boundary edges.
    fn on(&self, triangle: Vec<u32>, edges: impl IntoIterator<Item = ((usize, usize), u32)>) -> Groups {
        Groups {
            ambiguous: self.ambiguous.clone(),
            unused: self.unused.clone(),
            ..Groups::new(
                self.source.clone(),
                self.surfaces.clone(),
                self.curves.clone(),
                triangle,
                edges,
            )
        }
    }
}

impl Mesh {
    /// The physical groups of the mesh, when it was read from a Gmsh file with groups (or
    /// derived from such a mesh).
    pub fn groups(&self) -> Option<&Groups> {
        self.groups.as_deref()
    }

    /// The mesh with these groups.
    pub fn with_groups(mut self, groups: Groups) -> Mesh {
        assert_eq!(
            groups.triangle.len(),
            self.n_triangles(),
            "one group per triangle"
        );
        self.groups = Some(Box::new(groups));
        self
    }

    /// The boundary edges (a, b) with a < b, sorted: the edges of one triangle only (among those
    /// of two boundary vertices, the only candidates).
    pub fn boundary_edges(&self) -> Vec<(usize, usize)> {
        let mut half: Vec<(usize, usize)> = (self.triangles())
            .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
            .filter(|&(a, b)| self.on_boundary[a] && self.on_boundary[b])
            .collect();
        half.sort_unstable();
        (half.chunk_by(|a, b| a == b))
            .filter(|g| g.len() == 1)
            .map(|g| g[0])
            .collect()
    }
}

/// A physical name: (dimension, tag) and the name.
pub(super) type PhysicalName = ((i32, i32), String);

/// The physical names of a `$PhysicalNames` section (ASCII, also in binary files): (dimension,
/// tag) → name. Names are quoted; a file without the section has none.
pub(super) fn physical_names(bytes: &[u8]) -> Result<Vec<PhysicalName>, String> {
    let marker = b"$PhysicalNames";
    let Some(at) = bytes.windows(marker.len()).position(|w| w == marker) else {
        return Ok(Vec::new());
    };
    let rest = &bytes[at + marker.len()..];
    let end = rest
        .windows(b"$EndPhysicalNames".len())
        .position(|w| w == b"$EndPhysicalNames")
        .ok_or("the $PhysicalNames section has no $EndPhysicalNames")?;
    let text = std::str::from_utf8(&rest[..end]).map_err(|_| "the $PhysicalNames section is not text")?;
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let count: usize = (lines.next().and_then(|l| l.parse().ok()))
        .ok_or("the $PhysicalNames section does not start with its number of names")?;
    // No room for `count` names before they are read: a count that lies asks for terabytes.
    let mut names = Vec::new();
    for line in lines.by_ref().take(count) {
        let bad = || format!("the $PhysicalNames line «{line}» is not: dimension tag \"name\"");
        let mut words = line.splitn(3, char::is_whitespace);
        let dim: i32 = words.next().and_then(|w| w.parse().ok()).ok_or_else(bad)?;
        let tag: i32 = words.next().and_then(|w| w.trim().parse().ok()).ok_or_else(bad)?;
        let name = words.next().map(str::trim).ok_or_else(bad)?;
        let name = (name.strip_prefix('"').and_then(|n| n.strip_suffix('"'))).ok_or_else(bad)?;
        names.push(((dim, tag), name.to_string()));
    }
    if names.len() != count {
        return Err(format!(
            "the $PhysicalNames section announces {count} names but has {}",
            names.len()
        ));
    }
    Ok(names)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn physical_names_are_read_with_spaces_and_quotes() {
        let text = b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n3\n1 1 \"rim\"\n1 2 \"clamped edge\"\n2 3 \"loaded\"\n$EndPhysicalNames\n";
        let names = physical_names(text).unwrap();
        assert_eq!(
            names,
            vec![
                ((1, 1), "rim".to_string()),
                ((1, 2), "clamped edge".to_string()),
                ((2, 3), "loaded".to_string())
            ]
        );
        assert!(physical_names(b"$PhysicalNames\n2\n1 1 \"a\"\n$EndPhysicalNames\n").is_err());
        assert!(physical_names(b"$PhysicalNames\n1\n1 1 a\n$EndPhysicalNames\n").is_err());
        assert_eq!(physical_names(b"$MeshFormat\n").unwrap(), vec![]);
        // A count of 10¹² names was room asked for before reading them: an abort.
        let lie = physical_names(b"$PhysicalNames\n1000000000000\n1 1 \"a\"\n$EndPhysicalNames\n");
        assert_eq!(
            lie.unwrap_err(),
            "the $PhysicalNames section announces 1000000000000 names but has 1"
        );
    }
}
