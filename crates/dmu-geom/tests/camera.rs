//! Framing: every corner of the framed box is inside the camera's frustum, on
//! random boxes far from the origin, random view directions and fields of
//! view, and the box's centre is on the view axis. Extrapolation: a camera
//! moving and turning steadily is predicted where it goes.

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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// A camera walking a straight line at 1e6-1e7 from the origin while it
    /// turns about the vertical at a steady rate: `steps` steps on, the
    /// extrapolation is where the walk itself puts it (the analytic pose),
    /// within 1e-9 of the distance covered.
    #[test]
    fn a_steady_walk_and_turn_is_extrapolated_exactly(
        origin in (1e6..1e7f64, 1e6..1e7f64, -1e4..1e4f64),
        stride in (-2e3..2e3f64, -2e3..2e3f64, -50.0..50.0f64),
        heading in 0.0..std::f64::consts::TAU,
        turn_deg in -5.0..5.0f64,
        steps in 0.0..12.0f64,
    ) {
        let pose = |k: f64| {
            let eye = DVec3::from(origin) + DVec3::from(stride) * k;
            let h = heading + turn_deg.to_radians() * k;
            Camera {
                eye,
                target: eye + DVec3::new(h.cos(), h.sin(), -0.1) * 50.0,
                up: DVec3::Z,
                fov_y_rad: 1.0,
                near: 0.1,
            }
        };
        prop_assume!((turn_deg * steps).abs() < 89.0);
        let got = pose(1.0).extrapolated(&pose(0.0), steps);
        let want = pose(1.0 + steps);
        let scale = 1.0 + DVec3::from(stride).length() * steps;
        prop_assert!((got.eye - want.eye).length() < 1e-9 * scale, "{} vs {}", got.eye, want.eye);
        let (g, w) = ((got.target - got.eye).normalize(), (want.target - want.eye).normalize());
        prop_assert!((g - w).length() < 1e-9, "{g} vs {w}");
        prop_assert_eq!((got.up, got.fov_y_rad, got.near), (want.up, want.fov_y_rad, want.near));
    }
}

/// A turn is extrapolated at most a quarter turn on, a tilt up to 89 degrees
/// over the horizon; a camera standing still stays; nonsense steps keep the
/// camera.
#[test]
fn extrapolation_is_bounded() {
    let at = |eye: DVec3, forward: DVec3| Camera {
        eye,
        target: eye + forward,
        up: DVec3::Z,
        fov_y_rad: 1.0,
        near: 0.1,
    };
    let still = at(DVec3::new(5e8, 5e8, 0.0), DVec3::X);
    assert_eq!(still.extrapolated(&still, 10.0), still);
    let before = at(DVec3::ZERO, DVec3::X);
    let now = at(DVec3::ZERO, DVec3::new(1.0, 1.0, 0.0));
    // 45 degrees a step, 10 steps: capped at 90 degrees on.
    let far = now.extrapolated(&before, 10.0);
    let f = (far.target - far.eye).normalize();
    assert!(
        (f - DVec3::new(-1.0, 1.0, 0.0).normalize()).length() < 1e-12,
        "{f}"
    );
    for steps in [f64::NAN, f64::INFINITY, -1.0] {
        assert_eq!(now.extrapolated(&before, steps), now);
    }
    // Tilting up 30 degrees a step: 2 steps would look straight up (along
    // `up`, not a camera); it stops 1 degree short.
    let level = at(DVec3::ZERO, DVec3::X);
    let tilted = at(DVec3::ZERO, DVec3::new(3f64.sqrt(), 0.0, 1.0));
    let up = tilted.extrapolated(&level, 2.0);
    assert!(up.is_valid());
    let f = (up.target - up.eye).normalize();
    assert!((f.z.asin().to_degrees() - 89.0).abs() < 1e-9, "{f}");
    assert!(f.y.abs() < 1e-12 && f.x > 0.0, "{f}");
}
