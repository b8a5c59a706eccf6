//! A scene's structure without its geometry as flat arrays: what a store's
//! skeleton holds and what the streaming glTF import makes. No allocation per
//! element (names live in one string table per kind): 112 bytes a node (96 of
//! them its f64 transform) and its name, 12 a part, 36 a chunk, 8 a mesh;
//! chunk instances are not stored (a part instances all its mesh's chunks).

use bytemuck::{Pod, Zeroable};
use dmu_geom::Aabb3f;
use glam::{DAffine3, Vec3};

use crate::chunking::{ChunkData, ChunkedMesh};
use crate::error::SceneError;
use crate::ids::{MaterialId, MeshId, NodeId, PartId};
use crate::properties::Properties;
use crate::scene::{Scene, SceneBuilder, world_is_valid};

/// Marks the root's parent in [`NodeEntry::parent`].
pub const NO_PARENT: u32 = u32::MAX;

/// A node: its parent and its absolute world transform.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct NodeEntry {
    /// The parent's id, below this node's ([`NO_PARENT`] for the root, node 0).
    pub parent: u32,
    /// Zero.
    pub reserved: u32,
    /// Column-major 3x4 world transform (`DAffine3::to_cols_array`).
    pub world: [f64; 12],
}

/// A part: the node it is and the mesh it instances.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct PartEntry {
    /// Its node.
    pub node: u32,
    /// Its mesh.
    pub mesh: u32,
    /// 1 when hidden, else 0.
    pub hidden: u32,
}

/// A mesh: how many chunks it takes (meshes take the chunk table in order).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct MeshEntry {
    /// Its chunks: the next ones in the chunk table.
    pub chunks: u32,
    /// Zero-area triangles it holds.
    pub degenerate_triangles: u32,
    /// 1 when it bounds solids with outward windings ([`crate::is_solid`]), else 0.
    pub solid: u32,
}

/// A chunk: material, sizes, and its local box.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ChunkEntry {
    /// Its material.
    pub material: u32,
    /// Vertices (never 0).
    pub vertices: u32,
    /// Triangles (never 0).
    pub triangles: u32,
    /// Box minimum.
    pub min: [f32; 3],
    /// Box maximum.
    pub max: [f32; 3],
}

/// Strings in one table: string `i` is `bytes[ends[i-1]..ends[i]]`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Names {
    /// Where each string ends in `bytes`.
    pub ends: Vec<u64>,
    /// The strings, one after the other.
    pub bytes: Vec<u8>,
}

impl Names {
    /// Appends a string.
    pub fn push(&mut self, name: &str) {
        self.bytes.extend_from_slice(name.as_bytes());
        self.ends.push(self.bytes.len() as u64);
    }

    /// Strings held.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// Whether no string is held.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// String `i`; `""` for bytes that are not UTF-8 ([`Names::check`] refuses them).
    ///
    /// # Panics
    /// When `i` is out of range or the ends are not increasing within the bytes.
    pub fn get(&self, i: usize) -> &str {
        let start = if i == 0 { 0 } else { self.ends[i - 1] as usize };
        std::str::from_utf8(&self.bytes[start..self.ends[i] as usize]).unwrap_or_default()
    }

    /// Checks that the ends increase within the bytes and each string is UTF-8.
    pub fn check(&self, what: &str) -> Result<(), String> {
        let mut start = 0u64;
        for (i, &end) in self.ends.iter().enumerate() {
            if end < start || end > self.bytes.len() as u64 {
                return Err(format!(
                    "{what} name {i}: ends at {end}, outside {start}..{}",
                    self.bytes.len()
                ));
            }
            if std::str::from_utf8(&self.bytes[start as usize..end as usize]).is_err() {
                return Err(format!("{what} name {i}: not UTF-8"));
            }
            start = end;
        }
        if start != self.bytes.len() as u64 {
            return Err(format!(
                "{what} names: {} bytes after the last name",
                self.bytes.len() as u64 - start
            ));
        }
        Ok(())
    }

    pub(crate) fn held_bytes(&self) -> u64 {
        (self.ends.capacity() * 8 + self.bytes.capacity()) as u64
    }
}

