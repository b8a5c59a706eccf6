//! The right eye of a stereo pair reprojected from the left eye's image by its
//! depth (`shaders/reproject.wgsl`), as stereo shading reprojection does it in
//! VR renderers: the left eye is drawn once, into an image wide enough to
//! hold the right eye's window too, and every one of its pixels moves along
//! its row by its disparity `ipd * fx / z` into the right eye. What lands
//! lands at the nearest pixel (a disparity error of at most half a pixel);
//! where nothing lands (the gaps along near silhouettes that only the right
//! eye sees behind), the farther of the two pixels either side of the gap
//! fills in. So the right eye costs one pass over pixels, a row an
//! invocation in occlusion-compatible order (no depth test), instead of its
//! geometry, and what it gets wrong is those gaps, which the caller measures
//! against the pair drawn in full.
//!
//! The eyes must be parallel, with one pixel scale and one vertical field of
//! view (mirrored headset eyes are), and both images reverse-Z with an
//! infinite far plane, as every [`crate::View`] without a far plane draws.

use bytemuck::{Pod, Zeroable};

use crate::RenderError;
use crate::capture::{Capture, REPROJECT_SOURCE_FORMAT};
use crate::device::map_read;
use crate::gpu::REPROJECT_SHADER;

/// How the left eye's image maps onto the right eye's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reprojection {
    /// The left eye's image, pixels.
    pub source_size: (u32, u32),
    /// The right eye's image, pixels (the source's height: rows correspond).
    pub target_size: (u32, u32),
    /// The right eye's window's first column on the left image's pixel grid
    /// (generally fractional).
    pub target_offset: f64,
    /// Disparity in pixels at the near plane, `ipd * fx / near` (`fx` pixels
    /// per unit tangent): a depth value `d` moves `d` times this to the left.
    /// Not negative: the right eye is made from the left (the scan's order
    /// resolves occlusion only for that direction).
    pub disparity_at_near_px: f64,
}

/// `Params` of `reproject.wgsl`.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
struct Params {
    source_size: [u32; 2],
    target_size: [u32; 2],
    out_stride: u32,
    pad: u32,
    target_offset: f32,
    disparity_at_near: f32,
}
const _: () = assert!(size_of::<Params>() == 32);

/// Pixels per row of the output buffer: a whole number of 256-byte rows, as a
/// buffer-to-texture copy needs.
fn out_stride(width: u32) -> u32 {
    width.next_multiple_of(64)
}

/// The pipelines and buffers of one [`Reprojection`].
#[derive(Debug)]
pub struct Reprojector {
    reprojection: Reprojection,
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    /// Per target pixel: 1 where a left-eye pixel landed, 0 where filled.
    landed: wgpu::Buffer,
    /// Per target pixel, rows of [`out_stride`]: its colour.
    out: wgpu::Buffer,
    readback: wgpu::Buffer,
}

impl Reprojector {
    /// Pipelines and buffers for `reprojection`.
    ///
    /// # Panics
    /// When the images' heights differ or either is empty, the disparity is
    /// negative or either number is not finite.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, reprojection: Reprojection) -> Self {
        let r = reprojection;
        assert!(
            r.target_size.1 == r.source_size.1 && r.target_size.0 > 0 && r.source_size.0 > 0,
            "reprojection of {:?} into {:?}",
            r.source_size,
            r.target_size
        );
        assert!(
            r.disparity_at_near_px >= 0.0
                && r.disparity_at_near_px.is_finite()
                && r.target_offset.is_finite(),
            "reprojection with disparity {} and offset {}",
            r.disparity_at_near_px,
            r.target_offset
        );
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("dmu reproject.wgsl"),
            source: wgpu::ShaderSource::Wgsl(REPROJECT_SHADER.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("dmu reproject"),
            layout: None,
            module: &module,
            entry_point: Some("reproject_rows"),
            compilation_options: Default::default(),
            cache: None,
        });
        let buffer = |label, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let pixels = u64::from(r.target_size.0) * u64::from(r.target_size.1);
        let params = buffer(
            "dmu reproject params",
            size_of::<Params>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        queue.write_buffer(
            &params,
            0,
            bytemuck::bytes_of(&Params {
                source_size: [r.source_size.0, r.source_size.1],
                target_size: [r.target_size.0, r.target_size.1],
                out_stride: out_stride(r.target_size.0),
                pad: 0,
                target_offset: r.target_offset as f32,
                disparity_at_near: r.disparity_at_near_px as f32,
            }),
        );
        Self {
            reprojection,
            pipeline,
            params,
            landed: buffer(
                "dmu reproject landed",
                pixels * 4,
                storage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            ),
            out: buffer(
                "dmu reproject colour",
                u64::from(out_stride(r.target_size.0)) * u64::from(r.target_size.1) * 4,
                storage | wgpu::BufferUsages::COPY_SRC,
            ),
            readback: buffer(
                "dmu reproject readback",
                pixels * 4,
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            ),
        }
    }

    /// Records the reprojection of `source`'s layer 0 (colour and depth, of
    /// the source size) into layer `layer` of `target`'s colour (of the
    /// target size).
    ///
    /// # Panics
    /// When the captures' sizes are not the reprojection's or `target` has
    /// no layer `layer`.
    pub fn encode(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        source: &Capture,
        target: &Capture,
        layer: u32,
    ) {
        let r = &self.reprojection;
        assert_eq!(source.size(), r.source_size, "source size");
        assert_eq!(target.size(), r.target_size, "target size");
        let color = source
            .color_texture()
            .create_view(&wgpu::TextureViewDescriptor {
                format: Some(REPROJECT_SOURCE_FORMAT),
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: 0,
                array_layer_count: Some(1),
                ..Default::default()
            });
        let entries = [
            wgpu::BindGroupEntry {
                binding: 0,
                resource: self.params.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&color),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(source.depth_view(0)),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: self.landed.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: self.out.as_entire_binding(),
            },
        ];
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dmu reproject"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        encoder.clear_buffer(&self.landed, 0, None);
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("dmu reproject"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(r.target_size.1.div_ceil(64), 1, 1);
        }
        encoder.copy_buffer_to_texture(
            wgpu::TexelCopyBufferInfo {
                buffer: &self.out,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(out_stride(r.target_size.0) * 4),
                    rows_per_image: Some(r.target_size.1),
                },
            },
            wgpu::TexelCopyTextureInfo {
                origin: wgpu::Origin3d {
                    x: 0,
                    y: 0,
                    z: layer,
                },
                ..target.color_texture().as_image_copy()
            },
            wgpu::Extent3d {
                width: r.target_size.0,
                height: r.target_size.1,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Target pixels nothing landed on in the last reprojection submitted
    /// (the gaps filled from a neighbour), counted on a readback.
    pub fn read_gaps(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<u64, RenderError> {
        let size = self.landed.size();
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.landed, 0, &self.readback, 0, size);
        queue.submit([encoder.finish()]);
        map_read(device, &self.readback, size, "reprojection gaps", |bytes| {
            bytemuck::cast_slice::<u8, u32>(bytes)
                .iter()
                .filter(|&&k| k == 0)
                .count() as u64
        })
    }
}
