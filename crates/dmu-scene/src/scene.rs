//! The scene: product structure, parts, chunked part-local geometry, materials.

use std::ops::Range;

use dmu_geom::{Aabb3d, Aabb3f};
use glam::{DAffine3, Vec3};
use serde::{Deserialize, Serialize};

use crate::chunking::{ChunkData, ChunkedMesh, MeshData, chunk_mesh};
use crate::error::SceneError;
use crate::ids::{ChunkId, MaterialId, MeshId, NodeId, PartId};
use crate::properties::{GLOBAL_ID, Properties, SOURCE_FILE};
use crate::structure::Names;

/// Default maximum triangles per chunk.
pub const DEFAULT_CHUNK_TRIANGLES: u32 = 2048;

/// Input limits every front end (command line, viewer, Python) applies the
/// same way; docs/limits.md lists them with the rest.
pub mod limits {
    /// The fewest triangles of a generated plant.
    pub const MIN_PLANT_TRIANGLES: u64 = 10_000;
    /// The most triangles a generated or benchmarked model may have.
    pub const MAX_TRIANGLES: u64 = 1_000_000_000;
    /// The most steps, rays, moves or frames one command may run.
    pub const MAX_STEPS: u64 = 100_000_000;
    /// The most triangles per chunk.
    pub const MAX_CHUNK_TRIANGLES: u32 = 1 << 20;
    /// The largest distance, length or offset an argument takes, model units
    /// (1e12 mm is a million kilometres: past it f64 keeps less than a
    /// micrometre).
    pub const MAX_LENGTH: f64 = 1e12;
}

/// A material: a name and a base colour (linear RGBA, as glTF's `baseColorFactor`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Name, unique or not.
    pub name: String,
    /// Linear RGBA in `[0, 1]`.
    pub base_color: [f32; 4],
}

/// A node of the assembly tree (product structure). Its name and its
/// children are kept by the scene ([`Scene::node_name`],
/// [`Scene::children`]): a name table and sibling links take a few bytes a
/// node where a `String` and a `Vec` each took 24 and an allocation (the
/// 500M plant has 935,650 nodes).
#[derive(Clone, Debug, PartialEq)]
pub struct AssemblyNode {
    /// Parent node; `None` only for the root (node 0).
    pub parent: Option<NodeId>,
    /// Absolute world transform, f64: CAD coordinates far from the origin keep their
    /// millimetres. Stored absolutely, never accumulated, so moves are reversible bit
    /// for bit; moving a node does not move its children.
    pub world: DAffine3,
    /// The part this node instances, if it owns geometry.
    pub part: Option<PartId>,
    /// The first child, [`NO_NODE`] for none.
    first_child: u32,
    /// The next child of the same parent, [`NO_NODE`] for none.
    next_sibling: u32,
}

/// "No node" in a node's sibling links.
const NO_NODE: u32 = u32::MAX;

impl AssemblyNode {
    fn new(parent: Option<NodeId>, world: DAffine3) -> Self {
        Self {
            parent,
            world,
            part: None,
            first_child: NO_NODE,
            next_sibling: NO_NODE,
        }
    }
}

/// A node's children in file order ([`Scene::children`]).
#[derive(Clone, Debug)]
pub struct Children<'a> {
    nodes: &'a [AssemblyNode],
    next: u32,
}

impl Iterator for Children<'_> {
    type Item = NodeId;

    fn next(&mut self) -> Option<NodeId> {
        let node = self.nodes.get(self.next as usize)?;
        let id = NodeId(self.next);
        self.next = node.next_sibling;
        Some(id)
    }
}

/// A part: a node that owns geometry, i.e. one instance of a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The assembly node of this part (its name, path and world transform).
    pub node: NodeId,
    /// The part-local geometry, possibly shared with other parts.
    pub mesh: MeshId,
    /// Hidden parts are skipped by picking and drawing.
    pub hidden: bool,
}

/// Part-local geometry, f32, in chunks. Each chunk's vertices and triangles are
/// contiguous and its indices count from its first vertex.
///
/// **Geometry not loaded.** A mesh may hold its chunk table (ranges, boxes,
/// materials) and triangle count without its vertices: `positions`, `normals` and
/// `indices` are then empty and [`Mesh::is_loaded`] is false. A store's skeleton
/// holds a model this way while its geometry stays on disk
/// ([`SceneBuilder::add_unloaded_mesh`]). Whatever reads structure, transforms and
/// chunk boxes works on such a scene (the tree's build, moves and frustum queries,
/// counts, [`Scene::world_bounds`]); whatever reads triangles (picking, collision,
/// export, [`Scene::triangle_local`], [`Scene::tight_world_bounds`]) needs the
/// geometry loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Name.
    pub name: String,
    /// Local positions, chunk after chunk.
    pub positions: Vec<Vec3>,
    /// Unit normals, parallel to `positions`.
    pub normals: Vec<Vec3>,
    /// Chunk-local indices, three per triangle.
    pub indices: Vec<u32>,
    /// Number of triangles, known also when the geometry is not loaded.
    pub triangles: u32,
    /// This mesh's chunks, a contiguous range of the scene's chunks.
    pub chunks: Range<u32>,
    /// Local box of all positions (empty for a mesh without triangles).
    pub bounds: Aabb3f,
    /// Triangles of zero area: kept, and counted.
    pub degenerate_triangles: u32,
    /// Whether it bounds solids with outward windings ([`crate::is_solid`]):
    /// a renderer may cull its back faces.
    pub solid: bool,
}

