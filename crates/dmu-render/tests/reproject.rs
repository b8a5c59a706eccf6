//! The right eye reprojected from the left eye's image by depth
//! ([`dmu_render::Reprojector`]): the shader against a CPU reference of the
//! same scan, and the reprojected eye against the eye drawn.

use dmu_geom::Fov;
use dmu_render::{
    Camera, Capture, Culling, Reprojection, Reprojector, SURFACE_CHANGE, StereoCamera, View,
};
use dmu_scene::Scene;
use dmu_tree::Tree;

use crate::culling::{small_plant, viewpoints};
use dmu_testkit::image_path;

use crate::support::Rig;

/// Each eye's image.
const SIZE: (u32, u32) = (320, 240);
/// Columns the left image reaches beyond the right eye's window.
const MARGIN: u32 = 24;

/// The right eye's image as the shader makes it, scanned on the CPU in the
/// same f32 arithmetic: each row from the left, a pixel landing at
/// `floor(x + 0.5 - d * disparity_at_near - offset)`, later pixels replacing
/// earlier ones, the columns a landing skips past the furthest reached filled
/// with the farther of it and the pixel before. (A driver that fuses the multiply-add may land a pixel sitting on
/// a column boundary one column over; lavapipe, where CI runs, does not.)
fn reproject_cpu(color: &[u8], depth: &[f32], r: &Reprojection) -> Vec<u8> {
    let (sw, _) = r.source_size;
    let (tw, th) = r.target_size;
    let (disparity, offset) = (r.disparity_at_near_px as f32, r.target_offset as f32);
    let mut out = vec![0u32; (tw * th) as usize];
    for y in 0..th as usize {
        let row = &mut out[y * tw as usize..][..tw as usize];
        let fill = |row: &mut [u32], from: i32, to: i32, c: u32| {
            for u in from.max(0)..to.min(tw as i32) {
                row[u as usize] = c;
            }
        };
        let (mut furthest, mut prev_d, mut prev_c) = (-1i32, 0f32, 0u32);
        for x in 0..sw as usize {
            let i = y * sw as usize + x;
            let d = depth[i];
            let c = u32::from_le_bytes(color[i * 4..][..4].try_into().unwrap());
            let landing = (x as f32 + 0.5 - d * disparity - offset).floor();
            let u = landing.clamp(-1.0, tw as f32) as i32;
            if u > furthest + 1 {
                let gap = if x > 0 && prev_d < d { prev_c } else { c };
                fill(row, furthest + 1, u, gap);
            }
            if (0..tw as i32).contains(&u) {
                row[u as usize] = c;
            }
            (furthest, prev_d, prev_c) = (furthest.max(u), d, c);
        }
        fill(row, furthest + 1, tw as i32, prev_c);
    }
    out.iter().flat_map(|c| c.to_le_bytes()).collect()
}

/// A stereo pair from `center` with eyes `ipd` apart: the left eye drawn
/// wide (its window plus `MARGIN` columns), the right eye's window starting
/// `offset` pixels (fractional) into it, both lit from `center`.
struct Pair {
    center: Camera,
    ipd: f64,
    offset: f64,
}

impl Pair {
    fn fx(&self) -> f64 {
        let [l, r, _, _] = self.left_fov().tangents();
        f64::from(SIZE.0) / (r - l)
    }

    fn left_fov(&self) -> Fov {
        Fov::symmetric(self.center.fov_y_rad, f64::from(SIZE.0) / f64::from(SIZE.1))
    }

    /// The left image's field of view: the left eye's, `MARGIN` columns wider.
    fn wide_fov(&self) -> Fov {
        let f = self.left_fov();
        Fov {
            right: (f.right.tan() + f64::from(MARGIN) / self.fx()).atan(),
            ..f
        }
    }

    /// The right eye's: the left eye's moved `offset` pixels right.
    fn right_fov(&self) -> Fov {
        let f = self.left_fov();
        let shift = self.offset / self.fx();
        Fov {
            left: (f.left.tan() + shift).atan(),
            right: (f.right.tan() + shift).atan(),
            ..f
        }
    }

    fn eyes(&self) -> [Camera; 2] {
        StereoCamera {
            center: self.center,
            ipd: self.ipd,
        }
        .eyes()
    }

    fn view(&self, camera: Camera, fov: Fov, size: (u32, u32)) -> View {
        let mut v = View::new(camera, size, Culling::Frustum);
        v.fov = Some(fov);
        v.light = Some(self.center.eye);
        v
    }

    fn reprojection(&self) -> Reprojection {
        Reprojection {
            source_size: (SIZE.0 + MARGIN, SIZE.1),
            target_size: SIZE,
            target_offset: self.offset,
            disparity_at_near_px: self.ipd * self.fx() / self.center.near,
        }
    }
}

/// What one pair gives: the left eye's wide image, the right eye
/// reprojected on the GPU from it, as the CPU reference makes it, drawn, and
/// the gaps.
struct Right {
    wide: image::RgbaImage,
    reprojected: image::RgbaImage,
    reference: Vec<u8>,
    drawn: image::RgbaImage,
    gaps: u64,
}

