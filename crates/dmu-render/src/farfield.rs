//! Far fields (MMR's textured depth meshes): beyond a cull box around the
//! viewer, the model is replaced by six depth meshes captured from the centre
//! of the viewpoint cell the eye is in, textured projectively with the
//! captured colour.
//!
//! A far field is made by [`Renderer::capture_far_field`]: six square views
//! (a cube map whose faces overlap by a few pixels, so no seam opens between
//! them) draw every chunk instance that does not touch the cull box, their
//! colour, depth and part ids are read back, and each face's depth becomes a
//! grid mesh that is simplified with meshoptimizer in the space of (pixel x,
//! pixel y, parallax): a vertex's third coordinate is how many pixels it moves
//! when the eye moves from the centre to the cell's corner, so the one bound
//! `mesh_error_px` holds for image position and for parallax alike. Planes stay
//! planes in that space (a plane's inverse depth is linear in the pixel
//! coordinates), so planar runs merge into a few triangles. Quads across a
//! depth discontinuity are kept ("skins": seen edge-on from the centre, they
//! show the silhouette's colour stretched when the eye moves off it) or
//! dropped (holes instead), by [`FarFieldOptions::skins`]; the walk measures
//! both against the full image.
//!
//! A frame of a [`View`] whose [`View::far_field`] serves the eye draws the
//! chunk instances touching the cull box (the near field) as usual, then the
//! far field's meshes into the same depth. Edits: a part whose transform or
//! visibility differs from the model the far fields were made from
//! ([`Renderer::enable_far_fields`]) is drawn as geometry wherever it is, and
//! the far field's texels showing it are discarded, so it never shows at its
//! old place; [`FarField::is_stale`] says which far fields need capturing
//! again (their owner does it, [`Renderer::capture_far_field`] leaving out the
//! moved parts).

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::Instant;

use dmu_geom::Aabb3d;
use dmu_scene::Scene;
use dmu_tree::{Changes, EntryId, Revision, Tree};
use glam::{DMat4, DVec3, DVec4};

use crate::capture::Capture;
use crate::geometry::GeometrySource;
use crate::renderer::{FrameTarget, Renderer};
use crate::view::{Culling, View};
use crate::{Camera, RenderError};

/// The six faces of a far field: +X, -X, +Y, -Y, +Z, -Z (forward, up).
const FACES: [(DVec3, DVec3); 6] = [
    (DVec3::X, DVec3::Z),
    (DVec3::NEG_X, DVec3::Z),
    (DVec3::Y, DVec3::Z),
    (DVec3::NEG_Y, DVec3::Z),
    (DVec3::Z, DVec3::Y),
    (DVec3::NEG_Z, DVec3::Y),
];

/// Pixels by which neighbouring faces overlap at their shared edge.
const OVERLAP_PX: f64 = 2.0;

/// Resolutions a far field may have (pixels per face side).
pub const FAR_FIELD_RESOLUTIONS: std::ops::RangeInclusive<u32> = 16..=4096;

/// How a far field is captured and meshed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FarFieldOptions {
    /// Pixels per face side (the texture's, and the grid's before meshing).
    pub resolution: u32,
    /// Pixels between depth-mesh grid vertices.
    pub grid_step: u32,
    /// Simplification bound of the depth meshes, pixels of the capture: of
    /// image position, and of parallax as the eye moves to the cell's corner.
    pub mesh_error_px: f64,
    /// LOD error the captures draw with, pixels of the capture.
    pub lod_error_px: f64,
    /// Keep the triangles across depth discontinuities (skins) rather than
    /// leaving holes there.
    pub skins: bool,
}

impl Default for FarFieldOptions {
    fn default() -> Self {
        Self {
            resolution: 512,
            grid_step: 4,
            mesh_error_px: 1.0,
            lod_error_px: 0.5,
            skins: true,
        }
    }
}

/// A quad is a skin when its farthest corner is this much farther than its
/// nearest (1.25: a wall seen at 80 degrees off its normal over 4 pixels of
/// a 512-pixel face still is not one).
const SKIN_RATIO: f64 = 1.25;

/// The background (where a capture hit nothing) lies this many times
/// farther than the farthest sample that hit something.
const BACKGROUND: f64 = 4.0;

