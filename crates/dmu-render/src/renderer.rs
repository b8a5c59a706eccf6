//! The renderer: pipelines, shared buffers, per-view GPU state, and one round
//! of drawing and querying.

use std::num::NonZeroU32;
use std::ops::Range;

use dmu_geom::Plane;
use dmu_scene::{PartId, Scene};
use dmu_tree::Tree;
use glam::{DAffine3, DMat4};

use crate::RenderError;
use crate::capture::{DEPTH_FORMAT, ID_FORMAT};
use crate::device::map_read;
use crate::geometry::{GeometryPool, GeometrySource, PoolVertex};
use crate::gpu::{
    CHUNK_VERTEX_ATTRIBUTES, EntryGpu, FRAME_ATTRIBUTES, INSTANCE_ATTRIBUTES, InstanceGpu,
    PART_CLASHING, PART_HOVERED, PART_SELECTED, PROXY_VERTEX_ATTRIBUTES, QueryBox,
    RIGHT_EYE_ATTRIBUTES, SHADER, STEREO_SHADER, ViewUniform,
};
use crate::hierarchy::Hierarchy;
use crate::proxy::{Proxies, ProxyStats, ProxyVertex};
use crate::view::{MAX_SECTION_PLANES, View};

/// The lavapipe bug in Mesa 22.3 returns wrong counts past about 536 occlusion
/// queries in one render pass; 512 were always exact.
pub(crate) const QUERIES_PER_PASS: u32 = 512;
/// Passes per frame whose GPU time is measured.
const TIMED_PASSES: u32 = 64;
/// Bytes of one indexed indirect draw's arguments.
const DRAW_ARGS_BYTES: u64 = 20;
/// The most boxes of flagged parts' chunk instances each proxy is tested
/// against (`Renderer::proxies_tinted`); with more, every proxy is drawn
/// tinted.
const MAX_TINT_TESTS: usize = 256;
/// The layers a stereo pair's multiview pass draws: left eye 0, right eye 1.
const STEREO_VIEWS: NonZeroU32 = NonZeroU32::new(0b11).expect("non-zero");

/// Where a frame goes: a colour view (of the renderer's colour format, or
/// [`crate::ID_FORMAT`] for the oracle) and a [`crate::DEPTH_FORMAT`] view of
/// the same size.
#[derive(Clone, Copy, Debug)]
pub struct FrameTarget<'a> {
    /// Colour (or id) attachment.
    pub color: &'a wgpu::TextureView,
    /// Depth attachment.
    pub depth: &'a wgpu::TextureView,
}

/// Where a round draws: a view's target, or the layers of a stereo pair.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RoundTarget<'a> {
    /// Every layer at once: a view's target, or a stereo pair's array views.
    all: FrameTarget<'a>,
    /// Each eye's layer alone; empty for a single view.
    eyes: &'a [FrameTarget<'a>],
    /// A stereo pair's geometry goes to both layers in one multiview pass
    /// (else one pass per layer).
    multiview: bool,
    /// The first pass keeps the colour there (clears depth only).
    keep_color: bool,
}

impl<'a> RoundTarget<'a> {
    /// A single view's target.
    pub fn single(target: FrameTarget<'a>) -> Self {
        Self {
            all: target,
            eyes: &[],
            multiview: false,
            keep_color: false,
        }
    }

    /// The same target, its colour kept by the first pass ([`View::keep_color`]).
    ///
    /// [`View::keep_color`]: crate::View::keep_color
    pub fn keeping_color(self, keep_color: bool) -> Self {
        Self { keep_color, ..self }
    }

    /// A stereo pair's target, drawn with multiview or a pass per layer.
    pub fn stereo(target: &'a crate::StereoTarget<'a>, multiview: bool) -> Self {
        Self {
            all: FrameTarget {
                color: target.color,
                depth: target.depth,
            },
            eyes: &target.eyes,
            multiview,
            keep_color: false,
        }
    }

    /// Every layer's target at once (a single view's target).
    pub fn all(&self) -> FrameTarget<'a> {
        self.all
    }

    /// True when geometry is drawn into every layer by one multiview pass,
    /// which carries no occlusion queries.
    pub fn is_multiview(&self) -> bool {
        self.multiview
    }

    /// Eyes: 1 for a single view, 2 for a stereo pair.
    pub fn eye_count(&self) -> usize {
        self.eyes.len().max(1)
    }

    /// The round's passes ([`plan_passes`]).
    fn plan(&self, queried: &[bool], per_eye: usize, clear: bool) -> Vec<Pass> {
        plan_passes(self.eyes.len(), self.multiview, queried, per_eye, clear)
    }
}

/// A round's passes: what each draws and queries, into which layer, for a
/// single view (`eyes` 0) or a stereo pair drawn with `multiview` or a layer
/// at a time. `queried` flags the draws wrapped in queries; boxes are
/// eye-major, `per_eye` per eye. Draws and boxes are split into runs of at
/// most [`QUERIES_PER_PASS`] queries; with `clear`, the first pass into each
/// layer clears it.
fn plan_passes(
    eyes: usize,
    multiview: bool,
    queried: &[bool],
    per_eye: usize,
    clear: bool,
) -> Vec<Pass> {
    let draws = 0..queried.len();
    let eye_boxes = |k: usize| k * per_eye..(k + 1) * per_eye;
    // Segments: (layer, eye of the uniform, draws, boxes, clears).
    type Segment = (Option<usize>, usize, Range<usize>, Range<usize>, bool);
    let segments: Vec<Segment> = if eyes == 0 {
        vec![(None, 0, draws, eye_boxes(0), clear)]
    } else if multiview {
        let mut s = vec![(None, 0, draws, 0..0, clear)];
        s.extend((0..eyes).map(|k| (Some(k), k, 0..0, eye_boxes(k), false)));
        s
    } else {
        (0..eyes)
            .map(|k| (Some(k), k, draws.clone(), eye_boxes(k), clear))
            .collect()
    };
    let mut passes = Vec::new();
    for (layer, eye, draws, boxes, clear) in segments {
        // A segment's items: its draws, then its boxes (one query each).
        let n = draws.len();
        let items = n + boxes.len();
        let needs_query = |i: usize| i >= n || queried[draws.start + i];
        let (mut start, mut first) = (0, true);
        while start < items || (first && clear) {
            let (mut end, mut queries) = (start, 0);
            while end < items && (queries < QUERIES_PER_PASS || !needs_query(end)) {
                queries += u32::from(needs_query(end));
                end += 1;
            }
            passes.push(Pass {
                layer,
                eye,
                draws: draws.start + start.min(n)..draws.start + end.min(n),
                boxes: boxes.start + start.max(n) - n..boxes.start + end.max(n) - n,
                queries,
                clear: first && clear,
            });
            (start, first) = (end, false);
        }
    }
    passes
}

/// Settings fixed when the renderer is made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RendererOptions {
    /// Format of the colour targets it draws into.
    pub color_format: wgpu::TextureFormat,
    /// Size of each pooled geometry buffer.
    pub page_bytes: u64,
    /// Selection colour (rgb, linear) and its weight (a).
    pub highlight: [f32; 4],
    /// Colour of parts clashing with a moved part (rgb, linear) and its weight.
    pub clash_highlight: [f32; 4],
    /// Colour of the part under the pointer (rgb, linear) and its weight.
    pub hover_highlight: [f32; 4],
    /// Colour of cut faces under section planes (rgb, linear): the inside of
    /// a closed part seen through the cut.
    pub section_cap: [f32; 3],
    /// Background colour (linear).
    pub clear_color: wgpu::Color,
    /// How stereo pairs reach their two layers.
    pub stereo: crate::StereoMode,
    /// Give chunks simplified levels when they are uploaded (costs upload
    /// time and index memory), for views with
    /// [`crate::CullingOptions::lod_error_px`] above 0.
    pub lod_levels: bool,
    /// Record runs of chunk draws from the same pages, drawn without
    /// queries, as one indirect multi-draw each (where the device takes a
    /// first instance in indirect draws); off, each is its own draw call.
    /// The images are the same; on lavapipe batching saves 10-25 % of a
    /// frame.
    pub batch_draws: bool,
    /// Cull the back faces of solid meshes ([`dmu_scene::Mesh::solid`]) in
    /// parts that do not mirror, in frames without section planes: from
    /// outside a solid they are hidden behind its front faces. The images
    /// differ only where a back face won a depth tie at a silhouette; on
    /// lavapipe the view inside the 10M plant is about a quarter faster.
    pub cull_back_faces: bool,
}

