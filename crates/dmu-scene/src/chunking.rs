//! Splitting part-local geometry into chunks: recursive median splits on triangle
//! centroids, so chunks are spatially compact, hold at most `chunk_triangles`
//! triangles, never split a triangle and never duplicate one.

use std::ops::Range;

use dmu_geom::Aabb3f;
use glam::Vec3;

use crate::ids::MaterialId;

/// Geometry as it arrives from a file or a generator, before chunking.
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    /// Name of the mesh (for messages and export).
    pub name: String,
    /// Part-local positions; all finite.
    pub positions: Vec<Vec3>,
    /// One normal per position (see [`compute_normals`] when the source has none).
    pub normals: Vec<Vec3>,
    /// Triangle list, three indices per triangle, each `< positions.len()`.
    pub indices: Vec<u32>,
    /// Triangle ranges (in triangles, not indices) that share a material; they cover
    /// the triangle list in order without gaps.
    pub groups: Vec<MeshGroup>,
}

/// A run of triangles with one material (a glTF primitive).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshGroup {
    /// The material of these triangles.
    pub material: MaterialId,
    /// Triangle range (not index range) in [`MeshData::indices`].
    pub triangles: Range<u32>,
}

impl MeshData {
    /// Appends a triangle-list primitive with its material; indices are relative to
    /// the given positions.
    pub fn push_primitive(
        &mut self,
        positions: &[Vec3],
        normals: &[Vec3],
        indices: &[u32],
        material: MaterialId,
    ) {
        debug_assert_eq!(positions.len(), normals.len());
        debug_assert_eq!(indices.len() % 3, 0);
        let base = u32::try_from(self.positions.len()).expect("mesh over 4G vertices");
        let first = self.triangle_count();
        self.positions.extend_from_slice(positions);
        self.normals.extend_from_slice(normals);
        self.indices.extend(indices.iter().map(|&i| i + base));
        let last = self.triangle_count();
        match self.groups.last_mut() {
            Some(g) if g.material == material && g.triangles.end == first => g.triangles.end = last,
            _ if first == last => {}
            _ => self.groups.push(MeshGroup {
                material,
                triangles: first..last,
            }),
        }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> u32 {
        u32::try_from(self.indices.len() / 3).expect("mesh over 4G triangles")
    }
}

/// Area-weighted vertex normals of an indexed triangle list. Degenerate triangles
/// add nothing; a vertex touched only by degenerate triangles gets +Z, so the
/// result is always finite and unit length.
pub fn compute_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        // The unnormalised cross product weighs each face by twice its area.
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        if n.is_finite() {
            normals[a] += n;
            normals[b] += n;
            normals[c] += n;
        }
    }
    for n in &mut normals {
        *n = n.try_normalize().unwrap_or(Vec3::Z);
    }
    normals
}

/// One chunk of a [`ChunkedMesh`]: contiguous ranges of its triangles and vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct ChunkData {
    /// The material of every triangle in the chunk.
    pub material: MaterialId,
    /// Triangle range in [`ChunkedMesh::indices`] (divide index positions by 3).
    pub triangles: Range<u32>,
    /// Vertex range in the mesh's vertex arrays; the chunk's indices are relative to
    /// its start.
    pub vertices: Range<u32>,
    /// Local box of the chunk's vertices.
    pub bounds: Aabb3f,
}

/// A mesh reordered into chunks. Each chunk owns a contiguous run of vertices and
/// of triangles, and its indices count from its first vertex, so one chunk can be
/// loaded, uploaded or tested on its own. Vertices on a chunk border are repeated
/// in both chunks; triangles never are.
#[derive(Clone, Debug, Default)]
pub struct ChunkedMesh {
    /// Mesh name.
    pub name: String,
    /// Positions, chunk after chunk.
    pub positions: Vec<Vec3>,
    /// Normals, parallel to `positions`.
    pub normals: Vec<Vec3>,
    /// Chunk-local indices, chunk after chunk.
    pub indices: Vec<u32>,
    /// The chunks in order.
    pub chunks: Vec<ChunkData>,
    /// Triangles with zero area (kept, and counted here).
    pub degenerate_triangles: u32,
    /// Whether it bounds solids with outward windings ([`crate::is_solid`]).
    pub solid: bool,
}