/// A scene's structure (nodes, parts, meshes' chunk tables, materials) without
/// geometry, as flat arrays. The scene's name is the root's (node 0's) name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Structure {
    /// Nodes, parents first; node 0 is the root.
    pub nodes: Vec<NodeEntry>,
    /// Node names (the root's is the scene's name).
    pub node_names: Names,
    /// Parts.
    pub parts: Vec<PartEntry>,
    /// Meshes.
    pub meshes: Vec<MeshEntry>,
    /// Mesh names.
    pub mesh_names: Names,
    /// All chunks, mesh after mesh.
    pub chunks: Vec<ChunkEntry>,
    /// Material base colours (linear RGBA).
    pub materials: Vec<[f32; 4]>,
    /// Material names.
    pub material_names: Names,
    /// Nodes' properties.
    pub properties: Properties,
}

impl Structure {
    /// A structure of only a root node named `name`.
    pub fn new(name: &str) -> Self {
        let mut s = Self::default();
        s.nodes.push(NodeEntry {
            parent: NO_PARENT,
            reserved: 0,
            world: DAffine3::IDENTITY.to_cols_array(),
        });
        s.node_names.push(name);
        s
    }

    /// The structure of `scene` (loaded or not; its geometry is not read).
    pub fn of(scene: &Scene) -> Self {
        let mut s = Self::default();
        for (i, n) in scene.nodes().iter().enumerate() {
            s.nodes.push(NodeEntry {
                parent: n.parent.map_or(NO_PARENT, |p| p.0),
                reserved: 0,
                world: n.world.to_cols_array(),
            });
            s.node_names.push(scene.node_name(NodeId(i as u32)));
        }
        s.parts = scene
            .parts()
            .iter()
            .map(|p| PartEntry {
                node: p.node.0,
                mesh: p.mesh.0,
                hidden: u32::from(p.hidden),
            })
            .collect();
        for m in scene.meshes() {
            s.meshes.push(MeshEntry {
                chunks: m.chunks.end - m.chunks.start,
                degenerate_triangles: m.degenerate_triangles,
                solid: u32::from(m.solid),
            });
            s.mesh_names.push(&m.name);
        }
        s.chunks = scene
            .chunks()
            .iter()
            .map(|c| ChunkEntry {
                material: c.material.0,
                vertices: c.vertices.end - c.vertices.start,
                triangles: c.triangle_count(),
                min: c.bounds.min.to_array(),
                max: c.bounds.max.to_array(),
            })
            .collect();
        for m in scene.materials() {
            s.materials.push(m.base_color);
            s.material_names.push(&m.name);
        }
        s.properties = scene.properties().clone();
        s
    }

    /// The scene's name.
    pub fn name(&self) -> &str {
        self.node_names.get(0)
    }

    /// Adds a material.
    pub fn add_material(&mut self, name: &str, base_color: [f32; 4]) -> MaterialId {
        self.materials.push(base_color);
        self.material_names.push(name);
        MaterialId::from_index(self.materials.len() - 1)
    }

    /// Adds a node under `parent`.
    pub fn add_node(&mut self, parent: NodeId, name: &str, world: DAffine3) -> NodeId {
        self.nodes.push(NodeEntry {
            parent: parent.0,
            reserved: 0,
            world: world.to_cols_array(),
        });
        self.node_names.push(name);
        NodeId::from_index(self.nodes.len() - 1)
    }

    /// Adds a mesh's chunk table and counts (its chunk ranges following each
    /// other from 0, as [`crate::chunk_mesh`] makes them; the geometry is
    /// not kept).
    pub fn add_mesh(&mut self, mesh: &ChunkedMesh) -> MeshId {
        let chunks = &mesh.chunks;
        self.chunks.extend(chunks.iter().map(|c| ChunkEntry {
            material: c.material.0,
            vertices: c.vertices.end - c.vertices.start,
            triangles: c.triangles.end - c.triangles.start,
            min: c.bounds.min.to_array(),
            max: c.bounds.max.to_array(),
        }));
        self.meshes.push(MeshEntry {
            chunks: chunks.len() as u32,
            degenerate_triangles: mesh.degenerate_triangles,
            solid: u32::from(mesh.solid),
        });
        self.mesh_names.push(&mesh.name);
        MeshId::from_index(self.meshes.len() - 1)
    }

