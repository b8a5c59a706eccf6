//! Fuzz body of `store_open`: the bytes as a store file, opened, every chunk's
//! geometry and far field read, then the whole scene loaded. Errors are fine; a panic is a
//! finding.

use dmu_scene::ChunkId;
use dmu_store::Store;

/// Opens `data` as a store and reads everything in it.
pub fn run(data: &[u8]) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("model.dmu");
    std::fs::write(&path, data).expect("temporary file");
    let Ok(store) = Store::open(&path) else {
        return;
    };
    let _ = store.info();
    for c in 0..store.skeleton().chunks().len() {
        let _ = store.chunk_geometry(ChunkId::from_index(c));
    }
    let _ = store.far_field_index();
    for c in 0..store.far_field_cells() {
        let _ = store.far_field_cell(c as u32);
    }
    let _ = store.load_scene();
}

/// The committed corpus replayed through [`run`], in the test suite of the
/// crate that includes this file (with `fuzz/replay.rs` as `fuzz_replay`).
#[cfg(test)]
#[test]
fn corpus_never_panics() {
    crate::fuzz_replay::corpus("store_open", run);
}
