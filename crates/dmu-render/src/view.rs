//! Views: a camera, a viewport, a culling mode and the other settings a
//! caller sets, and apart from them the state culling carries from frame to
//! frame (`ViewState`).

use dmu_geom::{Camera, Plane};

use crate::settings::{Culling, CullingOptions, MAX_SECTION_PLANES};
use crate::state::ViewState;
use crate::stats::FrameStats;
use crate::stereo::StereoCamera;

/// A view: camera, viewport, culling and its own visibility state over the
/// renderer's shared tree and geometry.
#[derive(Debug)]
pub struct View {
    /// The camera.
    pub camera: Camera,
    /// Viewport size in pixels (the target's size).
    pub size: (u32, u32),
    /// Culling mode.
    pub culling: Culling,
    /// Culling knobs.
    pub options: CullingOptions,
    /// An off-centre field of view (a head-mounted display's eye) that
    /// replaces the camera's symmetric `fov_y_rad` for projection, culling
    /// and coverage; `None` draws the camera as it is. Its aspect should be
    /// the viewport's, or pixels are not square. A stereo pair's eyes share
    /// it (each eye's frustum is the centre's moved along screen right).
    pub fov: Option<dmu_geom::Fov>,
    /// A far plane, world units along the view axis (`None`: at infinity):
    /// what lies beyond is clipped and culled. With `camera.near` it selects
    /// a depth range, for drawing a scene's near and far parts apart.
    pub far: Option<f64>,
    /// Draw over the colour already in the target (its depth is cleared
    /// still) instead of clearing it to the background: a near part over a
    /// far part drawn before.
    pub keep_color: bool,
    /// Where the headlight is, world space (`None`: at each eye). A stereo
    /// pair lit from between the eyes, as one lamp on the head lights both,
    /// shades each surface point alike in both eyes, which a reprojected eye
    /// ([`crate::Reprojector`]) needs. A far field keeps the light of its
    /// capture.
    pub light: Option<glam::DVec3>,
    /// The far field of the viewpoint cell the eye is in
    /// ([`crate::FarField`]): where it serves the eye (and far fields are
    /// enabled on the renderer, the frame is a single view, and its culling
    /// is not `none`), the frame draws the chunk instances touching its cull
    /// box and the far field instead of the rest; `chc` frames run as
    /// frustum ones then.
    pub far_field: Option<std::sync::Arc<crate::FarField>>,
    /// A far-field capture's filter (what the capture leaves out).
    pub(crate) far_only: Option<crate::farfield::FarOnly>,
    /// Section planes, world space: what lies on the negative side of any of
    /// them is cut away (not drawn, not queried; see [`View::set_section`]).
    pub(crate) section: Vec<Plane>,
    /// What the view carries from frame to frame.
    pub(crate) state: ViewState,
}

impl View {
    /// A view with fresh visibility state.
    pub fn new(camera: Camera, size: (u32, u32), culling: Culling) -> Self {
        assert!(size.0 > 0 && size.1 > 0, "view size must be positive");
        Self {
            camera,
            size,
            culling,
            options: CullingOptions::default(),
            fov: None,
            far: None,
            keep_color: false,
            light: None,
            far_field: None,
            far_only: None,
            section: Vec::new(),
            state: ViewState::default(),
        }
    }

    /// Cuts the view with `planes` (world space, each keeping its positive
    /// side; none: the whole model). Cut faces show the inside of closed
    /// parts in the section colour ([`crate::RendererOptions::section_cap`]);
    /// nodes wholly cut away are culled, so a section makes frames cheaper.
    ///
    /// # Panics
    /// With more than [`MAX_SECTION_PLANES`] planes, or a plane whose normal
    /// is not a finite unit vector.
    pub fn set_section(&mut self, planes: &[Plane]) {
        assert!(
            planes.len() <= MAX_SECTION_PLANES,
            "{} section planes: at most {MAX_SECTION_PLANES}",
            planes.len()
        );
        assert!(
            planes
                .iter()
                .all(|p| p.normal.is_normalized() && p.d.is_finite()),
            "section planes need finite unit normals"
        );
        self.section.clear();
        self.section.extend_from_slice(planes);
    }

