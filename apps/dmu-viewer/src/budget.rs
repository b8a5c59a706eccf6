//! The viewer under `--memory-budget`: the model is a store's skeleton, its
//! chunks stream in through the store's residency manager (the same
//! [`dmu_store::Streamer`] as `dmu walk`), and a chunk wanted but not yet
//! loaded is drawn as its box (a stand-in) unless stand-ins are off, when it
//! is a hole. The budget is the whole process's: what the skeleton, the tree,
//! the collision check's whole-part index (built at open) and the renderer
//! take once the first frame is drawn (with stand-ins only),
//! the tools' geometry cap, the stored proxies' share
//! ([`dmu_app::lod::proxy_budget`], when the store has a level-of-detail
//! hierarchy) and a frame reserve come off it, and the residency
//! gets half of the rest (the GPU pool holds a second copy of what is
//! resident; on lavapipe in the same memory).

use std::sync::Arc;

use dmu_app::resident::{FrameSource, StreamedFrames};
use dmu_render::{Camera, GeometryPool};
use dmu_scene::{ChunkId, Scene};
use dmu_store::{
    CameraFrame, LoadOrder, LodCut, Pacing, PrefetchOptions, ResidencyOptions, Store, Streamer,
    View, Viewport,
};
use dmu_tree::{EntryId, Tree};
use serde::Serialize;
use serde_json::Value;

use crate::app::to_value;

/// The coverage threshold under a memory budget unless `--min-pixels` says
/// otherwise, pixels (box diagonal).
pub const MIN_PIXELS: f64 = 2.0;

/// Bytes kept for what the process takes beyond the first frame's peak
/// and the geometry: later frames' transient memory (the window, egui,
/// command buffers, lavapipe's binning of close-up views), the GPU pool's
/// simplified levels and its reuse of freed ranges. Measured on the 500M
/// plant (walk, pick, drag; docs/measurements.md): at most 115 MB beyond the
/// peak of the first frame and twice the resident geometry; this keeps
/// half as much again.
pub const FRAME_RESERVE_BYTES: u64 = 160 << 20;

/// The share of the budget the tools' meshes (picks, checks) may keep
/// loaded between operations: one sixty-fourth (16 MB of 1 GiB; the 500M
/// plant's walk, pick and drag loaded 0.42 MB, docs/measurements.md).
pub fn tool_cap_bytes(budget: u64) -> u64 {
    budget / 64
}

/// Streaming state of a viewer under a memory budget.
#[derive(Debug)]
pub struct Streaming {
    streamer: Streamer,
    store: Arc<Store>,
    viewport: Viewport,
    min_pixels: f64,
    /// The GPU pool's side of the streaming: evictions, stand-ins.
    frames: StreamedFrames,
    budget_bytes: u64,
    residency_budget_bytes: u64,
    fixed_bytes: u64,
    sized: bool,
    frames_drawn: u64,
    frames_with_hole: u64,
    frames_with_standin: u64,
    holes: u64,
    stand_ins_drawn: u64,
    /// The last frame's holes and stand-ins.
    last: (u64, u64),
    /// Where the renderer draws stored proxies: no chunk below is wanted.
    cut: Option<Arc<LodCut>>,
    /// Says when reading a remote store fails and when it works again.
    outage: dmu_app::remote::OutageWatch,
}

impl Streaming {
    /// Streaming from `store` for a process that must stay within
    /// `budget_bytes`; until [`Streaming::size`] the residency may hold
    /// nothing (its budget is 0), so the first frame draws stand-ins only
    /// and shows what the renderer itself takes.
    pub fn new(
        store: Arc<Store>,
        tree: &Tree,
        budget_bytes: u64,
        viewport: Viewport,
        min_pixels: f64,
        stand_ins: bool,
        cut: Option<Arc<LodCut>>,
    ) -> Self {
        let chunks = store.skeleton().chunks().len();
        let mut streamer = Self::streamer(Arc::clone(&store), tree, 0, viewport, min_pixels);
        streamer.set_cut(cut.clone());
        Self {
            streamer,
            cut,
            store,
            viewport,
            min_pixels,
            frames: StreamedFrames::new(chunks, stand_ins),
            budget_bytes,
            residency_budget_bytes: 0,
            fixed_bytes: 0,
            sized: false,
            frames_drawn: 0,
            frames_with_hole: 0,
            frames_with_standin: 0,
            holes: 0,
            stand_ins_drawn: 0,
            last: (0, 0),
            outage: dmu_app::remote::OutageWatch::default(),
        }
    }

