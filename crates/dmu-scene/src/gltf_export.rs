//! glTF 2.0 export of a scene with its current transforms, so an edited assembly
//! goes back to other tools. Instancing is kept (parts sharing a mesh share a glTF
//! mesh); each run of chunks with one material becomes a primitive; node
//! transforms are written as f64 matrices local to the parent node, recomputed
//! from the absolute world transforms dmu stores.

use std::path::Path;

use base64::Engine as _;
use glam::{DAffine3, DMat4, Vec3};
use serde_json::{Value, json};

use crate::NodeId;
use crate::error::ExportError;
use crate::scene::Scene;

/// Writes `scene` to `path`: binary glTF for `.glb`, JSON with an embedded
/// base64 buffer otherwise. Written to a temporary file then renamed, so a
/// failed export leaves any previous file untouched.
///
/// # Panics
/// When a mesh's geometry is not loaded (a store's skeleton): load it first.
pub fn export_gltf(scene: &Scene, path: &Path) -> Result<(), ExportError> {
    assert!(
        scene.meshes().iter().all(crate::Mesh::is_loaded),
        "export_gltf needs the geometry loaded"
    );
    let binary = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    let (mut doc, bin) = build(scene);
    let io = |source| ExportError::Io {
        path: path.to_owned(),
        source,
    };
    let bytes = if binary {
        if bin.len() as u64 + (1 << 20) > u64::from(u32::MAX) {
            return Err(ExportError::TooLarge {
                format: "glb",
                bytes: bin.len() as u64,
            });
        }
        doc["buffers"] = json!([{ "byteLength": bin.len() }]);
        glb(&serde_json::to_vec(&doc).map_err(|e| io(e.into()))?, &bin)
    } else {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        );
        doc["buffers"] = json!([{ "byteLength": bin.len(), "uri": uri }]);
        serde_json::to_vec(&doc).map_err(|e| io(e.into()))?
    };
    crate::atomic::write_file_atomically(path, &bytes).map_err(io)
}

fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let json_len = json.len().next_multiple_of(4);
    let bin_len = bin.len().next_multiple_of(4);
    let total = 12 + 8 + json_len + if bin.is_empty() { 0 } else { 8 + bin_len };
    let mut out = Vec::with_capacity(total);
    let word = |out: &mut Vec<u8>, w: usize| out.extend_from_slice(&(w as u32).to_le_bytes());
    out.extend_from_slice(b"glTF");
    word(&mut out, 2);
    word(&mut out, total);
    word(&mut out, json_len);
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(json);
    out.resize(20 + json_len, b' ');
    if !bin.is_empty() {
        word(&mut out, bin_len);
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
        out.resize(total, 0);
    }
    out
}

/// The binary buffer with its buffer views and accessors as they are written.
#[derive(Default)]
struct Writer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Writer {
    const ARRAY_BUFFER: u32 = 34962;
    const ELEMENT_ARRAY_BUFFER: u32 = 34963;

    /// Appends `bytes`, 4-byte aligned, as one buffer view, and an accessor over it.
    fn accessor(&mut self, bytes: &[u8], target: u32, mut accessor: Value) -> usize {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target }));
        self.bin.extend_from_slice(bytes);
        accessor["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn vec3(&mut self, data: &[Vec3], with_bounds: bool) -> usize {
        let mut a = json!({ "componentType": 5126, "count": data.len(), "type": "VEC3" });
        if with_bounds {
            let b = dmu_geom::Aabb3f::from_points(data.iter().copied());
            a["min"] = json!(b.min.to_array());
            a["max"] = json!(b.max.to_array());
        }
        self.accessor(bytemuck::cast_slice(data), Self::ARRAY_BUFFER, a)
    }

    fn indices(&mut self, data: &[u32]) -> usize {
        let a = json!({ "componentType": 5125, "count": data.len(), "type": "SCALAR" });
        self.accessor(bytemuck::cast_slice(data), Self::ELEMENT_ARRAY_BUFFER, a)
    }
}

fn build(scene: &Scene) -> (Value, Vec<u8>) {
    let mut w = Writer::default();
    let meshes: Vec<Value> = scene
        .meshes()
        .iter()
        .map(|mesh| {
            let chunks: Vec<_> = mesh.chunk_ids().map(|c| scene.chunk(c)).collect();
            let mut primitives = Vec::new();
            // A primitive per run of consecutive chunks sharing a material.
            for run in chunks.chunk_by(|a, b| a.material == b.material) {
                let verts =
                    run[0].vertices.start as usize..run[run.len() - 1].vertices.end as usize;
                let indices: Vec<u32> = run
                    .iter()
                    .flat_map(|c| {
                        let rebase = c.vertices.start - verts.start as u32;
                        let idx = &mesh.indices
                            [3 * c.triangles.start as usize..3 * c.triangles.end as usize];
                        idx.iter().map(move |&i| i + rebase)
                    })
                    .collect();
                let position = w.vec3(&mesh.positions[verts.clone()], true);
                let normal = w.vec3(&mesh.normals[verts], false);
                primitives.push(json!({
                    "attributes": { "POSITION": position, "NORMAL": normal },
                    "indices": w.indices(&indices),
                    "material": run[0].material.0,
                }));
            }
            json!({ "name": mesh.name, "primitives": primitives })
        })
        .collect();

    let materials: Vec<Value> = scene
        .materials()
        .iter()
        .map(|m| json!({ "name": m.name, "pbrMetallicRoughness": { "baseColorFactor": m.base_color } }))
        .collect();

    // Node i of the scene (i >= 1) is glTF node i - 1; the root becomes the glTF scene.
    let nodes: Vec<Value> = scene
        .nodes()
        .iter()
        .enumerate()
        .skip(1)
        .map(|(i, node)| {
            let id = NodeId(i as u32);
            let parent_world = node
                .parent
                .map_or(DAffine3::IDENTITY, |p| scene.node(p).world);
            let local = parent_world.inverse() * node.world;
            let mut n = json!({ "name": scene.node_name(id) });
            if local != DAffine3::IDENTITY {
                n["matrix"] = json!(DMat4::from(local).to_cols_array());
            }
            let children: Vec<usize> = scene.children(id).map(|c| c.index() - 1).collect();
            if !children.is_empty() {
                n["children"] = json!(children);
            }
            if let Some(part) = node.part {
                n["mesh"] = json!(scene.part(part).mesh.0);
            }
            let properties: serde_json::Map<String, serde_json::Value> = scene
                .node_properties(id)
                .map(|(k, v)| (k.to_owned(), json!(v)))
                .collect();
            if !properties.is_empty() {
                n["extras"] = serde_json::Value::Object(properties);
            }
            n
        })
        .collect();
    let roots: Vec<usize> = scene.children(NodeId(0)).map(|c| c.index() - 1).collect();

    let doc = json!({
        "asset": { "version": "2.0", "generator": concat!("dmu ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "name": scene.name(), "nodes": roots }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": w.accessors,
        "bufferViews": w.views,
    });
    (doc, w.bin)
}
