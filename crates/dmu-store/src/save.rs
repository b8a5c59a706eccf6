//! Saving edits: a new skeleton and table of contents with the scene's current
//! transforms, in a new file that replaces the store by rename.

use std::path::Path;

use dmu_scene::{ChunkId, Scene, Structure};

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
            &store.chunk_segment(id)?,
            chunk.vertices.end - chunk.vertices.start,
            chunk.triangle_count(),
        )?;
    }
    writer.finish(&Structure::of(scene))
}

/// The format a model is saved in, named by the output's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SavedFormat {
    /// Edits saved back into the store the scene was read from.
    Edits,
    /// A new `.dmu` store.
    Store,
    /// glTF (`.glb` binary, or `.gltf` with an embedded buffer).
    Gltf,
}

impl std::fmt::Display for SavedFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SavedFormat::Edits => "edits saved into the store",
            SavedFormat::Store => "store",
            SavedFormat::Gltf => "glTF",
        })
    }
}

/// Writes `scene` (geometry loaded) to `path` in the format its extension names:
/// `.dmu` a store, `.glb`/`.gltf` glTF; any other extension is refused, so an
/// output is never written in a format its name does not say. When `path` is
/// `source` (the store the scene was read from), the edits are saved into it
/// ([`save_edits`]). Every format goes through a temporary file renamed over
/// `path`: a failure leaves the previous file as it was.
///
/// # Panics
/// When the scene's geometry is not loaded.
pub fn save_scene(
    scene: &Scene,
    source: Option<&Path>,
    path: &Path,
) -> Result<SavedFormat, StoreError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("dmu") if source.is_some_and(|s| same_file(s, path)) => {
            save_edits(&Store::open(path)?, scene)?;
            Ok(SavedFormat::Edits)
        }
        Some("dmu") => {
            crate::write::write_scene(scene, path, WriteOptions::default())?;
            Ok(SavedFormat::Store)
        }
        Some("glb" | "gltf") => {
            dmu_scene::export_gltf(scene, path).map_err(|source| StoreError::Export {
                path: path.to_owned(),
                source,
            })?;
            Ok(SavedFormat::Gltf)
        }
        _ => Err(StoreError::UnknownOutputFormat {
            path: path.to_owned(),
        }),
    }
}

/// Whether two paths name the same file (the same path when either cannot be
/// resolved).
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}