impl Mesh {
    /// Number of triangles (also when the geometry is not loaded).
    pub fn triangle_count(&self) -> u64 {
        u64::from(self.triangles)
    }

    /// Whether the vertices and indices are held (always, for a mesh without
    /// triangles); see [`Mesh`] for meshes whose geometry is not loaded.
    pub fn is_loaded(&self) -> bool {
        self.indices.len() == 3 * self.triangles as usize
    }

    /// The chunk ids of this mesh.
    pub fn chunk_ids(&self) -> impl ExactSizeIterator<Item = ChunkId> + use<> {
        self.chunks.clone().map(ChunkId)
    }

    /// One of this mesh's chunks' geometry; `None` when the mesh's geometry
    /// is not loaded.
    pub fn chunk_geometry(&self, chunk: &Chunk) -> Option<ChunkGeometry<'_>> {
        self.is_loaded().then(|| {
            ChunkGeometry::slice(
                &self.positions,
                &self.normals,
                &self.indices,
                &chunk.vertices,
                &chunk.triangles,
            )
        })
    }
}

/// One chunk's geometry, borrowed: part-local f32 vertices and chunk-local
/// indices. What the renderer uploads, collision and picking read and the
/// store writes; the store's decoded chunks lend it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChunkGeometry<'a> {
    /// Positions.
    pub positions: &'a [Vec3],
    /// Unit normals, parallel to `positions`.
    pub normals: &'a [Vec3],
    /// Chunk-local indices, three per triangle, each `< positions.len()`.
    pub indices: &'a [u32],
    /// Its simplified levels ([`crate::lod_levels`] of this geometry) where
    /// they were made already (a store keeps them); `None` where not known,
    /// for whoever needs them to compute.
    pub levels: Option<&'a [crate::LodLevel]>,
}

