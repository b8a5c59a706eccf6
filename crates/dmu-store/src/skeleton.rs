//! The skeleton segment: everything but the geometry (materials, the assembly
//! tree with f64 transforms, parts, each mesh's chunk table with boxes) as flat
//! little-endian arrays, each at a 16-byte boundary:
//!
//! ```text
//! header     8 counts (u64): nodes, node name bytes, parts, meshes,
//!            mesh name bytes, chunks, materials, material name bytes
//! nodes      NodeEntry x nodes          parent u32, 0 u32, world 12 x f64
//! node names u64 end x nodes, then the UTF-8 bytes
//! parts      PartEntry x parts          node u32, mesh u32, hidden u32
//! meshes     MeshEntry x meshes         chunks u32, degenerate triangles u32, solid u32
//! mesh names u64 end x meshes, then the bytes
//! chunks     ChunkEntry x chunks        material, vertices, triangles u32, min, max 3 x f32
//! materials  [f32; 4] x materials, then their names as above
//! ```
//!
//! It is written from a [`Structure`]'s arrays as they are (no encoding copy)
//! and read with `pread` straight into them, array by array, while its checksum
//! is computed; the counts must account for the segment's length exactly,
//! which bounds what a corrupt count can make the reader allocate. Every index,
//! count and number is checked ([`Structure::check`]) before the scene is
//! built, so a crafted skeleton gives an error and never a panic.

use std::path::Path;

use bytemuck::{Pod, Zeroable};
use dmu_scene::{
    ChunkData, ChunkEntry, ChunkId, ChunkedMesh, DEFAULT_CHUNK_TRIANGLES, MeshEntry, MeshId, Names,
    NodeEntry, NodeId, PartEntry, PartId, Properties, Scene, SceneBuilder, Structure,
};
use xxhash_rust::xxh3::Xxh3;

use crate::error::StoreError;
use crate::format::{ALIGN, ReadAt, TocEntry, read_error};
use crate::geometry::OwnedChunkGeometry;

/// The counts that open the skeleton segment.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Counts {
    nodes: u64,
    node_name_bytes: u64,
    parts: u64,
    meshes: u64,
    mesh_name_bytes: u64,
    chunks: u64,
    materials: u64,
    material_name_bytes: u64,
}
const _: () = assert!(size_of::<Counts>() == 64);

impl Counts {
    fn of(s: &Structure) -> Self {
        Self {
            nodes: s.nodes.len() as u64,
            node_name_bytes: s.node_names.bytes.len() as u64,
            parts: s.parts.len() as u64,
            meshes: s.meshes.len() as u64,
            mesh_name_bytes: s.mesh_names.bytes.len() as u64,
            chunks: s.chunks.len() as u64,
            materials: s.materials.len() as u64,
            material_name_bytes: s.material_names.bytes.len() as u64,
        }
    }

    /// Bytes of each array after the counts, in file order; `None` on overflow.
    fn array_bytes(&self) -> Option<[u64; 11]> {
        let n = |count: u64, size: usize| count.checked_mul(size as u64);
        Some([
            n(self.nodes, size_of::<NodeEntry>())?,
            n(self.nodes, 8)?,
            self.node_name_bytes,
            n(self.parts, size_of::<PartEntry>())?,
            n(self.meshes, size_of::<MeshEntry>())?,
            n(self.meshes, 8)?,
            self.mesh_name_bytes,
            n(self.chunks, size_of::<ChunkEntry>())?,
            n(self.materials, 16)?,
            n(self.materials, 8)?,
            self.material_name_bytes,
        ])
    }

    /// The segment's length: the counts and every array padded to [`ALIGN`]
    /// but the last (the segment's own padding follows it).
    fn segment_bytes(&self) -> Option<u64> {
        let arrays = self.array_bytes()?;
        let padded = arrays
            .iter()
            .try_fold(size_of::<Self>() as u64, |total, &b| {
                total.checked_add(b.checked_next_multiple_of(ALIGN)?)
            })?;
        let last = arrays[arrays.len() - 1];
        Some(padded - (last.next_multiple_of(ALIGN) - last))
    }
}

/// The skeleton segment of `s`, as the byte slices to write one after the other,
/// each padded to [`ALIGN`] with zeros by the writer.
pub(crate) fn pieces(s: &Structure) -> ([u8; 64], [&[u8]; 11]) {
    let counts = bytemuck::cast(Counts::of(s));
    let pieces = [
        bytemuck::cast_slice(&s.nodes),
        bytemuck::cast_slice(&s.node_names.ends),
        &s.node_names.bytes[..],
        bytemuck::cast_slice(&s.parts),
        bytemuck::cast_slice(&s.meshes),
        bytemuck::cast_slice(&s.mesh_names.ends),
        &s.mesh_names.bytes[..],
        bytemuck::cast_slice(&s.chunks),
        bytemuck::cast_slice(&s.materials),
        bytemuck::cast_slice(&s.material_names.ends),
        &s.material_names.bytes[..],
    ];
    (counts, pieces)
}

