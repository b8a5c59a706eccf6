//! Two triangles in f64: distance with closest points, and whether they
//! penetrate. Every clash the crate reports comes down to these functions, on
//! part-local f32 vertices carried into a common frame in f64.

use std::cell::Cell;

use glam::DVec3;

/// How two triangles meet, from [`triangle_clash`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleClash {
    /// Euclidean distance between the triangles; 0 when they intersect.
    pub distance: f64,
    /// Closest point on the first triangle.
    pub point_a: DVec3,
    /// Closest point on the second triangle.
    pub point_b: DVec3,
    /// Unit direction in which to move the second triangle away from the first:
    /// along the closest points when they are apart, otherwise the axis of least
    /// penetration (for touching coplanar faces, the first triangle's normal).
    pub normal: DVec3,
    /// The triangles penetrate beyond the contact tolerance (see [`triangle_clash`]).
    pub penetrating: bool,
}

/// Distance and closest points of two triangles (degenerate ones included).
///
/// Exact up to f64 rounding: an edge of one crossing the other's interior gives
/// distance 0 at the crossing point; otherwise the closest pair is a vertex
/// against a triangle or an edge against an edge.
pub fn triangle_distance(a: &[DVec3; 3], b: &[DVec3; 3]) -> (f64, DVec3, DVec3) {
    distance_between(a, b, unit_normal(a).is_some(), unit_normal(b).is_some())
}

/// [`triangle_distance`] for triangles whose non-degeneracy (`unit_normal` is
/// `Some`) the caller knows already.
fn distance_between(
    a: &[DVec3; 3],
    b: &[DVec3; 3],
    a_has_normal: bool,
    b_has_normal: bool,
) -> (f64, DVec3, DVec3) {
    if let Some(x) = edges_cross(a, b).or_else(|| edges_cross(b, a)) {
        return (0.0, x, x);
    }
    let mut best = (f64::INFINITY, a[0], b[0]);
    let consider = |best: &mut (f64, DVec3, DVec3), pa: DVec3, pb: DVec3| {
        let d2 = pa.distance_squared(pb);
        if d2 < best.0 {
            *best = (d2, pa, pb);
        }
    };
    // A candidate whose boxes are farther apart than the best so far cannot
    // beat it (with a margin far above the rounding of the closest points, so
    // the answer is the one every candidate would give).
    let span = |p: &[DVec3]| {
        let (lo, hi) = p
            .iter()
            .fold((p[0], p[0]), |(lo, hi), q| (lo.min(*q), hi.max(*q)));
        (lo, hi)
    };
    let may_beat = |best: f64, (lo1, hi1): (DVec3, DVec3), (lo2, hi2): (DVec3, DVec3)| {
        let gap = (lo2 - hi1).max(lo1 - hi2).max(DVec3::ZERO).length_squared();
        gap <= best * (1.0 + 1e-9)
    };
    let (box_a, box_b) = (span(a), span(b));
    for &p in a {
        if may_beat(best.0, (p, p), box_b) {
            consider(&mut best, p, closest_on_triangle(p, b, b_has_normal));
        }
    }
    for &p in b {
        if may_beat(best.0, box_a, (p, p)) {
            consider(&mut best, closest_on_triangle(p, a, a_has_normal), p);
        }
    }
    for i in 0..3 {
        let ea = [a[i], a[(i + 1) % 3]];
        for j in 0..3 {
            let eb = [b[j], b[(j + 1) % 3]];
            if may_beat(best.0, span(&ea), span(&eb)) {
                let (pa, pb) = closest_on_segments(ea[0], ea[1], eb[0], eb[1]);
                consider(&mut best, pa, pb);
            }
        }
    }
    (best.0.sqrt(), best.1, best.2)
}

