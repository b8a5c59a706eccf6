//! The dmu renderer: chunk geometry in pooled GPU buffers, any number of views
//! over one cell tree, frustum, coverage, coherent occlusion and hierarchical-Z
//! culling, and
//! headless capture, on wgpu.
//!
//! Design choices:
//! - The renderer owns no window: it takes a device, a queue and target views
//!   ([`FrameTarget`]), so the desktop viewer, an XR session and headless
//!   captures ([`Capture`]) drive it alike.
//! - Geometry comes through [`GeometrySource`] ("this chunk, if resident"),
//!   which the in-memory scene implements, and the store's residency manager
//!   through `dmu_app::resident::StreamedFrames` (a `ResidentSource`, or a
//!   `StandInSource` drawing boxes). Chunks are uploaded once into large
//!   pooled buffers ([`GeometryPool`]) with u16 indices where they fit and a
//!   base vertex per draw, and shared by every part instancing them.
//! - Parts are never pre-transformed. A draw is one chunk instance, and its
//!   instance is a 64-byte record written by the CPU for each draw of a round:
//!   its part's model-view, formed in f64 camera-relative and narrowed to f32
//!   (so millimetres survive at 1e7 from the origin and moving a part uploads
//!   nothing but its draws' records), its colour (material and tint) and its
//!   entry id, which the chunk-id oracle ([`Renderer::render_ids`]) writes.
//!   The shaders read it as instance-rate vertex attributes: lavapipe fetches
//!   those once per draw, where a storage read indexed by instance is gathered
//!   lane by lane for every vertex (the view in the 10M plant drew 17 % slower
//!   with one more model-view read per vertex). So a frame's CPU work follows
//!   its draws, not the model's parts.
//! - Highlights are one flag word per part (selected, clashing, hovered;
//!   [`Renderer::set_selected`], [`Renderer::set_clashing`],
//!   [`Renderer::set_hovered`]), tinting, by priority, with a colour of
//!   [`RendererOptions`]: the records carry the tinted colour. Proxies'
//!   vertices carry their materials' colours, and only proxies that may
//!   hold a flagged part read the entries' looks per vertex.
//! - Every mode draws in one canonical order (cells front to back, then tree
//!   order), so the same visible set gives the same image whatever culled the
//!   rest: the occlusion-culled image is compared with the unculled one exactly.
//! - Occlusion culling is CHC-style with temporal coherence over a mirror of
//!   the tree that goes down to chunk instances: last frame's visible set is
//!   drawn first, the invisible frontier is queried by boxes against its depth,
//!   newly visible nodes are drawn or expanded in further rounds (wgpu returns
//!   results only after a submit), and leftovers wait a frame. At most 512
//!   queries go in one render pass (a Mesa 22 lavapipe bug past ~536). Each view
//!   measures what queries cost against what they save and switches them off
//!   where they do not pay ([`OcclusionDecision`]).
//! - Hierarchical-Z culling ([`Culling::Hzb`]) is the GPU-driven alternative:
//!   last frame's visible set is drawn, a compute pass reduces its depth to a
//!   pyramid and tests every candidate's box against it (a few texel reads,
//!   no fill, no query), and the newly visible are drawn in the same frame
//!   through indirect draws compacted per page pair by a count buffer. Two
//!   submissions a frame, every frame exact; the candidates' results come
//!   back with the frame and decide the next frame's first pass.
//! - A stereo pair ([`StereoView`]) is culled once, against a frustum enclosing
//!   both eyes, with one visibility state, and drawn in one multiview pass into
//!   a 2-layer target ([`Renderer::render_stereo`]). Each eye's model-views are
//!   formed in f64 as a single view of that eye forms them, so each layer equals
//!   that eye's single-view image. Occlusion queries run per eye in
//!   single-layer passes (a sample in either eye counts): a query in a Vulkan
//!   multiview pass takes one slot per view, which wgpu does not account for.
//!   Where multiview is missing or draws wrongly (checked once by a probe; Mesa
//!   22.3's lavapipe misplaces near-clipped triangles of the second view), each
//!   layer gets passes of its own from the same culling ([`StereoMode`]).
//!
//! Conventions: right-handed world, model units, f64 world and f32 local as in
//! `dmu-geom`; cameras look down -Z; reverse-Z depth (Depth32Float cleared to 0,
//! compared with Greater) and an infinite far plane; counter-clockwise fronts;
//! back faces are culled only for solid meshes (`dmu_scene::is_solid`) in
//! parts that do not mirror, in frames without section planes
//! ([`RendererOptions::cull_back_faces`]), since CAD windings are unreliable
//! elsewhere; shading is two-sided, a headlight at the eye. Colours are
//! linear; captures are sRGB.
//!
//! ```no_run
//! use dmu_render::{Camera, Capture, Culling, Renderer, View, headless_device};
//! use dmu_geom::glam::DVec3;
//!
//! let scene = dmu_samples::grid(4, 10.0, 4.0, 2048);
//! let tree = dmu_tree::Tree::build(&scene, Default::default());
//! let (device, queue, _) = headless_device()?;
//! let mut renderer = Renderer::new(&device, &queue, &scene, &tree, Default::default());
//! let camera = Camera {
//!     eye: DVec3::new(-40.0, -30.0, 50.0),
//!     target: DVec3::splat(15.0),
//!     up: DVec3::Z,
//!     fov_y_rad: 60f64.to_radians(),
//!     near: 0.1,
//! };
//! let mut view = View::new(camera, (640, 360), Culling::Occlusion);
//! let capture = Capture::new(&device, view.size);
//! let stats = renderer.render(&mut view, &scene, &tree, &scene, capture.frame_target())?;
//! println!("{} triangles, {} queries", stats.triangles_drawn, stats.queries);
//! let image = capture.read_color(&device, &queue)?;
//! dmu_render::save_png(&image, "grid.png".as_ref())?;
//! # Ok::<(), dmu_render::RenderError>(())
//! ```

