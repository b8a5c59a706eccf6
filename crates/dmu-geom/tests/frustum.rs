//! Frustum culling against clip space: a point is inside when its clip coordinates
//! satisfy `|x| <= w`, `|y| <= w` and `0 <= z <= w` (reverse-Z), computed with the
//! view-projection matrix directly, without planes.

use dmu_geom::glam::{DMat4, DVec3, DVec4};
use dmu_geom::{Aabb3d, Containment, Frustum, Plane, look_at, reverse_z_perspective};
use proptest::prelude::*;

/// A random camera; the far plane is infinite for `far = None`.
#[derive(Clone, Debug)]
struct Camera {
    eye: DVec3,
    forward: DVec3,
    fov_y_rad: f64,
    aspect: f64,
    near: f64,
    far: Option<f64>,
}

impl Camera {
    fn view(&self) -> DMat4 {
        let up = if self.forward.cross(DVec3::Z).length() > 0.1 * self.forward.length() {
            DVec3::Z
        } else {
            DVec3::Y
        };
        look_at(self.eye, self.eye + self.forward, up)
    }

    fn view_proj(&self) -> DMat4 {
        reverse_z_perspective(self.fov_y_rad, self.aspect, self.near, self.far) * self.view()
    }

    /// A world point from view-space depth `-z_view = depth` and NDC-like `x`, `y`
    /// (`|x|, |y| <= 1` on screen).
    fn point(&self, ndc_x: f64, ndc_y: f64, depth: f64) -> DVec3 {
        let half_height = (0.5 * self.fov_y_rad).tan() * depth;
        let view_point = DVec3::new(
            ndc_x * half_height * self.aspect,
            ndc_y * half_height,
            -depth,
        );
        self.view().inverse().transform_point3(view_point)
    }

    /// How far the cloud of test points reaches.
    fn reach(&self) -> f64 {
        self.far.unwrap_or(self.near * 1e4) * 1.3
    }
}

fn camera() -> impl Strategy<Value = Camera> {
    let offset = prop_oneof![Just(0.0), Just(1e7)];
    (
        [-100.0..100.0, -100.0..100.0, -100.0..100.0],
        offset,
        [-1.0..1.0, -1.0..1.0, -1.0..1.0f64],
        0.2..2.0f64,
        0.5..3.0f64,
        0.05..2.0f64,
        prop_oneof![Just(None), (2.0..1e4f64).prop_map(Some)],
    )
        .prop_filter_map(
            "forward must not be zero",
            |(eye, offset, forward, fov_y_rad, aspect, near, far)| {
                let forward = DVec3::from_array(forward).try_normalize()?;
                Some(Camera {
                    eye: DVec3::from_array(eye) + offset,
                    forward,
                    fov_y_rad,
                    aspect,
                    near,
                    far: far.map(|f| near * f),
                })
            },
        )
}

/// The six clip inequalities, each `>= 0` inside: `w + x`, `w - x`, `w + y`, `w - y`,
/// `w - z`, `z`, and a rounding margin for them.
fn clip_margins(view_proj: &DMat4, p: DVec3) -> ([f64; 6], f64) {
    let DVec4 { x, y, z, w } = *view_proj * p.extend(1.0);
    (
        [w + x, w - x, w + y, w - y, w - z, z],
        1e-9 * (x.abs() + y.abs() + z.abs() + w.abs()),
    )
}

/// A point generator: mostly near the view volume, some behind the camera.
fn sample() -> impl Strategy<Value = (f64, f64, f64)> {
    (-1.5..1.5f64, -1.5..1.5f64, -0.1..1.0f64)
}

