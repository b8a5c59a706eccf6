//! Damaged, foreign and interrupted files: each gives an error naming the file
//! and what is wrong, never a panic, and an interrupted save leaves the previous
//! file readable.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use dmu_store::{
    FORMAT_VERSION, OLDEST_READABLE_VERSION, Store, StoreError, WriteOptions, save_edits,
};
use glam::{DAffine3, DVec3};

use crate::support::{KIND_SKELETON, entry, small_plant, small_store, stored, with_toc};

/// Opens and reads every chunk: the error, if any.
fn read_all(path: &Path) -> Result<(), StoreError> {
    let store = Store::open(path)?;
    store.load_scene().map(|_| ())
}

#[test]
fn every_truncation_is_an_error() {
    let (_dir, path, bytes) = small_store();
    read_all(&path).unwrap();
    for len in 0..bytes.len() {
        std::fs::write(&path, &bytes[..len]).unwrap();
        let err = read_all(&path).expect_err(&format!("truncated to {len} bytes"));
        let msg = err.to_string();
        assert!(msg.contains("model.dmu"), "{msg}");
        if (8..64).contains(&len) {
            assert!(matches!(err, StoreError::Truncated { .. }), "{len}: {msg}");
        }
    }
    // The common case, an interrupted copy: named as truncation.
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let msg = read_all(&path).unwrap_err().to_string();
    assert!(msg.contains("truncated"), "{msg}");
}

/// A store cut short or rewritten on disk while it is open (another process
/// copying over it): every chunk read after that is either the chunk as it
/// was or an error naming the file and the chunk, never a panic or a
/// signal (the file is read with `pread`, not mapped, so there is no SIGBUS).
#[test]
fn a_store_changed_on_disk_while_open_gives_errors_not_crashes() {
    let (_dir, path, bytes) = small_store();
    let chunks = Store::open(&path).unwrap().info().chunks as u32;
    let original: Vec<_> = {
        let store = Store::open(&path).unwrap();
        (0..chunks)
            .map(|c| store.chunk_geometry(dmu_scene::ChunkId(c)).unwrap())
            .collect()
    };
    // Cut at the header (no chunk left), in the middle, just before the end
    // (chunks in the part kept still read); and rewritten in place with
    // other bytes of the same length (no chunk left).
    let mut flipped = bytes.clone();
    for b in flipped.iter_mut().skip(64) {
        *b ^= 0xa5;
    }
    let changes: [(Vec<u8>, bool); 4] = [
        (bytes[..64].to_vec(), true),
        (bytes[..bytes.len() / 2].to_vec(), false),
        (bytes[..bytes.len() - 1].to_vec(), false),
        (flipped, true),
    ];
    for (k, (changed, none_left)) in changes.iter().enumerate() {
        std::fs::write(&path, &bytes).unwrap();
        let store = Store::open(&path).unwrap();
        // Rewritten through a new handle, as another process would.
        std::fs::write(&path, changed).unwrap();
        let mut failed = 0;
        for c in 0..chunks {
            match store.chunk_geometry(dmu_scene::ChunkId(c)) {
                Ok(g) => assert_eq!(g, original[c as usize], "change {k}, chunk {c}"),
                Err(e) => {
                    let msg = e.to_string();
                    assert!(msg.contains("model.dmu"), "change {k}, chunk {c}: {msg}");
                    assert!(msg.contains("chunk"), "change {k}, chunk {c}: {msg}");
                    failed += 1;
                }
            }
        }
        if *none_left {
            assert_eq!(
                failed, chunks,
                "change {k}: a chunk read from changed bytes"
            );
        }
    }
}

/// Every byte is covered by a checksum: any single flipped byte is caught,
/// at open or when its chunk is first read.
#[test]
fn every_flipped_byte_is_an_error() {
    let (_dir, path, bytes) = small_store();
    for at in 0..bytes.len() {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0x5a;
        std::fs::write(&path, &damaged).unwrap();
        let err = read_all(&path).expect_err(&format!("byte {at} flipped"));
        assert!(err.to_string().contains("model.dmu"), "{err}");
    }
}