    fn streamer(
        store: Arc<Store>,
        tree: &Tree,
        budget_bytes: u64,
        viewport: Viewport,
        min_pixels: f64,
    ) -> Streamer {
        let loader_threads = store.loader_threads();
        Streamer::new(
            store,
            ResidencyOptions {
                budget_bytes,
                loader_threads,
                order: LoadOrder::Visibility,
                pacing: Pacing::Free,
            },
            Some(PrefetchOptions::for_tree(tree, min_pixels)),
            viewport,
            min_pixels,
        )
    }

    /// Gives the residency its budget once the first frame is drawn and
    /// presented ([`Streaming::begin_frame`] of the second):
    /// `fixed_bytes` is the most the process has held so far (the peak
    /// resident set: skeleton, tree, the checker's index, renderer, window,
    /// a frame drawn), the tools' cap and a frame reserve
    /// come off too, and the residency gets half of what is left. Fails when
    /// that is under 16 MB.
    fn size(&mut self, tree: &Tree, fixed_bytes: u64) -> anyhow::Result<()> {
        let tool_bytes = tool_cap_bytes(self.budget_bytes);
        let proxy_bytes = match self.store.blob_count(dmu_store::BlobSet::Lod) {
            0 => 0,
            _ => dmu_app::lod::proxy_budget(self.budget_bytes),
        };
        let taken = fixed_bytes + tool_bytes + proxy_bytes + FRAME_RESERVE_BYTES;
        let left = self.budget_bytes.saturating_sub(taken);
        anyhow::ensure!(
            left >= 16 << 20,
            "--memory-budget {:.0} MB: the model's structure, its tree and the renderer \
             take {:.0} MB once a frame is drawn; with {:.0} MB for picks and checks, \
             {:.0} MB for proxies and {:.0} MB for frames, under 16 MB would be left for geometry",
            self.budget_bytes as f64 / 1e6,
            fixed_bytes as f64 / 1e6,
            tool_bytes as f64 / 1e6,
            proxy_bytes as f64 / 1e6,
            FRAME_RESERVE_BYTES as f64 / 1e6
        );
        self.fixed_bytes = fixed_bytes;
        self.residency_budget_bytes = left / 2;
        // Nothing is resident under the first budget (0): the pool holds
        // stand-ins only, which stay listed.
        self.streamer = Self::streamer(
            Arc::clone(&self.store),
            tree,
            self.residency_budget_bytes,
            self.viewport,
            self.min_pixels,
        );
        self.streamer.set_cut(self.cut.clone());
        self.sized = true;
        Ok(())
    }

    /// The frame's geometry (after [`Streaming::begin_frame`]), stand-ins
    /// made from `scene`'s chunk boxes.
    pub fn source<'a>(&'a self, scene: &'a Scene) -> FrameSource<'a> {
        self.frames.source(self.streamer.residency(), scene)
    }

    /// Before a frame: sizes the residency after the first
    /// ([`Streaming::size`]), drops from the GPU pool what the residency evicted and
    /// the stand-ins of chunks now resident, then requests what `camera`
    /// wants (`dt` seconds after the last frame). Fails with the first load
    /// error (a store changed or truncated on disk).
    pub fn begin_frame(
        &mut self,
        pool: &mut GeometryPool,
        tree: &Tree,
        scene: &Scene,
        camera: &Camera,
        dt: f64,
    ) -> anyhow::Result<()> {
        // The first frame was drawn, painted and presented with stand-ins
        // only: the most the process has held so far is what the budget does
        // not share out. (The resident set at one moment misses a frame's
        // transient memory: at 500M, sampled before the paint it was 90 MB
        // short, after it up to 110 MB.)
        if !self.sized && self.frames_drawn > 0 {
            self.size(tree, dmu_app::progress::peak_rss_bytes().unwrap_or(0))?;
        }
        let residency = self.streamer.residency();
        if let Some(e) = residency.first_error() {
            anyhow::bail!("{e}");
        }
        if let Some(line) = self.outage.update(residency, self.store.path()) {
            eprintln!("{line}");
        }
        self.frames.begin(residency, pool);
        let frame = CameraFrame {
            eye: camera.eye,
            target: camera.target,
            up: camera.up,
            fov_y_deg: camera.fov_y_rad.to_degrees(),
        };
        if let Some(view) = View::new(&frame, self.viewport) {
            self.streamer.request(tree, scene, &view, dt);
        }
        Ok(())
    }

