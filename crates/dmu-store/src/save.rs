//! Saving edits: a new skeleton and table of contents with the scene's current
//! transforms, in a new file that replaces the store by rename.

use std::path::Path;

use dmu_scene::{ChunkId, Scene, Structure};
use rayon::prelude::*;

use crate::error::StoreError;
use crate::format::BlobSet;
use crate::read::Store;
use crate::remote::RemoteOptions;
use crate::skeleton::structure_difference;
use crate::write::{PendingStore, StoreSummary, StoreWriter, WriteOptions, batches};

/// Saves `scene`'s transforms and part visibility into the store it was opened
/// from, replacing the file by rename (a crash leaves the previous file).
///
/// Only transforms and visibility may differ from the store's skeleton; the
/// geometry segments, and the far-field index and cells if the store has them,
/// are copied verified, byte for byte, into the new file (whether moved parts
/// made far-field cells stale is the caller's to decide: see
/// [`write_far_fields`]). Cost: the whole file is read and written once
/// (sequential I/O, no decoding), e.g. about a second per gigabyte on an SSD.
/// A version-3 store is the exception: its chunks are decoded and given their
/// levels (format version 4), as an import would (seconds per 10M triangles).
/// The open `store` keeps reading the file it opened; open the path again to
/// see the saved one.
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
    // On object storage, conditional on the version the scene was read at
    // (the store may have been opened again since).
    let version = scene.source_version().or(store.remote_version());
    with_geometry_of(store, None, version)?.finish(&Structure::of(scene))
}

/// Replaces the far fields of `store` (an index and one blob per cell, opaque
/// bytes in the caller's encoding) in a new file written under a temporary
/// name; committing the result ([`PendingStore::commit`]) renames it over the
/// store's path. The skeleton and every chunk segment are copied verified, byte
/// for byte, as [`save_edits`] copies them (edits the caller made to the
/// skeleton are not saved: use [`save_edits`] for those).
///
/// `cells` yields the new cells in order, cell 0 first; as many cells as it
/// yields, the store will have. Each item is:
/// - `Ok(Some(blob))`: this cell's new blob;
/// - `Ok(None)`: keep the store's blob of this cell (copied verified); a cell
///   the store does not have is [`StoreError::NoSuchBlob`];
/// - `Err(e)`: the caller's failure, returned as it is.
///
/// So rebuilding a few stale cells is
/// `cells.map(|c| Ok(stale(c).then(|| build(c))))`. The iterator is drawn one
/// cell at a time and each blob is written and dropped before the next is
/// asked for, so the caller may make them as it goes. The index is always
/// given (pass [`Store::far_field_index`] to keep it). `E` is the caller's
/// error type (e.g. `anyhow::Error`, or [`StoreError`]).
///
/// On any error (the caller's, reading the store, writing), nothing is renamed:
/// the store's file is as it was and the temporary file is removed.
///
/// ```
/// use dmu_store::{Store, StoreError, WriteOptions, write_far_fields, write_scene};
///
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("grid.dmu");
/// write_scene(&dmu_samples::grid(2, 10.0, 4.0, 8), &path, WriteOptions::default()).unwrap();
/// let store = Store::open(&path).unwrap();
/// assert_eq!(store.far_field_index().unwrap(), None);
/// let cells = (0..3u8).map(|c| Ok::<_, StoreError>(Some(vec![c; 1000])));
/// write_far_fields(&store, b"index", cells).unwrap().commit().unwrap();
///
/// // Cell 1 rebuilt, cells 0 and 2 kept.
/// let store = Store::open(&path).unwrap();
/// let cells = [None, Some(vec![7; 10]), None].map(Ok::<_, StoreError>);
/// write_far_fields(&store, b"index", cells).unwrap().commit().unwrap();
/// let store = Store::open(&path).unwrap();
/// assert_eq!(store.far_field_cells(), 3);
/// assert_eq!(store.far_field_cell(0).unwrap(), vec![0; 1000]);
/// assert_eq!(store.far_field_cell(1).unwrap(), vec![7; 10]);
/// ```
pub fn write_far_fields<E: From<StoreError>>(
    store: &Store,
    index: &[u8],
    cells: impl IntoIterator<Item = Result<Option<Vec<u8>>, E>>,
) -> Result<PendingStore, E> {
    let mut writer = BlobWriter::new(store, BlobSet::FarField)?;
    for (cell, blob) in cells.into_iter().enumerate() {
        match blob? {
            Some(blob) => writer.push(&blob)?,
            None => writer.keep(cell_number(cell))?,
        };
    }
    Ok(writer.finish(index)?)
}

