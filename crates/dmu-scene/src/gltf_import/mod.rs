//! glTF 2.0 import (.gltf with external or data-URI buffers, .glb).
//!
//! The JSON is read as a stream (`nodes.rs`): nodes, the one member that grows
//! with the assembly, go one at a time into flat arrays with their transforms
//! as f64 (the `gltf` crate keeps them in f32, which cannot hold a millimetre
//! offset of 1e7); the other members are parsed by the `gltf` crate. Buffers,
//! accessors and the node graph are read here with every reference checked, so
//! a broken file gives an error naming the element at fault and never a panic.

mod accessor;
mod buffers;
mod nodes;
mod stream;

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DAffine3, DMat4, DQuat, DVec3, Vec3};
use gltf::json::{self, mesh::Mode, mesh::Semantic, validation::Checked};
use rayon::prelude::*;
use serde::Deserialize;

use self::accessor::{Data, read_indices, read_vectors};
use self::buffers::{invalid, load_buffers, resolve_views, split_container};
use crate::chunking::{ChunkedMesh, MeshData, chunk_mesh, compute_normals};
use crate::error::ImportError;
use crate::ids::{MaterialId, MeshId, NodeId, PartId};
use crate::scene::{Scene, SceneBuilder};
use crate::structure::StructureBuilder;

use self::nodes::{FileNodes, UNUSED_MEMBERS};
pub use stream::{StreamOptions, Streamed, import_gltf_streaming};

/// Required extensions dmu reads. Material, texture and light extensions change
/// only shading that dmu does not draw (it shows base colours), so geometry is
/// complete without them.
pub const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_mesh_quantization",
    "EXT_meshopt_compression",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_unlit",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_iridescence",
    "KHR_materials_anisotropy",
    "KHR_materials_dispersion",
    "KHR_materials_variants",
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "KHR_lights_punctual",
];

/// Import settings.
#[derive(Clone, Copy)]
pub struct ImportOptions<'a> {
    /// Maximum triangles per chunk.
    pub chunk_triangles: u32,
    /// Called with (meshes done, meshes total) from worker threads.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
}

impl std::fmt::Debug for ImportOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImportOptions")
            .field("chunk_triangles", &self.chunk_triangles)
            .finish_non_exhaustive()
    }
}

impl Default for ImportOptions<'_> {
    fn default() -> Self {
        Self {
            chunk_triangles: crate::DEFAULT_CHUNK_TRIANGLES,
            progress: None,
        }
    }
}

/// What an import skipped or repaired, for reports.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ImportReport {
    /// Primitives of mode POINTS, skipped.
    pub point_primitives_skipped: usize,
    /// Primitives of mode LINES, LINE_LOOP or LINE_STRIP, skipped.
    pub line_primitives_skipped: usize,
    /// Triangle primitives with no NORMAL (or a non-finite one), given computed normals.
    pub primitives_with_computed_normals: usize,
    /// Meshes referenced by no node in the scene (not imported as parts).
    pub unused_meshes: usize,
    /// Node `extras` members not kept as properties: a value that is null,
    /// an array or an object, a key over 256 bytes, a value over 4 KiB, or
    /// beyond 64 on one node (an `extras` that is not an object counts once).
    pub properties_dropped: usize,
    /// Products a converter could not tessellate (STEP and IFC, see
    /// `dmu_store::cad`): left out, the rest imported.
    pub failed_products: Vec<FailedProduct>,
}

/// A product of a CAD file left out of an import: its name, its class (an
/// IFC class, or "STEP product") and why.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FailedProduct {
    /// The product's name.
    pub name: String,
    /// Its class.
    pub class: String,
    /// What failed.
    pub reason: String,
}

/// Imports a .gltf or .glb file.
pub fn import_gltf(
    path: &Path,
    options: &ImportOptions<'_>,
) -> Result<(Scene, ImportReport), ImportError> {
    let bytes = crate::atomic::read_regular_file(path).map_err(|source| ImportError::Io {
        path: path.to_owned(),
        source,
    })?;
    let name = path
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    import_gltf_slice(&bytes, path.parent(), &name, options)
}

