//! `dmu render --stereo --shared-far-px E` and `--reproject`: a stereo pair
//! with headset-like asymmetric eye fields of view drawn for less than two
//! eyes, beside the pair drawn in full and one eye alone (their frames
//! interleaved, every view lit from between the eyes).
//!
//! `--reproject` draws the left eye once, wide enough for the right eye's
//! window too, and moves each of its pixels by its disparity into the right
//! eye ([`dmu_render::Reprojector`]): every pixel seen by both eyes lands
//! within half a pixel of where it belongs, and the gaps along near
//! silhouettes, which only the right eye sees into, are filled from the
//! farther side.
//!
//! `--shared-far-px E` shares the far part. Beyond the depth `D` where the eyes' disparity is below `E` pixels the two
//! eyes' images differ by less than `E`, so that part is drawn once, from
//! between the eyes, into an image covering both eyes' windows on their pixel
//! grid, and copied into each eye; only the near part (depth below `D`: the
//! far plane of the eye's view) is drawn per eye, over it. With parallel eyes
//! a point's depth is the same from either eye and from between them, so the
//! split is exact: every near fragment lies in front of every far one.
//!
//! The disparity error of the shared part is at most `ipd * fx / D` (the
//! disparity it no longer has, `fx` the pixels per unit tangent) plus the
//! right eye's window's offset from the shared image's pixel grid (the left
//! eye's is aligned), which the split distance leaves room for.

use std::time::Instant;

use anyhow::Context as _;
use dmu_geom::Fov;
use dmu_render::{
    Camera, Capture, Culling, CullingOptions, Renderer, Reprojection, Reprojector, StereoCamera,
    View, wgpu,
};
use dmu_scene::Scene;
use dmu_tree::Tree;
use serde_json::{Value, json};

/// The left eye's field of view from `l,r,d,u` in degrees (left and down
/// negative); the right eye's is its mirror image.
pub fn eye_fovs(degrees: &[f64; 4]) -> anyhow::Result<[Fov; 2]> {
    let [left, right, down, up] = degrees.map(f64::to_radians);
    let left_eye = Fov {
        left,
        right,
        down,
        up,
    };
    anyhow::ensure!(
        left_eye.is_valid(),
        "--eye-fov {degrees:?}: each angle must lie in (-90, 90) degrees, left below right, down below up"
    );
    Ok([
        left_eye,
        Fov {
            left: -right,
            right: -left,
            ..left_eye
        },
    ])
}

/// The eyes' fields of view from `--eye-fov L,R,D,U` (degrees, the left
/// eye's; [`eye_fovs`]).
pub fn parse_eye_fov(text: &str) -> anyhow::Result<[Fov; 2]> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--eye-fov {text:?}: four numbers, degrees"))?;
    let degrees: [f64; 4] = v.try_into().map_err(|v: Vec<f64>| {
        anyhow::anyhow!("--eye-fov {text:?}: four numbers, not {}", v.len())
    })?;
    eye_fovs(&degrees)
}

/// What the comparison runs with.
#[derive(Debug)]
pub struct Setup<'a> {
    /// The camera between the eyes (position, view direction, near plane).
    pub center: Camera,
    /// Eye separation, world units.
    pub ipd: f64,
    /// The eyes' fields of view (left, right).
    pub fovs: [Fov; 2],
    /// Each eye's image size.
    pub size: (u32, u32),
    pub culling: Culling,
    pub options: CullingOptions,
    pub frames: u32,
    pub scene: &'a Scene,
    pub tree: &'a Tree,
}

/// Where the shared far image lies against the eyes' windows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SharedWindow {
    /// The far image's field of view (both eyes' windows on one pixel grid).
    pub fov: Fov,
    /// Its width, pixels (height: the eyes').
    pub width: u32,
    /// Each eye's window's first column in it.
    pub offsets: [u32; 2],
    /// The disparity the shared part shows, pixels (left x minus right x):
    /// the right eye's window lies a fraction of a pixel off the grid (the
    /// left's is on it), and its column is rounded the way that suits `error_px`.
    pub shared_disparity_px: f64,
    /// The largest disparity, pixels, of what may be shared: content with a
    /// disparity from 0 to this shows `shared_disparity_px` instead, an error
    /// of at most `error_px`.
    pub max_shared_disparity_px: f64,
    /// Pixels per unit tangent, horizontally.
    pub fx: f64,
}