/// A rewrite of a store that replaces one [`BlobSet`] (the far fields, the
/// level-of-detail hierarchy) with blobs pushed one at a time, so a builder
/// never holds them all: a new file under a temporary name holding the
/// store's skeleton, chunk segments and other blob sets, copied verified byte
/// for byte (edits the caller made to the skeleton are not saved: use
/// [`save_edits`] for those). [`BlobWriter::finish`] writes the set's index
/// and gives the [`PendingStore`], whose commit renames it over the store.
#[derive(Debug)]
pub struct BlobWriter<'a> {
    store: &'a Store,
    set: BlobSet,
    writer: StoreWriter,
}

impl<'a> BlobWriter<'a> {
    /// Starts the rewrite of `store` with a new `set`.
    pub fn new(store: &'a Store, set: BlobSet) -> Result<Self, StoreError> {
        Ok(Self {
            store,
            set,
            writer: with_geometry_of(store, Some(set), store.remote_version())?,
        })
    }

    /// Appends the next blob; its number.
    pub fn push(&mut self, blob: &[u8]) -> Result<u32, StoreError> {
        self.writer.blob(self.set, blob)
    }

    /// Appends the store's own blob `blob` of the set as the next one
    /// (copied verified); a blob the store does not have is
    /// [`StoreError::NoSuchBlob`].
    pub fn keep(&mut self, blob: u32) -> Result<u32, StoreError> {
        let bytes = self.store.blob(self.set, blob)?;
        self.push(&bytes)
    }

    /// Writes the set's index, the skeleton and properties (the store's, as
    /// they are in the file) and the table of contents, and syncs the file.
    pub fn finish(mut self, index: &[u8]) -> Result<PendingStore, StoreError> {
        self.writer.blob_index(self.set, index)?;
        let properties = self.store.properties_segment()?;
        self.writer
            .finish_copied(&self.store.skeleton_segment()?, properties.as_deref())
    }
}

/// A writer for a new file at `store`'s path holding `store`'s chunk
/// segments and its blob sets but `replaced`, copied verified byte for byte
/// (a version-3 store's chunks with their levels added, computed in
/// parallel): what every rewrite of a store starts with. On object storage
/// its upload is conditional on `version`.
fn with_geometry_of(
    store: &Store,
    replaced: Option<BlobSet>,
    version: Option<&str>,
) -> Result<StoreWriter, StoreError> {
    let mut writer = StoreWriter::replacing(store, version)?;
    let chunks = store.skeleton().chunks();
    for batch in batches(chunks.iter().map(|c| c.triangle_count() as usize)) {
        let segments: Vec<Vec<u8>> = batch
            .clone()
            .into_par_iter()
            .map(|c| store.chunk_segment_with_levels(ChunkId::from_index(c)))
            .collect::<Result<_, _>>()?;
        for (chunk, bytes) in chunks[batch].iter().zip(segments) {
            writer.chunk_segment(
                &bytes,
                chunk.vertices.end - chunk.vertices.start,
                chunk.triangle_count(),
            )?;
        }
    }
    for set in BlobSet::ALL.into_iter().filter(|&s| Some(s) != replaced) {
        if let Some(index) = store.blob_index(set)? {
            writer.blob_index(set, &index)?;
            for blob in 0..store.blob_count(set) {
                writer.blob(set, &store.blob(set, cell_number(blob))?)?;
            }
        }
    }
    Ok(writer)
}

/// A blob position as a blob number (ids are `u32` on disk).
///
/// # Panics
/// Past `u32::MAX` blobs, which no store holds (each takes a 32-byte entry).
fn cell_number(cell: usize) -> u32 {
    u32::try_from(cell).expect("over 4G far-field cells")
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
/// ([`save_edits`]; on object storage, conditional on the version the scene
/// was read at, which the save then advances). Every format goes through a temporary file renamed over
/// `path`: a failure leaves the previous file as it was.
///
/// # Panics
/// When the scene's geometry is not loaded.
pub fn save_scene(
    scene: &mut Scene,
    source: Option<&Path>,
    path: &Path,
) -> Result<SavedFormat, StoreError> {
    save_scene_with(scene, source, path, &RemoteOptions::from_env())
}

/// [`save_scene`], reaching object storage as `remote` says.
pub fn save_scene_with(
    scene: &mut Scene,
    source: Option<&Path>,
    path: &Path,
    remote: &RemoteOptions,
) -> Result<SavedFormat, StoreError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("dmu") if source.is_some_and(|s| same_file(s, path)) => {
            let saved = save_edits(&Store::open_with(path, remote)?, scene)?;
            // The next save is conditional on this one.
            if saved.version.is_some() {
                scene.set_source_version(saved.version);
            }
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