/// Imports glTF from memory; `base_dir` resolves external buffer files.
pub fn import_gltf_slice(
    bytes: &[u8],
    base_dir: Option<&Path>,
    default_name: &str,
    options: &ImportOptions<'_>,
) -> Result<(Scene, ImportReport), ImportError> {
    let (json_bytes, blob) = split_container(bytes)?;
    let doc = Document::parse(json_bytes)?;
    let root = &doc.root;
    let buffers = load_buffers(root, blob, base_dir);
    let views = resolve_views(root, &buffers, &|_| true);
    let data = Data {
        root,
        views: &views,
    };
    let (mut builder, default_material) = doc.start(default_name, options.chunk_triangles);

    let mut report = ImportReport::default();
    let used = doc.used_meshes()?;
    let done = AtomicUsize::new(0);
    let total = used.iter().filter(|&&u| u).count();
    let meshes: Vec<Option<(ChunkedMesh, ImportReport)>> = root
        .meshes
        .par_iter()
        .enumerate()
        .map(|(m, mesh)| {
            if !used[m] {
                return Ok(None);
            }
            let decoded = decode_mesh(&data, m, mesh, default_material, options.chunk_triangles)?;
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            if let Some(progress) = options.progress {
                progress(n, total);
            }
            Ok(Some(decoded))
        })
        .collect::<Result<_, ImportError>>()?;
    let mut mesh_ids = vec![None; meshes.len()];
    for (m, decoded) in meshes.into_iter().enumerate() {
        match decoded {
            Some((chunked, r)) => {
                report.add(&r);
                mesh_ids[m] = Some(builder.add_chunked_mesh(chunked));
            }
            None => report.unused_meshes += 1,
        }
    }
    doc.add_nodes(&mesh_ids, &mut builder, &mut report)?;
    Ok((builder.finish(), report))
}

impl ImportReport {
    /// Adds a mesh's counts of skipped and repaired primitives.
    fn add(&mut self, r: &ImportReport) {
        self.point_primitives_skipped += r.point_primitives_skipped;
        self.line_primitives_skipped += r.line_primitives_skipped;
        self.primitives_with_computed_normals += r.primitives_with_computed_normals;
    }
}

/// A parsed glTF document: the typed JSON without its nodes, the nodes flat
/// (transforms as f64), and the scene to import.
struct Document {
    root: json::Root,
    nodes: FileNodes,
    scene_index: Option<usize>,
}

impl Document {
    /// Parses JSON held in memory (the in-memory import), as
    /// [`Document::parse_stream`] reads it.
    fn parse(json_bytes: &[u8]) -> Result<Self, ImportError> {
        Self::read(&mut serde_json::Deserializer::from_slice(json_bytes), &|| 0)
    }

    /// Reads the JSON as a stream: nodes go straight into flat arrays, one at a
    /// time; only the other members (a few per mesh) are held as values.
    /// `position` tells how far the reader has read (for the nodes' JSON size).
    fn parse_stream(
        reader: impl std::io::Read,
        position: &dyn Fn() -> u64,
    ) -> Result<Self, ImportError> {
        Self::read(&mut serde_json::Deserializer::from_reader(reader), position)
    }

    fn read<'de, R: serde_json::de::Read<'de>>(
        de: &mut serde_json::Deserializer<R>,
        position: &dyn Fn() -> u64,
    ) -> Result<Self, ImportError> {
        let (top, nodes) = nodes::read_document(&mut *de, position).map_err(malformed)?;
        de.end().map_err(malformed)?;
        Self::finish(top, nodes)
    }