#[test]
fn a_flipped_geometry_byte_names_its_chunk_when_touched() {
    let (_dir, path, mut bytes) = small_store();
    // The first segment after the 64-byte header is chunk 0's geometry.
    bytes[64 + 5] ^= 1;
    std::fs::write(&path, &bytes).unwrap();
    // The skeleton is intact: the store opens, and only chunk 0 fails.
    let store = Store::open(&path).unwrap();
    let err = store.chunk_geometry(dmu_scene::ChunkId(0)).unwrap_err();
    assert!(matches!(err, StoreError::Checksum { .. }), "{err}");
    assert!(err.to_string().contains("chunk"), "{err}");
    store.chunk_geometry(dmu_scene::ChunkId(1)).unwrap();
}

/// A store of format version 1 (bincode skeleton; `dmu generate grid --n 1`
/// before issue 14) is refused by version with a request to re-import, never
/// read as the flat arrays of later versions.
#[test]
fn a_version_1_store_asks_to_be_reimported() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/grid1_version1.dmu");
    let err = Store::open(&path).unwrap_err();
    assert!(
        matches!(
            err,
            StoreError::UnsupportedVersion {
                found: 1,
                supported: FORMAT_VERSION,
                ..
            }
        ),
        "{err}"
    );
    let msg = err.to_string();
    assert!(msg.contains("grid1_version1.dmu"), "{msg}");
    assert!(msg.contains("re-import"), "{msg}");
    assert_eq!(msg.lines().count(), 1, "{msg}");
}

#[test]
fn other_versions_and_other_files_are_named() {
    let (dir, path, bytes) = small_store();
    // The version before the oldest read (version 2: no solid flag in the
    // mesh records) and the next: refused by version.
    for version in [OLDEST_READABLE_VERSION - 1, FORMAT_VERSION + 1] {
        let mut other = bytes.clone();
        other[8..12].copy_from_slice(&version.to_le_bytes());
        std::fs::write(&path, &other).unwrap();
        let err = Store::open(&path).unwrap_err();
        assert!(
            matches!(err, StoreError::UnsupportedVersion { found, .. } if found == version),
            "{err}"
        );
        let msg = err.to_string();
        assert!(msg.contains(&format!("version {version}")), "{msg}");
        assert!(msg.contains("re-import"), "{msg}");
    }
    // Big-endian byte order mark.
    let mut be = bytes.clone();
    be[12..16].copy_from_slice(&0x0102_0304u32.to_be_bytes());
    std::fs::write(&path, &be).unwrap();
    assert!(matches!(
        Store::open(&path).unwrap_err(),
        StoreError::ByteOrder { .. }
    ));
    // A glTF file given as a store.
    let glb = dir.path().join("grid.glb");
    dmu_scene::export_gltf(&dmu_samples::grid(2, 10.0, 4.0, 8), &glb).unwrap();
    let msg = Store::open(&glb).unwrap_err().to_string();
    assert!(
        msg.contains("not a dmu store") && msg.contains("dmu import"),
        "{msg}"
    );
    let msg = Store::open(&dir.path().join("absent.dmu"))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("absent.dmu"), "{msg}");
}

/// A table of contents whose checksums hold but whose lengths or offsets lie
/// is refused naming the segment, never overflowing: a length that overflows
/// when padded to 16 bytes (debug builds panicked in `padded_len`; seen while
/// writing `dmu_store::reseal`, whose fuzz target now reaches it), one that
/// overflows with its offset, one past the table.
#[test]
fn crafted_table_lengths_are_refused() {
    let (_dir, path, bytes) = small_store();
    for length in [u64::MAX - 2, u64::MAX - 64, 1 << 40] {
        let crafted = with_toc(&bytes, |toc| toc[0].length = length);
        std::fs::write(&path, crafted).unwrap();
        let err = Store::open(&path).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, StoreError::Corrupt { .. }), "{msg}");
        assert!(msg.contains("runs into the table of contents"), "{msg}");
    }
}

/// A save that fails (here: dropped before its rename) leaves the previous
/// file as it was and no temporary file behind.
#[test]
fn an_abandoned_save_changes_nothing() {
    let (dir, path) = stored(&small_plant(20_000), WriteOptions::default());
    let before = std::fs::read(&path).unwrap();
    let store = Store::open(&path).unwrap();
    let mut edited = store.skeleton().clone();
    let p = edited.part_ids().next().unwrap();
    edited.set_part_world(p, DAffine3::from_translation(DVec3::splat(1.0)));
    let pending = dmu_store::prepare_save(&store, &edited).unwrap();
    assert!(pending.temp_path().exists());
    drop(pending);
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "temporary file left"
    );
}

