//! Chunk levels of detail in the store (format version 4): written at import
//! as `lod_levels` makes them, within their claimed error of the full chunk,
//! refused with a one-line error when damaged; version-3 stores, which have
//! none, still read and gain them when rewritten.

use std::path::{Path, PathBuf};

use dmu_geom::closest_point_on_triangle;
use dmu_scene::{ChunkId, LodLevel, lod_levels};
use dmu_store::{OwnedChunkGeometry, Store, StoreError, WriteOptions, reseal, save_edits};
use glam::{DVec3, Vec3};

use crate::support::{KIND_CHUNK, assert_same_scene, entry, small_plant, stored};

/// Every chunk of `store`, decoded.
fn decoded(store: &Store) -> Vec<OwnedChunkGeometry> {
    (0..store.skeleton().chunks().len())
        .map(|c| store.chunk_geometry(ChunkId::from_index(c)).unwrap())
        .collect()
}

/// What `lod_levels` makes of a decoded chunk's own geometry.
fn computed(g: &OwnedChunkGeometry) -> Vec<LodLevel> {
    let mut g = g.geometry();
    g.levels = None;
    lod_levels(&g)
}

/// The largest distance from any of `points` to the surface of `indices`
/// over `positions`, by brute force over every triangle.
fn farthest(points: &[DVec3], positions: &[Vec3], indices: &[u32]) -> f64 {
    let triangles: Vec<[DVec3; 3]> = indices
        .chunks_exact(3)
        .map(|t| [0, 1, 2].map(|k| positions[t[k] as usize].as_dvec3()))
        .collect();
    points
        .iter()
        .map(|&p| {
            triangles
                .iter()
                .map(|&t| closest_point_on_triangle(p, t).distance_squared(p))
                .fold(f64::INFINITY, f64::min)
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// Points on the surface of `indices`: each triangle's corners, edge
/// midpoints and centroid.
fn surface_samples(positions: &[Vec3], indices: &[u32]) -> Vec<DVec3> {
    indices
        .chunks_exact(3)
        .flat_map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize].as_dvec3());
            [
                a,
                b,
                c,
                (a + b) / 2.0,
                (b + c) / 2.0,
                (c + a) / 2.0,
                (a + b + c) / 3.0,
            ]
        })
        .collect()
}

/// The two-sided distance between a chunk's surface and its level's, sampled
/// on both: from every full-mesh vertex to the level, and from points of the
/// level's triangles back to the full mesh.
fn level_distance(g: &OwnedChunkGeometry, level: &LodLevel) -> f64 {
    let vertices: Vec<DVec3> = g.positions.iter().map(|p| p.as_dvec3()).collect();
    let out = farthest(&vertices, &g.positions, &level.indices);
    let back = farthest(
        &surface_samples(&g.positions, &level.indices),
        &g.positions,
        &g.indices,
    );
    out.max(back)
}

#[test]
fn stored_levels_are_lod_levels_within_their_error() {
    let scene = small_plant(30_000);
    let (_dir, path) = stored(&scene, WriteOptions::default());
    let store = Store::open(&path).unwrap();
    assert_eq!(store.info().version, 4);
    let chunks = decoded(&store);
    let mut with_levels = 0;
    for (c, g) in chunks.iter().enumerate() {
        let levels = g.levels.as_ref().expect("a version-4 chunk has its levels");
        assert_eq!(*levels, computed(g), "chunk {c}");
        with_levels += usize::from(!levels.is_empty());
    }
    assert!(
        with_levels * 4 >= chunks.len(),
        "{with_levels} of {}",
        chunks.len()
    );
    // The error bound, on every chunk with levels, by brute force.
    let mut checked = 0;
    for (c, g) in chunks.iter().enumerate() {
        for (k, level) in g.levels.iter().flatten().enumerate() {
            let distance = level_distance(g, level);
            assert!(
                distance <= f64::from(level.error),
                "chunk {c} level {k}: {distance} from the full chunk, claims {}",
                level.error
            );
            checked += 1;
        }
    }
    assert!(checked >= 12, "{checked} levels checked");
}

/// A version-4 store of a small plant, a chunk of it with levels and the
/// byte range of that chunk's segment.
fn a_chunk_with_levels() -> (tempfile::TempDir, PathBuf, ChunkId, OwnedChunkGeometry) {
    let (dir, path) = stored(&small_plant(10_000), WriteOptions::default());
    let store = Store::open(&path).unwrap();
    let (c, g) = decoded(&store)
        .into_iter()
        .enumerate()
        .find(|(_, g)| g.levels.as_ref().is_some_and(|l| l.len() >= 2))
        .expect("a chunk with two levels");
    (dir, path, ChunkId::from_index(c), g)
}

