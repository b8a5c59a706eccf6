//! Ray against triangle: agreement with Möller–Trumbore in f64 away from edges,
//! watertightness on shared edges and vertices, degenerate and coplanar cases, and
//! a part far from the world origin.

use dmu_geom::glam::{DAffine3, DQuat, DVec3, Vec3};
use dmu_geom::{
    Ray3d, Ray3f, RayTriTest3d, RayTriTest3f, TriHit, closest_point_on_triangle, is_degenerate,
    triangle_area, triangle_normal,
};
use proptest::prelude::*;

/// Möller–Trumbore in f64, unclipped: `(t, u, v)` with the hit point
/// `origin + t * dir = (1 - u - v) v0 + u v1 + v v2`, and the determinant scaled to
/// be a sine, so callers can skip near-parallel rays.
fn moller_trumbore(origin: DVec3, dir: DVec3, [v0, v1, v2]: [DVec3; 3]) -> (f64, f64, f64, f64) {
    let (e1, e2) = (v1 - v0, v2 - v0);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    let s = origin - v0;
    let q = s.cross(e1);
    let sine = det / (dir.length() * e1.cross(e2).length());
    (e2.dot(q) / det, s.dot(p) / det, dir.dot(q) / det, sine)
}

fn vec3(range: std::ops::Range<f32>) -> impl Strategy<Value = Vec3> {
    [range.clone(), range.clone(), range].prop_map(Vec3::from_array)
}

/// A triangle with no angle below about 8 degrees.
fn well_shaped_triangle() -> impl Strategy<Value = [Vec3; 3]> {
    [vec3(-10.0..10.0), vec3(-10.0..10.0), vec3(-10.0..10.0)].prop_filter(
        "well shaped",
        |&[a, b, c]| {
            let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            (b - a).cross(c - a).length() > 0.15 * longest * longest
        },
    )
}

/// A ray from anywhere towards a point of the triangle's plane with barycentrics
/// `(a, b)` (inside when `a, b >= 0` and `a + b <= 1`), sometimes pointing away.
#[derive(Clone, Debug)]
struct Aim {
    origin: Vec3,
    a: f32,
    b: f32,
    length: f32,
    backwards: bool,
}

fn aim() -> impl Strategy<Value = Aim> {
    (
        vec3(-20.0..20.0),
        -0.3f32..1.0,
        -0.3f32..1.0,
        0.1f32..10.0,
        prop::bool::weighted(0.2),
    )
        .prop_map(|(origin, a, b, length, backwards)| Aim {
            origin,
            a,
            b,
            length,
            backwards,
        })
}

impl Aim {
    fn ray(&self, [v0, v1, v2]: [Vec3; 3]) -> Ray3f {
        let target = v0 + self.a * (v1 - v0) + self.b * (v2 - v0);
        let dir = (target - self.origin).normalize_or_zero() * self.length;
        Ray3f::new(self.origin, if self.backwards { -dir } else { dir })
    }
}

/// Compares one hit result with the oracle, skipping rays within `margin` of an edge,
/// of `t = 0`, or nearly parallel to the triangle.
fn check_against_oracle(
    got: Option<TriHit<f64>>,
    origin: DVec3,
    dir: DVec3,
    tri: [DVec3; 3],
    t_max: f64,
    rel_tol: f64,
) -> Result<(), TestCaseError> {
    let (t, u, v, sine) = moller_trumbore(origin, dir, tri);
    let margin = 1e-3;
    let near_edge = u.abs() < margin || v.abs() < margin || (1.0 - u - v).abs() < margin;
    let near_bounds = t.abs() < margin || (t - t_max).abs() < margin * t_max;
    if sine.abs() < 0.05 || near_edge || near_bounds {
        return Ok(());
    }
    let expect_hit = u > 0.0 && v > 0.0 && u + v < 1.0 && t > 0.0 && t < t_max;
    match got {
        Some(hit) if expect_hit => {
            prop_assert!((hit.t - t).abs() <= rel_tol * t.abs(), "t {} vs {t}", hit.t);
            prop_assert!(
                (hit.u - u).abs() <= 10.0 * rel_tol && (hit.v - v).abs() <= 10.0 * rel_tol,
                "uv ({}, {}) vs ({u}, {v})",
                hit.u,
                hit.v
            );
        }
        None if !expect_hit => {}
        _ => prop_assert!(false, "got {got:?}, oracle t {t} u {u} v {v}"),
    }
    Ok(())
}