const CHILD_ENV: &str = "DMU_STORE_SAVE_LOOP";

/// The child of [`killing_a_save_leaves_a_readable_file`]: saves the store at
/// `$DMU_STORE_SAVE_LOOP` over and over, each time with part 0 moved one more
/// millimetre along x, until killed.
#[test]
#[ignore = "run by killing_a_save_leaves_a_readable_file as a child process"]
fn save_loop_child() {
    let path = std::path::PathBuf::from(std::env::var_os(CHILD_ENV).expect("run as a child"));
    for i in 1.. {
        let store = Store::open(&path).unwrap();
        let mut scene = store.skeleton().clone();
        let p = dmu_scene::PartId(0);
        let world = DAffine3::from_translation(DVec3::X) * scene.part_world(p);
        scene.set_part_world(p, world);
        save_edits(&store, &scene).unwrap();
        if i == 1 {
            // Tell the parent that saving is under way.
            println!("saving");
        }
    }
}

/// Kills a process that saves in a loop at random moments (mid-write, between
/// write and rename, after): the store always opens, reads whole, and part 0
/// has moved a whole number of millimetres, i.e. it is one complete save.
#[test]
fn killing_a_save_leaves_a_readable_file() {
    let scene = small_plant(100_000);
    let (_dir, path) = stored(&scene, WriteOptions::default());
    let x0 = scene.part_world(dmu_scene::PartId(0)).translation.x;
    let exe = std::env::current_exe().unwrap();
    let mut rng = 0x9e37_79b9_7f4a_7c15u64;
    let mut moves = Vec::new();
    for round in 0..8 {
        let mut child = Command::new(&exe)
            .args([
                "--ignored",
                "--exact",
                "files::save_loop_child",
                "--nocapture",
            ])
            .env(CHILD_ENV, &path)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Wait for the first save, then a pseudo-random 0-40 ms more.
        let mut out = child.stdout.take().unwrap();
        let mut seen = Vec::new();
        while !String::from_utf8_lossy(&seen).contains("saving") {
            let mut buf = [0u8; 256];
            let n = std::io::Read::read(&mut out, &mut buf).unwrap();
            assert!(n > 0, "round {round}: the child ended before saving");
            seen.extend_from_slice(&buf[..n]);
        }
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        std::thread::sleep(Duration::from_micros(rng % 40_000));
        child.kill().unwrap(); // SIGKILL: no destructor runs.
        let status = child.wait().unwrap();
        assert!(!status.success(), "round {round}: the child was not killed");
        let store = Store::open(&path).unwrap_or_else(|e| panic!("round {round}: {e}"));
        let loaded = store
            .load_scene()
            .unwrap_or_else(|e| panic!("round {round}: {e}"));
        let moved = loaded.part_world(dmu_scene::PartId(0)).translation.x - x0;
        assert!(
            moved >= 1.0 && (moved - moved.round()).abs() < 1e-6,
            "round {round}: part 0 moved {moved}"
        );
        assert_eq!(loaded.meshes(), scene.meshes(), "round {round}: geometry");
        moves.push(moved);
    }
    eprintln!("killed saves left part 0 moved by {moves:?} mm");
    // The killed writers' temporary files go with the next save.
    let store = Store::open(&path).unwrap();
    save_edits(&store, store.skeleton()).unwrap();
    let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["model.dmu"], "leftovers after a save");
}