    /// Makes `node` a part instancing `mesh`.
    pub fn add_part(&mut self, node: NodeId, mesh: MeshId) -> PartId {
        self.parts.push(PartEntry {
            node: node.0,
            mesh: mesh.0,
            hidden: 0,
        });
        PartId::from_index(self.parts.len() - 1)
    }

    /// Node `id`'s world transform.
    pub fn node_world(&self, id: NodeId) -> DAffine3 {
        DAffine3::from_cols_array(&self.nodes[id.index()].world)
    }

    /// A node's path: names from below the root down to it, joined by `/`.
    pub fn node_path(&self, id: NodeId) -> String {
        let mut names = Vec::new();
        let mut at = id.0;
        while at != 0 && at != NO_PARENT {
            names.push(self.node_names.get(at as usize));
            at = self.nodes[at as usize].parent;
        }
        names.reverse();
        names.join("/")
    }

    /// Triangles of each mesh, from its chunks.
    pub fn mesh_triangles(&self) -> Vec<u64> {
        let mut first = 0usize;
        self.meshes
            .iter()
            .map(|m| {
                let end = first + m.chunks as usize;
                let t = self.chunks[first..end]
                    .iter()
                    .map(|c| u64::from(c.triangles))
                    .sum();
                first = end;
                t
            })
            .collect()
    }

    /// Triangles over all parts (instances counted each time).
    pub fn triangle_count(&self) -> u64 {
        let per_mesh = self.mesh_triangles();
        self.parts.iter().map(|p| per_mesh[p.mesh as usize]).sum()
    }

    /// Triangles stored once per mesh.
    pub fn unique_triangle_count(&self) -> u64 {
        self.mesh_triangles().iter().sum()
    }

    /// Chunk instances over all parts.
    pub fn chunk_instance_count(&self) -> u64 {
        self.parts
            .iter()
            .map(|p| u64::from(self.meshes[p.mesh as usize].chunks))
            .sum()
    }

    /// Bytes its arrays hold (their capacities): what the structure costs in
    /// memory, a few dozen bytes a node, part, mesh and chunk plus the names.
    pub fn held_bytes(&self) -> u64 {
        (self.nodes.capacity() * size_of::<NodeEntry>()
            + self.parts.capacity() * size_of::<PartEntry>()
            + self.meshes.capacity() * size_of::<MeshEntry>()
            + self.chunks.capacity() * size_of::<ChunkEntry>()
            + self.materials.capacity() * 16) as u64
            + self.node_names.held_bytes()
            + self.mesh_names.held_bytes()
            + self.material_names.held_bytes()
            + self.properties.held_bytes()
    }

