//! `dmu render --stereo --shared-far-px E`: a stereo pair with headset-like
//! asymmetric eye fields of view whose far part is drawn once and shared.
//!
//! Beyond the depth `D` where the eyes' disparity is below `E` pixels the two
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
//! eye's is aligned), which the split distance leaves room for. The same pair
//! drawn in full ("true stereo") and one eye alone are timed beside it, and
//! the images compared.

use std::time::Instant;

use anyhow::Context as _;
use dmu_geom::Fov;
use dmu_render::{Camera, Capture, Culling, CullingOptions, Renderer, StereoCamera, View, wgpu};
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
    /// Disparity error allowed in the shared far part, pixels.
    pub error_px: f64,
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

/// The shared image's window for eyes with `fovs` and images `size`, sharing
/// what an error of `error_px` allows; `None` when the right eye's window's
/// offset from the grid alone exceeds it.
pub fn shared_window(fovs: &[Fov; 2], size: (u32, u32), error_px: f64) -> Option<SharedWindow> {
    let [l0, r0, _, _] = fovs[0].tangents();
    let [l1, _, _, _] = fovs[1].tangents();
    let fx = f64::from(size.0) / (r0 - l0);
    let first = l0.min(l1);
    // The grid starts a whole number of pixels left of the left eye's window.
    let left_offset = ((l0 - first) * fx).ceil();
    let start = l0 - left_offset / fx;
    let right_offset = (l1 - start) * fx;
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
    let offsets = [left_offset as u32, column as u32];
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

/// Median of the second half of `times` (the first frames warm caches up).
fn steady(times: &[f64]) -> f64 {
    let mut tail = times[times.len() / 2..].to_vec();
    tail.sort_by(f64::total_cmp);
    tail[tail.len() / 2]
}

/// Times `frames` calls of `frame`, each waited for on the GPU.
fn timed(
    device: &wgpu::Device,
    frames: u32,
    mut frame: impl FnMut() -> anyhow::Result<()>,
) -> anyhow::Result<Vec<f64>> {
    (0..frames.max(1))
        .map(|_| {
            let start = Instant::now();
            frame()?;
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .context("waiting for the GPU")?;
            Ok(start.elapsed().as_secs_f64() * 1e3)
        })
        .collect()
}

/// Draws the pair with the shared far part, in full, and one eye alone;
/// saves the shared pair's eyes to `outputs`; the report.
pub fn compare(
    renderer: &mut Renderer,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    s: &Setup<'_>,
    outputs: &[std::path::PathBuf; 2],
) -> anyhow::Result<Value> {
    let window = shared_window(&s.fovs, s.size, s.error_px).with_context(|| {
        format!(
            "--shared-far-px {}: the eyes' windows lie too far off one pixel grid at this size; allow more",
            s.error_px
        )
    })?;
    // Beyond this depth the eyes' disparity is below what may be shared.
    let split = s.ipd * window.fx / window.max_shared_disparity_px;
    let eyes = StereoCamera {
        center: s.center,
        ipd: s.ipd,
    }
    .eyes();
    let view = |camera: Camera, fov: Fov, size| {
        let mut v = View::new(camera, size, s.culling);
        v.options = s.options;
        v.fov = Some(fov);
        v
    };
    let mut far_view = view(
        Camera {
            near: split.max(s.center.near),
            ..s.center
        },
        window.fov,
        (window.width, s.size.1),
    );
    let mut near_views = [0, 1].map(|e| {
        let mut v = view(eyes[e], s.fovs[e], s.size);
        v.far = Some(split);
        v.keep_color = true;
        v
    });
    let mut full_views = [0, 1].map(|e| view(eyes[e], s.fovs[e], s.size));
    let mut one_eye = view(eyes[0], s.fovs[0], s.size);
    let far_capture = Capture::new(device, (window.width, s.size.1));
    let shared = Capture::stereo(device, s.size);
    let full = Capture::stereo(device, s.size);
    let single = Capture::new(device, s.size);
    let (scene, tree) = (s.scene, s.tree);
    let mut far_triangles = 0;
    let mut near_triangles = 0;
    // Per frame: the far pass's time, the near passes' (both eyes); the last
    // frame's draw calls of each.
    let mut parts: Vec<[f64; 2]> = Vec::new();
    let mut calls = [0u64; 2];
    let shared_ms = timed(device, s.frames, || {
        let far = renderer.render(
            &mut far_view,
            scene,
            tree,
            scene,
            far_capture.frame_target(),
        )?;
        far_triangles = far.triangles_drawn;
        let mut part = [far.cpu_ms, 0.0];
        calls = [far.draw_calls, 0];
        let mut encoder = device.create_command_encoder(&Default::default());
        for (e, &offset) in window.offsets.iter().enumerate() {
            encoder.copy_texture_to_texture(
                wgpu::TexelCopyTextureInfo {
                    origin: wgpu::Origin3d {
                        x: offset,
                        y: 0,
                        z: 0,
                    },
                    ..far_capture.color_texture().as_image_copy()
                },
                wgpu::TexelCopyTextureInfo {
                    origin: wgpu::Origin3d {
                        x: 0,
                        y: 0,
                        z: e as u32,
                    },
                    ..shared.color_texture().as_image_copy()
                },
                wgpu::Extent3d {
                    width: s.size.0,
                    height: s.size.1,
                    depth_or_array_layers: 1,
                },
            );
        }
        queue.submit([encoder.finish()]);
        let target = shared.stereo_target();
        near_triangles = 0;
        for (e, v) in near_views.iter_mut().enumerate() {
            let near = renderer.render(v, scene, tree, scene, target.eyes[e])?;
            near_triangles += near.triangles_drawn;
            part[1] += near.cpu_ms;
            calls[1] += near.draw_calls;
        }
        parts.push(part);
        Ok(())
    })?;
    let mut full_triangles = 0;
    let full_ms = timed(device, s.frames, || {
        let target = full.stereo_target();
        full_triangles = 0;
        for (e, v) in full_views.iter_mut().enumerate() {
            full_triangles += renderer
                .render(v, scene, tree, scene, target.eyes[e])?
                .triangles_drawn;
        }
        Ok(())
    })?;
    let mut one_draws = 0;
    let one_ms = timed(device, s.frames, || {
        one_draws = renderer
            .render(&mut one_eye, scene, tree, scene, single.frame_target())?
            .draw_calls;
        Ok(())
    })?;
    let mut differing = [0usize; 2];
    let mut over_8 = [0usize; 2];
    for e in 0..2 {
        let a = shared.read_color_layer(device, queue, e as u32)?;
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
    let pixels = f64::from(s.size.0) * f64::from(s.size.1);
    let (shared_med, full_med, one_med) = (steady(&shared_ms), steady(&full_ms), steady(&one_ms));
    Ok(json!({
        "eye_fov_deg": s.fovs.map(|f| [f.left, f.right, f.down, f.up].map(f64::to_degrees)),
        "error_px": s.error_px,
        "split_depth": split,
        "pixels_per_tangent": window.fx,
        "shared_width": window.width,
        "eye_offsets": window.offsets,
        "shared_disparity_px": window.shared_disparity_px,
        "disparity_error_bound_px": window.error_bound_px(),
        "frame_ms": shared_med,
        "true_stereo_frame_ms": full_med,
        "one_eye_frame_ms": one_med,
        "ratio": shared_med / one_med,
        "true_stereo_ratio": full_med / one_med,
        "triangles": { "far": far_triangles, "near_both_eyes": near_triangles, "true_stereo": full_triangles },
        // Where the shared pair's time goes, each a median of its own (the
        // copy of the far image into the eyes is waited for by the first near
        // pass, so it is in the near passes' time), and the draw calls of each.
        "far_pass_ms": steady(&parts.iter().map(|p| p[0]).collect::<Vec<_>>()),
        "near_passes_ms": steady(&parts.iter().map(|p| p[1]).collect::<Vec<_>>()),
        "draw_calls": { "far": calls[0], "near_both_eyes": calls[1], "one_eye": one_draws },
        "image_difference": {
            "pixels_differing": differing,
            "fraction_differing": differing.map(|d| d as f64 / pixels),
            "pixels_over_8_levels": over_8,
        },
        "outputs": outputs,
    }))
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
}
