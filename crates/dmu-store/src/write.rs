//! Writing a store: streaming, into a temporary file beside the target that is
//! synced and only then renamed over it, so a crash at any point leaves the
//! previous file (if any) whole and readable.

use std::fs::File;
use std::io::{BufWriter, Seek as _, SeekFrom, Write as _};
use std::ops::Range;
use std::path::{Path, PathBuf};

use dmu_geom::Aabb3f;
use dmu_scene::{AtomicFile, ChunkGeometry, ChunkedMesh, Scene, Structure};
use rayon::prelude::*;
use xxhash_rust::xxh3::Xxh3;

use crate::error::StoreError;
use crate::format::{
    ALIGN, BlobSet, HEADER_LEN, Header, KIND_CHUNK, KIND_PROPERTIES, KIND_SKELETON, TocEntry,
};
use crate::geometry::{self, resident_bytes};
use crate::read::Store;
use crate::remote::{RemoteOptions, is_remote, spool_path, upload};
use crate::skeleton;

/// Triangles of the chunks encoded together, in parallel (simplifying their
/// levels is most of the cost): about 128 default chunks, work for every
/// core, and about 10 MB of geometry held for it.
const BATCH_TRIANGLES: usize = 1 << 18;

/// Consecutive ranges of items (chunks) of the given triangle counts, each
/// holding [`BATCH_TRIANGLES`] or more but the last: what is encoded at once.
pub(crate) fn batches(triangles: impl IntoIterator<Item = usize>) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let (mut start, mut end, mut held) = (0, 0, 0);
    for t in triangles {
        (end, held) = (end + 1, held + t);
        if held >= BATCH_TRIANGLES {
            out.push(start..end);
            (start, held) = (end, 0);
        }
    }
    if start < end {
        out.push(start..end);
    }
    out
}

/// How geometry is written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteOptions {
    /// Positions as 16 bits per axis within each chunk's box, normals as two
    /// 16-bit octahedral components: geometry segments shrink from 24 to 10 bytes
    /// a vertex; positions move by at most 1/131070 of the chunk's extent.
    pub quantize: bool,
}

/// What a written store holds.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct StoreSummary {
    /// The file.
    pub path: PathBuf,
    /// Its size.
    pub file_bytes: u64,
    /// Chunk geometry segments.
    pub chunks: u64,
    /// Bytes of those segments in the file.
    pub geometry_file_bytes: u64,
    /// Bytes the geometry takes decoded in memory (what residency budgets count).
    pub geometry_resident_bytes: u64,
    /// Bytes of the skeleton segment.
    pub skeleton_bytes: u64,
    /// Written to object storage: the new object's version (its ETag).
    pub version: Option<String>,
}

/// Writes a store segment by segment: chunk geometry as it is produced (and can
/// be dropped), then the skeleton and the table of contents.
#[derive(Debug)]
pub struct StoreWriter {
    target: PathBuf,
    temp: AtomicFile,
    /// Where the store goes when the target is on object storage.
    remote: Option<RemoteTarget>,
    file: BufWriter<File>,
    offset: u64,
    toc: Vec<TocEntry>,
    /// (vertices, triangles) of each chunk written, checked against the skeleton.
    shapes: Vec<(u32, u32)>,
    /// Per [`BlobSet`]: whether its index is written, and its blobs written
    /// (the next blob's number).
    blob_sets: [(bool, u32); 2],
    /// Meshes given to [`StoreWriter::add_mesh`] whose chunks are not
    /// written yet, and their triangles: encoded together once these reach
    /// [`BATCH_TRIANGLES`].
    pending: Vec<ChunkedMesh>,
    pending_triangles: usize,
    options: WriteOptions,
    summary: StoreSummary,
}

/// A store written and synced under a temporary name: [`PendingStore::commit`]
/// renames it into place; dropping it removes it, leaving the target as it was.
#[derive(Debug)]
pub struct PendingStore {
    temp: AtomicFile,
    remote: Option<RemoteTarget>,
    summary: StoreSummary,
}

/// A store written locally for object storage: `temp` is uploaded to `url`
/// at commit, over `version` only when it is given; the temporary file's
/// target is where it is kept when the upload is refused for a conflict.
#[derive(Debug)]
struct RemoteTarget {
    url: String,
    options: RemoteOptions,
    version: Option<String>,
}