impl Default for RendererOptions {
    fn default() -> Self {
        Self {
            color_format: crate::CAPTURE_FORMAT,
            page_bytes: 64 << 20,
            highlight: [1.0, 0.55, 0.0, 0.7],
            clash_highlight: [1.0, 0.0, 0.15, 0.75],
            hover_highlight: [0.3, 0.75, 1.0, 0.35],
            section_cap: [0.75, 0.18, 0.12],
            clear_color: wgpu::Color {
                r: 0.02,
                g: 0.025,
                b: 0.035,
                a: 1.0,
            },
            stereo: crate::StereoMode::Auto,
            lod_levels: false,
            batch_draws: true,
            cull_back_faces: true,
        }
    }
}

/// A draw of one chunk instance, optionally wrapped in an occlusion query.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Draw {
    pub entry: u32,
    pub query: bool,
}

/// How a round picks chunk levels: the coarsest whose error projects to at
/// most `max_error_px` pixels on the chunk instance's box, as `coverage`
/// measures boxes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LodPick {
    pub coverage: dmu_geom::Coverage,
    pub max_error_px: f64,
}

/// Which pipeline draws the geometry of a round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Shading {
    Color,
    Ids,
}

/// What a round measured.
#[derive(Debug, Default)]
pub(crate) struct RoundResult {
    /// Samples of each queried draw, in draw order.
    pub draw_samples: Vec<u64>,
    /// Samples of each box.
    pub box_samples: Vec<u64>,
    pub passes: u32,
    pub not_resident: u64,
    pub triangles: u64,
    pub chunks: u64,
    /// Draw calls recorded (chunks per pass, and boxes).
    pub draw_calls: u64,
    /// Time the pool spent uploading chunks, ms.
    pub upload_ms: f64,
    pub gpu_ms: f64,
    pub gpu_draw_ms: f64,
}

/// A round given to the GPU ([`Renderer::submit_round`]), with what reading
/// its results back needs ([`Renderer::finish_round`]).
#[derive(Debug)]
pub(crate) struct SubmittedRound {
    /// All but the query results and times.
    result: RoundResult,
    passes: Vec<Pass>,
    /// Per draw in recorded order: wrapped in a query.
    queried: Vec<bool>,
    /// Per draw in the given order: its place among the queried draws.
    rank: Vec<usize>,
    /// Per draw in recorded order: its place among the resident draws given.
    order: Vec<usize>,
    /// Per queried draw given, in the given order: its geometry was resident.
    queried_resident: Vec<bool>,
    per_eye: usize,
    queried_draws: usize,
    /// Bytes of query results to read.
    need: u64,
    query_count: u32,
    /// Passes with timestamps.
    timed: usize,
}

/// A view's GPU resources, made on its first frame.
#[derive(Debug)]
pub(crate) struct ViewGpu {
    /// One [`ViewUniform`] per eye, each at a multiple of `uniform_stride`.
    uniform: wgpu::Buffer,
    /// The eyes' world-to-view transforms, as of `prepare_view`.
    eye_views: Vec<DAffine3>,
    /// A round's [`InstanceGpu`]s, eye-major: eye `k`'s from `k` times the
    /// round's draws on (a vertex buffer, bound at the eye's).
    pub(crate) instances: wgpu::Buffer,
    /// Query boxes and proxies' frames (a vertex buffer, read per instance).
    pub(crate) boxes: wgpu::Buffer,
    /// One per eye: eye `k`'s binds its own uniform.
    pub(crate) bind_groups: [wgpu::BindGroup; 2],
    query_sets: Vec<wgpu::QuerySet>,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    /// A round's indirect draw arguments, one per chunk draw in draw order
    /// (five u32: index count, instance count, first index, base vertex,
    /// first instance).
    draw_args: wgpu::Buffer,
    /// The frame cuts with section planes: it draws with the pipelines that
    /// discard what is cut away (the others keep early depth testing).
    pub(crate) sectioned: bool,
    /// The depth pyramid and box-test buffers of `hzb` frames.
    pub(crate) hzb: Option<crate::hzb::HzbGpu>,
}

/// Draws chunk instances of a scene's cell tree into caller-provided targets.
///
/// Owns the pipelines, the pooled geometry, the per-entry and per-part tables
/// and a mirror of the tree's structure; owns no window. Views ([`crate::View`])
/// carry their own visibility state and share everything here.
#[derive(Debug)]
pub struct Renderer {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    pub(crate) options: RendererOptions,
    layout: wgpu::BindGroupLayout,
    /// Shading, shading that discards what section planes cut away, and
    /// shading that culls back faces (indexed by [`Faces`]; so is every
    /// mesh pipeline triple here).
    pub(crate) shade: [wgpu::RenderPipeline; 3],
    /// The multiview shading pipelines; `None` without [`wgpu::Features::MULTIVIEW`]
    /// or when stereo pairs are drawn a layer at a time.
    shade_stereo: Option<[wgpu::RenderPipeline; 3]>,
    /// How stereo pairs are drawn, resolved from the options.
    stereo_mode: crate::StereoMode,
    /// Bytes between the eyes' uniforms (the device's uniform offset alignment).
    uniform_stride: u64,
    ids: [wgpu::RenderPipeline; 3],
    boxes_color: wgpu::RenderPipeline,
    /// Whether each tree entry's chunk belongs to a solid mesh.
    solid: Vec<bool>,
    entries: wgpu::Buffer,
    materials: wgpu::Buffer,
    /// The materials' colours (rgb), as the GPU's `materials`.
    material_colours: Vec<[f32; 3]>,
    part_flags: Vec<u32>,
    /// The parts with a flag set.
    flagged: std::collections::BTreeSet<PartId>,
    /// Parts whose flags changed since the last frame wrote their entries.
    flags_changed: Vec<PartId>,
    pub(crate) pool: GeometryPool,
    pub(crate) hierarchy: Hierarchy,
    pub(crate) timestamp_period_ns: Option<f64>,
    /// Reused per-round scratch: resolved slots of the round's draws.
    slots: Vec<(u32, crate::geometry::SlotDraw)>,
    /// Shading of proxies (merged subtrees) in their vertices' colours, and
    /// tinted as their entries' parts are, by [`Faces`].
    pub(crate) proxy: [[wgpu::RenderPipeline; 3]; 2],
    /// Proxies of the tree's subtrees and their GPU buffers, once set.
    pub(crate) proxies: Option<ProxyGpu>,
    /// The compute pipelines of `hzb` frames, made on the first.
    pub(crate) hzb: Option<crate::hzb::HzbPipelines>,
    /// Moved parts and uploaded far fields, once far fields are enabled.
    pub(crate) far: Option<crate::farfield::FarState>,
    /// The far-field pipeline, made when far fields are enabled.
    pub(crate) far_pipeline: Option<crate::farfield::FarPipeline>,
}

/// Proxies and the vertex and index buffer of each current one (by mirror node).
#[derive(Debug)]
pub(crate) struct ProxyGpu {
    pub cpu: Proxies,
    pub buffers: Vec<Option<(wgpu::Buffer, wgpu::Buffer)>>,
}

