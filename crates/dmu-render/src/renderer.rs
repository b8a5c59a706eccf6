//! The renderer: pipelines, shared buffers, per-view GPU state, and one round
//! of drawing and querying.

use dmu_scene::{PartId, Scene};
use dmu_tree::Tree;

use crate::RenderError;
use crate::capture::{DEPTH_FORMAT, ID_FORMAT};
use crate::device::map_read;
use crate::geometry::{GeometryPool, GeometrySource, PoolVertex};
use crate::gpu::{EntryGpu, ModelView, PART_SELECTED, QueryBox, SHADER, ViewUniform};
use crate::hierarchy::Hierarchy;

/// The lavapipe bug in Mesa 22.3 returns wrong counts past about 536 occlusion
/// queries in one render pass; 512 were always exact.
pub(crate) const QUERIES_PER_PASS: u32 = 512;
/// Passes per frame whose GPU time is measured.
const TIMED_PASSES: u32 = 64;

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

/// Settings fixed when the renderer is made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RendererOptions {
    /// Format of the colour targets it draws into.
    pub color_format: wgpu::TextureFormat,
    /// Size of each pooled geometry buffer.
    pub page_bytes: u64,
    /// Selection colour (rgb, linear) and its weight (a).
    pub highlight: [f32; 4],
    /// Background colour (linear).
    pub clear_color: wgpu::Color,
}

impl Default for RendererOptions {
    fn default() -> Self {
        Self {
            color_format: crate::CAPTURE_FORMAT,
            page_bytes: 64 << 20,
            highlight: [1.0, 0.55, 0.0, 0.7],
            clear_color: wgpu::Color {
                r: 0.02,
                g: 0.025,
                b: 0.035,
                a: 1.0,
            },
        }
    }
}

/// A draw of one chunk instance, optionally wrapped in an occlusion query.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Draw {
    pub entry: u32,
    pub query: bool,
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
    pub gpu_ms: f64,
    pub gpu_draw_ms: f64,
}