impl SharedWindow {
    /// The worst disparity error of the shared part, pixels.
    pub fn error_bound_px(&self) -> f64 {
        self.shared_disparity_px
            .abs()
            .max((self.max_shared_disparity_px - self.shared_disparity_px).abs())
    }
}

/// One pixel grid for both eyes' windows: the left eye's pixels, started a
/// whole number of pixels left of the left eye's window where the right
/// eye's reaches further left.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Grid {
    /// Pixels per unit tangent, horizontally.
    fx: f64,
    /// The tangent of the grid's left edge.
    start: f64,
    /// The left eye's window's first column.
    left_offset: u32,
    /// The right eye's window's first column, generally fractional.
    right_offset: f64,
}

impl Grid {
    fn new(fovs: &[Fov; 2], size: (u32, u32)) -> Self {
        let [l0, r0, _, _] = fovs[0].tangents();
        let [l1, _, _, _] = fovs[1].tangents();
        let fx = f64::from(size.0) / (r0 - l0);
        let left_offset = ((l0 - l0.min(l1)) * fx).ceil();
        let start = l0 - left_offset / fx;
        Self {
            fx,
            start,
            left_offset: left_offset as u32,
            right_offset: (l1 - start) * fx,
        }
    }
}

/// The shared image's window for eyes with `fovs` and images `size`, sharing
/// what an error of `error_px` allows; `None` when the right eye's window's
/// offset from the grid alone exceeds it.
pub fn shared_window(fovs: &[Fov; 2], size: (u32, u32), error_px: f64) -> Option<SharedWindow> {
    let Grid {
        fx,
        start,
        left_offset,
        right_offset,
    } = Grid::new(fovs, size);
    // Taking the right eye's window from column c shows the shared part with
    // disparity c - right_offset. True disparities of shared content run from
    // 0 to some d; the error is at most max(|s|, |d - s|): with s >= 0 (column
    // rounded up) d may reach s + error, with s < 0 only error + s.
    let up = right_offset.ceil() - right_offset;
    let down = right_offset.floor() - right_offset;
    let (column, shared, max) = [
        (right_offset.ceil(), up, up + error_px),
        (right_offset.floor(), down, error_px + down),
    ]
    .into_iter()
    .filter(|&(_, s, d)| s.abs() <= error_px && d > 0.0)
    .max_by(|a, b| a.2.total_cmp(&b.2))?;
    let offsets = [left_offset, column as u32];
    let width = offsets.iter().max().copied().unwrap_or(0) + size.0;
    Some(SharedWindow {
        fov: Fov {
            left: start.atan(),
            right: (start + f64::from(width) / fx).atan(),
            ..fovs[0]
        },
        width,
        offsets,
        shared_disparity_px: shared,
        max_shared_disparity_px: max,
        fx,
    })
}

/// Columns the left eye's image for reprojection reaches beyond the right
/// eye's window, for eyes `width` pixels wide: a fortieth of it (32 at
/// 1280). The right eye's last columns show what lies that much further
/// right from the left eye: content nearer than `ipd * fx / margin` (65 mm
/// at about 1.2 m for a 1280 px headset eye) is filled there instead.
pub fn reproject_margin(width: u32) -> u32 {
    width.div_ceil(40)
}

/// The left eye's image the right eye is reprojected from: the left eye's
/// pixel grid over both eyes' windows and [`reproject_margin`] more.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideWindow {
    pub fov: Fov,
    pub width: u32,
    /// The left eye's window's first column.
    pub left_offset: u32,
    /// The right eye's window's first column (fractional).
    pub right_offset: f64,
    /// Pixels per unit tangent, horizontally.
    pub fx: f64,
}

