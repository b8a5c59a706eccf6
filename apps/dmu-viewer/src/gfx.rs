//! The window's GPU side: device, surface, the offscreen 3D view egui shows as
//! an image, the egui painter with its copy of the panels as last painted
//! (see [`crate::compose`]), and reading a frame back for screenshots.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use dmu_render::{DEPTH_FORMAT, FrameTarget};
use winit::window::Window;

/// A 3D view's offscreen colour and depth, shown by egui as a texture.
#[derive(Debug)]
pub struct ViewTarget {
    /// Size in physical pixels.
    pub size: (u32, u32),
    /// The egui texture showing it.
    pub texture: egui::TextureId,
    /// Its colour, in the window's format (sRGB-encoding), copied into
    /// composed frames.
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    /// The same texels read without sRGB decoding: egui expects gamma-space
    /// textures and writes them out unchanged.
    egui_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
}

impl ViewTarget {
    /// Targets of `size` pixels with colour in `format`; `texture` is set by
    /// the caller once egui knows them.
    fn new(device: &wgpu::Device, size: (u32, u32), format: wgpu::TextureFormat) -> Self {
        let texture = |label, format, usage, view_formats: &[wgpu::TextureFormat]| {
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
                usage,
                view_formats,
            })
        };
        let gamma = format.remove_srgb_suffix();
        let color = texture(
            "dmu-viewer 3d colour",
            format,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            &[gamma],
        );
        let depth = texture(
            "dmu-viewer 3d depth",
            DEPTH_FORMAT,
            // Read by `hzb` culling's depth pyramid.
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            &[],
        );
        Self {
            size,
            texture: egui::TextureId::default(),
            color_view: color.create_view(&Default::default()),
            egui_view: color.create_view(&wgpu::TextureViewDescriptor {
                format: Some(gamma),
                ..Default::default()
            }),
            depth_view: depth.create_view(&Default::default()),
            color,
        }
    }

    /// Where the renderer draws.
    pub fn frame_target(&self) -> FrameTarget<'_> {
        FrameTarget {
            color: &self.color_view,
            depth: &self.depth_view,
        }
    }
}

/// Device, surface and painters of the window.
pub struct Gfx {
    /// The window.
    pub window: Arc<Window>,
    /// The device everything shares.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter's name, for reports.
    pub adapter: String,
    /// The 3D views' colour format: the window's, sRGB-encoding (so a view
    /// copies into a frame as it is).
    pub view_format: wgpu::TextureFormat,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    /// Whether frames can be copied out of the swapchain (screenshots).
    can_read_back: bool,
    /// egui's painter.
    pub egui: egui_wgpu::Renderer,
    /// One target per 3D view (pane), each with its egui texture.
    pub views: Vec<ViewTarget>,
    /// The panels as last painted, when frames are composed from them (the
    /// surface can be copied into, and it is not turned off).
    panels: Option<Panels>,
    /// Whether the surface can be copied into (frames can be composed).
    can_compose: bool,
    /// How long the panels as last painted may stand for panels that
    /// changed, while [`Gfx::present`] is told they may lag (a part is
    /// being dragged); zero: never.
    pub panel_lag: Duration,
}

/// The window's panels as last painted and what they were painted from.
struct Panels {
    texture: Option<wgpu::Texture>,
    /// The primitives outside the views it was painted from, and where the
    /// views were (`None`: it cannot be reused).
    painted_from: Option<PaintedFrom>,
    /// When it was painted.
    painted_at: Option<Instant>,
}

/// What the panels were painted from: the primitives outside the views, and
/// each view's texture and pixel rectangle.
type PaintedFrom = (
    Vec<(egui::Rect, egui::epaint::Mesh)>,
    Vec<(egui::TextureId, [u32; 4])>,
);

/// What [`Gfx::present`] did.
#[derive(Debug, Default)]
pub struct Presented {
    /// The frame as shown (RGBA, sRGB-encoded), when asked for.
    pub image: Option<image::RgbaImage>,
    /// Whether the whole window was painted; otherwise the panels were copied
    /// from the last paint and only the 3D views' rectangles painted.
    pub painted_whole: bool,
    /// Whether the panels copied were painted from panels that have changed
    /// since (a drag within [`Gfx::panel_lag`] of their paint).
    pub panels_stale: bool,
}

impl std::fmt::Debug for Gfx {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gfx")
            .field("adapter", &self.adapter)
            .field("surface", &self.config)
            .field("views", &self.views.len())
            .finish_non_exhaustive()
    }
}

