//! Fuzz body of `gltf_import`: the bytes as a glTF file, imported in memory and
//! streamed from disk (as `model.gltf` when they start with `{`, else
//! `model.glb`). Errors are fine; a panic is a finding.

use dmu_scene::{
    ImportError, ImportOptions, StreamOptions, import_gltf_slice, import_gltf_streaming,
};

/// Runs both importers on `data`.
pub fn run(data: &[u8]) {
    let _ = import_gltf_slice(data, None, "fuzz", &ImportOptions::default());
    let dir = tempfile::tempdir().expect("temporary directory");
    let name = if data.first() == Some(&b'{') {
        "model.gltf"
    } else {
        "model.glb"
    };
    let path = dir.path().join(name);
    std::fs::write(&path, data).expect("temporary file");
    let options = StreamOptions {
        chunk_triangles: dmu_scene::DEFAULT_CHUNK_TRIANGLES,
        memory_budget_bytes: 0,
        min_batch_bytes: 1 << 20,
        progress: None,
    };
    let _ = import_gltf_streaming::<ImportError>(&path, &options, &mut |_, _| Ok(()));
}

/// The committed corpus replayed through [`run`], in the test suite of the
/// crate that includes this file (with `fuzz/replay.rs` as `fuzz_replay`).
#[cfg(test)]
#[test]
fn corpus_never_panics() {
    crate::fuzz_replay::corpus("gltf_import", run);
}
