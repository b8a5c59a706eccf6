//! Views: a camera, a viewport, a culling mode and the per-node visibility
//! state that coherent occlusion culling carries from frame to frame.

use dmu_geom::{Camera, Plane};

/// The most section planes a view cuts with (a section box takes six).
pub const MAX_SECTION_PLANES: usize = 6;

/// How a view decides what to draw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Culling {
    /// Everything that is not hidden: the reference image.
    None,
    /// Frustum and screen-coverage culling on the tree.
    #[default]
    Frustum,
    /// Frustum, coverage and coherent hierarchical occlusion culling (CHC).
    Occlusion,
    /// Frustum, coverage and two-pass hierarchical-Z occlusion culling: last
    /// frame's visible set drawn first, every other candidate's box tested
    /// against a depth pyramid of it in a compute pass, and the newly
    /// visible drawn in the same frame through indirect draws. Single views
    /// only; a stereo pair, or a device or target without what it needs
    /// (indirect draws with a first instance, a depth target a shader can
    /// read), is culled by frustum instead ([`FrameStats::culling`]).
    Hzb,
    /// Per view, whichever of frustum, chc and hzb draws its frames fastest
    /// here: each is timed in turn, the fastest is kept, and the others are
    /// timed again every [`AUTO_PROBE_EVERY`] frames; the stats say which
    /// ran and what each took ([`FrameStats::auto`]).
    Auto,
}

/// Frames an `auto` view keeps its fastest mode before timing another again.
pub const AUTO_PROBE_EVERY: u32 = 60;

impl Culling {
    /// Every mode that culls one way (all but [`Culling::Auto`]), in the
    /// order the tools list them.
    pub const ALL: [Culling; 4] = [
        Culling::None,
        Culling::Frustum,
        Culling::Occlusion,
        Culling::Hzb,
    ];

    /// The mode's name in the tools' flags and reports: `none`, `frustum`,
    /// `chc`, `hzb` or `auto`.
    pub fn name(self) -> &'static str {
        match self {
            Culling::None => "none",
            Culling::Frustum => "frustum",
            Culling::Occlusion => "chc",
            Culling::Hzb => "hzb",
            Culling::Auto => "auto",
        }
    }
}

impl std::str::FromStr for Culling {
    type Err = String;

    /// The mode of a [`Culling::name`].
    fn from_str(name: &str) -> Result<Self, String> {
        Culling::ALL
            .into_iter()
            .chain([Culling::Auto])
            .find(|c| c.name() == name)
            .ok_or_else(|| format!("culling {name:?} is not none, frustum, chc, hzb or auto"))
    }
}

/// Knobs of culling, each with its cost shown in [`FrameStats`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CullingOptions {
    /// Nodes covering fewer pixels across ([`dmu_geom::Coverage::size_px`],
    /// from the nearest eye) are dropped (0 keeps everything: images stay exact).
    pub min_pixels: f64,
    /// Rounds of query-then-draw per frame; what is left waits for the next frame.
    pub max_rounds: u32,
    /// A visible chunk is re-checked every `requery_interval` frames (plus a
    /// per-chunk random offset, so re-checks spread over frames). A re-check
    /// rides on the chunk's own draw, so it costs little; a longer interval
    /// keeps chunks that became hidden drawn for longer. Measured on the 10M
    /// plant's path at 60 Hz (docs/measurements.md): 2 draws 1.33x the exactly
    /// visible triangles against 1.50x for 8, at the same frame time.
    pub requery_interval: u32,
    /// Tree levels a visible internal node is expanded by before querying again.
    pub expand_levels: u32,
    /// Switch occlusion queries off in a view where they cost more than they save.
    pub adaptive: bool,
    /// Draw a chunk's coarsest simplified level whose error projects to at
    /// most this many pixels (from the nearest eye, on the chunk instance's
    /// box); 0 draws every chunk whole (images stay exact). Needs a renderer
    /// made with [`crate::RendererOptions::lod_levels`].
    pub lod_error_px: f64,
    /// A frame-time budget, ms: each frame then picks its LOD error (from 0,
    /// exact) and coverage threshold (from `min_pixels`) after the last
    /// frame's time ([`crate::KnobsInEffect::next`]); `None`: the two knobs
    /// are fixed as set.
    pub target_ms: Option<f64>,
}