/// One viewpoint cell's far field: depth meshes and their captured colour
/// and part ids. Positions are f32 relative to `center` (an f64 origin).
#[derive(Clone, Debug, PartialEq)]
pub struct FarField {
    /// Where it was captured from: the cell's centre.
    pub center: DVec3,
    /// The eye positions it serves.
    pub cell: Aabb3d,
    /// The cull box: chunk instances touching it are the near field, drawn
    /// as geometry; the rest is in the far field.
    pub near_box: Aabb3d,
    /// Pixels per face side.
    pub resolution: u32,
    /// Tangent of each face's half angle (a little over 1: faces overlap).
    pub tan_half: f32,
    /// Depth-mesh vertices: x, y, z relative to `center`, and the face (0-5).
    pub vertices: Vec<[f32; 4]>,
    /// Triangles, face by face.
    pub indices: Vec<u32>,
    /// Where each face's triangles start in `indices` (and the end).
    pub face_starts: [u32; 7],
    /// Colour of the six faces, face-major, rows top to bottom, RGBA8 sRGB.
    pub color: Vec<u8>,
    /// Part id + 1 of each texel (0: nothing there), as `color`.
    pub parts: Vec<u32>,
    /// Parts showing in it, sorted.
    pub seen: Vec<u32>,
    /// Parts left out of it (moved when it was captured; drawn as geometry),
    /// sorted.
    pub excluded: Vec<u32>,
    /// The depth meshes' simplification bound, pixels.
    pub mesh_error_px: f32,
    /// Time the capture and meshing took, ms.
    pub build_ms: f64,
}

/// What one far field's capture did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FarFieldBuild {
    /// Grid triangles before simplification.
    pub grid_triangles: u64,
    /// Triangles kept.
    pub triangles: u64,
    /// Time drawing and reading the six faces back, ms.
    pub capture_ms: f64,
    /// Time meshing and simplifying, ms.
    pub mesh_ms: f64,
}

impl FarField {
    /// True when an eye at `p` may use it.
    pub fn serves(&self, p: DVec3) -> bool {
        self.cell.contains_point(p) && self.near_box.contains_point(p)
    }

    /// Triangles of its depth meshes.
    pub fn triangles(&self) -> u64 {
        self.indices.len() as u64 / 3
    }

    /// True when it no longer shows the model as it is: a part showing in it
    /// has moved (is in `moved`), or a part it left out is back in place.
    pub fn is_stale(&self, moved: &BTreeSet<u32>) -> bool {
        self.seen.iter().any(|p| moved.contains(p))
            || self.excluded.iter().any(|p| !moved.contains(p))
    }

    /// The face cameras' view-projection relative to `center` (f32 on the GPU).
    fn face_view_proj(&self, face: usize) -> DMat4 {
        face_camera(DVec3::ZERO, face, f64::from(self.tan_half), 1.0).view_proj()
    }
}

/// The camera of `face` at `center`, `tan_half` the tangent of its half angle.
fn face_camera(center: DVec3, face: usize, tan_half: f64, near: f64) -> FaceCamera {
    let (forward, up) = FACES[face];
    FaceCamera {
        camera: Camera {
            eye: center,
            target: center + forward,
            up,
            fov_y_rad: 2.0 * tan_half.atan(),
            near,
        },
    }
}

struct FaceCamera {
    camera: Camera,
}

impl FaceCamera {
    fn view_proj(&self) -> DMat4 {
        self.camera.projection(1.0) * self.camera.view_matrix()
    }
}

/// A frame's near field: the chunk instances touching the cull box and
/// those of the parts drawn as geometry wherever they are (found once a
/// frame, with the tree's box query).
#[derive(Clone, Debug)]
pub(crate) struct NearField {
    /// Sorted, each once.
    pub entries: Vec<EntryId>,
    /// Parts drawn as geometry wherever they are.
    pub always: Vec<u32>,
}

/// A capture's filter: what does not touch the cull box, less the parts left
/// out.
#[derive(Clone, Debug)]
pub(crate) struct FarOnly {
    pub near_box: Aabb3d,
    pub excluded: BTreeSet<u32>,
}

/// Which of a frame's chunk instances it draws, when far fields are involved.
#[derive(Clone, Debug, Default)]
pub(crate) enum FarCut {
    /// All (no far field).
    #[default]
    None,
    /// The near field of a far field drawn too.
    Near(NearField),
    /// What a far field captures.
    FarOnly(FarOnly),
}