/// The left eye's wide image for eyes with `fovs` and images `size`; an error
/// where the eyes' pixel scales or vertical fields of view differ (a row of
/// one would not be a row of the other).
pub fn wide_window(fovs: &[Fov; 2], size: (u32, u32)) -> anyhow::Result<WideWindow> {
    let [l0, r0, d0, u0] = fovs[0].tangents();
    let [l1, r1, d1, u1] = fovs[1].tangents();
    anyhow::ensure!(
        ((r1 - l1) - (r0 - l0)).abs() < 1e-9 && (d1 - d0).abs() < 1e-9 && (u1 - u0).abs() < 1e-9,
        "--reproject needs eyes of one horizontal extent and one vertical field of view"
    );
    let grid = Grid::new(fovs, size);
    let width =
        ((r0.max(r1) - grid.start) * grid.fx - 1e-9).ceil() as u32 + reproject_margin(size.0);
    Ok(WideWindow {
        fov: Fov {
            left: grid.start.atan(),
            right: (grid.start + f64::from(width) / grid.fx).atan(),
            ..fovs[0]
        },
        width,
        left_offset: grid.left_offset,
        right_offset: grid.right_offset,
        fx: grid.fx,
    })
}

/// Median of the second half of `times` (the first frames warm caches up).
fn steady(times: &[f64]) -> f64 {
    dmu_geom::median(times[times.len() / 2..].to_vec())
}

/// Waits for the GPU; the milliseconds since `start`.
fn waited(device: &wgpu::Device, start: Instant) -> anyhow::Result<f64> {
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .context("waiting for the GPU")?;
    Ok(start.elapsed().as_secs_f64() * 1e3)
}

/// An error unless both eyes' windows on one pixel grid, `margin` columns
/// more, fit a texture of this device: the image `flag` draws (checked in
/// f64, before any width is a `u32`).
fn grid_fits(
    device: &wgpu::Device,
    fovs: &[Fov; 2],
    size: (u32, u32),
    margin: u32,
    flag: &str,
) -> anyhow::Result<()> {
    let [l0, r0, _, _] = fovs[0].tangents();
    let [l1, r1, _, _] = fovs[1].tangents();
    let fx = f64::from(size.0) / (r0 - l0);
    // Two columns for rounding each window onto the grid.
    let width = (r0.max(r1) - l0.min(l1)) * fx + f64::from(margin) + 2.0;
    let side = device.limits().max_texture_dimension_2d;
    anyhow::ensure!(
        width <= f64::from(side) && size.1 <= side,
        "{flag}: both eyes' windows on one pixel grid make a {width:.0}x{} image, more than this device's {side} px a side; make --size smaller or let the --eye-fov windows overlap more",
        size.1
    );
    Ok(())
}

/// Copies `size` pixels of `from`'s colour from column `x` into layer
/// `layer` of `to`'s.
fn copy_window(
    encoder: &mut wgpu::CommandEncoder,
    from: &Capture,
    x: u32,
    to: &Capture,
    layer: u32,
    size: (u32, u32),
) {
    encoder.copy_texture_to_texture(
        wgpu::TexelCopyTextureInfo {
            origin: wgpu::Origin3d { x, y: 0, z: 0 },
            ..from.color_texture().as_image_copy()
        },
        wgpu::TexelCopyTextureInfo {
            origin: wgpu::Origin3d {
                x: 0,
                y: 0,
                z: layer,
            },
            ..to.color_texture().as_image_copy()
        },
        wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: 1,
        },
    );
}

