//! Offscreen targets and their readback: colour images for captures and tests,
//! chunk-id images for the exact-visibility oracle.

use std::collections::BTreeSet;
use std::path::Path;

use dmu_tree::EntryId;

use crate::RenderError;
use crate::device::map_read;
use crate::target::{FrameTarget, StereoTarget};

/// Colour format of captures: sRGB, so linear material colours are encoded as
/// a PNG viewer expects.
pub const CAPTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Depth format of every target (reverse-Z: cleared to 0, compared with Greater).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The view format the stereo reprojection reads captures' colour through:
/// [`CAPTURE_FORMAT`] without the sRGB decoding, so it copies stored bytes.
pub(crate) const REPROJECT_SOURCE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Format of chunk-id targets: entry id + 1, 0 for the background.
pub const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// Offscreen colour, id and depth textures of one size: one layer for a view,
/// two (left eye, right eye) for a stereo pair.
#[derive(Debug)]
pub struct Capture {
    size: (u32, u32),
    color: wgpu::Texture,
    ids: wgpu::Texture,
    depth: wgpu::Texture,
    /// Colour and depth views of each layer alone.
    layers: Vec<(wgpu::TextureView, wgpu::TextureView)>,
    ids_view: wgpu::TextureView,
    /// Colour and depth views of both layers, for the multiview pass (stereo only).
    array: Option<(wgpu::TextureView, wgpu::TextureView)>,
}

impl Capture {
    /// Targets of `size` pixels for one view.
    pub fn new(device: &wgpu::Device, size: (u32, u32)) -> Self {
        Self::with_layers(device, size, 1)
    }

    /// Targets of `size` pixels for a stereo pair: colour and depth of two
    /// layers, layer 0 the left eye ([`crate::Renderer::render_stereo`]).
    pub fn stereo(device: &wgpu::Device, size: (u32, u32)) -> Self {
        Self::with_layers(device, size, 2)
    }

