//! Proxies kept in a store (issue 42): made once, at import or by `dmu lod
//! build`, streamed into the file node by node, and read back on demand by a
//! renderer that holds only those its views need.
//!
//! A model larger than memory cannot have its proxies made at load time from
//! the whole scene, as [`Proxies::build`] does: every chunk would have to be
//! read. [`build_stored`] makes the same proxies in post-order, a batch of
//! the lowest level at a time in parallel (rayon) from the chunks a
//! [`ChunkLoader`] brings in for that batch, hands each to a sink as bytes
//! ([`encode`]) and drops it once its parent is made: what it holds is the
//! proxies still waiting for their parent, a few per level.
//!
//! A renderer given stored proxies ([`Proxies::stored`]) knows every node's
//! error and content signature from the index, so it can decide what fits
//! without the geometry; it asks for the proxies a frame wanted (coarse
//! first: the larger on screen for their bytes), loads them within a time
//! budget per frame and keeps them within a byte budget, least recently
//! drawn evicted first. A stored proxy whose signature no longer matches its
//! node (a part moved since it was made) is stale like any other: never
//! drawn, the frame refines past it.

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use bytemuck::{Pod, Zeroable};
use dmu_geom::Aabb3f;
use dmu_scene::{ChunkId, Scene};
use dmu_tree::Tree;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{Cluster, MAX_CLUSTERS, Proxies, Proxy, ProxyOptions, ProxyStats, ProxyVertex};
use crate::geometry::GeometrySource;
use crate::hierarchy::{Hierarchy, NodeKind};

/// The first bytes of a stored proxy.
const PROXY_MAGIC: [u8; 8] = *b"DMUPRXY1";
/// The first bytes of the stored index.
const INDEX_MAGIC: [u8; 8] = *b"DMULODX1";

/// A stored proxy's fixed part.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ProxyHeader {
    magic: [u8; 8],
    origin: [f64; 3],
    error: f64,
    signature: u64,
    source_triangles: u64,
    solid: u32,
    vertices: u32,
    indices: u32,
    clusters: u32,
}
const _: () = assert!(size_of::<ProxyHeader>() == 72);

/// A cluster as stored.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ClusterRecord {
    first_index: u32,
    index_count: u32,
    min: [f32; 3],
    max: [f32; 3],
}
const _: () = assert!(size_of::<ClusterRecord>() == 32);

/// The index's fixed part.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct IndexHeader {
    magic: [u8; 8],
    /// Mirror nodes of the hierarchy the proxies were made for.
    mirror_nodes: u64,
    /// [`ProxyOptions::error_fraction`] they were made with.
    error_fraction: f64,
    nodes: u64,
    /// The root's content signature: its proxy, once loaded, is never
    /// evicted (it is what a frame falls back to last).
    root: u64,
}

/// One node's entry in the stored index.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub(crate) struct StoredNode {
    /// Mirror node id.
    pub node: u32,
    /// Blob number in the store.
    pub blob: u32,
    /// The proxy's claimed error, world units.
    pub error: f64,
    /// The content it shows.
    pub signature: u64,
    /// Bytes it takes in memory once loaded (its geometry on the GPU;
    /// earlier builds counted its CPU copy too). The loader's priorities
    /// read it; its budget counts the proxy loaded.
    pub bytes: u64,
}
const _: () = assert!(size_of::<StoredNode>() == 32);

/// A proxy as bytes.
pub(crate) fn encode(p: &Proxy) -> Vec<u8> {
    let header = ProxyHeader {
        magic: PROXY_MAGIC,
        origin: p.origin.to_array(),
        error: p.error,
        signature: p.signature,
        source_triangles: p.source_triangles,
        solid: u32::from(p.solid),
        vertices: p.vertices.len() as u32,
        indices: p.indices.len() as u32,
        clusters: p.clusters.len() as u32,
    };
    let clusters: Vec<ClusterRecord> = p
        .clusters
        .iter()
        .map(|c| ClusterRecord {
            first_index: c.first_index,
            index_count: c.index_count,
            min: c.bounds.min.to_array(),
            max: c.bounds.max.to_array(),
        })
        .collect();
    let mut out = Vec::with_capacity(
        size_of::<ProxyHeader>()
            + size_of_val(clusters.as_slice())
            + size_of_val(p.vertices.as_slice())
            + size_of_val(p.indices.as_slice()),
    );
    out.extend_from_slice(bytemuck::bytes_of(&header));
    out.extend_from_slice(bytemuck::cast_slice(&clusters));
    out.extend_from_slice(bytemuck::cast_slice(&p.vertices));
    out.extend_from_slice(bytemuck::cast_slice(&p.indices));
    out
}

