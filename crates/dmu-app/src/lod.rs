//! A store's level-of-detail hierarchy (issue 42): merged, simplified
//! proxies of the tree's upper nodes, made at import or by `dmu lod build`
//! and kept in the store as a blob set ([`dmu_store::BlobSet::Lod`]), then
//! read on demand by the renderer ([`stored_proxies`]).
//!
//! The build reads the store's chunks a batch at a time within a byte budget
//! ([`StoreChunks`]) and streams each proxy into the rewritten store as it is
//! made ([`dmu_render::build_stored`]), so a model larger than memory is
//! built within `--memory-budget`.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use dmu_render::{ChunkLoader, GeometrySource, ProxyBlobs, ProxyOptions};
use dmu_scene::{ChunkGeometry, ChunkId};
use dmu_store::{BlobSet, BlobWriter, OwnedChunkGeometry, Store};
use dmu_tree::{Tree, TreeOptions};
use serde::Serialize;

/// The chunks of a store loaded for a build, within a byte budget.
#[derive(Debug)]
pub struct StoreChunks<'a> {
    store: &'a Store,
    loaded: HashMap<ChunkId, OwnedChunkGeometry>,
    bytes: u64,
    budget: u64,
    /// Chunk reads made (a chunk read again after being dropped counts again).
    pub reads: u64,
}

impl<'a> StoreChunks<'a> {
    /// Reads from `store`, holding at most about `budget` bytes between
    /// batches.
    pub fn new(store: &'a Store, budget: u64) -> Self {
        Self {
            store,
            loaded: HashMap::new(),
            bytes: 0,
            budget,
            reads: 0,
        }
    }
}

impl GeometrySource for StoreChunks<'_> {
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>> {
        self.loaded.get(&chunk).map(OwnedChunkGeometry::geometry)
    }
}

impl ChunkLoader for StoreChunks<'_> {
    fn load(&mut self, chunks: &[ChunkId]) -> Result<(), String> {
        if self.bytes > self.budget {
            let keep: std::collections::HashSet<ChunkId> = chunks.iter().copied().collect();
            self.loaded.retain(|c, _| keep.contains(c));
            self.bytes = self.loaded.values().map(|g| g.resident_bytes()).sum();
        }
        let missing: Vec<ChunkId> = chunks
            .iter()
            .copied()
            .filter(|c| !self.loaded.contains_key(c))
            .collect();
        use rayon::prelude::*;
        let read: Vec<(ChunkId, OwnedChunkGeometry)> = missing
            .par_iter()
            .map(|&c| self.store.chunk_geometry(c).map(|g| (c, g)))
            .collect::<Result<_, _>>()
            .map_err(|e| e.to_string())?;
        self.reads += read.len() as u64;
        for (c, g) in read {
            self.bytes += g.resident_bytes();
            self.loaded.insert(c, g);
        }
        Ok(())
    }

    fn source(&self) -> &(dyn GeometrySource + Sync) {
        self
    }
}

/// What a hierarchy build did.
#[derive(Clone, Debug, Serialize)]
pub struct LodBuildReport {
    /// Proxies stored.
    pub nodes: u64,
    /// Their triangles.
    pub triangles: u64,
    /// Bytes they take in the store.
    pub stored_bytes: u64,
    /// Nodes left without a proxy (a chunk that could not be read).
    pub missing: u64,
    /// The most proxies held at once.
    pub peak_held: usize,
    /// Chunk reads made.
    pub chunk_reads: u64,
    /// Seconds the build took (reading, merging, writing, syncing).
    pub seconds: f64,
}

/// Proxies a build makes at a time in parallel, at the lowest level.
const BATCH: usize = 64;

/// Builds the level-of-detail hierarchy of the store at `path` and rewrites
/// it with the hierarchy (replacing any it had), reading chunks within about
/// `chunk_budget` bytes; `progress` is told (nodes done, nodes).
pub fn build(
    path: &Path,
    chunk_budget: u64,
    options: ProxyOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<LodBuildReport> {
    let start = Instant::now();
    let mut store = Store::open(path)?;
    let scene = store.take_skeleton();
    let tree = Tree::build(&scene, TreeOptions::default());
    let mut writer = BlobWriter::new(&store, BlobSet::Lod)?;
    let mut chunks = StoreChunks::new(&store, chunk_budget);
    let mut sink = |bytes: &[u8]| writer.push(bytes).map_err(|e| e.to_string());
    let built = dmu_render::build_stored(
        &scene,
        &tree,
        &mut chunks,
        options,
        BATCH,
        &mut sink,
        progress,
    )
    .map_err(anyhow::Error::msg)
    .with_context(|| format!("{}: building the level-of-detail hierarchy", path.display()))?;
    let chunk_reads = chunks.reads;
    drop(chunks);
    writer.finish(&built.index)?.commit()?;
    Ok(LodBuildReport {
        nodes: built.stats.proxies,
        triangles: built.stats.triangles,
        stored_bytes: built.stats.bytes,
        missing: built.missing,
        peak_held: built.peak_held,
        chunk_reads,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// A store's level-of-detail blobs, for the renderer.
#[derive(Debug)]
struct StoreBlobs(Arc<Store>);

impl ProxyBlobs for StoreBlobs {
    fn blob(&self, blob: u32) -> Result<Vec<u8>, String> {
        self.0.blob(BlobSet::Lod, blob).map_err(|e| e.to_string())
    }
}

/// The share of a memory budget loaded stored proxies may take: a
/// thirty-second (32 MiB of 1 GiB, their geometry on the GPU: about 800 of
/// the mended 500M plant's proxies, which average 1,300 triangles; its
/// overview at 1 px asks for more, and draws coarser where they do not
/// fit: `FrameStats::lod_coarse`).
pub fn proxy_budget(memory_budget: u64) -> u64 {
    memory_budget / 32
}

/// Time a frame may spend loading stored proxies (at least one is loaded).
pub const LOAD_BUDGET: Duration = Duration::from_millis(8);

/// Hands `proxies` to `renderer` and, where they are a store's, gives the
/// cut its loader's wanted set stops at for views drawn at `lod_error_px`
/// (the nodes whose stored proxies fit: the chunks below are not drawn).
pub fn use_proxies(
    renderer: &mut dmu_render::Renderer,
    proxies: dmu_render::Proxies,
    scene: &dmu_scene::Scene,
    tree: &Tree,
    lod_error_px: f64,
) -> Option<Arc<dmu_store::LodCut>> {
    renderer.set_proxies(proxies);
    let slots = renderer.stored_proxy_slots(scene, tree);
    (!slots.is_empty()).then(|| Arc::new(dmu_store::LodCut::new(slots, lod_error_px)))
}

/// The store's stored proxies, read on demand within `budget` bytes
/// (`None` when it has no hierarchy: a one-line hint says how to add one).
pub fn stored_proxies(
    store: &Arc<Store>,
    budget: u64,
) -> anyhow::Result<Option<dmu_render::Proxies>> {
    let Some(index) = store.blob_index(BlobSet::Lod)? else {
        eprintln!(
            "note: {} has no level-of-detail hierarchy; `dmu lod build {}` adds one (faster overviews)",
            store.path().display(),
            store.path().display()
        );
        return Ok(None);
    };
    let proxies = dmu_render::Proxies::stored(
        &index,
        Box::new(StoreBlobs(store.clone())),
        budget,
        LOAD_BUDGET,
    )
    .map_err(anyhow::Error::msg)
    .with_context(|| format!("{}: the level-of-detail index", store.path().display()))?;
    Ok(Some(proxies))
}