/// The crate's classification at the level of two triangles: `None` when they
/// are farther apart than `max_distance`, otherwise their distance, closest
/// points and whether they penetrate.
///
/// Triangles within `tolerance` of each other *penetrate* when either
/// - they cannot be separated by a translation shorter than `tolerance`
///   (separating-axis depth over the two normals and the nine edge-pair
///   directions), i.e. they cross by more than the tolerance; or
/// - they are coplanar within `tolerance`, face the same way (their winding
///   normals agree) and their interiors overlap by more than `tolerance`: the
///   coincident faces of two closed, outward-facing solids lying on the same
///   side, so the solids overlap there.
///
/// Otherwise they *touch*: coplanar faces facing each other, an edge resting on
/// a face, crossings shallower than the tolerance (rounding noise).
pub fn triangle_clash(
    a: &[DVec3; 3],
    b: &[DVec3; 3],
    tolerance: f64,
    max_distance: f64,
) -> Option<TriangleClash> {
    let (a, b) = (Placed::new(*a), Placed::new(*b));
    placed_clash(&a, &b, tolerance, max_distance)
}

/// A triangle in the frame of a comparison with what [`triangle_clash`] needs
/// of it alone: its box, and its unit normal once a pair gets past the boxes,
/// computed once for all the triangles it meets.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Placed {
    pub v: [DVec3; 3],
    /// See [`unit_normal`]; `None` until first asked for.
    normal: Cell<Option<Option<DVec3>>>,
    pub min: DVec3,
    pub max: DVec3,
}

impl Placed {
    pub fn new(v: [DVec3; 3]) -> Self {
        Self {
            v,
            normal: Cell::new(None),
            min: v[0].min(v[1]).min(v[2]),
            max: v[0].max(v[1]).max(v[2]),
        }
    }

    /// See [`unit_normal`].
    pub fn normal(&self) -> Option<DVec3> {
        if let Some(n) = self.normal.get() {
            return n;
        }
        let n = unit_normal(&self.v);
        self.normal.set(Some(n));
        n
    }

    /// Squared gap between the two triangles' boxes (0 when they overlap).
    pub fn box_gap_squared(&self, other: &Self) -> f64 {
        (other.min - self.max)
            .max(self.min - other.max)
            .max(DVec3::ZERO)
            .length_squared()
    }
}

/// [`triangle_clash`] of placed triangles.
pub(crate) fn placed_clash(
    a: &Placed,
    b: &Placed,
    tolerance: f64,
    max_distance: f64,
) -> Option<TriangleClash> {
    let facing = Facing::of(a, b, max_distance)?;
    facing.clash(&a.v, &b.v, tolerance, max_distance)
}

/// [`triangle_clash`] with `max_distance` equal to `tolerance`, when only a
/// penetrating result matters (the search already holds a pair at distance 0,
/// which no touching pair can beat): `Some` exactly when that call would say
/// `penetrating`, with the same result. Most touching pairs are settled without
/// the distance computation: faces lying flat on each other and facing each
/// other (a part resting on a floor) cannot penetrate, and neither can a pair
/// whose separating-axis depth is within the tolerance unless they are
/// coplanar faces facing the same way.
pub(crate) fn triangle_penetration(
    a: &Placed,
    b: &Placed,
    tolerance: f64,
) -> Option<TriangleClash> {
    let facing = Facing::of(a, b, tolerance)?;
    let (a, b) = (&a.v, &b.v);
    let within =
        |s: Option<[f64; 3]>, limit: f64| s.is_some_and(|s| s.iter().all(|d| d.abs() <= limit));
    let flat = |limit| within(facing.side_a, limit) && within(facing.side_b, limit);
    let same_way = match (facing.na, facing.nb) {
        (Some(na), Some(nb)) => na.dot(nb) > 0.0,
        _ => false,
    };
    // Flat on each other well inside the tolerance and facing each other: the
    // separating-axis depth along the first normal is at most half the
    // tolerance (plus rounding far below it), so `clash` finds no penetration.
    if flat(0.5 * tolerance) && !same_way {
        return None;
    }
    let mut separable = false;
    separating_axes(a, b, facing.na, facing.nb, |depth, _| {
        separable = depth <= tolerance;
        separable // stop at the first axis that separates within the tolerance
    });
    if separable && !(flat(tolerance) && same_way) {
        return None;
    }
    facing
        .clash(a, b, tolerance, tolerance)
        .filter(|c| c.penetrating)
}

