//! The skeleton segment: everything but the geometry (materials, the assembly
//! tree with f64 transforms, parts, each mesh's chunk table with boxes), bincode
//! encoded. Decoding checks every index and count before the scene is built, so
//! a crafted skeleton gives an error and never a panic.

use dmu_geom::Aabb3f;
use dmu_scene::{
    ChunkData, ChunkId, ChunkedMesh, DEFAULT_CHUNK_TRIANGLES, MaterialId, MeshId, NodeId, PartId,
    Scene, SceneBuilder,
};
use glam::{DAffine3, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::StoreError;
use crate::geometry::OwnedChunkGeometry;

/// The largest skeleton decoded: a bound on what a corrupt length prefix can
/// make the decoder allocate. A million parts take about 150 MB.
const MAX_SKELETON_BYTES: usize = 1 << 30;

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_limit::<MAX_SKELETON_BYTES>()
}

#[derive(Serialize, Deserialize)]
struct Record {
    name: String,
    materials: Vec<(String, [f32; 4])>,
    /// Nodes after the root, in id order (parents first).
    nodes: Vec<NodeRecord>,
    meshes: Vec<MeshRecord>,
    /// All chunks in id order; each mesh takes the next `chunks` of them.
    chunks: Vec<ChunkRecord>,
    parts: Vec<PartRecord>,
}

#[derive(Serialize, Deserialize)]
struct NodeRecord {
    name: String,
    /// The parent's node id (0 is the root), below this node's id.
    parent: u32,
    /// Column-major 3x4 world transform.
    world: [f64; 12],
}

#[derive(Serialize, Deserialize)]
struct MeshRecord {
    name: String,
    chunks: u32,
    degenerate_triangles: u32,
}

#[derive(Serialize, Deserialize)]
struct ChunkRecord {
    material: u32,
    vertices: u32,
    triangles: u32,
    min: [f32; 3],
    max: [f32; 3],
}

#[derive(Serialize, Deserialize)]
struct PartRecord {
    node: u32,
    mesh: u32,
    hidden: bool,
}

/// The skeleton of a scene, loaded or not.
pub(crate) fn encode(scene: &Scene) -> Vec<u8> {
    let record = Record {
        name: scene.name().to_owned(),
        materials: scene
            .materials()
            .iter()
            .map(|m| (m.name.clone(), m.base_color))
            .collect(),
        nodes: scene.nodes()[1..]
            .iter()
            .map(|n| NodeRecord {
                name: n.name.clone(),
                parent: n.parent.map_or(0, |p| p.0),
                world: n.world.to_cols_array(),
            })
            .collect(),
        meshes: scene
            .meshes()
            .iter()
            .map(|m| MeshRecord {
                name: m.name.clone(),
                chunks: m.chunks.len() as u32,
                degenerate_triangles: m.degenerate_triangles,
            })
            .collect(),
        chunks: scene
            .chunks()
            .iter()
            .map(|c| ChunkRecord {
                material: c.material.0,
                vertices: c.vertices.end - c.vertices.start,
                triangles: c.triangle_count(),
                min: c.bounds.min.to_array(),
                max: c.bounds.max.to_array(),
            })
            .collect(),
        parts: scene
            .parts()
            .iter()
            .map(|p| PartRecord {
                node: p.node.0,
                mesh: p.mesh.0,
                hidden: p.hidden,
            })
            .collect(),
    };
    bincode::serde::encode_to_vec(&record, config()).expect("encoding to memory cannot fail")
}

