//! Framing: every corner of the framed box is inside the camera's frustum, on
//! random boxes far from the origin, random view directions and fields of
//! view, and the box's centre is on the view axis.

use dmu_geom::{Aabb3d, Camera};
use glam::DVec3;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn a_framed_box_is_all_in_view(
        origin in (-1e7..1e7f64, -1e7..1e7f64, -1e4..1e4f64),
        size in (1e-3..1e4f64, 1e-3..1e4f64, 1e-3..1e4f64),
        forward in (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
        fov_deg in 5.0..150.0f64,
        aspect in 1.0..3.0f64,
    ) {
        let min = DVec3::from(origin);
        let bounds = Aabb3d::new(min, min + DVec3::from(size));
        let forward = DVec3::from(forward);
        prop_assume!(forward.length() > 0.1 && forward.normalize().cross(DVec3::Z).length() > 0.05);
        let camera = Camera::framing(&bounds, forward, DVec3::Z, fov_deg.to_radians(), 1e-3);
        prop_assert!(camera.is_valid());
        prop_assert!(((camera.target - camera.eye).normalize() - forward.normalize()).length() < 1e-9);
        let frustum = camera.frustum(aspect);
        let scale = bounds.extent().length() + (camera.eye - camera.target).length();
        for corner in bounds.corners() {
            for plane in &frustum.planes {
                prop_assert!(plane.signed_distance(corner) >= -1e-9 * scale, "{corner} outside");
            }
        }
    }
}