proptest! {
    #[test]
    fn f32_test_agrees_with_moller_trumbore(tri in well_shaped_triangle(), aim in aim(), t_max in prop_oneof![Just(f32::INFINITY), 1.0f32..40.0]) {
        let ray = aim.ray(tri);
        let got = RayTriTest3f::new(&ray).hit(tri[0], tri[1], tri[2], 0.0, t_max);
        let got = got.map(|h| TriHit { t: f64::from(h.t), u: f64::from(h.u), v: f64::from(h.v) });
        check_against_oracle(got, ray.origin.as_dvec3(), ray.dir.as_dvec3(), tri.map(Vec3::as_dvec3), f64::from(t_max), 1e-5)?;
    }

    #[test]
    fn f64_test_agrees_with_moller_trumbore(tri in well_shaped_triangle(), aim in aim(), t_max in prop_oneof![Just(f64::INFINITY), 1.0f64..40.0]) {
        let ray = aim.ray(tri);
        let (origin, dir, tri) = (ray.origin.as_dvec3(), ray.dir.as_dvec3(), tri.map(Vec3::as_dvec3));
        let got = RayTriTest3d::new(&Ray3d::new(origin, dir)).hit(tri[0], tri[1], tri[2], 0.0, t_max);
        check_against_oracle(got, origin, dir, tri, t_max, 1e-10)?;
    }
}

/// A height field of `N x N` quads, each split into two triangles along alternating
/// diagonals, on integer x, y with heights that are multiples of 1/64. Every vertex
/// and edge midpoint is then exact in f32, and so is the direction towards it from an
/// origin on a 1/8 grid: the rays really pass through the shared edges and vertices.
struct HeightField {
    vertices: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

const N: u32 = 6;

impl HeightField {
    fn new(heights: &[i8]) -> Self {
        let index = |i: u32, j: u32| i * (N + 1) + j;
        let vertices = (0..=N)
            .flat_map(|i| (0..=N).map(move |j| (i, j)))
            .map(|(i, j)| {
                Vec3::new(
                    i as f32,
                    j as f32,
                    f32::from(heights[index(i, j) as usize]) / 64.0,
                )
            })
            .collect();
        let mut triangles = Vec::new();
        for i in 0..N {
            for j in 0..N {
                let [a, b, c, d] = [
                    index(i, j),
                    index(i + 1, j),
                    index(i + 1, j + 1),
                    index(i, j + 1),
                ];
                if (i + j) % 2 == 0 {
                    triangles.extend([[a, b, c], [a, c, d]]);
                } else {
                    triangles.extend([[a, b, d], [b, c, d]]);
                }
            }
        }
        HeightField {
            vertices,
            triangles,
        }
    }

    /// Interior vertices and the midpoints of interior edges.
    fn shared_points(&self) -> Vec<Vec3> {
        let interior = |p: Vec3| p.x > 0.0 && p.x < N as f32 && p.y > 0.0 && p.y < N as f32;
        let mut points: Vec<Vec3> = self
            .vertices
            .iter()
            .copied()
            .filter(|&p| interior(p))
            .collect();
        for tri in &self.triangles {
            for k in 0..3 {
                let mid = (self.vertices[tri[k] as usize]
                    + self.vertices[tri[(k + 1) % 3] as usize])
                    * 0.5;
                if interior(mid) {
                    points.push(mid);
                }
            }
        }
        points
    }

