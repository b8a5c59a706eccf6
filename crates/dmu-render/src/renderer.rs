//! The renderer: what every view shares (the pipelines, the pooled
//! geometry, the per-entry and per-part tables, the tree's mirror, proxies
//! and far fields) and the settings it is made with. A frame is drawn in
//! `frame.rs`, culled by a strategy of `culling/`, in rounds of `round.rs`.

use dmu_scene::{PartId, Scene};
use dmu_tree::Tree;
use glam::DAffine3;

use crate::farfield::FarState;
use crate::geometry::{GeometryPool, GeometrySource, SlotDraw};
use crate::gpu::{EntryGpu, InstanceGpu, PART_CLASHING, PART_HOVERED, PART_SELECTED, ViewUniform};
use crate::hierarchy::Hierarchy;
use crate::pipelines::{FarPipeline, HzbPipelines, Pipelines};
use crate::proxy::{Proxies, ProxyBuffers, ProxyGpu, ProxyStats};
use crate::stereo::StereoMode;

/// The most boxes of flagged parts' chunk instances each proxy is tested
/// against (`Renderer::proxies_tinted`); with more, every proxy is drawn
/// tinted.
const MAX_TINT_TESTS: usize = 256;

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
    pub stereo: StereoMode,
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
            stereo: StereoMode::Auto,
            lod_levels: false,
            batch_draws: true,
            cull_back_faces: true,
        }
    }
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
    pub(crate) pipelines: Pipelines,
    /// Bytes between the eyes' uniforms (the device's uniform offset alignment).
    pub(crate) uniform_stride: u64,
    /// Whether each tree entry's chunk belongs to a solid mesh.
    pub(crate) solid: Vec<bool>,
    pub(crate) entries: wgpu::Buffer,
    pub(crate) materials: wgpu::Buffer,
    /// The materials' colours (rgb), as the GPU's `materials`.
    pub(crate) material_colours: Vec<[f32; 3]>,
    pub(crate) part_flags: Vec<u32>,
    /// The parts with a flag set.
    pub(crate) flagged: std::collections::BTreeSet<PartId>,
    /// Parts whose flags changed since the last frame wrote their entries.
    pub(crate) flags_changed: Vec<PartId>,
    pub(crate) pool: GeometryPool,
    pub(crate) hierarchy: Hierarchy,
    pub(crate) timestamp_period_ns: Option<f64>,
    /// Reused per-round scratch: resolved slots of the round's draws.
    pub(crate) slots: Vec<(u32, SlotDraw)>,
    /// Proxies of the tree's subtrees and their GPU buffers, once set.
    pub(crate) proxies: Option<ProxyGpu>,
    /// The compute pipelines of `hzb` frames, made on the first.
    pub(crate) hzb: Option<HzbPipelines>,
    /// Moved parts and uploaded far fields, once far fields are enabled.
    pub(crate) far: Option<FarState>,
    /// The far-field pipeline, made when far fields are enabled.
    pub(crate) far_pipeline: Option<FarPipeline>,
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
            pipelines: Pipelines::new(device, queue, options.color_format, options.stereo),
            uniform_stride: size_of::<ViewUniform>()
                .next_multiple_of(device.limits().min_uniform_buffer_offset_alignment as usize)
                as u64,
            solid: tree
                .entries()
                .iter()
                .map(|e| scene.mesh(scene.chunk(e.chunk).mesh).solid)
                .collect(),
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
            buffers: std::collections::HashMap::new(),
            cpu: proxies,
        };
        let all: Vec<u32> = (0..gpu.cpu.nodes.len() as u32).collect();
        self.upload_proxies(&mut gpu, &all);
        self.proxies = Some(gpu);
    }

    /// The tree nodes (their slots in `tree`, for `dmu_store::LodCut`) that
    /// hold what a stored proxy shows, with its error: where a loader need
    /// not bring the chunks below once the proxy fits. Empty without stored
    /// proxies.
    pub fn stored_proxy_slots(&mut self, scene: &Scene, tree: &Tree) -> Vec<(u32, f64)> {
        self.hierarchy.sync(tree);
        let Some(p) = self.proxies.as_mut() else {
            return Vec::new();
        };
        p.cpu.sync(&self.hierarchy, scene, tree);
        p.cpu.stored_slots(&self.hierarchy, tree.entries().len())
    }

    /// Lists in `drawn` what drawing node `n`'s proxy (of `h`, this
    /// renderer's mirror, which a frame may hold apart) drew: the chunk
    /// instances below it, approximated, for proxies made in memory; nothing
    /// for a store's, which stand for chunks that need not be loaded (a
    /// loader asked for them all would bring the model in).
    pub(crate) fn proxy_drawn(&self, h: &Hierarchy, n: u32, drawn: &mut Vec<u32>) {
        if self
            .proxies
            .as_ref()
            .is_some_and(|p| p.cpu.stored.is_none())
        {
            h.leaves(n, drawn);
        }
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
        gpu.cpu.refresh(&self.hierarchy, scene, tree, geometry);
        gpu.cpu.load_requested();
        let spent = if gpu.cpu.dirty.is_empty() {
            std::time::Duration::ZERO
        } else {
            let dirty = std::mem::take(&mut gpu.cpu.dirty);
            self.upload_proxies(&mut gpu, &dirty);
            start.elapsed()
        };
        self.proxies = Some(gpu);
        spent
    }

    /// Uploads the proxies of mirror nodes `nodes` (dropping the buffers of
    /// those that have none now).
    fn upload_proxies(&self, gpu: &mut ProxyGpu, nodes: &[u32]) {
        for &n in nodes {
            let made = gpu.cpu.nodes[n as usize]
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
                    // 16-bit indices where the vertices allow: half their
                    // bytes (padded to the 4 bytes a buffer write takes).
                    let mut short: Vec<u16> = Vec::new();
                    let (indices, format) = if p.short_indices() {
                        short.extend(p.indices.iter().map(|&i| i as u16));
                        if short.len() % 2 == 1 {
                            short.push(0);
                        }
                        (bytemuck::cast_slice(&short), wgpu::IndexFormat::Uint16)
                    } else {
                        (bytemuck::cast_slice(&p.indices), wgpu::IndexFormat::Uint32)
                    };
                    ProxyBuffers {
                        vertices: buffer(
                            "dmu proxy vertices",
                            bytemuck::cast_slice(&p.vertices),
                            wgpu::BufferUsages::VERTEX,
                        ),
                        indices: buffer("dmu proxy indices", indices, wgpu::BufferUsages::INDEX),
                        format,
                    }
                });
            // A stored proxy's CPU copy goes once uploaded: nothing is made
            // from it, and its budget counts the GPU's.
            if made.is_some()
                && gpu.cpu.is_stored()
                && let Some(p) = gpu.cpu.nodes[n as usize].as_mut()
            {
                p.vertices = Vec::new();
                p.indices = Vec::new();
            }
            // Freed at once: dropping a buffer leaves its memory to wgpu's
            // next cleanup, while a store's proxies come and go every frame.
            let old = match made {
                Some(buffers) => gpu.buffers.insert(n, buffers),
                None => gpu.buffers.remove(&n),
            };
            if let Some(old) = old {
                old.vertices.destroy();
                old.indices.destroy();
            }
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

    /// How stereo pairs are drawn: [`StereoMode::Multiview`] or
    /// [`StereoMode::LayerPasses`] (`Auto` resolved when the renderer
    /// was made).
    pub fn stereo_mode(&self) -> StereoMode {
        self.pipelines.stereo_mode
    }

    /// Whether [`Renderer::render_stereo`] can draw: multiview was asked for
    /// on a device without it.
    pub(crate) fn stereo_unsupported(&self) -> bool {
        self.pipelines.stereo_mode == StereoMode::Multiview && self.pipelines.shade_stereo.is_none()
    }

    /// Whether GPU times in the stats come from timestamp queries.
    pub fn has_timestamps(&self) -> bool {
        self.timestamp_period_ns.is_some()
    }

    /// The instance of a draw of tree entry `entry` in the eye whose
    /// world-to-view is `eye_view`: its part's model-view, formed in f64 (the
    /// eye's large translation cancels the part's before anything is
    /// rounded to f32, so far-from-origin models stay exact, and a stereo
    /// eye gets what a single view from there gets), and its colour by the
    /// rule of `base_colour` in `mesh.wgsl` (which a driver may round a last
    /// place differently).
    pub(crate) fn instance(
        &self,
        scene: &Scene,
        tree: &Tree,
        eye_view: DAffine3,
        entry: u32,
    ) -> InstanceGpu {
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
}

/// The GPU record of a chunk instance whose part has `flags`.
fn entry_gpu(scene: &Scene, entry: &dmu_tree::Entry, flags: u32) -> EntryGpu {
    EntryGpu::new(scene.chunk(entry.chunk).material.0, flags)
}