    /// The typed document of the members other than the nodes.
    fn finish(
        mut top: serde_json::Map<String, serde_json::Value>,
        nodes: FileNodes,
    ) -> Result<Self, ImportError> {
        // dmu shows geometry and base colours only: sections it never reads are dropped
        // before typed parsing, so their schema quirks (e.g. an animation target
        // without a node, valid since KHR_animation_pointer) cannot fail an import.
        for unused in UNUSED_MEMBERS {
            top.remove(unused);
        }
        let mut value = serde_json::Value::Object(top);
        integral_floats_to_integers(&mut value);
        // `scene.nodes` is optional in the spec but required by the `gltf` crate.
        for scene in value
            .get_mut("scenes")
            .and_then(|s| s.as_array_mut())
            .into_iter()
            .flatten()
        {
            if let Some(scene) = scene.as_object_mut() {
                scene
                    .entry("nodes")
                    .or_insert_with(|| serde_json::json!([]));
            }
        }
        let root = json::Root::deserialize(&value).map_err(malformed)?;
        drop(value);
        if let Some(name) = root
            .extensions_required
            .iter()
            .find(|e| !SUPPORTED_REQUIRED.contains(&e.as_str()))
        {
            return Err(ImportError::UnsupportedExtension { name: name.clone() });
        }
        let scene_index = match root.scene {
            Some(s) => Some(s.value()),
            None if root.scenes.is_empty() => None,
            None => Some(0),
        };
        if let Some(s) = scene_index
            && s >= root.scenes.len()
        {
            return Err(invalid(format!("scene {s} does not exist")));
        }
        Ok(Self {
            root,
            nodes,
            scene_index,
        })
    }

    fn scene_json(&self) -> Option<&json::Scene> {
        self.scene_index.map(|s| &self.root.scenes[s])
    }

    /// The scene's name, and the material for primitives that name none (a
    /// grey added after the file's materials, only when needed), calling
    /// `add_material` for each material.
    fn materials(
        &self,
        default_name: &str,
        add_material: &mut dyn FnMut(&str, [f32; 4]),
    ) -> (String, MaterialId) {
        let root = &self.root;
        let name = self
            .scene_json()
            .and_then(|s| s.name.clone())
            .unwrap_or_else(|| default_name.to_owned());
        for (i, m) in root.materials.iter().enumerate() {
            let name = m.name.clone().unwrap_or_else(|| format!("material{i}"));
            add_material(&name, base_color(m));
        }
        let default_material = MaterialId::from_index(root.materials.len());
        if root
            .meshes
            .iter()
            .flat_map(|m| &m.primitives)
            .any(|p| p.material.is_none())
        {
            add_material("default", [0.8, 0.8, 0.8, 1.0]);
        }
        (name, default_material)
    }

    /// A builder named after the scene holding the file's materials, and the
    /// material for primitives that name none.
    fn start(&self, default_name: &str, chunk_triangles: u32) -> (SceneBuilder, MaterialId) {
        let mut materials = Vec::new();
        let (name, default_material) =
            self.materials(default_name, &mut |n, c| materials.push((n.to_owned(), c)));
        let mut builder = SceneBuilder::new(name, chunk_triangles);
        for (n, c) in materials {
            builder.add_material(n, c);
        }
        (builder, default_material)
    }

    fn used_meshes(&self) -> Result<Vec<bool>, ImportError> {
        let mut used = vec![false; self.root.meshes.len()];
        self.walk_nodes(|n, _| {
            if let Some(m) = self.nodes.mesh(n) {
                *used.get_mut(m).ok_or_else(|| {
                    invalid(format!("nodes[{n}].mesh: mesh {m} does not exist"))
                })? = true;
            }
            Ok(())
        })?;
        Ok(used)
    }

    /// The root nodes of the imported scene: the chosen scene's, or every parentless
    /// node when the file has no scene (a CAD viewer shows what is there).
    fn root_nodes(&self) -> Vec<usize> {
        match self.scene_json() {
            Some(s) => s.nodes.iter().map(|n| n.value()).collect(),
            None => {
                let mut has_parent = vec![false; self.nodes.len()];
                for n in 0..self.nodes.len() {
                    for &c in self.nodes.children(n) {
                        if let Some(p) = has_parent.get_mut(c as usize) {
                            *p = true;
                        }
                    }
                }
                (0..self.nodes.len()).filter(|&i| !has_parent[i]).collect()
            }
        }
    }