/// A view's GPU resources, made on its first frame.
#[derive(Debug)]
pub(crate) struct ViewGpu {
    uniform: wgpu::Buffer,
    model_views: wgpu::Buffer,
    boxes: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    query_sets: Vec<wgpu::QuerySet>,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    /// Reused model-view staging.
    staging: Vec<ModelView>,
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
    shade: wgpu::RenderPipeline,
    ids: wgpu::RenderPipeline,
    boxes_color: wgpu::RenderPipeline,
    entries: wgpu::Buffer,
    part_flags_buffer: wgpu::Buffer,
    materials: wgpu::Buffer,
    part_flags: Vec<u32>,
    pub(crate) pool: GeometryPool,
    pub(crate) hierarchy: Hierarchy,
    timestamp_period_ns: Option<f64>,
    /// Reused per-round scratch: resolved slots of the round's draws.
    slots: Vec<(u32, crate::geometry::ChunkSlot)>,
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
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("dmu mesh.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
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
                storage(3),
                storage(4),
                storage(5),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("dmu"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let mesh_buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: size_of::<PoolVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Snorm8x4],
        })];
        let pipeline =
            |label, vs, buffers: &[Option<wgpu::VertexBufferLayout>], fs, format, write: bool| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some(vs),
                        compilation_options: Default::default(),
                        buffers,
                    },
                    // CAD windings are unreliable: nothing is culled.
                    primitive: wgpu::PrimitiveState {
                        topology: wgpu::PrimitiveTopology::TriangleList,
                        cull_mode: None,
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
                        module: &module,
                        entry_point: Some(fs),
                        compilation_options: Default::default(),
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
                    multiview_mask: None,
                    cache: None,
                })
            };
        let shade = pipeline(
            "dmu shade",
            "vs_mesh",
            &mesh_buffers,
            "fs_shade",
            options.color_format,
            true,
        );
        let ids = pipeline(
            "dmu ids",
            "vs_mesh",
            &mesh_buffers,
            "fs_id",
            ID_FORMAT,
            true,
        );
        let boxes_color = pipeline(
            "dmu query boxes",
            "vs_box",
            &[],
            "fs_box",
            options.color_format,
            false,
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
            .map(|e| EntryGpu {
                part: e.part.0,
                material: scene.chunk(e.chunk).material.0,
            })
            .collect();
        let materials: Vec<[f32; 4]> = scene.materials().iter().map(|m| m.base_color).collect();
        let part_flags = vec![0u32; scene.parts().len()];
        Self {
            entries: storage_buffer("dmu entries", bytemuck::cast_slice(&entry_table)),
            materials: storage_buffer("dmu materials", bytemuck::cast_slice(&materials)),
            part_flags_buffer: storage_buffer("dmu part flags", bytemuck::cast_slice(&part_flags)),
            part_flags,
            device: device.clone(),
            queue: queue.clone(),
            options,
            layout,
            shade,
            ids,
            boxes_color,
            pool: GeometryPool::new(scene.chunks().len(), options.page_bytes),
            hierarchy: Hierarchy::default(),
            timestamp_period_ns: device
                .features()
                .contains(wgpu::Features::TIMESTAMP_QUERY)
                .then(|| f64::from(queue.get_timestamp_period())),
            slots: Vec::new(),
        }
    }

    /// Highlights a part or not; writes one word to the GPU.
    pub fn set_selected(&mut self, part: PartId, selected: bool) {
        let flags = &mut self.part_flags[part.index()];
        *flags = if selected {
            *flags | PART_SELECTED
        } else {
            *flags & !PART_SELECTED
        };
        self.queue.write_buffer(
            &self.part_flags_buffer,
            4 * part.index() as u64,
            bytemuck::bytes_of(flags),
        );
    }

    /// The pooled geometry (resident chunks, bytes; eviction).
    pub fn geometry_pool(&mut self) -> &mut GeometryPool {
        &mut self.pool
    }

    /// Whether GPU times in the stats come from timestamp queries.
    pub fn has_timestamps(&self) -> bool {
        self.timestamp_period_ns.is_some()
    }

    /// Makes or grows a view's GPU resources and uploads its per-frame data:
    /// the projection and every part's camera-relative model-view.
    pub(crate) fn prepare_view(
        &self,
        gpu: &mut Option<ViewGpu>,
        scene: &Scene,
        proj: glam::DMat4,
        view_matrix: glam::DAffine3,
    ) {
        let g = gpu.get_or_insert_with(|| self.make_view_gpu(scene.parts().len().max(1)));
        let uniform = ViewUniform {
            proj: proj.as_mat4().to_cols_array_2d(),
            highlight: self.options.highlight,
        };
        self.queue
            .write_buffer(&g.uniform, 0, bytemuck::bytes_of(&uniform));
        // Formed in f64: the view's large translation cancels the part's before
        // anything is rounded to f32, so far-from-origin models stay exact.
        g.staging.clear();
        g.staging.extend(scene.part_ids().map(|p| {
            let m = view_matrix * scene.part_world(p);
            let (a, t) = (m.matrix3, m.translation);
            let row = |i: usize| {
                [
                    a.x_axis[i] as f32,
                    a.y_axis[i] as f32,
                    a.z_axis[i] as f32,
                    t[i] as f32,
                ]
            };
            ModelView {
                rows: [row(0), row(1), row(2)],
            }
        }));
        if !g.staging.is_empty() {
            self.queue
                .write_buffer(&g.model_views, 0, bytemuck::cast_slice(&g.staging));
        }
    }

    fn make_view_gpu(&self, parts: usize) -> ViewGpu {
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
            "dmu view uniform",
            size_of::<ViewUniform>() as u64,
            wgpu::BufferUsages::UNIFORM | copy_dst,
        );
        let model_views = buffer(
            "dmu model-views",
            (parts * size_of::<ModelView>()) as u64,
            wgpu::BufferUsages::STORAGE | copy_dst,
        );
        let boxes = buffer(
            "dmu query boxes",
            64 * size_of::<QueryBox>() as u64,
            wgpu::BufferUsages::STORAGE | copy_dst,
        );
        let bind_group = self.bind_group(&uniform, &model_views, &boxes);
        ViewGpu {
            uniform,
            model_views,
            boxes,
            bind_group,
            query_sets: Vec::new(),
            resolve: buffer("dmu query resolve", 8, resolve_usage),
            readback: buffer("dmu query readback", 8, read_usage),
            timestamps,
            staging: Vec::new(),
        }
    }

    fn bind_group(
        &self,
        uniform: &wgpu::Buffer,
        model_views: &wgpu::Buffer,
        boxes: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            }
        }
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dmu view"),
            layout: &self.layout,
            entries: &[
                entry(0, uniform),
                entry(1, model_views),
                entry(2, &self.entries),
                entry(3, &self.part_flags_buffer),
                entry(4, &self.materials),
                entry(5, boxes),
            ],
        })
    }

    /// Grows a view's box buffer (and so its bind group) to hold `count` boxes.
    fn ensure_box_capacity(&self, gpu: &mut ViewGpu, count: usize) {
        let need = (count * size_of::<QueryBox>()) as u64;
        if gpu.boxes.size() >= need {
            return;
        }
        gpu.boxes = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dmu query boxes"),
            size: need.max(2 * gpu.boxes.size()),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.bind_group = self.bind_group(&gpu.uniform, &gpu.model_views, &gpu.boxes);
    }

    /// One submission: draws (in the given order, some wrapped in queries), then
    /// box queries against the depth they leave, split into passes of at most
    /// [`QUERIES_PER_PASS`] queries; then waits for the query results.
    #[expect(
        clippy::too_many_arguments,
        reason = "one call site per mode; a struct would only rename them"
    )]
    pub(crate) fn run_round(
        &mut self,
        gpu: &mut ViewGpu,
        target: FrameTarget<'_>,
        shading: Shading,
        clear: bool,
        geometry: &dyn GeometrySource,
        tree: &Tree,
        draws: &[Draw],
        boxes: &[QueryBox],
    ) -> Result<RoundResult, RenderError> {
        let mut result = RoundResult::default();
        // Upload what is missing first: recording borrows the pool's buffers.
        self.slots.clear();
        let mut queried = Vec::with_capacity(draws.len());
        for d in draws {
            let chunk = tree.entries()[d.entry as usize].chunk;
            match self.pool.ensure(&self.device, &self.queue, geometry, chunk) {
                Some(slot) => {
                    self.slots.push((d.entry, slot));
                    queried.push(d.query);
                    result.chunks += 1;
                    result.triangles += u64::from(slot.index_count / 3);
                }
                None => result.not_resident += 1,
            }
        }
        if !boxes.is_empty() {
            self.ensure_box_capacity(gpu, boxes.len());
            self.queue
                .write_buffer(&gpu.boxes, 0, bytemuck::cast_slice(boxes));
        }
        let query_count = queried.iter().filter(|&&q| q).count() + boxes.len();
        let total = self.slots.len() + boxes.len();
        // Passes: each item is a draw or a box; a pass ends at the query limit.
        let mut pass_ranges: Vec<(usize, usize, u32)> = Vec::new();
        let (mut start, mut queries) = (0, 0u32);
        let item_queries = queried.iter().copied().chain(boxes.iter().map(|_| true));
        for (i, needs_query) in item_queries.enumerate() {
            if needs_query && queries == QUERIES_PER_PASS {
                pass_ranges.push((start, i, queries));
                (start, queries) = (i, 0);
            }
            queries += u32::from(needs_query);
        }
        if total > start || (clear && pass_ranges.is_empty()) {
            pass_ranges.push((start, total, queries));
        }
        while gpu.query_sets.len() < pass_ranges.len() {
            gpu.query_sets
                .push(self.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("dmu occlusion"),
                    ty: wgpu::QueryType::Occlusion,
                    count: QUERIES_PER_PASS,
                }));
        }
        let set_bytes = u64::from(QUERIES_PER_PASS) * 8;
        let need = pass_ranges.len() as u64 * set_bytes;
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

        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("dmu round"),
            });
        let timed = pass_ranges.len().min(TIMED_PASSES as usize);
        for (p, &(from, to, pass_queries)) in pass_ranges.iter().enumerate() {
            let first = p == 0 && clear;
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
                    view: target.color,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: if first {
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
                    view: target.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: if first {
                            wgpu::LoadOp::Clear(0.0)
                        } else {
                            wgpu::LoadOp::Load
                        },
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes,
                occlusion_query_set: (pass_queries > 0).then(|| &gpu.query_sets[p]),
                multiview_mask: None,
            });
            pass.set_bind_group(0, &gpu.bind_group, &[]);
            let mut q = 0;
            let mut bound: Option<(u32, u32, bool)> = None;
            let draws_end = to.min(self.slots.len());
            if from < draws_end {
                pass.set_pipeline(match shading {
                    Shading::Color => &self.shade,
                    Shading::Ids => &self.ids,
                });
            }
            for (&(entry, slot), &wrapped) in self.slots[from.min(draws_end)..draws_end]
                .iter()
                .zip(&queried[from.min(draws_end)..draws_end])
            {
                let key = (slot.vertex_page, slot.index_page, slot.short_indices);
                if bound != Some(key) {
                    pass.set_vertex_buffer(0, self.pool.vertex_buffer(slot.vertex_page).slice(..));
                    let format = if slot.short_indices {
                        wgpu::IndexFormat::Uint16
                    } else {
                        wgpu::IndexFormat::Uint32
                    };
                    pass.set_index_buffer(
                        self.pool.index_buffer(slot.index_page).slice(..),
                        format,
                    );
                    bound = Some(key);
                }
                if wrapped {
                    pass.begin_occlusion_query(q);
                    q += 1;
                }
                pass.draw_indexed(
                    slot.first_index..slot.first_index + slot.index_count,
                    slot.first_vertex as i32,
                    entry..entry + 1,
                );
                if wrapped {
                    pass.end_occlusion_query();
                }
            }
            let boxes_from = from.max(self.slots.len());
            if boxes_from < to {
                pass.set_pipeline(&self.boxes_color);
                for i in boxes_from..to {
                    let b = (i - self.slots.len()) as u32;
                    pass.begin_occlusion_query(q);
                    pass.draw(0..36, b..b + 1);
                    pass.end_occlusion_query();
                    q += 1;
                }
            }
            debug_assert_eq!(q, pass_queries);
        }
        for (p, &(_, _, n)) in pass_ranges.iter().enumerate() {
            if n > 0 {
                encoder.resolve_query_set(
                    &gpu.query_sets[p],
                    0..n,
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

        result.passes = pass_ranges.len() as u32;
        if query_count > 0 {
            let samples: Vec<u64> = map_read(
                &self.device,
                &gpu.readback,
                need,
                "occlusion queries",
                bytemuck::pod_collect_to_vec,
            )?;
            // Query q of pass p sits at p * QUERIES_PER_PASS + q; walk in item order.
            let mut at = pass_ranges.iter().enumerate().flat_map(|(p, &(_, _, n))| {
                (0..n as usize).map(move |q| p * QUERIES_PER_PASS as usize + q)
            });
            for &wrapped in &queried {
                if wrapped {
                    result
                        .draw_samples
                        .push(samples[at.next().expect("one slot per query")]);
                }
            }
            for _ in boxes {
                result
                    .box_samples
                    .push(samples[at.next().expect("one slot per query")]);
            }
        } else if total > 0 || clear {
            // Nothing to read, but the caller's timing must include the work.
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| RenderError::Readback {
                    what: "frame completion",
                    reason: e.to_string(),
                })?;
        }
        if let (Some((_, _, readback)), Some(period)) = (&gpu.timestamps, self.timestamp_period_ns)
            && timed > 0
        {
            let ticks: Vec<u64> = map_read(
                &self.device,
                readback,
                16 * timed as u64,
                "timestamps",
                bytemuck::pod_collect_to_vec,
            )?;
            for (p, &(from, _, _)) in pass_ranges.iter().take(timed).enumerate() {
                let ms = ticks[2 * p + 1].saturating_sub(ticks[2 * p]) as f64 * period * 1e-6;
                result.gpu_ms += ms;
                if from < self.slots.len() {
                    result.gpu_draw_ms += ms;
                }
            }
        }
        Ok(result)
    }
}