impl CullingOptions {
    /// Whether views culled with these options may draw simplified levels (a
    /// LOD error above 0, or a budget that may raise it): their renderer
    /// wants [`crate::RendererOptions::lod_levels`].
    pub fn may_draw_lods(&self) -> bool {
        self.lod_error_px > 0.0 || self.target_ms.is_some()
    }
}

impl Default for CullingOptions {
    fn default() -> Self {
        Self {
            min_pixels: 0.0,
            max_rounds: 6,
            requery_interval: 2,
            expand_levels: 2,
            adaptive: true,
            lod_error_px: 0.0,
            target_ms: None,
        }
    }
}

/// Whether occlusion queries are on in a view, and why.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OcclusionDecision {
    /// Queries are used this frame.
    pub enabled: bool,
    /// Average milliseconds a frame spent on queries and waiting for them.
    pub cost_ms: f64,
    /// Average milliseconds of drawing saved (culled triangles at the measured
    /// cost per triangle).
    pub saved_ms: f64,
    /// Frames until a disabled view tries queries again.
    pub retry_in_frames: u32,
}

/// What a frame of one view did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Frame number of the view (1 for its first frame).
    pub frame: u64,
    /// The culling the frame used: the view's, or frustum culling where
    /// occlusion queries were off or `hzb` could not run.
    pub culling: Culling,
    /// Tree nodes (internal, cells and chunk instances) looked at.
    pub nodes_visited: u64,
    /// Nodes dropped by the frustum.
    pub culled_frustum: u64,
    /// Nodes dropped for covering too few pixels.
    pub culled_coverage: u64,
    /// Chunk instances in the frustum that occlusion culling did not draw.
    pub culled_occlusion: u64,
    /// Chunk instances skipped because their part is hidden.
    pub hidden: u64,
    /// Tree nodes (internal, cells and chunk instances) wholly cut away by
    /// the view's section planes: neither drawn nor queried.
    pub culled_section: u64,
    /// Chunk instances skipped because their geometry is not resident.
    pub not_resident: u64,
    /// Occlusion queries issued (a stereo pair queries each node in both
    /// eyes; counted once).
    pub queries: u64,
    /// Queries that found something visible.
    pub queries_visible: u64,
    /// Query-and-draw rounds (submissions) this frame.
    pub rounds: u32,
    /// Render passes this frame.
    pub passes: u32,
    /// Chunk instances drawn.
    pub chunks_drawn: u64,
    /// Proxies drawn, each instead of a subtree's chunk instances
    /// ([`crate::Proxies`]; their triangles are in `triangles_drawn`).
    pub proxies_drawn: u64,
    /// Clusters of proxies drawn in part that `hzb` left out, their boxes
    /// hidden behind the first pass's depth ([`crate::Proxies`]).
    pub culled_clusters: u64,
    /// Proxies stale after this frame (their subtree changed; they are
    /// remade once it is calm and meanwhile not drawn).
    pub proxies_stale: u64,
    /// The LOD error bound the frame drew with, pixels (chosen by the budget
    /// under [`CullingOptions::target_ms`]).
    pub lod_error_px: f64,
    /// The coverage threshold the frame drew with, pixels.
    pub min_pixels: f64,
    /// Draw commands recorded: an indirect multi-draw (a run of chunk
    /// instances from the same pages, drawn without queries) counts once,
    /// as does each other chunk draw, proxy and query box. The draws inside
    /// them are `chunks_drawn` and `proxies_drawn`.
    pub draw_calls: u64,
    /// Time spent uploading chunks to the GPU pool (with their simplified
    /// levels), ms; part of `cpu_ms`.
    pub upload_ms: f64,
    /// Triangles drawn.
    pub triangles_drawn: u64,
    /// Triangles of the chunk instances that passed frustum and coverage culling.
    pub triangles_in_frustum: u64,
    /// Chunk instances found newly visible this frame (0 once converged).
    pub newly_visible: u64,
    /// Wall time of the frame on the CPU (culling, recording, waiting), ms.
    pub cpu_ms: f64,
    /// GPU time of the frame's passes from timestamp queries, ms (0 when the
    /// device has no timestamps).
    pub gpu_ms: f64,
    /// GPU time of the passes that drew geometry, ms.
    pub gpu_draw_ms: f64,
    /// Occlusion culling's decision for this view.
    pub occlusion: OcclusionDecision,
    /// In an `auto` view: what each mode's frames took here.
    pub auto: Option<AutoChoice>,
    /// The view's far field was drawn (it served the eye).
    pub far_field: bool,
    /// Triangles of the far field's depth meshes drawn (not in
    /// `triangles_drawn`).
    pub far_field_triangles: u64,
    /// Parts drawn as geometry wherever they are because they moved since
    /// the far field was made (or it left them out).
    pub far_field_moved_parts: u64,
}