/// A round's proxies: mirror nodes, each one's frame in each eye's view
/// space (eye-major), as [`crate::gpu::QueryBox`]es, whether each is drawn
/// tinted ([`Renderer::proxies_tinted`]), and which of each one's clusters
/// are drawn (bit c: cluster c; empty: every proxy whole).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ProxyRound<'a> {
    pub nodes: &'a [u32],
    pub frames: &'a [QueryBox],
    pub tinted: &'a [bool],
    pub clusters: &'a [u64],
}

impl Renderer {
    /// A renderer for `scene` and its `tree` (entries and parts are fixed for
    /// the renderer's life; transforms, visibility and selection may change).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        tree: &Tree,
        options: RendererOptions,
    ) -> Self {
        let shader = |label, source: &str| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
        };
        let module = shader("dmu mesh.wgsl", SHADER);
        let multiview = device.features().contains(wgpu::Features::MULTIVIEW)
            && device.limits().max_multiview_view_count >= STEREO_VIEWS.get().count_ones();
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dmu view"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1),
                storage(2),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("dmu"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let vertices = wgpu::VertexBufferLayout {
            array_stride: size_of::<PoolVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &CHUNK_VERTEX_ATTRIBUTES,
        };
        let per_instance =
            |attributes: &'static [wgpu::VertexAttribute]| wgpu::VertexBufferLayout {
                array_stride: size_of::<InstanceGpu>() as u64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes,
            };
        let frames = wgpu::VertexBufferLayout {
            array_stride: size_of::<QueryBox>() as u64,
            ..per_instance(&FRAME_ATTRIBUTES)
        };
        let mesh_buffers = [
            Some(vertices.clone()),
            Some(per_instance(&INSTANCE_ATTRIBUTES)),
        ];
        let stereo_buffers = [
            Some(vertices),
            Some(per_instance(&INSTANCE_ATTRIBUTES)),
            Some(per_instance(&RIGHT_EYE_ATTRIBUTES)),
        ];
        let pipeline = |label,
                        module: &wgpu::ShaderModule,
                        vs,
                        buffers: &[Option<wgpu::VertexBufferLayout>],
                        fs,
                        format,
                        write: bool,
                        multiview_mask,
                        faces: Faces| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers,
                },
                // CAD windings are unreliable: only solid meshes' back faces
                // are culled, with the pipelines for them.
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: (faces == Faces::Solid).then_some(wgpu::Face::Back),
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(write),
                    // Reverse-Z: nearer is greater. Boxes pass on equality too,
                    // so a box touching visible geometry counts as visible.
                    depth_compare: Some(if write {
                        wgpu::CompareFunction::Greater
                    } else {
                        wgpu::CompareFunction::GreaterEqual
                    }),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some(fs),
                    // The uncut pipelines compile without the discard, which
                    // would cost early depth testing.
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: if faces == Faces::Cut {
                            &[("SECTIONED", 1.0)]
                        } else {
                            &[]
                        },
                        ..Default::default()
                    },
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend: None,
                        write_mask: if write {
                            wgpu::ColorWrites::ALL
                        } else {
                            wgpu::ColorWrites::empty()
                        },
                    })],
                }),
                multiview_mask,
                cache: None,
            })
        };
        let proxy_buffers = [
            Some(wgpu::VertexBufferLayout {
                array_stride: size_of::<ProxyVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &PROXY_VERTEX_ATTRIBUTES,
            }),
            Some(frames.clone()),
        ];
        let proxy = ["vs_proxy", "vs_proxy_tinted"].map(|vs| {
            Faces::ALL.map(|faces| {
                pipeline(
                    "dmu shade proxies",
                    &module,
                    vs,
                    &proxy_buffers,
                    "fs_shade",
                    options.color_format,
                    true,
                    None,
                    faces,
                )
            })
        });
        let shade = Faces::ALL.map(|faces| {
            pipeline(
                "dmu shade",
                &module,
                "vs_mesh",
                &mesh_buffers,
                "fs_shade",
                options.color_format,
                true,
                None,
                faces,
            )
        });
        // Its own module: one naming `view_index` fails validation without multiview.
        let stereo_module = (multiview && options.stereo != crate::StereoMode::LayerPasses)
            .then(|| shader("dmu mesh.wgsl + stereo.wgsl", STEREO_SHADER));
        let shade_stereo = stereo_module.as_ref().map(|module| {
            Faces::ALL.map(|faces| {
                pipeline(
                    "dmu shade stereo",
                    module,
                    "vs_mesh_stereo",
                    &stereo_buffers,
                    "fs_shade",
                    options.color_format,
                    true,
                    Some(STEREO_VIEWS),
                    faces,
                )
            })
        });
        let stereo_mode = match (options.stereo, &stereo_module) {
            (crate::StereoMode::Auto, Some(module))
                if crate::stereo::multiview_clips_correctly(device, queue, module) =>
            {
                crate::StereoMode::Multiview
            }
            (crate::StereoMode::Auto, _) => crate::StereoMode::LayerPasses,
            (mode, _) => mode,
        };
        let ids = Faces::ALL.map(|faces| {
            pipeline(
                "dmu ids",
                &module,
                "vs_mesh",
                &mesh_buffers,
                "fs_id",
                ID_FORMAT,
                true,
                None,
                faces,
            )
        });
        // Stereo pairs query each eye's layer in a pass of its own (see
        // `submit_round`), so the box pipeline is single-view only.
        let boxes_color = pipeline(
            "dmu query boxes",
            &module,
            "vs_box",
            &[Some(frames)],
            "fs_box",
            options.color_format,
            false,
            None,
            Faces::Uncut,
        );

        let storage_buffer = |label, contents: &[u8]| {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (contents.len() as u64).max(16).next_multiple_of(4),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            queue.write_buffer(&buffer, 0, contents);
            buffer
        };
        let entry_table: Vec<EntryGpu> = tree
            .entries()
            .iter()
            .map(|e| entry_gpu(scene, e, 0))
            .collect();
        let materials: Vec<[f32; 4]> = scene.materials().iter().map(|m| m.base_color).collect();
        Self {
            entries: storage_buffer("dmu entries", bytemuck::cast_slice(&entry_table)),
            materials: storage_buffer("dmu materials", bytemuck::cast_slice(&materials)),
            material_colours: materials.iter().map(|&[r, g, b, _]| [r, g, b]).collect(),
            part_flags: vec![0; scene.parts().len()],
            flagged: Default::default(),
            flags_changed: Vec::new(),
            device: device.clone(),
            queue: queue.clone(),
            options,
            layout,
            shade,
            shade_stereo: shade_stereo.filter(|_| stereo_mode == crate::StereoMode::Multiview),
            stereo_mode,
            uniform_stride: size_of::<ViewUniform>()
                .next_multiple_of(device.limits().min_uniform_buffer_offset_alignment as usize)
                as u64,
            ids,
            boxes_color,
            solid: tree
                .entries()
                .iter()
                .map(|e| scene.mesh(scene.chunk(e.chunk).mesh).solid)
                .collect(),
            proxy,
            proxies: None,
            hzb: None,
            far: None,
            far_pipeline: None,
            pool: GeometryPool::new(scene.chunks().len(), options.page_bytes, options.lod_levels),
            hierarchy: Hierarchy::default(),
            timestamp_period_ns: device
                .features()
                .contains(wgpu::Features::TIMESTAMP_QUERY)
                .then(|| f64::from(queue.get_timestamp_period())),
            slots: Vec::new(),
        }
    }

    /// Draws subtrees far enough away as their proxies ([`Proxies`], made
    /// for this renderer's scene and tree) from now on, in frames that may
    /// draw simplified levels (a LOD error above 0) into single-view or
    /// layer-at-a-time passes; proxies that go stale are remade as frames go.
    pub fn set_proxies(&mut self, proxies: Proxies) {
        let mut gpu = ProxyGpu {
            buffers: Vec::new(),
            cpu: proxies,
        };
        let all: Vec<u32> = (0..gpu.cpu.nodes.len() as u32).collect();
        self.upload_proxies(&mut gpu, &all);
        self.proxies = Some(gpu);
    }

    /// The proxies' state: how many are current and stale, their size, and
    /// what the last build or refresh made (`None` without proxies).
    pub fn proxy_stats(&self) -> Option<ProxyStats> {
        self.proxies.as_ref().map(|p| p.cpu.stats())
    }

    /// Brings the proxies up to date with the tree and scene for a frame and
    /// remakes those due (within their time budget), uploading what changed;
    /// the upload time counts as the frame's chunk uploads do.
    pub(crate) fn sync_proxies(
        &mut self,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
    ) -> std::time::Duration {
        let Some(mut gpu) = self.proxies.take() else {
            return std::time::Duration::ZERO;
        };
        let start = std::time::Instant::now();
        gpu.cpu.sync(&self.hierarchy, scene, tree);
        let spent = if gpu.cpu.refresh(&self.hierarchy, scene, tree, geometry) {
            let dirty = std::mem::take(&mut gpu.cpu.dirty);
            self.upload_proxies(&mut gpu, &dirty);
            start.elapsed()
        } else {
            std::time::Duration::ZERO
        };
        self.proxies = Some(gpu);
        spent
    }

    fn upload_proxies(&self, gpu: &mut ProxyGpu, nodes: &[u32]) {
        gpu.buffers.resize_with(gpu.cpu.nodes.len(), || None);
        for &n in nodes {
            gpu.buffers[n as usize] = gpu.cpu.nodes[n as usize]
                .as_ref()
                .filter(|p| !p.indices.is_empty())
                .map(|p| {
                    let buffer = |label, contents: &[u8], usage| {
                        let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                            label: Some(label),
                            size: contents.len() as u64,
                            usage: usage | wgpu::BufferUsages::COPY_DST,
                            mapped_at_creation: false,
                        });
                        self.queue.write_buffer(&b, 0, contents);
                        b
                    };
                    (
                        buffer(
                            "dmu proxy vertices",
                            bytemuck::cast_slice(&p.vertices),
                            wgpu::BufferUsages::VERTEX,
                        ),
                        buffer(
                            "dmu proxy indices",
                            bytemuck::cast_slice(&p.indices),
                            wgpu::BufferUsages::INDEX,
                        ),
                    )
                });
        }
    }

    /// Highlights a part as selected or not, from the next frame on (its
    /// draws' instances carry the tint; its entries, which proxies read, are
    /// rewritten then).
    pub fn set_selected(&mut self, part: PartId, selected: bool) {
        self.set_part_flag(part, PART_SELECTED, selected);
    }

    /// Marks a part as clashing (tinted with
    /// [`RendererOptions::clash_highlight`]) or not; a selected part shows the
    /// selection colour instead.
    pub fn set_clashing(&mut self, part: PartId, clashing: bool) {
        self.set_part_flag(part, PART_CLASHING, clashing);
    }

    /// Marks a part as under the pointer (tinted with
    /// [`RendererOptions::hover_highlight`]) or not; selection and clash
    /// colours take precedence.
    pub fn set_hovered(&mut self, part: PartId, hovered: bool) {
        self.set_part_flag(part, PART_HOVERED, hovered);
    }

    /// Sets or clears one flag bit of a part; the next frame writes the
    /// part's entries to the GPU when it changed.
    fn set_part_flag(&mut self, part: PartId, bit: u32, on: bool) {
        let flags = &mut self.part_flags[part.index()];
        let new = if on { *flags | bit } else { *flags & !bit };
        if new == *flags {
            return;
        }
        *flags = new;
        if new == 0 {
            self.flagged.remove(&part);
        } else {
            self.flagged.insert(part);
        }
        self.flags_changed.push(part);
    }

    /// Writes the entries of the parts whose flags changed since the last
    /// frame (one 4-byte write each).
    pub(crate) fn sync_part_flags(&mut self, scene: &Scene, tree: &Tree) {
        self.flags_changed.sort_unstable();
        self.flags_changed.dedup();
        for part in self.flags_changed.drain(..) {
            let flags = self.part_flags[part.index()];
            for e in tree.part_entries(part) {
                let gpu = entry_gpu(scene, &tree.entries()[e.0 as usize], flags);
                self.queue.write_buffer(
                    &self.entries,
                    (size_of::<EntryGpu>() as u64) * u64::from(e.0),
                    bytemuck::bytes_of(&gpu),
                );
            }
        }
    }

    /// The pooled geometry (resident chunks, bytes; eviction).
    pub fn geometry_pool(&mut self) -> &mut GeometryPool {
        &mut self.pool
    }

    /// How stereo pairs are drawn: [`crate::StereoMode::Multiview`] or
    /// [`crate::StereoMode::LayerPasses`] (`Auto` resolved when the renderer
    /// was made).
    pub fn stereo_mode(&self) -> crate::StereoMode {
        self.stereo_mode
    }

    /// Whether [`Renderer::render_stereo`] can draw: multiview was asked for
    /// on a device without it.
    pub(crate) fn stereo_unsupported(&self) -> bool {
        self.stereo_mode == crate::StereoMode::Multiview && self.shade_stereo.is_none()
    }

    /// Whether GPU times in the stats come from timestamp queries.
    pub fn has_timestamps(&self) -> bool {
        self.timestamp_period_ns.is_some()
    }

    /// Sets a view's uniforms for its eyes (world-to-view `eye_views`) and
    /// keeps the eyes for its rounds, which form their draws' model-views.
    pub(crate) fn prepare_view(&self, view: &mut View, eye_views: &[DAffine3]) -> ViewGpu {
        let proj = view.projection();
        let clip = section_in_eyes(&view.section, eye_views);
        let mut g = view.gpu.take().unwrap_or_else(|| self.make_view_gpu());
        g.sectioned = !view.section.is_empty();
        g.eye_views.clear();
        g.eye_views.extend_from_slice(eye_views);
        let mut light = [[0.0; 4]; 2];
        if let Some(at) = view.light {
            for (l, v) in light.iter_mut().zip(eye_views) {
                *l = v.transform_point3(at).as_vec3().extend(0.0).to_array();
            }
        }
        for eye in 0..eye_views.len() {
            let uniform = ViewUniform {
                proj: proj.as_mat4().to_cols_array_2d(),
                highlight: self.options.highlight,
                clash: self.options.clash_highlight,
                hover: self.options.hover_highlight,
                section_cap: self.options.section_cap,
                eye: eye as u32,
                light,
                clip,
            };
            self.queue.write_buffer(
                &g.uniform,
                eye as u64 * self.uniform_stride,
                bytemuck::bytes_of(&uniform),
            );
        }
        g
    }

    /// The instance of a draw of tree entry `entry` in the eye whose
    /// world-to-view is `eye_view`: its part's model-view, formed in f64 (the
    /// eye's large translation cancels the part's before anything is
    /// rounded to f32, so far-from-origin models stay exact, and a stereo
    /// eye gets what a single view from there gets), and its colour by the
    /// rule of `base_colour` in `mesh.wgsl` (which a driver may round a last
    /// place differently).
    fn instance(&self, scene: &Scene, tree: &Tree, eye_view: DAffine3, entry: u32) -> InstanceGpu {
        let e = &tree.entries()[entry as usize];
        let m = eye_view * scene.part_world(e.part);
        let (a, t) = (m.matrix3, m.translation);
        let row = |i: usize| {
            [
                a.x_axis[i] as f32,
                a.y_axis[i] as f32,
                a.z_axis[i] as f32,
                t[i] as f32,
            ]
        };
        let [r, g, b] = self.material_colours[scene.chunk(e.chunk).material.index()];
        let flags = self.part_flags[e.part.index()];
        let tint = if flags & PART_SELECTED != 0 {
            Some(self.options.highlight)
        } else if flags & PART_CLASHING != 0 {
            Some(self.options.clash_highlight)
        } else if flags & PART_HOVERED != 0 {
            Some(self.options.hover_highlight)
        } else {
            None
        };
        let base = match tint {
            // WGSL's mix(x, y, a) is defined as x * (1 - a) + y * a.
            Some([tr, tg, tb, w]) => [
                r * (1.0 - w) + tr * w,
                g * (1.0 - w) + tg * w,
                b * (1.0 - w) + tb * w,
            ],
            None => [r, g, b],
        };
        InstanceGpu {
            rows: [row(0), row(1), row(2)],
            base,
            entry,
        }
    }

    /// Writes the instances of `entries` (`None`: an unused slot) for each
    /// of the view's eyes, eye-major, into its instance buffer.
    pub(crate) fn write_instances(
        &self,
        gpu: &mut ViewGpu,
        scene: &Scene,
        tree: &Tree,
        entries: &[Option<u32>],
    ) {
        let count = gpu.eye_views.len() * entries.len();
        let bytes = (count * std::mem::size_of::<InstanceGpu>()) as u64;
        let Some(size) = wgpu::BufferSize::new(bytes) else {
            return;
        };
        grow_buffer(&self.device, &mut gpu.instances, "dmu instances", bytes);
        // Written straight into the upload's staging memory: a round of the
        // 500M plant's overview has 330k draws (21 MB of records).
        let Some(mut staging) = self.queue.write_buffer_with(&gpu.instances, 0, size) else {
            return;
        };
        // Formed in small batches, each copied whole: written record by
        // record, the hzb view in the 10M plant took about 5 % longer.
        let mut rest = staging.slice(..);
        let mut batch: Vec<InstanceGpu> = Vec::with_capacity(INSTANCE_BATCH);
        for &eye_view in &gpu.eye_views {
            for part in entries.chunks(INSTANCE_BATCH) {
                batch.clear();
                batch.extend(part.iter().map(|e| {
                    e.map_or_else(<InstanceGpu as bytemuck::Zeroable>::zeroed, |e| {
                        self.instance(scene, tree, eye_view, e)
                    })
                }));
                let records: &[u8] = bytemuck::cast_slice(&batch);
                let (mut head, tail) = rest.split_at(records.len());
                head.copy_from_slice(records);
                rest = tail;
            }
        }
    }

    fn make_view_gpu(&self) -> ViewGpu {
        let buffer = |label, size: u64, usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let copy_dst = wgpu::BufferUsages::COPY_DST;
        let resolve_usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
        let read_usage = copy_dst | wgpu::BufferUsages::MAP_READ;
        let timestamps = self.timestamp_period_ns.map(|_| {
            let bytes = u64::from(2 * TIMED_PASSES) * 8;
            (
                self.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("dmu pass times"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2 * TIMED_PASSES,
                }),
                buffer("dmu time resolve", bytes, resolve_usage),
                buffer("dmu time readback", bytes, read_usage),
            )
        });
        let uniform = buffer(
            "dmu view uniforms",
            self.uniform_stride + size_of::<ViewUniform>() as u64,
            wgpu::BufferUsages::UNIFORM | copy_dst,
        );
        let vertex = wgpu::BufferUsages::VERTEX | copy_dst;
        let bind_groups = self.bind_groups(&uniform);
        ViewGpu {
            uniform,
            eye_views: Vec::new(),
            instances: buffer(
                "dmu instances",
                64 * size_of::<InstanceGpu>() as u64,
                vertex,
            ),
            boxes: buffer("dmu query boxes", 64 * size_of::<QueryBox>() as u64, vertex),
            bind_groups,
            query_sets: Vec::new(),
            resolve: buffer("dmu query resolve", 8, resolve_usage),
            readback: buffer("dmu query readback", 8, read_usage),
            timestamps,
            draw_args: buffer(
                "dmu draw arguments",
                DRAW_ARGS_BYTES,
                copy_dst | wgpu::BufferUsages::INDIRECT,
            ),
            sectioned: false,
            hzb: None,
        }
    }

    /// The faces a draw of tree entry `entry` draws: the front faces only
    /// for a solid mesh in a part that does not mirror (its windings would
    /// flip; eyes never mirror), in a frame without section planes, where
    /// the options allow it.
    pub(crate) fn faces_of(&self, gpu: &ViewGpu, scene: &Scene, tree: &Tree, entry: u32) -> Faces {
        let solid = self.solid[entry as usize]
            && scene
                .part_world(tree.entries()[entry as usize].part)
                .matrix3
                .determinant()
                >= 0.0;
        self.faces(gpu, solid)
    }

    /// Which of the proxies of mirror nodes `nodes` (of `h`, this renderer's
    /// mirror of `tree`) may hold a part with a flag (selected, clashing,
    /// hovered), so are drawn tinted: those whose box meets a flagged part's
    /// chunk instance's (a subtree's box holds its chunk instances'), or all
    /// of them past [`MAX_TINT_TESTS`] such boxes.
    pub(crate) fn proxies_tinted(&self, h: &Hierarchy, tree: &Tree, nodes: &[u32]) -> Vec<bool> {
        let mut boxes = Vec::new();
        for &part in &self.flagged {
            boxes.extend(
                tree.part_entries(part)
                    .map(|e| tree.entries()[e.0 as usize].bounds),
            );
            if boxes.len() > MAX_TINT_TESTS {
                return vec![true; nodes.len()];
            }
        }
        (nodes.iter())
            .map(|&n| {
                let node = h.bounds(tree, n);
                boxes.iter().any(|b| b.overlaps(node))
            })
            .collect()
    }

    /// The pipeline of proxies drawing `faces`, `tinted` or in their
    /// vertices' colours.
    pub(crate) fn proxy_pipeline(&self, tinted: bool, faces: Faces) -> &wgpu::RenderPipeline {
        &self.proxy[usize::from(tinted)][faces as usize]
    }

    /// The faces a frame draws of a mesh that bounds solids (`solid`, as
    /// placed) or not.
    pub(crate) fn faces(&self, gpu: &ViewGpu, solid: bool) -> Faces {
        if gpu.sectioned {
            Faces::Cut
        } else if solid && self.options.cull_back_faces {
            Faces::Solid
        } else {
            Faces::Uncut
        }
    }

    /// A view's bind group for each eye, which differ in the uniform.
    fn bind_groups(&self, uniform: &wgpu::Buffer) -> [wgpu::BindGroup; 2] {
        fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            }
        }
        [0, 1].map(|eye| {
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("dmu view"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: uniform,
                            offset: eye * self.uniform_stride,
                            size: wgpu::BufferSize::new(size_of::<ViewUniform>() as u64),
                        }),
                    },
                    entry(1, &self.entries),
                    entry(2, &self.materials),
                ],
            })
        })
    }

    /// Grows a view's box buffer to hold `boxes` boxes.
    pub(crate) fn ensure_capacity(&self, gpu: &mut ViewGpu, boxes: usize) {
        grow_buffer(
            &self.device,
            &mut gpu.boxes,
            "dmu query boxes",
            (boxes * size_of::<QueryBox>()) as u64,
        );
    }

    /// Where chunk instance `entry`'s geometry is in the pool (uploaded now
    /// if need be), at the level `lod` picks; `None` when not resident.
    pub(crate) fn resolve_slot(
        &mut self,
        geometry: &dyn GeometrySource,
        tree: &Tree,
        entry: u32,
        lod: Option<LodPick>,
    ) -> Option<crate::geometry::ChunkSlot> {
        let entry = &tree.entries()[entry as usize];
        self.pool
            .ensure(&self.device, &self.queue, geometry, entry.chunk)
            .map(|slot| match lod {
                Some(l) => slot.at_lod(l.coverage.size_px(&entry.bounds), l.max_error_px),
                None => slot,
            })
    }

    /// One submission: draws (in the given order, some wrapped in queries), then
    /// box queries against the depth they leave, split into passes of at most
    /// [`QUERIES_PER_PASS`] queries. [`Self::finish_round`] waits for it and
    /// reads the query results back; the CPU may prepare more work in
    /// between.
    ///
    /// A stereo pair's `boxes` hold one run per eye (eye-major), and a draw's
    /// or a box's samples are summed over the eyes. With multiview, geometry
    /// goes to both layers in one pass and each eye's boxes are queried in a
    /// pass of that layer alone: Vulkan gives a query in a multiview pass one
    /// slot per view, which wgpu neither resets nor resolves, so the multiview
    /// pass carries no queries. Without, each eye's draws and boxes go to its
    /// layer in passes of their own.
    #[expect(
        clippy::too_many_arguments,
        reason = "one call site per mode; a struct would only rename them"
    )]
    pub(crate) fn submit_round(
        &mut self,
        gpu: &mut ViewGpu,
        target: RoundTarget<'_>,
        shading: Shading,
        clear: bool,
        geometry: &dyn GeometrySource,
        scene: &Scene,
        tree: &Tree,
        draws: &[Draw],
        boxes: &[QueryBox],
        lod: Option<LodPick>,
        proxies: ProxyRound<'_>,
    ) -> SubmittedRound {
        assert!(
            !target.is_multiview() || (shading == Shading::Color && draws.iter().all(|d| !d.query)),
            "a multiview pass shades and carries no queries"
        );
        assert!(
            proxies.nodes.is_empty() || (shading == Shading::Color && !target.is_multiview()),
            "proxies are shaded in single-layer passes"
        );
        let eyes = target.eye_count();
        assert_eq!(boxes.len() % eyes, 0, "one run of boxes per eye");
        let per_eye = boxes.len() / eyes;
        let mut result = RoundResult::default();
        // Upload what is missing first: recording borrows the pool's buffers.
        self.slots.clear();
        let mut queried = Vec::with_capacity(draws.len());
        let mut resident = Vec::with_capacity(draws.len());
        let uploaded_before = self.pool.upload_time;
        for d in draws {
            let slot = self.resolve_slot(geometry, tree, d.entry, lod);
            resident.push(slot.is_some());
            match slot {
                Some(slot) => {
                    self.slots.push((d.entry, slot.draw_range()));
                    queried.push(d.query);
                    result.chunks += 1;
                    result.triangles += u64::from(slot.index_count / 3);
                }
                None => result.not_resident += 1,
            }
        }
        result.upload_ms = (self.pool.upload_time - uploaded_before).as_secs_f64() * 1e3;
        // Queried draw k's place among the round's queried draws, in draw order.
        let mut rank = Vec::with_capacity(queried.len());
        let mut queried_draws = 0;
        for &wrapped in &queried {
            rank.push(queried_draws);
            queried_draws += usize::from(wrapped);
        }
        // Draws of solid meshes first, each kind in draw order, so that a
        // pass changes pipeline at most once; `order[k]` is draw k's place
        // before.
        let faces: Vec<Faces> = (self.slots.iter())
            .map(|&(entry, _)| self.faces_of(gpu, scene, tree, entry))
            .collect();
        let solid = |k: &usize| faces[*k] == Faces::Solid;
        let mut order: Vec<usize> = (0..faces.len()).filter(solid).collect();
        order.extend((0..faces.len()).filter(|k| !solid(k)));
        self.slots = order.iter().map(|&k| self.slots[k]).collect();
        let queried: Vec<bool> = order.iter().map(|&k| queried[k]).collect();
        let faces: Vec<Faces> = order.iter().map(|&k| faces[k]).collect();
        // Draw k's instance is the k-th of its eye's.
        let instances: Vec<Option<u32>> = self.slots.iter().map(|&(e, _)| Some(e)).collect();
        self.write_instances(gpu, scene, tree, &instances);
        // The proxies' frames follow the query boxes in the same buffer.
        if !boxes.is_empty() || !proxies.frames.is_empty() {
            self.ensure_capacity(gpu, boxes.len() + proxies.frames.len());
            self.queue
                .write_buffer(&gpu.boxes, 0, bytemuck::cast_slice(boxes));
            self.queue.write_buffer(
                &gpu.boxes,
                std::mem::size_of_val(boxes) as u64,
                bytemuck::cast_slice(proxies.frames),
            );
        }
        let proxy_buffers: Vec<_> = match &self.proxies {
            Some(p) => proxies
                .nodes
                .iter()
                .enumerate()
                .filter_map(|(k, &n)| {
                    let proxy = p.cpu.nodes[n as usize].as_ref()?;
                    let (v, i) = p.buffers.get(n as usize)?.as_ref()?;
                    let faces = self.faces(gpu, proxy.solid);
                    let mask = proxies.clusters.get(k).copied().unwrap_or(u64::MAX);
                    Some((
                        k as u32,
                        v,
                        i,
                        crate::proxy::cluster_ranges(&proxy.clusters, mask),
                        (proxies.tinted[k], faces),
                    ))
                })
                .collect(),
            None => Vec::new(),
        };
        let mut proxies_drawn_in = [false; 2];
        // A round drawing proxies has a pass into each layer even without
        // chunk draws or boxes (one that clears only where asked).
        let mut passes = target.plan(&queried, per_eye, clear || !proxies.nodes.is_empty());
        if !clear {
            for p in &mut passes {
                p.clear = false;
            }
        }
        let query_count: u32 = passes.iter().map(|p| p.queries).sum();
        while gpu.query_sets.len() < passes.len() {
            gpu.query_sets
                .push(self.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("dmu occlusion"),
                    ty: wgpu::QueryType::Occlusion,
                    count: QUERIES_PER_PASS,
                }));
        }
        let set_bytes = u64::from(QUERIES_PER_PASS) * 8;
        let need = passes.len() as u64 * set_bytes;
        if query_count > 0 && gpu.resolve.size() < need {
            let usage_resolve = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
            let usage_read = wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ;
            let size = need.max(gpu.resolve.size() * 2);
            gpu.resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dmu query resolve"),
                size,
                usage: usage_resolve,
                mapped_at_creation: false,
            });
            gpu.readback = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dmu query readback"),
                size,
                usage: usage_read,
                mapped_at_creation: false,
            });
        }

        // Runs of unqueried draws from the same pages go in one indirect
        // multi-draw each (lavapipe's cost is per recorded command as much
        // as per triangle): their arguments, in draw order. The draw's place
        // is its first instance, hence the feature.
        let batched = self.options.batch_draws
            && self
                .device
                .features()
                .contains(wgpu::Features::INDIRECT_FIRST_INSTANCE)
            && queried.contains(&false);
        if batched {
            let args: Vec<u32> = (self.slots.iter().zip(0..))
                .flat_map(|(&(_, slot), k)| {
                    [slot.index_count, 1, slot.first_index, slot.first_vertex, k]
                })
                .collect();
            grow_buffer(
                &self.device,
                &mut gpu.draw_args,
                "dmu draw arguments",
                args.len() as u64 * 4,
            );
            self.queue
                .write_buffer(&gpu.draw_args, 0, bytemuck::cast_slice(&args));
        }
        let eye_instances = |eye: usize| {
            let start = (eye * instances.len() * size_of::<InstanceGpu>()) as u64;
            gpu.instances.slice(start..)
        };
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("dmu round"),
            });
        let timed = passes.len().min(TIMED_PASSES as usize);
        for (p, pass_plan) in passes.iter().enumerate() {
            let (pass_target, multiview_mask) = match pass_plan.layer {
                Some(eye) => (target.eyes[eye], None),
                None => (target.all, target.is_multiview().then_some(STEREO_VIEWS)),
            };
            let timestamp_writes =
                gpu.timestamps
                    .as_ref()
                    .filter(|_| p < timed)
                    .map(|(set, _, _)| wgpu::RenderPassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: Some(2 * p as u32),
                        end_of_pass_write_index: Some(2 * p as u32 + 1),
                    });
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("dmu pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: pass_target.color,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: if pass_plan.clear
                            && !(target.keep_color && shading == Shading::Color)
                        {
                            wgpu::LoadOp::Clear(match shading {
                                Shading::Color => self.options.clear_color,
                                Shading::Ids => wgpu::Color::TRANSPARENT,
                            })
                        } else {
                            wgpu::LoadOp::Load
                        },
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: pass_target.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: if pass_plan.clear {
                            wgpu::LoadOp::Clear(0.0)
                        } else {
                            wgpu::LoadOp::Load
                        },
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes,
                occlusion_query_set: (pass_plan.queries > 0).then(|| &gpu.query_sets[p]),
                multiview_mask,
            });
            pass.set_bind_group(0, &gpu.bind_groups[pass_plan.eye], &[]);
            if !pass_plan.draws.is_empty() {
                pass.set_vertex_buffer(1, eye_instances(pass_plan.eye));
                if multiview_mask.is_some() {
                    pass.set_vertex_buffer(2, eye_instances(1));
                }
            }
            let mut q = 0;
            let mut bound: Option<(u32, u32, bool)> = None;
            let mut bound_faces = None;
            let range = pass_plan.draws.clone();
            let mut k = range.start;
            while k < range.end {
                let slot = self.slots[k].1;
                let wrapped = queried[k];
                let draw_faces = faces[k];
                if bound_faces != Some(draw_faces) {
                    pass.set_pipeline(match shading {
                        _ if multiview_mask.is_some() => &self
                            .shade_stereo
                            .as_ref()
                            .expect("multiview rounds only where the pipeline exists")
                            [draw_faces as usize],
                        Shading::Color => &self.shade[draw_faces as usize],
                        Shading::Ids => &self.ids[draw_faces as usize],
                    });
                    bound_faces = Some(draw_faces);
                }
                let key = pages(&slot);
                if bound != Some(key) {
                    pass.set_vertex_buffer(0, self.pool.vertex_slice(slot.vertex_page));
                    let format = if slot.short_indices {
                        wgpu::IndexFormat::Uint16
                    } else {
                        wgpu::IndexFormat::Uint32
                    };
                    pass.set_index_buffer(self.pool.index_slice(slot.index_page), format);
                    bound = Some(key);
                }
                if batched && !wrapped {
                    let mut end = k + 1;
                    while end < range.end
                        && !queried[end]
                        && faces[end] == faces[k]
                        && pages(&self.slots[end].1) == key
                    {
                        end += 1;
                    }
                    pass.multi_draw_indexed_indirect(
                        &gpu.draw_args,
                        k as u64 * DRAW_ARGS_BYTES,
                        (end - k) as u32,
                    );
                    result.draw_calls += 1;
                    k = end;
                    continue;
                }
                if wrapped {
                    pass.begin_occlusion_query(q);
                    q += 1;
                }
                pass.draw_indexed(
                    slot.first_index..slot.first_index + slot.index_count,
                    slot.first_vertex as i32,
                    k as u32..k as u32 + 1,
                );
                result.draw_calls += 1;
                if wrapped {
                    pass.end_occlusion_query();
                }
                k += 1;
            }
            // Proxies go into the first pass of each layer, after its chunks and
            // before its boxes, whose queries they may hide.
            let eye = pass_plan.layer.unwrap_or(0);
            if !proxy_buffers.is_empty() && !std::mem::replace(&mut proxies_drawn_in[eye], true) {
                let first_frame = (boxes.len() + eye * proxies.nodes.len()) as u32;
                pass.set_vertex_buffer(1, gpu.boxes.slice(..));
                let mut bound_pipeline = None;
                for (k, vertices, indices, ranges, (tinted, faces)) in &proxy_buffers {
                    if bound_pipeline != Some((*tinted, *faces)) {
                        pass.set_pipeline(self.proxy_pipeline(*tinted, *faces));
                        bound_pipeline = Some((*tinted, *faces));
                    }
                    pass.set_vertex_buffer(0, vertices.slice(..));
                    pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
                    let frame = first_frame + k;
                    for range in ranges {
                        pass.draw_indexed(range.clone(), 0, frame..frame + 1);
                        result.draw_calls += 1;
                        if eye == 0 {
                            result.triangles += u64::from(range.len() as u32 / 3);
                        }
                    }
                }
            }
            if !pass_plan.boxes.is_empty() {
                pass.set_pipeline(&self.boxes_color);
                pass.set_vertex_buffer(0, gpu.boxes.slice(..));
                // Eye-major: a box's instance is its index in the buffer.
                for b in pass_plan.boxes.clone() {
                    let b = b as u32;
                    pass.begin_occlusion_query(q);
                    pass.draw(0..36, b..b + 1);
                    result.draw_calls += 1;
                    pass.end_occlusion_query();
                    q += 1;
                }
            }
            debug_assert_eq!(q, pass_plan.queries);
        }
        for (p, pass_plan) in passes.iter().enumerate() {
            if pass_plan.queries > 0 {
                encoder.resolve_query_set(
                    &gpu.query_sets[p],
                    0..pass_plan.queries,
                    &gpu.resolve,
                    p as u64 * set_bytes,
                );
            }
        }
        if query_count > 0 {
            encoder.copy_buffer_to_buffer(&gpu.resolve, 0, &gpu.readback, 0, need);
        }
        if let Some((set, resolve, readback)) = &gpu.timestamps
            && timed > 0
        {
            encoder.resolve_query_set(set, 0..2 * timed as u32, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, readback, 0, 16 * timed as u64);
        }
        self.queue.submit([encoder.finish()]);
        result.passes = passes.len() as u32;
        SubmittedRound {
            result,
            passes,
            queried,
            rank,
            order,
            queried_resident: (draws.iter().zip(resident))
                .filter_map(|(d, r)| d.query.then_some(r))
                .collect(),
            per_eye,
            queried_draws,
            need,
            query_count,
            timed,
        }
    }

    /// Waits for a round [`Self::submit_round`] gave the GPU and reads its
    /// query results and times.
    pub(crate) fn finish_round(
        &self,
        gpu: &ViewGpu,
        round: SubmittedRound,
    ) -> Result<RoundResult, RenderError> {
        let mut result = round.result;
        if round.query_count > 0 {
            let samples: Vec<u64> = map_read(
                &self.device,
                &gpu.readback,
                round.need,
                "occlusion queries",
                bytemuck::pod_collect_to_vec,
            )?;
            // Every eye's passes add to a queried draw's result.
            result.draw_samples = vec![0; round.queried_draws];
            result.box_samples = vec![0; round.per_eye];
            // Query q of pass p sits at p * QUERIES_PER_PASS + q, in item order.
            for (p, pass_plan) in round.passes.iter().enumerate() {
                let mut at = (p * QUERIES_PER_PASS as usize..).map(|i| samples[i]);
                for j in pass_plan.draws.clone().filter(|&j| round.queried[j]) {
                    result.draw_samples[round.rank[round.order[j]]] +=
                        at.next().expect("one slot per query");
                }
                for b in pass_plan.boxes.clone() {
                    result.box_samples[b % round.per_eye] += at.next().expect("one slot per query");
                }
            }
        } else if !round.passes.is_empty() {
            // Nothing to read, but the caller's timing must include the work.
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| RenderError::Readback {
                    what: "frame completion",
                    reason: e.to_string(),
                })?;
        }
        if result.not_resident > 0 {
            // A queried draw whose geometry is not resident was not drawn: it
            // counts as visible, so it stays wanted and is drawn once it arrives.
            let mut drawn = std::mem::take(&mut result.draw_samples).into_iter();
            result.draw_samples = (round.queried_resident.iter())
                .map(|&r| {
                    if r {
                        drawn.next().expect("one result per drawn query")
                    } else {
                        1
                    }
                })
                .collect();
        }
        if let (Some((_, _, readback)), Some(period)) = (&gpu.timestamps, self.timestamp_period_ns)
            && round.timed > 0
        {
            let ticks: Vec<u64> = map_read(
                &self.device,
                readback,
                16 * round.timed as u64,
                "timestamps",
                bytemuck::pod_collect_to_vec,
            )?;
            for (p, pass_plan) in round.passes.iter().take(round.timed).enumerate() {
                let ms = ticks[2 * p + 1].saturating_sub(ticks[2 * p]) as f64 * period * 1e-6;
                result.gpu_ms += ms;
                if !pass_plan.draws.is_empty() {
                    result.gpu_draw_ms += ms;
                }
            }
        }
        Ok(result)
    }
}