    /// The hits of `ray` with every triangle, in f32 and f64.
    fn hits(&self, ray: &Ray3f) -> (Vec<f32>, Vec<f64>) {
        let (test32, test64) = (
            RayTriTest3f::new(ray),
            RayTriTest3d::new(&Ray3d::new(ray.origin.as_dvec3(), ray.dir.as_dvec3())),
        );
        let mut hits = (Vec::new(), Vec::new());
        for tri in &self.triangles {
            let [a, b, c] = tri.map(|k| self.vertices[k as usize]);
            hits.0
                .extend(test32.hit(a, b, c, 0.0, f32::INFINITY).map(|h| h.t));
            hits.1.extend(
                test64
                    .hit(a.as_dvec3(), b.as_dvec3(), c.as_dvec3(), 0.0, f64::INFINITY)
                    .map(|h| h.t),
            );
        }
        hits
    }
}

/// The ray from `target + offset` through `target`, where `offset` descends (or
/// climbs) at least twice as steeply as any triangle of the field. The ray then
/// crosses the field exactly once, transversally, so it must hit at `t = 1`: it never
/// merely grazes a silhouette edge, where either answer would be right.
fn steep_offset(dx: f32, dy: f32, lift: f32, below: bool) -> Vec3 {
    let dz = 2.0 * (dx.abs() + dy.abs()) + 1.0 + lift;
    Vec3::new(dx, dy, if below { -dz } else { dz })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Every steep ray aimed exactly at a shared vertex or edge point, from above or
    /// below, hits some triangle there (`t = 1` at the target).
    #[test]
    fn rays_through_shared_edges_and_vertices_never_fall_through(
        heights in prop::collection::vec(-32i8..32, ((N + 1) * (N + 1)) as usize),
        steps in [-40i32..40, -40i32..40, 0i32..400],
        below in any::<bool>(),
    ) {
        let field = HeightField::new(&heights);
        // Steps of 1/8 keep `target - origin` exact in f32.
        let [dx, dy, lift] = steps.map(|s| s as f32 / 8.0);
        let offset = steep_offset(dx, dy, lift, below);
        for target in field.shared_points() {
            for ray in [Ray3f::new(target + offset, -offset), Ray3f::new(target + Vec3::Z, -Vec3::Z)] {
                let (hits32, hits64) = field.hits(&ray);
                prop_assert!(hits32.iter().any(|&t| (t - 1.0).abs() < 1e-5), "f32 fell through at {target}: {ray:?}");
                prop_assert!(hits64.iter().any(|&t| (t - 1.0).abs() < 1e-12), "f64 fell through at {target}: {ray:?}");
            }
        }
    }

    /// The same on a rotated, translated field, where nothing is exact any more:
    /// still no steep ray aimed at a shared edge or vertex escapes.
    #[test]
    fn rays_near_shared_edges_of_a_rotated_field_never_fall_through(
        heights in prop::collection::vec(-32i8..32, ((N + 1) * (N + 1)) as usize),
        axis in vec3(-1.0..1.0),
        angle in 0.0f32..6.3,
        offset in vec3(-5.0..5.0),
        below in any::<bool>(),
    ) {
        let field = HeightField::new(&heights);
        let rotation = dmu_geom::glam::Quat::from_axis_angle(axis.try_normalize().unwrap_or(Vec3::X), angle);
        let place = |p: Vec3| rotation * p + Vec3::new(3.0, -7.0, 11.0);
        let shared = field.shared_points();
        let field = HeightField { vertices: field.vertices.iter().map(|&p| place(p)).collect(), ..field };
        let offset = rotation * steep_offset(offset.x, offset.y, offset.z.abs(), below);
        for target in shared.into_iter().map(place) {
            let (hits32, _) = field.hits(&Ray3f::new(target + offset, -offset));
            prop_assert!(hits32.iter().any(|&t| (t - 1.0).abs() < 1e-4), "fell through at {target}: {hits32:?}");
        }
    }
}

fn hit32(tri: [Vec3; 3], origin: Vec3, dir: Vec3) -> Option<TriHit<f32>> {
    RayTriTest3f::new(&Ray3f::new(origin, dir)).hit(tri[0], tri[1], tri[2], 0.0, f32::INFINITY)
}

fn hit64(tri: [Vec3; 3], origin: Vec3, dir: Vec3) -> Option<TriHit<f64>> {
    let tri = tri.map(Vec3::as_dvec3);
    RayTriTest3d::new(&Ray3d::new(origin.as_dvec3(), dir.as_dvec3())).hit(
        tri[0],
        tri[1],
        tri[2],
        0.0,
        f64::INFINITY,
    )
}

proptest! {
    /// Coincident and exactly collinear vertices (on a 1/8 grid, so the collinear
    /// points are exact), hit by rays aimed exactly at them: never a hit.
    #[test]
    fn degenerate_triangles_are_never_hit(
        p in [-40i32..40, -40i32..40, -40i32..40],
        e in [-16i32..16, -16i32..16, -16i32..16],
        steps in [-3i32..4, -3i32..4],
        aim_step in -4i32..8,
        origin in [-160i32..160, -160i32..160, -160i32..160],
    ) {
        let grid = |c: [i32; 3]| Vec3::from_array(c.map(|k| k as f32 / 8.0));
        let (p, e, origin) = (grid(p), grid(e), grid(origin));
        let tri = [p, p + steps[0] as f32 * e, p + steps[1] as f32 * e];
        prop_assert!(is_degenerate(tri[0], tri[1], tri[2]));
        prop_assert_eq!(triangle_area(tri[0], tri[1], tri[2]), 0.0);
        prop_assert_eq!(triangle_normal(tri[0], tri[1], tri[2]), Vec3::ZERO);
        let target = p + (aim_step as f32 * 0.5) * e;
        for dir in [target - origin, Vec3::Z, -Vec3::ONE] {
            let origin = if dir == target - origin { origin } else { target - dir };
            for order in [[0, 1, 2], [1, 2, 0], [2, 1, 0]] {
                let tri = order.map(|k| tri[k]);
                prop_assert_eq!(hit32(tri, origin, dir), None);
                prop_assert_eq!(hit64(tri, origin, dir), None);
            }
        }
    }

    /// Needles: one vertex a hair off the opposite edge. Hits are finite with
    /// barycentrics in range; rays aimed at the middle of the needle hit it.
    #[test]
    fn sliver_triangles_give_finite_hits(
        a in vec3(-10.0..10.0),
        b in vec3(-10.0..10.0),
        s in 0.0f32..1.0,
        offset_exp in -5i32..-1,
        aim in aim(),
    ) {
        let edge = b - a;
        prop_assume!(edge.length() > 1.0);
        let side = edge.normalize().any_orthonormal_vector() * 10f32.powi(offset_exp) * edge.length();
        let tri = [a, b, a + s * edge + side];
        prop_assert!(!is_degenerate(tri[0], tri[1], tri[2]));
        // Half base times height, the height measured from the f32 apex in f64.
        let (base, apex) = (b.as_dvec3() - a.as_dvec3(), tri[2].as_dvec3() - a.as_dvec3());
        let height = (apex - apex.project_onto(base)).length();
        let area = f64::from(triangle_area(tri[0], tri[1], tri[2]));
        prop_assert!((area / (0.5 * base.length() * height) - 1.0).abs() < 1e-6, "{area} vs {}", 0.5 * base.length() * height);
        for ray in [aim.ray(tri), Ray3f::new(aim.origin, (a + 0.5 * edge + 0.25 * (s - 0.5) * edge + 0.25 * side) - aim.origin)] {
            if let Some(hit) = RayTriTest3f::new(&ray).hit(tri[0], tri[1], tri[2], 0.0, f32::INFINITY) {
                prop_assert!(hit.t.is_finite() && hit.t >= 0.0);
                prop_assert!(hit.u >= 0.0 && hit.v >= 0.0 && hit.u + hit.v <= 1.0 + 1e-6, "{hit:?}");
            }
        }
    }

    /// Rays in the triangle's plane: no area is crossed, so at most a rounding hit,
    /// and never a NaN.
    #[test]
    fn coplanar_rays_give_no_nan(tri in well_shaped_triangle(), a in -0.5f32..1.5, b in -0.5f32..1.5, c in -0.5f32..1.5, d in -0.5f32..1.5) {
        let [v0, v1, v2] = tri;
        let in_plane = |a: f32, b: f32| v0 + a * (v1 - v0) + b * (v2 - v0);
        let (origin, target) = (in_plane(a, b), in_plane(c, d));
        let hits = [
            hit32(tri, origin, target - origin).map(|h| [h.t, h.u, h.v].map(f64::from)),
            hit64(tri, origin, target - origin).map(|h| [h.t, h.u, h.v]),
        ];
        for [t, u, v] in hits.into_iter().flatten() {
            prop_assert!(t.is_finite() && t >= 0.0, "t {t}");
            prop_assert!(u >= 0.0 && v >= 0.0 && u + v <= 1.0 + 1e-6, "u {u} v {v}");
        }
    }
}

#[test]
fn exactly_coplanar_rays_miss() {
    let tri = [
        Vec3::ZERO,
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 4.0, 0.0),
    ];
    for (origin, dir) in [
        (Vec3::new(-1.0, 1.0, 0.0), Vec3::X),
        (Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 0.5, 0.0)),
        (Vec3::new(-1.0, -1.0, 0.0), Vec3::ONE.with_z(0.0)),
    ] {
        assert_eq!(hit32(tri, origin, dir), None);
        assert_eq!(hit64(tri, origin, dir), None);
    }
}