/// The pixels of each eye of `pair` that differ from the pair drawn in full
/// (`full`), at all and by more than 8 levels; saves `pair`'s eyes to
/// `outputs`.
fn difference(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pair: &Capture,
    full: &Capture,
    outputs: &[std::path::PathBuf; 2],
) -> anyhow::Result<Value> {
    let mut differing = [0usize; 2];
    let mut over_8 = [0usize; 2];
    for e in 0..2 {
        let a = pair.read_color_layer(device, queue, e as u32)?;
        let b = full.read_color_layer(device, queue, e as u32)?;
        for (p, q) in a.pixels().zip(b.pixels()) {
            let d =
                p.0.iter()
                    .zip(q.0)
                    .map(|(x, y)| x.abs_diff(y))
                    .max()
                    .unwrap_or(0);
            differing[e] += usize::from(d > 0);
            over_8[e] += usize::from(d > 8);
        }
        dmu_render::save_png(&a, &outputs[e])?;
    }
    let (w, h) = pair.size();
    let pixels = f64::from(w) * f64::from(h);
    Ok(json!({
        "pixels_differing": differing,
        "fraction_differing": differing.map(|d| d as f64 / pixels),
        "pixels_over_8_levels": over_8,
        "fraction_over_8_levels": over_8.map(|d| d as f64 / pixels),
    }))
}

/// The cheaper pairs `compare` draws beside the pair in full, each with the
/// paths its eyes are saved to.
#[derive(Debug)]
pub struct Variants {
    /// The far part shared beyond this disparity error, pixels.
    pub shared_far: Option<(f64, [std::path::PathBuf; 2])>,
    /// The right eye reprojected from the left eye's image.
    pub reprojected: Option<[std::path::PathBuf; 2]>,
}

/// What every drawing holds: the views' settings and the renderer's inputs.
struct Ctx<'a, 's> {
    s: &'a Setup<'s>,
    device: &'a wgpu::Device,
    queue: &'a wgpu::Queue,
}

impl Ctx<'_, '_> {
    /// A view of `camera` with a field of view and size, lit from between
    /// the eyes, as one lamp on the head lights both: a surface point shades
    /// alike in either eye, as a reprojected eye shows it.
    fn view(&self, camera: Camera, fov: Fov, size: (u32, u32)) -> View {
        let mut v = View::new(camera, size, self.s.culling);
        v.options = self.s.options;
        v.fov = Some(fov);
        v.light = Some(self.s.center.eye);
        v
    }

    fn eyes(&self) -> [Camera; 2] {
        StereoCamera {
            center: self.s.center,
            ipd: self.s.ipd,
        }
        .eyes()
    }

    fn render(
        &self,
        renderer: &mut Renderer,
        view: &mut View,
        target: dmu_render::FrameTarget<'_>,
    ) -> anyhow::Result<dmu_render::FrameStats> {
        let (scene, tree) = (self.s.scene, self.s.tree);
        Ok(renderer.render(view, scene, tree, scene, target)?)
    }
}

/// A way of drawing the pair (or one eye), a frame at a time, timed by the
/// caller; the frames of all of them interleave, so a busy moment of this
/// shared machine slows them alike.
trait Drawing {
    /// Draws a frame and submits it (the caller waits for it).
    fn frame(&mut self, renderer: &mut Renderer, c: &Ctx<'_, '_>) -> anyhow::Result<()>;
}

/// The pair drawn in full: each eye its own view.
struct FullPair {
    views: [View; 2],
    pair: Capture,
    triangles: u64,
}

impl Drawing for FullPair {
    fn frame(&mut self, renderer: &mut Renderer, c: &Ctx<'_, '_>) -> anyhow::Result<()> {
        let target = self.pair.stereo_target();
        self.triangles = 0;
        for (e, v) in self.views.iter_mut().enumerate() {
            self.triangles += c.render(renderer, v, target.eyes[e])?.triangles_drawn;
        }
        Ok(())
    }
}

/// The left eye alone.
struct OneEye {
    view: View,
    capture: Capture,
    draw_calls: u64,
}

impl Drawing for OneEye {
    fn frame(&mut self, renderer: &mut Renderer, c: &Ctx<'_, '_>) -> anyhow::Result<()> {
        self.draw_calls = c
            .render(renderer, &mut self.view, self.capture.frame_target())?
            .draw_calls;
        Ok(())
    }
}

