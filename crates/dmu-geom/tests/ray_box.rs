//! Ray against box: the slab test against a per-axis interval oracle computed by
//! division in f64, plus the cases where `0 * inf` would be NaN.

use dmu_geom::glam::{DAffine3, DVec3, Vec3};
use dmu_geom::{Aabb3d, Aabb3f, Ray3d, Ray3f, RayBoxTest3d, RayBoxTest3f};
use proptest::prelude::*;

/// What the oracle says about a ray and a box.
#[derive(Clone, Copy, Debug)]
enum Expected {
    /// A zero direction component with the origin outside that slab: a certain miss.
    ParallelOutside,
    /// The parameter interval inside the box, unclipped emptiness allowed
    /// (`enter > exit` is a miss).
    Interval { enter: f64, exit: f64 },
}

/// Per-axis interval reasoning: a parallel axis either excludes the ray or does not
/// constrain it; any other axis bounds `t` between the two slab crossings, found by
/// division (not by a reciprocal) in f64.
fn oracle(origin: DVec3, dir: DVec3, aabb: &Aabb3d, t_max: f64) -> Expected {
    let (mut enter, mut exit) = (0.0f64, t_max);
    for axis in 0..3 {
        let (o, d) = (origin[axis], dir[axis]);
        if d == 0.0 {
            if o < aabb.min[axis] || o > aabb.max[axis] {
                return Expected::ParallelOutside;
            }
        } else {
            let (t0, t1) = ((aabb.min[axis] - o) / d, (aabb.max[axis] - o) / d);
            enter = enter.max(t0.min(t1));
            exit = exit.min(t0.max(t1));
        }
    }
    Expected::Interval { enter, exit }
}

/// Checks a slab test result against the oracle, leaving undecided only intervals
/// within `rel_tol` of empty (grazing a box edge).
fn check(got: Option<(f64, f64)>, expected: &Expected, rel_tol: f64) -> Result<(), TestCaseError> {
    match (*expected, got) {
        (Expected::ParallelOutside, got) => prop_assert_eq!(got, None),
        (Expected::Interval { enter, exit }, got) => {
            let tol =
                rel_tol * (1.0 + enter.abs() + if exit.is_finite() { exit.abs() } else { 0.0 });
            if exit - enter > tol {
                let (e, x) =
                    got.ok_or_else(|| TestCaseError::fail(format!("missed {expected:?}")))?;
                prop_assert!((e - enter).abs() <= tol, "enter {e} vs {expected:?}");
                prop_assert!(
                    x == exit || (x - exit).abs() <= tol,
                    "exit {x} vs {expected:?}"
                );
            } else if enter - exit > tol {
                prop_assert_eq!(got, None);
            } else if let Some((e, x)) = got {
                prop_assert!(e <= x);
            }
        }
    }
    Ok(())
}

/// Direction components: often exactly zero of either sign.
fn dir_component() -> impl Strategy<Value = f64> {
    prop_oneof![1 => Just(0.0), 1 => Just(-0.0), 4 => -1.0..1.0]
}

/// Box extents: often exactly zero (flat boxes).
fn extent_component() -> impl Strategy<Value = f64> {
    prop_oneof![1 => Just(0.0), 3 => 0.0..10.0]
}

/// Which coordinate an origin takes on one axis: free, or exactly on a slab plane.
#[derive(Clone, Copy, Debug)]
enum OriginOn {
    Free(f64),
    Min,
    Max,
}

fn origin_on() -> impl Strategy<Value = OriginOn> {
    prop_oneof![2 => (-20.0..20.0).prop_map(OriginOn::Free), 1 => Just(OriginOn::Min), 1 => Just(OriginOn::Max)]
}

fn t_max() -> impl Strategy<Value = f64> {
    prop_oneof![Just(f64::INFINITY), 0.0..60.0]
}

/// A box, an origin with some coordinates on its slab planes, a direction with some
/// zero components, and `t_max`, all offset by `offset`.
#[derive(Clone, Debug)]
struct Case {
    aabb: Aabb3d,
    origin: DVec3,
    dir: DVec3,
    t_max: f64,
}

