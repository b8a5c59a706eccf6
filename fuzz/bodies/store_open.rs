//! Fuzz body of `store_open`: the bytes as a store file, every checksum in it
//! resealed ([`dmu_store::reseal`]), opened, every chunk's geometry and far
//! field read, then the whole scene loaded. Errors are fine; a panic is a
//! finding.
//!
//! Resealed, a mutated store reaches what the checksums guard: the table of
//! contents' checks, the skeleton decoder and its checks, the geometry
//! decoder. Unsealed, nearly every mutation failed the header's or the
//! table's checksum first. The checksum failures themselves are tested in
//! `crates/dmu-store/tests/files.rs` (every byte of a store flipped).

use dmu_scene::ChunkId;
use dmu_store::Store;

/// Opens `data`, its checksums resealed, as a store and reads everything in it.
pub fn run(data: &[u8]) {
    let mut data = data.to_vec();
    dmu_store::reseal(&mut data);
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("model.dmu");
    std::fs::write(&path, &data).expect("temporary file");
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

/// Writes the seed corpus's valid stores into `fuzz/corpus/store_open/` (each
/// a few KB): `cargo test -p dmu-store --test tests -- --ignored
/// write_store_seed_corpus`.
#[cfg(test)]
#[test]
#[ignore = "rewrites the committed seed corpus"]
fn write_store_seed_corpus() {
    use dmu_store::{StoreError, WriteOptions, write_far_fields, write_scene};

    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/store_open");
    let quantized = WriteOptions { quantize: true };
    // As `dmu generate grid --n 1` (and 2) writes them, and two broken copies.
    for n in [1, 2] {
        let grid = dmu_samples::grid(n, 10.0, 4.0, dmu_scene::DEFAULT_CHUNK_TRIANGLES);
        write_scene(
            &grid,
            &dir.join(format!("grid{n}.dmu")),
            WriteOptions::default(),
        )
        .unwrap();
    }
    let grid1 = std::fs::read(dir.join("grid1.dmu")).unwrap();
    let mut flipped = grid1.clone();
    flipped[grid1.len() - 100] ^= 0x10; // in the skeleton, before the table
    std::fs::write(dir.join("flipped_byte.dmu"), flipped).unwrap();
    std::fs::write(dir.join("truncated.dmu"), &grid1[..100]).unwrap();
    // Quantized geometry (the other decoder).
    write_scene(
        &dmu_samples::grid(1, 10.0, 4.0, 8),
        &dir.join("grid1_quantized.dmu"),
        quantized,
    )
    .unwrap();
    // Meshes of several chunks, one part hidden.
    let mut scene = dmu_samples::grid(2, 10.0, 4.0, 4);
    scene.set_part_hidden(dmu_scene::PartId(1), true);
    write_scene(
        &scene,
        &dir.join("grid2_chunks_hidden.dmu"),
        WriteOptions::default(),
    )
    .unwrap();
    // Far fields: an index and three cells.
    let far = dir.join("grid1_farfield.dmu");
    write_scene(
        &dmu_samples::grid(1, 10.0, 4.0, 8),
        &far,
        WriteOptions::default(),
    )
    .unwrap();
    let store = Store::open(&far).unwrap();
    let cells = (0..3u8).map(|c| Ok::<_, StoreError>(Some(vec![c; 40])));
    write_far_fields(&store, b"far-field index", cells)
        .unwrap()
        .commit()
        .unwrap();
    // A small plant: many parts, instanced meshes, far from the origin.
    let plant = dmu_samples::plant(&dmu_samples::PlantOptions {
        triangles: 2_000,
        ..dmu_samples::PlantOptions::default()
    });
    write_scene(&plant, &dir.join("plant_2k_quantized.dmu"), quantized).unwrap();
}