/// What a [`Culling::Auto`] view measured: each mode's frame time here, ms
/// (a running average of its frames after the first two; 0: not yet timed).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AutoChoice {
    /// The mode the frame ran (chc may still have had its queries off:
    /// [`FrameStats::culling`] says what culled).
    pub ran: Culling,
    /// Frustum and coverage culling.
    pub frustum_ms: f64,
    /// Occlusion queries (as their own decision runs them).
    pub chc_ms: f64,
    /// Hierarchical-Z culling.
    pub hzb_ms: f64,
}

/// Visibility state of one chunk instance in one view.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct EntryState {
    /// Last frame the chunk instance was drawn as visible (0: never).
    pub visible_frame: u64,
    /// Frame at which a visible chunk instance is queried again.
    pub requery_frame: u64,
}

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
    pub(crate) frame: u64,
    pub(crate) entries: Vec<EntryState>,
    pub(crate) decision: OcclusionDecision,
    /// Per-frame averages behind the decision.
    pub(crate) ns_per_triangle: f64,
    /// Frames of the current adaptive probe (queries on while measuring).
    pub(crate) probe_frames: u32,
    /// Average non-drawing time of frames without queries, ms.
    pub(crate) baseline_overhead_ms: f64,
    /// Average frame time without queries, ms, measured where proxies draw
    /// (0: not measured yet).
    pub(crate) frustum_frame_ms: f64,
    pub(crate) last: FrameStats,
    /// The knobs the next frame draws with under a budget (`None` before the
    /// first frame).
    pub(crate) knobs: Option<crate::KnobsInEffect>,
    /// What `auto` culling has timed, and the mode it runs.
    pub(crate) auto: crate::adapt::AutoState,
    /// Per mirror node: last frame its proxy tested visible in an `hzb`
    /// frame (0: never).
    pub(crate) proxy_visible: Vec<u64>,
    /// What the last `hzb` frame found visible, which the next one draws
    /// first.
    pub(crate) hzb_visible: crate::hzb::HzbVisible,
    /// Chunk instances drawn in the last frame, in draw order.
    pub(crate) drawn: Vec<u32>,
    /// GPU resources, made by the renderer on the first frame.
    pub(crate) gpu: Option<crate::renderer::ViewGpu>,
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
            frame: 0,
            entries: Vec::new(),
            decision: OcclusionDecision {
                enabled: true,
                ..OcclusionDecision::default()
            },
            ns_per_triangle: 0.0,
            probe_frames: 0,
            baseline_overhead_ms: 0.0,
            frustum_frame_ms: 0.0,
            last: FrameStats::default(),
            knobs: None,
            auto: crate::adapt::AutoState::default(),
            proxy_visible: Vec::new(),
            hzb_visible: Default::default(),
            drawn: Vec::new(),
            gpu: None,
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
        &self.last
    }

    /// The chunk instances the last frame drew, in draw order (then those
    /// its proxies drew, approximated).
    pub fn drawn_entries(&self) -> impl ExactSizeIterator<Item = dmu_tree::EntryId> + '_ {
        self.drawn.iter().map(|&e| dmu_tree::EntryId(e))
    }

    /// Starts from `other`'s visibility (a view near this one: the same eye a
    /// moment later, say): the next frame's occlusion culling begins from
    /// what `other` last found visible, as if this view had drawn it, rather
    /// than from nothing, where its first frames would draw every chunk
    /// instance in view.
    pub fn inherit_visibility(&mut self, other: &View) {
        self.frame = other.frame;
        self.entries.clone_from(&other.entries);
        self.proxy_visible.clone_from(&other.proxy_visible);
        self.hzb_visible.clone_from(&other.hzb_visible);
    }

    /// Forgets visibility (after a jump of the camera, say): the next frame
    /// starts occlusion culling from scratch.
    pub fn reset_visibility(&mut self) {
        self.entries.clear();
        self.proxy_visible.clear();
        self.hzb_visible = Default::default();
    }
}