fn case(offset: f64, to_f32: bool) -> impl Strategy<Value = Case> {
    let round = move |v: DVec3| if to_f32 { v.as_vec3().as_dvec3() } else { v };
    (
        [-10.0..10.0, -10.0..10.0, -10.0..10.0],
        [extent_component(), extent_component(), extent_component()],
        [origin_on(), origin_on(), origin_on()],
        [dir_component(), dir_component(), dir_component()],
        t_max(),
    )
        .prop_map(move |(min, extent, on, dir, t_max)| {
            let min = round(DVec3::from_array(min) + offset);
            let max = round(min + DVec3::from_array(extent));
            let origin = DVec3::from_array(std::array::from_fn(|axis| match on[axis] {
                OriginOn::Free(v) => round(DVec3::splat(v + offset)).x,
                OriginOn::Min => min[axis],
                OriginOn::Max => max[axis],
            }));
            Case {
                aabb: Aabb3d::new(min, max),
                origin,
                dir: round(DVec3::from_array(dir)),
                t_max,
            }
        })
}

proptest! {
    #[test]
    fn f32_slab_test_agrees_with_oracle(c in case(0.0, true)) {
        let aabb = Aabb3f::new(c.aabb.min.as_vec3(), c.aabb.max.as_vec3());
        let ray = Ray3f::new(c.origin.as_vec3(), c.dir.as_vec3());
        let got = RayBoxTest3f::new(&ray).hit(&aabb, c.t_max as f32);
        let expected = oracle(c.origin, c.dir, &c.aabb, f64::from(c.t_max as f32));
        check(got.map(|(e, x)| (f64::from(e), f64::from(x))), &expected, 1e-5)?;
        if let Some((t_enter, _)) = got {
            // The entry point itself lies in the box, up to rounding.
            let p = c.origin + c.dir * f64::from(t_enter);
            prop_assert!(c.aabb.inflated(1e-4 * (1.0 + p.abs().max_element())).contains_point(p));
        }
    }

    #[test]
    fn f64_slab_test_agrees_with_oracle(c in case(0.0, false)) {
        let got = RayBoxTest3d::new(&Ray3d::new(c.origin, c.dir)).hit(&c.aabb, c.t_max);
        check(got, &oracle(c.origin, c.dir, &c.aabb, c.t_max), 1e-12)?;
    }

    #[test]
    fn f64_slab_test_agrees_with_oracle_far_from_origin(c in case(1e7, false)) {
        let ray = Ray3d::new(c.origin, c.dir);
        let got = RayBoxTest3d::new(&ray).hit(&c.aabb, c.t_max);
        check(got, &oracle(c.origin, c.dir, &c.aabb, c.t_max), 1e-9)?;
        if let Some((t_enter, _)) = got {
            prop_assert!(c.aabb.inflated(1e-6).contains_point(ray.at(t_enter)));
        }
    }
}

fn hit3d(origin: DVec3, dir: DVec3, aabb: &Aabb3d) -> Option<(f64, f64)> {
    RayBoxTest3d::new(&Ray3d::new(origin, dir)).hit(aabb, f64::INFINITY)
}

fn hit3f(origin: Vec3, dir: Vec3, aabb: &Aabb3f) -> Option<(f32, f32)> {
    RayBoxTest3f::new(&Ray3f::new(origin, dir)).hit(aabb, f32::INFINITY)
}

/// Exit distances are widened by a few ulps on purpose; entries are exact in these
/// hand-made cases.
fn assert_interval(got: Option<(f64, f64)>, enter: f64, exit: f64) {
    let (e, x) = got.unwrap_or_else(|| panic!("expected a hit on [{enter}, {exit}]"));
    assert_eq!(e, enter, "entry");
    assert!(
        x >= exit && x - exit <= 1e-14 * exit.abs(),
        "exit {x} vs {exit}"
    );
}