impl<'a> ChunkGeometry<'a> {
    /// The chunk with vertex range `vertices` and triangle range `triangles`
    /// (index positions divided by three) of a mesh's arrays.
    ///
    /// # Panics
    /// When a range reaches beyond its array.
    pub fn slice(
        positions: &'a [Vec3],
        normals: &'a [Vec3],
        indices: &'a [u32],
        vertices: &Range<u32>,
        triangles: &Range<u32>,
    ) -> Self {
        let v = vertices.start as usize..vertices.end as usize;
        let t = 3 * triangles.start as usize..3 * triangles.end as usize;
        Self {
            positions: &positions[v.clone()],
            normals: &normals[v],
            indices: &indices[t],
            levels: None,
        }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A chunk: a spatially compact run of one mesh's triangles with one material.
#[derive(Clone, Debug, PartialEq)]
pub struct Chunk {
    /// The mesh it belongs to.
    pub mesh: MeshId,
    /// Material of all its triangles.
    pub material: MaterialId,
    /// Triangle range in the mesh (index positions divided by three).
    pub triangles: Range<u32>,
    /// Vertex range in the mesh; the chunk's indices are relative to its start.
    pub vertices: Range<u32>,
    /// Local box of its vertices.
    pub bounds: Aabb3f,
}

impl Chunk {
    /// Number of triangles.
    pub fn triangle_count(&self) -> u32 {
        self.triangles.end - self.triangles.start
    }
}

/// A whole product: assembly tree, parts, meshes, chunks, materials.
///
/// Built through [`SceneBuilder`]; afterwards only part transforms and visibility
/// change, so the geometry invariants checked by [`Scene::validate`] hold for life.
#[derive(Clone, Debug)]
pub struct Scene {
    nodes: Vec<AssemblyNode>,
    /// Every node's name, by node.
    names: Names,
    /// What the source file says of nodes beside their names.
    properties: Properties,
    parts: Vec<Part>,
    meshes: Vec<Mesh>,
    chunks: Vec<Chunk>,
    materials: Vec<Material>,
    /// For a scene read from object storage: the version (ETag) of the
    /// object it was read from, on which a save into it is conditional.
    source_version: Option<String>,
}

impl Scene {
    /// For a scene read from object storage: the version (ETag) of the
    /// object it was read from (or last saved into).
    pub fn source_version(&self) -> Option<&str> {
        self.source_version.as_deref()
    }

    /// Records the version of the object this scene was read from or saved
    /// into ([`Scene::source_version`]).
    pub fn set_source_version(&mut self, version: Option<String>) {
        self.source_version = version;
    }

    /// The scene's name (the root node's name).
    pub fn name(&self) -> &str {
        self.node_name(NodeId(0))
    }
    /// Assembly nodes; index 0 is the root.
    pub fn nodes(&self) -> &[AssemblyNode] {
        &self.nodes
    }
    /// Parts, indexed by [`PartId`].
    pub fn parts(&self) -> &[Part] {
        &self.parts
    }
    /// Meshes, indexed by [`MeshId`].
    pub fn meshes(&self) -> &[Mesh] {
        &self.meshes
    }
    /// Chunks, indexed by [`ChunkId`].
    pub fn chunks(&self) -> &[Chunk] {
        &self.chunks
    }
    /// Materials, indexed by [`MaterialId`].
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }
    /// One node.
    pub fn node(&self, id: NodeId) -> &AssemblyNode {
        &self.nodes[id.index()]
    }
    /// A node's name; importers give unnamed nodes stable generated names.
    pub fn node_name(&self, id: NodeId) -> &str {
        self.names.get(id.index())
    }
    /// A node's properties (an IFC element's GlobalId and class, a STEP
    /// product's name, a glTF node's `extras`), in file order.
    pub fn node_properties(&self, id: NodeId) -> impl Iterator<Item = (&str, &str)> + '_ {
        self.properties.of(id)
    }
    /// Every node's properties.
    pub fn properties(&self) -> &Properties {
        &self.properties
    }
    /// Gives the nodes the properties `properties` (a store keeps them in a
    /// segment of their own); an error when one names a node the scene does
    /// not have.
    pub fn set_properties(&mut self, properties: Properties) -> Result<(), SceneError> {
        properties
            .check(self.nodes.len())
            .map_err(|what| SceneError::Invalid { what })?;
        self.properties = properties;
        Ok(())
    }
    /// A node's children in file order.
    pub fn children(&self, id: NodeId) -> Children<'_> {
        Children {
            nodes: &self.nodes,
            next: self.nodes[id.index()].first_child,
        }
    }
    /// One part.
    pub fn part(&self, id: PartId) -> &Part {
        &self.parts[id.index()]
    }
    /// One mesh.
    pub fn mesh(&self, id: MeshId) -> &Mesh {
        &self.meshes[id.index()]
    }
    /// One chunk.
    pub fn chunk(&self, id: ChunkId) -> &Chunk {
        &self.chunks[id.index()]
    }
    /// A part's geometry.
    pub fn part_mesh(&self, id: PartId) -> &Mesh {
        self.mesh(self.part(id).mesh)
    }
    /// A part's name (its node's name).
    pub fn part_name(&self, id: PartId) -> &str {
        self.node_name(self.part(id).node)
    }
    /// A part's world transform.
    pub fn part_world(&self, id: PartId) -> DAffine3 {
        self.node(self.part(id).node).world
    }
    /// Sets a part's absolute world transform (nothing accumulates).
    ///
    /// # Panics
    /// When the transform is not finite: callers validate user input first.
    pub fn set_part_world(&mut self, id: PartId, world: DAffine3) {
        assert!(world.is_finite(), "part {id}: non-finite transform");
        let node = self.part(id).node;
        self.nodes[node.index()].world = world;
    }
    /// Loads a mesh's geometry into a scene that holds its chunk table only
    /// (a store's skeleton): `chunks` are the mesh's chunks in order, each
    /// checked against its chunk's vertex and triangle counts (indices
    /// below its vertices). Picking and collision then read it like any
    /// loaded mesh. Fails, changing nothing, when a count differs.
    pub fn load_mesh_geometry(
        &mut self,
        id: MeshId,
        chunks: &[ChunkGeometry<'_>],
    ) -> Result<(), SceneError> {
        let m = &self.meshes[id.index()];
        let invalid = |what: String| SceneError::Invalid {
            what: format!("mesh {id} ({:?}): {what}", m.name),
        };
        if chunks.len() != m.chunks.len() {
            return Err(invalid(format!(
                "{} chunks given for {}",
                chunks.len(),
                m.chunks.len()
            )));
        }
        for (c, g) in m.chunk_ids().zip(chunks) {
            let chunk = &self.chunks[c.index()];
            let vertices = (chunk.vertices.end - chunk.vertices.start) as usize;
            let bad_index = g.indices.iter().any(|&i| i as usize >= vertices);
            if g.positions.len() != vertices
                || g.normals.len() != vertices
                || g.indices.len() != 3 * chunk.triangle_count() as usize
                || bad_index
            {
                return Err(invalid(format!(
                    "chunk {c}'s geometry does not fit its table"
                )));
            }
        }
        let m = &mut self.meshes[id.index()];
        m.positions = chunks.iter().flat_map(|g| g.positions).copied().collect();
        m.normals = chunks.iter().flat_map(|g| g.normals).copied().collect();
        m.indices = chunks.iter().flat_map(|g| g.indices).copied().collect();
        Ok(())
    }

    /// Drops a mesh's geometry, keeping its chunk table (the inverse of
    /// [`Scene::load_mesh_geometry`]).
    pub fn unload_mesh_geometry(&mut self, id: MeshId) {
        let m = &mut self.meshes[id.index()];
        if m.triangles > 0 {
            m.positions = Vec::new();
            m.normals = Vec::new();
            m.indices = Vec::new();
        }
    }
    /// Shows or hides a part.
    pub fn set_part_hidden(&mut self, id: PartId, hidden: bool) {
        self.parts[id.index()].hidden = hidden;
    }
    /// Iterates the part ids.
    pub fn part_ids(&self) -> impl ExactSizeIterator<Item = PartId> + use<> {
        (0..self.parts.len() as u32).map(PartId)
    }

    /// The part's place in the product structure: node names from the root's child
    /// down to the part, joined by `/`.
    pub fn part_path(&self, id: PartId) -> String {
        self.node_path(self.part(id).node)
    }

    /// A node's path: names from below the root down to the node, joined by `/`.
    pub fn node_path(&self, id: NodeId) -> String {
        let mut names = Vec::new();
        let mut at = Some(id);
        while let Some(n) = at {
            let node = self.node(n);
            if node.parent.is_some() {
                names.push(self.node_name(n));
            }
            at = node.parent;
        }
        names.reverse();
        names.join("/")
    }

    /// Depth of the assembly tree: 0 for a root alone, 1 when parts hang from the root.
    pub fn assembly_depth(&self) -> usize {
        let mut depth = vec![0usize; self.nodes.len()];
        // Nodes are stored parents first (the builder only links to existing nodes).
        for (i, node) in self.nodes.iter().enumerate() {
            if let Some(p) = node.parent {
                depth[i] = depth[p.index()] + 1;
            }
        }
        depth.into_iter().max().unwrap_or(0)
    }

    /// Triangles over all parts (instances counted each time).
    pub fn triangle_count(&self) -> u64 {
        self.parts
            .iter()
            .map(|p| self.mesh(p.mesh).triangle_count())
            .sum()
    }

    /// Triangles stored once per mesh (instancing not expanded).
    pub fn unique_triangle_count(&self) -> u64 {
        self.meshes.iter().map(Mesh::triangle_count).sum()
    }

    /// Chunk instances over all parts: what the tree holds.
    pub fn chunk_instance_count(&self) -> u64 {
        self.parts
            .iter()
            .map(|p| self.mesh(p.mesh).chunks.len() as u64)
            .sum()
    }

    /// Degenerate (zero-area) triangles over all parts.
    pub fn degenerate_triangle_count(&self) -> u64 {
        self.parts
            .iter()
            .map(|p| u64::from(self.mesh(p.mesh).degenerate_triangles))
            .sum()
    }

    /// A part's world box: its mesh's local box through its f64 world transform.
    pub fn part_world_bounds(&self, id: PartId) -> Aabb3d {
        self.part_mesh(id).bounds.transformed(&self.part_world(id))
    }

    /// A hash of part `id`'s pose (its world transform's bits and its hidden
    /// flag), for change detectors: equal poses hash equal.
    pub fn part_pose_hash(&self, id: PartId) -> u64 {
        xxhash_rust::xxh3::xxh3_64(&self.pose_bytes(id))
    }

    /// A hash of every part's pose in part order (xxh3 of their
    /// [`Scene::part_pose_hash`] bytes one after another). Stores keep it
    /// beside their far fields to tell the model they were made from, so its
    /// value must not change.
    pub fn pose_hash(&self) -> u64 {
        let mut hash = xxhash_rust::xxh3::Xxh3::new();
        for p in self.part_ids() {
            hash.update(&self.pose_bytes(p));
        }
        hash.digest()
    }

    /// A part's world transform (12 `f64`, column-major) and hidden flag.
    fn pose_bytes(&self, id: PartId) -> [u8; 97] {
        let mut bytes = [0; 97];
        bytes[..96].copy_from_slice(bytemuck::cast_slice(&self.part_world(id).to_cols_array()));
        bytes[96] = u8::from(self.part(id).hidden);
        bytes
    }

    /// A chunk's world box when instanced by `part`.
    pub fn chunk_world_bounds(&self, part: PartId, chunk: ChunkId) -> Aabb3d {
        self.chunk(chunk).bounds.transformed(&self.part_world(part))
    }

    /// World box of every part (hidden ones too), from the parts' local boxes:
    /// conservative (it encloses the geometry, padded by a few ulps) and cheap.
    pub fn world_bounds(&self) -> Aabb3d {
        self.part_ids()
            .map(|p| self.part_world_bounds(p))
            .fold(Aabb3d::EMPTY, Aabb3d::union)
    }

    /// The exact world box of every vertex of every part, each transformed in f64:
    /// what a report of the model's extent should show (tight also for rotated
    /// parts). Costs a pass over all instanced vertices, in parallel.
    pub fn tight_world_bounds(&self) -> Aabb3d {
        use rayon::prelude::*;
        (0..self.parts.len())
            .into_par_iter()
            .map(|p| {
                let part = PartId(p as u32);
                let world = self.part_world(part);
                self.part_mesh(part)
                    .positions
                    .iter()
                    .fold(Aabb3d::EMPTY, |b, v| {
                        b.grown(world.transform_point3(v.as_dvec3()))
                    })
            })
            .reduce(|| Aabb3d::EMPTY, Aabb3d::union)
    }

    /// A chunk's geometry; `None` when its mesh's geometry is not loaded (a
    /// store's skeleton).
    pub fn chunk_geometry(&self, id: ChunkId) -> Option<ChunkGeometry<'_>> {
        let c = self.chunk(id);
        self.mesh(c.mesh).chunk_geometry(c)
    }

    /// The three local vertex positions of a chunk's triangle `t` (mesh-relative index).
    pub fn triangle_local(&self, mesh: MeshId, chunk: ChunkId, t: u32) -> [Vec3; 3] {
        let m = self.mesh(mesh);
        let c = self.chunk(chunk);
        let base = c.vertices.start as usize;
        let i = 3 * t as usize;
        [0, 1, 2].map(|k| m.positions[base + m.indices[i + k] as usize])
    }

    /// Finds a part by name, by `#id`, by its full path, or else by its
    /// GlobalId property (an IFC element's). Fails when nothing or more than
    /// one part matches, listing the candidates.
    pub fn find_part(&self, key: &str) -> Result<PartId, SceneError> {
        if let Some(num) = key.strip_prefix('#') {
            return match num.parse::<u32>() {
                Ok(i) if (i as usize) < self.parts.len() => Ok(PartId(i)),
                _ => Err(SceneError::UnknownPart {
                    key: key.to_owned(),
                }),
            };
        }
        let by_name: Vec<PartId> = self
            .part_ids()
            .filter(|&p| self.part_name(p) == key)
            .collect();
        let mut matches = if by_name.is_empty() && key.contains('/') {
            self.parts_at_path(key)
        } else {
            by_name
        };
        if matches.is_empty() {
            matches = self.parts_with_global_id(key);
        }
        match matches.as_slice() {
            [one] => Ok(*one),
            [] => Err(SceneError::UnknownPart {
                key: key.to_owned(),
            }),
            many => Err(SceneError::AmbiguousPart {
                key: key.to_owned(),
                candidates: many
                    .iter()
                    .take(8)
                    .map(|&p| format!("{p} {}", self.part_path(p)))
                    .collect(),
                count: many.len(),
            }),
        }
    }

    /// The parts whose GlobalId property is `global_id`, in id order.
    pub fn parts_with_global_id(&self, global_id: &str) -> Vec<PartId> {
        let mut parts: Vec<PartId> = self
            .properties
            .iter()
            .filter(|&(_, k, v)| k == GLOBAL_ID && v == global_id)
            .filter_map(|(node, _, _)| self.node(node).part)
            .collect();
        parts.sort_unstable();
        parts.dedup();
        parts
    }

    /// The parts whose name, or one of whose property values (a GlobalId,
    /// an IFC class; not the source file, the same on every part), holds
    /// `query`, ignoring case; in id order. What the viewer's
    /// product-structure search lists.
    pub fn search_parts(&self, query: &str) -> Vec<PartId> {
        let query = query.to_lowercase();
        let holds = |s: &str| contains_ignoring_case(s, &query);
        let mut found = vec![false; self.parts.len()];
        for (node, key, value) in self.properties.iter() {
            if key != SOURCE_FILE
                && let Some(part) = self.node(node).part
                && !found[part.index()]
                && holds(value)
            {
                found[part.index()] = true;
            }
        }
        self.part_ids()
            .filter(|&p| found[p.index()] || holds(self.part_name(p)))
            .collect()
    }

    /// The parts whose [`Scene::node_path`] is `path`, found by walking down
    /// from the root through the children whose names lead the rest of it
    /// (names may hold `/` themselves). Each `#id`-less record line looks a
    /// part up: comparing `path` with every part's path built a string a part
    /// per lookup (0.75 ms a line on the 2M plant, 300 s for a batch of
    /// 10,000 records of 40 lines; issue 48's soak).
    fn parts_at_path(&self, path: &str) -> Vec<PartId> {
        let mut found = Vec::new();
        let mut stack = vec![(NodeId(0), path)];
        while let Some((node, rest)) = stack.pop() {
            for child in self.children(node) {
                let Some(after) = rest.strip_prefix(self.node_name(child)) else {
                    continue;
                };
                if after.is_empty() {
                    found.extend(self.node(child).part);
                } else if let Some(below) = after.strip_prefix('/') {
                    stack.push((child, below));
                }
            }
        }
        found.sort_unstable();
        found
    }

    /// Checks every structural invariant; tests call it after each mutation.
    pub fn validate(&self) -> Result<(), SceneError> {
        let fail = |what: String| Err(SceneError::Invalid { what });
        if self.nodes.first().is_none_or(|r| r.parent.is_some()) {
            return fail("node 0 must be the root".into());
        }
        if let Err(what) = self.properties.check(self.nodes.len()) {
            return fail(what);
        }
        // Each node listed once among its parent's children: linear, where a
        // search of the parent's list was quadratic for wide assemblies.
        let mut listed = vec![false; self.nodes.len()];
        for (i, node) in self.nodes.iter().enumerate() {
            if i > 0 && node.parent.is_none_or(|p| p.index() >= i) {
                return fail(format!("node {i} must have a parent stored before it"));
            }
            for c in self.children(NodeId(i as u32)) {
                if self.nodes.get(c.index()).and_then(|c| c.parent) != Some(NodeId(i as u32)) {
                    return fail(format!("node {i}: child {c} does not name it as parent"));
                }
                if std::mem::replace(&mut listed[c.index()], true) {
                    return fail(format!("node {c} listed twice among its parent's children"));
                }
            }
        }
        for (i, node) in self.nodes.iter().enumerate() {
            if node.parent.is_some() && !listed[i] {
                return fail(format!("node {i} missing from its parent's children"));
            }
            if !node.world.is_finite() {
                return fail(format!("node {i}: non-finite world transform"));
            }
            if let Some(part) = node.part
                && self.parts.get(part.index()).map(|p| p.node) != Some(NodeId(i as u32))
            {
                return fail(format!("node {i}: part {part} does not point back"));
            }
        }
        for (i, part) in self.parts.iter().enumerate() {
            if self.nodes.get(part.node.index()).and_then(|n| n.part) != Some(PartId(i as u32)) {
                return fail(format!("part {i}: node {} does not point back", part.node));
            }
            if part.mesh.index() >= self.meshes.len() {
                return fail(format!("part {i}: mesh {} out of range", part.mesh));
            }
        }
        let mut next_chunk = 0u32;
        for (m, mesh) in self.meshes.iter().enumerate() {
            if mesh.chunks.start != next_chunk || mesh.chunks.end as usize > self.chunks.len() {
                return fail(format!(
                    "mesh {m}: chunk range {:?} not contiguous",
                    mesh.chunks
                ));
            }
            next_chunk = mesh.chunks.end;
            let loaded = mesh.is_loaded();
            let holds_vertices = !(mesh.positions.is_empty() && mesh.normals.is_empty());
            if !loaded && holds_vertices {
                return fail(format!("mesh {m}: vertices held but not indices"));
            }
            if mesh.normals.len() != mesh.positions.len() || mesh.indices.len() % 3 != 0 {
                return fail(format!("mesh {m}: attribute lengths disagree"));
            }
            let (mut tri, mut vert, mut bounds) = (0u32, 0u32, Aabb3f::EMPTY);
            for c in mesh.chunk_ids() {
                let chunk = self.chunk(c);
                if chunk.mesh != MeshId(m as u32) || chunk.material.index() >= self.materials.len()
                {
                    return fail(format!("chunk {c}: wrong mesh or material"));
                }
                if chunk.triangles.start != tri || chunk.vertices.start != vert {
                    return fail(format!("chunk {c}: ranges not contiguous"));
                }
                (tri, vert) = (chunk.triangles.end, chunk.vertices.end);
                let Some(g) = mesh.chunk_geometry(chunk) else {
                    // Not loaded: nothing to check the box against but its own sanity.
                    if chunk.bounds.is_empty() || !chunk.bounds.is_finite() {
                        return fail(format!("chunk {c}: box empty or not finite"));
                    }
                    bounds = bounds.union(chunk.bounds);
                    continue;
                };
                let verts = chunk.vertices.end - chunk.vertices.start;
                if let Some(bad) = g.indices.iter().find(|&&i| i >= verts) {
                    return fail(format!("chunk {c}: index {bad} >= {verts} vertices"));
                }
                if chunk.bounds != Aabb3f::from_points(g.positions.iter().copied()) {
                    return fail(format!("chunk {c}: box does not fit its vertices"));
                }
                bounds = bounds.union(chunk.bounds);
            }
            let covered = if loaded {
                vert as usize == mesh.positions.len()
            } else {
                true
            };
            if tri != mesh.triangles || !covered {
                return fail(format!("mesh {m}: chunks do not cover the mesh"));
            }
            if bounds != mesh.bounds {
                return fail(format!("mesh {m}: box is not the union of its chunks"));
            }
        }
        if next_chunk as usize != self.chunks.len() {
            return fail("chunks not owned by any mesh".into());
        }
        if let Some(p) = self
            .part_ids()
            .find(|&p| !self.is_valid_world(p, &self.part_world(p)))
        {
            return fail(format!(
                "part {p} ({}): world box not finite or beyond ±{MAX_WORLD_COORDINATE:e}",
                self.part_path(p)
            ));
        }
        Ok(())
    }

    /// Whether `world` is a valid world transform for a part: finite, and giving
    /// the part a world box within ±[`MAX_WORLD_COORDINATE`] (finite coordinates
    /// times finite scales can overflow, and squared distances between points
    /// far beyond it do). Every part of a valid scene has one; inputs that set
    /// one (an import, a typed move, a record's pose) are checked with this first.
    pub fn is_valid_world(&self, id: PartId, world: &DAffine3) -> bool {
        let mesh = self.part_mesh(id);
        world_is_valid(world, &mesh.bounds, mesh.triangles)
    }
}

