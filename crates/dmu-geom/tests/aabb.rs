//! Boxes: the transform against the box of transformed corners, the f32 narrowing
//! against the f64 box it must enclose, and the set operations against point
//! membership.

use dmu_geom::glam::{DAffine3, DMat3, DQuat, DVec3, Vec3};
use dmu_geom::{Aabb3d, Aabb3f};
use proptest::prelude::*;

fn dvec3(range: std::ops::Range<f64>) -> impl Strategy<Value = DVec3> {
    [range.clone(), range.clone(), range].prop_map(DVec3::from_array)
}

/// Rotation, non-uniform scale of either sign and translation up to 1e7.
fn affine() -> impl Strategy<Value = DAffine3> {
    let scale = (0.01f64..100.0, any::<bool>()).prop_map(|(s, neg)| if neg { -s } else { s });
    (
        dvec3(-1.0..1.0),
        0.0..std::f64::consts::TAU,
        [scale.clone(), scale.clone(), scale],
        dvec3(-1e7..1e7),
    )
        .prop_map(|(axis, angle, scale, translation)| {
            let rotation = DQuat::from_axis_angle(axis.try_normalize().unwrap_or(DVec3::X), angle);
            DAffine3::from_scale_rotation_translation(
                DVec3::from_array(scale),
                rotation,
                translation,
            )
        })
}

/// A box with some zero-extent axes.
fn aabb3d(range: f64) -> impl Strategy<Value = Aabb3d> {
    let extent = prop_oneof![1 => Just(0.0), 3 => 0.0..range];
    (
        dvec3(-range..range),
        [extent.clone(), extent.clone(), extent],
    )
        .prop_map(|(min, extent)| Aabb3d::new(min, min + DVec3::from_array(extent)))
}

/// Boxes and points on a coarse integer grid, so that shared faces and points on
/// the boundary are common.
fn grid_point() -> impl Strategy<Value = DVec3> {
    [-3i32..=3, -3i32..=3, -3i32..=3].prop_map(|c| DVec3::from_array(c.map(f64::from)))
}

fn grid_box() -> impl Strategy<Value = Aabb3d> {
    prop::collection::vec(grid_point(), 1..4).prop_map(Aabb3d::from_points)
}

/// Componentwise `|a - b| <= tol`.
fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).abs().cmple(DVec3::splat(tol)).all()
}

/// Regression (a CI run's proptest case): a translation that nearly cancels
/// the rotated centre (-23,359 + 22,938 = -421) left the centre with the
/// rounding of the large terms, more than a pad scaled by the small centre
/// covered; the box fell 6e-14 short of a transformed corner.
#[test]
fn a_translation_cancelling_the_rotated_centre_still_encloses() {
    let aabb = Aabb3d {
        min: DVec3::new(-406.9422364589349, -160.42731694847097, 0.0),
        max: DVec3::new(-406.9422364589349, -160.42731694847097, 804.066835184158),
    };
    let m = DAffine3 {
        matrix3: DMat3::from_cols(
            DVec3::new(-19.978559368966675, -19.865890987922295, -77.00682275892946),
            DVec3::new(-92.3025971487713, 5.7882177426573795, 22.45365738266422),
            DVec3::new(
                4.224196694158078e-7,
                -0.009683007721245914,
                0.002497871352142397,
            ),
        ),
        translation: DVec3::new(-23358.637292008807, 0.0, 0.0),
    };
    let local = Aabb3f::new(aabb.min.as_vec3(), aabb.max.as_vec3());
    let corners = |points: [DVec3; 8]| Aabb3d::from_points(points.map(|c| m.transform_point3(c)));
    for (got, want) in [
        (aabb.transformed(&m), corners(aabb.corners())),
        (
            local.transformed(&m),
            corners(local.corners().map(|c| c.as_dvec3())),
        ),
    ] {
        assert!(got.contains(&want), "{got:?} does not enclose {want:?}");
    }
}

