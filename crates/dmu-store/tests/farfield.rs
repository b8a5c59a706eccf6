//! Far-field segments: an index and a blob per cell kept beside the geometry,
//! written (all or a few cells replaced), carried over by saves, and refused
//! or failed alone when damaged or crafted.

use std::path::Path;

use dmu_store::{Store, StoreError, save_edits, write_far_fields};
use glam::{DAffine3, DVec3};

use crate::support::{
    KIND_FAR_CELL, KIND_FAR_INDEX, KIND_SKELETON, assert_same_scene, entry, small_store, toc,
    with_toc,
};

/// A blob for `cell`, different for each `salt`, of a length that is not a
/// multiple of the alignment (so padding is exercised).
fn blob(cell: usize, salt: u8) -> Vec<u8> {
    (0..40 + 7 * cell)
        .map(|i| (i as u8).wrapping_mul(31) ^ cell as u8 ^ salt)
        .collect()
}

/// Replaces the far fields of the store at `path` with `index` and `cells`
/// (`None`: keep that cell), committed.
fn write(path: &Path, index: &[u8], cells: Vec<Option<Vec<u8>>>) {
    let store = Store::open(path).unwrap();
    write_far_fields(&store, index, cells.into_iter().map(Ok::<_, StoreError>))
        .unwrap()
        .commit()
        .unwrap();
}

/// Every far-field blob of the store at `path`: the index and the cells.
fn far_fields(path: &Path) -> (Option<Vec<u8>>, Vec<Vec<u8>>) {
    let store = Store::open(path).unwrap();
    let cells = (0..store.far_field_cells() as u32)
        .map(|c| store.far_field_cell(c).unwrap())
        .collect();
    (store.far_field_index().unwrap(), cells)
}

/// The small grid store with an index and three cells: folder, path, bytes.
fn far_store() -> (tempfile::TempDir, std::path::PathBuf, Vec<u8>) {
    let (dir, path, _) = small_store();
    write(
        &path,
        b"the index",
        (0..3).map(|c| Some(blob(c, 0))).collect(),
    );
    let bytes = std::fs::read(&path).unwrap();
    (dir, path, bytes)
}

#[test]
fn a_store_without_far_fields_has_none() {
    let (_dir, path, _) = small_store();
    let store = Store::open(&path).unwrap();
    assert_eq!(store.far_field_index().unwrap(), None);
    assert_eq!(store.far_field_cells(), 0);
    assert_eq!(store.far_field_bytes(), 0);
    let info = store.info();
    assert_eq!((info.far_field_cells, info.far_field_bytes), (0, 0));
    let err = store.far_field_cell(0).unwrap_err();
    assert!(
        matches!(
            err,
            StoreError::NoSuchBlob {
                blob: 0,
                blobs: 0,
                ..
            }
        ),
        "{err}"
    );
    let msg = err.to_string();
    assert!(
        msg.contains("model.dmu") && msg.contains("far-field cell #0"),
        "{msg}"
    );
}

/// A store without far fields is the format it was: no segment of the new
/// kinds, and saving it changes no byte.
#[test]
fn a_store_without_far_fields_saves_unchanged() {
    let (_dir, path, bytes) = small_store();
    assert!(toc(&bytes).iter().all(|e| e.kind <= 2), "only old kinds");
    let store = Store::open(&path).unwrap();
    save_edits(&store, store.skeleton()).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
}