proptest! {
    #[test]
    fn points_are_inside_iff_clip_coordinates_are(cam in camera(), samples in prop::collection::vec(sample(), 64)) {
        let view_proj = cam.view_proj();
        let frustum = Frustum::from_view_proj_reverse_z(&view_proj);
        let (mut inside, mut outside) = (0, 0);
        for (x, y, depth) in samples {
            // Depths spread log-uniformly so both the near and the far plane are probed.
            let depth = if depth < 0.0 { depth * cam.reach() } else { cam.near * 0.5 * (cam.reach() / (cam.near * 0.5)).powf(depth) };
            let p = cam.point(x, y, depth);
            let (clip, margin) = clip_margins(&view_proj, p);
            if clip.iter().all(|&c| c > margin) {
                prop_assert!(frustum.contains_point(p), "{p} clip {clip:?}");
                inside += 1;
            } else if clip.iter().any(|&c| c < -margin) {
                prop_assert!(!frustum.contains_point(p), "{p} clip {clip:?}");
                outside += 1;
            }
        }
        // The samples probe both sides, or the test says nothing.
        prop_assert!(inside > 0 && outside > 0);
    }

    #[test]
    fn boxes_are_classified_conservatively(
        cam in camera(),
        boxes in prop::collection::vec((sample(), [0.0..0.25f64, 0.0..0.25, 0.0..0.25]), 64),
    ) {
        let view_proj = cam.view_proj();
        let frustum = Frustum::from_view_proj_reverse_z(&view_proj);
        let mut seen = [0; 3];
        for ((x, y, depth), half) in boxes {
            let depth = if depth < 0.0 { depth * cam.reach() } else { cam.near + depth * cam.reach() };
            let center = cam.point(x, y, depth);
            // Sizes relative to the screen at that distance, some flat, all
            // axis-aligned in the world.
            let screen = (0.5 * cam.fov_y_rad).tan() * depth.abs().max(cam.near);
            let half = DVec3::from_array(half.map(|h| if h < 0.05 { 0.0 } else { h })) * screen;
            let aabb = Aabb3d::new(center - half, center + half);
            let corners = aabb.corners().map(|c| clip_margins(&view_proj, c));
            let result = frustum.test_aabb(&aabb);
            seen[result as usize] += 1;
            prop_assert_eq!(frustum.intersects_aabb(&aabb), result != Containment::Outside);

            let clearly_inside = |(clip, margin): &([f64; 6], f64)| clip.iter().all(|&c| c > *margin);
            let outside_plane = |k: usize, strictly: bool| corners.iter().all(|(clip, margin)| {
                if strictly { clip[k] < -margin } else { clip[k] <= *margin }
            });
            match result {
                // All eight corners outside one common plane.
                Containment::Outside => prop_assert!((0..6).any(|k| outside_plane(k, false)), "{aabb:?}"),
                Containment::Inside => prop_assert!(corners.iter().all(|(clip, margin)| clip.iter().all(|&c| c >= -margin))),
                Containment::Intersecting => {}
            }
            if corners.iter().any(clearly_inside) {
                prop_assert_ne!(result, Containment::Outside);
            }
            if corners.iter().all(clearly_inside) {
                prop_assert_eq!(result, Containment::Inside);
            }
            // The p-vertex test is exact for a single plane.
            if (0..6).any(|k| outside_plane(k, true)) {
                prop_assert_eq!(result, Containment::Outside);
            }
        }
        // Every outcome occurs, or the checks above say little.
        prop_assert!(seen.iter().all(|&n| n > 0), "{seen:?}");
    }
}

#[test]
fn reverse_z_maps_near_to_one_and_far_to_zero() {
    let depth = |proj: &DMat4, distance: f64| {
        let clip = *proj * DVec4::new(0.3, -0.2, -distance, 1.0);
        clip.z / clip.w
    };
    let finite = reverse_z_perspective(1.2, 1.5, 0.1, Some(1000.0));
    assert!((depth(&finite, 0.1) - 1.0).abs() < 1e-12);
    assert!(depth(&finite, 1000.0).abs() < 1e-12);
    // Reverse-Z with depth = near / distance at infinity, minus the finite far's share.
    let expected = |d: f64| 0.1 * (1000.0 - d) / (d * (1000.0 - 0.1));
    assert!((depth(&finite, 7.0) - expected(7.0)).abs() < 1e-12);
    let infinite = reverse_z_perspective(1.2, 1.5, 0.1, None);
    assert!((depth(&infinite, 0.1) - 1.0).abs() < 1e-12);
    assert!((depth(&infinite, 1e9) - 1e-10).abs() < 1e-20);
    // Right-handed, y up: a point up and to the right lands in the top right.
    let clip = infinite * DVec4::new(1.0, 1.0, -5.0, 1.0);
    assert!(clip.x > 0.0 && clip.y > 0.0 && clip.w == 5.0);
}