    /// Walks the node graph once, checking references, cycles and shared children,
    /// and calls `visit(node, parent_slot)` parents first.
    fn walk_nodes(
        &self,
        mut visit: impl FnMut(usize, Option<usize>) -> Result<(), ImportError>,
    ) -> Result<(), ImportError> {
        let mut seen = vec![false; self.nodes.len()];
        let mut stack: Vec<(usize, Option<usize>)> = self
            .root_nodes()
            .into_iter()
            .rev()
            .map(|n| (n, None))
            .collect();
        while let Some((n, parent)) = stack.pop() {
            if n >= self.nodes.len() {
                return Err(invalid(format!("node {n} does not exist")));
            }
            if std::mem::replace(&mut seen[n], true) {
                return Err(invalid(format!(
                    "nodes[{n}] is reached twice: the node graph has a cycle or a shared child"
                )));
            }
            visit(n, parent)?;
            for &c in self.nodes.children(n).iter().rev() {
                stack.push((c as usize, Some(n)));
            }
        }
        Ok(())
    }

    /// Adds the scene's nodes (parents first, absolute f64 transforms) with
    /// their properties, and a part for each node whose mesh was imported
    /// (`mesh_ids`); counts the properties dropped into `report`.
    fn add_nodes(
        &self,
        mesh_ids: &[Option<MeshId>],
        builder: &mut dyn Assembly,
        report: &mut ImportReport,
    ) -> Result<(), ImportError> {
        report.properties_dropped = self.nodes.properties_dropped();
        let root = &self.root;
        let mut ids: Vec<Option<NodeId>> = vec![None; self.nodes.len()];
        self.walk_nodes(|n, parent| {
            let parent_id = parent.and_then(|p| ids[p]).unwrap_or(SceneBuilder::ROOT);
            let world = builder.node_world(parent_id) * self.nodes.local(n)?;
            let mesh_index = self.nodes.mesh(n);
            let generated;
            let name = match self.nodes.name(n) {
                Some(name) => name,
                None => {
                    // Stable names from file indices: unnamed instances of a named
                    // mesh keep the mesh's name.
                    generated = match mesh_index.and_then(|m| root.meshes[m].name.as_ref()) {
                        Some(mesh_name) => format!("{mesh_name}.{n}"),
                        None => format!("node{n}"),
                    };
                    generated.as_str()
                }
            };
            let id = builder.add_node(parent_id, name, world);
            ids[n] = Some(id);
            for (key, value) in self.nodes.properties(n) {
                builder.add_property(id, key, value);
            }
            let non_finite = |builder: &dyn Assembly, what| ImportError::NonFiniteWorld {
                node: n,
                path: builder.node_path(id),
                what,
            };
            if !world.is_finite() {
                return Err(non_finite(builder, "world transform"));
            }
            if let Some(mesh) = mesh_index.and_then(|m| mesh_ids[m]) {
                let part = builder.add_part(id, mesh);
                if !builder.part_world_is_valid(part) {
                    return Err(non_finite(builder, "world box"));
                }
            }
            Ok(())
        })
    }
}

/// Where the node walk puts nodes and parts: a scene's builder (the in-memory
/// import) or a flat structure (the streaming one).
trait Assembly {
    fn add_node(&mut self, parent: NodeId, name: &str, world: DAffine3) -> NodeId;
    fn add_property(&mut self, node: NodeId, key: &str, value: &str);
    fn node_world(&self, id: NodeId) -> DAffine3;
    fn node_path(&self, id: NodeId) -> String;
    fn add_part(&mut self, node: NodeId, mesh: MeshId) -> PartId;
    fn part_world_is_valid(&self, part: PartId) -> bool;
}

impl Assembly for SceneBuilder {
    fn add_node(&mut self, parent: NodeId, name: &str, world: DAffine3) -> NodeId {
        SceneBuilder::add_node(self, parent, name, world)
    }
    fn add_property(&mut self, node: NodeId, key: &str, value: &str) {
        SceneBuilder::add_property(self, node, key, value);
    }
    fn node_world(&self, id: NodeId) -> DAffine3 {
        SceneBuilder::node_world(self, id)
    }
    fn node_path(&self, id: NodeId) -> String {
        SceneBuilder::node_path(self, id)
    }
    fn add_part(&mut self, node: NodeId, mesh: MeshId) -> PartId {
        SceneBuilder::add_part(self, node, mesh)
    }
    fn part_world_is_valid(&self, part: PartId) -> bool {
        SceneBuilder::part_world_is_valid(self, part)
    }
}