proptest! {
    #[test]
    fn transformed_equals_box_of_transformed_corners(aabb in aabb3d(1e3), m in affine()) {
        let oracle = Aabb3d::from_points(aabb.corners().map(|c| m.transform_point3(c)));
        let got = aabb.transformed(&m);
        let tol = 1e-12 * (oracle.min.abs().max(oracle.max.abs()).max_element() + 1.0);
        prop_assert!(close(got.min, oracle.min, tol) && close(got.max, oracle.max, tol), "{got:?} vs {oracle:?}");
        // Never an ulp short: trees rely on boxes that enclose.
        prop_assert!(got.contains(&oracle), "{got:?} does not enclose {oracle:?}");
    }

    #[test]
    fn transformed_f32_box_equals_box_of_transformed_corners(aabb in aabb3d(1e3), m in affine()) {
        let local = Aabb3f::new(aabb.min.as_vec3(), aabb.max.as_vec3());
        let oracle = Aabb3d::from_points(local.corners().map(|c| m.transform_point3(c.as_dvec3())));
        let got = local.transformed(&m);
        let tol = 1e-12 * (oracle.min.abs().max(oracle.max.abs()).max_element() + 1.0);
        prop_assert!(close(got.min, oracle.min, tol) && close(got.max, oracle.max, tol), "{got:?} vs {oracle:?}");
        prop_assert!(got.contains(&oracle), "{got:?} does not enclose {oracle:?}");
    }

    #[test]
    fn as_vec_outward_encloses_and_is_tight(aabb in aabb3d(1e7), fraction in dvec3(0.0..1.0)) {
        // Fractional parts that f32 cannot hold at this magnitude.
        let aabb = Aabb3d::new(aabb.min + fraction, aabb.max + fraction);
        let narrow = aabb.as_vec_outward();
        prop_assert!(narrow.as_dvec().contains(&aabb));
        for axis in 0..3 {
            // One ulp further in would lose part of the box.
            prop_assert!(f64::from(narrow.min[axis].next_up()) > aabb.min[axis]);
            prop_assert!(f64::from(narrow.max[axis].next_down()) < aabb.max[axis]);
        }
    }

    #[test]
    fn union_is_box_of_all_points(
        a in prop::collection::vec(grid_point(), 1..5),
        b in prop::collection::vec(grid_point(), 1..5),
        p in grid_point(),
    ) {
        let (box_a, box_b) = (Aabb3d::from_points(a.iter().copied()), Aabb3d::from_points(b.iter().copied()));
        let union = box_a.union(box_b);
        prop_assert_eq!(union, Aabb3d::from_points(a.iter().chain(&b).copied()));
        prop_assert!(union.contains(&box_a) && union.contains(&box_b));
        prop_assert_eq!(box_a.union(Aabb3d::EMPTY), box_a);
        if box_a.contains_point(p) || box_b.contains_point(p) {
            prop_assert!(union.contains_point(p));
        }
    }

    #[test]
    fn set_operations_agree_with_point_membership(a in grid_box(), b in grid_box(), p in grid_point()) {
        let in_a = p.cmpge(a.min).all() && p.cmple(a.max).all();
        prop_assert_eq!(a.contains_point(p), in_a);
        prop_assert_eq!(a.intersection(b).contains_point(p), in_a && b.contains_point(p));
        // Boxes are convex: containing all corners is containing the box.
        prop_assert_eq!(a.contains(&b), b.corners().iter().all(|&c| a.contains_point(c)));
        prop_assert_eq!(a.overlaps(&b), !a.intersection(b).is_empty());
        prop_assert_eq!(a.overlaps(&b), b.overlaps(&a));
        prop_assert!(a.contains(&Aabb3d::EMPTY) && !Aabb3d::EMPTY.contains(&a));
        prop_assert!(!Aabb3d::EMPTY.contains_point(p) && !Aabb3d::EMPTY.overlaps(&a));
    }
}

#[test]
fn empty_box_stays_empty() {
    let m = DAffine3::from_translation(DVec3::splat(5.0));
    assert!(Aabb3d::EMPTY.is_empty() && Aabb3d::EMPTY.transformed(&m).is_empty());
    assert!(Aabb3f::EMPTY.transformed(&m).is_empty());
    assert_eq!(Aabb3d::from_points([]), Aabb3d::EMPTY);
    assert_eq!(Aabb3d::EMPTY.extent(), DVec3::ZERO);
    let flat = Aabb3f::from_points([Vec3::ZERO, Vec3::new(1.0, 2.0, 0.0)]);
    assert!(!flat.is_empty() && flat.contains_point(Vec3::new(0.5, 1.0, 0.0)));
    assert_eq!(flat.surface_area(), 4.0);
}