/// Splits `mesh` into chunks of at most `chunk_triangles` triangles. Each material
/// group is split on its own, so a chunk has one material.
///
/// # Panics
/// When `chunk_triangles` is zero or an index is out of range: importers check
/// their input and name the offending accessor before calling this.
pub fn chunk_mesh(mesh: &MeshData, chunk_triangles: u32) -> ChunkedMesh {
    assert!(chunk_triangles > 0, "chunk_triangles must be positive");
    let vertex_count = mesh.positions.len();
    assert!(
        mesh.indices.iter().all(|&i| (i as usize) < vertex_count),
        "mesh {:?}: index out of range",
        mesh.name
    );
    let tri = |t: u32| {
        let i = 3 * t as usize;
        [mesh.indices[i], mesh.indices[i + 1], mesh.indices[i + 2]]
    };
    let centroid = |t: u32| {
        tri(t)
            .iter()
            .map(|&i| mesh.positions[i as usize])
            .sum::<Vec3>()
            / 3.0
    };

    let mut out = ChunkedMesh {
        name: mesh.name.clone(),
        solid: crate::is_solid(&mesh.positions, &mesh.indices),
        positions: Vec::with_capacity(vertex_count),
        normals: Vec::with_capacity(vertex_count),
        indices: Vec::with_capacity(mesh.indices.len()),
        ..ChunkedMesh::default()
    };
    // Scratch for the old-to-new vertex map: `stamp` tells which chunk wrote `remap`,
    // so it never needs clearing between chunks.
    let mut remap = vec![0u32; vertex_count];
    let mut stamp = vec![u32::MAX; vertex_count];
    let mut leaves: Vec<Range<usize>> = Vec::new();

    let mut tris: Vec<u32> = Vec::new();
    for group in &mesh.groups {
        let mut keyed: Vec<(u32, Vec3)> =
            group.triangles.clone().map(|t| (t, centroid(t))).collect();
        leaves.clear();
        split(&mut keyed, 0, chunk_triangles as usize, &mut leaves);

        for leaf in &leaves {
            tris.clear();
            tris.extend(keyed[leaf.clone()].iter().map(|&(t, _)| t));
            // Keep the source order inside a chunk: it is usually cache friendly.
            tris.sort_unstable();
            let chunk_index = u32::try_from(out.chunks.len()).expect("over 4G chunks");
            let first_vertex = out.positions.len() as u32;
            let first_triangle = (out.indices.len() / 3) as u32;
            let mut bounds = Aabb3f::EMPTY;
            for &t in &tris {
                let corners = tri(t);
                let p = corners.map(|i| mesh.positions[i as usize]);
                if (p[1] - p[0]).cross(p[2] - p[0]) == Vec3::ZERO {
                    out.degenerate_triangles += 1;
                }
                for i in corners {
                    let i = i as usize;
                    if stamp[i] != chunk_index {
                        stamp[i] = chunk_index;
                        remap[i] = out.positions.len() as u32 - first_vertex;
                        out.positions.push(mesh.positions[i]);
                        out.normals.push(mesh.normals[i]);
                        bounds = bounds.grown(mesh.positions[i]);
                    }
                    out.indices.push(remap[i]);
                }
            }
            out.chunks.push(ChunkData {
                material: group.material,
                triangles: first_triangle..(out.indices.len() / 3) as u32,
                vertices: first_vertex..out.positions.len() as u32,
                bounds,
            });
        }
    }
    out
}

/// Orders `items` (an id and a point each) into spatially compact runs of at
/// most `max` (`max` > 0), as chunks are cut: recursive median splits on the
/// longest axis of the points' box. The runs' ranges, in order; where
/// `items` holds more than `max`, each run holds at least half of `max`
/// (rounded up), so there are at most `items.len() / max.div_ceil(2)`.
pub fn spatial_runs(items: &mut [(u32, Vec3)], max: usize) -> Vec<Range<usize>> {
    assert!(max > 0, "a run holds at least one item");
    let mut runs = Vec::new();
    split(items, 0, max, &mut runs);
    runs
}

/// Recursive median split of `items[..]` (triangle id, centroid) on the longest
/// axis of the centroids' box; appends the leaf ranges (offset by `base`).
fn split(items: &mut [(u32, Vec3)], base: usize, max: usize, leaves: &mut Vec<Range<usize>>) {
    if items.len() <= max {
        if !items.is_empty() {
            leaves.push(base..base + items.len());
        }
        return;
    }
    let bounds = Aabb3f::from_points(items.iter().map(|&(_, c)| c));
    let axis = bounds.extent().max_position();
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| a.1[axis].total_cmp(&b.1[axis]));
    let (left, right) = items.split_at_mut(mid);
    split(left, base, max, leaves);
    split(right, base + mid, max, leaves);
}
