//! Replaying a camera path against a residency manager without a GPU: each
//! frame's wanted set comes from the tree's frustum and screen-coverage culling,
//! and a wanted chunk that is not resident when the frame is drawn is a miss.
//!
//! The frame model: the frame's requests go to the manager, the frame is drawn
//! with what is resident (the drawn chunks are pinned while it is), then the
//! loaders get the frame's time: a fixed number of disk bytes
//! ([`WalkOptions::disk_bytes_per_frame`], deterministic), or one frame of wall
//! time (real time). A chunk that comes into view can be drawn at the earliest
//! the frame after it is requested, so only prefetching avoids misses when the
//! view changes. Opening frames before the walk draw its first view until one
//! misses nothing (or the view proves not to fit the budget), so that the walk
//! does not start from nothing.

use std::sync::Arc;
use std::time::{Duration, Instant};

use dmu_scene::ChunkId;
use dmu_tree::Tree;

use crate::error::WalkError;
use crate::geometry::OwnedChunkGeometry;
use crate::prefetch::PrefetchOptions;
use crate::priority::LoadOrder;
use crate::read::Store;
use crate::residency::{Pacing, Residency, ResidencyOptions};
use crate::streamer::Streamer;
use crate::view::{CameraFrame, LodCut, View, Viewport, Wanted};

/// Settings of [`walk`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct WalkOptions {
    /// Queue order.
    pub order: LoadOrder,
    /// Residency budget, decoded bytes.
    pub budget_bytes: u64,
    /// Loader threads.
    pub loader_threads: usize,
    /// Disk bytes the loaders read per frame; `None` lets them run freely while
    /// each frame takes `1 / frame_rate_hz` of wall time.
    pub disk_bytes_per_frame: Option<u64>,
    /// Frames per second of the path (for velocities, and for real-time pacing).
    pub frame_rate_hz: f64,
    /// Output size.
    pub viewport: Viewport,
    /// Screen-coverage threshold: chunks smaller on screen (projected box
    /// diagonal, pixels) are not drawn.
    pub min_pixels: f64,
    /// Prefetching along the predicted path, or none.
    pub prefetch: Option<PrefetchOptions>,
    /// Frames before the walk counts as warm (without an opening the first
    /// view loads from nothing; with one, the frames after it catch up).
    pub warmup_frames: usize,
    /// Frames drawn at the path's first camera before the walk, each followed
    /// by its loads, until one misses nothing or [`OPENING_STALL_FRAMES`] in a
    /// row miss no fewer than the fewest before them while the budget stalls
    /// the loads (at most this many; 0: none), as
    /// a viewer opening on a view shows it once it has loaded. Not counted
    /// among the walk's frames; [`WalkReport::opening`] says what they took.
    pub opening_frames: usize,
    /// Where a renderer draws merged proxies instead of chunks (a store's
    /// level-of-detail hierarchy): chunks below are not wanted.
    #[serde(skip)]
    pub lod_cut: Option<Arc<LodCut>>,
}

/// Opening frames in a row that miss no fewer chunks than the fewest before
/// them, with loads stalled by the budget, end the opening: the first view
/// does not fit (what one frame loads evicts what another needs), and more
/// frames would only take time. Frames that gain nothing because loading is
/// slow (a chunk larger than a frame's disk grant) do not count.
pub const OPENING_STALL_FRAMES: u32 = 3;

/// What the frames before a walk loaded ([`WalkOptions::opening_frames`]).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Opening {
    /// Frames drawn at the first camera.
    pub frames: u64,
    /// Chunks the last of them missed (0 when the first view was complete).
    pub missing_chunks: u64,
    /// File bytes loaded.
    pub loaded_bytes: u64,
    /// Wall time, milliseconds.
    pub wall_ms: f64,
}

/// One frame of a walk.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct FrameReport {
    /// Chunks drawn (wanted and at least the coverage threshold), each once.
    pub wanted_chunks: u64,
    /// Their decoded bytes.
    pub wanted_bytes: u64,
    /// Wanted chunks not resident when the frame was drawn.
    pub missing_chunks: u64,
    /// File bytes loaded during the frame.
    pub loaded_bytes: u64,
    /// Resident bytes at the end of the frame.
    pub resident_bytes: u64,
    /// Highest resident plus in-flight bytes so far.
    pub peak_resident_bytes: u64,
    /// Requests still queued at the end of the frame.
    pub queue_len: u64,
    /// Whether the prefetch queue was rebuilt this frame.
    pub prefetch_rebuilt: bool,
}