    /// Checks every index, count, range and number, so that
    /// [`Structure::into_scene`] cannot panic on it (a structure read from a file
    /// may be anything).
    pub fn check(&self) -> Result<(), String> {
        let node_count = self.nodes.len();
        if node_count == 0 {
            return Err("no root node".into());
        }
        self.properties.check(node_count)?;
        for (len, names, what) in [
            (node_count, &self.node_names, "node"),
            (self.meshes.len(), &self.mesh_names, "mesh"),
            (self.materials.len(), &self.material_names, "material"),
        ] {
            if names.len() != len {
                return Err(format!("{} {what} names for {len} {what}s", names.len()));
            }
            names.check(what)?;
        }
        for (i, n) in self.nodes.iter().enumerate() {
            let parent_ok = if i == 0 {
                n.parent == NO_PARENT
            } else {
                (n.parent as usize) < i
            };
            if !parent_ok {
                return Err(format!(
                    "node {i}: parent {} is not stored before it",
                    n.parent
                ));
            }
            if !n.world.iter().all(|v| v.is_finite()) {
                return Err(format!("node {i}: transform is not finite"));
            }
        }
        let mut chunk_total = 0usize;
        for (m, mesh) in self.meshes.iter().enumerate() {
            if mesh.solid > 1 {
                return Err(format!("mesh {m}: solid flag {}", mesh.solid));
            }
            let first = chunk_total;
            chunk_total = chunk_total
                .checked_add(mesh.chunks as usize)
                .filter(|&t| t <= self.chunks.len())
                .ok_or_else(|| format!("mesh {m}: its chunks run past the chunk table"))?;
            let (mut tri, mut vert) = (0u32, 0u32);
            for (k, c) in self.chunks[first..chunk_total].iter().enumerate() {
                let id = first + k;
                if c.material as usize >= self.materials.len() {
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
        if chunk_total != self.chunks.len() {
            return Err(format!(
                "{} chunks belong to no mesh",
                self.chunks.len() - chunk_total
            ));
        }
        let mut has_part = vec![false; node_count];
        for (i, p) in self.parts.iter().enumerate() {
            if p.node == 0 || p.node as usize >= node_count {
                return Err(format!("part {i}: node {} out of range", p.node));
            }
            if std::mem::replace(&mut has_part[p.node as usize], true) {
                return Err(format!("part {i}: node {} already has a part", p.node));
            }
            if p.mesh as usize >= self.meshes.len() {
                return Err(format!("part {i}: mesh {} out of range", p.mesh));
            }
            if p.hidden > 1 {
                return Err(format!("part {i}: hidden flag {}", p.hidden));
            }
        }
        Ok(())
    }

    /// The scene of this structure with its geometry not loaded (see
    /// [`crate::Mesh`]), after [`Structure::check`] and [`Scene::validate`].
    pub fn into_scene(self) -> Result<Scene, SceneError> {
        let invalid = |what: String| SceneError::Invalid { what };
        self.check().map_err(invalid)?;
        let mut b = SceneBuilder::new(self.name(), crate::DEFAULT_CHUNK_TRIANGLES);
        b.reserve_nodes(self.nodes.len());
        for (i, &color) in self.materials.iter().enumerate() {
            b.add_material(self.material_names.get(i), color);
        }
        for (i, n) in self.nodes.iter().enumerate().skip(1) {
            b.add_node(
                NodeId(n.parent),
                self.node_names.get(i),
                DAffine3::from_cols_array(&n.world),
            );
        }
        let mut chunks = self.chunks.iter();
        for (m, mesh) in self.meshes.iter().enumerate() {
            let (mut tri, mut vert) = (0u32, 0u32);
            let table = chunks
                .by_ref()
                .take(mesh.chunks as usize)
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
            b.add_unloaded_mesh(
                self.mesh_names.get(m),
                table,
                mesh.degenerate_triangles,
                mesh.solid == 1,
            );
        }
        let mut hidden = Vec::new();
        for p in &self.parts {
            let part = b.add_part(NodeId(p.node), MeshId(p.mesh));
            if p.hidden == 1 {
                hidden.push(part);
            }
        }
        // Validated here, an error: `Structure::check` does not see the
        // parts' world boxes (a finite transform can still put one beyond
        // ±MAX_WORLD_COORDINATE), and `finish` would assert on them.
        for (node, key, value) in self.properties.iter() {
            b.add_property(node, key, value);
        }
        let mut scene = b.finish_unvalidated();
        for part in hidden {
            scene.set_part_hidden(part, true);
        }
        scene.validate()?;
        Ok(scene)
    }
}

/// A [`Structure`] being built by an importer, with each mesh's box and
/// triangles at hand to check its parts' world transforms as they are added.
#[derive(Debug)]
pub(crate) struct StructureBuilder {
    pub structure: Structure,
    mesh_boxes: Vec<(Aabb3f, u32)>,
}

impl StructureBuilder {
    pub fn new(name: &str) -> Self {
        Self {
            structure: Structure::new(name),
            mesh_boxes: Vec::new(),
        }
    }

    pub fn add_mesh(&mut self, mesh: &ChunkedMesh) -> MeshId {
        let chunks = &mesh.chunks;
        let bounds = chunks.iter().fold(Aabb3f::EMPTY, |b, c| b.union(c.bounds));
        let triangles = chunks.last().map_or(0, |c| c.triangles.end);
        self.mesh_boxes.push((bounds, triangles));
        self.structure.add_mesh(mesh)
    }

    /// Whether `part`'s world transform is valid (see [`Scene::is_valid_world`]).
    pub fn part_world_is_valid(&self, part: PartId) -> bool {
        let p = self.structure.parts[part.index()];
        let (bounds, triangles) = self.mesh_boxes[p.mesh as usize];
        world_is_valid(
            &self.structure.node_world(NodeId(p.node)),
            &bounds,
            triangles,
        )
    }
}
