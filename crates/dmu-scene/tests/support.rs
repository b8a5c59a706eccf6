//! Test support: a minimal glTF writer independent of dmu's exporter (the
//! shared real-world models are found by `dmu_testkit::Data`).

use base64::Engine as _;
use dmu_scene::{ImportError, ImportOptions, ImportReport, Scene, import_gltf_slice};
use serde_json::{Value, json};

/// A glTF document built by hand, one buffer embedded as a data URI.
pub struct Doc {
    pub json: Value,
    pub bin: Vec<u8>,
}

impl Doc {
    pub fn new() -> Self {
        Self {
            json: json!({ "asset": { "version": "2.0" }, "accessors": [], "bufferViews": [], "meshes": [], "nodes": [], "scenes": [{ "nodes": [] }], "scene": 0 }),
            bin: Vec::new(),
        }
    }

    fn push(&mut self, key: &str, v: Value) -> usize {
        let a = self.json[key].as_array_mut().expect("array");
        a.push(v);
        a.len() - 1
    }

    /// Adds raw bytes as a buffer view; returns its index.
    pub fn view(&mut self, bytes: &[u8], stride: Option<usize>) -> usize {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut v = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        self.bin.extend_from_slice(bytes);
        self.push("bufferViews", v)
    }

    /// Adds an accessor over a fresh buffer view.
    pub fn accessor(
        &mut self,
        bytes: &[u8],
        component_type: u32,
        count: usize,
        ty: &str,
        extra: Value,
    ) -> usize {
        let view = self.view(bytes, None);
        let mut a = json!({ "bufferView": view, "componentType": component_type, "count": count, "type": ty });
        if let Value::Object(m) = extra {
            for (k, v) in m {
                a[k] = v;
            }
        }
        self.push("accessors", a)
    }

    pub fn positions(&mut self, p: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = p.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        self.accessor(&bytes, 5126, p.len(), "VEC3", json!({}))
    }

    pub fn indices(&mut self, i: &[u32]) -> usize {
        let bytes: Vec<u8> = i.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.accessor(&bytes, 5125, i.len(), "SCALAR", json!({}))
    }

    /// Adds a mesh of the given primitives (JSON objects).
    pub fn mesh(&mut self, name: &str, primitives: Vec<Value>) -> usize {
        self.push("meshes", json!({ "name": name, "primitives": primitives }))
    }

    /// Adds a node (JSON object) and makes it a scene root when `root`.
    pub fn node(&mut self, node: Value, root: bool) -> usize {
        let n = self.push("nodes", node);
        if root {
            self.json["scenes"][0]["nodes"]
                .as_array_mut()
                .expect("array")
                .push(json!(n));
        }
        n
    }

    /// The document as .gltf bytes with the buffer embedded.
    pub fn bytes(&self) -> Vec<u8> {
        let mut j = self.json.clone();
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.bin)
        );
        j["buffers"] = json!([{ "byteLength": self.bin.len(), "uri": uri }]);
        serde_json::to_vec(&j).expect("json")
    }

    /// The document as .glb bytes.
    pub fn glb(&self) -> Vec<u8> {
        let mut j = self.json.clone();
        j["buffers"] = json!([{ "byteLength": self.bin.len() }]);
        let mut json = serde_json::to_vec(&j).expect("json");
        json.resize(json.len().next_multiple_of(4), b' ');
        let mut bin = self.bin.clone();
        bin.resize(bin.len().next_multiple_of(4), 0);
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::new();
        for w in [
            0x4654_6C67u32,
            2,
            total as u32,
            json.len() as u32,
            0x4E4F_534A,
        ] {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out.extend_from_slice(&json);
        for w in [bin.len() as u32, 0x004E_4942] {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out.extend_from_slice(&bin);
        out
    }

    pub fn import(&self) -> Result<(Scene, ImportReport), ImportError> {
        import_gltf_slice(&self.bytes(), None, "test", &ImportOptions::default())
    }
}

/// A unit square in the z = 0 plane as one triangle-list primitive on a node.
pub fn one_quad_doc() -> Doc {
    let mut d = Doc::new();
    let pos = d.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ]);
    let idx = d.indices(&[0, 1, 2, 0, 2, 3]);
    let mesh = d.mesh(
        "quad",
        vec![json!({ "attributes": { "POSITION": pos }, "indices": idx })],
    );
    d.node(json!({ "name": "quad", "mesh": mesh }), true);
    d
}
