//! Two-pass hierarchical-Z occlusion culling ([`crate::Culling::Hzb`]), as
//! GPU-driven renderers do it (Haar & Aaltonen 2015, Wihlidal 2016, niagara):
//! the first pass draws what was visible last frame; a compute pass builds a
//! depth pyramid from it and tests the box of every candidate in the frustum
//! against the pyramid (a few texel reads each, no fill, no query); the
//! second pass draws the newly visible through indirect draws, compacted per
//! page pair by a count buffer where the device has one, in the same frame.
//! A test is conservative: a box is culled only where its nearest point lies
//! behind the first pass's farthest depth everywhere it covers.
//!
//! Each candidate's result comes back with the frame (4 bytes a candidate)
//! and decides which pass draws it next frame.
//!
//! This is the GPU side (the pyramid, the tests, the second pass); which
//! candidates each pass draws is the strategy's, in `culling/hzb.rs`.

use std::collections::HashMap;

use crate::RenderError;
use crate::device::map_read;
use crate::geometry::ChunkSlot;
use crate::gpu::{HZB_DRAWN, HZB_FORCED, HzbCandidate, HzbParams, QueryBox};
use crate::pipelines::{Faces, HzbPipelines};
use crate::renderer::Renderer;
use crate::round::{Draw, LodPick, Model, ViewGpu, pass_over};
use crate::target::FrameTarget;

/// Bytes of one `DrawIndexedIndirectArgs`.
const ARGS_BYTES: u64 = 20;
/// Timestamps of a second submission: the compute pass's and the second
/// render pass's begin and end.
const TIMESTAMPS: u64 = 4;

/// A view's depth pyramid and the buffers of its box tests.
#[derive(Debug)]
pub(crate) struct HzbGpu {
    size: (u32, u32),
    /// One view per level, and one of them all.
    levels: Vec<wgpu::TextureView>,
    pyramid: wgpu::TextureView,
    params: wgpu::Buffer,
    candidates: wgpu::Buffer,
    /// The second pass's indirect draws, grouped.
    draws: wgpu::Buffer,
    /// Draws per group (the count buffer).
    counts: wgpu::Buffer,
    /// Per candidate: 1 when visible.
    visible: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Timestamps of the compute pass and the second pass (begin, end
    /// each), with their resolve and readback buffers, where the device
    /// has timestamp queries.
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
}

impl HzbGpu {
    fn new(device: &wgpu::Device, size: (u32, u32), timed: bool) -> Self {
        let base = (size.0.div_ceil(2), size.1.div_ceil(2));
        let levels = 32 - base.0.max(base.1).leading_zeros();
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("dmu depth pyramid"),
            size: wgpu::Extent3d {
                width: base.0,
                height: base.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: levels,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let level_views = (0..levels)
            .map(|l| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    base_mip_level: l,
                    mip_level_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        Self {
            size,
            levels: level_views,
            pyramid: texture.create_view(&Default::default()),
            params: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dmu hzb params"),
                size: size_of::<HzbParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            candidates: buffer("dmu hzb candidates", storage),
            draws: buffer("dmu hzb draws", storage | wgpu::BufferUsages::INDIRECT),
            counts: buffer("dmu hzb counts", storage | wgpu::BufferUsages::INDIRECT),
            visible: buffer("dmu hzb visible", storage | wgpu::BufferUsages::COPY_SRC),
            readback: buffer("dmu hzb readback", wgpu::BufferUsages::MAP_READ),
            timestamps: timed.then(|| {
                let bytes = |label, usage| {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size: 8 * TIMESTAMPS,
                        usage,
                        mapped_at_creation: false,
                    })
                };
                (
                    device.create_query_set(&wgpu::QuerySetDescriptor {
                        label: Some("dmu hzb times"),
                        ty: wgpu::QueryType::Timestamp,
                        count: TIMESTAMPS as u32,
                    }),
                    bytes(
                        "dmu hzb time resolve",
                        wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    ),
                    bytes(
                        "dmu hzb time readback",
                        wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    ),
                )
            }),
        }
    }

