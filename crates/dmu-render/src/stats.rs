//! What a frame did and what culling decided, as the stats report it.

use crate::settings::Culling;

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
    /// Proxies stale after this frame (their subtree changed; proxies made
    /// in memory are remade once it is calm, and meanwhile not drawn; a
    /// store's are refined past). A stored proxy still loading is not
    /// stale.
    pub proxies_stale: u64,
    /// Nodes drawn coarser than the LOD bound asks: the stored proxy a view
    /// wants there is still loading, and a loaded one above stands in for it
    /// (0: the image is as faithful as the bound says).
    pub lod_coarse: u64,
    /// The LOD error bound the frame drew with, pixels (chosen by the budget
    /// under [`crate::CullingOptions::target_ms`]).
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
