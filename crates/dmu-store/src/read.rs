//! Reading a store: the file is memory-mapped; the header, the table of contents
//! and the skeleton are checked at open, each chunk's geometry segment when
//! first touched.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use dmu_scene::{ChunkId, Scene};
use memmap2::Mmap;

use crate::error::StoreError;
use crate::format::{self, FORMAT_VERSION, Layout, TocEntry};
use crate::geometry::{self, ChunkGeometry, resident_bytes};
use crate::skeleton;

/// An open store: the skeleton in memory, geometry on disk until asked for.
///
/// The file is mapped, not read: geometry costs memory only while a chunk is
/// decoded. Stores are never modified in place (writes go to a new file that is
/// renamed over the old one), so the mapping stays valid; an open store keeps
/// reading the file it opened even after a save replaced it.
#[derive(Debug)]
pub struct Store {
    path: PathBuf,
    map: Mmap,
    layout: Layout,
    /// Per chunk: its segment's checksum has been verified.
    verified: Vec<AtomicBool>,
    skeleton: Scene,
}

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
}

#[expect(
    unsafe_code,
    reason = "memmap2 cannot promise the file is not changed while mapped; stores \
              are only ever replaced by rename, never written in place"
)]
fn map_file(file: &File) -> std::io::Result<Mmap> {
    // SAFETY: see the reason above.
    unsafe { Mmap::map(file) }
}

impl Store {
    /// Opens a store, checking its header, table of contents and skeleton.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        let io = |source| StoreError::Io {
            path: path.to_owned(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let map = map_file(&file).map_err(io)?;
        let layout = format::parse(&map, path)?;
        let bytes = format::verified(&map, &layout.skeleton, || "the skeleton".into(), path)?;
        let corrupt = |what: String| StoreError::Corrupt {
            path: path.to_owned(),
            what,
        };
        let skeleton = skeleton::decode(bytes).map_err(corrupt)?;
        if skeleton.chunks().len() != layout.chunks.len() {
            return Err(corrupt(format!(
                "the skeleton has {} chunks, the table of contents {}",
                skeleton.chunks().len(),
                layout.chunks.len()
            )));
        }
        let verified = (0..layout.chunks.len())
            .map(|_| AtomicBool::new(false))
            .collect();
        Ok(Store {
            path: path.to_owned(),
            map,
            layout,
            verified,
            skeleton,
        })
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

    /// Sizes.
    pub fn info(&self) -> StoreInfo {
        let chunks = &self.layout.chunks;
        StoreInfo {
            version: FORMAT_VERSION,
            file_bytes: self.map.len() as u64,
            chunks: chunks.len() as u64,
            geometry_file_bytes: chunks.iter().map(TocEntry::padded_len).sum(),
            geometry_resident_bytes: (0..chunks.len())
                .map(|c| self.chunk_resident_bytes(ChunkId::from_index(c)))
                .sum(),
            skeleton_bytes: self.layout.skeleton.length,
        }
    }

    /// Bytes a chunk's segment takes in the file: what loading it reads.
    pub fn chunk_file_bytes(&self, chunk: ChunkId) -> u64 {
        self.layout.chunks[chunk.index()].padded_len()
    }

    /// Bytes a chunk takes decoded: what it costs in a residency budget.
    pub fn chunk_resident_bytes(&self, chunk: ChunkId) -> u64 {
        let c = self.skeleton.chunk(chunk);
        resident_bytes(
            u64::from(c.vertices.end - c.vertices.start),
            u64::from(c.triangle_count()),
        )
    }

    /// Reads and decodes a chunk's geometry, verifying its segment's checksum the
    /// first time.
    ///
    /// # Panics
    /// When `chunk` is not a chunk of this store.
    pub fn chunk_geometry(&self, chunk: ChunkId) -> Result<ChunkGeometry, StoreError> {
        let entry = &self.layout.chunks[chunk.index()];
        let verified = &self.verified[chunk.index()];
        let bytes = if verified.load(Ordering::Acquire) {
            format::payload(&self.map, entry)
        } else {
            let bytes =
                format::verified(&self.map, entry, || format!("chunk {chunk}"), &self.path)?;
            verified.store(true, Ordering::Release);
            bytes
        };
        let c = self.skeleton.chunk(chunk);
        geometry::decode(
            bytes,
            c.vertices.end - c.vertices.start,
            c.triangle_count(),
            &c.bounds,
        )
        .map_err(|what| StoreError::Corrupt {
            path: self.path.clone(),
            what: format!("chunk {chunk}: {what}"),
        })
    }

    /// A chunk's encoded segment, verified (for copying into a new store).
    pub(crate) fn chunk_segment(&self, chunk: ChunkId) -> Result<&[u8], StoreError> {
        let entry = &self.layout.chunks[chunk.index()];
        let bytes = format::verified(&self.map, entry, || format!("chunk {chunk}"), &self.path)?;
        self.verified[chunk.index()].store(true, Ordering::Release);
        Ok(bytes)
    }

    /// The whole scene with its geometry (every segment verified and decoded, in
    /// parallel).
    pub fn load_scene(&self) -> Result<Scene, StoreError> {
        skeleton::with_geometry(&self.skeleton, &|mesh| {
            self.skeleton
                .mesh(mesh)
                .chunk_ids()
                .map(|c| self.chunk_geometry(c))
                .collect()
        })
    }
}