/// The error reading `chunk` after `damage` changed its segment (the
/// checksums recomputed: a crafted file, which only the decoder can refuse).
fn read_damaged(path: &Path, chunk: ChunkId, damage: impl FnOnce(&mut [u8])) -> StoreError {
    let mut bytes = std::fs::read(path).unwrap();
    let segment = entry(&bytes, KIND_CHUNK, chunk.0).payload();
    damage(&mut bytes[segment]);
    reseal(&mut bytes);
    let damaged = path.with_file_name("damaged.dmu");
    std::fs::write(&damaged, &bytes).unwrap();
    Store::open(&damaged)
        .unwrap()
        .chunk_geometry(chunk)
        .unwrap_err()
}

/// A change to a chunk's segment.
type Damage = Box<dyn FnOnce(&mut [u8])>;

#[test]
fn damaged_levels_are_one_line_errors_naming_the_chunk() {
    let (_dir, path, chunk, g) = a_chunk_with_levels();
    let levels = g.levels.as_ref().unwrap();
    // Unquantized, u16 indices: the level table follows the chunk's indices.
    assert!(g.positions.len() <= 1 << 16);
    let table = 16 + 24 * g.positions.len() + 2 * g.indices.len();
    let vertices = g.positions.len() as u16;
    let last = format!("level {}: index {vertices} >= {vertices}", levels.len() - 1);
    let cases: [(&str, Damage); 5] = [
        (
            &last,
            Box::new(move |b: &mut [u8]| {
                let last = b.len() - 2;
                b[last..].copy_from_slice(&vertices.to_le_bytes());
            }),
        ),
        (
            "bytes where its counts make",
            Box::new(move |b: &mut [u8]| set_word(b, table, levels_len(b, table) + 3)),
        ),
        (
            "not whole triangles",
            Box::new(move |b: &mut [u8]| {
                // One index moved from level 0 to level 1: the length holds.
                let (first, second) = (levels_len(b, table), levels_len(b, table + 8));
                set_word(b, table, first - 1);
                set_word(b, table + 8, second + 1);
            }),
        ),
        (
            "claims error",
            Box::new(move |b: &mut [u8]| set_word(b, table + 12, f32::NAN.to_bits())),
        ),
        (
            "8 levels, more than 7",
            Box::new(|b: &mut [u8]| set_word(b, 12, 8)),
        ),
    ];
    for (what, damage) in cases {
        let msg = read_damaged(&path, chunk, damage).to_string();
        assert!(msg.contains(&format!("chunk {chunk}")), "{msg}");
        assert!(msg.contains(what), "{what}: {msg}");
        assert_eq!(msg.lines().count(), 1, "{msg}");
    }
}

/// The index count of the level whose table entry is at `at`.
fn levels_len(segment: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(segment[at..at + 4].try_into().unwrap())
}

/// Writes the little-endian word `v` at `at`.
fn set_word(segment: &mut [u8], at: usize, v: u32) {
    segment[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// A version-3 store, written by the build before format 4 (7f1c359):
/// `dmu generate plant --triangles 10k -o plant10k_version3.dmu`.
pub fn version_3_store() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/plant10k_version3.dmu")
}

#[test]
fn a_version_3_store_reads_without_levels_and_gains_them_when_rewritten() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.dmu");
    std::fs::copy(version_3_store(), &path).unwrap();
    let store = Store::open(&path).unwrap();
    assert_eq!(store.info().version, 3);
    let old = decoded(&store);
    assert!(old.iter().all(|g| g.levels.is_none()));
    // The same plant as the generator makes today, geometry and all.
    assert_same_scene(&store.load_scene().unwrap(), &small_plant(10_000));
    // Its budget counts no levels: it holds none.
    let old_budget = store.info().geometry_resident_bytes;
    let expected: u64 = old.iter().map(OwnedChunkGeometry::resident_bytes).sum();
    assert_eq!(old_budget, expected);

    save_edits(&store, store.skeleton()).unwrap();
    let store = Store::open(&path).unwrap();
    assert_eq!(store.info().version, 4);
    let new = decoded(&store);
    let mut with_levels = 0;
    for (c, (old, new)) in old.iter().zip(&new).enumerate() {
        assert_eq!(
            (&old.positions, &old.normals, &old.indices),
            (&new.positions, &new.normals, &new.indices),
            "chunk {c}"
        );
        let levels = new.levels.as_ref().expect("a rewritten chunk has levels");
        assert_eq!(*levels, computed(old), "chunk {c}");
        with_levels += usize::from(!levels.is_empty());
    }
    assert!(with_levels > 0);
    assert!(store.info().geometry_resident_bytes > old_budget);
}