/// Decodes a skeleton into a scene whose geometry is not loaded.
pub(crate) fn decode(bytes: &[u8]) -> Result<Scene, String> {
    let (record, used): (Record, usize) = bincode::serde::decode_from_slice(bytes, config())
        .map_err(|e| format!("skeleton does not decode: {e}"))?;
    if used != bytes.len() {
        return Err(format!(
            "skeleton has {} bytes after its end",
            bytes.len() - used
        ));
    }
    check(&record)?;
    let mut b = SceneBuilder::new(record.name, DEFAULT_CHUNK_TRIANGLES);
    for (name, color) in record.materials {
        b.add_material(name, color);
    }
    for n in record.nodes {
        b.add_node(
            NodeId(n.parent),
            n.name,
            DAffine3::from_cols_array(&n.world),
        );
    }
    let mut chunks = record.chunks.into_iter();
    for m in record.meshes {
        let (mut tri, mut vert) = (0u32, 0u32);
        let table = chunks
            .by_ref()
            .take(m.chunks as usize)
            .map(|c| {
                let data = ChunkData {
                    material: MaterialId(c.material),
                    triangles: tri..tri + c.triangles,
                    vertices: vert..vert + c.vertices,
                    bounds: Aabb3f {
                        min: Vec3::from_array(c.min),
                        max: Vec3::from_array(c.max),
                    },
                };
                (tri, vert) = (data.triangles.end, data.vertices.end);
                data
            })
            .collect();
        b.add_unloaded_mesh(m.name, table, m.degenerate_triangles);
    }
    let mut hidden = Vec::new();
    for p in record.parts {
        let part = b.add_part(NodeId(p.node), MeshId(p.mesh));
        if p.hidden {
            hidden.push(part);
        }
    }
    let mut scene = b.finish();
    for part in hidden {
        scene.set_part_hidden(part, true);
    }
    scene.validate().map_err(|e| e.to_string())?;
    Ok(scene)
}

/// Everything the builder would panic on, and everything `Scene::validate`
/// checks that the builder does not make true by construction.
fn check(r: &Record) -> Result<(), String> {
    let node_count = r.nodes.len() + 1;
    for (i, n) in r.nodes.iter().enumerate() {
        let id = i + 1;
        if n.parent as usize >= id {
            return Err(format!(
                "node {id}: parent {} is not stored before it",
                n.parent
            ));
        }
        if !n.world.iter().all(|v| v.is_finite()) {
            return Err(format!("node {id}: transform is not finite"));
        }
    }
    let mut chunk_total = 0usize;
    for (m, mesh) in r.meshes.iter().enumerate() {
        let first = chunk_total;
        chunk_total = chunk_total
            .checked_add(mesh.chunks as usize)
            .filter(|&t| t <= r.chunks.len())
            .ok_or_else(|| format!("mesh {m}: its chunks run past the chunk table"))?;
        let (mut tri, mut vert) = (0u32, 0u32);
        for (k, c) in r.chunks[first..chunk_total].iter().enumerate() {
            let id = first + k;
            if c.material as usize >= r.materials.len() {
                return Err(format!("chunk {id}: material {} out of range", c.material));
            }
            // Chunks are never empty; an empty one would make a mesh of no
            // triangles whose vertex ranges point at nothing.
            if c.triangles == 0 || c.vertices == 0 {
                return Err(format!("chunk {id}: empty"));
            }
            tri = tri
                .checked_add(c.triangles)
                .ok_or_else(|| format!("mesh {m}: over 4G triangles"))?;
            vert = vert
                .checked_add(c.vertices)
                .ok_or_else(|| format!("mesh {m}: over 4G vertices"))?;
            let finite = c.min.iter().chain(&c.max).all(|v| v.is_finite());
            if !finite || (0..3).any(|k| c.min[k] > c.max[k]) {
                return Err(format!("chunk {id}: box empty or not finite"));
            }
        }
    }
    if chunk_total != r.chunks.len() {
        return Err(format!(
            "{} chunks belong to no mesh",
            r.chunks.len() - chunk_total
        ));
    }
    let mut has_part = vec![false; node_count];
    for (i, p) in r.parts.iter().enumerate() {
        if p.node == 0 || p.node as usize >= node_count {
            return Err(format!("part {i}: node {} out of range", p.node));
        }
        if std::mem::replace(&mut has_part[p.node as usize], true) {
            return Err(format!("part {i}: node {} already has a part", p.node));
        }
        if p.mesh as usize >= r.meshes.len() {
            return Err(format!("part {i}: mesh {} out of range", p.mesh));
        }
    }
    Ok(())
}