/// Whether `world` is a valid world transform for a part whose mesh has the
/// local box `bounds` and `triangles` triangles (see [`Scene::is_valid_world`]).
pub(crate) fn world_is_valid(world: &DAffine3, bounds: &Aabb3f, triangles: u32) -> bool {
    let inside = |v: glam::DVec3| v.abs().max_element() <= MAX_WORLD_COORDINATE;
    world.is_finite()
        && inside(world.translation)
        && (triangles == 0 || {
            let b = bounds.transformed(world);
            inside(b.min) && inside(b.max)
        })
}

/// The largest world coordinate a part may reach, in model units: 1e15 mm is a
/// billion kilometres, and f64 still resolves 0.125 mm there. Beyond about
/// 1e154 squared distances overflow; this keeps every computation far from it.
pub const MAX_WORLD_COORDINATE: f64 = 1e15;

/// Builds a [`Scene`]: materials, nodes (parents before children), meshes, parts.
#[derive(Debug)]
pub struct SceneBuilder {
    scene: Scene,
    chunk_triangles: u32,
    /// Each node's last child so far, [`NO_NODE`] for none.
    last_child: Vec<u32>,
}

impl SceneBuilder {
    /// A scene with a root node named `name` at the identity transform.
    pub fn new(name: impl AsRef<str>, chunk_triangles: u32) -> Self {
        assert!(chunk_triangles > 0, "chunk_triangles must be positive");
        Self {
            scene: Scene {
                nodes: vec![AssemblyNode::new(None, DAffine3::IDENTITY)],
                names: {
                    let mut names = Names::default();
                    names.push(name.as_ref());
                    names
                },
                properties: Properties::default(),
                parts: Vec::new(),
                meshes: Vec::new(),
                chunks: Vec::new(),
                materials: Vec::new(),
                source_version: None,
            },
            chunk_triangles,
            last_child: vec![NO_NODE],
        }
    }