/// A render pass over `target` that keeps its colour and depth (draws over
/// what earlier passes of the frame drew).
pub(crate) fn pass_over<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    target: FrameTarget<'_>,
    timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    let keep = wgpu::Operations {
        load: wgpu::LoadOp::Load,
        store: wgpu::StoreOp::Store,
    };
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target.color,
            depth_slice: None,
            resolve_target: None,
            ops: keep,
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: target.depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// Which faces a mesh pipeline draws: all of them (`Uncut`), all but what
/// section planes cut away (`Cut`), or the front faces only (`Solid`, for
/// solid meshes in frames without section planes). Indexes the pipeline
/// triples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Faces {
    Uncut = 0,
    Cut = 1,
    Solid = 2,
}

impl Faces {
    const ALL: [Self; 3] = [Self::Uncut, Self::Cut, Self::Solid];
}

/// The GPU record of a chunk instance whose part has `flags`.
fn entry_gpu(scene: &Scene, entry: &dmu_tree::Entry, flags: u32) -> EntryGpu {
    EntryGpu::new(scene.chunk(entry.chunk).material.0, flags)
}

/// A render pass of a round.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Pass {
    /// The eye whose layer alone it draws into; `None`: every layer.
    layer: Option<usize>,
    /// The eye whose uniform and instance records it binds.
    eye: usize,
    /// The round's draws it issues (indices into the resolved slots).
    draws: Range<usize>,
    /// The boxes it queries (indices into the round's eye-major box buffer).
    boxes: Range<usize>,
    /// Occlusion queries it issues.
    queries: u32,
    /// It clears its layers first.
    clear: bool,
}