/// Two triangles that passed the cheap rejections: their unit normals (`None`
/// when degenerate) and each one's vertices' signed distances from the other's
/// plane.
struct Facing {
    na: Option<DVec3>,
    nb: Option<DVec3>,
    side_a: Option<[f64; 3]>,
    side_b: Option<[f64; 3]>,
}

impl Facing {
    /// `None` when the triangles' boxes, or one triangle and the other's plane,
    /// are farther apart than `max_distance`: most pairs a BVH hands over.
    fn of(a: &Placed, b: &Placed, max_distance: f64) -> Option<Self> {
        if a.box_gap_squared(b) > max_distance * max_distance {
            return None;
        }
        let (na, nb) = (a.normal(), b.normal());
        let (a, b) = (&a.v, &b.v);
        let side_a = nb.map(|n| a.map(|p| n.dot(p - b[0])));
        let side_b = na.map(|n| b.map(|p| n.dot(p - a[0])));
        let beyond = |s: &[f64; 3]| {
            s.iter().all(|&d| d > max_distance) || s.iter().all(|&d| d < -max_distance)
        };
        if side_a.as_ref().is_some_and(beyond) || side_b.as_ref().is_some_and(beyond) {
            return None;
        }
        Some(Self {
            na,
            nb,
            side_a,
            side_b,
        })
    }

    /// The rest of [`triangle_clash`].
    fn clash(
        &self,
        a: &[DVec3; 3],
        b: &[DVec3; 3],
        tolerance: f64,
        max_distance: f64,
    ) -> Option<TriangleClash> {
        let Self {
            na,
            nb,
            side_a,
            side_b,
        } = *self;
        let (distance, point_a, point_b) = distance_between(a, b, na.is_some(), nb.is_some());
        if distance > max_distance {
            return None;
        }
        let mut clash = TriangleClash {
            distance,
            point_a,
            point_b,
            normal: (point_b - point_a) / distance,
            penetrating: false,
        };
        if distance > tolerance {
            return Some(clash);
        }
        let (depth, axis) = penetration_depth(a, b, na, nb);
        clash.normal = axis;
        clash.penetrating = depth > tolerance;
        if !clash.penetrating
            && let (Some(na), Some(nb), Some(sa), Some(sb)) = (na, nb, side_a, side_b)
        {
            let flat = |s: [f64; 3]| s.iter().all(|d| d.abs() <= tolerance);
            if flat(sa) && flat(sb) {
                clash.normal = na;
                clash.penetrating = na.dot(nb) > 0.0 && coplanar_overlap(a, b, na) > tolerance;
            }
        }
        Some(clash)
    }
}

/// The unit normal by the winding, `None` for a degenerate triangle.
fn unit_normal(t: &[DVec3; 3]) -> Option<DVec3> {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let scale = (t[1] - t[0])
        .length_squared()
        .max((t[2] - t[0]).length_squared())
        .max((t[2] - t[1]).length_squared());
    // Zero area, or so thin that the normal is rounding noise.
    (n.length_squared() > 1e-24 * scale * scale).then(|| n.normalize())
}

/// A point where an edge of `a` passes strictly through the plane of `b` inside
/// `b` (boundary included). Every transversal intersection of two triangles has
/// such a point: its segment ends on an edge of one of them.
fn edges_cross(a: &[DVec3; 3], b: &[DVec3; 3]) -> Option<DVec3> {
    let n = (b[1] - b[0]).cross(b[2] - b[0]);
    if n == DVec3::ZERO {
        return None;
    }
    let s = a.map(|p| n.dot(p - b[0]));
    (0..3).find_map(|i| {
        let j = (i + 1) % 3;
        if !((s[i] > 0.0 && s[j] < 0.0) || (s[i] < 0.0 && s[j] > 0.0)) {
            return None;
        }
        let x = a[i] + (a[j] - a[i]) * (s[i] / (s[i] - s[j]));
        let inside = (0..3).all(|k| {
            let (p, q) = (b[k], b[(k + 1) % 3]);
            (q - p).cross(x - p).dot(n) >= 0.0
        });
        inside.then_some(x)
    })
}

