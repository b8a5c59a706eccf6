//! One frame at a time against a residency manager: what a view wants becomes
//! the frame's requests (drawn last frame first, then in view, below the
//! coverage threshold, prefetched), and what the frame drew is remembered for
//! the next. The GPU-free walk ([`crate::walk_with`]) and the viewer's frames
//! under a memory budget both go through it.

use std::sync::Arc;

use dmu_scene::{ChunkId, Scene};
use dmu_tree::Tree;

use crate::prefetch::{PrefetchOptions, Prefetcher};
use crate::priority::{Class, Request};
use crate::read::Store;
use crate::residency::{Residency, ResidencyOptions};
use crate::view::{LodCut, View, Viewport, Wanted, wanted};

/// Turns each frame's view into requests to a [`Residency`] it owns.
#[derive(Debug)]
pub struct Streamer {
    residency: Residency,
    prefetcher: Option<Prefetcher>,
    min_pixels: f64,
    set: Wanted,
    /// Frames ended ([`Streamer::drawn`] calls).
    frame: u32,
    /// Per chunk: the frame that last drew it (0: none).
    drawn_at: Vec<u32>,
    /// A [`Streamer::request`] opened the frame [`Streamer::drawn`] ends.
    requested: bool,
    /// The chunks drawn in the last [`KEEP_VISIBLE_FRAMES`] frames.
    recent: Vec<ChunkId>,
    requests: Vec<Request>,
    /// Where merged proxies stand for subtrees: not wanted below.
    cut: Option<Arc<LodCut>>,
}

/// For how many frames after it was last drawn a chunk is still requested
/// ahead of what culling merely wants (the first as [`Class::Visible`], the
/// rest, while resident, as [`Class::Recent`]): what was seen a moment ago is
/// the likeliest to be seen again (through the gaps that open and close as
/// the eye moves), and should not be evicted for what culling merely wants.
/// Measured on the 100M plant's walk within 10 % (docs/measurements.md): 30
/// halves the frames drawing a stand-in; 120 as a class of its own with
/// `Visible` overflowed the budget. A recent chunk that is not resident is
/// not loaded for being recent: a cold first frame draws every chunk in view
/// as its box, and loading all of them as recent would evict what the frames
/// after it found visible.
pub const KEEP_VISIBLE_FRAMES: u32 = 30;

impl Streamer {
    /// A residency manager over `store` with `options`, prefetching along the
    /// predicted path for views of `viewport` when `prefetch` is set; chunks
    /// under `min_pixels` on screen (projected box diagonal) are requested
    /// last ([`Class::Subpixel`]).
    pub fn new(
        store: Arc<Store>,
        options: ResidencyOptions,
        prefetch: Option<PrefetchOptions>,
        viewport: Viewport,
        min_pixels: f64,
    ) -> Streamer {
        let chunks = store.skeleton().chunks().len();
        Streamer {
            residency: Residency::new(store, options),
            prefetcher: prefetch.map(|p| Prefetcher::new(p, viewport)),
            min_pixels,
            set: Wanted::default(),
            frame: 0,
            drawn_at: vec![0; chunks],
            requested: false,
            recent: Vec::new(),
            requests: Vec::new(),
            cut: None,
        }
    }

    /// From now on, wants no chunk below a node `cut` draws as its proxy
    /// (in view and prefetched alike).
    pub fn set_cut(&mut self, cut: Option<Arc<LodCut>>) {
        self.cut = cut;
    }

    /// The residency manager (its [`Residency::get`] gives resident geometry).
    pub fn residency(&self) -> &Residency {
        &self.residency
    }

    /// What the last [`Streamer::request`]'s view wants by frustum and coverage.
    pub fn wanted(&self) -> &Wanted {
        &self.set
    }

    /// Prefetch queue rebuilds so far.
    pub fn prefetch_rebuilds(&self) -> u64 {
        self.prefetcher.as_ref().map_or(0, Prefetcher::rebuilds)
    }