#[test]
fn both_faces_are_hit_with_the_same_barycentrics() {
    let tri = [
        Vec3::ZERO,
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 4.0, 0.0),
    ];
    let front = hit32(tri, Vec3::new(1.0, 2.0, 3.0), -Vec3::Z).unwrap();
    let back = hit32(tri, Vec3::new(1.0, 2.0, -3.0), Vec3::Z).unwrap();
    assert_eq!(
        front,
        TriHit {
            t: 3.0,
            u: 0.25,
            v: 0.5
        }
    );
    assert_eq!(back, front);
    assert_eq!(triangle_normal(tri[0], tri[1], tri[2]), Vec3::Z);
    assert_eq!(triangle_area(tri[0], tri[1], tri[2]), 8.0);
}

#[test]
fn t_range_is_inclusive() {
    let tri = [
        Vec3::ZERO,
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 4.0, 0.0),
    ];
    let test = RayTriTest3f::new(&Ray3f::new(Vec3::new(1.0, 1.0, 2.0), -Vec3::Z));
    assert_eq!(
        test.hit(tri[0], tri[1], tri[2], 0.0, 2.0).map(|h| h.t),
        Some(2.0)
    );
    assert_eq!(
        test.hit(tri[0], tri[1], tri[2], 2.0, 3.0).map(|h| h.t),
        Some(2.0)
    );
    assert_eq!(test.hit(tri[0], tri[1], tri[2], 0.0, 1.99), None);
    assert_eq!(test.hit(tri[0], tri[1], tri[2], 2.01, 3.0), None);
    // A zero direction hits nothing.
    assert_eq!(
        RayTriTest3f::new(&Ray3f::new(Vec3::ZERO, Vec3::ZERO)).hit(
            tri[0],
            tri[1],
            tri[2],
            0.0,
            f32::INFINITY
        ),
        None
    );
}