fn right_eye(rig: &mut Rig, pair: &Pair, scene: &Scene, tree: &Tree) -> Right {
    let [left, right] = pair.eyes();
    let r = pair.reprojection();
    let (device, queue) = (&rig.device, &rig.queue);
    let wide = Capture::new(device, r.source_size);
    let mut wide_view = pair.view(left, pair.wide_fov(), r.source_size);
    rig.renderer
        .render(&mut wide_view, scene, tree, scene, wide.frame_target())
        .expect("render");
    let out = Capture::stereo(device, SIZE);
    let reprojector = Reprojector::new(device, queue, r);
    let mut encoder = device.create_command_encoder(&Default::default());
    reprojector.encode(device, &mut encoder, &wide, &out, 1);
    queue.submit([encoder.finish()]);
    let reprojected = out.read_color_layer(device, queue, 1).expect("read");
    let gaps = reprojector.read_gaps(device, queue).expect("gaps");
    let color = wide.read_color(device, queue).expect("read");
    let depth = wide.read_depth(device, queue).expect("read depth");
    let reference = reproject_cpu(color.as_raw(), &depth, &r);
    let mut right_view = pair.view(right, pair.right_fov(), SIZE);
    rig.frame(&mut right_view, scene, tree);
    Right {
        wide: color,
        reprojected,
        reference,
        drawn: rig.image(),
        gaps,
    }
}

/// Pixels of `a` differing from `b` shifted `shift` columns, by more than
/// `levels` in a channel (the `|shift|` columns at each side left out).
fn over(a: &image::RgbaImage, b: &image::RgbaImage, shift: i32, levels: u8) -> usize {
    let (w, h) = a.dimensions();
    let edge = shift.unsigned_abs();
    (0..h)
        .flat_map(|y| (edge..w - edge).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let p = a.get_pixel(x, y);
            let q = b.get_pixel(x.wrapping_add_signed(shift), y);
            p.0.iter().zip(q.0).any(|(s, t)| s.abs_diff(t) > levels)
        })
        .count()
}

/// The shader does what its CPU reference does, pixel for pixel, at
/// viewpoints with near structure (gaps to fill) and a fractional window
/// offset; and the reprojected eye is the drawn one but along near
/// silhouettes and where the half-pixel landing resamples thin detail:
/// shifting it a column either way matches worse (the disparity is placed
/// right), and a pair without eye separation gets the left image's window.
#[test]
fn the_reprojected_eye_matches_its_reference_and_the_drawn_eye() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let mut rig = Rig::new(gpu, &scene, &tree, SIZE);
        let pixels = (SIZE.0 * SIZE.1) as usize;
        for (i, center) in viewpoints().into_iter().enumerate().take(3) {
            for (ipd, offset) in [(65.0, 0.37), (65.0, 3.0), (0.0, 0.0)] {
                let pair = Pair {
                    center,
                    ipd,
                    offset,
                };
                let right = right_eye(&mut rig, &pair, &scene, &tree);
                let mismatched = right
                    .reprojected
                    .as_raw()
                    .chunks(4)
                    .zip(right.reference.chunks(4))
                    .filter(|(a, b)| a != b)
                    .count();
                assert_eq!(
                    mismatched, 0,
                    "viewpoint {i}, ipd {ipd}, offset {offset}: pixels unlike the CPU reference"
                );
                if i == 0 && offset == 0.37 {
                    right
                        .reprojected
                        .save(image_path("reprojected-right.png"))
                        .expect("save");
                    right
                        .drawn
                        .save(image_path("drawn-right.png"))
                        .expect("save");
                }
                let wrong = |shift| over(&right.reprojected, &right.drawn, shift, SURFACE_CHANGE);
                let (at, left, right_shift) = (wrong(0), wrong(-1), wrong(1));
                eprintln!(
                    "viewpoint {i}, ipd {ipd}, offset {offset}: {} gaps, {at} pixels another surface ({left} and {right_shift} a column off)",
                    right.gaps
                );
                if ipd == 0.0 {
                    assert_eq!(right.gaps, 0, "viewpoint {i}: nothing moves");
                    let window = image::imageops::crop_imm(&right.wide, 0, 0, SIZE.0, SIZE.1);
                    assert!(
                        window.to_image() == right.reprojected,
                        "viewpoint {i}: the left image's window, unmoved"
                    );
                    // The drawn eye differs only where another projection of
                    // the same rays rasterizes an edge the other way.
                    assert!(at <= pixels / 10_000, "viewpoint {i}: {at}");
                    continue;
                }
                assert!(right.gaps > 0, "viewpoint {i}: near structure leaves gaps");
                assert!(
                    at * 10 < pixels && at * 2 < left.min(right_shift),
                    "viewpoint {i}, offset {offset}: {at} pixels another surface, {left} and {right_shift} a column off"
                );
            }
        }
    });
}

/// A lamp placed at the eye ([`View::light`]) is the headlight the view has
/// without one (up to a level of rounding); one placed elsewhere lights the
/// view differently.
#[test]
fn a_lamp_at_the_eye_is_the_headlight() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let mut rig = Rig::new(gpu, &scene, &tree, SIZE);
        let camera = viewpoints()[0];
        let mut shot = |light| {
            let mut view = View::new(camera, SIZE, Culling::Frustum);
            view.light = light;
            rig.frame(&mut view, &scene, &tree);
            rig.image()
        };
        let headlight = shot(None);
        let at_eye = shot(Some(camera.eye));
        let above = shot(Some(camera.eye + dmu_geom::glam::DVec3::Z * 5_000.0));
        let pixels = (SIZE.0 * SIZE.1) as usize;
        assert_eq!(over(&at_eye, &headlight, 0, 1), 0);
        let moved = over(&above, &headlight, 0, 8);
        assert!(
            moved * 10 > pixels,
            "{moved} of {pixels} pixels lit differently"
        );
    });
}
