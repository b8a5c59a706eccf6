//! Every pipeline the renderer draws or computes with, built in one place:
//! one mesh-pipeline builder ([`MeshPipeline`]) for the main passes (shading,
//! ids, query boxes, proxies, multiview), the far field and the second pass
//! of `hzb` frames (which draws with the shading pipelines), and the compute
//! pipelines of the depth pyramid.

use std::num::NonZeroU32;

use crate::capture::{DEPTH_FORMAT, ID_FORMAT};
use crate::geometry::PoolVertex;
use crate::gpu::{
    CHUNK_VERTEX_ATTRIBUTES, FRAME_ATTRIBUTES, HZB_SHADER, INSTANCE_ATTRIBUTES, InstanceGpu,
    PROXY_VERTEX_ATTRIBUTES, QueryBox, RIGHT_EYE_ATTRIBUTES, SHADER, STEREO_SHADER,
};
use crate::proxy::ProxyVertex;
use crate::stereo::StereoMode;

/// A read-only storage buffer binding.
const STORAGE: wgpu::BufferBindingType = wgpu::BufferBindingType::Storage { read_only: true };

/// A bind group layout entry of a buffer bound whole.
fn buffer_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// The layers a stereo pair's multiview pass draws: left eye 0, right eye 1.
pub(crate) const STEREO_VIEWS: NonZeroU32 = NonZeroU32::new(0b11).expect("non-zero");

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

/// A render pipeline drawing meshes into a colour and a
/// [`DEPTH_FORMAT`] target, reverse-Z.
#[derive(Clone, Copy)]
pub(crate) struct MeshPipeline<'a> {
    pub label: &'a str,
    pub layout: &'a wgpu::PipelineLayout,
    pub module: &'a wgpu::ShaderModule,
    /// Vertex entry point.
    pub vs: &'a str,
    pub buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    /// Fragment entry point.
    pub fs: &'a str,
    pub format: wgpu::TextureFormat,
    /// Writes colour and depth; else tests depth only (a query box).
    pub write: bool,
    pub multiview_mask: Option<NonZeroU32>,
    pub faces: Faces,
}

impl MeshPipeline<'_> {
    pub fn build(&self, device: &wgpu::Device) -> wgpu::RenderPipeline {
        let write = self.write;
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(self.label),
            layout: Some(self.layout),
            vertex: wgpu::VertexState {
                module: self.module,
                entry_point: Some(self.vs),
                compilation_options: Default::default(),
                buffers: self.buffers,
            },
            // CAD windings are unreliable: only solid meshes' back faces
            // are culled, with the pipelines for them.
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: (self.faces == Faces::Solid).then_some(wgpu::Face::Back),
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
                module: self.module,
                entry_point: Some(self.fs),
                // The uncut pipelines compile without the discard, which
                // would cost early depth testing.
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: if self.faces == Faces::Cut {
                        &[("SECTIONED", 1.0)]
                    } else {
                        &[]
                    },
                    ..Default::default()
                },
                targets: &[Some(wgpu::ColorTargetState {
                    format: self.format,
                    blend: None,
                    write_mask: if write {
                        wgpu::ColorWrites::ALL
                    } else {
                        wgpu::ColorWrites::empty()
                    },
                })],
            }),
            multiview_mask: self.multiview_mask,
            cache: None,
        })
    }

    /// This pipeline for each of [`Faces::ALL`].
    fn triple(self, device: &wgpu::Device) -> [wgpu::RenderPipeline; 3] {
        Faces::ALL.map(|faces| MeshPipeline { faces, ..self }.build(device))
    }
}

/// The main passes' pipelines (indexed by [`Faces`] where in threes) and
/// the bind group layout of a view.
#[derive(Debug)]
pub(crate) struct Pipelines {
    pub layout: wgpu::BindGroupLayout,
    /// Shading, shading that discards what section planes cut away, and
    /// shading that culls back faces.
    pub shade: [wgpu::RenderPipeline; 3],
    /// The multiview shading pipelines; `None` without [`wgpu::Features::MULTIVIEW`]
    /// or when stereo pairs are drawn a layer at a time.
    pub shade_stereo: Option<[wgpu::RenderPipeline; 3]>,
    /// How stereo pairs are drawn, resolved from the options.
    pub stereo_mode: StereoMode,
    pub ids: [wgpu::RenderPipeline; 3],
    pub boxes: wgpu::RenderPipeline,
    /// Shading of proxies (merged subtrees) in their vertices' colours, and
    /// tinted as their entries' parts are.
    pub proxy: [[wgpu::RenderPipeline; 3]; 2],
}