proptest! {
    /// A part placed 1e7 from the world origin, rotated and scaled: the world ray
    /// taken to the local frame in f64 and then narrowed to f32 hits where it was
    /// aimed, with the same `t` as in the world.
    #[test]
    fn part_far_from_origin_is_hit_in_its_local_frame(
        tri in well_shaped_triangle(),
        bary in (0.05f64..0.9, 0.05f64..0.9).prop_filter("inside", |(a, b)| a + b < 0.95),
        axis in vec3(-1.0..1.0),
        angle in 0.0f64..6.3,
        scale in 0.5f64..4.0,
        from in vec3(-1.0..1.0),
    ) {
        let rotation = DQuat::from_axis_angle(axis.as_dvec3().try_normalize().unwrap_or(DVec3::Y), angle);
        let world = DAffine3::from_scale_rotation_translation(DVec3::new(scale, 1.0, 2.0), rotation, DVec3::new(1e7, -3e7, 2e7));
        let [v0, v1, v2] = tri.map(Vec3::as_dvec3);
        let local_target = v0 + bary.0 * (v1 - v0) + bary.1 * (v2 - v0);
        let normal = (v1 - v0).cross(v2 - v0).normalize();
        let local_origin = local_target + 20.0 * normal + 10.0 * from.as_dvec3();
        let (world_origin, world_target) = (world.transform_point3(local_origin), world.transform_point3(local_target));
        let ray = Ray3d::new(world_origin, (world_target - world_origin) * 0.5);
        let local = ray.to_local(&world);
        prop_assert!((local.origin - local_origin).length() < 1e-6);
        let hit = RayTriTest3f::new(&local.as_f32()).hit(tri[0], tri[1], tri[2], 0.0, f32::INFINITY);
        let hit = hit.ok_or_else(|| TestCaseError::fail("missed the part"))?;
        prop_assert!((f64::from(hit.t) - 2.0).abs() < 1e-4, "t {}", hit.t);
        prop_assert!((f64::from(hit.u) - bary.0).abs() < 1e-4 && (f64::from(hit.v) - bary.1).abs() < 1e-4);
        prop_assert!((ray.at(f64::from(hit.t)) - world_target).length() < 1e-2);
    }
}

