//! A round: one submission of chunk draws, proxies and query boxes into a
//! view's target, read back when the GPU is done. It goes in named steps:
//! plan (resolve the draws' geometry, order them, split them into passes),
//! prepare (instances, boxes, query sets, indirect arguments), record the
//! chunk draws, the proxies and the boxes of each pass, and read back.

use std::ops::Range;

use dmu_scene::Scene;
use dmu_tree::Tree;
use glam::DAffine3;

use crate::RenderError;
use crate::device::map_read;
use crate::geometry::{ChunkSlot, GeometrySource, SlotDraw};
use crate::gpu::{InstanceGpu, QueryBox, ViewUniform};
use crate::pipelines::{Faces, STEREO_VIEWS};
use crate::proxy::ProxyBuffers;
use crate::renderer::Renderer;
use crate::target::{FrameTarget, RoundTarget};

/// The lavapipe bug in Mesa 22.3 returns wrong counts past about 536 occlusion
/// queries in one render pass; 512 were always exact.
pub(crate) const QUERIES_PER_PASS: u32 = 512;
/// Passes per frame whose GPU time is measured.
const TIMED_PASSES: u32 = 64;
/// Bytes of one pass's occlusion query results.
const QUERY_SET_BYTES: u64 = QUERIES_PER_PASS as u64 * 8;
/// Bytes of one indexed indirect draw's arguments.
const DRAW_ARGS_BYTES: u64 = 20;
/// Instance records formed and copied into staging memory at a time.
const INSTANCE_BATCH: usize = 1024;

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
    pub gpu_ms: f64,
    pub gpu_draw_ms: f64,
}

/// A round given to the GPU ([`Renderer::submit_round`]), with what reading
/// its results back needs ([`Renderer::finish_round`]).
#[derive(Debug)]
pub(crate) struct SubmittedRound {
    plan: Plan,
    /// Passes with timestamps.
    timed: usize,
}

/// A view's GPU resources, made on its first frame.
#[derive(Debug)]
pub(crate) struct ViewGpu {
    /// One [`ViewUniform`] per eye, each at a multiple of `uniform_stride`.
    pub(crate) uniform: wgpu::Buffer,
    /// The eyes' world-to-view transforms, as of `prepare_view`.
    pub(crate) eye_views: Vec<DAffine3>,
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

/// What a colour round without queries draws (a frame without occlusion
/// culling, or an `hzb` frame's first pass): chunk instances in canonical
/// order, and proxies (mirror nodes) front to back with their frames.
#[derive(Debug, Default)]
pub(crate) struct ColorDraws {
    pub draws: Vec<Draw>,
    pub nodes: Vec<u32>,
    pub frames: Vec<QueryBox>,
    /// Per node, the clusters of its proxy drawn (bit c: cluster c); empty:
    /// every proxy whole.
    pub clusters: Vec<u64>,
}

impl Renderer {
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

