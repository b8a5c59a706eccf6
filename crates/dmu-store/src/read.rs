//! Reading a store: the header, the table of contents and the skeleton are read
//! and checked at open, each chunk's geometry segment and each far-field
//! segment whenever it is read.

use std::fs::File;
use std::path::{Path, PathBuf};

use dmu_scene::{ChunkId, MeshId, Properties, Scene};

use crate::error::StoreError;
use crate::format::{self, BlobSet, Layout, ReadAt, TocEntry};
use crate::geometry::{self, OwnedChunkGeometry, resident_bytes};
use crate::remote::{RemoteObject, RemoteOptions, RemoteStats, is_remote};
use crate::skeleton;

/// An open store: the skeleton in memory, geometry on disk until asked for.
///
/// Geometry is read with positioned reads (`pread`) when a chunk is asked for,
/// so it costs memory only while decoded. The file is not memory-mapped: a store
/// truncated or rewritten by another process while open gives a `Truncated` or
/// `Checksum` error naming the segment, where a mapping would end the process
/// with `SIGBUS`. Every read is checked against its segment's checksum (xxh3,
/// far faster than the decode that follows). Stores are never modified in place
/// (writes go to a new file renamed over the old one), so an open store keeps
/// reading the file it opened even after a save replaced it.
#[derive(Debug)]
pub struct Store {
    path: PathBuf,
    file: Source,
    /// The file's length when opened (the layout tiles exactly this many bytes).
    file_bytes: u64,
    layout: Layout,
    skeleton: Scene,
}

/// Where a store's bytes come from: a file, or an object on object storage
/// ([`crate::remote`]).
#[derive(Debug)]
enum Source {
    Local(File),
    Remote(Box<RemoteObject>),
}

impl Source {
    fn reader(&self) -> &dyn ReadAt {
        match self {
            Source::Local(f) => f,
            Source::Remote(o) => &**o,
        }
    }
}

impl ReadAt for Source {
    fn len(&self) -> std::io::Result<u64> {
        self.reader().len()
    }
    fn read_exact_at(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        self.reader().read_exact_at(offset, len)
    }
    fn read_at_most(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        self.reader().read_at_most(offset, len)
    }
    fn read_into(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        self.reader().read_into(offset, buf)
    }
}

/// Loader threads for a store on object storage ([`Store::loader_threads`]).
pub const REMOTE_LOADERS: usize = 8;

/// Sizes of an open store.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct StoreInfo {
    /// Format version.
    pub version: u32,
    /// File size.
    pub file_bytes: u64,
    /// Chunk geometry segments.
    pub chunks: u64,
    /// Bytes of geometry segments in the file.
    pub geometry_file_bytes: u64,
    /// Bytes the geometry takes decoded (what residency budgets count).
    pub geometry_resident_bytes: u64,
    /// Bytes of the skeleton segment.
    pub skeleton_bytes: u64,
    /// Far-field cell segments (0 without far fields).
    pub far_field_cells: u64,
    /// Bytes of the far-field index and cell segments in the file.
    pub far_field_bytes: u64,
    /// Level-of-detail node segments (0 without the hierarchy).
    pub lod_nodes: u64,
    /// Bytes of the level-of-detail index and node segments in the file.
    pub lod_bytes: u64,
}