impl Pipelines {
    /// The pipelines drawing into `color_format`, stereo pairs as `stereo`
    /// asks (`Auto`: multiview where the device has it and the probe finds
    /// it draws correctly).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        color_format: wgpu::TextureFormat,
        stereo: StereoMode,
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
        let both = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dmu view"),
            entries: &[
                buffer_entry(0, both, wgpu::BufferBindingType::Uniform),
                buffer_entry(1, both, STORAGE),
                buffer_entry(2, both, STORAGE),
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
        let proxy_buffers = [
            Some(wgpu::VertexBufferLayout {
                array_stride: size_of::<ProxyVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &PROXY_VERTEX_ATTRIBUTES,
            }),
            Some(frames.clone()),
        ];
        let shade = MeshPipeline {
            label: "dmu shade",
            layout: &pipeline_layout,
            module: &module,
            vs: "vs_mesh",
            buffers: &mesh_buffers,
            fs: "fs_shade",
            format: color_format,
            write: true,
            multiview_mask: None,
            faces: Faces::Uncut,
        };
        let proxy = ["vs_proxy", "vs_proxy_tinted"].map(|vs| {
            MeshPipeline {
                label: "dmu shade proxies",
                vs,
                buffers: &proxy_buffers,
                ..shade
            }
            .triple(device)
        });
        // Its own module: one naming `view_index` fails validation without multiview.
        let stereo_module = (multiview && stereo != StereoMode::LayerPasses)
            .then(|| shader("dmu mesh.wgsl + stereo.wgsl", STEREO_SHADER));
        let shade_stereo = stereo_module.as_ref().map(|module| {
            MeshPipeline {
                label: "dmu shade stereo",
                module,
                vs: "vs_mesh_stereo",
                buffers: &stereo_buffers,
                multiview_mask: Some(STEREO_VIEWS),
                ..shade
            }
            .triple(device)
        });
        let stereo_mode = match (stereo, &stereo_module) {
            (StereoMode::Auto, Some(module))
                if crate::stereo::multiview_clips_correctly(device, queue, module) =>
            {
                StereoMode::Multiview
            }
            (StereoMode::Auto, _) => StereoMode::LayerPasses,
            (mode, _) => mode,
        };
        let ids = MeshPipeline {
            label: "dmu ids",
            fs: "fs_id",
            format: ID_FORMAT,
            ..shade
        }
        .triple(device);
        // Stereo pairs query each eye's layer in a pass of its own (see
        // `submit_round`), so the box pipeline is single-view only.
        let boxes = MeshPipeline {
            label: "dmu query boxes",
            vs: "vs_box",
            buffers: &[Some(frames)],
            fs: "fs_box",
            write: false,
            ..shade
        }
        .build(device);
        Self {
            layout,
            shade: shade.triple(device),
            shade_stereo: shade_stereo.filter(|_| stereo_mode == StereoMode::Multiview),
            stereo_mode,
            ids,
            boxes,
            proxy,
        }
    }

    /// The pipeline of proxies drawing `faces`, `tinted` or in their
    /// vertices' colours.
    pub fn proxy(&self, tinted: bool, faces: Faces) -> &wgpu::RenderPipeline {
        &self.proxy[usize::from(tinted)][faces as usize]
    }
}

#[derive(Debug)]
pub(crate) struct FarPipeline {
    pub layout: wgpu::BindGroupLayout,
    pub pipeline: wgpu::RenderPipeline,
    pub sampler: wgpu::Sampler,
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
                buffer_entry(
                    0,
                    wgpu::ShaderStages::VERTEX_FRAGMENT,
                    wgpu::BufferBindingType::Uniform,
                ),
                texture(1, wgpu::TextureSampleType::Float { filterable: true }),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
                texture(3, wgpu::TextureSampleType::Uint),
                buffer_entry(4, wgpu::ShaderStages::FRAGMENT, STORAGE),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("dmu far field"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = MeshPipeline {
            label: "dmu far field",
            layout: &pipeline_layout,
            module: &module,
            vs: "vs_far",
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: 16,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x4],
            })],
            fs: "fs_far",
            format: color_format,
            write: true,
            multiview_mask: None,
            faces: Faces::Uncut,
        }
        .build(device);
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

/// The compute pipelines, made on a renderer's first `hzb` frame.
#[derive(Debug)]
pub(crate) struct HzbPipelines {
    pub reduce_depth: wgpu::ComputePipeline,
    pub reduce_level: wgpu::ComputePipeline,
    pub test: wgpu::ComputePipeline,
    /// Nearest and clamped to the edge, for gathering 2x2 blocks of depth.
    pub gather: wgpu::Sampler,
}

impl HzbPipelines {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("dmu hzb.wgsl"),
            source: wgpu::ShaderSource::Wgsl(HZB_SHADER.into()),
        });
        let pipeline = |entry| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Self {
            reduce_depth: pipeline("reduce_depth"),
            reduce_level: pipeline("reduce_level"),
            test: pipeline("test_boxes"),
            gather: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("dmu hzb gather"),
                ..Default::default()
            }),
        }
    }
}