/// Totals of a walk.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WalkTotals {
    /// Frames walked.
    pub frames: u64,
    /// Frames after the warm-up.
    pub warm_frames: u64,
    /// Frames with at least one miss.
    pub frames_with_miss: u64,
    /// Warm frames with at least one miss.
    pub warm_frames_with_miss: u64,
    /// `warm_frames_with_miss / warm_frames`.
    pub warm_miss_fraction: f64,
    /// Misses over all frames (a chunk missing on three frames counts three).
    pub missing_chunks: u64,
    /// Wanted chunks over all frames.
    pub wanted_chunks: u64,
    /// Most bytes wanted by one frame.
    pub max_wanted_bytes: u64,
    /// File bytes loaded, the opening's ([`WalkReport::opening`]) included.
    pub loaded_bytes: u64,
    /// Chunks loaded, the opening's included.
    pub loads: u64,
    /// Chunks evicted, the opening's included.
    pub evictions: u64,
    /// Highest resident plus in-flight bytes: never above `budget_bytes`.
    pub peak_resident_bytes: u64,
    /// The budget.
    pub budget_bytes: u64,
    /// Mean requests queued at the end of a frame.
    pub mean_queue_len: f64,
    /// Prefetch queue rebuilds.
    pub prefetch_rebuilds: u64,
    /// Chunk loads that failed (corrupt segments), the opening's included.
    pub failed_loads: u64,
    /// Chunk loads that failed for I/O (a server away) and were tried again
    /// later, the opening's included.
    pub fetch_errors: u64,
    /// Wall time of the walk, the opening's included, milliseconds.
    pub wall_ms: f64,
}

/// A walk's frames and totals.
#[derive(Clone, Debug, serde::Serialize)]
pub struct WalkReport {
    /// The options it ran with.
    pub options: WalkOptions,
    /// The frames before the walk.
    pub opening: Opening,
    /// Per frame.
    pub frames: Vec<FrameReport>,
    /// In total.
    pub total: WalkTotals,
    /// The first load error, if any.
    pub first_error: Option<String>,
    /// For a store on object storage: requests made, bytes fetched, cache
    /// hits, retries and timeouts.
    pub remote: Option<crate::remote::RemoteStats>,
}

/// What drawing one frame found.
#[derive(Debug, Default)]
pub struct Drawn {
    /// Chunks the frame wanted to draw that were not resident.
    pub missing_chunks: u64,
    /// Chunks drawn: requested as [`crate::Class::Visible`] next frame.
    pub visible: Vec<ChunkId>,
    /// Geometry in use until the frame ends (the loaders run meanwhile).
    pub pins: Vec<Arc<OwnedChunkGeometry>>,
}

/// Walks `path` through `store` (whose skeleton `tree` was built from) with a
/// new residency manager, drawing each frame with what is resident: a chunk the
/// frustum and coverage culling want that is not resident is a miss. Fails on
/// a frame that is not a camera, naming it.
pub fn walk(
    store: &Arc<Store>,
    tree: &Tree,
    path: &[CameraFrame],
    options: &WalkOptions,
) -> Result<WalkReport, WalkError> {
    walk_with(store, tree, path, options, &mut |_, set, residency| {
        // Nothing else holds copies of evicted geometry.
        residency.take_evicted();
        let mut drawn = Drawn::default();
        for &(chunk, _) in &set.drawn {
            match residency.get(chunk) {
                Some(g) => drawn.pins.push(g),
                None => drawn.missing_chunks += 1,
            }
            drawn.visible.push(chunk);
        }
        Ok(drawn)
    })
}

/// How [`walk_with`] draws a frame: the frame's index (none for an opening
/// frame), the chunks frustum and coverage culling want, and the residency.
pub type DrawFrame<'a> =
    dyn FnMut(Option<usize>, &Wanted, &Residency) -> Result<Drawn, DrawError> + 'a;

/// What one frame of [`walk_with`] found and left.
struct Stepped {
    missing_chunks: u64,
    wanted_chunks: u64,
    wanted_bytes: u64,
    rebuilt: bool,
    stats: crate::residency::ResidencyStats,
}

/// Why a frame could not be drawn, as [`walk_with`]'s `draw` reports it
/// (any error type converts with `?`).
pub type DrawError = Box<dyn std::error::Error + Send + Sync>;