/// Moved parts, against the model the far fields were made from.
#[derive(Debug)]
pub(crate) struct FarState {
    /// Per part: a hash of its world transform and hidden flag then.
    base: Vec<u64>,
    revision: Revision,
    hidden: Vec<bool>,
    moved: BTreeSet<u32>,
    /// `moved` as bits, on the GPU for the far-field shader.
    bits: wgpu::Buffer,
    bits_current: bool,
    /// Uploaded far fields, most recently used first.
    uploaded: Vec<(Arc<FarField>, FarFieldGpu)>,
}

/// Far fields kept on the GPU at once.
const UPLOADED_FAR_FIELDS: usize = 4;

fn part_hash(scene: &Scene, p: dmu_scene::PartId) -> u64 {
    let m = scene.part_world(p);
    let mut h = fnv(bytemuck::cast_slice(&m.to_cols_array()));
    h ^= u64::from(scene.part(p).hidden);
    h
}

/// FNV-1a over bytes: a change detector, not a checksum.
fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[derive(Debug)]
pub(crate) struct FarFieldGpu {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Each face's bounds relative to the centre (empty: nothing there).
    face_bounds: [Aabb3d; 6],
}

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

#[derive(Debug)]
pub(crate) struct FarPipeline {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
}

const FAR_SHADER: &str = include_str!("../../../shaders/farfield.wgsl");

impl FarPipeline {
    pub fn new(device: &wgpu::Device, color_format: wgpu::TextureFormat) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("dmu farfield.wgsl"),
            source: wgpu::ShaderSource::Wgsl(FAR_SHADER.into()),
        });
        let texture = |binding, sample_type| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type,
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dmu far field"),
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
                texture(1, wgpu::TextureSampleType::Float { filterable: true }),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
                texture(3, wgpu::TextureSampleType::Uint),
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("dmu far field"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("dmu far field"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_far"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 16,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x4],
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: crate::DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Greater),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_far"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: color_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("dmu far field"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        Self {
            layout,
            pipeline,
            sampler,
        }
    }
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
            base: scene.part_ids().map(|p| part_hash(scene, p)).collect(),
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
            let now = part_hash(scene, dmu_scene::PartId::from_index(p as usize));
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
            let mut pass = crate::renderer::pass_over(&mut encoder, "dmu far field", target, None);
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

    /// Captures the far field of the viewpoint cell `cell` around its centre:
    /// everything not touching `near_box` but the parts in `excluded` (which
    /// are drawn as geometry wherever they are), six faces of
    /// `options.resolution` pixels, meshed as the module says. The renderer's
    /// colour format must be [`crate::CAPTURE_FORMAT`].
    #[expect(
        clippy::too_many_arguments,
        reason = "the model, the cell and the options, passed through once"
    )]
    pub fn capture_far_field(
        &mut self,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        cell: Aabb3d,
        near_box: Aabb3d,
        excluded: &BTreeSet<u32>,
        options: &FarFieldOptions,
    ) -> Result<(FarField, FarFieldBuild), RenderError> {
        let start = Instant::now();
        let r = options.resolution;
        assert!(
            FAR_FIELD_RESOLUTIONS.contains(&r),
            "far-field resolution {r} out of range"
        );
        let center = cell.center();
        let tan_half = 1.0 + 2.0 * OVERLAP_PX / f64::from(r);
        // Far geometry lies outside the cull box, which holds the centre.
        let half = (near_box.max - center)
            .min(center - near_box.min)
            .min_element();
        let near = (0.5 * half).max(1e-6 * (center.length() + 1.0));
        let capture = Capture::new(&self.device, (r, r));
        let texels = (r * r) as usize;
        let mut color = Vec::with_capacity(6 * texels * 4);
        let mut parts = Vec::with_capacity(6 * texels);
        let mut depths = Vec::with_capacity(6);
        for face in 0..6 {
            let camera = face_camera(center, face, tan_half, near).camera;
            let mut view = View::new(camera, (r, r), Culling::Frustum);
            view.options.lod_error_px = options.lod_error_px;
            view.options.target_ms = None;
            view.far_only = Some(FarOnly {
                near_box,
                excluded: excluded.clone(),
            });
            self.render(&mut view, scene, tree, geometry, capture.frame_target())?;
            color.extend_from_slice(capture.read_color(&self.device, &self.queue)?.as_raw());
            depths.push(capture.read_depth(&self.device, &self.queue)?);
            let ids = self.render_ids(&mut view, scene, tree, geometry, &capture)?;
            parts.extend(ids.ids.iter().map(|&id| match id {
                0 => 0,
                e => tree.entries()[e as usize - 1].part.0 + 1,
            }));
        }
        let capture_ms = start.elapsed().as_secs_f64() * 1e3;
        let mesh_start = Instant::now();
        // A parallax of one pixel: the cell's corner seen from its centre.
        let reach = (cell.extent() * 0.5).length();
        let focal = f64::from(r) / (2.0 * tan_half);
        let mut build = FarFieldBuild::default();
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let mut face_starts = [0u32; 7];
        for (face, depth) in depths.iter().enumerate() {
            let grid = face_grid(face, depth, r, options, tan_half, near, reach * focal);
            build.grid_triangles += grid.indices.len() as u64 / 3;
            let (kept, _) = dmu_scene::simplify_to_error(
                &grid.warped,
                &grid.indices,
                options.mesh_error_px as f32,
            );
            // Keep the referenced vertices only.
            let mut remap = vec![u32::MAX; grid.relative.len()];
            for i in kept {
                let slot = &mut remap[i as usize];
                if *slot == u32::MAX {
                    *slot = vertices.len() as u32;
                    let p = grid.relative[i as usize];
                    vertices.push([p[0], p[1], p[2], face as f32]);
                }
                indices.push(*slot);
            }
            face_starts[face + 1] = indices.len() as u32;
        }
        build.triangles = indices.len() as u64 / 3;
        build.capture_ms = capture_ms;
        build.mesh_ms = mesh_start.elapsed().as_secs_f64() * 1e3;
        let seen: BTreeSet<u32> = parts.iter().filter_map(|&p| p.checked_sub(1)).collect();
        Ok((
            FarField {
                center,
                cell,
                near_box,
                resolution: r,
                tan_half: tan_half as f32,
                vertices,
                indices,
                face_starts,
                color,
                parts,
                seen: seen.into_iter().collect(),
                excluded: excluded.iter().copied().collect(),
                mesh_error_px: options.mesh_error_px as f32,
                build_ms: start.elapsed().as_secs_f64() * 1e3,
            },
            build,
        ))
    }
}