impl StoreWriter {
    /// Starts a store that will replace `path` when committed. An address
    /// on object storage (`s3://bucket/key`, reached as
    /// [`RemoteOptions::from_env`] says) is written to a local file first
    /// and put there at commit ([`crate::remote`]).
    pub fn create(path: &Path, options: WriteOptions) -> Result<Self, StoreError> {
        Self::create_with(path, options, &RemoteOptions::from_env())
    }

    /// [`StoreWriter::create`], reaching object storage as `remote` says.
    pub fn create_with(
        path: &Path,
        options: WriteOptions,
        remote: &RemoteOptions,
    ) -> Result<Self, StoreError> {
        let io = |source| StoreError::Io {
            path: path.to_owned(),
            source,
        };
        let remote = is_remote(path).then(|| RemoteTarget {
            url: path.to_string_lossy().into_owned(),
            options: remote.clone(),
            version: None,
        });
        let local = match &remote {
            Some(r) => spool_path(&r.url, &r.options).map_err(io)?,
            None => path.to_owned(),
        };
        let mut temp = AtomicFile::create(&local).map_err(io)?;
        let file = temp.file().try_clone().map_err(io)?;
        let mut file = BufWriter::with_capacity(1 << 20, file);
        // The header is written last, when the table's place is known.
        file.write_all(&[0; HEADER_LEN as usize]).map_err(io)?;
        Ok(Self {
            target: path.to_owned(),
            temp,
            remote,
            file,
            offset: HEADER_LEN,
            toc: Vec::new(),
            shapes: Vec::new(),
            blob_sets: [(false, 0); 2],
            pending: Vec::new(),
            pending_triangles: 0,
            options,
            summary: StoreSummary::default(),
        })
    }

    fn io(&self, source: std::io::Error) -> StoreError {
        StoreError::Io {
            path: self.temp.temp_path().to_owned(),
            source,
        }
    }

    /// Appends one segment made of `pieces`, each zero padded to the alignment
    /// (the segment's length counts the padding between pieces, not after the
    /// last); returns its entry.
    fn segment(&mut self, id: u32, kind: u32, pieces: &[&[u8]]) -> Result<TocEntry, StoreError> {
        let padding = [0u8; ALIGN as usize];
        let mut hash = Xxh3::new();
        let (mut length, mut last_pad) = (0, 0);
        for piece in pieces {
            let pad = &padding[..(piece.len().next_multiple_of(ALIGN as usize) - piece.len())];
            last_pad = pad.len() as u64;
            hash.update(piece);
            hash.update(pad);
            self.file
                .write_all(piece)
                .and_then(|()| self.file.write_all(pad))
                .map_err(|e| self.io(e))?;
            length += (piece.len() + pad.len()) as u64;
        }
        let entry = TocEntry {
            id,
            kind,
            offset: self.offset,
            length: length - last_pad,
            checksum: hash.digest(),
        };
        self.offset += entry.padded_len();
        self.toc.push(entry);
        Ok(entry)
    }