impl Store {
    /// Opens a store, checking its header, table of contents and skeleton:
    /// a file, an object on object storage (`s3://bucket/key`, reached as
    /// the AWS variables say: [`RemoteOptions::from_env`]) or a web address
    /// (`https://…`, read by range requests).
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        Self::open_with(path, &RemoteOptions::from_env())
    }

    /// [`Store::open`], reaching object storage as `remote` says.
    pub fn open_with(path: &Path, remote: &RemoteOptions) -> Result<Store, StoreError> {
        let io = |source| StoreError::Io {
            path: path.to_owned(),
            source,
        };
        let file = if is_remote(path) {
            let url = path.to_string_lossy();
            Source::Remote(Box::new(RemoteObject::open(&url, remote).map_err(io)?))
        } else {
            Source::Local(dmu_scene::open_regular_file(path).map_err(io)?)
        };
        let layout = format::parse(&file, path)?;
        let file_bytes = format::ReadAt::len(&file).map_err(io)?;
        let corrupt = |what: String| StoreError::Corrupt {
            path: path.to_owned(),
            what,
        };
        let mut skeleton = skeleton::read(&file, &layout.skeleton, path)?;
        if let Some(bytes) = properties_segment(&file, &layout, path)? {
            skeleton.properties = Properties::from_bytes(&bytes, skeleton.nodes.len())
                .map_err(|e| corrupt(format!("the properties: {e}")))?;
        }
        let mut skeleton = skeleton
            .into_scene()
            .map_err(|e| corrupt(format!("the skeleton: {e}")))?;
        if let Source::Remote(o) = &file {
            skeleton.set_source_version(o.version().map(str::to_owned));
        }
        if skeleton.chunks().len() != layout.chunks.len() {
            return Err(corrupt(format!(
                "the skeleton has {} chunks, the table of contents {}",
                skeleton.chunks().len(),
                layout.chunks.len()
            )));
        }
        Ok(Store {
            path: path.to_owned(),
            file,
            file_bytes,
            layout,
            skeleton,
        })
    }

    /// How many loader threads suit this store: 2 for a file (decoding is
    /// most of a load, and two keep a disk busy), [`REMOTE_LOADERS`] for
    /// a store on object storage, where each load mostly waits on the
    /// network (at 20 ms a request, 8 keep 100 Mbit/s full).
    pub fn loader_threads(&self) -> usize {
        match self.remote() {
            None => 2,
            Some(_) => REMOTE_LOADERS,
        }
    }

    /// The object it reads, for a store on object storage or a web server.
    fn remote(&self) -> Option<&RemoteObject> {
        match &self.file {
            Source::Local(_) => None,
            Source::Remote(o) => Some(o),
        }
    }

    /// For a store on object storage or a web server: what reading it has
    /// cost so far (requests, bytes fetched, cache hits, retries).
    pub fn remote_stats(&self) -> Option<RemoteStats> {
        self.remote().map(RemoteObject::stats)
    }

    /// For a store on object storage: the version it was read at (the
    /// object's ETag).
    pub fn remote_version(&self) -> Option<&str> {
        self.remote().and_then(RemoteObject::version)
    }

    /// For a store on object storage: how it was reached.
    pub fn remote_options(&self) -> Option<&RemoteOptions> {
        self.remote().map(RemoteObject::options)
    }

    /// The file it was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The scene without its geometry: structure, transforms, chunk tables and
    /// boxes (see [`dmu_scene::Mesh`]). Enough to build the cell tree.
    pub fn skeleton(&self) -> &Scene {
        &self.skeleton
    }

    /// Takes the skeleton out (for a caller that edits it: moves, visibility),
    /// leaving the store its materials, meshes and chunk tables, all that
    /// reading geometry needs ([`Store::chunk_geometry`],
    /// [`Store::mesh_geometry`], a [`crate::Residency`]): afterwards
    /// [`Store::skeleton`] has the root node only and no parts. Saves a
    /// second copy of the nodes and parts (about 190 bytes a node).
    pub fn take_skeleton(&mut self) -> Scene {
        let tables = skeleton::chunk_tables(&self.skeleton);
        std::mem::replace(&mut self.skeleton, tables)
    }

    /// Sizes.
    pub fn info(&self) -> StoreInfo {
        let chunks = &self.layout.chunks;
        StoreInfo {
            version: self.layout.version,
            file_bytes: self.file_bytes,
            chunks: chunks.len() as u64,
            geometry_file_bytes: chunks.iter().map(TocEntry::padded_len).sum(),
            geometry_resident_bytes: (0..chunks.len())
                .map(|c| self.chunk_resident_bytes(ChunkId::from_index(c)))
                .sum(),
            skeleton_bytes: self.layout.skeleton.length,
            far_field_cells: self.far_field_cells() as u64,
            far_field_bytes: self.far_field_bytes(),
            lod_nodes: self.blob_count(BlobSet::Lod) as u64,
            lod_bytes: self.blob_bytes(BlobSet::Lod),
        }
    }

    /// Bytes a chunk's segment takes in the file: what loading it reads.
    pub fn chunk_file_bytes(&self, chunk: ChunkId) -> u64 {
        self.layout.chunks[chunk.index()].padded_len()
    }

    /// Bytes a chunk takes decoded (at most, with its levels): what it costs
    /// in a residency budget.
    pub fn chunk_resident_bytes(&self, chunk: ChunkId) -> u64 {
        let c = self.skeleton.chunk(chunk);
        resident_bytes(
            u64::from(c.vertices.end - c.vertices.start),
            u64::from(c.triangle_count()),
            self.stores_levels(),
        )
    }

    /// Whether its chunks hold their simplified levels (format version 4 on).
    fn stores_levels(&self) -> bool {
        self.layout.version >= 4
    }

    /// Reads and decodes a chunk's geometry, verifying its segment's checksum.
    ///
    /// # Panics
    /// When `chunk` is not a chunk of this store.
    pub fn chunk_geometry(&self, chunk: ChunkId) -> Result<OwnedChunkGeometry, StoreError> {
        let bytes = self.chunk_segment(chunk)?;
        self.decode(chunk, &bytes)
    }

    /// Decodes the segment of `chunk`.
    fn decode(&self, chunk: ChunkId, bytes: &[u8]) -> Result<OwnedChunkGeometry, StoreError> {
        let c = self.skeleton.chunk(chunk);
        geometry::decode(
            bytes,
            self.layout.version,
            c.vertices.end - c.vertices.start,
            c.triangle_count(),
            &c.bounds,
        )
        .map_err(|what| StoreError::Corrupt {
            path: self.path.clone(),
            what: format!("chunk {chunk}: {what}"),
        })
    }

    /// A chunk's encoded segment, verified.
    fn chunk_segment(&self, chunk: ChunkId) -> Result<Vec<u8>, StoreError> {
        let entry = &self.layout.chunks[chunk.index()];
        format::verified(&self.file, entry, || format!("chunk {chunk}"), &self.path)
    }

    /// A chunk's segment in this build's format, for copying into a new
    /// store: verified, and as it is in the file when that holds levels; a
    /// version-3 chunk is decoded (checked) and gets its levels computed and
    /// added after its bytes.
    pub(crate) fn chunk_segment_with_levels(&self, chunk: ChunkId) -> Result<Vec<u8>, StoreError> {
        let mut bytes = self.chunk_segment(chunk)?;
        if !self.stores_levels() {
            let g = self.decode(chunk, &bytes)?;
            geometry::add_levels(&mut bytes, &dmu_scene::lod_levels(&g.geometry()));
        }
        Ok(bytes)
    }

    /// The skeleton segment as it is in the file, verified (for copying into a
    /// new store: unlike [`Store::skeleton`], untouched by
    /// [`Store::take_skeleton`]).
    pub(crate) fn skeleton_segment(&self) -> Result<Vec<u8>, StoreError> {
        format::verified(
            &self.file,
            &self.layout.skeleton,
            || "the skeleton".into(),
            &self.path,
        )
    }

    /// The properties segment as it is in the file, its checksum verified
    /// (for a rewrite to copy); `None` when no node has a property.
    pub(crate) fn properties_segment(&self) -> Result<Option<Vec<u8>>, StoreError> {
        properties_segment(&self.file, &self.layout, &self.path)
    }

    /// The index of blob set `set`, its checksum verified; `None` when the
    /// store has none (no far fields, no level-of-detail hierarchy). Its
    /// encoding is the caller's: the store keeps bytes.
    pub fn blob_index(&self, set: BlobSet) -> Result<Option<Vec<u8>>, StoreError> {
        self.layout
            .blob_set(set)
            .index
            .as_ref()
            .map(|entry| {
                format::verified(
                    &self.file,
                    entry,
                    || format!("the {}", set.index_name()),
                    &self.path,
                )
            })
            .transpose()
    }

    /// How many blobs of `set` the store holds (numbered `0..n`; 0 without
    /// the set).
    pub fn blob_count(&self, set: BlobSet) -> usize {
        self.layout.blob_set(set).blobs.len()
    }

    /// Blob `blob` of `set`, its checksum verified (a damaged blob fails
    /// alone; the rest of the store still reads). One the store does not have
    /// is [`StoreError::NoSuchBlob`].
    pub fn blob(&self, set: BlobSet, blob: u32) -> Result<Vec<u8>, StoreError> {
        let blobs = &self.layout.blob_set(set).blobs;
        let entry = blobs
            .get(blob as usize)
            .ok_or_else(|| StoreError::NoSuchBlob {
                path: self.path.clone(),
                what: set.blob_name(),
                blob: u64::from(blob),
                blobs: blobs.len() as u64,
            })?;
        format::verified(
            &self.file,
            entry,
            || format!("{} #{blob}", set.blob_name()),
            &self.path,
        )
    }

    /// Bytes the index and blobs of `set` take in the file (0 without it).
    pub fn blob_bytes(&self, set: BlobSet) -> u64 {
        let segments = self.layout.blob_set(set);
        segments
            .index
            .iter()
            .chain(&segments.blobs)
            .map(TocEntry::padded_len)
            .sum()
    }

    /// The far-field index ([`Store::blob_index`] of [`BlobSet::FarField`]).
    pub fn far_field_index(&self) -> Result<Option<Vec<u8>>, StoreError> {
        self.blob_index(BlobSet::FarField)
    }

    /// How many far-field cells the store holds.
    pub fn far_field_cells(&self) -> usize {
        self.blob_count(BlobSet::FarField)
    }

    /// One far-field cell's blob ([`Store::blob`]).
    pub fn far_field_cell(&self, cell: u32) -> Result<Vec<u8>, StoreError> {
        self.blob(BlobSet::FarField, cell)
    }

    /// Bytes the far-field index and cells take in the file.
    pub fn far_field_bytes(&self) -> u64 {
        self.blob_bytes(BlobSet::FarField)
    }

    /// A mesh's chunks, read and decoded in order (for
    /// [`Scene::load_mesh_geometry`] on a skeleton).
    ///
    /// # Panics
    /// When `mesh` is not a mesh of this store.
    pub fn mesh_geometry(&self, mesh: MeshId) -> Result<Vec<OwnedChunkGeometry>, StoreError> {
        self.skeleton
            .mesh(mesh)
            .chunk_ids()
            .map(|c| self.chunk_geometry(c))
            .collect()
    }

    /// The whole scene with its geometry (every segment verified and decoded, in
    /// parallel).
    pub fn load_scene(&self) -> Result<Scene, StoreError> {
        let mut scene = skeleton::with_geometry(&self.skeleton, &|mesh| self.mesh_geometry(mesh))?;
        scene.set_source_version(self.remote_version().map(str::to_owned));
        Ok(scene)
    }
}

/// The properties segment of the store at `path` laid out as `layout`, its
/// checksum verified; `None` when it has none.
fn properties_segment(
    file: &Source,
    layout: &Layout,
    path: &Path,
) -> Result<Option<Vec<u8>>, StoreError> {
    layout
        .properties
        .as_ref()
        .map(|entry| format::verified(file, entry, || "the properties".into(), path))
        .transpose()
}