/// [`walk`] with another way of drawing a frame, e.g. a renderer whose
/// occlusion culling decides what is drawn: `draw` gets the frame's index, the
/// chunks frustum and coverage culling want, and the manager (whose
/// [`Residency::get`] gives the resident geometry); the chunks it reports
/// visible are requested first on the next frame. The opening frames
/// ([`WalkOptions::opening_frames`]) come to `draw` with no index.
pub fn walk_with(
    store: &Arc<Store>,
    tree: &Tree,
    path: &[CameraFrame],
    options: &WalkOptions,
    draw: &mut DrawFrame<'_>,
) -> Result<WalkReport, WalkError> {
    let start = Instant::now();
    let scene = store.skeleton();
    let mut streamer = Streamer::new(
        Arc::clone(store),
        ResidencyOptions {
            budget_bytes: options.budget_bytes,
            loader_threads: options.loader_threads,
            order: options.order,
            pacing: if options.disk_bytes_per_frame.is_some() {
                Pacing::Granted
            } else {
                Pacing::Free
            },
        },
        options.prefetch,
        options.viewport,
        options.min_pixels,
    );
    streamer.set_cut(options.lod_cut.clone());
    let dt = 1.0 / options.frame_rate_hz;
    let view_of = |i: usize| {
        let frame = &path[i];
        View::new(frame, options.viewport).ok_or_else(|| WalkError::NotACamera {
            frame: i,
            camera: format!(
                "eye {:?}, target {:?}, up {:?}, fov {}°",
                frame.eye.to_array(),
                frame.target.to_array(),
                frame.up.to_array(),
                frame.fov_y_deg
            ),
        })
    };
    // One frame: its requests, its drawing with what is resident (pinned
    // until it ends), what it found visible queued first, then its loads.
    let mut step = |index: Option<usize>, view: &View| -> Result<Stepped, WalkError> {
        let frame_start = Instant::now();
        let rebuilt = streamer.request(tree, scene, view, dt);
        let (set, residency) = (streamer.wanted(), streamer.residency());
        let drawn = draw(index, set, residency).map_err(|source| WalkError::Draw {
            frame: index,
            source,
        })?;
        let wanted_bytes = set
            .drawn
            .iter()
            .map(|&(chunk, _)| store.chunk_resident_bytes(chunk))
            .sum();
        let wanted_chunks = set.drawn.len() as u64;
        streamer.drawn(&drawn.visible);
        let residency = streamer.residency();
        match options.disk_bytes_per_frame {
            Some(bytes) => residency.load_granted(bytes),
            None => {
                let frame_time = Duration::from_secs_f64(dt);
                std::thread::sleep(frame_time.saturating_sub(frame_start.elapsed()));
            }
        }
        let missing_chunks = drawn.missing_chunks;
        drop(drawn);
        debug_assert_eq!(residency.validate(), Ok(()));
        Ok(Stepped {
            missing_chunks,
            wanted_chunks,
            wanted_bytes,
            rebuilt,
            stats: residency.stats(),
        })
    };
    let mut opening = Opening::default();
    let mut loaded_before = 0;
    if options.opening_frames > 0 && !path.is_empty() {
        let view = view_of(0)?;
        let (mut fewest, mut stalled, mut budget_stalls) = (u64::MAX, 0, 0);
        for _ in 0..options.opening_frames {
            let s = step(None, &view)?;
            opening.frames += 1;
            opening.missing_chunks = s.missing_chunks;
            loaded_before = s.stats.loaded_file_bytes;
            let over_budget = s.stats.budget_stalls > budget_stalls;
            budget_stalls = s.stats.budget_stalls;
            if s.missing_chunks < fewest {
                (fewest, stalled) = (s.missing_chunks, 0);
            } else if over_budget {
                stalled += 1;
            } else {
                stalled = 0;
            }
            if s.missing_chunks == 0 || stalled == OPENING_STALL_FRAMES {
                break;
            }
        }
        opening.loaded_bytes = loaded_before;
        opening.wall_ms = start.elapsed().as_secs_f64() * 1e3;
    }
    let mut frames = Vec::with_capacity(path.len());
    for i in 0..path.len() {
        let s = step(Some(i), &view_of(i)?)?;
        frames.push(FrameReport {
            wanted_chunks: s.wanted_chunks,
            wanted_bytes: s.wanted_bytes,
            missing_chunks: s.missing_chunks,
            loaded_bytes: s.stats.loaded_file_bytes - loaded_before,
            resident_bytes: s.stats.resident_bytes,
            peak_resident_bytes: s.stats.peak_bytes,
            queue_len: s.stats.queue_len,
            prefetch_rebuilt: s.rebuilt,
        });
        loaded_before = s.stats.loaded_file_bytes;
    }
    let residency = streamer.residency();
    residency.validate()?;
    let stats = residency.stats();
    let warm = &frames[options.warmup_frames.min(frames.len())..];
    let warm_with_miss = warm.iter().filter(|f| f.missing_chunks > 0).count() as u64;
    let total = WalkTotals {
        frames: frames.len() as u64,
        warm_frames: warm.len() as u64,
        frames_with_miss: frames.iter().filter(|f| f.missing_chunks > 0).count() as u64,
        warm_frames_with_miss: warm_with_miss,
        warm_miss_fraction: warm_with_miss as f64 / warm.len().max(1) as f64,
        missing_chunks: frames.iter().map(|f| f.missing_chunks).sum(),
        wanted_chunks: frames.iter().map(|f| f.wanted_chunks).sum(),
        max_wanted_bytes: frames.iter().map(|f| f.wanted_bytes).max().unwrap_or(0),
        loaded_bytes: stats.loaded_file_bytes,
        loads: stats.loads,
        evictions: stats.evictions,
        peak_resident_bytes: stats.peak_bytes,
        budget_bytes: options.budget_bytes,
        mean_queue_len: frames.iter().map(|f| f.queue_len as f64).sum::<f64>()
            / frames.len().max(1) as f64,
        prefetch_rebuilds: streamer.prefetch_rebuilds(),
        failed_loads: stats.failures,
        fetch_errors: stats.fetch_errors,
        wall_ms: start.elapsed().as_secs_f64() * 1e3,
    };
    Ok(WalkReport {
        options: options.clone(),
        opening,
        frames,
        total,
        first_error: residency.first_error(),
        remote: store.remote_stats(),
    })
}