#[test]
fn far_fields_round_trip() {
    let (_dir, path, before) = small_store();
    let scene = Store::open(&path).unwrap().load_scene().unwrap();
    let cells: Vec<Vec<u8>> = (0..5).map(|c| blob(c, 0)).collect();
    let store = Store::open(&path).unwrap();
    let pending = write_far_fields(
        &store,
        b"index bytes",
        cells.iter().cloned().map(|b| Ok::<_, StoreError>(Some(b))),
    )
    .unwrap();
    // Nothing is in place before the commit.
    assert_eq!(std::fs::read(&path).unwrap(), before);
    let summary = pending.commit().unwrap();
    let after = std::fs::read(&path).unwrap();
    assert_eq!(summary.file_bytes, after.len() as u64);

    let store = Store::open(&path).unwrap();
    assert_eq!(
        store.far_field_index().unwrap().as_deref(),
        Some(&b"index bytes"[..])
    );
    assert_eq!(store.far_field_cells(), 5);
    for (c, cell) in cells.iter().enumerate() {
        assert_eq!(&store.far_field_cell(c as u32).unwrap(), cell, "cell {c}");
    }
    let padded: u64 = std::iter::once(11)
        .chain(cells.iter().map(Vec::len))
        .map(|l| (l as u64).next_multiple_of(16))
        .sum();
    assert_eq!(store.far_field_bytes(), padded);
    let info = store.info();
    assert_eq!((info.far_field_cells, info.far_field_bytes), (5, padded));
    assert_eq!(info.file_bytes, after.len() as u64);
    // The skeleton and the geometry are the ones copied, byte for byte.
    let skeleton = |b: &[u8]| b[entry(b, KIND_SKELETON, 0).payload()].to_vec();
    assert_eq!(skeleton(&after), skeleton(&before));
    assert_same_scene(&store.load_scene().unwrap(), &scene);
    // Past the last cell: an error naming the cell and the file.
    let err = store.far_field_cell(5).unwrap_err();
    assert!(
        matches!(
            err,
            StoreError::NoSuchBlob {
                blob: 5,
                blobs: 5,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("model.dmu"), "{err}");
}

#[test]
fn an_index_without_cells_is_a_store_with_far_fields() {
    let (_dir, path, _) = small_store();
    write(&path, b"", Vec::new());
    let store = Store::open(&path).unwrap();
    assert_eq!(store.far_field_index().unwrap(), Some(Vec::new()));
    assert_eq!(store.far_field_cells(), 0);
}

#[test]
fn replacing_some_cells_keeps_the_others() {
    let (_dir, path, _) = far_store();
    // Cells 1 and (a new) 3 rebuilt, 0 and 2 kept, a new index.
    write(
        &path,
        b"index 2",
        vec![None, Some(blob(1, 9)), None, Some(blob(3, 9))],
    );
    let (index, cells) = far_fields(&path);
    assert_eq!(index.as_deref(), Some(&b"index 2"[..]));
    assert_eq!(cells, [blob(0, 0), blob(1, 9), blob(2, 0), blob(3, 9)]);
    // Fewer cells than before: the rest are dropped.
    write(&path, b"index 3", vec![None, None]);
    assert_eq!(far_fields(&path).1, [blob(0, 0), blob(1, 9)]);
    // The index kept as it was, every cell kept: the same file.
    let before = std::fs::read(&path).unwrap();
    let store = Store::open(&path).unwrap();
    let index = store.far_field_index().unwrap().unwrap();
    write(&path, &index, vec![None, None]);
    assert_eq!(std::fs::read(&path).unwrap(), before);
}

/// The caller's cells are drawn one at a time, each written before the next
/// is asked for.
#[test]
fn cells_are_drawn_one_at_a_time() {
    let (_dir, path, _) = small_store();
    let store = Store::open(&path).unwrap();
    let drawn = std::cell::Cell::new(0);
    let cells = (0..4).map(|c| {
        assert_eq!(drawn.get(), c, "cells drawn in order, once each");
        drawn.set(c + 1);
        Ok::<_, StoreError>(Some(blob(c, 1)))
    });
    write_far_fields(&store, b"i", cells)
        .unwrap()
        .commit()
        .unwrap();
    assert_eq!(drawn.get(), 4);
    assert_eq!(far_fields(&path).1.len(), 4);
}

#[test]
fn save_edits_keeps_the_far_fields() {
    let (_dir, path, _) = far_store();
    let far = far_fields(&path);
    let store = Store::open(&path).unwrap();
    let mut edited = store.skeleton().clone();
    let p = edited.part_ids().next().unwrap();
    let moved = DAffine3::from_translation(DVec3::new(5.0, 0.0, 0.0)) * edited.part_world(p);
    edited.set_part_world(p, moved);
    save_edits(&store, &edited).unwrap();
    let reopened = Store::open(&path).unwrap();
    assert_eq!(reopened.skeleton().part_world(p), moved);
    assert_eq!(far_fields(&path), far);
}

/// Writing far fields after [`Store::take_skeleton`] (the viewer's way of
/// holding a store) keeps the whole skeleton: it is copied from the file, not
/// from what the store has left in memory.
#[test]
fn writing_far_fields_after_taking_the_skeleton_keeps_it() {
    let (_dir, path, _) = small_store();
    let mut store = Store::open(&path).unwrap();
    let skeleton = store.take_skeleton();
    write_far_fields(&store, b"i", [Ok::<_, StoreError>(Some(vec![1, 2, 3]))])
        .unwrap()
        .commit()
        .unwrap();
    let reopened = Store::open(&path).unwrap();
    assert_eq!(reopened.skeleton().parts(), skeleton.parts());
    assert_eq!(reopened.skeleton().nodes(), skeleton.nodes());
    assert_eq!(reopened.far_field_cell(0).unwrap(), [1, 2, 3]);
}

#[test]
fn a_flipped_far_field_byte_fails_that_segment_only() {
    let (_dir, path, bytes) = far_store();
    let scene = Store::open(&path).unwrap().load_scene().unwrap();
    let mut damaged = bytes.clone();
    damaged[entry(&bytes, KIND_FAR_CELL, 1).offset as usize + 3] ^= 1;
    std::fs::write(&path, &damaged).unwrap();
    // The store opens; only cell 1 fails, naming itself and the file.
    let store = Store::open(&path).unwrap();
    let err = store.far_field_cell(1).unwrap_err();
    assert!(matches!(err, StoreError::Checksum { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("model.dmu") && msg.contains("far-field cell #1"),
        "{msg}"
    );
    assert_eq!(store.far_field_cell(0).unwrap(), blob(0, 0));
    assert_eq!(store.far_field_cell(2).unwrap(), blob(2, 0));
    assert!(store.far_field_index().unwrap().is_some());
    assert_same_scene(&store.load_scene().unwrap(), &scene);
    // A damaged index likewise.
    let mut damaged = bytes.clone();
    damaged[entry(&bytes, KIND_FAR_INDEX, 0).offset as usize] ^= 1;
    std::fs::write(&path, &damaged).unwrap();
    let store = Store::open(&path).unwrap();
    let err = store.far_field_index().unwrap_err();
    assert!(matches!(err, StoreError::Checksum { .. }), "{err}");
    assert!(err.to_string().contains("the far-field index"), "{err}");
    assert_eq!(store.far_field_cell(1).unwrap(), blob(1, 0));
    // A save carries the damaged index over, so it fails and writes nothing.
    let err = save_edits(&store, store.skeleton()).unwrap_err();
    assert!(err.to_string().contains("the far-field index"), "{err}");
    assert_eq!(std::fs::read(&path).unwrap(), damaged);
    // A new index with every cell kept never reads the damaged one: it repairs
    // the store.
    let cells = (0..3).map(|_| Ok::<_, StoreError>(None));
    write_far_fields(&store, b"rebuilt", cells)
        .unwrap()
        .commit()
        .unwrap();
    let (index, cells) = far_fields(&path);
    assert_eq!(index.as_deref(), Some(&b"rebuilt"[..]));
    assert_eq!(cells, [blob(0, 0), blob(1, 0), blob(2, 0)]);
}

/// Every byte of a store with far fields is covered by a checksum: any
/// single flipped byte is caught at open or when its segment is read.
#[test]
fn every_flipped_byte_of_a_far_field_store_is_an_error() {
    let (_dir, path, bytes) = far_store();
    let read_all = |path: &Path| -> Result<(), StoreError> {
        let store = Store::open(path)?;
        store.far_field_index()?;
        for c in 0..store.far_field_cells() as u32 {
            store.far_field_cell(c)?;
        }
        store.load_scene().map(|_| ())
    };
    read_all(&path).unwrap();
    for at in 0..bytes.len() {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0x5a;
        std::fs::write(&path, &damaged).unwrap();
        let err = read_all(&path).expect_err(&format!("byte {at} flipped"));
        assert!(err.to_string().contains("model.dmu"), "{err}");
    }
}

/// Tables of contents whose checksums hold but whose far-field entries lie
/// (crafted, not damaged) are refused at open with one line naming the file
/// and what is wrong.
#[test]
fn crafted_far_field_tables_are_refused() {
    let (_dir, path, bytes) = far_store();
    // The unchanged table passes through the helper intact.
    assert_eq!(with_toc(&bytes, |_| {}), bytes);
    let find = |toc: &[crate::support::Entry], kind: u32, id: u32| {
        toc.iter()
            .position(|e| (e.kind, e.id) == (kind, id))
            .unwrap()
    };
    type Change = Box<dyn Fn(&mut [crate::support::Entry])>;
    let cases: [(&str, Change); 5] = [
        (
            "far-field cell #1 has two segments",
            Box::new(move |t| t[find(t, KIND_FAR_CELL, 2)].id = 1),
        ),
        (
            "far-field cell #7 is out of range (3 far-field cell segments)",
            Box::new(move |t| t[find(t, KIND_FAR_CELL, 2)].id = 7),
        ),
        (
            "two far-field index segments",
            Box::new(move |t| t[find(t, KIND_FAR_CELL, 0)].kind = KIND_FAR_INDEX),
        ),
        (
            "4 far-field cell segments but no far-field index",
            Box::new(move |t| {
                let i = find(t, KIND_FAR_INDEX, 0);
                (t[i].kind, t[i].id) = (KIND_FAR_CELL, 3);
            }),
        ),
        (
            "the far-field index has id 1, not 0",
            Box::new(move |t| t[find(t, KIND_FAR_INDEX, 0)].id = 1),
        ),
    ];
    for (needle, change) in cases {
        std::fs::write(&path, with_toc(&bytes, change)).unwrap();
        let err = Store::open(&path).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, StoreError::Corrupt { .. }), "{msg}");
        assert!(
            msg.contains("model.dmu") && msg.contains(needle),
            "{needle}: {msg}"
        );
        assert_eq!(msg.lines().count(), 1, "{msg}");
    }
}

/// A far-field write that fails (the caller's cells fail, or a kept cell the
/// store does not have) leaves the store as it was and no temporary file.
#[test]
fn a_failed_far_field_write_changes_nothing() {
    let (dir, path, bytes) = far_store();
    let store = Store::open(&path).unwrap();
    let only_the_store = || {
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "temporary file left"
        );
    };

    // The caller's error, in its own type (here a boxed error, as anyhow's
    // would be), comes back as it was.
    let cells = (0..3).map(|c| -> Result<_, Box<dyn std::error::Error>> {
        if c == 1 {
            Err(format!("rendering cell {c} failed").into())
        } else {
            Ok(Some(blob(c, 5)))
        }
    });
    let err = write_far_fields(&store, b"new", cells).unwrap_err();
    assert_eq!(err.to_string(), "rendering cell 1 failed");
    only_the_store();

    // Keeping cell 3 of a store with three.
    let cells = (0..4).map(|_| Ok::<_, StoreError>(None));
    let err = write_far_fields(&store, b"new", cells).unwrap_err();
    assert!(
        matches!(
            err,
            StoreError::NoSuchBlob {
                blob: 3,
                blobs: 3,
                ..
            }
        ),
        "{err}"
    );
    only_the_store();

    // Written but dropped before its commit.
    let cells = (0..3).map(|c| Ok::<_, StoreError>(Some(blob(c, 6))));
    let pending = write_far_fields(&store, b"new", cells).unwrap();
    assert!(pending.temp_path().exists());
    drop(pending);
    only_the_store();
}