    /// Room for `nodes` more nodes, when the caller knows (a store's
    /// structure): the node table is then allocated once, at its size.
    pub fn reserve_nodes(&mut self, nodes: usize) {
        self.scene.nodes.reserve_exact(nodes);
        self.scene.names.ends.reserve_exact(nodes);
        self.last_child.reserve_exact(nodes);
    }

    /// The root node.
    pub const ROOT: NodeId = NodeId(0);

    /// The chunk size this builder splits meshes with.
    pub fn chunk_triangles(&self) -> u32 {
        self.chunk_triangles
    }

    /// Adds a material.
    pub fn add_material(&mut self, name: impl Into<String>, base_color: [f32; 4]) -> MaterialId {
        self.scene.materials.push(Material {
            name: name.into(),
            base_color,
        });
        MaterialId::from_index(self.scene.materials.len() - 1)
    }

    /// Number of materials so far.
    pub fn material_count(&self) -> usize {
        self.scene.materials.len()
    }

    /// Adds a node under `parent` with an absolute world transform.
    pub fn add_node(&mut self, parent: NodeId, name: impl AsRef<str>, world: DAffine3) -> NodeId {
        let id = NodeId::from_index(self.scene.nodes.len());
        let p = parent.index();
        match self.last_child[p] {
            NO_NODE => self.scene.nodes[p].first_child = id.0,
            last => self.scene.nodes[last as usize].next_sibling = id.0,
        }
        self.last_child[p] = id.0;
        self.last_child.push(NO_NODE);
        self.scene
            .nodes
            .push(AssemblyNode::new(Some(parent), world));
        self.scene.names.push(name.as_ref());
        id
    }