/// The pair with its far part shared ([`shared_window`]).
struct SharedFar {
    error_px: f64,
    window: SharedWindow,
    split: f64,
    far_view: View,
    near_views: [View; 2],
    far_capture: Capture,
    pair: Capture,
    triangles: [u64; 2],
    /// Per frame: the far pass's time and the near passes' (both eyes).
    parts: Vec<[f64; 2]>,
    /// The last frame's draw calls: far, near (both eyes).
    calls: [u64; 2],
}

impl SharedFar {
    fn new(c: &Ctx<'_, '_>, error_px: f64) -> anyhow::Result<Self> {
        let s = c.s;
        grid_fits(c.device, &s.fovs, s.size, 0, "--shared-far-px")?;
        let window = shared_window(&s.fovs, s.size, error_px).with_context(|| {
            format!(
                "--shared-far-px {error_px}: the eyes' windows lie too far off one pixel grid at this size; allow more"
            )
        })?;
        // Beyond this depth the eyes' disparity is below what may be shared.
        let split = s.ipd * window.fx / window.max_shared_disparity_px;
        anyhow::ensure!(
            split > s.center.near * (1.0 + 1e-9),
            "--shared-far-px {error_px}: with --ipd {} the eyes' disparity is within it everywhere beyond the near plane ({}), so there is no near part to draw per eye; use a smaller --shared-far-px or a larger --ipd",
            s.ipd,
            s.center.near
        );
        let eyes = c.eyes();
        let far_view = c.view(
            Camera {
                near: split.max(s.center.near),
                ..s.center
            },
            window.fov,
            (window.width, s.size.1),
        );
        let near_views = [0, 1].map(|e| {
            let mut v = c.view(eyes[e], s.fovs[e], s.size);
            v.far = Some(split);
            v.keep_color = true;
            v
        });
        Ok(Self {
            error_px,
            window,
            split,
            far_view,
            near_views,
            far_capture: Capture::new(c.device, (window.width, s.size.1)),
            pair: Capture::stereo(c.device, s.size),
            triangles: [0; 2],
            parts: Vec::new(),
            calls: [0; 2],
        })
    }

    fn report(&self, frame_ms: f64) -> Value {
        let w = &self.window;
        json!({
            "error_px": self.error_px,
            "split_depth": self.split,
            "pixels_per_tangent": w.fx,
            "shared_width": w.width,
            "eye_offsets": w.offsets,
            "shared_disparity_px": w.shared_disparity_px,
            "disparity_error_bound_px": w.error_bound_px(),
            "frame_ms": frame_ms,
            "triangles": { "far": self.triangles[0], "near_both_eyes": self.triangles[1] },
            // Where the shared pair's time goes, each a median of its own (the
            // copy of the far image into the eyes is waited for by the first near
            // pass, so it is in the near passes' time), and the draw calls of each.
            "far_pass_ms": steady(&self.parts.iter().map(|p| p[0]).collect::<Vec<_>>()),
            "near_passes_ms": steady(&self.parts.iter().map(|p| p[1]).collect::<Vec<_>>()),
            "draw_calls": { "far": self.calls[0], "near_both_eyes": self.calls[1] },
        })
    }
}

impl Drawing for SharedFar {
    fn frame(&mut self, renderer: &mut Renderer, c: &Ctx<'_, '_>) -> anyhow::Result<()> {
        let far = c.render(
            renderer,
            &mut self.far_view,
            self.far_capture.frame_target(),
        )?;
        let mut part = [far.cpu_ms, 0.0];
        self.calls = [far.draw_calls, 0];
        self.triangles = [far.triangles_drawn, 0];
        let mut encoder = c.device.create_command_encoder(&Default::default());
        for (e, &offset) in self.window.offsets.iter().enumerate() {
            let (from, to) = (&self.far_capture, &self.pair);
            copy_window(&mut encoder, from, offset, to, e as u32, c.s.size);
        }
        c.queue.submit([encoder.finish()]);
        let target = self.pair.stereo_target();
        for (e, v) in self.near_views.iter_mut().enumerate() {
            let near = c.render(renderer, v, target.eyes[e])?;
            self.triangles[1] += near.triangles_drawn;
            part[1] += near.cpu_ms;
            self.calls[1] += near.draw_calls;
        }
        self.parts.push(part);
        Ok(())
    }
}