    /// Grows the buffers to `candidates` candidates, `draws` draws and
    /// `groups` groups.
    fn reserve(&mut self, device: &wgpu::Device, candidates: usize, draws: usize, groups: usize) {
        let grow = |buffer: &mut wgpu::Buffer, need: u64| {
            if buffer.size() < need {
                *buffer = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("dmu hzb buffer"),
                    size: need.max(2 * buffer.size()).next_multiple_of(16),
                    usage: buffer.usage(),
                    mapped_at_creation: false,
                });
            }
        };
        let n = candidates as u64;
        grow(&mut self.candidates, n * size_of::<HzbCandidate>() as u64);
        grow(&mut self.draws, draws as u64 * ARGS_BYTES);
        grow(&mut self.counts, groups as u64 * 4);
        grow(&mut self.visible, n * 4);
        grow(&mut self.readback, n * 4);
    }
}

/// What the second pass draws from: the pool's pages, or one proxy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum GroupKey {
    Pages {
        vertex_page: u32,
        index_page: u32,
        short_indices: bool,
        faces: Faces,
    },
    /// A proxy by its place in the frame's proxies.
    Proxy(u32),
}

/// What an `hzb` frame's second pass tests and draws: the candidates, the
/// proxies' mirror nodes and frames (by place), how chunk levels are picked,
/// and the view's projection (which the box tests use).
#[derive(Clone, Copy)]
pub(crate) struct SecondPassInput<'a> {
    pub projection: glam::DMat4,
    pub candidates: &'a [Candidate],
    pub proxy_nodes: &'a [u32],
    pub proxy_frames: &'a [QueryBox],
    pub lod: Option<LodPick>,
}

/// A candidate of the frame: a chunk instance or a proxy, its box and
/// whether the first pass drew it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    pub kind: CandidateKind,
    pub bounds: QueryBox,
    pub drawn: bool,
    pub forced: bool,
}

/// A chunk instance (entry id), a proxy (its place in the frame's proxies),
/// or one cluster of a proxy (its place, the cluster).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CandidateKind {
    Entry(u32),
    Proxy(u32),
    ProxyCluster(u32, u32),
}

/// The outcome of the second submission.
#[derive(Debug, Default)]
pub(crate) struct SecondPass {
    /// Per candidate, in the order given: visible.
    pub visible: Vec<bool>,
    /// Triangles the second pass drew.
    pub triangles: u64,
    /// Indirect draw calls recorded.
    pub draw_calls: u64,
    /// GPU time of the pyramid and the tests, and of the second pass, ms
    /// (0 without timestamps).
    pub compute_ms: f64,
    pub draw_ms: f64,
    /// Per candidate: a chunk instance the first pass did not draw whose
    /// geometry is not resident, so no pass drew it (it counts as visible,
    /// so it stays wanted).
    pub missing: Vec<bool>,
}