impl Assembly for StructureBuilder {
    fn add_node(&mut self, parent: NodeId, name: &str, world: DAffine3) -> NodeId {
        self.structure.add_node(parent, name, world)
    }
    fn add_property(&mut self, node: NodeId, key: &str, value: &str) {
        self.structure.properties.push(node, key, value);
    }
    fn node_world(&self, id: NodeId) -> DAffine3 {
        self.structure.node_world(id)
    }
    fn node_path(&self, id: NodeId) -> String {
        self.structure.node_path(id)
    }
    fn add_part(&mut self, node: NodeId, mesh: MeshId) -> PartId {
        self.structure.add_part(node, mesh)
    }
    fn part_world_is_valid(&self, part: PartId) -> bool {
        StructureBuilder::part_world_is_valid(self, part)
    }
}

fn malformed(e: serde_json::Error) -> ImportError {
    ImportError::Malformed {
        message: format!("JSON: {e}"),
    }
}

/// JSON has one number type: `1.0` is a valid glTF integer (the validator accepts
/// it), but the `gltf` crate's serde types refuse it. Integral floats become
/// integers; fields that want floats accept integers.
fn integral_floats_to_integers(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Number(n) if n.is_f64() => {
            if let Some(f) = n.as_f64().filter(|f| f.fract() == 0.0 && f.abs() < 9.0e15) {
                *n = if f < 0.0 {
                    (f as i64).into()
                } else {
                    (f as u64).into()
                };
            }
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(integral_floats_to_integers),
        serde_json::Value::Object(o) => o.values_mut().for_each(integral_floats_to_integers),
        _ => {}
    }
}

fn base_color(m: &json::Material) -> [f32; 4] {
    // Specular-glossiness files keep their colour in diffuseFactor.
    let spec_gloss = m
        .extensions
        .as_ref()
        .and_then(|e| e.others.get("KHR_materials_pbrSpecularGlossiness"))
        .and_then(|e| e.get("diffuseFactor"))
        .and_then(|v| serde_json::from_value::<[f32; 4]>(v.clone()).ok());
    let c = spec_gloss.unwrap_or(m.pbr_metallic_roughness.base_color_factor.0);
    c.map(|v| {
        if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            1.0
        }
    })
}

/// A node's transform as f64 (the `gltf` crate holds it as f32).
#[derive(Deserialize)]
struct RawNode {
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
}

impl RawNode {
    fn local(&self, index: usize) -> Result<DAffine3, ImportError> {
        let m = if let Some(m) = self.matrix {
            // Column-major: the last row is m[3], m[7], m[11], m[15].
            if [m[3], m[7], m[11], m[15]] != [0.0, 0.0, 0.0, 1.0] {
                return Err(invalid(format!(
                    "nodes[{index}].matrix: the last row is {:?}, not [0, 0, 0, 1] (glTF node matrices are affine)",
                    [m[3], m[7], m[11], m[15]]
                )));
            }
            DAffine3::from_mat4(DMat4::from_cols_array(&m))
        } else {
            let t = self.translation.map_or(DVec3::ZERO, DVec3::from_array);
            let r = self
                .rotation
                .map_or(DQuat::IDENTITY, |q| DQuat::from_array(q).normalize());
            let s = self.scale.map_or(DVec3::ONE, DVec3::from_array);
            DAffine3::from_scale_rotation_translation(s, r, t)
        };
        if m.is_finite() {
            Ok(m)
        } else {
            Err(invalid(format!("nodes[{index}]: transform is not finite")))
        }
    }
}