/// Separating-axis penetration depth of two triangles that meet: the shortest
/// translation of `b` that separates them, over the normals and the edge-pair
/// directions, with the axis (pointing the way `b` should move). For coplanar
/// triangles this is 0 along their common normal.
fn penetration_depth(
    a: &[DVec3; 3],
    b: &[DVec3; 3],
    na: Option<DVec3>,
    nb: Option<DVec3>,
) -> (f64, DVec3) {
    let mut best = (f64::INFINITY, na.or(nb).unwrap_or(DVec3::Z));
    separating_axes(a, b, na, nb, |depth, u| {
        if depth < best.0 {
            best = (depth, u);
        }
        false
    });
    best
}

/// Calls `visit(depth, axis)` for each candidate separating axis of two
/// triangles (the normals, then the edge-pair directions) with the overlap of
/// their projections on it and the unit axis pointing the way `b` should move,
/// until `visit` returns true.
fn separating_axes(
    a: &[DVec3; 3],
    b: &[DVec3; 3],
    na: Option<DVec3>,
    nb: Option<DVec3>,
    mut visit: impl FnMut(f64, DVec3) -> bool,
) {
    let mut axis = |u: DVec3| {
        let pa = a.map(|p| u.dot(p));
        let pb = b.map(|p| u.dot(p));
        let (amin, amax) = (pa[0].min(pa[1]).min(pa[2]), pa[0].max(pa[1]).max(pa[2]));
        let (bmin, bmax) = (pb[0].min(pb[1]).min(pb[2]), pb[0].max(pb[1]).max(pb[2]));
        let (up, down) = (amax - bmin, bmax - amin);
        visit(up.min(down), if up <= down { u } else { -u })
    };
    for n in [na, nb].into_iter().flatten() {
        if axis(n) {
            return;
        }
    }
    for i in 0..3 {
        let ea = a[(i + 1) % 3] - a[i];
        for j in 0..3 {
            let eb = b[(j + 1) % 3] - b[j];
            let c = ea.cross(eb);
            // Parallel edges give no axis of their own.
            if c.length_squared() > 1e-24 * ea.length_squared() * eb.length_squared()
                && axis(c.normalize())
            {
                return;
            }
        }
    }
}

/// How far the interiors of two coplanar triangles overlap: the smallest overlap
/// of their projections on the in-plane edge normals (≤ 0 when apart or only
/// touching along an edge or at a vertex).
fn coplanar_overlap(a: &[DVec3; 3], b: &[DVec3; 3], n: DVec3) -> f64 {
    let mut overlap = f64::INFINITY;
    for t in [a, b] {
        for i in 0..3 {
            let u = n.cross(t[(i + 1) % 3] - t[i]);
            if u.length_squared() == 0.0 {
                continue;
            }
            let u = u.normalize();
            let pa = a.map(|p| u.dot(p));
            let pb = b.map(|p| u.dot(p));
            let lo = pa[0].min(pa[1]).min(pa[2]).max(pb[0].min(pb[1]).min(pb[2]));
            let hi = pa[0].max(pa[1]).max(pa[2]).min(pb[0].max(pb[1]).max(pb[2]));
            overlap = overlap.min(hi - lo);
        }
    }
    overlap
}