impl Renderer {
    /// Whether a frame into `depth` can use hierarchical-Z culling: the
    /// device draws indirect with a first instance, and the depth target can
    /// be read by a shader.
    pub(crate) fn hzb_supported(&self, depth: &wgpu::TextureView) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::INDIRECT_FIRST_INSTANCE)
            && depth
                .texture()
                .usage()
                .contains(wgpu::TextureUsages::TEXTURE_BINDING)
    }

    /// After the first pass was submitted to draw into `target` (the CPU
    /// work here overlaps its drawing): builds the pyramid from its depth,
    /// tests `candidates` against it and draws those newly visible (not
    /// drawn by the first pass) into `target`, in one submission. The
    /// proxies' frames are `proxy_frames` (by place), the chunk levels picked
    /// with `lod`.
    pub(crate) fn hzb_second_pass(
        &mut self,
        gpu: &mut ViewGpu,
        pyramid: &mut Option<HzbGpu>,
        target: FrameTarget<'_>,
        model: Model<'_>,
        input: &SecondPassInput<'_>,
    ) -> Result<SecondPass, RenderError> {
        let Model {
            scene,
            tree,
            geometry,
        } = model;
        let SecondPassInput {
            projection,
            candidates,
            proxy_nodes,
            proxy_frames,
            lod,
        } = *input;
        let size = {
            let t = target.depth.texture();
            (t.width(), t.height())
        };
        if self.hzb.is_none() {
            self.hzb = Some(HzbPipelines::new(&self.device));
        }
        let mut state = match pyramid.take() {
            Some(s) if s.size == size => s,
            _ => HzbGpu::new(&self.device, size, self.has_timestamps()),
        };
        let mut out = SecondPass::default();

        // Each candidate not drawn yet: its draw and its group.
        let mut groups: Vec<(GroupKey, u32)> = Vec::new();
        let mut group_of: HashMap<GroupKey, u32> = HashMap::new();
        let mut gpu_candidates = Vec::with_capacity(candidates.len());
        let mut triangles_of = Vec::with_capacity(candidates.len());
        // Per proxy candidate: its index range (first, count), the whole
        // proxy's or a cluster's.
        let proxy_of = |n: u32| self.proxies.as_ref()?.cpu.nodes[n as usize].as_deref();
        let proxy_faces: Vec<Faces> = (proxy_nodes.iter())
            .map(|&n| self.faces(gpu, proxy_of(n).is_some_and(|x| x.solid)))
            .collect();
        let proxy_ranges: Vec<(u32, u32)> = (candidates.iter())
            .map(|c| match c.kind {
                CandidateKind::Entry(_) => (0, 0),
                CandidateKind::Proxy(k) => (
                    0,
                    proxy_of(proxy_nodes[k as usize]).map_or(0, |p| p.index_count),
                ),
                CandidateKind::ProxyCluster(k, cl) => {
                    proxy_of(proxy_nodes[k as usize]).map_or((0, 0), |p| {
                        let cluster = p.clusters[cl as usize];
                        (cluster.first_index, cluster.index_count)
                    })
                }
            })
            .collect();
        let tinted = self.proxies_tinted(&self.hierarchy, tree, proxy_nodes);
        out.missing = vec![false; candidates.len()];
        // Candidate i's draw is instance i.
        let mut instances = vec![None; candidates.len()];
        for (i, c) in candidates.iter().enumerate() {
            let mut g = HzbCandidate {
                bounds: c.bounds,
                index_count: 0,
                first_index: 0,
                base_vertex: 0,
                first_instance: 0,
                group: 0,
                slot_base: 0,
                flags: if c.drawn { HZB_DRAWN } else { 0 } | if c.forced { HZB_FORCED } else { 0 },
                _pad: 0,
            };
            let mut triangles = 0;
            if !c.drawn {
                let key = match c.kind {
                    CandidateKind::Entry(e) => match self.resolve_slot(geometry, tree, e, lod) {
                        Some(slot) => {
                            set_draw(&mut g, &slot, i as u32);
                            instances[i] = Some(e);
                            triangles = slot.index_count / 3;
                            Some(GroupKey::Pages {
                                vertex_page: slot.vertex_page,
                                index_page: slot.index_page,
                                short_indices: slot.short_indices,
                                faces: self.faces_of(gpu, scene, tree, e),
                            })
                        }
                        None => {
                            out.missing[i] = true;
                            g.flags = HZB_DRAWN | HZB_FORCED;
                            None
                        }
                    },
                    CandidateKind::Proxy(k) | CandidateKind::ProxyCluster(k, _) => {
                        (g.first_index, g.index_count) = proxy_ranges[i];
                        g.first_instance = k;
                        triangles = g.index_count / 3;
                        Some(GroupKey::Proxy(k))
                    }
                };
                if let Some(key) = key {
                    let next = groups.len() as u32;
                    let id = *group_of.entry(key).or_insert(next);
                    if id == next {
                        groups.push((key, 0));
                    }
                    g.group = id;
                    g.slot_base = groups[id as usize].1; // rank within group for now
                    groups[id as usize].1 += 1;
                }
            }
            gpu_candidates.push(g);
            triangles_of.push(triangles);
        }
        // Groups' first slots: prefix sums of their sizes.
        let mut first_slot = Vec::with_capacity(groups.len());
        let mut total = 0u32;
        for &(_, len) in &groups {
            first_slot.push(total);
            total += len;
        }
        for g in &mut gpu_candidates {
            if g.flags & HZB_DRAWN == 0 {
                g.slot_base = first_slot[g.group as usize];
            }
        }
        state.reserve(
            &self.device,
            candidates.len().max(1),
            total.max(1) as usize,
            groups.len().max(1),
        );
        let params = HzbParams {
            proj: projection.as_mat4().to_cols_array_2d(),
            size: [size.0, size.1],
            levels: state.levels.len() as u32,
            count: candidates.len() as u32,
        };
        self.queue
            .write_buffer(&state.params, 0, bytemuck::bytes_of(&params));
        if !gpu_candidates.is_empty() {
            self.queue
                .write_buffer(&state.candidates, 0, bytemuck::cast_slice(&gpu_candidates));
        }
        self.write_instances(gpu, scene, tree, &instances);
        // Proxies' frames, read by the proxy pipeline at their places.
        if !proxy_frames.is_empty() {
            self.ensure_capacity(gpu, proxy_frames.len());
            self.queue
                .write_buffer(&gpu.boxes, 0, bytemuck::cast_slice(proxy_frames));
        }

        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("dmu hzb"),
            });
        encoder.clear_buffer(&state.counts, 0, Some((groups.len().max(1) * 4) as u64));
        encoder.clear_buffer(&state.draws, 0, Some(u64::from(total.max(1)) * ARGS_BYTES));
        let times = state.timestamps.as_ref().map(|t| &t.0);
        let writes = |first: u32| times.map(|set| (set, Some(first), Some(first + 1)));
        self.encode_pyramid_and_tests(
            &mut encoder,
            &state,
            target.depth,
            candidates.len(),
            writes(0),
        );

        let count_buffer = self
            .device
            .features()
            .contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT);
        if total > 0 {
            let timestamps =
                writes(2).map(|(query_set, begin, end)| wgpu::RenderPassTimestampWrites {
                    query_set,
                    beginning_of_pass_write_index: begin,
                    end_of_pass_write_index: end,
                });
            let mut pass = pass_over(&mut encoder, "dmu hzb second pass", target, timestamps);
            pass.set_bind_group(0, &gpu.bind_groups[0], &[]);
            let mut bound_pipeline = None;
            for (g, &(key, len)) in groups.iter().enumerate() {
                // Whether it draws a proxy (tinted or not), and which faces.
                let pipeline = match key {
                    GroupKey::Pages { faces, .. } => (None, faces),
                    GroupKey::Proxy(k) => (Some(tinted[k as usize]), proxy_faces[k as usize]),
                };
                if bound_pipeline != Some(pipeline) {
                    pass.set_pipeline(match pipeline {
                        (Some(tinted), faces) => self.pipelines.proxy(tinted, faces),
                        (None, faces) => &self.pipelines.shade[faces as usize],
                    });
                    bound_pipeline = Some(pipeline);
                }
                match key {
                    GroupKey::Pages {
                        vertex_page,
                        index_page,
                        short_indices,
                        ..
                    } => {
                        pass.set_vertex_buffer(0, self.pool.vertex_slice(vertex_page));
                        pass.set_vertex_buffer(1, gpu.instances.slice(..));
                        pass.set_index_buffer(
                            self.pool.index_slice(index_page),
                            if short_indices {
                                wgpu::IndexFormat::Uint16
                            } else {
                                wgpu::IndexFormat::Uint32
                            },
                        );
                    }
                    GroupKey::Proxy(k) => {
                        let Some(b) = self
                            .proxies
                            .as_ref()
                            .and_then(|p| p.buffers.get(&proxy_nodes[k as usize]))
                        else {
                            continue;
                        };
                        pass.set_vertex_buffer(0, b.vertices.slice(..));
                        pass.set_vertex_buffer(1, gpu.boxes.slice(..));
                        pass.set_index_buffer(b.indices.slice(..), b.format);
                    }
                }
                let offset = u64::from(first_slot[g]) * ARGS_BYTES;
                if count_buffer {
                    pass.multi_draw_indexed_indirect_count(
                        &state.draws,
                        offset,
                        &state.counts,
                        g as u64 * 4,
                        len,
                    );
                } else {
                    // Unused slots stay cleared: no instances.
                    pass.multi_draw_indexed_indirect(&state.draws, offset, len);
                }
                out.draw_calls += 1;
            }
        }
        let n = candidates.len() as u64 * 4;
        if n > 0 {
            encoder.copy_buffer_to_buffer(&state.visible, 0, &state.readback, 0, n);
        }
        // Only the passes recorded wrote their timestamps.
        let timed = if total > 0 { TIMESTAMPS } else { 2 };
        if let Some((set, resolve, readback)) = &state.timestamps {
            encoder.resolve_query_set(set, 0..timed as u32, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, readback, 0, 8 * timed);
        }
        self.queue.submit([encoder.finish()]);
        let visible: Vec<u32> = if n > 0 {
            map_read(
                &self.device,
                &state.readback,
                n,
                "hzb visibility",
                bytemuck::pod_collect_to_vec,
            )?
        } else {
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| RenderError::Readback {
                    what: "frame completion",
                    reason: e.to_string(),
                })?;
            Vec::new()
        };
        if let (Some((_, _, readback)), Some(period)) =
            (&state.timestamps, self.timestamp_period_ns)
        {
            let ticks: Vec<u64> = map_read(
                &self.device,
                readback,
                8 * timed,
                "hzb timestamps",
                bytemuck::pod_collect_to_vec,
            )?;
            let ms = |k: usize| ticks[k + 1].saturating_sub(ticks[k]) as f64 * period * 1e-6;
            out.compute_ms = ms(0);
            out.draw_ms = if total > 0 { ms(2) } else { 0.0 };
        }
        *pyramid = Some(state);
        out.visible = visible.iter().map(|&v| v != 0).collect();
        out.triangles = candidates
            .iter()
            .zip(&out.visible)
            .zip(&triangles_of)
            .filter(|&((c, &v), _)| v && !c.drawn)
            .map(|(_, &t)| u64::from(t))
            .sum();
        Ok(out)
    }

    /// Records the pyramid's reduction from `depth` and the box tests of
    /// `count` candidates.
    fn encode_pyramid_and_tests(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        state: &HzbGpu,
        depth: &wgpu::TextureView,
        count: usize,
        times: Option<(&wgpu::QuerySet, Option<u32>, Option<u32>)>,
    ) {
        let p = self.hzb.as_ref().expect("made before the first frame");
        let group = |pipeline: &wgpu::ComputePipeline, entries: &[wgpu::BindGroupEntry<'_>]| {
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("dmu hzb"),
                layout: &pipeline.get_bind_group_layout(0),
                entries,
            })
        };
        fn texture(binding: u32, view: &wgpu::TextureView) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: wgpu::BindingResource::TextureView(view),
            }
        }
        fn buffer(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            }
        }
        let mut reductions = vec![(
            &p.reduce_depth,
            group(
                &p.reduce_depth,
                &[
                    texture(0, depth),
                    texture(1, &state.levels[0]),
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::Sampler(&p.gather),
                    },
                ],
            ),
        )];
        for l in 1..state.levels.len() {
            reductions.push((
                &p.reduce_level,
                group(
                    &p.reduce_level,
                    &[
                        texture(0, &state.levels[l - 1]),
                        texture(1, &state.levels[l]),
                    ],
                ),
            ));
        }
        let tests = group(
            &p.test,
            &[
                buffer(0, &state.params),
                buffer(1, &state.candidates),
                texture(2, &state.pyramid),
                buffer(3, &state.draws),
                buffer(4, &state.counts),
                buffer(5, &state.visible),
            ],
        );
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("dmu hzb pyramid and tests"),
            timestamp_writes: times.map(|(query_set, begin, end)| {
                wgpu::ComputePassTimestampWrites {
                    query_set,
                    beginning_of_pass_write_index: begin,
                    end_of_pass_write_index: end,
                }
            }),
        });
        // Level 0 is half the target, rounded up; each next level halves
        // it, rounded down (as mip levels are).
        let (w, h) = (state.size.0.div_ceil(2), state.size.1.div_ceil(2));
        for (l, (pipeline, bind_group)) in reductions.iter().enumerate() {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind_group, &[]);
            let (lw, lh) = ((w >> l).max(1), (h >> l).max(1));
            pass.dispatch_workgroups(lw.div_ceil(8), lh.div_ceil(8), 1);
        }
        if count > 0 {
            pass.set_pipeline(&p.test);
            pass.set_bind_group(0, &tests, &[]);
            let groups = (count as u32).div_ceil(64);
            pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
        }
    }
}

/// Fills a candidate's draw from its chunk's slot; its instance is
/// `instance`.
fn set_draw(g: &mut HzbCandidate, slot: &ChunkSlot, instance: u32) {
    g.index_count = slot.index_count;
    g.first_index = slot.first_index;
    g.base_vertex = slot.first_vertex as i32;
    g.first_instance = instance;
}

/// Candidates of a frame in the order its first pass would draw them.
pub(crate) fn draw_list(candidates: &[Candidate]) -> Vec<Draw> {
    candidates
        .iter()
        .filter_map(|c| match c.kind {
            CandidateKind::Entry(e) if c.drawn => Some(Draw {
                entry: e,
                query: false,
            }),
            _ => None,
        })
        .collect()
}