    /// Gives a node added earlier a property.
    ///
    /// # Panics
    /// When `node` comes before a node given one earlier: properties are
    /// added in node order.
    pub fn add_property(&mut self, node: NodeId, key: &str, value: &str) {
        self.scene.properties.push(node, key, value);
    }

    /// The world transform of a node added earlier.
    pub fn node_world(&self, id: NodeId) -> DAffine3 {
        self.scene.nodes[id.index()].world
    }

    /// The path of a node added earlier (see [`Scene::node_path`]).
    pub fn node_path(&self, id: NodeId) -> String {
        self.scene.node_path(id)
    }

    /// Whether a part added earlier has a valid world transform (see
    /// [`Scene::is_valid_world`]).
    pub fn part_world_is_valid(&self, id: PartId) -> bool {
        self.scene.is_valid_world(id, &self.scene.part_world(id))
    }

    /// Chunks and adds a mesh (see [`chunk_mesh`]).
    pub fn add_mesh(&mut self, mesh: &MeshData) -> MeshId {
        let chunked = chunk_mesh(mesh, self.chunk_triangles);
        self.add_chunked_mesh(chunked)
    }

    /// Adds a mesh chunked beforehand, e.g. on a rayon worker.
    pub fn add_chunked_mesh(&mut self, mesh: ChunkedMesh) -> MeshId {
        let triangles = u32::try_from(mesh.indices.len() / 3).expect("mesh over 4G triangles");
        self.push_mesh(mesh, triangles)
    }