    /// Appends the geometry of the next chunks (chunk ids follow the write
    /// order), each with its box and its levels: those it lends, else
    /// computed. Encoded in parallel.
    fn chunks(&mut self, chunks: &[(ChunkGeometry<'_>, &Aabb3f)]) -> Result<(), StoreError> {
        let quantize = self.options.quantize;
        let encoded: Vec<Vec<u8>> = chunks
            .par_iter()
            .map(|(g, bounds)| match g.levels {
                Some(levels) => geometry::encode(g, levels, bounds, quantize),
                None => geometry::encode(g, &dmu_scene::lod_levels(g), bounds, quantize),
            })
            .collect();
        for ((g, _), bytes) in chunks.iter().zip(encoded) {
            self.chunk_segment(&bytes, g.positions.len() as u32, g.triangle_count() as u32)?;
        }
        Ok(())
    }

    /// Appends an encoded chunk segment of the given shape.
    pub(crate) fn chunk_segment(
        &mut self,
        bytes: &[u8],
        vertices: u32,
        triangles: u32,
    ) -> Result<(), StoreError> {
        let id = u32::try_from(self.shapes.len()).expect("over 4G chunks");
        let entry = self.segment(id, KIND_CHUNK, &[bytes])?;
        self.shapes.push((vertices, triangles));
        self.summary.chunks += 1;
        self.summary.geometry_file_bytes += entry.padded_len();
        self.summary.geometry_resident_bytes +=
            resident_bytes(u64::from(vertices), u64::from(triangles), true);
        Ok(())
    }

    /// Appends a mesh's chunks; they get the next chunk ids, which must be the
    /// ids they have in the skeleton given to [`StoreWriter::finish`]. Held
    /// until the meshes given reach `BATCH_TRIANGLES`, so their levels are
    /// computed in parallel even when each mesh is a chunk or two.
    pub fn add_mesh(&mut self, mesh: ChunkedMesh) -> Result<(), StoreError> {
        self.pending_triangles += mesh.indices.len() / 3;
        self.pending.push(mesh);
        if self.pending_triangles >= BATCH_TRIANGLES {
            self.write_pending()?;
        }
        Ok(())
    }

    /// Writes the chunks of the meshes held by [`StoreWriter::add_mesh`].
    fn write_pending(&mut self) -> Result<(), StoreError> {
        let meshes = std::mem::take(&mut self.pending);
        self.pending_triangles = 0;
        let chunks: Vec<_> = meshes
            .iter()
            .flat_map(|mesh| {
                mesh.chunks.iter().map(|c| {
                    let g = ChunkGeometry::slice(
                        &mesh.positions,
                        &mesh.normals,
                        &mesh.indices,
                        &c.vertices,
                        &c.triangles,
                    );
                    (g, &c.bounds)
                })
            })
            .collect();
        self.chunks(&chunks)
    }

    /// Appends the index of blob set `set` (opaque bytes), before or after
    /// its blobs.
    ///
    /// # Panics
    /// When the set's index was written already.
    pub(crate) fn blob_index(&mut self, set: BlobSet, bytes: &[u8]) -> Result<(), StoreError> {
        assert!(
            !self.blob_sets[set as usize].0,
            "a second {}",
            set.index_name()
        );
        self.segment(0, set.kinds().0, &[bytes])?;
        self.blob_sets[set as usize].0 = true;
        Ok(())
    }

    /// Appends the next blob of `set` (numbers follow the write order) and
    /// gives its number.
    pub(crate) fn blob(&mut self, set: BlobSet, bytes: &[u8]) -> Result<u32, StoreError> {
        let number = self.blob_sets[set as usize].1;
        self.segment(number, set.kinds().1, &[bytes])?;
        self.blob_sets[set as usize].1 = number
            .checked_add(1)
            .unwrap_or_else(|| panic!("over 4G {} blobs", set.blob_name()));
        Ok(number)
    }

    /// Starts the rewrite of `store` at its path: on object storage, reached
    /// as `store` was, and conditional on `version` (the one read), so a
    /// save over someone else's is refused ([`StoreError::RemoteConflict`]).
    pub(crate) fn replacing(store: &Store, version: Option<&str>) -> Result<Self, StoreError> {
        let remote = store
            .remote_options()
            .cloned()
            .unwrap_or_else(RemoteOptions::from_env);
        let mut writer = Self::create_with(store.path(), WriteOptions::default(), &remote)?;
        if let Some(remote) = &mut writer.remote {
            remote.version = version.map(str::to_owned);
        }
        Ok(writer)
    }

    /// Chunks given so far (written, or held to be encoded with the next).
    pub fn chunks_written(&self) -> usize {
        self.shapes.len() + self.pending.iter().map(|m| m.chunks.len()).sum::<usize>()
    }

    /// Writes the skeleton (`structure`: the scene's nodes, transforms, parts
    /// and chunk tables) and the table of contents, and syncs the file; nothing
    /// is in place until [`PendingStore::commit`].
    ///
    /// # Panics
    /// When the chunks written are not those of the structure's chunk table.
    pub fn finish(mut self, structure: &Structure) -> Result<PendingStore, StoreError> {
        self.write_pending()?;
        let written = self.shapes.len() == structure.chunks.len()
            && self
                .shapes
                .iter()
                .zip(&structure.chunks)
                .all(|(&shape, c)| shape == (c.vertices, c.triangles));
        assert!(
            written,
            "the chunks written ({}) are not the structure's ({})",
            self.shapes.len(),
            structure.chunks.len()
        );
        let (counts, arrays) = skeleton::pieces(structure);
        let mut pieces = vec![&counts[..]];
        pieces.extend(arrays);
        let properties = &structure.properties;
        let properties = (!properties.is_empty()).then(|| properties.to_bytes());
        self.finish_with_skeleton(&pieces, properties.as_deref())
    }

    /// [`StoreWriter::finish`] with a skeleton segment and properties copied
    /// from another store (verified, as they were there), whose chunks are
    /// the ones written.
    pub(crate) fn finish_copied(
        self,
        skeleton: &[u8],
        properties: Option<&[u8]>,
    ) -> Result<PendingStore, StoreError> {
        self.finish_with_skeleton(&[skeleton], properties)
    }

    /// Writes the skeleton segment made of `pieces`, the properties segment
    /// when there is one, the table of contents and the header, and syncs
    /// the file.
    ///
    /// # Panics
    /// When a blob set has blobs but no index.
    fn finish_with_skeleton(
        mut self,
        pieces: &[&[u8]],
        properties: Option<&[u8]>,
    ) -> Result<PendingStore, StoreError> {
        if let Some(bytes) = properties {
            self.segment(0, KIND_PROPERTIES, &[bytes])?;
        }
        for (set, &(index, blobs)) in BlobSet::ALL.iter().zip(&self.blob_sets) {
            assert!(
                index || blobs == 0,
                "{} blobs but no index",
                set.blob_name()
            );
        }
        let entry = self.segment(0, KIND_SKELETON, pieces)?;
        self.summary.skeleton_bytes = entry.length;
        let toc_offset = self.offset;
        let toc = std::mem::take(&mut self.toc);
        let header = Header::new(toc_offset, &toc);
        let result = (|| {
            self.file.write_all(bytemuck::cast_slice(&toc))?;
            self.file.flush()?;
            let file = self.file.get_mut();
            file.seek(SeekFrom::Start(0))?;
            file.write_all(bytemuck::bytes_of(&header))?;
            file.sync_all()
        })();
        result.map_err(|e| self.io(e))?;
        self.summary.path = self.target.clone();
        self.summary.file_bytes = toc_offset + std::mem::size_of_val(toc.as_slice()) as u64;
        Ok(PendingStore {
            temp: self.temp,
            remote: self.remote,
            summary: self.summary,
        })
    }
}

impl PendingStore {
    /// The temporary file holding the finished store.
    pub fn temp_path(&self) -> &Path {
        self.temp.temp_path()
    }

    /// Renames the store into place (atomic on one file system) and syncs the
    /// directory so the rename survives a power cut. A store for object
    /// storage is uploaded instead; when that meets a conflict
    /// ([`StoreError::RemoteConflict`]) it is kept in a local file.
    pub fn commit(self) -> Result<StoreSummary, StoreError> {
        let Some(remote) = self.remote else {
            let target = self.temp.target().to_owned();
            self.temp.commit().map_err(|source| StoreError::Io {
                path: target,
                source,
            })?;
            return Ok(self.summary);
        };
        let path = self.summary.path.clone();
        match upload::upload(
            &remote.url,
            &remote.options,
            self.temp.temp_path(),
            remote.version.as_deref(),
        ) {
            Ok(version) => Ok(StoreSummary {
                version,
                ..self.summary
            }),
            Err(upload::UploadError::Conflict) => {
                let kept = self.temp.target().to_owned();
                self.temp.commit().map_err(|source| StoreError::Io {
                    path: kept.clone(),
                    source,
                })?;
                Err(StoreError::RemoteConflict { path, kept })
            }
            Err(upload::UploadError::Failed(source)) => Err(StoreError::Io { path, source }),
        }
    }
}

/// Writes a whole in-memory scene as a store at `path` (replacing any file).
///
/// # Panics
/// When the scene's geometry is not loaded.
pub fn write_scene(
    scene: &Scene,
    path: &Path,
    options: WriteOptions,
) -> Result<StoreSummary, StoreError> {
    assert!(
        scene.meshes().iter().all(dmu_scene::Mesh::is_loaded),
        "write_scene needs the geometry loaded"
    );
    let mut writer = StoreWriter::create(path, options)?;
    let chunks = scene.chunks();
    for batch in batches(chunks.iter().map(|c| c.triangle_count() as usize)) {
        let batch: Vec<_> = chunks[batch]
            .iter()
            .map(|c| {
                let g = scene.mesh(c.mesh).chunk_geometry(c);
                (g.expect("asserted loaded above"), &c.bounds)
            })
            .collect();
        writer.chunks(&batch)?;
    }
    writer.finish(&Structure::of(scene))?.commit()
}