/// The pair with its right eye reprojected from the left eye's wide image
/// ([`wide_window`], [`dmu_render::Reprojector`]).
struct Reprojected {
    window: WideWindow,
    wide_view: View,
    wide: Capture,
    pair: Capture,
    reprojector: Reprojector,
    triangles: u64,
    draw_calls: u64,
    /// Per frame: the wide left eye's time, and the reprojection's (with
    /// the copy of the left window), each waited for.
    parts: Vec<[f64; 2]>,
}

impl Reprojected {
    fn new(c: &Ctx<'_, '_>) -> anyhow::Result<Self> {
        let s = c.s;
        grid_fits(
            c.device,
            &s.fovs,
            s.size,
            reproject_margin(s.size.0),
            "--reproject",
        )?;
        let window = wide_window(&s.fovs, s.size)?;
        let left = c.eyes()[0];
        let wide_size = (window.width, s.size.1);
        let limits = c.device.limits();
        let buffer = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let bytes = u64::from(s.size.0.next_multiple_of(64)) * u64::from(s.size.1) * 4;
        anyhow::ensure!(
            bytes <= buffer,
            "--reproject: a {}x{} eye needs {bytes} bytes in one buffer, more than this device's {buffer}; make --size smaller",
            s.size.0,
            s.size.1
        );
        Ok(Self {
            window,
            wide_view: c.view(left, window.fov, wide_size),
            wide: Capture::new(c.device, wide_size),
            pair: Capture::stereo(c.device, s.size),
            reprojector: Reprojector::new(
                c.device,
                c.queue,
                Reprojection {
                    source_size: wide_size,
                    target_size: s.size,
                    target_offset: window.right_offset,
                    disparity_at_near_px: s.ipd * window.fx / left.near,
                },
            ),
            triangles: 0,
            draw_calls: 0,
            parts: Vec::new(),
        })
    }

    fn report(&self, c: &Ctx<'_, '_>, frame_ms: f64) -> anyhow::Result<Value> {
        let gaps = self.reprojector.read_gaps(c.device, c.queue)?;
        let pixels = f64::from(c.s.size.0) * f64::from(c.s.size.1);
        let part = |k: usize| steady(&self.parts.iter().map(|p| p[k]).collect::<Vec<_>>());
        Ok(json!({
            "pixels_per_tangent": self.window.fx,
            "wide_width": self.window.width,
            "margin_px": reproject_margin(c.s.size.0),
            "right_eye_offset": self.window.right_offset,
            // Every pixel that lands lands in the pixel holding where it
            // belongs; the gaps (along near silhouettes, and single columns
            // where a slanted surface widens in the right eye) are filled
            // from a neighbour instead and show in the difference.
            "disparity_error_bound_px": 0.5,
            "frame_ms": frame_ms,
            "wide_pass_ms": part(0),
            "reproject_ms": part(1),
            "triangles": { "wide": self.triangles },
            "draw_calls": { "wide": self.draw_calls },
            "gap_pixels": gaps,
            "gap_fraction": gaps as f64 / pixels,
        }))
    }
}

impl Drawing for Reprojected {
    fn frame(&mut self, renderer: &mut Renderer, c: &Ctx<'_, '_>) -> anyhow::Result<()> {
        let start = Instant::now();
        let stats = c.render(renderer, &mut self.wide_view, self.wide.frame_target())?;
        let drawn = waited(c.device, start)?;
        (self.triangles, self.draw_calls) = (stats.triangles_drawn, stats.draw_calls);
        let start = Instant::now();
        let mut encoder = c.device.create_command_encoder(&Default::default());
        let left = self.window.left_offset;
        copy_window(&mut encoder, &self.wide, left, &self.pair, 0, c.s.size);
        self.reprojector
            .encode(c.device, &mut encoder, &self.wide, &self.pair, 1);
        c.queue.submit([encoder.finish()]);
        self.parts.push([drawn, waited(c.device, start)?]);
        Ok(())
    }
}

