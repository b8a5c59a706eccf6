//! Speculative prefetching along the predicted camera path, by MMR's rules
//! (Aliaga et al. 1999, 5.2):
//! - moving slowly, the user looks around where she is: fetch what the
//!   neighbouring viewpoints see in any direction, spiralling out from the eye;
//! - moving quickly, she keeps going: fetch what the frustum will hold at
//!   viewpoints ahead along the velocity;
//! - a turn of more than 30 degrees (from the direction the queue was built
//!   for) rebuilds the queue, as does leaving the neighbourhood it was built
//!   for or changing between slow and fast. Otherwise the queue is kept, and
//!   the loaders work through it while the view is steady.
//!
//! Prefetched chunks are requested as [`Class::OutsideFrustum`], with their area
//! as seen from the predicted viewpoint divided by one plus its distance in
//! steps, so nearer predictions load first.

use dmu_scene::Scene;
use dmu_tree::Tree;
use glam::DVec3;

use crate::priority::{Class, Request};
use crate::view::{LodCut, View, Viewport, Wanted, wanted};

/// Settings of a [`Prefetcher`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PrefetchOptions {
    /// World units between predicted viewpoints; also how far the eye may move
    /// before the queue is rebuilt. About a cell of the tree.
    pub spacing: f64,
    /// Seconds ahead that fast prediction looks.
    pub horizon_s: f64,
    /// A speed (world units per second) covering `spacing` in less than this
    /// many seconds counts as fast.
    pub fast_after_s: f64,
    /// A turn larger than this (degrees) rebuilds the queue (MMR: 30).
    pub turn_deg: f64,
    /// Chunks smaller than this on screen from a predicted viewpoint are not
    /// prefetched.
    pub min_pixels: f64,
}

impl PrefetchOptions {
    /// MMR's settings for `tree`: viewpoints a typical cell apart (the
    /// median cell's largest extent), one second ahead, fast when covering a
    /// cell in under a second, rebuilt past a 30-degree turn.
    pub fn for_tree(tree: &Tree, min_pixels: f64) -> Self {
        let sizes: Vec<f64> = tree
            .cell_ids()
            .map(|c| tree.cell_bounds(c).extent().max_element())
            .filter(|s| s.is_finite())
            .collect();
        let spacing = if sizes.is_empty() {
            1.0
        } else {
            dmu_geom::median(sizes).max(f64::MIN_POSITIVE)
        };
        Self {
            spacing,
            horizon_s: 1.0,
            fast_after_s: 1.0,
            turn_deg: 30.0,
            min_pixels,
        }
    }
}

/// Predicts where the camera goes and what it will want there.
#[derive(Debug)]
pub struct Prefetcher {
    options: PrefetchOptions,
    viewport: Viewport,
    last_eye: Option<DVec3>,
    /// Smoothed velocity, world units per second.
    velocity: DVec3,
    /// Eye, view direction and mode the queue was built for.
    built: Option<(DVec3, DVec3, bool)>,
    requests: Vec<Request>,
    rebuilds: u64,
    scratch: Wanted,
}

impl Prefetcher {
    /// A prefetcher for views of `viewport`.
    pub fn new(options: PrefetchOptions, viewport: Viewport) -> Prefetcher {
        Prefetcher {
            options,
            viewport,
            last_eye: None,
            velocity: DVec3::ZERO,
            built: None,
            requests: Vec::new(),
            rebuilds: 0,
            scratch: Wanted::default(),
        }
    }

    /// The current prefetch requests.
    pub fn requests(&self) -> &[Request] {
        &self.requests
    }

    /// Times the queue was rebuilt.
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds
    }

    /// Takes the frame's view (`dt` seconds after the previous) and rebuilds the
    /// requests when a rule says so; returns whether it did.
    pub fn update(
        &mut self,
        tree: &Tree,
        scene: &Scene,
        view: &View,
        dt: f64,
        cut: Option<&LodCut>,
    ) -> bool {
        if let Some(last) = self.last_eye
            && dt > 0.0
        {
            // Smoothed over a few frames: paths recorded by hand jitter.
            let v = (view.eye - last) / dt;
            self.velocity = self.velocity.lerp(v, 0.5);
        }
        self.last_eye = Some(view.eye);
        let o = &self.options;
        let fast = self.velocity.length() * o.fast_after_s > o.spacing;
        let rebuild = match self.built {
            None => true,
            Some((eye, dir, was_fast)) => {
                dir.angle_between(view.dir).to_degrees() > o.turn_deg
                    || eye.distance(view.eye) > o.spacing
                    || was_fast != fast
            }
        };
        if rebuild {
            self.build(tree, scene, view, fast, cut);
            self.built = Some((view.eye, view.dir, fast));
            self.rebuilds += 1;
        }
        rebuild
    }

    fn build(&mut self, tree: &Tree, scene: &Scene, view: &View, fast: bool, cut: Option<&LodCut>) {
        self.requests.clear();
        let o = self.options;
        // Viewpoints with how far along the prediction they are (in steps), and
        // whether they look every way.
        let mut points: Vec<(DVec3, f64)> = Vec::new();
        if fast {
            let steps = (self.velocity.length() * o.horizon_s / o.spacing)
                .ceil()
                .clamp(1.0, 8.0);
            for k in 1..=steps as u32 {
                let t = o.horizon_s * f64::from(k) / steps;
                points.push((view.eye + self.velocity * t, f64::from(k)));
            }
        } else {
            // The eye, then its eight neighbours in the plane across `up`: the
            // four beside it before the four diagonal ones, spiralling out.
            let up = view.frame.up.normalize_or(DVec3::Z);
            let ahead = view
                .dir
                .reject_from(up)
                .normalize_or(up.any_orthonormal_vector());
            let side = ahead.cross(up);
            points.push((view.eye, 0.0));
            for (a, s) in [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]
                .into_iter()
                .chain([(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)])
            {
                let offset = (ahead * a + side * s) * o.spacing;
                points.push((view.eye + offset, offset.length() / o.spacing));
            }
        }
        for (eye, steps) in points {
            let Some(at) = view.moved_to(eye, self.viewport) else {
                continue;
            };
            wanted(
                tree,
                scene,
                &at,
                o.min_pixels,
                !fast,
                cut,
                &mut self.scratch,
            );
            let discount = (1.0 + steps) as f32;
            self.requests
                .extend(self.scratch.drawn.iter().map(|&(chunk, area)| Request {
                    chunk,
                    class: Class::OutsideFrustum,
                    area_px: area / discount,
                }));
        }
        dedup_max(&mut self.requests);
    }
}

/// Keeps one request per chunk, the one with the largest area.
fn dedup_max(requests: &mut Vec<Request>) {
    requests.sort_unstable_by(|a, b| a.chunk.cmp(&b.chunk).then(b.area_px.total_cmp(&a.area_px)));
    requests.dedup_by_key(|r| r.chunk);
}