    /// A view's GPU resources, made on its first frame.
    pub(crate) fn make_view_gpu(&self) -> ViewGpu {
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
                layout: &self.pipelines.layout,
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
    ) -> Option<ChunkSlot> {
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
    pub(crate) fn submit_round(
        &mut self,
        gpu: &mut ViewGpu,
        target: RoundTarget<'_>,
        model: Model<'_>,
        round: &Round<'_>,
    ) -> SubmittedRound {
        let mut plan = self.plan_round(gpu, target, model, round);
        let batched = self.prepare_round(gpu, model, round, &plan);
        let proxies = self.round_proxies(gpu, &round.proxies);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("dmu round"),
            });
        let timed = plan.passes.len().min(TIMED_PASSES as usize);
        let mut proxies_drawn_in = [false; 2];
        for (p, pass_plan) in plan.passes.iter().enumerate() {
            let multiview = pass_plan.layer.is_none() && target.is_multiview();
            let mut pass = begin_round_pass(
                &mut encoder,
                gpu,
                RoundPass {
                    index: p,
                    timed: p < timed,
                    target: match pass_plan.layer {
                        Some(eye) => target.eyes[eye],
                        None => target.all,
                    },
                    multiview,
                    clear: pass_plan.clear.then(|| {
                        (!(target.keep_color && round.shading == Shading::Color)).then_some(
                            match round.shading {
                                Shading::Color => self.options.clear_color,
                                Shading::Ids => wgpu::Color::TRANSPARENT,
                            },
                        )
                    }),
                },
                pass_plan.queries > 0,
            );
            pass.set_bind_group(0, &gpu.bind_groups[pass_plan.eye], &[]);
            let mut q = 0;
            plan.result.draw_calls += self.record_chunk_draws(
                &mut pass,
                gpu,
                &plan,
                pass_plan,
                ChunkPipelines {
                    shading: round.shading,
                    multiview,
                    batched,
                },
                &mut q,
            );
            // Proxies go into the first pass of each layer, after its chunks and
            // before its boxes, whose queries they may hide.
            let eye = pass_plan.layer.unwrap_or(0);
            if !proxies.is_empty() && !std::mem::replace(&mut proxies_drawn_in[eye], true) {
                let first_frame = (round.boxes.len() + eye * round.proxies.nodes.len()) as u32;
                let (calls, triangles) = self.record_proxies(&mut pass, gpu, &proxies, first_frame);
                plan.result.draw_calls += calls;
                if eye == 0 {
                    plan.result.triangles += triangles;
                }
            }
            plan.result.draw_calls += self.record_boxes(&mut pass, gpu, pass_plan, &mut q);
            debug_assert_eq!(q, pass_plan.queries);
        }
        self.read_back(&mut encoder, gpu, &plan, timed);
        self.queue.submit([encoder.finish()]);
        plan.result.passes = plan.passes.len() as u32;
        SubmittedRound { plan, timed }
    }

    /// Plans a round: resolves its draws' geometry (uploading what is
    /// missing first: recording borrows the pool's buffers), orders them
    /// (solid meshes first, each kind in draw order, so that a pass changes
    /// pipeline at most once) and splits them and the boxes into passes.
    fn plan_round(
        &mut self,
        gpu: &ViewGpu,
        target: RoundTarget<'_>,
        model: Model<'_>,
        round: &Round<'_>,
    ) -> Plan {
        let Round {
            shading,
            clear,
            draws,
            boxes,
            lod,
            proxies,
        } = *round;
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
        self.slots.clear();
        let mut queried = Vec::with_capacity(draws.len());
        let mut resident = Vec::with_capacity(draws.len());
        for d in draws {
            let slot = self.resolve_slot(model.geometry, model.tree, d.entry, lod);
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
        // Queried draw k's place among the round's queried draws, in draw order.
        let mut rank = Vec::with_capacity(queried.len());
        let mut queried_draws = 0;
        for &wrapped in &queried {
            rank.push(queried_draws);
            queried_draws += usize::from(wrapped);
        }
        // `order[k]` is draw k's place before.
        let faces: Vec<Faces> = (self.slots.iter())
            .map(|&(entry, _)| self.faces_of(gpu, model.scene, model.tree, entry))
            .collect();
        let solid = |k: &usize| faces[*k] == Faces::Solid;
        let mut order: Vec<usize> = (0..faces.len()).filter(solid).collect();
        order.extend((0..faces.len()).filter(|k| !solid(k)));
        self.slots = order.iter().map(|&k| self.slots[k]).collect();
        let queried: Vec<bool> = order.iter().map(|&k| queried[k]).collect();
        let faces: Vec<Faces> = order.iter().map(|&k| faces[k]).collect();
        // A round drawing proxies has a pass into each layer even without
        // chunk draws or boxes (one that clears only where asked).
        let mut passes = plan_passes(
            target.eyes.len(),
            target.multiview,
            &queried,
            per_eye,
            clear || !proxies.nodes.is_empty(),
        );
        if !clear {
            for p in &mut passes {
                p.clear = false;
            }
        }
        let query_count: u32 = passes.iter().map(|p| p.queries).sum();
        Plan {
            need: passes.len() as u64 * QUERY_SET_BYTES,
            result,
            passes,
            queried,
            faces,
            rank,
            order,
            queried_resident: (draws.iter().zip(resident))
                .filter_map(|(d, r)| d.query.then_some(r))
                .collect(),
            per_eye,
            queried_draws,
            query_count,
        }
    }

    /// Prepares a planned round's buffers: the draws' instances, the boxes
    /// and proxies' frames, the query sets and their readback, and the
    /// indirect arguments of batched draws; whether draws are batched.
    fn prepare_round(
        &self,
        gpu: &mut ViewGpu,
        model: Model<'_>,
        round: &Round<'_>,
        plan: &Plan,
    ) -> bool {
        // Draw k's instance is the k-th of its eye's.
        let instances: Vec<Option<u32>> = self.slots.iter().map(|&(e, _)| Some(e)).collect();
        self.write_instances(gpu, model.scene, model.tree, &instances);
        // The proxies' frames follow the query boxes in the same buffer.
        let (boxes, frames) = (round.boxes, round.proxies.frames);
        if !boxes.is_empty() || !frames.is_empty() {
            self.ensure_capacity(gpu, boxes.len() + frames.len());
            self.queue
                .write_buffer(&gpu.boxes, 0, bytemuck::cast_slice(boxes));
            self.queue.write_buffer(
                &gpu.boxes,
                std::mem::size_of_val(boxes) as u64,
                bytemuck::cast_slice(frames),
            );
        }
        while gpu.query_sets.len() < plan.passes.len() {
            gpu.query_sets
                .push(self.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("dmu occlusion"),
                    ty: wgpu::QueryType::Occlusion,
                    count: QUERIES_PER_PASS,
                }));
        }
        if plan.query_count > 0 && gpu.resolve.size() < plan.need {
            let usage_resolve = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
            let usage_read = wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ;
            let size = plan.need.max(gpu.resolve.size() * 2);
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
            && plan.queried.contains(&false);
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
        batched
    }

