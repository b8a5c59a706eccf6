//! Off-centre fields of view against their definition: a view-space direction
//! along each side lands on that side of clip space, and a symmetric one is
//! exactly the camera's own projection.

use dmu_geom::glam::{DVec3, DVec4};
use dmu_geom::{Camera, Fov};
use proptest::prelude::*;

fn fov_strategy() -> impl Strategy<Value = Fov> {
    // Each side between 5° and 75° from the axis, either sign, sides ordered.
    (-1.3f64..0.9, 0.1f64..1.2, -1.3f64..0.9, 0.1f64..1.2).prop_map(
        |(left, width, down, height)| Fov {
            left,
            right: (left + width).min(1.4),
            down,
            up: (down + height).min(1.4),
        },
    )
}

proptest! {
    /// A direction `(tan a, tan b, -1)` at any depth maps to the NDC the
    /// angles give: ±1 on the sides, linear in tangent between them, and
    /// depth `near / distance` (reverse-Z, infinite far plane).
    #[test]
    fn directions_land_where_their_angles_say(fov in fov_strategy(), s in 0.0f64..1.0, t in 0.0f64..1.0, depth in 0.01f64..1e6, near in 1e-3f64..10.0) {
        let p = fov.projection(near);
        let [l, r, d, u] = fov.tangents();
        let (tx, ty) = (l + s * (r - l), d + t * (u - d));
        let clip = p * DVec4::new(tx * depth, ty * depth, -depth, 1.0);
        let ndc = clip.truncate() / clip.w;
        prop_assert!((ndc.x - (2.0 * s - 1.0)).abs() < 1e-9, "{ndc}");
        prop_assert!((ndc.y - (2.0 * t - 1.0)).abs() < 1e-9, "{ndc}");
        prop_assert!((ndc.z - near / depth).abs() < 1e-9 * (1.0 + near / depth), "{ndc}");
    }
}

/// A symmetric field of view gives the camera's own projection, frustum and
/// coverage.
#[test]
fn symmetric_is_the_cameras_projection() {
    let camera = Camera {
        eye: DVec3::new(1e6, -2e6, 300.0),
        target: DVec3::new(1e6 + 10.0, -2e6 + 3.0, 290.0),
        up: DVec3::Z,
        fov_y_rad: 0.9,
        near: 0.25,
    };
    let aspect = 1.6;
    let fov = Fov::symmetric(camera.fov_y_rad, aspect);
    assert!((fov.aspect() - aspect).abs() < 1e-12);
    let (a, b) = (fov.projection(camera.near), camera.projection(aspect));
    assert!(a.abs_diff_eq(b, 1e-12), "{a} vs {b}");
    assert_eq!(
        fov.coverage(&camera, 720).focal_px,
        camera.coverage(720).focal_px
    );
    let (fa, fb) = (fov.frustum(&camera, None), camera.frustum(aspect));
    for (pa, pb) in fa.planes.iter().zip(&fb.planes) {
        assert!(pa.normal.abs_diff_eq(pb.normal, 1e-9), "{pa:?} vs {pb:?}");
    }
    assert!(fov.is_valid());
    assert!(
        !Fov {
            up: f64::NAN,
            ..fov
        }
        .is_valid()
    );
    assert!(
        !Fov {
            right: fov.left,
            ..fov
        }
        .is_valid()
    );
}

/// With a far plane: the symmetric case is `reverse_z_perspective`'s finite
/// projection, and the far plane's depth is 0.
#[test]
fn far_planes_map_to_depth_zero() {
    let fov = Fov::symmetric(1.1, 1.25);
    let (near, far) = (0.5, 800.0);
    let a = fov.projection_to(near, Some(far));
    let b = dmu_geom::reverse_z_perspective(1.1, 1.25, near, Some(far));
    assert!(a.abs_diff_eq(b, 1e-12), "{a} vs {b}");
    let off = Fov {
        left: -0.9,
        right: 0.3,
        down: -0.5,
        up: 0.7,
    };
    let p = off.projection_to(near, Some(far));
    for (z, depth) in [
        (near, 1.0),
        (far, 0.0),
        (2.0 * near * far / (near + far), 0.5),
    ] {
        let clip = p * DVec4::new(0.1 * z, -0.2 * z, -z, 1.0);
        assert!(
            (clip.z / clip.w - depth).abs() < 1e-12,
            "z {z}: {}",
            clip.z / clip.w
        );
    }
}

/// The near plane's farthest corner, against the corners themselves.
#[test]
fn near_reach_is_the_farthest_corner() {
    let fov = Fov {
        left: -0.742,
        right: 0.6,
        down: -0.779,
        up: 0.7,
    };
    let near = 0.05;
    let [l, r, d, u] = fov.tangents();
    let corners = [(l, d), (l, u), (r, d), (r, u)];
    let farthest = corners
        .iter()
        .map(|&(x, y)| DVec3::new(x * near, y * near, -near).length())
        .fold(0.0, f64::max);
    assert!((fov.near_reach(near) - farthest).abs() < 1e-15);
}