/// Instance records formed and copied into staging memory at a time.
const INSTANCE_BATCH: usize = 1024;

/// Replaces `buffer` (keeping its usage) by one of at least `need` bytes,
/// twice as large as before at least, when it is smaller; whether it did.
fn grow_buffer(device: &wgpu::Device, buffer: &mut wgpu::Buffer, label: &str, need: u64) -> bool {
    if buffer.size() >= need {
        return false;
    }
    *buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: need.max(2 * buffer.size()),
        usage: buffer.usage(),
        mapped_at_creation: false,
    });
    true
}

/// The pool pages and index format a chunk draw binds: draws with the same
/// can share a multi-draw.
fn pages(slot: &crate::geometry::SlotDraw) -> (u32, u32, bool) {
    (slot.vertex_page, slot.index_page, slot.short_indices)
}

/// The section planes in each eye's view space, six per eye (unused slots are
/// `(0, 0, 0, 1)`: every point is 1 above them, kept). The plane
/// goes through the inverse transpose of world-to-view in f64, so a plane far
/// from the origin becomes a small camera-relative one before narrowing to f32.
fn section_in_eyes(
    section: &[Plane],
    eye_views: &[DAffine3],
) -> [[f32; 4]; 2 * MAX_SECTION_PLANES] {
    let mut clip = [[0.0, 0.0, 0.0, 1.0]; 2 * MAX_SECTION_PLANES];
    for (eye, view) in eye_views.iter().take(2).enumerate() {
        let view_to_world_t = DMat4::from(view.inverse()).transpose();
        for (i, p) in section.iter().enumerate() {
            let v = view_to_world_t * p.normal.extend(p.d);
            clip[eye * MAX_SECTION_PLANES + i] = v.as_vec4().to_array();
        }
    }
    clip
}