    /// The section planes the view cuts with.
    pub fn section(&self) -> &[Plane] {
        &self.section
    }

    /// Width over height.
    pub fn aspect(&self) -> f64 {
        f64::from(self.size.0) / f64::from(self.size.1)
    }

    /// The field of view: [`View::fov`], or the camera's symmetric one.
    fn fov_or_camera(&self) -> dmu_geom::Fov {
        self.fov
            .unwrap_or_else(|| dmu_geom::Fov::symmetric(self.camera.fov_y_rad, self.aspect()))
    }

    /// View to clip: the camera's projection, or its off-centre
    /// [`View::fov`], to [`View::far`].
    pub fn projection(&self) -> glam::DMat4 {
        match (&self.fov, self.far) {
            (None, None) => self.camera.projection(self.aspect()),
            _ => self
                .fov_or_camera()
                .projection_to(self.camera.near, self.far),
        }
    }

    /// The world-space culling frustum of [`View::projection`].
    pub fn frustum(&self) -> dmu_geom::Frustum {
        self.frustum_at(&self.camera)
    }

    /// The frustum of this view's projection from `camera`'s pose (a
    /// stereo pair's eye).
    pub(crate) fn frustum_at(&self, camera: &crate::Camera) -> dmu_geom::Frustum {
        match (&self.fov, self.far) {
            (None, None) => camera.frustum(self.aspect()),
            _ => self.fov_or_camera().frustum(camera, self.far),
        }
    }

    /// The screen-coverage metric of this view's eye and projection.
    pub fn coverage(&self) -> dmu_geom::Coverage {
        match &self.fov {
            Some(fov) => fov.coverage(&self.camera, self.size.1),
            None => self.camera.coverage(self.size.1),
        }
    }

    /// How far the near plane's corners lie from the eye.
    pub(crate) fn near_reach(&self) -> f64 {
        self.fov_or_camera().near_reach(self.camera.near)
    }

    /// The stats of the last frame.
    pub fn last_stats(&self) -> &FrameStats {
        &self.state.last
    }

    /// The chunk instances the last frame drew, in draw order (then those
    /// its proxies made in memory drew, approximated; a store's proxies
    /// stand for chunks not listed).
    pub fn drawn_entries(&self) -> impl ExactSizeIterator<Item = dmu_tree::EntryId> + '_ {
        self.state.drawn.iter().map(|&e| dmu_tree::EntryId(e))
    }

    /// Starts from `other`'s visibility (a view near this one: the same eye a
    /// moment later, say): the next frame's occlusion culling begins from
    /// what `other` last found visible, as if this view had drawn it, rather
    /// than from nothing, where its first frames would draw every chunk
    /// instance in view.
    pub fn inherit_visibility(&mut self, other: &View) {
        self.state.frame = other.state.frame;
        self.state.entries.clone_from(&other.state.entries);
        self.state.hzb.clone_from(&other.state.hzb);
    }

    /// Forgets visibility (after a jump of the camera, say): the next frame
    /// starts occlusion culling from scratch.
    pub fn reset_visibility(&mut self) {
        self.state.forget_visibility();
    }
}

/// A stereo pair's view: the eyes, and the size, culling and visibility
/// state that the pair shares (culled once for both eyes).
#[derive(Debug)]
pub struct StereoView {
    /// The eyes.
    pub camera: StereoCamera,
    /// Size (of each eye's layer), culling, options, stats and visibility of
    /// the pair. Its camera is the centre eye, set from `camera` every frame.
    pub view: View,
}

impl StereoView {
    /// A stereo view with fresh visibility state.
    pub fn new(camera: StereoCamera, size: (u32, u32), culling: Culling) -> Self {
        Self {
            camera,
            view: View::new(camera.center, size, culling),
        }
    }
}
