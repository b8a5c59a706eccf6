//! Saving edits: a new skeleton and table of contents with the scene's current
//! transforms, in a new file that replaces the store by rename.

use dmu_scene::{ChunkId, Scene};

use crate::error::StoreError;
use crate::read::Store;
use crate::skeleton::structure_difference;
use crate::write::{PendingStore, StoreSummary, StoreWriter, WriteOptions};

/// Saves `scene`'s transforms and part visibility into the store it was opened
/// from, replacing the file by rename (a crash leaves the previous file).
///
/// Only transforms and visibility may differ from the store's skeleton; the
/// geometry segments are copied verified, byte for byte, into the new file. Cost:
/// the whole file is read and written once (sequential I/O, no decoding), e.g.
/// about a second per gigabyte on an SSD. The open `store` keeps reading the
/// file it opened; open the path again to see the saved one.
pub fn save_edits(store: &Store, scene: &Scene) -> Result<StoreSummary, StoreError> {
    prepare_save(store, scene)?.commit()
}

/// [`save_edits`] up to the rename: the new file is written and synced under a
/// temporary name; committing the result puts it in place.
pub fn prepare_save(store: &Store, scene: &Scene) -> Result<PendingStore, StoreError> {
    if let Some(what) = structure_difference(store.skeleton(), scene) {
        return Err(StoreError::SceneMismatch {
            path: store.path().to_owned(),
            what,
        });
    }
    let mut writer = StoreWriter::create(store.path(), WriteOptions::default())?;
    for (c, chunk) in store.skeleton().chunks().iter().enumerate() {
        let id = ChunkId::from_index(c);
        writer.chunk_segment(
            store.chunk_segment(id)?,
            chunk.vertices.end - chunk.vertices.start,
            chunk.triangle_count(),
        )?;
    }
    writer.finish(scene)
}