/// The scene of `skeleton` with its geometry, chunk by chunk from `geometry`.
pub(crate) fn with_geometry(
    skeleton: &Scene,
    geometry: &(dyn Fn(MeshId) -> Result<Vec<OwnedChunkGeometry>, StoreError> + Sync),
) -> Result<Scene, StoreError> {
    use rayon::prelude::*;
    let mut b = SceneBuilder::new(skeleton.name(), DEFAULT_CHUNK_TRIANGLES);
    for m in skeleton.materials() {
        b.add_material(m.name.clone(), m.base_color);
    }
    for n in &skeleton.nodes()[1..] {
        b.add_node(
            n.parent.unwrap_or(SceneBuilder::ROOT),
            n.name.clone(),
            n.world,
        );
    }
    // Decoding is the work; meshes go to the builder in order.
    let ids: Vec<MeshId> = (0..skeleton.meshes().len())
        .map(MeshId::from_index)
        .collect();
    let meshes: Vec<ChunkedMesh> = ids
        .par_iter()
        .map(|&id| {
            let mesh = skeleton.mesh(id);
            let chunks = geometry(id)?;
            let mut out = ChunkedMesh {
                name: mesh.name.clone(),
                degenerate_triangles: mesh.degenerate_triangles,
                ..ChunkedMesh::default()
            };
            for (c, g) in mesh.chunk_ids().zip(chunks) {
                let chunk = skeleton.chunk(c);
                out.positions.extend_from_slice(&g.positions);
                out.normals.extend_from_slice(&g.normals);
                out.indices.extend_from_slice(&g.indices);
                out.chunks.push(ChunkData {
                    material: chunk.material,
                    triangles: chunk.triangles.clone(),
                    vertices: chunk.vertices.clone(),
                    bounds: chunk.bounds,
                });
            }
            Ok(out)
        })
        .collect::<Result<_, StoreError>>()?;
    for mesh in meshes {
        b.add_chunked_mesh(mesh);
    }
    for p in skeleton.parts() {
        b.add_part(p.node, p.mesh);
    }
    let mut scene = b.finish();
    for (i, p) in skeleton.parts().iter().enumerate() {
        scene.set_part_hidden(PartId::from_index(i), p.hidden);
    }
    Ok(scene)
}

/// The first structural difference between two scenes, ignoring what an edit
/// may change (node transforms, part visibility) and whether geometry is loaded.
pub(crate) fn structure_difference(a: &Scene, b: &Scene) -> Option<String> {
    if a.name() != b.name() {
        return Some("scene names differ".into());
    }
    if a.materials() != b.materials() {
        return Some("materials differ".into());
    }
    if a.nodes().len() != b.nodes().len() {
        return Some(format!(
            "{} nodes against {}",
            a.nodes().len(),
            b.nodes().len()
        ));
    }
    for (i, (x, y)) in a.nodes().iter().zip(b.nodes()).enumerate() {
        if (&x.name, x.parent, &x.children, x.part) != (&y.name, y.parent, &y.children, y.part) {
            return Some(format!("node {i} ({:?}) differs", x.name));
        }
    }
    if a.parts().len() != b.parts().len()
        || a.parts()
            .iter()
            .zip(b.parts())
            .any(|(x, y)| (x.node, x.mesh) != (y.node, y.mesh))
    {
        return Some("parts differ".into());
    }
    if a.meshes().len() != b.meshes().len() {
        return Some("mesh counts differ".into());
    }
    for (i, (x, y)) in a.meshes().iter().zip(b.meshes()).enumerate() {
        let key = |m: &dmu_scene::Mesh| {
            (
                m.name.clone(),
                m.chunks.clone(),
                m.triangles,
                m.degenerate_triangles,
            )
        };
        if key(x) != key(y) {
            return Some(format!("mesh {i} ({:?}) differs", x.name));
        }
    }
    (a.chunks() != b.chunks()).then(|| {
        let c = (0..a.chunks().len())
            .find(|&c| a.chunks()[c] != b.chunks()[c])
            .map_or(a.chunks().len(), |c| c);
        format!("chunk {} differs", ChunkId::from_index(c))
    })
}