    fn with_layers(device: &wgpu::Device, size: (u32, u32), layers: u32) -> Self {
        let texture =
            |label, format, layers| attachment_texture(device, label, size, layers, format);
        let color = texture("dmu capture colour", CAPTURE_FORMAT, layers);
        // The id oracle is a single-view operation.
        let ids = texture("dmu capture ids", ID_FORMAT, 1);
        let depth = texture("dmu capture depth", DEPTH_FORMAT, layers);
        let view = |t: &wgpu::Texture, dimension, base_array_layer, array_layer_count| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(dimension),
                base_array_layer,
                array_layer_count: Some(array_layer_count),
                ..Default::default()
            })
        };
        let d2 = wgpu::TextureViewDimension::D2;
        let array = wgpu::TextureViewDimension::D2Array;
        Self {
            size,
            layers: (0..layers)
                .map(|l| (view(&color, d2, l, 1), view(&depth, d2, l, 1)))
                .collect(),
            ids_view: view(&ids, d2, 0, 1),
            array: (layers > 1).then(|| {
                (
                    view(&color, array, 0, layers),
                    view(&depth, array, 0, layers),
                )
            }),
            color,
            ids,
            depth,
        }
    }

    /// The colour texture (one layer per eye of a stereo capture), to copy
    /// frames out (an XR swapchain image of the same size and format) or in
    /// (a shared far part, drawn over with [`crate::View::keep_color`]).
    pub fn color_texture(&self) -> &wgpu::Texture {
        &self.color
    }

    /// Size in pixels.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The colour and depth views to render a frame into (layer 0 of a stereo
    /// capture).
    pub fn frame_target(&self) -> FrameTarget<'_> {
        self.layer_target(0)
    }

    fn layer_target(&self, layer: usize) -> FrameTarget<'_> {
        let (color, depth) = &self.layers[layer];
        FrameTarget { color, depth }
    }

    /// The depth view of one layer.
    pub(crate) fn depth_view(&self, layer: usize) -> &wgpu::TextureView {
        &self.layers[layer].1
    }

    /// The views to render a stereo pair into.
    ///
    /// # Panics
    /// When the capture was not made by [`Capture::stereo`].
    pub fn stereo_target(&self) -> StereoTarget<'_> {
        let (color, depth) = self
            .array
            .as_ref()
            .expect("stereo_target needs a capture made by Capture::stereo");
        StereoTarget {
            color,
            depth,
            eyes: [self.layer_target(0), self.layer_target(1)],
        }
    }

    /// The id and depth views for the oracle.
    pub fn id_target(&self) -> FrameTarget<'_> {
        FrameTarget {
            color: &self.ids_view,
            depth: &self.layers[0].1,
        }
    }

    /// The colour image (RGBA8, sRGB); layer 0 of a stereo capture.
    pub fn read_color(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<image::RgbaImage, RenderError> {
        self.read_color_layer(device, queue, 0)
    }

    /// The colour image of one layer (0: left eye, 1: right eye of a stereo
    /// capture).
    ///
    /// # Panics
    /// When the capture has no such layer.
    pub fn read_color_layer(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        layer: u32,
    ) -> Result<image::RgbaImage, RenderError> {
        assert!(
            (layer as usize) < self.layers.len(),
            "layer {layer} of a {}-layer capture",
            self.layers.len()
        );
        let bytes = read_texture(device, queue, &self.color, self.size, layer, "colour image")?;
        Ok(image::RgbaImage::from_raw(self.size.0, self.size.1, bytes)
            .expect("readback has width * height * 4 bytes"))
    }

    /// The depth image (reverse-Z: 1 at the near plane, 0 where nothing
    /// was drawn), rows from the top.
    pub fn read_depth(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Vec<f32>, RenderError> {
        let bytes = read_texture(device, queue, &self.depth, self.size, 0, "depth image")?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// The id image.
    pub fn read_ids(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<IdImage, RenderError> {
        let bytes = read_texture(device, queue, &self.ids, self.size, 0, "id image")?;
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

/// Saves an image as PNG, through a temporary file renamed over `path`
/// ([`dmu_scene::write_file_atomically`]): a full disk or a kill leaves the
/// previous image whole.
/// A name that does not end in `.png` is refused: an image never replaces a
/// model or a store.
pub fn save_png(image: &image::RgbaImage, path: &Path) -> Result<(), RenderError> {
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        return Err(RenderError::Image {
            path: path.display().to_string(),
            source: std::io::Error::other("a PNG is written only to a name ending in .png").into(),
        });
    }
    encode_png(image)
        .and_then(|png| dmu_scene::write_file_atomically(path, &png).map_err(Into::into))
        .map_err(|source| RenderError::Image {
            path: path.display().to_string(),
            source,
        })
}

/// An image as the bytes of a PNG file (for a snapshot kept in memory, as in
/// a BCF archive).
pub fn encode_png(image: &image::RgbaImage) -> Result<Vec<u8>, image::ImageError> {
    let mut png = Vec::new();
    image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

/// Copies one layer of a 4-byte-per-texel texture to tightly packed rows.
pub(crate) fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    size: (u32, u32),
    layer: u32,
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
            origin: wgpu::Origin3d {
                x: 0,
                y: 0,
                z: layer,
            },
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

/// A 2D render attachment of `layers` layers that can be copied out.
pub(crate) fn attachment_texture(
    device: &wgpu::Device,
    label: &str,
    size: (u32, u32),
    layers: u32,
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: layers,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST
            // Depth is read by `hzb` culling's pyramid, colour and depth by
            // the stereo reprojection.
            | wgpu::TextureUsages::TEXTURE_BINDING,
        // Colour is also read as plain RGBA8 (its stored bytes) by the
        // stereo reprojection.
        view_formats: if format == CAPTURE_FORMAT {
            &[REPROJECT_SOURCE_FORMAT]
        } else {
            &[]
        },
    })
}

/// A channel difference above which a pixel shows another surface (or none)
/// rather than the same one shaded a little differently (as a simplified
/// level shades it).
pub const SURFACE_CHANGE: u8 = 24;

/// Pixels of two same-sized RGBA8 images that differ at all, and those that
/// differ by more than [`SURFACE_CHANGE`] in a channel.
pub fn count_differing(a: &[u8], b: &[u8]) -> (u64, u64) {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    let (mut any, mut surface) = (0, 0);
    for (p, q) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        if p != q {
            any += 1;
            surface += u64::from(
                p.iter()
                    .zip(q)
                    .any(|(x, y)| x.abs_diff(*y) > SURFACE_CHANGE),
            );
        }
    }
    (any, surface)
}

#[cfg(test)]
mod tests {
    #[test]
    fn differing_pixels_are_counted_and_surface_changes_apart() {
        let a = [
            10, 10, 10, 255, 10, 10, 10, 255, 10, 10, 10, 255, 0, 0, 0, 255,
        ];
        // Same; shaded 24 brighter in red (not another surface); alpha only;
        // 25 darker in blue (another surface).
        let b = [
            10, 10, 10, 255, 34, 10, 10, 255, 10, 10, 10, 0, 0, 0, 25, 255,
        ];
        assert_eq!(super::count_differing(&a, &b), (3, 2));
        assert_eq!(super::count_differing(&a, &a), (0, 0));
    }
}