/// Reads `n` records of `T` at `*at`, advancing it.
fn take<T: Pod>(bytes: &[u8], at: &mut usize, n: usize, what: &str) -> Result<Vec<T>, String> {
    let len = n
        .checked_mul(size_of::<T>())
        .filter(|&len| len <= bytes.len() - *at)
        .ok_or_else(|| format!("{n} {what} run past the end ({} bytes)", bytes.len()))?;
    let out = bytes[*at..*at + len]
        .chunks_exact(size_of::<T>())
        .map(bytemuck::pod_read_unaligned)
        .collect();
    *at += len;
    Ok(out)
}

/// A stored proxy read back, every count and index checked: an error says
/// what is wrong, in a few words.
pub(crate) fn decode(bytes: &[u8]) -> Result<Proxy, String> {
    let mut at = 0;
    let header: ProxyHeader = take(bytes, &mut at, 1, "headers")?[0];
    if header.magic != PROXY_MAGIC {
        return Err("not a stored proxy".into());
    }
    let origin = DVec3::from_array(header.origin);
    if !origin.is_finite() || !header.error.is_finite() || header.error < 0.0 {
        return Err("its origin or error is not finite".into());
    }
    if header.clusters as usize > MAX_CLUSTERS {
        return Err(format!(
            "{} clusters (at most {MAX_CLUSTERS})",
            header.clusters
        ));
    }
    let records: Vec<ClusterRecord> = take(bytes, &mut at, header.clusters as usize, "clusters")?;
    let vertices: Vec<ProxyVertex> = take(bytes, &mut at, header.vertices as usize, "vertices")?;
    let indices: Vec<u32> = take(bytes, &mut at, header.indices as usize, "indices")?;
    if at != bytes.len() {
        return Err(format!("{} bytes after its indices", bytes.len() - at));
    }
    if !indices.len().is_multiple_of(3) {
        return Err(format!("{} indices, not whole triangles", indices.len()));
    }
    if let Some(i) = indices.iter().find(|&&i| i as usize >= vertices.len()) {
        return Err(format!("index {i} of {} vertices", vertices.len()));
    }
    if vertices
        .iter()
        .any(|v| !Vec3::from(v.position).is_finite() || !Vec3::from(v.base).is_finite())
    {
        return Err("a vertex is not finite".into());
    }
    let mut next = 0u32;
    let clusters = records
        .iter()
        .map(|r| {
            let end = r.first_index.checked_add(r.index_count);
            if r.first_index != next || end.is_none_or(|e| e as usize > indices.len()) {
                return Err(format!(
                    "cluster of indices {}+{} does not follow the last",
                    r.first_index, r.index_count
                ));
            }
            next = r.first_index + r.index_count;
            Ok(Cluster {
                first_index: r.first_index,
                index_count: r.index_count,
                bounds: Aabb3f {
                    min: Vec3::from(r.min),
                    max: Vec3::from(r.max),
                },
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    if !clusters.is_empty() && next as usize != indices.len() {
        return Err("its clusters do not cover its indices".into());
    }
    Ok(Proxy::new(
        origin,
        vertices,
        indices,
        header.error,
        header.signature,
        header.source_triangles,
        header.solid != 0,
        clusters,
    ))
}

/// Bytes a loaded stored proxy takes: its geometry on the GPU (the CPU
/// copy is dropped once uploaded, within the frame that loads it).
fn resident_bytes(p: &Proxy) -> u64 {
    p.geometry_bytes()
}

/// Brings in the chunk geometry a stored build needs, a batch at a time.
pub trait ChunkLoader {
    /// Makes `chunks` available from [`ChunkLoader::source`]; chunks loaded
    /// for earlier batches may be dropped.
    fn load(&mut self, chunks: &[ChunkId]) -> Result<(), String>;
    /// The chunks loaded.
    fn source(&self) -> &(dyn GeometrySource + Sync);
}

/// What [`build_stored`] made.
#[derive(Clone, Debug, Default)]
pub struct StoredBuild {
    /// The index to store beside the blobs ([`Proxies::stored`] reads it).
    pub index: Vec<u8>,
    /// Proxies made, their triangles, bytes stored, and the time it took.
    pub stats: ProxyStats,
    /// Nodes with no proxy (a chunk the loader could not give).
    pub missing: u64,
    /// The most proxies held at once.
    pub peak_held: usize,
}

/// Makes the proxies of every node of `tree` as [`Proxies::build`] does,
/// streamed: each goes to `sink` as bytes as soon as it is made (`sink`
/// gives its blob number), and is dropped once its parent level is made.
/// The lowest level is made `batch` nodes at a time in parallel, from chunks
/// `loader` brings in for the batch; `progress` is told (nodes done, nodes).
pub fn build_stored(
    scene: &Scene,
    tree: &Tree,
    loader: &mut dyn ChunkLoader,
    options: ProxyOptions,
    batch: usize,
    sink: &mut dyn FnMut(&[u8]) -> Result<u32, String>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<StoredBuild, String> {
    let start = Instant::now();
    let (h, mut proxies, order) = Proxies::to_make(scene, tree, options);
    let mut out = Emitter {
        h: &h,
        sink,
        index: Vec::new(),
        held: 0,
        build: StoredBuild::default(),
    };
    let mut pending: Vec<u32> = Vec::new();
    let total = order.len();
    for (done, &n) in order.iter().enumerate() {
        if below_levels(&proxies, &h, n).next().is_none() {
            pending.push(n);
            if pending.len() >= batch.max(1) {
                out.flush(&mut proxies, &mut pending, scene, tree, loader)?;
            }
        } else {
            out.flush(&mut proxies, &mut pending, scene, tree, loader)?;
            loader.load(&cell_chunks(&proxies, &h, tree, n))?;
            let made = proxies.make(&h, scene, tree, loader.source(), n);
            out.emit(&mut proxies, n, made)?;
        }
        if (done + 1) % 16 == 0 || done + 1 == total {
            progress(done + 1, total);
        }
    }
    out.flush(&mut proxies, &mut pending, scene, tree, loader)?;
    let header = IndexHeader {
        magic: INDEX_MAGIC,
        mirror_nodes: h.len() as u64,
        error_fraction: options.error_fraction,
        nodes: out.index.len() as u64,
        // 0 (no content) for an empty tree, which has no root to keep.
        root: proxies.signature.get(h.root as usize).copied().unwrap_or(0),
    };
    let mut build = out.build;
    build.index = bytemuck::bytes_of(&header).to_vec();
    build
        .index
        .extend_from_slice(bytemuck::cast_slice(&out.index));
    build.stats.made = build.stats.proxies;
    build.stats.ms = start.elapsed().as_secs_f64() * 1e3;
    Ok(build)
}

/// Where a stored build's proxies go.
struct Emitter<'a> {
    h: &'a Hierarchy,
    sink: &'a mut dyn FnMut(&[u8]) -> Result<u32, String>,
    index: Vec<StoredNode>,
    /// Proxies held now.
    held: usize,
    build: StoredBuild,
}

impl Emitter<'_> {
    /// Node `n`'s proxy is made (or could not be): out to the sink and into
    /// the index, held until its parent level is made; the level nodes it
    /// was made of are dropped.
    fn emit(&mut self, proxies: &mut Proxies, n: u32, made: Option<Proxy>) -> Result<(), String> {
        let below: Vec<u32> = below_levels(proxies, self.h, n).collect();
        for c in below {
            if proxies.nodes[c as usize].take().is_some() {
                self.held -= 1;
            }
        }
        let Some(p) = made else {
            self.build.missing += 1;
            return Ok(());
        };
        let bytes = encode(&p);
        let blob = (self.sink)(&bytes)?;
        self.index.push(StoredNode {
            node: n,
            blob,
            error: p.error,
            signature: p.signature,
            bytes: resident_bytes(&p),
        });
        let stats = &mut self.build.stats;
        stats.proxies += 1;
        stats.solid += u64::from(p.solid);
        stats.triangles += p.triangles();
        stats.bytes += bytes.len() as u64;
        proxies.nodes[n as usize] = Some(Box::new(p));
        self.held += 1;
        self.build.peak_held = self.build.peak_held.max(self.held);
        Ok(())
    }

    /// Makes the lowest-level nodes `pending` in parallel from the chunks
    /// `loader` brings in for them, and emits them.
    fn flush(
        &mut self,
        proxies: &mut Proxies,
        pending: &mut Vec<u32>,
        scene: &Scene,
        tree: &Tree,
        loader: &mut dyn ChunkLoader,
    ) -> Result<(), String> {
        if pending.is_empty() {
            return Ok(());
        }
        let mut chunks: Vec<ChunkId> = pending
            .iter()
            .flat_map(|&n| cell_chunks(proxies, self.h, tree, n))
            .collect();
        chunks.sort_unstable();
        chunks.dedup();
        loader.load(&chunks)?;
        let source = loader.source();
        let h = self.h;
        let made: Vec<Option<Proxy>> = pending
            .par_iter()
            .map(|&n| proxies.make(h, scene, tree, source, n))
            .collect();
        for (&n, p) in pending.iter().zip(made) {
            self.emit(proxies, n, p)?;
        }
        pending.clear();
        Ok(())
    }
}

/// The nearest level nodes below `n` (what its proxy is made of, with the
/// chunk instances of cells with no level between).
fn below_levels<'a>(
    proxies: &'a Proxies,
    h: &'a Hierarchy,
    n: u32,
) -> impl Iterator<Item = u32> + 'a {
    let mut stack: Vec<u32> = match h.kind(n) {
        NodeKind::Cell(_) => Vec::new(),
        _ => h.children(n).to_vec(),
    };
    std::iter::from_fn(move || {
        while let Some(c) = stack.pop() {
            if proxies.is_level(c) {
                return Some(c);
            }
            if let NodeKind::Internal = h.kind(c) {
                stack.extend_from_slice(h.children(c));
            }
        }
        None
    })
}

/// The chunks of the cells whose instances go into `n`'s proxy directly.
fn cell_chunks(proxies: &Proxies, h: &Hierarchy, tree: &Tree, n: u32) -> Vec<ChunkId> {
    let mut chunks = Vec::new();
    let mut stack = vec![n];
    while let Some(c) = stack.pop() {
        if c != n && proxies.is_level(c) {
            continue;
        }
        match h.kind(c) {
            NodeKind::Cell(_) => chunks.extend(
                h.children(c)
                    .iter()
                    .map(|&e| tree.entries()[e as usize].chunk),
            ),
            NodeKind::Internal => stack.extend_from_slice(h.children(c)),
            NodeKind::Entry(_) | NodeKind::Free => {}
        }
    }
    chunks
}

/// Reads stored proxies' bytes by blob number (the application's store).
pub trait ProxyBlobs: Send + Sync + std::fmt::Debug {
    /// Blob `blob`'s bytes, or why not (one line).
    fn blob(&self, blob: u32) -> Result<Vec<u8>, String>;
}

/// The stored side of [`Proxies`]: the index, the blobs, and what is loaded.
#[derive(Debug)]
pub(crate) struct Stored {
    /// By content signature: its entry in the index. Keyed by what a node
    /// holds, not by its number, since the tree's parallel build numbers its
    /// nodes differently from run to run; a node whose content was stored
    /// finds its proxy whatever its number.
    pub nodes: HashMap<u64, StoredNode>,
    blobs: Arc<dyn ProxyBlobs>,
    /// A thread reading and decoding proxies ahead of the frames that
    /// apply them ([`Proxies::load_in_background`]); without it frames
    /// read and decode them themselves.
    background: Option<Background>,
    /// Bytes loaded proxies may take.
    budget: u64,
    /// The root's content signature: its proxy is never evicted.
    root: u64,
    /// Bytes loaded proxies take.
    pub resident: u64,
    /// Nodes frames asked for since the last load, with their priority
    /// (screen size over bytes).
    pub requested: Mutex<Vec<(u32, f64)>>,
    /// Nodes frames drew since the last load.
    pub drawn: Mutex<Vec<u32>>,
    /// Per loaded mirror node: the load tick it was last drawn or loaded at.
    last_used: HashMap<u32, u64>,
    /// Loads run (a tick each).
    tick: u64,
    /// Time loads may take per frame (at least one is made when any is due).
    load_budget: Duration,
    /// Loaded, evicted and failed so far.
    pub loads: u64,
    pub evictions: u64,
    pub failures: u64,
    /// Loads refused (and loading stopped for the frame): what the last
    /// frame drew filled the budget.
    pub refused: u64,
}

/// Proxies read on another thread: jobs out, results back.
#[derive(Debug)]
struct Background {
    jobs: mpsc::Sender<(u32, StoredNode)>,
    done: Mutex<mpsc::Receiver<Fetched>>,
    /// Nodes sent and not yet back.
    in_flight: HashSet<u32>,
}

/// A proxy read for node `.0` from its entry `.1`, or why not.
type Fetched = (u32, StoredNode, Result<Proxy, String>);

/// Proxies the loading thread is asked for ahead of the frames.
const IN_FLIGHT: usize = 32;

impl Proxies {
    /// Stored proxies are read and decoded on a thread of their own from
    /// now on, as many as 32 (`IN_FLIGHT`) ahead, and a frame applies (makes
    /// room for, uploads) what came back within its load time; so loading
    /// is not bound by the frame's time. Without this (or if the thread
    /// cannot start) frames read them themselves, which is deterministic.
    pub fn load_in_background(&mut self) {
        let Some(s) = self.stored.as_mut() else {
            return;
        };
        if s.background.is_some() {
            return;
        }
        let (jobs, job_queue) = mpsc::channel::<(u32, StoredNode)>();
        let (results, done) = mpsc::channel();
        let blobs = Arc::clone(&s.blobs);
        let started = std::thread::Builder::new()
            .name("dmu proxy loader".into())
            .spawn(move || {
                for (n, entry) in job_queue {
                    let read = blobs.blob(entry.blob).and_then(|b| decode(&b));
                    if results.send((n, entry, read)).is_err() {
                        break;
                    }
                }
            });
        if started.is_ok() {
            s.background = Some(Background {
                jobs,
                done: Mutex::new(done),
                in_flight: HashSet::new(),
            });
        }
    }

    /// Proxies read on demand from a store: `index` as [`build_stored`]
    /// made it, `blobs` its blobs; loaded ones take at most `budget` bytes,
    /// loading at most `load_budget` a frame. An index that does not decode
    /// is an error of a few words.
    pub fn stored(
        index: &[u8],
        blobs: Box<dyn ProxyBlobs>,
        budget: u64,
        load_budget: Duration,
    ) -> Result<Self, String> {
        let mut at = 0;
        let header: IndexHeader = take(index, &mut at, 1, "index headers")?[0];
        if header.magic != INDEX_MAGIC {
            return Err("not a level-of-detail index".into());
        }
        let entries: Vec<StoredNode> = take(index, &mut at, header.nodes as usize, "nodes")?;
        if at != index.len() || header.mirror_nodes > u64::from(u32::MAX) {
            return Err("the index's size does not match its node count".into());
        }
        let mut nodes = HashMap::with_capacity(entries.len());
        for e in entries {
            if !e.error.is_finite() || e.error < 0.0 {
                return Err(format!("node {}'s error is damaged", e.node));
            }
            nodes.insert(e.signature, e);
        }
        Ok(Self {
            options: ProxyOptions {
                error_fraction: header.error_fraction,
                ..ProxyOptions::default()
            },
            stored: Some(Stored {
                last_used: HashMap::new(),
                nodes,
                blobs: Arc::from(blobs),
                background: None,
                budget,
                root: header.root,
                resident: 0,
                requested: Mutex::default(),
                drawn: Mutex::default(),
                tick: 0,
                load_budget,
                loads: 0,
                evictions: 0,
                failures: 0,
                refused: 0,
            }),
            ..Self::default()
        })
    }

    /// The tree nodes of `h` (their slots in the tree, for
    /// `dmu_store::LodCut`) that hold what a stored proxy shows, with its
    /// error, as of the last [`Proxies::sync`].
    pub(crate) fn stored_slots(&self, h: &Hierarchy, entries: usize) -> Vec<(u32, f64)> {
        (entries..h.len())
            .filter_map(|n| {
                let e = self.stored_entry(n as u32)?;
                Some(((n - entries) as u32, e.error))
            })
            .collect()
    }

    /// Node `n`'s entry in the stored index, when it holds what a stored
    /// proxy shows.
    fn stored_entry(&self, n: u32) -> Option<&StoredNode> {
        let signature = self.signature.get(n as usize)?;
        self.stored.as_ref()?.nodes.get(signature)
    }

    /// The error node `n`'s stored proxy claims, when it has a current one
    /// (loaded or not).
    pub(crate) fn stored_error(&self, n: u32) -> Option<f64> {
        self.stored_entry(n).map(|e| e.error)
    }

    /// Whether these are a store's proxies, loaded on demand.
    pub(crate) fn is_stored(&self) -> bool {
        self.stored.is_some()
    }

    /// A frame wants node `n`'s proxy, which is not loaded and covers
    /// `size_px` on screen: asked for by that size per byte, or, when
    /// `first` (no loaded proxy above stands in for it), ahead of all of
    /// those, the larger on screen first (the root before its children).
    pub(crate) fn request(&self, n: u32, size_px: f64, first: bool) {
        if let Some(s) = &self.stored
            && let Some(e) = self.stored_entry(n)
        {
            let priority = match first {
                true => 1e12 + size_px.min(1e11),
                false => size_px / (e.bytes.max(1) as f64),
            };
            s.requested
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push((n, priority));
        }
    }

    /// A frame drew node `n`'s proxy.
    pub(crate) fn used(&self, n: u32) {
        if let Some(s) = &self.stored {
            s.drawn
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push(n);
        }
    }

    /// Loads the proxies frames asked for, the highest priority first, within
    /// the time budget (at least one) and the byte budget: room is made by
    /// evicting the least recently drawn (never one drawn since the last
    /// load, nor the root's, the last fallback of every frame), and loading
    /// stops where what the last frame drew fills the budget (those nodes
    /// stay drawn coarser, `FrameStats::lod_coarse`). The root's loads
    /// whatever it takes, on top of the budget. With [`Proxies::load_in_background`] the proxies
    /// applied are those the thread read since, and the most wanted are
    /// sent to it. The nodes loaded or evicted go to `dirty`.
    pub(crate) fn load_requested(&mut self) {
        let Some(s) = self.stored.as_mut() else {
            return;
        };
        s.tick += 1;
        let tick = s.tick;
        let drawn = std::mem::take(s.drawn.get_mut().unwrap_or_else(|e| e.into_inner()));
        for &n in &drawn {
            s.last_used.insert(n, tick);
        }
        let mut requested =
            std::mem::take(s.requested.get_mut().unwrap_or_else(|e| e.into_inner()));
        requested.sort_unstable_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        requested.dedup_by_key(|r| r.0);
        let start = Instant::now();
        let wanted = requested.iter().filter_map(|&(n, _)| {
            let entry = *self
                .signature
                .get(n as usize)
                .and_then(|sig| s.nodes.get(sig))?;
            self.nodes
                .get(n as usize)
                .is_some_and(Option::is_none)
                .then_some((n, entry))
        });
        let fetched: Vec<Fetched> = match s.background.as_mut() {
            Some(b) => {
                for (n, entry) in wanted {
                    if b.in_flight.len() >= IN_FLIGHT {
                        break;
                    }
                    if b.in_flight.insert(n) && b.jobs.send((n, entry)).is_err() {
                        b.in_flight.remove(&n);
                    }
                }
                let done = b.done.get_mut().unwrap_or_else(|e| e.into_inner());
                let mut fetched = Vec::new();
                while fetched.is_empty() || start.elapsed() < s.load_budget {
                    let Ok(f) = done.try_recv() else {
                        break;
                    };
                    b.in_flight.remove(&f.0);
                    fetched.push(f);
                }
                fetched
            }
            None => {
                let mut fetched = Vec::new();
                for (n, entry) in wanted {
                    if !fetched.is_empty() && start.elapsed() >= s.load_budget {
                        break;
                    }
                    let read = s.blobs.blob(entry.blob).and_then(|b| decode(&b));
                    fetched.push((n, entry, read));
                }
                fetched
            }
        };
        for (n, entry, read) in fetched {
            let slot = n as usize;
            // Back from the thread for a node that changed, or loaded
            // meanwhile: not applied.
            if self.signature.get(slot) != Some(&entry.signature)
                || self.nodes.get(slot).is_none_or(Option::is_some)
            {
                continue;
            }
            let p = match read {
                Ok(p) => p,
                Err(e) => {
                    // Never asked for again: the node refines past it.
                    eprintln!("warning: level-of-detail node #{}: {e}", entry.blob);
                    s.nodes.remove(&entry.signature);
                    s.failures += 1;
                    continue;
                }
            };
            // Room is made by evicting what the last frame did not draw; where
            // that is not enough, what it drew fills the budget and loading
            // stops (the root's loads whatever it takes, on top of the
            // budget).
            let need = resident_bytes(&p);
            if entry.signature != s.root {
                evict(
                    s,
                    &mut self.nodes,
                    &mut self.dirty,
                    tick,
                    s.budget.saturating_sub(need),
                );
                if s.resident + need > s.budget {
                    s.refused += 1;
                    break;
                }
            }
            s.resident += need;
            s.last_used.insert(n, tick);
            self.nodes[slot] = Some(Box::new(p));
            self.dirty.push(n);
            s.loads += 1;
        }
        evict(s, &mut self.nodes, &mut self.dirty, tick, s.budget);
    }
}

/// Evicts loaded proxies, least recently drawn first, until those loaded
/// take at most `target` bytes or none is left that frames before load
/// tick `tick` alone drew (the root's never).
fn evict(
    s: &mut Stored,
    nodes: &mut [Option<Box<Proxy>>],
    dirty: &mut Vec<u32>,
    tick: u64,
    target: u64,
) {
    if s.resident <= target {
        return;
    }
    let is_root = |n: u32| {
        nodes
            .get(n as usize)
            .and_then(Option::as_ref)
            .is_some_and(|p| p.signature == s.root)
    };
    let mut loaded: Vec<(u64, u32)> = (s.last_used.iter())
        .filter(|&(&n, &at)| at < tick && !is_root(n))
        .map(|(&n, &at)| (at, n))
        .collect();
    loaded.sort_unstable();
    for (_, n) in loaded {
        if s.resident <= target {
            break;
        }
        s.last_used.remove(&n);
        if let Some(p) = nodes.get_mut(n as usize).and_then(Option::take) {
            s.resident -= resident_bytes(&p);
            dirty.push(n);
            s.evictions += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proxy::tests::plant_250k;
    use dmu_samples::Rng;

    /// The whole scene as a loader.
    struct InMemory<'a>(&'a Scene);

    impl ChunkLoader for InMemory<'_> {
        fn load(&mut self, _: &[ChunkId]) -> Result<(), String> {
            Ok(())
        }

        fn source(&self) -> &(dyn GeometrySource + Sync) {
            self.0
        }
    }

    fn stored(scene: &Scene, tree: &Tree, batch: usize) -> (StoredBuild, Vec<Vec<u8>>) {
        let mut blobs = Vec::new();
        let mut sink = |b: &[u8]| {
            blobs.push(b.to_vec());
            Ok(blobs.len() as u32 - 1)
        };
        let built = build_stored(
            scene,
            tree,
            &mut InMemory(scene),
            ProxyOptions::default(),
            batch,
            &mut sink,
            &mut |_, _| {},
        )
        .unwrap();
        (built, blobs)
    }

    /// A streamed build, batched and parallel, stores byte for byte the
    /// proxies the in-memory build makes (the oracle), holds a handful at
    /// a time, and its index gives each node's error and signature.
    #[test]
    fn a_stored_build_stores_what_the_in_memory_build_makes() {
        let (scene, tree) = plant_250k();
        let truth = Proxies::build(
            &scene,
            &tree,
            &scene,
            ProxyOptions::default(),
            &mut |_, _| {},
        );
        for batch in [1, 5, 64] {
            let (built, blobs) = stored(&scene, &tree, batch);
            assert_eq!(built.stats.proxies, truth.stats().proxies, "batch {batch}");
            assert_eq!(built.missing, 0);
            // At this size every level waits on few (10M: 927 proxies).
            assert!(
                built.peak_held < built.stats.proxies as usize,
                "batch {batch}: held {} of {}",
                built.peak_held,
                built.stats.proxies
            );
            let mut index = Proxies::stored(
                &built.index,
                Box::new(VecBlobs(blobs.clone())),
                u64::MAX,
                Duration::ZERO,
            )
            .unwrap();
            let stored = index.stored.take().unwrap();
            let mut seen = 0;
            for n in 0..truth.nodes.len() {
                let entry = stored.nodes.values().find(|e| e.node == n as u32);
                let want = truth.nodes[n].as_deref();
                match (entry, want) {
                    (Some(e), Some(t)) => {
                        let p = decode(&blobs[e.blob as usize]).unwrap();
                        assert_eq!(encode(&p), encode(t), "node {n}");
                        assert_eq!((e.error, e.signature), (t.error, t.signature));
                        seen += 1;
                    }
                    (None, None) => {}
                    _ => panic!("node {n}: stored {entry:?}, in memory {}", want.is_some()),
                }
            }
            assert_eq!(seen, truth.stats().proxies);
        }
    }

    /// Loaded stored proxies never take more than their budget, whatever
    /// frames ask for and draw, read by the frames or on the loading thread
    /// (the root's comes on top: it loads whatever it takes): loads past it
    /// first evict what the last frame did not draw, and are refused where
    /// that is not enough.
    #[test]
    fn loaded_proxies_keep_within_their_budget() {
        let (scene, tree) = plant_250k();
        let (built, blobs) = stored(&scene, &tree, 64);
        let mut h = Hierarchy::default();
        h.sync(&tree);
        let total: u64 = built.stats.bytes;
        let mut rng = Rng::new(7);
        for (budget, background) in [
            (total / 3, false),
            (total / 10, false),
            (total / 40, false),
            (total / 10, true),
        ] {
            let (mut p, stored_nodes) = synced(
                (&scene, &tree, &h),
                (&built, &blobs),
                budget,
                Duration::from_secs(1),
                background,
            );
            let root = p.stored_entry(h.root).map_or(0, |e| e.bytes);
            for frame in 0..30 {
                // A frame asks for a random half of the nodes and draws a
                // random half of those loaded.
                for &n in &stored_nodes {
                    if rng.range(0.0, 1.0) < 0.5 {
                        p.request(n, rng.range(1.0, 500.0), rng.range(0.0, 1.0) < 0.2);
                    }
                    if p.current(n).is_some() && rng.range(0.0, 1.0) < 0.5 {
                        p.used(n);
                    }
                }
                if background {
                    // Give the thread time to read some.
                    std::thread::sleep(Duration::from_millis(5));
                }
                p.load_requested();
                let s = p.stored.as_ref().unwrap();
                let loaded: u64 = p.nodes.iter().flatten().map(|q| resident_bytes(q)).sum();
                assert_eq!(loaded, s.resident, "frame {frame}");
                assert!(
                    s.resident <= budget.saturating_add(root),
                    "budget {budget}, frame {frame}: {} loaded",
                    s.resident
                );
            }
            let s = p.stored.as_ref().unwrap();
            println!(
                "budget {budget}: {} loads, {} refused, {} evicted",
                s.loads, s.refused, s.evictions
            );
            // The budget was reached: loads were refused.
            assert!(s.refused > 0, "budget {budget}");
        }
    }

    /// Proxies read on the loading thread land on the nodes that asked for
    /// them, each what its blob holds, until every one asked for is loaded.
    #[test]
    fn proxies_read_in_the_background_are_those_asked_for() {
        let (scene, tree) = plant_250k();
        let (built, blobs) = stored(&scene, &tree, 64);
        let mut h = Hierarchy::default();
        h.sync(&tree);
        let (mut p, wanted) = synced(
            (&scene, &tree, &h),
            (&built, &blobs),
            u64::MAX,
            Duration::ZERO,
            true,
        );
        assert!(p.stored.as_ref().unwrap().background.is_some());
        let mut frames = 0;
        while wanted.iter().any(|&n| p.current(n).is_none()) {
            for &n in &wanted {
                p.request(n, 100.0, false);
            }
            p.load_requested();
            frames += 1;
            assert!(frames < 10_000, "never all loaded");
            std::thread::sleep(Duration::from_millis(1));
        }
        for &n in &wanted {
            let entry = p.stored_entry(n).unwrap();
            let want = decode(&blobs[entry.blob as usize]).unwrap();
            assert_eq!(encode(p.current(n).unwrap()), encode(&want), "node {n}");
        }
        println!("{} proxies loaded in {frames} frames", wanted.len());
    }

    /// `built`'s proxies read from `blobs` within `budget` bytes and `load`
    /// a frame (on the loading thread where `background`), synced with the
    /// model, and the mirror nodes that have one.
    fn synced(
        (scene, tree, h): (&Scene, &Tree, &Hierarchy),
        (built, blobs): (&StoredBuild, &[Vec<u8>]),
        budget: u64,
        load: Duration,
        background: bool,
    ) -> (Proxies, Vec<u32>) {
        let mut p = Proxies::stored(
            &built.index,
            Box::new(VecBlobs(blobs.to_vec())),
            budget,
            load,
        )
        .unwrap();
        if background {
            p.load_in_background();
        }
        p.sync(h, scene, tree);
        let nodes = (0..h.len() as u32)
            .filter(|&n| p.stored_error(n).is_some())
            .collect();
        (p, nodes)
    }

    #[derive(Debug)]
    struct VecBlobs(Vec<Vec<u8>>);

    impl ProxyBlobs for VecBlobs {
        fn blob(&self, blob: u32) -> Result<Vec<u8>, String> {
            Ok(self.0[blob as usize].clone())
        }
    }

    /// A damaged stored proxy or index is an error of a few words, never a
    /// panic: crafted cases, then random byte flips and truncations.
    #[test]
    fn damaged_stored_proxies_are_refused() {
        let (scene, tree) = plant_250k();
        let (built, blobs) = stored(&scene, &tree, 8);
        let good = &blobs[blobs.len() - 1];
        let p = decode(good).unwrap();
        let header = size_of::<ProxyHeader>();
        let index_at = header
            + p.clusters.len() * size_of::<ClusterRecord>()
            + p.vertices.len() * size_of::<ProxyVertex>();
        let mut bad_index = good.clone();
        bad_index[index_at..index_at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let mut bad_magic = good.clone();
        bad_magic[0] ^= 1;
        let mut bad_cluster = good.clone();
        bad_cluster[header..header + 4].copy_from_slice(&7u32.to_le_bytes());
        for (bytes, needle) in [
            (&good[..good.len() - 1], "run past the end"),
            (&bad_index[..], "of"),
            (&bad_magic[..], "not a stored proxy"),
            (&bad_cluster[..], "does not follow"),
            (&[][..], "run past the end"),
        ] {
            let err = decode(bytes).unwrap_err();
            assert!(err.contains(needle), "{err}");
            assert!(!err.contains('\n'));
        }
        let mut rng = Rng::new(3);
        for _ in 0..2000 {
            let mut bytes = if rng.below(2) == 0 {
                good.clone()
            } else {
                built.index.clone()
            };
            let cut = rng.below(bytes.len() as u64 + 1) as usize;
            if rng.below(4) == 0 {
                bytes.truncate(cut);
            } else if let Some(b) = bytes.get_mut(cut) {
                *b ^= 1 << rng.below(8);
            }
            let _ = decode(&bytes);
            let _ = Proxies::stored(&bytes, Box::new(VecBlobs(Vec::new())), 0, Duration::ZERO);
        }
    }
}