    /// The round's proxies that have buffers: their place, vertices,
    /// indices, the index ranges of their clusters drawn, and pipeline.
    fn round_proxies<'s>(&'s self, gpu: &ViewGpu, proxies: &ProxyRound<'_>) -> Vec<ProxyDraw<'s>> {
        let Some(p) = &self.proxies else {
            return Vec::new();
        };
        (proxies.nodes.iter().enumerate())
            .filter_map(|(k, &n)| {
                let proxy = p.cpu.nodes[n as usize].as_ref()?;
                let ProxyBuffers {
                    vertices,
                    indices,
                    format,
                } = p.buffers.get(&n)?;
                let mask = proxies.clusters.get(k).copied().unwrap_or(u64::MAX);
                Some(ProxyDraw {
                    place: k as u32,
                    vertices,
                    indices,
                    format: *format,
                    ranges: crate::proxy::cluster_ranges(&proxy.clusters, mask),
                    pipeline: (proxies.tinted[k], self.faces(gpu, proxy.solid)),
                })
            })
            .collect()
    }

    /// Records a pass's chunk draws, batching runs where `how` allows;
    /// numbers its queries from `q` on. Returns the draw calls recorded.
    fn record_chunk_draws(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        gpu: &ViewGpu,
        plan: &Plan,
        pass_plan: &Pass,
        how: ChunkPipelines,
        q: &mut u32,
    ) -> u64 {
        let range = pass_plan.draws.clone();
        if range.is_empty() {
            return 0;
        }
        let eye_instances = |eye: usize| {
            let start = (eye * self.slots.len() * size_of::<InstanceGpu>()) as u64;
            gpu.instances.slice(start..)
        };
        pass.set_vertex_buffer(1, eye_instances(pass_plan.eye));
        if how.multiview {
            pass.set_vertex_buffer(2, eye_instances(1));
        }
        let mut calls = 0;
        let mut bound: Option<(u32, u32, bool)> = None;
        let mut bound_faces = None;
        let mut k = range.start;
        while k < range.end {
            let slot = self.slots[k].1;
            let wrapped = plan.queried[k];
            let draw_faces = plan.faces[k];
            if bound_faces != Some(draw_faces) {
                let p = &self.pipelines;
                pass.set_pipeline(match how.shading {
                    _ if how.multiview => &p
                        .shade_stereo
                        .as_ref()
                        .expect("multiview rounds only where the pipeline exists")
                        [draw_faces as usize],
                    Shading::Color => &p.shade[draw_faces as usize],
                    Shading::Ids => &p.ids[draw_faces as usize],
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
            if how.batched && !wrapped {
                let mut end = k + 1;
                while end < range.end
                    && !plan.queried[end]
                    && plan.faces[end] == plan.faces[k]
                    && pages(&self.slots[end].1) == key
                {
                    end += 1;
                }
                pass.multi_draw_indexed_indirect(
                    &gpu.draw_args,
                    k as u64 * DRAW_ARGS_BYTES,
                    (end - k) as u32,
                );
                calls += 1;
                k = end;
                continue;
            }
            if wrapped {
                pass.begin_occlusion_query(*q);
                *q += 1;
            }
            pass.draw_indexed(
                slot.first_index..slot.first_index + slot.index_count,
                slot.first_vertex as i32,
                k as u32..k as u32 + 1,
            );
            calls += 1;
            if wrapped {
                pass.end_occlusion_query();
            }
            k += 1;
        }
        calls
    }

    /// Records the proxies into a pass, their frames from `first_frame` on
    /// in the box buffer. Returns the draw calls and triangles recorded.
    fn record_proxies(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        gpu: &ViewGpu,
        proxies: &[ProxyDraw<'_>],
        first_frame: u32,
    ) -> (u64, u64) {
        let (mut calls, mut triangles) = (0, 0);
        pass.set_vertex_buffer(1, gpu.boxes.slice(..));
        let mut bound_pipeline = None;
        for d in proxies {
            if bound_pipeline != Some(d.pipeline) {
                pass.set_pipeline(self.pipelines.proxy(d.pipeline.0, d.pipeline.1));
                bound_pipeline = Some(d.pipeline);
            }
            pass.set_vertex_buffer(0, d.vertices.slice(..));
            pass.set_index_buffer(d.indices.slice(..), d.format);
            let frame = first_frame + d.place;
            for range in &d.ranges {
                pass.draw_indexed(range.clone(), 0, frame..frame + 1);
                calls += 1;
                triangles += u64::from(range.len() as u32 / 3);
            }
        }
        (calls, triangles)
    }

    /// Records a pass's query boxes, numbering their queries from `q` on.
    /// Returns the draw calls recorded.
    fn record_boxes(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        gpu: &ViewGpu,
        pass_plan: &Pass,
        q: &mut u32,
    ) -> u64 {
        if pass_plan.boxes.is_empty() {
            return 0;
        }
        pass.set_pipeline(&self.pipelines.boxes);
        pass.set_vertex_buffer(0, gpu.boxes.slice(..));
        // Eye-major: a box's instance is its index in the buffer.
        for b in pass_plan.boxes.clone() {
            let b = b as u32;
            pass.begin_occlusion_query(*q);
            pass.draw(0..36, b..b + 1);
            pass.end_occlusion_query();
            *q += 1;
        }
        pass_plan.boxes.len() as u64
    }

    /// Records the copies that bring the round's query results and the
    /// first `timed` passes' times to the readback buffers.
    fn read_back(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        gpu: &ViewGpu,
        plan: &Plan,
        timed: usize,
    ) {
        for (p, pass_plan) in plan.passes.iter().enumerate() {
            if pass_plan.queries > 0 {
                encoder.resolve_query_set(
                    &gpu.query_sets[p],
                    0..pass_plan.queries,
                    &gpu.resolve,
                    p as u64 * QUERY_SET_BYTES,
                );
            }
        }
        if plan.query_count > 0 {
            encoder.copy_buffer_to_buffer(&gpu.resolve, 0, &gpu.readback, 0, plan.need);
        }
        if let Some((set, resolve, readback)) = &gpu.timestamps
            && timed > 0
        {
            encoder.resolve_query_set(set, 0..2 * timed as u32, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, readback, 0, 16 * timed as u64);
        }
    }

    /// Waits for a round [`Self::submit_round`] gave the GPU and reads its
    /// query results and times.
    pub(crate) fn finish_round(
        &self,
        gpu: &ViewGpu,
        round: SubmittedRound,
    ) -> Result<RoundResult, RenderError> {
        let SubmittedRound { plan: round, timed } = round;
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
            && timed > 0
        {
            let ticks: Vec<u64> = map_read(
                &self.device,
                readback,
                16 * timed as u64,
                "timestamps",
                bytemuck::pod_collect_to_vec,
            )?;
            for (p, pass_plan) in round.passes.iter().take(timed).enumerate() {
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
    begin_pass(encoder, label, target, None, timestamp_writes, None, None)
}

/// A render pass into `target`; with `clear`, its depth is cleared, and its
/// colour too where a colour is given.
fn begin_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    target: FrameTarget<'_>,
    clear: Option<Option<wgpu::Color>>,
    timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
    occlusion_query_set: Option<&wgpu::QuerySet>,
    multiview_mask: Option<std::num::NonZeroU32>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target.color,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: match clear {
                    Some(Some(color)) => wgpu::LoadOp::Clear(color),
                    _ => wgpu::LoadOp::Load,
                },
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: target.depth,
            depth_ops: Some(wgpu::Operations {
                load: match clear {
                    Some(_) => wgpu::LoadOp::Clear(0.0),
                    None => wgpu::LoadOp::Load,
                },
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes,
        occlusion_query_set,
        multiview_mask,
    })
}

/// Pass `index` of a round: into `target` (every layer at once where
/// `multiview`), its timestamps written where `timed`, cleared as `clear`
/// says ([`begin_pass`]).
struct RoundPass<'a> {
    index: usize,
    timed: bool,
    target: FrameTarget<'a>,
    multiview: bool,
    clear: Option<Option<wgpu::Color>>,
}

/// Begins a round's pass, with its query set where it has `queries`.
fn begin_round_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    gpu: &ViewGpu,
    pass: RoundPass<'_>,
    queries: bool,
) -> wgpu::RenderPass<'e> {
    let p = pass.index as u32;
    let timestamp_writes = (gpu.timestamps.as_ref())
        .filter(|_| pass.timed)
        .map(|(set, _, _)| wgpu::RenderPassTimestampWrites {
            query_set: set,
            beginning_of_pass_write_index: Some(2 * p),
            end_of_pass_write_index: Some(2 * p + 1),
        });
    begin_pass(
        encoder,
        "dmu pass",
        pass.target,
        pass.clear,
        timestamp_writes,
        queries.then(|| &gpu.query_sets[pass.index]),
        pass.multiview.then_some(STEREO_VIEWS),
    )
}

/// What a round draws from: the scene, its tree and the source of chunks
/// not yet on the GPU.
#[derive(Clone, Copy)]
pub(crate) struct Model<'a> {
    pub scene: &'a Scene,
    pub tree: &'a Tree,
    pub geometry: &'a dyn GeometrySource,
}

/// What a round draws: with which pipelines, whether it clears the target
/// first, its chunk draws (in order, some wrapped in queries), its query
/// boxes (eye-major), how chunk levels are picked, and its proxies.
#[derive(Clone, Copy)]
pub(crate) struct Round<'a> {
    pub shading: Shading,
    pub clear: bool,
    pub draws: &'a [Draw],
    pub boxes: &'a [QueryBox],
    pub lod: Option<LodPick>,
    pub proxies: ProxyRound<'a>,
}

/// A planned round ([`Renderer::plan_round`]): its resident draws in
/// recorded order, their passes, and what reading the results back needs.
#[derive(Debug)]
struct Plan {
    /// All but the query results, times and draw calls so far.
    result: RoundResult,
    passes: Vec<Pass>,
    /// Per draw in recorded order: wrapped in a query.
    queried: Vec<bool>,
    /// Per draw in recorded order: the faces it draws.
    faces: Vec<Faces>,
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
}

/// A proxy of a round with its buffers: its place among the round's
/// proxies, the index ranges drawn, and its pipeline (tinted, faces).
struct ProxyDraw<'a> {
    place: u32,
    vertices: &'a wgpu::Buffer,
    indices: &'a wgpu::Buffer,
    format: wgpu::IndexFormat,
    ranges: Vec<std::ops::Range<u32>>,
    pipeline: (bool, Faces),
}

/// How a pass's chunk draws are recorded: with which pipelines, into every
/// layer at once (`multiview`), runs batched into indirect multi-draws.
#[derive(Clone, Copy)]
struct ChunkPipelines {
    shading: Shading,
    multiview: bool,
    batched: bool,
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
fn pages(slot: &SlotDraw) -> (u32, u32, bool) {
    (slot.vertex_page, slot.index_page, slot.short_indices)
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
