//! What a view is asked to do: its culling mode and the knobs of culling,
//! plain settings that the rest of the crate reads.

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
    /// read), is culled by frustum instead ([`crate::FrameStats::culling`]).
    Hzb,
    /// Per view, whichever of frustum, chc and hzb draws its frames fastest
    /// here: each is timed in turn, the fastest is kept, and the others are
    /// timed again every [`AUTO_PROBE_EVERY`] frames; the stats say which
    /// ran and what each took ([`crate::FrameStats::auto`]).
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

/// Knobs of culling, each with its cost shown in [`crate::FrameStats`].
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