#[cfg(test)]
mod tests {
    use super::{Pass, QUERIES_PER_PASS, plan_passes};

    /// Every draw is issued once per layer it must reach and every box once,
    /// in order; no pass holds more than [`QUERIES_PER_PASS`] queries; each
    /// layer is cleared exactly once, before anything is drawn into it.
    fn check(
        eyes: usize,
        multiview: bool,
        queried: &[bool],
        per_eye: usize,
        clear: bool,
    ) -> Vec<Pass> {
        let passes = plan_passes(eyes, multiview, queried, per_eye, clear);
        let layers = eyes.max(1);
        let mut draws_into = vec![0usize; layers];
        let mut boxes = 0;
        let mut cleared = vec![0; layers];
        for p in &passes {
            let reached: Vec<usize> = match p.layer {
                Some(k) => vec![k],
                None => (0..layers).collect(),
            };
            assert!(p.queries <= QUERIES_PER_PASS, "{p:?}");
            let queries = queried[p.draws.clone()].iter().filter(|&&q| q).count() + p.boxes.len();
            assert_eq!(p.queries as usize, queries, "{p:?}");
            for &k in &reached {
                if p.clear {
                    assert_eq!(draws_into[k], 0, "layer {k} cleared after drawing");
                    cleared[k] += 1;
                }
                assert!(
                    p.draws.is_empty() || p.draws.start == draws_into[k],
                    "{p:?}"
                );
                draws_into[k] += p.draws.len();
            }
            assert_eq!(p.eye, p.layer.unwrap_or(0), "{p:?}");
            assert!(!multiview || p.layer.is_some() || p.queries == 0, "{p:?}");
            assert_eq!(p.boxes.start, boxes, "{p:?}");
            if !p.boxes.is_empty() {
                // A layer's boxes go after all its draws, and into that layer.
                assert!(
                    reached.iter().all(|&k| draws_into[k] == queried.len()),
                    "{p:?}"
                );
                let eye_of = |b: usize| if eyes == 0 { None } else { Some(b / per_eye) };
                assert_eq!(eye_of(p.boxes.start), p.layer, "{p:?}");
                assert_eq!(eye_of(p.boxes.end - 1), p.layer, "{p:?}");
            }
            boxes = p.boxes.end;
        }
        assert!(
            draws_into.iter().all(|&d| d == queried.len()),
            "{draws_into:?}"
        );
        assert_eq!(boxes, layers * per_eye);
        assert!(
            cleared.iter().all(|&c| c == usize::from(clear)),
            "{cleared:?}"
        );
        passes
    }

    #[test]
    fn passes_cover_every_draw_and_box_once_per_layer() {
        let queried: Vec<bool> = (0..1500).map(|i| i % 3 == 0).collect();
        let unqueried = vec![false; 1500];
        for clear in [false, true] {
            for per_eye in [0, 1, 700] {
                check(0, false, &queried, per_eye, clear);
                check(0, false, &[], per_eye, clear);
                check(2, false, &queried, per_eye, clear);
                check(2, false, &[], per_eye, clear);
                let passes = check(2, true, &unqueried, per_eye, clear);
                // Multiview: all draws in one pass, boxes a layer at a time.
                assert_eq!(passes[0].draws, 0..1500);
                check(2, true, &[], per_eye, clear);
            }
        }
        // Nothing to do and nothing to clear: no pass.
        assert!(plan_passes(2, true, &[], 0, false).is_empty());
    }
}