const UNIT: Aabb3d = Aabb3d::new(DVec3::ZERO, DVec3::ONE);

/// A ray along `axis` whose other two coordinates sit exactly on slab planes
/// (`0 * inf` territory) hits, whatever the sign of the zero components.
#[test]
fn parallel_ray_on_slab_plane_hits() {
    for axis in 0..3 {
        for on in [0.0, 1.0] {
            for zero in [0.0, -0.0] {
                let mut origin = DVec3::splat(on);
                origin[axis] = -2.0;
                let mut dir = DVec3::splat(zero);
                dir[axis] = 0.5;
                assert_interval(hit3d(origin, dir, &UNIT), 4.0, 6.0);
                let unit = Aabb3f::new(Vec3::ZERO, Vec3::ONE);
                let (e, x) =
                    hit3f(origin.as_vec3(), dir.as_vec3(), &unit).expect("f32 ray on a face plane");
                assert!(e == 4.0 && (x - 6.0).abs() < 1e-5, "f32 [{e}, {x}]");
            }
        }
    }
}

/// One ulp outside a slab, a parallel ray misses.
#[test]
fn parallel_ray_just_outside_slab_misses() {
    for zero in [0.0, -0.0] {
        let dir = DVec3::new(1.0, zero, zero);
        assert_eq!(
            hit3d(DVec3::new(-1.0, 1.0f64.next_up(), 0.5), dir, &UNIT),
            None
        );
        assert_eq!(
            hit3d(DVec3::new(-1.0, 0.5, 0.0f64.next_down()), dir, &UNIT),
            None
        );
        assert_eq!(
            hit3d(DVec3::new(-1.0, 1.0, 1.0), dir, &UNIT).map(|h| h.0),
            Some(1.0)
        );
    }
}

#[test]
fn flat_box_hit_and_miss() {
    let flat = Aabb3d::new(DVec3::new(0.0, 0.0, 2.0), DVec3::new(1.0, 1.0, 2.0));
    // Crossing the flat box: entry and exit coincide.
    assert_interval(hit3d(DVec3::new(0.5, 0.5, 0.0), DVec3::Z, &flat), 2.0, 2.0);
    assert_interval(
        hit3d(DVec3::ZERO, DVec3::new(0.25, 0.25, 1.0), &flat),
        2.0,
        2.0,
    );
    // Crossing the plane outside the box, or stopping before it.
    assert_eq!(hit3d(DVec3::new(1.5, 0.5, 0.0), DVec3::Z, &flat), None);
    assert_eq!(
        RayBoxTest3d::new(&Ray3d::new(DVec3::new(0.5, 0.5, 0.0), DVec3::Z)).hit(&flat, 1.999),
        None
    );
    // Lying in the flat box's plane: inside it along the whole crossing.
    assert_eq!(
        hit3d(DVec3::new(-1.0, 0.5, 2.0), DVec3::X, &flat).map(|h| h.0),
        Some(1.0)
    );
    assert_eq!(
        hit3d(DVec3::new(-1.0, 0.5, 2.0f64.next_up()), DVec3::X, &flat),
        None
    );
    // A box flat on all three axes is a point.
    let point = Aabb3d::new(DVec3::splat(3.0), DVec3::splat(3.0));
    assert_interval(hit3d(DVec3::new(3.0, 3.0, 0.0), DVec3::Z, &point), 3.0, 3.0);
    assert_eq!(
        hit3d(DVec3::new(3.0, 3.0, 3.0), DVec3::ZERO, &point),
        Some((0.0, f64::INFINITY))
    );
    assert_eq!(
        hit3d(DVec3::new(3.0, 3.0f64.next_up(), 0.0), DVec3::Z, &point),
        None
    );
    let flat32 = Aabb3f::new(Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 1.0, 2.0));
    let (e, x) = hit3f(Vec3::new(0.5, 0.5, 0.0), Vec3::Z, &flat32).expect("f32 flat box");
    assert!(e == 2.0 && (x - 2.0).abs() < 1e-6, "f32 [{e}, {x}]");
    assert_eq!(hit3f(Vec3::new(1.5, 0.5, 0.0), Vec3::Z, &flat32), None);
}

