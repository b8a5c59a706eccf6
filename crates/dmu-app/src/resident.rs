//! The bridge from a store's residency manager to the renderer: chunk geometry
//! streamed from disk, drawn as it arrives.

use std::sync::{Arc, OnceLock};

use dmu_render::{ChunkGeometry, GeometrySource};
use dmu_scene::ChunkId;
use dmu_store::Residency;

/// Chunk geometry for one frame from a residency manager: each chunk the
/// renderer asks for is looked up once (resident or not) and pinned until
/// this source is dropped, so a chunk evicted while the frame is drawn stays
/// valid for it.
///
/// Make one per frame, after handing the renderer's geometry pool the chunks
/// the residency evicted (`Residency::take_evicted`, then
/// `GeometryPool::evict`); chunks not resident are `None`, which the renderer
/// skips for the frame and counts as not resident.
#[derive(Debug)]
pub struct ResidentSource<'a> {
    residency: &'a Residency,
    pins: Vec<OnceLock<Option<Arc<dmu_store::ChunkGeometry>>>>,
}

impl<'a> ResidentSource<'a> {
    /// A source over `residency` for a scene of `chunks` chunks (the store's
    /// `skeleton().chunks().len()`).
    pub fn new(residency: &'a Residency, chunks: usize) -> Self {
        Self {
            residency,
            pins: (0..chunks).map(|_| OnceLock::new()).collect(),
        }
    }
}

impl GeometrySource for ResidentSource<'_> {
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>> {
        let g = self
            .pins
            .get(chunk.index())?
            .get_or_init(|| self.residency.get(chunk))
            .as_ref()?;
        Some(ChunkGeometry {
            positions: &g.positions,
            normals: &g.normals,
            indices: &g.indices,
        })
    }
}
