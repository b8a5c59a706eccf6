//! Off-centre fields of view (a headset's eyes): an asymmetric view's image is
//! the matching crop of a symmetric view that encloses it, from the same eye
//! on the same pixel grid.

use dmu_geom::Fov;
use dmu_render::{Culling, View};

use crate::culling::{small_plant, viewpoints};
use dmu_testkit::image_path;

use crate::support::{Rig, differing};

/// Tangent extent of one pixel, the same in both views.
const PX: f64 = 0.005;

/// The asymmetric image against the crop of a symmetric render whose pixel
/// grid contains it: a pixel's centre is the same ray in both, so only
/// rounding in the two projections (and so in rasterization at triangle
/// edges) can differ.
#[test]
fn off_centre_view_is_a_crop_of_the_symmetric_one() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        // Tangents chosen on the pixel grid: left -0.5, right 0.3, down -0.4, up 0.2.
        let (l, r, d, u) = (-100i32, 60i32, -80i32, 40i32);
        let fov = Fov {
            left: (f64::from(l) * PX).atan(),
            right: (f64::from(r) * PX).atan(),
            down: (f64::from(d) * PX).atan(),
            up: (f64::from(u) * PX).atan(),
        };
        let size = ((r - l) as u32, (u - d) as u32);
        // The symmetric view: ±0.5 horizontally, ±0.4 vertically.
        let (half_w, half_h) = (l.abs().max(r.abs()), d.abs().max(u.abs()));
        let full = ((2 * half_w) as u32, (2 * half_h) as u32);
        let mut small = Rig::new(gpu, &scene, &tree, size);
        let mut big = Rig::new(gpu, &scene, &tree, full);
        let (mut compared, mut wrong) = (0usize, 0usize);
        for (i, camera) in viewpoints().into_iter().enumerate() {
            let camera = dmu_render::Camera {
                fov_y_rad: 2.0 * (f64::from(half_h) * PX).atan(),
                ..camera
            };
            let mut view = View::new(camera, size, Culling::None);
            view.fov = Some(fov);
            small.frame(&mut view, &scene, &tree);
            let off_centre = small.image();
            let whole = big.shot(camera, Culling::None, &scene, &tree);
            // Column 0 of the crop is tangent l; row 0 is tangent u (y down).
            let (x0, y0) = ((l + half_w) as u32, (half_h - u) as u32);
            let crop = image::imageops::crop_imm(&whole, x0, y0, size.0, size.1).to_image();
            let diff = differing(&off_centre, &crop);
            if i == 0 {
                off_centre
                    .save(image_path("fov-off-centre.png"))
                    .expect("save");
                crop.save(image_path("fov-crop.png")).expect("save");
            }
            compared += (size.0 * size.1) as usize;
            wrong += diff.len();
            // Background pixels alone would pass trivially: the plant is in view.
            let background = *off_centre.get_pixel(0, 0);
            let covered = off_centre.pixels().filter(|p| **p != background).count();
            assert!(
                covered > 1_000,
                "viewpoint {i}: {covered} pixels show the plant"
            );
        }
        eprintln!("{wrong} of {compared} pixels differ from the symmetric crop");
        // Edge pixels may round the other way; anything systematic (a shifted or
        // flipped projection) differs on most covered pixels.
        assert!(
            wrong * 200 < compared,
            "{wrong} of {compared} pixels differ"
        );
    });
}