    /// Starts a frame seen from `view`, `dt` seconds after the last: the
    /// chunks frustum and coverage culling want (drawn last frame:
    /// [`Class::Visible`], in the [`KEEP_VISIBLE_FRAMES`] less one before and
    /// resident: [`Class::Recent`], else [`Class::InFrustum`]; under the threshold:
    /// [`Class::Subpixel`]), the chunks drawn lately that culling no longer
    /// wants (drawn last frame, or still resident), and the prefetcher's,
    /// replace the load queue. Returns whether
    /// the prefetch queue was rebuilt.
    pub fn request(&mut self, tree: &Tree, scene: &Scene, view: &View, dt: f64) -> bool {
        let cut = self.cut.as_deref();
        wanted(
            tree,
            scene,
            view,
            self.min_pixels,
            false,
            cut,
            &mut self.set,
        );
        let (drawn_at, frame, residency) = (&self.drawn_at, self.frame, &self.residency);
        let class = |c: ChunkId| match drawn_at[c.index()] {
            at if at == frame && at > 0 => Class::Visible,
            _ if is_recent(drawn_at, frame, c) && residency.is_resident(c) => Class::Recent,
            _ => Class::InFrustum,
        };
        self.requests.clear();
        self.requests
            .extend(self.set.drawn.iter().map(|&(chunk, area_px)| Request {
                chunk,
                class: class(chunk),
                area_px,
            }));
        self.requests
            .extend(self.set.subpixel.iter().map(|&(chunk, area_px)| Request {
                chunk,
                class: Class::Subpixel,
                area_px,
            }));
        // Drawn lately although culling no longer wants it (e.g. under the
        // coverage threshold now, or behind the eye): still the most likely
        // to be seen again (duplicates: the higher priority counts).
        self.requests.extend(
            self.recent
                .iter()
                .map(|&chunk| Request {
                    chunk,
                    class: class(chunk),
                    area_px: 0.0,
                })
                .filter(|r| matches!(r.class, Class::Visible | Class::Recent)),
        );
        let rebuilt = match &mut self.prefetcher {
            Some(p) => {
                let rebuilt = p.update(tree, scene, view, dt, cut);
                self.requests.extend_from_slice(p.requests());
                rebuilt
            }
            None => false,
        };
        self.residency.request(&self.requests);
        self.requested = true;
        rebuilt
    }

    /// Ends a frame: `visible` (the chunks it drew, duplicates allowed) are
    /// requested as [`Class::Visible`] next frame and, while resident, as
    /// [`Class::Recent`] for the [`KEEP_VISIBLE_FRAMES`] less one after, and, when a
    /// [`Streamer::request`] opened this frame, from now on: the chunks
    /// among them not drawn last frame go to the head of the load queue at
    /// once (ahead of those culling merely wants), so that loads made before
    /// the next frame bring what this frame found visible.
    pub fn drawn(&mut self, visible: &[ChunkId]) {
        let last = self.frame;
        let found = visible
            .iter()
            .any(|c| last == 0 || self.drawn_at[c.index()] != last);
        self.frame += 1;
        let (drawn_at, frame) = (&self.drawn_at, self.frame);
        self.recent.retain(|&c| is_recent(drawn_at, frame, c));
        for &c in visible {
            // Listed exactly when recent.
            if !is_recent(&self.drawn_at, self.frame, c) {
                self.recent.push(c);
            }
            self.drawn_at[c.index()] = self.frame;
        }
        let (drawn_at, frame) = (&self.drawn_at, self.frame);
        if !(std::mem::take(&mut self.requested) && found) {
            return;
        }
        for r in &mut self.requests {
            if r.class != Class::Visible && drawn_at[r.chunk.index()] == frame {
                r.class = Class::Visible;
            }
        }
        // Drawn although not requested at all (e.g. out of the frustum, seen
        // by a view ahead of the eye).
        self.requests.extend(visible.iter().map(|&chunk| Request {
            chunk,
            class: Class::Visible,
            area_px: 0.0,
        }));
        self.residency.request(&self.requests);
    }
}

/// Whether `chunk` was drawn in the last [`KEEP_VISIBLE_FRAMES`] frames before
/// the end of `frame` (`drawn_at` as [`Streamer`] keeps it).
fn is_recent(drawn_at: &[u32], frame: u32, chunk: ChunkId) -> bool {
    let at = drawn_at[chunk.index()];
    at > 0 && frame - at < KEEP_VISIBLE_FRAMES
}