/// Draws the pair in full, one eye alone and each of `variants`, their
/// frames interleaved; the report: each variant's frame time against one eye
/// and against the pair in full, and its image difference from the pair in
/// full.
pub fn compare(
    renderer: &mut Renderer,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    s: &Setup<'_>,
    variants: &Variants,
) -> anyhow::Result<Value> {
    let c = Ctx { s, device, queue };
    let eyes = c.eyes();
    let mut full = FullPair {
        views: [0, 1].map(|e| c.view(eyes[e], s.fovs[e], s.size)),
        pair: Capture::stereo(device, s.size),
        triangles: 0,
    };
    let mut one = OneEye {
        view: c.view(eyes[0], s.fovs[0], s.size),
        capture: Capture::new(device, s.size),
        draw_calls: 0,
    };
    let mut shared = match &variants.shared_far {
        Some((error_px, _)) => Some(SharedFar::new(&c, *error_px)?),
        None => None,
    };
    let mut reprojected = match &variants.reprojected {
        Some(_) => Some(Reprojected::new(&c)?),
        None => None,
    };
    // Frame times: the pair in full, one eye, shared, reprojected.
    let mut times: [Vec<f64>; 4] = Default::default();
    for _ in 0..s.frames.max(1) {
        let mut drawings: [Option<&mut dyn Drawing>; 4] = [
            Some(&mut full),
            Some(&mut one),
            shared.as_mut().map(|d| d as &mut dyn Drawing),
            reprojected.as_mut().map(|d| d as &mut dyn Drawing),
        ];
        for (drawing, t) in drawings.iter_mut().zip(&mut times) {
            if let Some(d) = drawing {
                let start = Instant::now();
                d.frame(renderer, &c)?;
                t.push(waited(device, start)?);
            }
        }
    }
    let [full_med, one_med, shared_med, reprojected_med] =
        times.map(|t| if t.is_empty() { f64::NAN } else { steady(&t) });
    // What every variant's report holds besides its own: the eyes, the pair
    // in full and one eye, its ratios, its image difference.
    let finish = |mut report: Value, pair: &Capture, outputs: &[std::path::PathBuf; 2]| {
        let frame_ms = report["frame_ms"].as_f64().unwrap_or(f64::NAN);
        report["eye_fov_deg"] = json!(
            s.fovs
                .map(|f| [f.left, f.right, f.down, f.up].map(f64::to_degrees))
        );
        report["lit_from"] = json!("between the eyes");
        report["one_eye_frame_ms"] = json!(one_med);
        report["true_stereo_frame_ms"] = json!(full_med);
        report["ratio"] = json!(frame_ms / one_med);
        report["true_stereo_ratio"] = json!(full_med / one_med);
        report["triangles"]["true_stereo"] = json!(full.triangles);
        report["draw_calls"]["one_eye"] = json!(one.draw_calls);
        report["image_difference"] = difference(device, queue, pair, &full.pair, outputs)?;
        report["outputs"] = json!(outputs);
        anyhow::Ok(report)
    };
    let shared_far = match (&shared, &variants.shared_far) {
        (Some(d), Some((_, outputs))) => Some(finish(d.report(shared_med), &d.pair, outputs)?),
        _ => None,
    };
    let reprojected = match (&reprojected, &variants.reprojected) {
        (Some(d), Some(outputs)) => Some(finish(d.report(&c, reprojected_med)?, &d.pair, outputs)?),
        _ => None,
    };
    Ok(json!({ "shared_far": shared_far, "reprojected": reprojected }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mirrored asymmetric eyes: the shared window holds both on one grid,
    /// the left exactly, the right within a pixel, the union covered; the
    /// shared part's disparity error, brute-forced over depths, stays within
    /// the bound and the bound within what was allowed.
    #[test]
    fn shared_window_covers_both_eyes_within_the_error() {
        let fovs = eye_fovs(&[-52.0, 43.0, -50.0, 48.0]).unwrap();
        let mut shared = 0;
        for width in [640, 720, 800, 960, 1280, 1440] {
            let size = (width, 700);
            let fx = f64::from(width) / (fovs[0].right.tan() - fovs[0].left.tan());
            let Some(w) = shared_window(&fovs, size, 0.5) else {
                // Only where the right window lies about half a pixel off.
                let off = (fovs[1].left.tan() - fovs[0].left.tan()) * fx;
                assert!((off.fract() - 0.5).abs() < 0.01, "width {width}: {off}");
                continue;
            };
            shared += 1;
            let px = |t: f64| (t - w.fov.left.tan()) * w.fx;
            for (e, fov) in fovs.iter().enumerate() {
                let [l, r, _, _] = fov.tangents();
                let column = px(l);
                assert!(
                    (column - f64::from(w.offsets[e])).abs() < 1.0,
                    "eye {e}: {column}"
                );
                assert!(px(r) <= f64::from(w.width) + 1.0);
            }
            assert!((px(fovs[0].left.tan()) - f64::from(w.offsets[0])).abs() < 1e-6);
            assert!((w.fx - fx).abs() < 1e-9);
            // The eyes' true disparity at depth z is ipd fx / z; shared
            // content shows `shared_disparity_px` instead.
            let ipd = 63.0;
            let split = ipd * w.fx / w.max_shared_disparity_px;
            let worst = (0..=1000)
                .map(|i| split * (1.0 + f64::from(i) * 0.01).powi(3))
                .map(|z| (ipd * w.fx / z - w.shared_disparity_px).abs())
                .fold(0.0, f64::max);
            assert!(worst <= w.error_bound_px() + 1e-9, "width {width}: {worst}");
            assert!(w.error_bound_px() <= 0.5 + 1e-9, "width {width}");
        }
        assert!(shared >= 4, "{shared} widths shared");
        assert!(eye_fovs(&[10.0, -10.0, -40.0, 40.0]).is_err());
    }

    /// The wide image holds the left eye's window exactly and the right
    /// eye's on the same grid, its offset the fraction the tangents give,
    /// plus the margin, for mirrored eyes wider outside and wider inside;
    /// eyes of different extents are refused.
    #[test]
    fn wide_window_holds_both_eyes_on_the_left_grid() {
        for degrees in [[-52.0, 43.0, -50.0, 48.0], [-43.0, 52.0, -50.0, 48.0]] {
            let fovs = eye_fovs(&degrees).unwrap();
            for width in [320, 1280, 1279] {
                let size = (width, 700);
                let w = wide_window(&fovs, size).unwrap();
                let [l0, r0, _, _] = fovs[0].tangents();
                let [l1, r1, _, _] = fovs[1].tangents();
                let fx = f64::from(width) / (r0 - l0);
                assert!((w.fx - fx).abs() < 1e-9);
                let px = |t: f64| (t - w.fov.left.tan()) * fx;
                // The left window starts on a column, the right where its
                // tangent falls; both end inside, the margin beyond.
                assert!(
                    (px(l0) - f64::from(w.left_offset)).abs() < 1e-6,
                    "{degrees:?}"
                );
                assert!((px(l1) - w.right_offset).abs() < 1e-6, "{degrees:?}");
                let end = px(r0.max(r1));
                let margin = f64::from(reproject_margin(width));
                assert!(
                    end <= f64::from(w.width) - margin + 1e-6,
                    "{degrees:?} {width}"
                );
                assert!(
                    end > f64::from(w.width) - margin - 1.0,
                    "{degrees:?} {width}"
                );
                assert!((px(r1) - w.right_offset - f64::from(width)).abs() < 1e-6);
                assert_eq!(w.left_offset > 0, degrees[0] > -52.0, "{degrees:?}");
            }
        }
        let mut uneven = eye_fovs(&[-52.0, 43.0, -50.0, 48.0]).unwrap();
        uneven[1].right = 0.9;
        assert!(wide_window(&uneven, (320, 200)).is_err());
    }
}
