//! What a camera wants, without a GPU: the tree's frustum and screen-coverage
//! culling give the chunks to draw, and those in view but below the coverage
//! threshold.

use dmu_geom::{Aabb3d, Camera, Coverage, Frustum, Plane};
use dmu_scene::{ChunkId, Scene};
use dmu_tree::{EntryVisibility, Tree};
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

/// A camera prepared for culling: the one [`Camera`], its frustum and its
/// [`Coverage`] on the viewport.
#[derive(Clone, Copy, Debug)]
pub struct View {
    /// The eye.
    pub eye: DVec3,
    /// Unit view direction.
    pub dir: DVec3,
    /// The frame it came from.
    pub frame: CameraFrame,
    frustum: Frustum,
    coverage: Coverage,
}

impl CameraFrame {
    /// The camera of this frame with its near plane at `near`.
    pub fn camera(&self, near: f64) -> Camera {
        Camera {
            eye: self.eye,
            target: self.target,
            up: self.up,
            fov_y_rad: self.fov_y_deg.to_radians(),
            near,
        }
    }
}

impl View {
    /// Prepares a camera; `None` when the frame is not a camera (non-finite,
    /// eye on the target, up along the view, field of view out of range).
    pub fn new(frame: &CameraFrame, viewport: Viewport) -> Option<View> {
        // The near plane only trims what touches the eye: any small value will do.
        let camera = frame.camera(1e-3);
        let dir = (frame.target - frame.eye).try_normalize()?;
        if !camera.is_valid() || viewport.width == 0 || viewport.height == 0 {
            return None;
        }
        let aspect = f64::from(viewport.width) / f64::from(viewport.height);
        Some(View {
            eye: frame.eye,
            dir,
            frame: *frame,
            frustum: camera.frustum(aspect),
            coverage: camera.coverage(viewport.height),
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

    /// Projected size in pixels of a box ([`Coverage::size_px`]).
    pub fn size_px(&self, b: &Aabb3d) -> f64 {
        self.coverage.size_px(b)
    }
}

/// Tree nodes a renderer draws as one merged proxy (a store's
/// level-of-detail hierarchy) where the proxy's error projects within
/// `lod_error_px`: a view's wanted set stops there, since the chunks below
/// are not drawn.
#[derive(Clone, Debug, Default)]
pub struct LodCut {
    /// Each proxy's error, world units, by tree node slot.
    errors: std::collections::HashMap<u32, f64>,
    lod_error_px: f64,
}

impl LodCut {
    /// Proxies of `errors` (tree node slot, error in world units) drawn at
    /// `lod_error_px`.
    pub fn new(errors: impl IntoIterator<Item = (u32, f64)>, lod_error_px: f64) -> Self {
        Self {
            errors: errors.into_iter().collect(),
            lod_error_px,
        }
    }

    /// Whether the node at `slot`, of box `bounds`, is drawn as its proxy.
    fn cuts(&self, coverage: &Coverage, slot: u32, bounds: &Aabb3d) -> bool {
        self.errors
            .get(&slot)
            .is_some_and(|&e| coverage.error_fits(bounds, e, self.lod_error_px))
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
    cut: Option<&LodCut>,
    out: &mut Wanted,
) {
    out.begin(scene.chunks().len());
    let all = Frustum {
        planes: [Plane::ACCEPT_ALL; 6],
    };
    let frustum = if omni { &all } else { &view.frustum };
    let stop =
        |slot: u32, bounds: &Aabb3d| cut.is_some_and(|c| c.cuts(&view.coverage, slot, bounds));
    tree.visit_visible_above(
        frustum,
        &view.coverage,
        min_pixels,
        &stop,
        &mut |_, entry, v| {
            if let EntryVisibility::InFrustum { size_px, wanted } = v
                && !scene.part(entry.part).hidden
            {
                let area = (size_px * size_px).min(f64::from(f32::MAX)) as f32;
                out.add(entry.chunk, area, wanted);
            }
        },
    );
    out.end();
}