#[test]
fn origin_inside_box_enters_at_zero() {
    assert_interval(
        hit3d(DVec3::splat(0.5), DVec3::new(1.0, -0.5, 0.25), &UNIT),
        0.0,
        0.5,
    );
    // On a corner, leaving: the box is touched at t = 0 only.
    assert_interval(hit3d(DVec3::ONE, DVec3::ONE, &UNIT), 0.0, 0.0);
    // Zero direction: inside for every t, or never.
    assert_eq!(
        hit3d(DVec3::splat(0.5), DVec3::ZERO, &UNIT),
        Some((0.0, f64::INFINITY))
    );
    assert_eq!(hit3d(DVec3::splat(1.5), DVec3::ZERO, &UNIT), None);
    assert_eq!(
        hit3d(DVec3::splat(0.5), -DVec3::ZERO, &UNIT),
        Some((0.0, f64::INFINITY))
    );
}

#[test]
fn ray_along_face_and_edge_hits() {
    for zero in [0.0, -0.0] {
        // In the face y = 1, crossing it along x.
        assert_interval(
            hit3d(
                DVec3::new(-1.0, 1.0, 0.5),
                DVec3::new(2.0, zero, zero),
                &UNIT,
            ),
            0.5,
            1.0,
        );
        // Along the edge y = 0, z = 1, backwards.
        assert_interval(
            hit3d(
                DVec3::new(3.0, 0.0, 1.0),
                DVec3::new(-1.0, zero, zero),
                &UNIT,
            ),
            2.0,
            3.0,
        );
    }
}

#[test]
fn empty_and_inverted_boxes_are_never_hit() {
    let inverted = Aabb3d::new(DVec3::ONE, DVec3::ZERO);
    for origin in [
        DVec3::ZERO,
        DVec3::splat(0.5),
        DVec3::splat(-5.0),
        DVec3::new(0.5, 0.5, -3.0),
    ] {
        for dir in [
            DVec3::Z,
            DVec3::ONE,
            -DVec3::ONE,
            DVec3::ZERO,
            -DVec3::ZERO,
            DVec3::new(0.0, -0.0, 1.0),
        ] {
            assert_eq!(hit3d(origin, dir, &Aabb3d::EMPTY), None, "{origin} {dir}");
            assert_eq!(hit3d(origin, dir, &inverted), None, "{origin} {dir}");
            assert_eq!(
                hit3f(origin.as_vec3(), dir.as_vec3(), &Aabb3f::EMPTY),
                None,
                "{origin} {dir}"
            );
        }
    }
}

#[test]
fn t_max_and_negative_t_bound_the_hit() {
    let ray = RayBoxTest3d::new(&Ray3d::new(DVec3::new(0.5, 0.5, -2.0), DVec3::Z));
    assert_eq!(ray.hit(&UNIT, 1.5), None);
    // `t_max` caps the exit exactly: it is not widened.
    assert_eq!(ray.hit(&UNIT, 2.0), Some((2.0, 2.0)));
    assert_eq!(ray.hit(&UNIT, 2.5), Some((2.0, 2.5)));
    // The box behind the origin.
    let behind = RayBoxTest3d::new(&Ray3d::new(DVec3::new(0.5, 0.5, 3.0), DVec3::Z));
    assert_eq!(behind.hit(&UNIT, f64::INFINITY), None);
}