/// One face's depth as a grid mesh: positions relative to the centre, the
/// same in (pixel x, pixel y, parallax in pixels) for the simplifier, and
/// the triangles.
struct FaceGrid {
    relative: Vec<[f32; 3]>,
    warped: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

fn face_grid(
    face: usize,
    depth: &[f32],
    r: u32,
    options: &FarFieldOptions,
    tan_half: f64,
    near: f64,
    parallax_scale: f64,
) -> FaceGrid {
    let step = options.grid_step.clamp(1, r);
    let unproject = face_camera(DVec3::ZERO, face, tan_half, near)
        .view_proj()
        .inverse();
    let axis = FACES[face].0;
    let samples: Vec<u32> = (0..r)
        .step_by(step as usize)
        .chain((!(r - 1).is_multiple_of(step)).then_some(r - 1))
        .collect();
    let n = samples.len();
    let mut slot = vec![u32::MAX; n * n];
    let mut grid = FaceGrid {
        relative: Vec::new(),
        warped: Vec::new(),
        indices: Vec::new(),
    };
    // A sample that hit nothing lies on a background far behind the
    // farthest that did, so thin parts between samples and silhouettes
    // against the sky still get a surface to be textured onto.
    let at = |x: u32, y: u32, d: f64| {
        let ndc = DVec4::new(
            (f64::from(x) + 0.5) / f64::from(r) * 2.0 - 1.0,
            1.0 - (f64::from(y) + 0.5) / f64::from(r) * 2.0,
            d,
            1.0,
        );
        let p = unproject * ndc;
        p.truncate() / p.w
    };
    let farthest = samples
        .iter()
        .flat_map(|&y| samples.iter().map(move |&x| (x, y)))
        .map(|(x, y)| depth[(y * r + x) as usize])
        .filter(|&d| d > 0.0)
        .fold(f32::MAX, f32::min);
    if farthest == f32::MAX {
        return grid;
    }
    let background = at(0, 0, f64::from(farthest)).dot(axis) * BACKGROUND;
    let mut distance = vec![0.0f64; n * n];
    for (j, &y) in samples.iter().enumerate() {
        for (i, &x) in samples.iter().enumerate() {
            let d = depth[(y * r + x) as usize];
            let p = if d > 0.0 {
                at(x, y, f64::from(d))
            } else {
                let p = at(x, y, 1.0);
                p * (background / p.dot(axis))
            };
            let along = p.dot(axis);
            slot[j * n + i] = grid.relative.len() as u32;
            distance[j * n + i] = along;
            grid.relative.push(p.as_vec3().to_array());
            grid.warped.push([
                x as f32,
                y as f32,
                (parallax_scale / along.max(1e-30)) as f32,
            ]);
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let k = [
                j * n + i,
                j * n + i + 1,
                (j + 1) * n + i,
                (j + 1) * n + i + 1,
            ];
            if k.iter().any(|&k| slot[k] == u32::MAX) {
                continue;
            }
            if !options.skins {
                let d = k.map(|k| distance[k]);
                let (lo, hi) = d
                    .iter()
                    .fold((f64::MAX, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
                if hi > SKIN_RATIO * lo {
                    continue;
                }
            }
            let [a, b, c, d] = k.map(|k| slot[k]);
            grid.indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    grid
}

/// The first bytes of an encoded far field.
const MAGIC: [u8; 8] = *b"DMUFAR01";

/// Fixed-size head of an encoded far field, little-endian.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Head {
    magic: [u8; 8],
    center: [f64; 3],
    cell: [f64; 6],
    near_box: [f64; 6],
    build_ms: f64,
    resolution: u32,
    tan_half: f32,
    mesh_error_px: f32,
    vertices: u32,
    indices: u32,
    seen: u32,
    excluded: u32,
    color_png: u32,
    parts_png: u32,
    face_starts: [u32; 7],
}

impl FarField {
    /// Its bytes: a head, the meshes and part lists, and the colour and part
    /// ids as PNG images (a column of the six faces).
    pub fn encode(&self) -> Vec<u8> {
        let r = self.resolution;
        let png = |bytes: Vec<u8>| {
            let image = image::RgbaImage::from_raw(r, 6 * r, bytes).expect("six faces");
            crate::encode_png(&image).expect("PNG encoding in memory")
        };
        let color = png(self.color.clone());
        let parts = png(bytemuck::cast_slice(&self.parts).to_vec());
        let b = |b: &Aabb3d| [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z];
        let head = Head {
            magic: MAGIC,
            center: self.center.to_array(),
            cell: b(&self.cell),
            near_box: b(&self.near_box),
            build_ms: self.build_ms,
            resolution: r,
            tan_half: self.tan_half,
            mesh_error_px: self.mesh_error_px,
            vertices: self.vertices.len() as u32,
            indices: self.indices.len() as u32,
            seen: self.seen.len() as u32,
            excluded: self.excluded.len() as u32,
            color_png: color.len() as u32,
            parts_png: parts.len() as u32,
            face_starts: self.face_starts,
        };
        let mut out = bytemuck::bytes_of(&head).to_vec();
        out.extend_from_slice(bytemuck::cast_slice(&self.vertices));
        out.extend_from_slice(bytemuck::cast_slice(&self.indices));
        out.extend_from_slice(bytemuck::cast_slice(&self.seen));
        out.extend_from_slice(bytemuck::cast_slice(&self.excluded));
        out.extend_from_slice(&color);
        out.extend_from_slice(&parts);
        out
    }

    /// Reads [`FarField::encode`]'s bytes, checking every count, index,
    /// number and image against the others and part ids against `parts`
    /// (the model's part count): the reason in words when they do not fit.
    pub fn decode(bytes: &[u8], parts: usize) -> Result<FarField, String> {
        let head_len = size_of::<Head>();
        let head: Head = bytemuck::pod_read_unaligned(
            bytes
                .get(..head_len)
                .ok_or_else(|| format!("{} bytes: shorter than its head", bytes.len()))?,
        );
        if head.magic != MAGIC {
            return Err("not a far field (wrong magic)".into());
        }
        let r = head.resolution;
        if !FAR_FIELD_RESOLUTIONS.contains(&r) {
            return Err(format!("resolution {r} outside {FAR_FIELD_RESOLUTIONS:?}"));
        }
        let mut at = head_len;
        let mut take = |len: usize, what: &str| -> Result<&[u8], String> {
            let piece = at
                .checked_add(len)
                .and_then(|end| bytes.get(at..end))
                .ok_or_else(|| format!("{what}: {len} bytes past the end"))?;
            at += len;
            Ok(piece)
        };
        let vertices: Vec<[f32; 4]> =
            bytemuck::pod_collect_to_vec(take(16 * head.vertices as usize, "vertices")?);
        let indices: Vec<u32> =
            bytemuck::pod_collect_to_vec(take(4 * head.indices as usize, "indices")?);
        let seen: Vec<u32> = bytemuck::pod_collect_to_vec(take(4 * head.seen as usize, "seen")?);
        let excluded: Vec<u32> =
            bytemuck::pod_collect_to_vec(take(4 * head.excluded as usize, "excluded")?);
        let color = take(head.color_png as usize, "colour image")?.to_vec();
        let parts_png = take(head.parts_png as usize, "part image")?.to_vec();
        if at != bytes.len() {
            return Err(format!("{} bytes after its end", bytes.len() - at));
        }
        let finite = head
            .center
            .iter()
            .chain(&head.cell)
            .chain(&head.near_box)
            .all(|x| x.is_finite())
            && head.tan_half.is_finite()
            && head.tan_half >= 1.0
            && head.tan_half < 2.0
            && head.mesh_error_px.is_finite();
        if !finite {
            return Err("a centre, box, angle or bound is not a finite number in range".into());
        }
        let b =
            |a: [f64; 6]| Aabb3d::new(DVec3::new(a[0], a[1], a[2]), DVec3::new(a[3], a[4], a[5]));
        let (cell, near_box) = (b(head.cell), b(head.near_box));
        if cell.is_empty() || near_box.is_empty() {
            return Err("an empty cell or cull box".into());
        }
        let fs = head.face_starts;
        if fs[0] != 0
            || fs[6] != head.indices
            || fs.windows(2).any(|w| w[0] > w[1] || w[1] % 3 != 0)
        {
            return Err(format!(
                "face starts {fs:?} do not split {} indices in triangles",
                head.indices
            ));
        }
        for (f, w) in fs.windows(2).enumerate() {
            for &i in &indices[w[0] as usize..w[1] as usize] {
                let v = vertices
                    .get(i as usize)
                    .ok_or_else(|| format!("index {i} past {} vertices", vertices.len()))?;
                if v[3] != f as f32 || !v.iter().all(|x| x.is_finite()) {
                    return Err(format!(
                        "vertex {i} of face {f} is not a finite point of that face"
                    ));
                }
            }
        }
        let sorted_parts = |list: &[u32], what: &str| {
            if list.windows(2).any(|w| w[0] >= w[1])
                || list.last().is_some_and(|&p| p as usize >= parts)
            {
                Err(format!(
                    "{what} parts are not sorted part ids below {parts}"
                ))
            } else {
                Ok(())
            }
        };
        sorted_parts(&seen, "seen")?;
        sorted_parts(&excluded, "excluded")?;
        let image = |png: &[u8], what: &str| -> Result<Vec<u8>, String> {
            let image = image::load_from_memory_with_format(png, image::ImageFormat::Png)
                .map_err(|e| format!("{what}: {e}"))?;
            if (image.width(), image.height()) != (r, 6 * r) {
                return Err(format!(
                    "{what} is {}x{}, not {r}x{}",
                    image.width(),
                    image.height(),
                    6 * r
                ));
            }
            Ok(image.into_rgba8().into_raw())
        };
        let color = image(&color, "colour image")?;
        let part_ids: Vec<u32> = bytemuck::pod_collect_to_vec(&image(&parts_png, "part image")?);
        if part_ids.iter().any(|&p| p as usize > parts) {
            return Err(format!("a texel's part id is not below {parts}"));
        }
        Ok(FarField {
            center: DVec3::from_array(head.center),
            cell,
            near_box,
            resolution: r,
            tan_half: head.tan_half,
            vertices,
            indices,
            face_starts: fs,
            color,
            parts: part_ids,
            seen,
            excluded,
            mesh_error_px: head.mesh_error_px,
            build_ms: head.build_ms,
        })
    }
}