mod budget;
mod capture;
mod cull;
mod culling;
mod device;
mod error;
mod farfield;
mod frame;
mod geometry;
mod gpu;
mod hierarchy;
mod hzb;
mod pipelines;
mod proxy;
mod renderer;
mod reproject;
mod round;
mod settings;
mod state;
mod stats;
mod stereo;
mod target;
mod view;

pub use budget::{KnobsInEffect, MAX_LOD_ERROR_PX, MAX_MIN_PIXELS};
pub use capture::{
    CAPTURE_FORMAT, Capture, DEPTH_FORMAT, ID_FORMAT, IdImage, SURFACE_CHANGE, count_differing,
    encode_png, save_png,
};
pub use device::{OPTIONAL_FEATURES, headless_device, instance_descriptor, memory_hints};
pub use dmu_geom::Camera;
pub use error::RenderError;
pub use farfield::codec::FarFieldDecodeError;
pub use farfield::{
    FAR_FIELD_RESOLUTIONS, FarField, FarFieldBuild, FarFieldOptions, FarFieldRegion,
};
pub use geometry::{GeometryPool, GeometrySource};
pub use hierarchy::Hierarchy;
pub use proxy::{
    CALM_TICKS, ChunkLoader, Proxies, ProxyBlobs, ProxyOptions, ProxyStats, StoredBuild,
    build_stored,
};
pub use renderer::{Renderer, RendererOptions};
pub use reproject::{Reprojection, Reprojector};
pub use settings::{AUTO_PROBE_EVERY, Culling, CullingOptions, MAX_SECTION_PLANES};
pub use stats::{AutoChoice, FrameStats, OcclusionDecision};
pub use stereo::{StereoCamera, StereoMode};
pub use target::{FrameTarget, StereoTarget};
pub use view::{StereoView, View};
pub use wgpu;