/// A box of a part placed 1e7 from the origin: tested in world f64 directly, and in
/// f32 after taking the ray to the part's frame, the same `t` comes out.
#[test]
fn box_far_from_origin() {
    let world = DAffine3::from_translation(DVec3::new(1e7, -2e7, 3e7))
        * DAffine3::from_scale(DVec3::splat(2.0));
    let local = Aabb3f::new(Vec3::new(-0.25, -0.25, -0.25), Vec3::new(0.25, 0.25, 0.25));
    let world_box = local.transformed(&world);
    let exact = Aabb3d::new(
        DVec3::new(1e7 - 0.5, -2e7 - 0.5, 3e7 - 0.5),
        DVec3::new(1e7 + 0.5, -2e7 + 0.5, 3e7 + 0.5),
    );
    // Encloses the exact box, padded by no more than a few ulps at 3e7.
    assert!(world_box.contains(&exact));
    assert!((world_box.min - exact.min).abs().max_element() < 1e-6);
    assert!((world_box.max - exact.max).abs().max_element() < 1e-6);
    let ray = Ray3d::new(
        DVec3::new(1e7 + 0.25, -2e7 + 0.25, 3e7 - 10.0),
        DVec3::new(0.0, 0.0, 2.0),
    );
    let (e, x) = RayBoxTest3d::new(&ray)
        .hit(&world_box, f64::INFINITY)
        .unwrap();
    // Within the enclosing pad (a few ulps of 3e7 over |dir| = 2).
    assert!((e - 4.75).abs() < 1e-7 && (x - 5.25).abs() < 1e-7);
    let (e32, x32) = RayBoxTest3f::new(&ray.to_local(&world).as_f32())
        .hit(&local, f32::INFINITY)
        .unwrap();
    assert!((f64::from(e32) - 4.75).abs() < 1e-5 && (f64::from(x32) - 5.25).abs() < 1e-5);
    // One millimetre beside the box: a miss in both frames.
    let beside = Ray3d::new(ray.origin + DVec3::new(0.25 + 1e-3, 0.0, 0.0), ray.dir);
    assert_eq!(
        RayBoxTest3d::new(&beside).hit(&world_box, f64::INFINITY),
        None
    );
    assert_eq!(
        RayBoxTest3f::new(&beside.to_local(&world).as_f32()).hit(&local, f32::INFINITY),
        None
    );
}

/// A direction too short or too long to square is scaled by an exact power of
/// two (same direction, every bit kept); any other is left alone; zero and
/// non-finite ones are refused.
#[test]
fn issue_20_ray_directions_are_made_safe_to_square() {
    let o = DVec3::new(1.0, 2.0, 3.0);
    for d in [
        DVec3::new(0.6, -0.3, 0.1),
        DVec3::new(1e-150, 0.0, 0.0),
        DVec3::new(0.0, 3e150, -1.0),
    ] {
        assert_eq!(Ray3d::with_safe_dir(o, d).unwrap().dir, d, "{d}");
    }
    for d in [
        DVec3::new(1e-300, -2e-301, 0.0),
        DVec3::new(f64::from_bits(1), 0.0, 0.0),
        DVec3::new(1e160, 1.0, -3e159),
        DVec3::new(f64::MAX, f64::MAX, -f64::MAX),
    ] {
        let safe = Ray3d::with_safe_dir(o, d).unwrap().dir;
        let largest = safe.abs().max_element();
        assert!((1.0..2.0).contains(&largest), "{d} -> {safe}");
        assert!(safe.length_squared().is_normal(), "{d} -> {safe}");
        // An exact power of two, the same for every component (2^1074 for the
        // smallest subnormal is not an f64: that one is checked by its bits).
        let scale = safe.x / d.x;
        if scale.is_finite() {
            assert_eq!(scale.log2().fract(), 0.0, "{scale} is a power of two");
            for (s, d) in safe.to_array().into_iter().zip(d.to_array()) {
                assert_eq!(s, d * scale, "{d} -> {safe}");
            }
        } else {
            assert_eq!(safe, DVec3::X);
        }
    }
    assert!(Ray3d::with_safe_dir(o, DVec3::ZERO).is_none());
    assert!(Ray3d::with_safe_dir(o, DVec3::new(f64::NAN, 1.0, 0.0)).is_none());
    assert!(Ray3d::with_safe_dir(DVec3::INFINITY, DVec3::X).is_none());
}
