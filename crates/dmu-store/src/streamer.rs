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
use crate::view::{View, Viewport, Wanted, wanted};

/// Turns each frame's view into requests to a [`Residency`] it owns.
#[derive(Debug)]
pub struct Streamer {
    residency: Residency,
    prefetcher: Option<Prefetcher>,
    min_pixels: f64,
    set: Wanted,
    /// Per chunk: drawn in the last frame.
    visible_last: Vec<bool>,
    /// The chunks set in `visible_last`.
    visible_now: Vec<ChunkId>,
    requests: Vec<Request>,
}

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
            visible_last: vec![false; chunks],
            visible_now: Vec::new(),
            requests: Vec::new(),
        }
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
    /// [`Class::Visible`], else [`Class::InFrustum`]; under the threshold:
    /// [`Class::Subpixel`]), the chunks drawn last frame that culling no
    /// longer wants, and the prefetcher's, replace the load queue. Returns
    /// whether the prefetch queue was rebuilt.
    pub fn request(&mut self, tree: &Tree, scene: &Scene, view: &View, dt: f64) -> bool {
        wanted(tree, scene, view, self.min_pixels, false, &mut self.set);
        let visible_last = &self.visible_last;
        self.requests.clear();
        self.requests
            .extend(self.set.drawn.iter().map(|&(chunk, area_px)| Request {
                chunk,
                class: if visible_last[chunk.index()] {
                    Class::Visible
                } else {
                    Class::InFrustum
                },
                area_px,
            }));
        self.requests
            .extend(self.set.subpixel.iter().map(|&(chunk, area_px)| Request {
                chunk,
                class: Class::Subpixel,
                area_px,
            }));
        // Drawn last frame although culling no longer wants it (e.g. under the
        // coverage threshold now): still the most likely to be seen again.
        self.requests
            .extend(self.visible_now.iter().map(|&chunk| Request {
                chunk,
                class: Class::Visible,
                area_px: 0.0,
            }));
        let rebuilt = match &mut self.prefetcher {
            Some(p) => {
                let rebuilt = p.update(tree, scene, view, dt);
                self.requests.extend_from_slice(p.requests());
                rebuilt
            }
            None => false,
        };
        self.residency.request(&self.requests);
        rebuilt
    }

    /// Ends a frame: `visible` (the chunks it drew, duplicates allowed) are
    /// requested as [`Class::Visible`] next frame.
    pub fn drawn(&mut self, visible: &[ChunkId]) {
        for c in self.visible_now.drain(..) {
            self.visible_last[c.index()] = false;
        }
        for &c in visible {
            if !self.visible_last[c.index()] {
                self.visible_last[c.index()] = true;
                self.visible_now.push(c);
            }
        }
    }
}