/// Decodes and chunks one mesh; its primitives become material groups.
fn decode_mesh(
    data: &Data<'_>,
    m: usize,
    mesh: &json::Mesh,
    default_material: MaterialId,
    chunk_triangles: u32,
) -> Result<(ChunkedMesh, ImportReport), ImportError> {
    let mesh_name = mesh.name.clone().unwrap_or_else(|| format!("mesh{m}"));
    let mut out = MeshData {
        name: mesh_name.clone(),
        ..MeshData::default()
    };
    let mut report = ImportReport::default();
    for (p, prim) in mesh.primitives.iter().enumerate() {
        let mode = match prim.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => {
                return Err(invalid(format!(
                    "meshes[{m}].primitives[{p}].mode is invalid"
                )));
            }
        };
        match mode {
            Mode::Points => {
                report.point_primitives_skipped += 1;
                continue;
            }
            Mode::Lines | Mode::LineLoop | Mode::LineStrip => {
                report.line_primitives_skipped += 1;
                continue;
            }
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => {}
        }
        let attribute = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|a| a.value());
        let pos_accessor = attribute(Semantic::Positions).ok_or_else(|| {
            invalid(format!(
                "meshes[{m}].primitives[{p}] has no POSITION attribute"
            ))
        })?;
        let positions: Vec<Vec3> = read_vectors::<3>(data, pos_accessor)?
            .into_iter()
            .map(Vec3::from_array)
            .collect();
        if let Some(vertex) = positions.iter().position(|v| !v.is_finite()) {
            return Err(ImportError::NonFinitePosition {
                mesh: m,
                mesh_name,
                primitive: p,
                accessor: pos_accessor,
                vertex,
            });
        }
        let (list, index_accessor) = match prim.indices {
            Some(a) => (read_indices(data, a.value())?, Some(a.value())),
            None => ((0..positions.len() as u32).collect(), None),
        };
        if let Some(position) = list.iter().position(|&i| i as usize >= positions.len()) {
            return Err(ImportError::IndexOutOfRange {
                mesh: m,
                mesh_name,
                primitive: p,
                accessor: index_accessor.unwrap_or(pos_accessor),
                position,
                index: list[position],
                vertex_count: positions.len(),
            });
        }
        let indices = triangulate(mode, &list);
        let normals = match attribute(Semantic::Normals) {
            Some(a) => {
                let n: Vec<Vec3> = read_vectors::<3>(data, a)?
                    .into_iter()
                    .map(Vec3::from_array)
                    .collect();
                if n.len() != positions.len() {
                    return Err(invalid(format!(
                        "meshes[{m}].primitives[{p}]: NORMAL has {} elements, POSITION {}",
                        n.len(),
                        positions.len()
                    )));
                }
                n.iter().all(|v| v.is_finite()).then_some(n)
            }
            None => None,
        };
        let normals = normals.unwrap_or_else(|| {
            report.primitives_with_computed_normals += 1;
            compute_normals(&positions, &indices)
        });
        let material = match prim.material {
            Some(mat) if mat.value() < data.root.materials.len() => {
                MaterialId::from_index(mat.value())
            }
            Some(mat) => {
                return Err(invalid(format!(
                    "meshes[{m}].primitives[{p}].material {} does not exist",
                    mat.value()
                )));
            }
            None => default_material,
        };
        out.push_primitive(&positions, &normals, &indices, material);
    }
    Ok((chunk_mesh(&out, chunk_triangles), report))
}

/// Turns a strip or fan into a triangle list (glTF 2.0 spec 3.7.2.1 winding), and
/// drops the incomplete tail of a list.
fn triangulate(mode: Mode, list: &[u32]) -> Vec<u32> {
    match mode {
        Mode::TriangleStrip => (0..list.len().saturating_sub(2))
            .flat_map(|i| {
                let (a, b, c) = (list[i], list[i + 1], list[i + 2]);
                if i % 2 == 0 { [a, b, c] } else { [b, a, c] }
            })
            .collect(),
        Mode::TriangleFan => (1..list.len().saturating_sub(1))
            .flat_map(|i| [list[0], list[i], list[i + 1]])
            .collect(),
        _ => list[..list.len() - list.len() % 3].to_vec(),
    }
}