    /// Adds a mesh whose geometry is not loaded: its chunk table and counts only
    /// (see [`Mesh`]). A store's skeleton is built this way.
    ///
    /// # Panics
    /// When the chunks' triangle and vertex ranges do not follow each other from 0
    /// (as [`chunk_mesh`] makes them), or a chunk names an unknown material.
    pub fn add_unloaded_mesh(
        &mut self,
        name: impl Into<String>,
        chunks: Vec<ChunkData>,
        degenerate_triangles: u32,
        solid: bool,
    ) -> MeshId {
        let (mut tri, mut vert) = (0, 0);
        for c in &chunks {
            assert!(
                c.triangles.start == tri && c.vertices.start == vert,
                "unloaded mesh: chunk ranges must follow each other from 0"
            );
            (tri, vert) = (c.triangles.end, c.vertices.end);
        }
        let mesh = ChunkedMesh {
            name: name.into(),
            chunks,
            degenerate_triangles,
            solid,
            ..ChunkedMesh::default()
        };
        self.push_mesh(mesh, tri)
    }

    fn push_mesh(&mut self, mesh: ChunkedMesh, triangles: u32) -> MeshId {
        let id = MeshId::from_index(self.scene.meshes.len());
        let first = self.scene.chunks.len() as u32;
        let mut bounds = Aabb3f::EMPTY;
        for c in mesh.chunks {
            assert!(
                c.material.index() < self.scene.materials.len(),
                "unknown material {}",
                c.material
            );
            bounds = bounds.union(c.bounds);
            self.scene.chunks.push(Chunk {
                mesh: id,
                material: c.material,
                triangles: c.triangles,
                vertices: c.vertices,
                bounds: c.bounds,
            });
        }
        self.scene.meshes.push(Mesh {
            name: mesh.name,
            positions: mesh.positions,
            normals: mesh.normals,
            indices: mesh.indices,
            triangles,
            chunks: first..self.scene.chunks.len() as u32,
            bounds,
            degenerate_triangles: mesh.degenerate_triangles,
            solid: mesh.solid,
        });
        id
    }