/// Another process truncating or rewriting a store in place while it is open
/// (the store was memory-mapped, and this ended the reader with `SIGBUS`): every
/// read after it is an error naming the file and the segment, or the same
/// geometry, never a signal.
#[test]
fn issue_20_a_store_changed_while_open_gives_errors_not_signals() {
    let (_dir, path, bytes) = small_store();
    let store = Store::open(&path).unwrap();
    let whole = store.load_scene().unwrap();
    let chunks = whole.chunks().len();
    // Truncated in place (the same inode, as `truncate -s` does) into the first
    // geometry segment: the segments follow the 64-byte header.
    let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    file.set_len(80).unwrap();
    let mut truncated = 0;
    for c in 0..chunks {
        let id = dmu_scene::ChunkId::from_index(c);
        match store.chunk_geometry(id) {
            Ok(g) => assert_eq!(g.positions.len(), whole.chunk(id).vertices.len()),
            Err(e @ StoreError::Truncated { .. }) => {
                let msg = e.to_string();
                assert!(msg.contains("model.dmu") && msg.contains("chunk"), "{msg}");
                truncated += 1;
            }
            Err(e) => panic!("chunk {c}: {e}"),
        }
    }
    assert_eq!(truncated, chunks, "every segment is past the end now");
    // Rewritten in place with other bytes: checksums catch it.
    let mut flipped = bytes.clone();
    for b in &mut flipped[64..bytes.len() - 64] {
        *b ^= 0x5a;
    }
    std::fs::write(&path, &flipped).unwrap();
    let err = store.load_scene().expect_err("every segment changed");
    assert!(matches!(err, StoreError::Checksum { .. }), "{err}");
}

/// `bytes` (a whole store) with its skeleton segment changed by `change` and
/// every checksum above it recomputed, so only the skeleton's own checks see it.
fn with_skeleton(bytes: &[u8], change: impl FnOnce(&mut [u8])) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let skeleton = entry(&out, KIND_SKELETON, 0);
    change(&mut out[skeleton.payload()]);
    let sum = xxhash_rust::xxh3::xxh3_64(&out[skeleton.padded()]);
    with_toc(&out, |toc| {
        for e in toc.iter_mut().filter(|e| e.kind == KIND_SKELETON) {
            e.checksum = sum;
        }
    })
}

/// A skeleton whose checksums hold but whose counts or contents lie (crafted,
/// not damaged) is refused naming what is wrong: counts that do not make its
/// length (so no count can make the reader allocate more than the file holds),
/// a parent after its child, a name past its table, a part beyond the world's
/// range.
#[test]
fn a_crafted_skeleton_is_refused_by_its_own_checks() {
    let (_dir, path, bytes) = small_store();
    let node = |i: usize| 64 + 104 * i;
    // The first mesh record, past the nodes, their names and the parts
    // (each array at a 16-byte boundary): chunks, degenerate triangles,
    // solid (u32 each).
    let first_mesh = |s: &[u8]| {
        let count = |k: usize| u64::from_le_bytes(s[8 * k..8 * k + 8].try_into().unwrap()) as usize;
        [104 * count(0), 8 * count(0), count(1), 12 * count(2)]
            .iter()
            .fold(64, |at, bytes| (at + bytes).next_multiple_of(16))
    };
    type Change = Box<dyn Fn(&mut [u8])>;
    let cases: [(&str, Change); 6] = [
        ("do not make its", Box::new(|s| s[0] += 1)),
        (
            "do not make its",
            Box::new(|s| s[16..24].copy_from_slice(&u64::MAX.to_le_bytes())),
        ),
        (
            "node 1: parent 7 is not stored before it",
            Box::new(move |s| s[node(1)..node(1) + 4].copy_from_slice(&7u32.to_le_bytes())),
        ),
        (
            "mesh 0: solid flag 2",
            Box::new(move |s| {
                let at = first_mesh(s) + 8;
                assert_eq!(s[at..at + 4], 1u32.to_le_bytes(), "the grid's box is solid");
                s[at..at + 4].copy_from_slice(&2u32.to_le_bytes());
            }),
        ),
        (
            "node 2: transform is not finite",
            Box::new(move |s| {
                s[node(2) + 8..node(2) + 16].copy_from_slice(&f64::NAN.to_le_bytes());
            }),
        ),
        // Finite, but its part's world box beyond ±1e15: refused where debug
        // builds used to assert (found by the resealed store_open fuzz target).
        (
            "world box not finite or beyond",
            Box::new(move |s| {
                let x = node(2) + 8 + 9 * 8; // the translation's x
                s[x..x + 8].copy_from_slice(&1e16f64.to_le_bytes());
            }),
        ),
    ];
    // The unchanged skeleton passes through the helper intact.
    assert_eq!(with_skeleton(&bytes, |_| {}), bytes);
    for (needle, change) in cases {
        std::fs::write(&path, with_skeleton(&bytes, change)).unwrap();
        let err = Store::open(&path).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, StoreError::Corrupt { .. }), "{msg}");
        assert!(
            msg.contains("the skeleton") && msg.contains(needle),
            "{msg}"
        );
    }
}
