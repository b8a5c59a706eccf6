//! Far fields in frames: which parts moved since they were made, their
//! upload, the near field a frame draws as geometry, and the far field drawn
//! over it.

use std::collections::BTreeSet;
use std::sync::Arc;

use dmu_geom::Aabb3d;
use dmu_scene::Scene;
use dmu_tree::{Changes, Tree};
use glam::DVec3;

use crate::error::RenderError;
use crate::pipelines::FarPipeline;
use crate::renderer::Renderer;
use crate::round::pass_over;
use crate::target::FrameTarget;
use crate::view::View;

use super::{FarField, FarFieldGpu, FarState, NearField, UPLOADED_FAR_FIELDS};

/// The far-field pipeline's uniform.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FarUniform {
    proj: [[f32; 4]; 4],
    /// The centre in view space, and the world axes there.
    origin: [f32; 4],
    axis_x: [f32; 4],
    axis_y: [f32; 4],
    axis_z: [f32; 4],
    faces: [[[f32; 4]; 4]; 6],
    resolution: u32,
    _pad: [u32; 3],
}

impl Renderer {
    /// Makes far fields usable by this renderer's views: `scene` as it is now
    /// is the model they were made from, so a part whose transform or
    /// visibility later differs is drawn as geometry and left out of them.
    pub fn enable_far_fields(&mut self, scene: &Scene, tree: &Tree) {
        let parts = scene.parts().len();
        let bits = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dmu moved parts"),
            size: (parts.div_ceil(32).max(1) * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.far_pipeline
            .get_or_insert_with(|| FarPipeline::new(&self.device, self.options.color_format));
        self.far = Some(FarState {
            base: scene.part_ids().map(|p| scene.part_pose_hash(p)).collect(),
            revision: tree.revision(),
            hidden: scene.parts().iter().map(|p| p.hidden).collect(),
            moved: BTreeSet::new(),
            bits,
            bits_current: false,
            uploaded: Vec::new(),
        });
    }

    /// Parts whose transform or visibility differs from the model the far
    /// fields were made from (empty before [`Renderer::enable_far_fields`]).
    pub fn moved_parts(&self) -> BTreeSet<u32> {
        self.far
            .as_ref()
            .map(|f| f.moved.clone())
            .unwrap_or_default()
    }

    /// Brings the moved parts up to date with `scene` and `tree`.
    pub(crate) fn sync_far(&mut self, scene: &Scene, tree: &Tree) {
        let Some(far) = &mut self.far else { return };
        let mut check: Vec<u32> = match tree.changes_since(far.revision) {
            Changes::Rebuild => (0..far.base.len() as u32).collect(),
            Changes::Touched(changes) => changes
                .iter()
                .filter_map(|c| match c {
                    dmu_tree::Change::Entry(e) => Some(tree.entries()[e.0 as usize].part.0),
                    _ => None,
                })
                .collect(),
        };
        far.revision = tree.revision();
        for (p, part) in scene.parts().iter().enumerate() {
            if far.hidden[p] != part.hidden {
                far.hidden[p] = part.hidden;
                check.push(p as u32);
            }
        }
        for p in check {
            let now = scene.part_pose_hash(dmu_scene::PartId::from_index(p as usize));
            let changed = if now == far.base[p as usize] {
                far.moved.remove(&p)
            } else {
                far.moved.insert(p)
            };
            far.bits_current &= !changed;
        }
        if !far.bits_current {
            let mut words = vec![0u32; far.base.len().div_ceil(32).max(1)];
            for &p in &far.moved {
                words[p as usize / 32] |= 1 << (p % 32);
            }
            self.queue
                .write_buffer(&far.bits, 0, bytemuck::cast_slice(&words));
            far.bits_current = true;
        }
    }

    /// The near field of `view`'s frame when its far field serves the eye.
    pub(crate) fn near_field(&self, view: &View, tree: &Tree) -> Option<NearField> {
        let far = self.far.as_ref()?;
        let field = view.far_field.as_ref()?;
        if !field.serves(view.camera.eye) {
            return None;
        }
        let mut always: Vec<u32> = far.moved.iter().copied().collect();
        always.extend_from_slice(&field.excluded);
        always.sort_unstable();
        always.dedup();
        let mut entries = Vec::new();
        tree.entries_in_box(&field.near_box, &mut entries);
        for &p in &always {
            entries.extend(tree.part_entries(dmu_scene::PartId::from_index(p as usize)));
        }
        entries.sort_unstable();
        entries.dedup();
        Some(NearField { entries, always })
    }

    /// Uploads `field` unless it is on the GPU; the most recently used first.
    fn upload_far_field(&mut self, field: &Arc<FarField>) {
        let far = self.far.as_mut().expect("far fields enabled");
        if let Some(i) = far.uploaded.iter().position(|(f, _)| Arc::ptr_eq(f, field)) {
            far.uploaded[..=i].rotate_right(1);
            return;
        }
        let pipeline = self.far_pipeline.as_ref().expect("made with the far state");
        let device = &self.device;
        let buffer = |label, bytes: &[u8], usage| {
            let b = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (bytes.len() as u64).max(16).next_multiple_of(4),
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.queue.write_buffer(&b, 0, bytes);
            b
        };
        let r = field.resolution;
        let texture = |label, format, bytes: &[u8]| {
            let t = device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: r,
                    height: r,
                    depth_or_array_layers: 6,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            self.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &t,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                bytes,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(r * 4),
                    rows_per_image: Some(r),
                },
                wgpu::Extent3d {
                    width: r,
                    height: r,
                    depth_or_array_layers: 6,
                },
            );
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            })
        };
        let color = texture("dmu far colour", crate::CAPTURE_FORMAT, &field.color);
        let parts = texture(
            "dmu far parts",
            wgpu::TextureFormat::R32Uint,
            bytemuck::cast_slice(&field.parts),
        );
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dmu far uniform"),
            size: size_of::<FarUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dmu far field"),
            layout: &pipeline.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&color),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&pipeline.sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&parts),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: far.bits.as_entire_binding(),
                },
            ],
        });
        let mut face_bounds = [Aabb3d::EMPTY; 6];
        for (f, bounds) in face_bounds.iter_mut().enumerate() {
            let range = field.face_starts[f] as usize..field.face_starts[f + 1] as usize;
            *bounds = Aabb3d::from_points(field.indices[range].iter().map(|&i| {
                let v = field.vertices[i as usize];
                DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
            }));
        }
        let gpu = FarFieldGpu {
            vertices: buffer(
                "dmu far vertices",
                bytemuck::cast_slice(&field.vertices),
                wgpu::BufferUsages::VERTEX,
            ),
            indices: buffer(
                "dmu far indices",
                bytemuck::cast_slice(&field.indices),
                wgpu::BufferUsages::INDEX,
            ),
            uniform,
            bind_group,
            face_bounds,
        };
        far.uploaded.insert(0, (field.clone(), gpu));
        far.uploaded.truncate(UPLOADED_FAR_FIELDS);
    }

    /// Draws `view`'s far field over what the frame drew (depth composited),
    /// the faces in the frustum only; returns the triangles drawn.
    pub(crate) fn draw_far_field(
        &mut self,
        view: &View,
        target: FrameTarget<'_>,
    ) -> Result<u64, RenderError> {
        let field = view.far_field.clone().expect("a far field to draw");
        self.upload_far_field(&field);
        let far = self.far.as_ref().expect("far fields enabled");
        let gpu = &far.uploaded[0].1;
        let view_matrix = glam::DAffine3::from_mat4(view.camera.view_matrix());
        let v = |d: DVec3| [d.x as f32, d.y as f32, d.z as f32, 0.0];
        let m = view_matrix.matrix3;
        let mut uniform = FarUniform {
            proj: view.projection().as_mat4().to_cols_array_2d(),
            origin: v(view_matrix.transform_point3(field.center)),
            axis_x: v(m.x_axis),
            axis_y: v(m.y_axis),
            axis_z: v(m.z_axis),
            faces: [[[0.0; 4]; 4]; 6],
            resolution: field.resolution,
            _pad: [0; 3],
        };
        for (f, face) in uniform.faces.iter_mut().enumerate() {
            *face = field.face_view_proj(f).as_mat4().to_cols_array_2d();
        }
        self.queue
            .write_buffer(&gpu.uniform, 0, bytemuck::bytes_of(&uniform));
        let frustum = view.frustum();
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("dmu far field"),
            });
        let mut triangles = 0;
        {
            let mut pass = pass_over(&mut encoder, "dmu far field", target, None);
            let pipeline = self.far_pipeline.as_ref().expect("made with the far state");
            pass.set_pipeline(&pipeline.pipeline);
            pass.set_bind_group(0, &gpu.bind_group, &[]);
            pass.set_vertex_buffer(0, gpu.vertices.slice(..));
            pass.set_index_buffer(gpu.indices.slice(..), wgpu::IndexFormat::Uint32);
            for f in 0..6 {
                let b = gpu.face_bounds[f];
                let (start, end) = (field.face_starts[f], field.face_starts[f + 1]);
                let world = Aabb3d {
                    min: b.min + field.center,
                    max: b.max + field.center,
                };
                if start == end || !frustum.intersects_aabb(&world) {
                    continue;
                }
                pass.draw_indexed(start..end, 0, 0..1);
                triangles += u64::from(end - start) / 3;
            }
        }
        self.queue.submit([encoder.finish()]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Readback {
                what: "far field",
                reason: e.to_string(),
            })?;
        Ok(triangles)
    }
}