impl Gfx {
    /// Opens the device for `window` with the optional features the renderer
    /// uses, and configures the surface (`vsync` or as fast as possible).
    /// With `compose`, frames reuse the panels as last painted where the
    /// surface can be copied into.
    pub fn new(
        instance: &wgpu::Instance,
        window: Arc<Window>,
        vsync: bool,
        compose: bool,
    ) -> anyhow::Result<Self> {
        let surface = instance
            .create_surface(window.clone())
            .context("creating the window surface")?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: Some(&surface),
            ..Default::default()
        }))
        .context("no GPU adapter can draw into the window")?;
        let info = adapter.get_info();
        let required_features = adapter.features() & dmu_render::OPTIONAL_FEATURES;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("dmu-viewer"),
            required_features,
            required_limits: adapter.limits(),
            memory_hints: dmu_render::memory_hints(&info),
            ..Default::default()
        }))
        .with_context(|| format!("opening {}", info.name))?;
        let caps = surface.get_capabilities(&adapter);
        // egui wants a gamma-space target (it writes gamma values as they are).
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .context("the surface offers no format")?;
        let can_read_back = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        // The views are drawn in the surface's format, sRGB-encoding, and
        // copied into frames; a surface without an sRGB twin (10-bit, float)
        // gets the views in the capture format, shown through egui only.
        let view_format = if format.add_srgb_suffix() == format.remove_srgb_suffix() {
            dmu_render::CAPTURE_FORMAT
        } else {
            format.add_srgb_suffix()
        };
        let can_compose = caps.usages.contains(wgpu::TextureUsages::COPY_DST)
            && view_format.remove_srgb_suffix() == format.remove_srgb_suffix();
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | caps.usages & (wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST),
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: if vsync {
                wgpu::PresentMode::AutoVsync
            } else {
                wgpu::PresentMode::AutoNoVsync
            },
            desired_maximum_frame_latency: 2,
            alpha_mode: caps.alpha_modes[0],
            view_formats: vec![],
        };
        surface.configure(&device, &config);
        let egui = egui_wgpu::Renderer::new(
            &device,
            format,
            egui_wgpu::RendererOptions {
                // The 3D view goes through egui's shader: no noise on it.
                dithering: false,
                ..Default::default()
            },
        );
        let mut gfx = Self {
            window,
            device,
            queue,
            adapter: info.name,
            view_format,
            surface,
            config,
            can_read_back,
            egui,
            views: Vec::new(),
            panels: None,
            can_compose,
            panel_lag: Duration::ZERO,
        };
        gfx.set_compose(compose);
        Ok(gfx)
    }

    /// Composes frames from the panels as last painted (where the surface
    /// allows), or paints the whole window every frame.
    pub fn set_compose(&mut self, compose: bool) {
        if compose != self.panels.is_some() {
            self.panels = (compose && self.can_compose).then(|| Panels {
                texture: None,
                painted_from: None,
                painted_at: None,
            });
        }
    }

    /// Follows a window resize.
    pub fn resize(&mut self, width: u32, height: u32) {
        if width > 0 && height > 0 {
            self.config.width = width;
            self.config.height = height;
            self.surface.configure(&self.device, &self.config);
        }
    }

    /// Window size in physical pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.config.width, self.config.height)
    }

    /// Makes `count` 3D view targets exist (new ones 1x1 until sized), each
    /// with its egui texture.
    pub fn ensure_views(&mut self, count: usize) {
        while self.views.len() < count {
            let mut view = ViewTarget::new(&self.device, (1, 1), self.view_format);
            view.texture = self.egui.register_native_texture(
                &self.device,
                &view.egui_view,
                wgpu::FilterMode::Nearest,
            );
            self.views.push(view);
        }
    }

    /// Makes 3D view `index` (made by [`Gfx::ensure_views`]) `size` pixels,
    /// re-pointing its egui texture when the size changes.
    pub fn resize_view(&mut self, index: usize, size: (u32, u32)) {
        let size = (size.0.max(1), size.1.max(1));
        let view = &mut self.views[index];
        if view.size != size {
            let texture = view.texture;
            *view = ViewTarget::new(&self.device, size, self.view_format);
            view.texture = texture;
            self.egui.update_egui_texture_from_wgpu_texture(
                &self.device,
                &view.egui_view,
                wgpu::FilterMode::Nearest,
                texture,
            );
        }
    }

    /// Paints egui's output and presents it. When frames are composed and
    /// nothing outside the 3D views changed since the panels were last
    /// painted, the frame is a copy of that paint with only the views'
    /// rectangles painted over it; otherwise the whole window is painted (and
    /// kept). With `may_lag` (a part is being dragged: its position and
    /// clashes change every frame), panels that changed are still copied
    /// while their paint is under [`Gfx::panel_lag`] old, where the views
    /// have not moved: on a CPU rasterizer painting the whole window costs
    /// as much as the 3D view. With `read_back`, the frame as shown comes
    /// back too, never with stale panels.
    pub fn present(
        &mut self,
        ctx: &egui::Context,
        output: egui::FullOutput,
        read_back: bool,
        may_lag: bool,
    ) -> anyhow::Result<Presented> {
        // A new glyph or image changes how unchanged primitives look: the
        // kept panels are stale even if this frame is never shown.
        let textures_changed = !output.textures_delta.set.is_empty();
        if let Some(panels) = self.panels.as_mut().filter(|_| textures_changed) {
            panels.painted_from = None;
        }
        // Texture updates go first: egui counts them applied whatever happens next.
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                self.egui
                    .update_texture(&self.device, &self.queue, *id, delta);
            }
        }
        let mut output = output;
        output.textures_delta.set.clear();
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            other => {
                for id in &output.textures_delta.free {
                    self.egui.free_texture(id);
                }
                output.textures_delta.clear();
                if matches!(
                    other,
                    wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost
                ) {
                    self.surface.configure(&self.device, &self.config);
                }
                if read_back {
                    anyhow::bail!("no frame to read back: the surface said {other:?}");
                }
                return Ok(Presented::default());
            }
        };
        let pixels_per_point = output.pixels_per_point;
        let jobs = ctx.tessellate(std::mem::take(&mut output.shapes), pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [self.config.width, self.config.height],
            pixels_per_point,
        };
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("dmu-viewer egui"),
            });
        let target = frame.texture.create_view(&Default::default());
        let view_textures: Vec<egui::TextureId> = self.views.iter().map(|v| v.texture).collect();
        let size = frame.texture.size();
        // The views' images to copy: set when the panels' last paint is
        // reused, and then only what lies over the views is painted.
        let mut copies = None;
        let mut panels_stale = false;
        let (jobs, panels) = match self.panels.as_mut() {
            None => (jobs, None),
            Some(panels) => {
                let split = crate::compose::split(&jobs, &view_textures, pixels_per_point);
                if panels.texture.as_ref().map(wgpu::Texture::size) != Some(size) {
                    panels.texture = Some(self.device.create_texture(&wgpu::TextureDescriptor {
                        label: Some("dmu-viewer panels"),
                        size,
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: wgpu::TextureDimension::D2,
                        format: self.config.format,
                        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                            | wgpu::TextureUsages::COPY_SRC,
                        view_formats: &[],
                    }));
                    panels.painted_from = None;
                }
                let found = split
                    .as_ref()
                    .and_then(|s| image_copies(&self.views, &s.images, size));
                let (same_panels, same_views) = match (split.as_ref(), panels.painted_from.as_ref())
                {
                    (Some(s), Some((p, i))) => (s.panels == *p, s.images == *i),
                    _ => (false, false),
                };
                let lagging = may_lag
                    && !read_back
                    && panels
                        .painted_at
                        .is_some_and(|at| at.elapsed() < self.panel_lag);
                let reuse =
                    !textures_changed && found.is_some() && same_views && (same_panels || lagging);
                panels_stale = reuse && !same_panels;
                let jobs = match split {
                    Some(split) if reuse => {
                        copies = found;
                        split.over_views
                    }
                    split => {
                        panels.painted_from = split.map(|s| (s.panels, s.images));
                        panels.painted_at = Some(Instant::now());
                        jobs
                    }
                };
                (jobs, panels.texture.as_ref())
            }
        };
        let mut commands =
            self.egui
                .update_buffers(&self.device, &self.queue, &mut encoder, &jobs, &screen);
        let painted_whole = copies.is_none();
        // The panels, painted anew where they changed, then copied in.
        if let Some(texture) = panels {
            if painted_whole {
                let view = texture.create_view(&Default::default());
                paint(&self.egui, &mut encoder, &view, true, &jobs, &screen);
            }
            encoder.copy_texture_to_texture(
                texture.as_image_copy(),
                frame.texture.as_image_copy(),
                size,
            );
        }
        match (panels, copies) {
            (None, _) => paint(&self.egui, &mut encoder, &target, true, &jobs, &screen),
            (Some(_), None) => {}
            (Some(_), Some(copies)) => {
                // The views' images, then what lies over them.
                for (view, origin) in copies {
                    encoder.copy_texture_to_texture(
                        view.as_image_copy(),
                        wgpu::TexelCopyTextureInfo {
                            texture: &frame.texture,
                            mip_level: 0,
                            origin,
                            aspect: wgpu::TextureAspect::All,
                        },
                        view.size(),
                    );
                }
                paint(&self.egui, &mut encoder, &target, false, &jobs, &screen);
            }
        }
        let readback = (read_back && self.can_read_back).then(|| {
            let (w, h) = (frame.texture.width(), frame.texture.height());
            let row = (4 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
            let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dmu-viewer screenshot"),
                size: u64::from(row) * u64::from(h),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            encoder.copy_texture_to_buffer(
                frame.texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row),
                        rows_per_image: Some(h),
                    },
                },
                frame.texture.size(),
            );
            (buffer, row, w, h)
        });
        commands.push(encoder.finish());
        self.queue.submit(commands);
        self.window.pre_present_notify();
        self.queue.present(frame);
        for id in &output.textures_delta.free {
            self.egui.free_texture(id);
        }
        output.textures_delta.clear();
        let image = match readback {
            Some((buffer, row, w, h)) => Some(self.read_frame(&buffer, row, w, h)?),
            None if read_back => anyhow::bail!(
                "this surface cannot be copied from (no COPY_SRC usage): no screenshot"
            ),
            None => None,
        };
        Ok(Presented {
            image,
            painted_whole,
            panels_stale,
        })
    }

    fn read_frame(
        &self,
        buffer: &wgpu::Buffer,
        row: u32,
        w: u32,
        h: u32,
    ) -> anyhow::Result<image::RgbaImage> {
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .context("waiting for the screenshot")?;
        rx.recv()?.context("mapping the screenshot")?;
        let bgra = matches!(
            self.config.format,
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        );
        anyhow::ensure!(
            bgra || matches!(
                self.config.format,
                wgpu::TextureFormat::Rgba8Unorm | wgpu::TextureFormat::Rgba8UnormSrgb
            ),
            "screenshots of a {:?} surface are not supported",
            self.config.format
        );
        let mapped = buffer
            .get_mapped_range(..)
            .map_err(|e| anyhow::anyhow!("reading the screenshot: {e}"))?;
        let mut pixels = Vec::with_capacity((4 * w * h) as usize);
        for y in 0..h as usize {
            let line = &mapped[y * row as usize..][..4 * w as usize];
            for p in line.chunks_exact(4) {
                let (r, b) = if bgra { (p[2], p[0]) } else { (p[0], p[2]) };
                // The window is opaque whatever the swapchain's alpha holds.
                pixels.extend_from_slice(&[r, p[1], b, 255]);
            }
        }
        drop(mapped);
        buffer.unmap();
        image::RgbaImage::from_raw(w, h, pixels).context("screenshot size")
    }
}