proptest! {
    /// The nearest point of a triangle against brute force: no point of a
    /// fine barycentric grid over the triangle is nearer, and the answer lies
    /// in the triangle (its barycentric coordinates are within [0, 1]).
    #[test]
    fn the_nearest_point_of_a_triangle_beats_a_grid_of_its_points(
        v in prop::array::uniform3(prop::array::uniform3(-100.0f64..100.0)),
        p in prop::array::uniform3(-200.0f64..200.0),
    ) {
        let [a, b, c] = v.map(DVec3::from_array);
        let p = DVec3::from_array(p);
        let n = (b - a).cross(c - a);
        prop_assume!(n.length() > 1e-3 * (b - a).length() * (c - a).length());
        let q = closest_point_on_triangle(p, [a, b, c]);
        let d = q.distance(p);
        let steps = 60;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (u, w) = (f64::from(i) / f64::from(steps), f64::from(j) / f64::from(steps));
                let g = a + (b - a) * u + (c - a) * w;
                prop_assert!(d <= g.distance(p) + 1e-9 * (1.0 + d), "{q} at {d}, {g} nearer");
            }
        }
        // Barycentric coordinates of q.
        let (v0, v1, v2) = (b - a, c - a, q - a);
        let (d00, d01, d11, d20, d21) = (v0.dot(v0), v0.dot(v1), v1.dot(v1), v2.dot(v0), v2.dot(v1));
        let den = d00 * d11 - d01 * d01;
        let (bv, bw) = ((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den);
        let eps = 1e-9;
        prop_assert!(bv >= -eps && bw >= -eps && bv + bw <= 1.0 + eps, "({bv}, {bw})");
        prop_assert!((q - a).dot(n).abs() <= 1e-9 * n.length() * (1.0 + (q - a).length()));
    }
}