    /// After a frame: `stood_in` got stand-ins in the pool, `drawn` are the
    /// chunk instances the panes drew (the first pane's are requested as
    /// visible next frame), `not_resident` the draws with nothing to draw.
    pub fn end_frame(
        &mut self,
        tree: &Tree,
        stood_in: Vec<ChunkId>,
        drawn: &[Vec<EntryId>],
        not_resident: u64,
    ) {
        let chunk = |e: &EntryId| tree.entries()[e.0 as usize].chunk;
        let misses = self
            .frames
            .end(stood_in, drawn.iter().flatten().map(chunk), not_resident);
        self.frames_drawn += 1;
        self.last = (misses.holes, misses.stand_ins);
        self.holes += misses.holes;
        self.stand_ins_drawn += misses.stand_ins;
        self.frames_with_hole += u64::from(misses.holes > 0);
        self.frames_with_standin += u64::from(misses.stand_ins > 0);
        let visible: Vec<ChunkId> = drawn.first().into_iter().flatten().map(chunk).collect();
        self.streamer.drawn(&visible);
    }

    /// The last frame's holes (chunk instances drawn without geometry) and
    /// stand-ins (drawn as their boxes).
    pub fn last_misses(&self) -> (u64, u64) {
        self.last
    }

    /// The top bar's line: the budget and the geometry loaded within it.
    pub fn summary(&self) -> String {
        let mb = |b: u64| b as f64 / 1e6;
        if !self.sized {
            return format!(
                "memory: budget {:.0} MB · sizing on the first frame",
                mb(self.budget_bytes)
            );
        }
        let away = match self.streamer.residency().outage() {
            Some(_) => " · reading the store fails: stand-ins, trying again",
            None => "",
        };
        format!(
            "memory: budget {:.0} MB · geometry {:.0} of {:.0} MB loaded{away}",
            mb(self.budget_bytes),
            mb(self.streamer.residency().stats().resident_bytes),
            mb(self.residency_budget_bytes),
        )
    }

    /// A scripted frame's memory facts, for a soak to follow frame by
    /// frame: the residency's bytes (resident, reserved by loads in
    /// flight) against its budget and its evictions so far, and the GPU
    /// pool's copy (bytes of the chunks and stand-ins it holds, its pages
    /// and the bytes they have handed out), which the budget allows as much
    /// again as the residency's.
    pub fn frame_json(&self, pool: &GeometryPool) -> Value {
        let stats = self.streamer.residency().stats();
        to_value(FrameMemory {
            resident_bytes: stats.resident_bytes,
            reserved_bytes: stats.reserved_bytes,
            residency_budget_bytes: self.residency_budget_bytes,
            evictions: stats.evictions,
            pool_resident_bytes: pool.resident_bytes(),
            pool_handed_out_bytes: pool.handed_out_bytes(),
            pool_pages: pool.pages(),
            pool_stand_ins: self.frames.stand_ins_held(),
        })
    }

    /// The report's facts.
    pub fn json(&self) -> Value {
        to_value(Memory {
            memory_budget_bytes: self.budget_bytes,
            fixed_bytes: self.fixed_bytes,
            residency_budget_bytes: self.residency_budget_bytes,
            stand_ins: if self.frames.stand_ins() {
                "box"
            } else {
                "none"
            },
            frames: self.frames_drawn,
            frames_with_hole: self.frames_with_hole,
            frames_with_standin: self.frames_with_standin,
            holes: self.holes,
            stand_ins_drawn: self.stand_ins_drawn,
            residency: self.streamer.residency().stats(),
            prefetch_rebuilds: self.streamer.prefetch_rebuilds(),
            remote: self.store.remote_stats(),
        })
    }
}

/// A scripted frame's memory facts ([`Streaming::frame_json`]).
#[derive(Debug, Serialize)]
struct FrameMemory {
    resident_bytes: u64,
    reserved_bytes: u64,
    residency_budget_bytes: u64,
    evictions: u64,
    pool_resident_bytes: u64,
    pool_handed_out_bytes: u64,
    pool_pages: usize,
    pool_stand_ins: usize,
}

/// The run's memory facts ([`Streaming::json`]).
#[derive(Debug, Serialize)]
struct Memory {
    memory_budget_bytes: u64,
    fixed_bytes: u64,
    residency_budget_bytes: u64,
    stand_ins: &'static str,
    frames: u64,
    frames_with_hole: u64,
    frames_with_standin: u64,
    holes: u64,
    stand_ins_drawn: u64,
    residency: dmu_store::ResidencyStats,
    prefetch_rebuilds: u64,
    /// A store on object storage: requests, bytes fetched, cache hits.
    remote: Option<dmu_store::remote::RemoteStats>,
}