#[test]
fn look_at_puts_target_on_negative_z() {
    let eye = DVec3::new(1e7, 2.0, 3.0);
    let view = look_at(eye, eye + DVec3::new(0.0, 10.0, 0.0), DVec3::Z * 7.0);
    assert!(view.transform_point3(eye).length() < 1e-9);
    assert!(
        (view.transform_point3(eye + DVec3::new(0.0, 10.0, 0.0)) - DVec3::new(0.0, 0.0, -10.0))
            .length()
            < 1e-9
    );
    // Up stays up, and right-handed means +x to the right when looking along +y world.
    assert!((view.transform_vector3(DVec3::Z) - DVec3::Y).length() < 1e-12);
    assert!((view.transform_vector3(DVec3::X) - DVec3::X).length() < 1e-12);
}

#[test]
fn infinite_far_plane_accepts_any_depth() {
    let eye = DVec3::new(5.0, -3.0, 1e7);
    let view_proj =
        reverse_z_perspective(1.0, 1.0, 0.5, None) * look_at(eye, eye - DVec3::Z, DVec3::Y);
    let frustum = Frustum::from_view_proj_reverse_z(&view_proj);
    assert_eq!(frustum.planes[5], Plane::ACCEPT_ALL);
    assert!(frustum.contains_point(eye - DVec3::Z * 1e12));
    assert!(frustum.contains_point(eye - DVec3::Z * 0.5));
    assert!(!frustum.contains_point(eye - DVec3::Z * 0.49));
    assert!(!frustum.contains_point(eye + DVec3::Z));
    let far_box = Aabb3d::new(
        eye - DVec3::new(1.0, 1.0, 1e9 + 1.0),
        eye - DVec3::new(-1.0, -1.0, 1e9),
    );
    assert_eq!(frustum.test_aabb(&far_box), Containment::Inside);
    // Beside the camera, at any depth: outside the left plane.
    let beside = Aabb3d::new(
        eye + DVec3::new(-1e9, -1.0, -1e6),
        eye + DVec3::new(-1e8, 1.0, -1.0),
    );
    assert_eq!(frustum.test_aabb(&beside), Containment::Outside);
    // Around the eye: crosses the near plane.
    assert_eq!(
        frustum.test_aabb(&Aabb3d::new(eye - 1.0, eye + 1.0)),
        Containment::Intersecting
    );
    assert_eq!(frustum.test_aabb(&Aabb3d::EMPTY), Containment::Outside);
    assert!(!frustum.intersects_aabb(&Aabb3d::EMPTY));
}

#[test]
fn finite_far_plane_culls_beyond_far() {
    let view_proj = reverse_z_perspective(1.0, 1.0, 0.5, Some(100.0))
        * look_at(DVec3::ZERO, -DVec3::Z, DVec3::Y);
    let frustum = Frustum::from_view_proj_reverse_z(&view_proj);
    assert!((frustum.planes[5].signed_distance(DVec3::new(0.0, 0.0, -100.0))).abs() < 1e-9);
    assert!(frustum.planes[5].normal.dot(DVec3::Z) > 0.999);
    assert!(frustum.contains_point(DVec3::new(0.0, 0.0, -99.9)));
    assert!(!frustum.contains_point(DVec3::new(0.0, 0.0, -100.1)));
    for plane in &frustum.planes {
        assert!((plane.normal.length() - 1.0).abs() < 1e-12);
        // Normals point in: the frustum's middle is on their positive side.
        assert!(plane.signed_distance(DVec3::new(0.0, 0.0, -50.0)) > 0.0);
    }
}

#[test]
fn plane_from_point_normal_and_coefficients() {
    let plane = Plane::from_point_normal(DVec3::new(1.0, 2.0, 3.0), DVec3::new(0.0, 0.0, -4.0));
    assert_eq!(plane.normal, -DVec3::Z);
    assert_eq!(plane.signed_distance(DVec3::new(9.0, 9.0, 1.0)), 2.0);
    assert_eq!(plane.signed_distance(DVec3::new(-5.0, 0.0, 3.0)), 0.0);
    let scaled = Plane::normalized(DVec4::new(0.0, 0.0, -4.0, 12.0)).unwrap();
    assert_eq!(scaled, plane);
    assert_eq!(Plane::normalized(DVec4::new(0.0, 0.0, 0.0, 1.0)), None);
    assert_eq!(Plane::normalized(DVec4::new(f64::NAN, 0.0, 1.0, 1.0)), None);
    assert_eq!(Plane::ACCEPT_ALL.signed_distance(DVec3::splat(-1e300)), 1.0);
}