    /// Makes `node` a part instancing `mesh`.
    ///
    /// # Panics
    /// When the node already has a part.
    pub fn add_part(&mut self, node: NodeId, mesh: MeshId) -> PartId {
        assert!(
            mesh.index() < self.scene.meshes.len(),
            "unknown mesh {mesh}"
        );
        let id = PartId::from_index(self.scene.parts.len());
        let slot = &mut self.scene.nodes[node.index()].part;
        assert!(slot.is_none(), "node {node} already has a part");
        *slot = Some(id);
        self.scene.parts.push(Part {
            node,
            mesh,
            hidden: false,
        });
        id
    }

    /// Triangles over the parts added so far.
    pub fn triangle_count(&self) -> u64 {
        self.scene.triangle_count()
    }

    /// The finished scene.
    pub fn finish(self) -> Scene {
        debug_assert_eq!(self.scene.validate(), Ok(()));
        self.scene
    }

    /// The scene as built, not validated: for a caller that builds from input
    /// read from a file and calls [`Scene::validate`] itself, so that a bad
    /// input is an error (where [`SceneBuilder::finish`] asserts in debug
    /// builds).
    pub(crate) fn finish_unvalidated(self) -> Scene {
        self.scene
    }
}

/// Whether `haystack` holds `lower` (already lower-case), ignoring case:
/// without allocating when `haystack` is ASCII, as names and ids mostly are.
fn contains_ignoring_case(haystack: &str, lower: &str) -> bool {
    if !haystack.is_ascii() || !lower.is_ascii() {
        return haystack.to_lowercase().contains(lower);
    }
    let (h, n) = (haystack.as_bytes(), lower.as_bytes());
    n.is_empty() || h.windows(n.len()).any(|w| w.eq_ignore_ascii_case(n))
}
