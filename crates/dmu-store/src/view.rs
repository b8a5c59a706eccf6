//! What a camera wants, without a GPU: the tree's frustum and screen-coverage
//! culling give the chunks to draw, and those in view but below the coverage
//! threshold.

use dmu_geom::{Aabb3d, Containment, Frustum, Plane, look_at, reverse_z_perspective};
use dmu_scene::{ChunkId, Scene};
use dmu_tree::Tree;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// One frame of a camera path: where the eye is, what it looks at, which way is
/// up, and the vertical field of view in degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraFrame {
    /// Eye position, world units.
    pub eye: DVec3,
    /// A point looked at (not the eye).
    pub target: DVec3,
    /// Screen up (not along the view direction).
    pub up: DVec3,
    /// Vertical field of view, degrees, in (0, 180).
    #[serde(rename = "fov")]
    pub fov_y_deg: f64,
}

/// Output size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Viewport {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

/// A camera prepared for culling.
#[derive(Clone, Copy, Debug)]
pub struct View {
    /// The eye.
    pub eye: DVec3,
    /// Unit view direction.
    pub dir: DVec3,
    /// The frame it came from.
    pub frame: CameraFrame,
    frustum: Frustum,
    /// Pixels per unit of size at unit distance: `height / (2 tan(fov / 2))`.
    focal_px: f64,
}

impl View {
    /// Prepares a camera; `None` when the frame is not a camera (non-finite,
    /// eye on the target, up along the view, field of view out of range).
    pub fn new(frame: &CameraFrame, viewport: Viewport) -> Option<View> {
        let fov = frame.fov_y_deg.to_radians();
        let dir = (frame.target - frame.eye).try_normalize()?;
        let ok = frame.eye.is_finite()
            && frame.target.is_finite()
            && frame.up.is_finite()
            && dir.cross(frame.up) != DVec3::ZERO
            && fov > 0.0
            && fov < std::f64::consts::PI
            && viewport.width > 0
            && viewport.height > 0;
        if !ok {
            return None;
        }
        let aspect = f64::from(viewport.width) / f64::from(viewport.height);
        // The near plane only trims what touches the eye: any small value will do.
        let near = 1e-3;
        let view_proj = reverse_z_perspective(fov, aspect, near, None)
            * look_at(frame.eye, frame.target, frame.up);
        Some(View {
            eye: frame.eye,
            dir,
            frame: *frame,
            frustum: Frustum::from_view_proj_reverse_z(&view_proj),
            focal_px: f64::from(viewport.height) / (2.0 * (fov * 0.5).tan()),
        })
    }

    /// The same camera moved to `eye`, looking the same way.
    pub fn moved_to(&self, eye: DVec3, viewport: Viewport) -> Option<View> {
        let frame = CameraFrame {
            eye,
            target: eye + (self.frame.target - self.frame.eye),
            ..self.frame
        };
        View::new(&frame, viewport)
    }

    /// Projected size in pixels of a box: its diagonal over its distance from
    /// the eye (size and distance together). Never smaller for a box than for a
    /// box inside it, so a subtree can be cut on its root's size.
    pub fn size_px(&self, b: &Aabb3d) -> f64 {
        let nearest = self.eye.clamp(b.min, b.max);
        let distance = self.eye.distance(nearest);
        let diagonal = (b.max - b.min).length();
        if distance <= 0.0 {
            return f64::INFINITY;
        }
        diagonal / distance * self.focal_px
    }
}

/// Chunks wanted by a view, each once, with its projected area (the largest of
/// its instances').
#[derive(Debug, Default)]
pub struct Wanted {
    /// In the frustum and at least the coverage threshold: drawn.
    pub drawn: Vec<(ChunkId, f32)>,
    /// In a visited cell of the frustum but below the threshold.
    pub subpixel: Vec<(ChunkId, f32)>,
    /// Per chunk: the epoch it was last seen in, its largest area, whether any
    /// instance is drawn.
    best: Vec<(u64, f32, bool)>,
    touched: Vec<ChunkId>,
    epoch: u64,
}

impl Wanted {
    fn begin(&mut self, chunks: usize) {
        self.drawn.clear();
        self.subpixel.clear();
        self.touched.clear();
        self.best.resize(chunks, (0, 0.0, false));
        self.epoch += 1;
    }

    fn add(&mut self, chunk: ChunkId, area: f32, drawn: bool) {
        let best = &mut self.best[chunk.index()];
        if best.0 == self.epoch {
            best.1 = best.1.max(area);
            best.2 |= drawn;
        } else {
            *best = (self.epoch, area, drawn);
            self.touched.push(chunk);
        }
    }

    fn end(&mut self) {
        for &c in &self.touched {
            let (_, area, drawn) = self.best[c.index()];
            let list = if drawn {
                &mut self.drawn
            } else {
                &mut self.subpixel
            };
            list.push((c, area));
        }
    }
}

/// Collects the chunks `view` wants into `out`: cells are visited through the
/// tree's frustum traversal, subtrees smaller than `min_pixels` on screen are
/// cut, and each visible part's chunk in a visited cell is drawn when its own
/// box is in the frustum and at least `min_pixels`, subpixel otherwise. When
/// `omni`, the frustum is ignored (every direction from the eye), as for a
/// prefetch around a viewpoint.
pub fn wanted(
    tree: &Tree,
    scene: &Scene,
    view: &View,
    min_pixels: f64,
    omni: bool,
    out: &mut Wanted,
) {
    out.begin(scene.chunks().len());
    let all = Frustum {
        planes: [Plane::ACCEPT_ALL; 6],
    };
    let frustum = if omni { &all } else { &view.frustum };
    tree.visit_frustum(frustum, &mut |node| {
        if view.size_px(&node.bounds) < min_pixels {
            return false;
        }
        let Some(cell) = node.cell else {
            return true;
        };
        for (part, entries) in tree.cell_groups(cell) {
            if scene.part(part).hidden {
                continue;
            }
            for &e in entries {
                let entry = &tree.entries()[e as usize];
                if node.containment != Containment::Inside
                    && !frustum.intersects_aabb(&entry.bounds)
                {
                    continue;
                }
                let size = view.size_px(&entry.bounds);
                let area = (size * size).min(f64::from(f32::MAX)) as f32;
                out.add(entry.chunk, area, size >= min_pixels);
            }
        }
        false
    });
    out.end();
}