/// Reads the skeleton segment `entry` of `file` into a [`Structure`], checking
/// its checksum and its layout (not yet its contents: [`Structure::check`]).
pub(crate) fn read(
    file: &impl ReadAt,
    entry: &TocEntry,
    path: &Path,
) -> Result<Structure, StoreError> {
    let corrupt = |what: String| StoreError::Corrupt {
        path: path.to_owned(),
        what: format!("the skeleton: {what}"),
    };
    let end = entry.offset + entry.padded_len();
    let mut hash = Xxh3::new();
    let mut at = entry.offset;
    let mut read = |buf: &mut [u8]| -> Result<(), StoreError> {
        let padded = (buf.len() as u64).next_multiple_of(ALIGN);
        let result = file.read_into(at, buf).and_then(|()| {
            let mut pad = [0u8; ALIGN as usize];
            let pad = &mut pad[..(padded - buf.len() as u64) as usize];
            file.read_into(at + buf.len() as u64, pad)?;
            hash.update(buf);
            hash.update(pad);
            Ok(())
        });
        result.map_err(|source| {
            let actual = file.len().unwrap_or(0);
            read_error(path, source, "the skeleton", end, actual)
        })?;
        at += padded;
        Ok(())
    };
    if entry.length < size_of::<Counts>() as u64 {
        return Err(corrupt(format!(
            "{} bytes, shorter than its counts",
            entry.length
        )));
    }
    let mut counts = Counts::zeroed();
    read(bytemuck::bytes_of_mut(&mut counts))?;
    if counts.segment_bytes() != Some(entry.length) {
        return Err(corrupt(format!(
            "its counts ({} nodes, {} parts, {} meshes, {} chunks, {} materials) do not make its {} bytes",
            counts.nodes,
            counts.parts,
            counts.meshes,
            counts.chunks,
            counts.materials,
            entry.length
        )));
    }
    // Every count is now bounded by the segment's length, which the table of
    // contents bounds by the file's.
    fn array<T: Pod>(
        n: u64,
        read: &mut dyn FnMut(&mut [u8]) -> Result<(), StoreError>,
    ) -> Result<Vec<T>, StoreError> {
        let mut v = vec![T::zeroed(); n as usize];
        read(bytemuck::cast_slice_mut(&mut v))?;
        Ok(v)
    }
    let names = |n: u64, bytes: u64, read: &mut dyn FnMut(&mut [u8]) -> Result<(), StoreError>| {
        Ok::<_, StoreError>(Names {
            ends: array(n, read)?,
            bytes: array(bytes, read)?,
        })
    };
    let nodes = array(counts.nodes, &mut read)?;
    let node_names = names(counts.nodes, counts.node_name_bytes, &mut read)?;
    let parts = array(counts.parts, &mut read)?;
    let meshes = array(counts.meshes, &mut read)?;
    let mesh_names = names(counts.meshes, counts.mesh_name_bytes, &mut read)?;
    let chunks = array(counts.chunks, &mut read)?;
    let materials = array(counts.materials, &mut read)?;
    let material_names = names(counts.materials, counts.material_name_bytes, &mut read)?;
    let computed = hash.digest();
    if computed != entry.checksum {
        return Err(StoreError::Checksum {
            path: path.to_owned(),
            segment: "the skeleton".into(),
            stored: entry.checksum,
            computed,
        });
    }
    Ok(Structure {
        nodes,
        node_names,
        parts,
        meshes,
        mesh_names,
        chunks,
        materials,
        material_names,
        properties: Properties::default(),
    })
}

/// A chunk's table row, as the builder takes it.
fn chunk_data(chunk: &dmu_scene::Chunk) -> ChunkData {
    ChunkData {
        material: chunk.material,
        triangles: chunk.triangles.clone(),
        vertices: chunk.vertices.clone(),
        bounds: chunk.bounds,
    }
}

/// `skeleton`'s materials, meshes (not loaded) and chunks, under a root
/// node alone: no other nodes, no parts.
pub(crate) fn chunk_tables(skeleton: &Scene) -> Scene {
    let mut b = SceneBuilder::new(skeleton.name(), DEFAULT_CHUNK_TRIANGLES);
    for m in skeleton.materials() {
        b.add_material(m.name.clone(), m.base_color);
    }
    for mesh in skeleton.meshes() {
        let table = mesh
            .chunk_ids()
            .map(|c| chunk_data(skeleton.chunk(c)))
            .collect();
        b.add_unloaded_mesh(
            mesh.name.clone(),
            table,
            mesh.degenerate_triangles,
            mesh.solid,
        );
    }
    b.finish()
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
    b.reserve_nodes(skeleton.nodes().len());
    for (i, n) in skeleton.nodes().iter().enumerate().skip(1) {
        b.add_node(
            n.parent.unwrap_or(SceneBuilder::ROOT),
            skeleton.node_name(NodeId(i as u32)),
            n.world,
        );
    }
    for (node, key, value) in skeleton.properties().iter() {
        b.add_property(node, key, value);
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
                solid: mesh.solid,
                ..ChunkedMesh::default()
            };
            for (c, g) in mesh.chunk_ids().zip(chunks) {
                let chunk = skeleton.chunk(c);
                out.positions.extend_from_slice(&g.positions);
                out.normals.extend_from_slice(&g.normals);
                out.indices.extend_from_slice(&g.indices);
                out.chunks.push(chunk_data(chunk));
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
        let id = NodeId(i as u32);
        if (a.node_name(id), x.parent, x.part) != (b.node_name(id), y.parent, y.part)
            || !a.children(id).eq(b.children(id))
        {
            return Some(format!("node {i} ({:?}) differs", a.node_name(id)));
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
                m.solid,
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