/// Paints egui's `jobs` (their buffers updated) into `target`, cleared first
/// when `clear`.
fn paint(
    egui: &egui_wgpu::Renderer,
    encoder: &mut wgpu::CommandEncoder,
    target: &wgpu::TextureView,
    clear: bool,
    jobs: &[egui::ClippedPrimitive],
    screen: &egui_wgpu::ScreenDescriptor,
) {
    let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("dmu-viewer egui"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: if clear {
                    wgpu::LoadOp::Clear(wgpu::Color::BLACK)
                } else {
                    wgpu::LoadOp::Load
                },
                store: wgpu::StoreOp::Store,
            },
        })],
        ..Default::default()
    });
    egui.render(&mut pass.forget_lifetime(), jobs, screen);
}

/// Where each view's image goes in a frame of `frame` size: its colour
/// texture and the pixel it starts at. `None` when an image is not exactly
/// its view's texture inside the frame (a pane being resized), which only a
/// paint can show.
fn image_copies<'a>(
    views: &'a [ViewTarget],
    images: &[(egui::TextureId, [u32; 4])],
    frame: wgpu::Extent3d,
) -> Option<Vec<(&'a wgpu::Texture, wgpu::Origin3d)>> {
    images
        .iter()
        .map(|&(id, [x, y, w, h])| {
            let view = views.iter().find(|v| v.texture == id)?;
            let fits = (w, h) == view.size
                && x.checked_add(w)? <= frame.width
                && y.checked_add(h)? <= frame.height;
            fits.then_some((&view.color, wgpu::Origin3d { x, y, z: 0 }))
        })
        .collect()
}
