//! Shared test helpers: small models, stores in temporary folders, and scene
//! comparison.

use std::path::PathBuf;

use dmu_samples::{PlantOptions, plant};
use dmu_scene::Scene;
use dmu_store::{WriteOptions, write_scene};

/// A small plant (about `triangles`), far from the origin as real plants are.
pub fn small_plant(triangles: u64) -> Scene {
    plant(&PlantOptions {
        triangles,
        ..PlantOptions::default()
    })
}

/// `scene` written as a store in a fresh temporary folder.
pub fn stored(scene: &Scene, options: WriteOptions) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.dmu");
    write_scene(scene, &path, options).unwrap();
    (dir, path)
}

/// A store of a 3x3x3 grid of boxes (27 parts, a chunk each, a few KB): its
/// folder, path and bytes.
pub fn small_store() -> (tempfile::TempDir, PathBuf, Vec<u8>) {
    let scene = dmu_samples::grid(3, 10.0, 4.0, 8);
    let (dir, path) = stored(&scene, WriteOptions::default());
    let bytes = std::fs::read(&path).unwrap();
    (dir, path, bytes)
}

/// Structure, names, transforms (exactly), colours, visibility and geometry agree.
pub fn assert_same_scene(a: &Scene, b: &Scene) {
    assert_eq!(a.parts().len(), b.parts().len(), "part count");
    assert_eq!(a.triangle_count(), b.triangle_count(), "triangles");
    for p in a.part_ids() {
        assert_eq!(a.part_path(p), b.part_path(p));
        assert_eq!(
            a.part_world(p),
            b.part_world(p),
            "transform of {}",
            a.part_name(p)
        );
        assert_eq!(a.part(p).hidden, b.part(p).hidden);
        assert_eq!(
            a.part_mesh(p).triangle_count(),
            b.part_mesh(p).triangle_count()
        );
    }
    assert_eq!(a.materials(), b.materials(), "materials and colours");
    assert_eq!(a.chunks(), b.chunks(), "chunk tables and boxes");
    assert_eq!(a.meshes(), b.meshes(), "geometry");
}

/// Segment kinds as the table of contents names them (`format.rs`).
pub const KIND_SKELETON: u32 = 1;
/// A chunk's geometry segment.
pub const KIND_CHUNK: u32 = 2;
/// A far-field index segment.
pub const KIND_FAR_INDEX: u32 = 3;
/// A far-field cell segment.
pub const KIND_FAR_CELL: u32 = 4;

/// One table-of-contents entry as the file holds it (`format.rs`'s `TocEntry`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Entry {
    pub id: u32,
    pub kind: u32,
    pub offset: u64,
    pub length: u64,
    pub checksum: u64,
}

impl Entry {
    /// Where its payload is in the file.
    pub fn payload(&self) -> std::ops::Range<usize> {
        self.offset as usize..(self.offset + self.length) as usize
    }

    /// Where its payload and padding are: what its checksum covers.
    pub fn padded(&self) -> std::ops::Range<usize> {
        self.offset as usize..(self.offset + self.length.next_multiple_of(16)) as usize
    }
}

fn word(bytes: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
}

/// The table of contents of `bytes` (a whole store), in file order.
pub fn toc(bytes: &[u8]) -> Vec<Entry> {
    let (at, entries) = (word(bytes, 24) as usize, word(bytes, 32) as usize);
    bytes[at..at + 32 * entries]
        .chunks_exact(32)
        .map(bytemuck::pod_read_unaligned)
        .collect()
}

/// The entry of the segment of `kind` and `id` in `bytes` (a whole store).
pub fn entry(bytes: &[u8], kind: u32, id: u32) -> Entry {
    toc(bytes)
        .into_iter()
        .find(|e| (e.kind, e.id) == (kind, id))
        .unwrap_or_else(|| panic!("no segment of kind {kind}, id {id}"))
}

/// `bytes` (a whole store) with its table of contents changed by `change` and
/// the checksums of the table and the header recomputed, so only the checks on
/// the entries themselves see it: a crafted file, not a damaged one.
pub fn with_toc(bytes: &[u8], change: impl FnOnce(&mut [Entry])) -> Vec<u8> {
    use xxhash_rust::xxh3::xxh3_64;
    let mut entries = toc(bytes);
    change(&mut entries);
    let table: &[u8] = bytemuck::cast_slice(&entries);
    let mut out = bytes.to_vec();
    let at = word(bytes, 24) as usize;
    out[at..at + table.len()].copy_from_slice(table);
    out[40..48].copy_from_slice(&xxh3_64(table).to_le_bytes());
    let sum = xxh3_64(&out[..56]);
    out[56..64].copy_from_slice(&sum.to_le_bytes());
    out
}
