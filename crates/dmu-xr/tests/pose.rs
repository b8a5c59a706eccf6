//! Eye poses as cameras: against the analytic projection of a point seen by
//! two eyes an IPD apart (its disparity), and the tracking-to-world mapping
//! against its definition.

use dmu_geom::Fov;
use dmu_geom::glam::{DQuat, DVec3};
use dmu_xr::{Placement, Pose, eye_pixel, eye_ray, eye_size};
use proptest::prelude::*;

fn placement(heading_rad: f64) -> Placement {
    Placement {
        origin: DVec3::new(4_512_000.0, 5_342_750.0, 12_000.0),
        heading_rad,
        units_per_metre: 1000.0,
    }
}

/// Where a world point lands in an eye's image, pixels (x right, y down).
fn pixel(placement: &Placement, eye: &Pose, fov: &Fov, size: (u32, u32), p: DVec3) -> (f64, f64) {
    let camera = placement.eye_camera(eye, fov, 10.0);
    eye_pixel(&camera, fov, size, p).expect("in front of the eye")
}

proptest! {
    /// Two eyes `ipd` apart along the head's x, a point straight ahead at
    /// distance `d` metres: the left eye sees it `ipd / d` (in tangent) to
    /// the right of where the right eye does, so its pixel x is larger by
    /// `ipd / d * width / (tan r - tan l)`, and the rows agree.
    #[test]
    fn disparity_is_ipd_over_distance(
        heading in -3.0f64..3.0,
        yaw in -0.5f64..0.5,
        ipd in 0.05f64..0.075,
        d in 0.5f64..50.0,
        off in -0.2f64..0.2,
    ) {
        let placement = placement(heading);
        let orientation = DQuat::from_rotation_y(yaw);
        let head = DVec3::new(0.3, 1.7, -0.4);
        let right_axis = orientation * DVec3::X;
        let eye = |side: f64| Pose { position: head + right_axis * (side * ipd / 2.0), orientation };
        let fov = Fov { left: -0.742, right: 0.70, down: -0.779, up: 0.75 };
        let size = (800, 860);
        // The point: d metres ahead of the head, a little to the side and up.
        let ahead = orientation * DVec3::new(off * d, 0.1 * d, -d);
        let p = placement.point(head + ahead);
        let (lx, ly) = pixel(&placement, &eye(-1.0), &fov, size, p);
        let (rx, ry) = pixel(&placement, &eye(1.0), &fov, size, p);
        let [l, r, _, _] = fov.tangents();
        let expected = ipd / d * f64::from(size.0) / (r - l);
        prop_assert!((lx - rx - expected).abs() < 1e-6, "{} vs {expected}", lx - rx);
        prop_assert!((ly - ry).abs() < 1e-6);
    }
}

/// The mapping's axes: tracking +Y is world +Z, -Z (forward) is world +Y
/// turned by the heading, metres become model units, the origin lands on
/// the placement's.
#[test]
fn tracking_axes_map_to_the_world() {
    let p = placement(std::f64::consts::FRAC_PI_2);
    assert_eq!(p.point(DVec3::ZERO), p.origin);
    let up = p.point(DVec3::Y) - p.origin;
    assert!(up.abs_diff_eq(DVec3::new(0.0, 0.0, 1000.0), 1e-9), "{up}");
    // Heading 90°: forward (+Y at heading 0) turns to -X.
    let forward = p.direction(DVec3::NEG_Z);
    assert!(forward.abs_diff_eq(DVec3::NEG_X, 1e-12), "{forward}");
    let camera = p.eye_camera(&Pose::IDENTITY, &Fov::symmetric(1.0, 1.0), 10.0);
    assert!(camera.up.normalize().abs_diff_eq(DVec3::Z, 1e-12));
    assert!(camera.is_valid());
}

/// Eye sizes keep the recommended aspect and stay within the maximum.
#[test]
fn eye_sizes_keep_the_aspect_within_the_maximum() {
    let max = (4096, 4096);
    assert_eq!(eye_size((1440, 1600), max, 1600), (1440, 1600));
    assert_eq!(eye_size((1440, 1600), max, 800), (720, 800));
    assert_eq!(eye_size((320, 240), max, 640), (640, 480));
    assert_eq!(eye_size((1600, 900), (1000, 1000), 3200), (1000, 563));
    assert_eq!(eye_size((0, 0), max, 400), (400, 400));
}

proptest! {
    /// A ray through an image point comes back to that point.
    #[test]
    fn rays_through_pixels_project_back(x in 0.0f64..640.0, y in 0.0f64..480.0, t in 1.0f64..1e5) {
        let placement = placement(0.4);
        let fov = Fov { left: -0.8, right: 0.6, down: -0.7, up: 0.5 };
        let pose = Pose { position: DVec3::new(0.1, 1.6, 0.2), orientation: DQuat::from_rotation_x(-0.3) };
        let camera = placement.eye_camera(&pose, &fov, 10.0);
        let ray = eye_ray(&camera, &fov, (640, 480), x, y);
        let p = ray.origin + ray.dir * t;
        let (px, py) = eye_pixel(&camera, &fov, (640, 480), p).unwrap();
        prop_assert!((px - x).abs() < 1e-6 && (py - y).abs() < 1e-6, "{px},{py} vs {x},{y}");
    }
}