/// The point of triangle `t` nearest to `p`
/// ([`dmu_geom::closest_point_on_triangle`]); degenerate triangles
/// (`has_normal` false: see [`unit_normal`]) fall back to their edges.
fn closest_on_triangle(p: DVec3, t: &[DVec3; 3], has_normal: bool) -> DVec3 {
    let [a, b, c] = *t;
    if !has_normal {
        return [(a, b), (b, c), (c, a)]
            .map(|(s, e)| closest_on_segment(p, s, e))
            .into_iter()
            .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
            .unwrap_or(a);
    }
    dmu_geom::closest_point_on_triangle(p, [a, b, c])
}

/// The point of segment `s..e` nearest to `p`.
fn closest_on_segment(p: DVec3, s: DVec3, e: DVec3) -> DVec3 {
    let d = e - s;
    let len2 = d.length_squared();
    if len2 == 0.0 {
        return s;
    }
    s + d * ((p - s).dot(d) / len2).clamp(0.0, 1.0)
}

/// Closest points of segments `p1..q1` and `p2..q2` (Ericson 5.1.9), zero-length
/// and parallel segments included.
fn closest_on_segments(p1: DVec3, q1: DVec3, p2: DVec3, q2: DVec3) -> (DVec3, DVec3) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    let (s, t) = if a == 0.0 && e == 0.0 {
        (0.0, 0.0)
    } else if a == 0.0 {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(r);
        if e == 0.0 {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            // Parallel segments: any s works, t follows from it.
            let s = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t = (b * s + f) / e;
            if t < 0.0 {
                ((-c / a).clamp(0.0, 1.0), 0.0)
            } else if t > 1.0 {
                (((b - c) / a).clamp(0.0, 1.0), 1.0)
            } else {
                (s, t)
            }
        }
    };
    (p1 + d1 * s, p2 + d2 * t)
}

#[cfg(test)]
mod tests {
    use dmu_samples::Rng;
    use glam::{DQuat, DVec3};

    use super::{Placed, triangle_clash, triangle_penetration};

    fn random_triangle(rng: &mut Rng, size: f64) -> [DVec3; 3] {
        [(); 3].map(|_| DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0) * size)
    }

    /// The penetration-only test answers exactly as the full one on pairs where
    /// its shortcuts apply and where they must not: faces flat on each other
    /// facing either way, offset within and beyond the tolerance, tilted a
    /// little or a lot, crossing, degenerate, far from the origin.
    #[test]
    fn penetration_only_equals_the_full_test_filtered() {
        let mut rng = Rng::new(18);
        let mut penetrating = 0;
        for i in 0..200_000 {
            let tolerance = [1e-6, 1e-3, 0.1][i % 3];
            let size = [1.0, 100.0][i / 3 % 2];
            let a = random_triangle(&mut rng, size);
            let mut b = random_triangle(&mut rng, size);
            if rng.chance(0.5) {
                b.swap(1, 2); // the other way up
            }
            if rng.chance(0.1) {
                b[2] = b[0].lerp(b[1], 0.5); // degenerate
            }
            let tilt = [0.0, 1e-9, 1e-4, 0.3, 1.5][rng.below(5) as usize];
            let turn = DQuat::from_axis_angle(
                DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0).normalize_or(DVec3::X),
                tilt,
            );
            let lift = tolerance * [0.0, 0.3, 0.5, 0.9, 1.0, 1.1, 3.0][rng.below(7) as usize];
            let offset = DVec3::new(0.0, 0.0, if rng.chance(0.5) { lift } else { -lift })
                + if rng.chance(0.3) {
                    DVec3::splat(1e7)
                } else {
                    DVec3::ZERO
                };
            let (a, b) = (
                a.map(|p| p + offset.with_z(0.0)),
                b.map(|p| turn * p + offset),
            );
            let full = triangle_clash(&a, &b, tolerance, tolerance).filter(|c| c.penetrating);
            let placed = triangle_penetration(&Placed::new(a), &Placed::new(b), tolerance);
            assert_eq!(placed, full, "case {i}: {a:?} {b:?}");
            penetrating += usize::from(full.is_some());
        }
        // Both answers occur often (the test cannot pass by always saying no).
        assert!(penetrating > 10_000, "{penetrating}");
    }
}
