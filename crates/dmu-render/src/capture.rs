//! Offscreen targets and their readback: colour images for captures and tests,
//! chunk-id images for the exact-visibility oracle.

use std::collections::BTreeSet;
use std::path::Path;

use dmu_tree::EntryId;

use crate::RenderError;
use crate::device::map_read;

/// Colour format of captures: sRGB, so linear material colours are encoded as
/// a PNG viewer expects.
pub const CAPTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Depth format of every target (reverse-Z: cleared to 0, compared with Greater).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Format of chunk-id targets: entry id + 1, 0 for the background.
pub const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// Offscreen colour, id and depth textures of one size.
#[derive(Debug)]
pub struct Capture {
    size: (u32, u32),
    color: wgpu::Texture,
    ids: wgpu::Texture,
    color_view: wgpu::TextureView,
    ids_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
}

impl Capture {
    /// Targets of `size` pixels.
    pub fn new(device: &wgpu::Device, size: (u32, u32)) -> Self {
        let texture = |label, format| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let color = texture("dmu capture colour", CAPTURE_FORMAT);
        let ids = texture("dmu capture ids", ID_FORMAT);
        let depth = texture("dmu capture depth", DEPTH_FORMAT);
        Self {
            size,
            color_view: color.create_view(&wgpu::TextureViewDescriptor::default()),
            ids_view: ids.create_view(&wgpu::TextureViewDescriptor::default()),
            depth_view: depth.create_view(&wgpu::TextureViewDescriptor::default()),
            color,
            ids,
        }
    }

    /// Size in pixels.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The colour and depth views to render a frame into.
    pub fn frame_target(&self) -> crate::FrameTarget<'_> {
        crate::FrameTarget {
            color: &self.color_view,
            depth: &self.depth_view,
        }
    }

    /// The id and depth views for the oracle.
    pub fn id_target(&self) -> crate::FrameTarget<'_> {
        crate::FrameTarget {
            color: &self.ids_view,
            depth: &self.depth_view,
        }
    }

    /// The colour image (RGBA8, sRGB).
    pub fn read_color(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<image::RgbaImage, RenderError> {
        let bytes = read_texture(device, queue, &self.color, self.size, "colour image")?;
        Ok(image::RgbaImage::from_raw(self.size.0, self.size.1, bytes)
            .expect("readback has width * height * 4 bytes"))
    }

    /// The id image.
    pub fn read_ids(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<IdImage, RenderError> {
        let bytes = read_texture(device, queue, &self.ids, self.size, "id image")?;
        Ok(IdImage {
            size: self.size,
            ids: bytemuck::pod_collect_to_vec(&bytes),
        })
    }
}

/// Chunk instances per pixel, row-major from the top-left.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IdImage {
    /// Width and height.
    pub size: (u32, u32),
    /// Entry id + 1 per pixel, 0 for the background.
    pub ids: Vec<u32>,
}

impl IdImage {
    /// The chunk instance owning pixel `(x, y)`.
    pub fn at(&self, x: u32, y: u32) -> Option<EntryId> {
        let v = self.ids[(y * self.size.0 + x) as usize];
        v.checked_sub(1).map(EntryId)
    }

    /// Every chunk instance owning at least one pixel, sorted.
    pub fn visible_entries(&self) -> BTreeSet<EntryId> {
        self.ids
            .iter()
            .filter_map(|&v| v.checked_sub(1).map(EntryId))
            .collect()
    }
}

/// Saves an image as PNG.
pub fn save_png(image: &image::RgbaImage, path: &Path) -> Result<(), RenderError> {
    image.save(path).map_err(|source| RenderError::Image {
        path: path.display().to_string(),
        source,
    })
}

/// Copies a 4-byte-per-texel texture to tightly packed rows.
fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    size: (u32, u32),
    what: &'static str,
) -> Result<Vec<u8>, RenderError> {
    let row = size.0 * 4;
    let padded = row.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let bytes = u64::from(padded) * u64::from(size.1);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("dmu texture readback"),
        size: bytes,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(size.1),
            },
        },
        wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: 1,
        },
    );
    queue.submit([encoder.finish()]);
    map_read(device, &buffer, bytes, what, |data| {
        let mut out = Vec::with_capacity((row * size.1) as usize);
        for r in data.chunks_exact(padded as usize) {
            out.extend_from_slice(&r[..row as usize]);
        }
        out
    })
}
