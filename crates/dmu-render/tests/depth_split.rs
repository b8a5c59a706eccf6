//! Drawing a view's depth range in two parts: the far part (near plane at
//! the split) then the near part over it (far plane at the split, colour
//! kept) gives the view drawn whole.

use dmu_render::{Culling, View};

use crate::culling::{small_plant, viewpoints};
use dmu_testkit::image_path;

use crate::support::{Rig, differing};

#[test]
fn near_over_far_equals_the_whole_view() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (320, 180);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        let (mut compared, mut wrong, mut near_pixels) = (0usize, 0usize, 0usize);
        for (i, camera) in viewpoints().into_iter().enumerate() {
            let whole = rig.shot(camera, Culling::Frustum, &scene, &tree);
            for split in [5_000.0, 20_000.0] {
                let mut far = View::new(
                    dmu_render::Camera {
                        near: split,
                        ..camera
                    },
                    size,
                    Culling::Frustum,
                );
                rig.frame(&mut far, &scene, &tree);
                let far_drawn = far.last_stats().triangles_drawn;
                let far_only = rig.image();
                let mut near = View::new(camera, size, Culling::Frustum);
                near.far = Some(split);
                near.keep_color = true;
                rig.frame(&mut near, &scene, &tree);
                let near_drawn = near.last_stats().triangles_drawn;
                let composed = rig.image();
                // The near part is culled by its far plane; the far part keeps
                // every chunk that reaches past the split (long pipes do).
                let mut all = View::new(camera, size, Culling::Frustum);
                rig.frame(&mut all, &scene, &tree);
                let all_drawn = all.last_stats().triangles_drawn;
                assert!(
                    near_drawn < all_drawn && far_drawn <= all_drawn,
                    "viewpoint {i}, split {split}: far {far_drawn}, near {near_drawn}, all {all_drawn}"
                );
                if i == 0 && split == 5_000.0 {
                    far_only.save(image_path("split-far.png")).expect("save");
                    composed
                        .save(image_path("split-composed.png"))
                        .expect("save");
                }
                let diff = differing(&whole, &composed);
                compared += (size.0 * size.1) as usize;
                wrong += diff.len();
                near_pixels += differing(&whole, &far_only).len();
            }
        }
        eprintln!(
            "{wrong} of {compared} pixels differ from the whole view; the near parts cover {near_pixels}"
        );
        // The splits cut something: the far parts alone are not the whole.
        assert!(near_pixels > 2_000, "{near_pixels} pixels of near parts");
        // Only pixels where a triangle crosses the split plane can round apart.
        assert!(
            wrong * 500 < compared,
            "{wrong} of {compared} pixels differ"
        );
    });
}
