//! Two triangles in f64: distance with closest points, and whether they
//! penetrate. Every clash the crate reports comes down to these functions, on
//! part-local f32 vertices carried into a common frame in f64.

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
    if let Some(x) = edges_cross(a, b).or_else(|| edges_cross(b, a)) {
        return (0.0, x, x);
    }
    let mut best = (f64::INFINITY, a[0], b[0]);
    let mut consider = |pa: DVec3, pb: DVec3| {
        let d2 = pa.distance_squared(pb);
        if d2 < best.0 {
            best = (d2, pa, pb);
        }
    };
    for &p in a {
        consider(p, closest_on_triangle(p, b));
    }
    for &p in b {
        consider(closest_on_triangle(p, a), p);
    }
    for i in 0..3 {
        for j in 0..3 {
            let (pa, pb) = closest_on_segments(a[i], a[(i + 1) % 3], b[j], b[(j + 1) % 3]);
            consider(pa, pb);
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
    // Cheap rejections first: most pairs a BVH hands over are not close.
    if box_gap_squared(a, b) > max_distance * max_distance {
        return None;
    }
    let na = unit_normal(a);
    let nb = unit_normal(b);
    let side_a = nb.map(|n| a.map(|p| n.dot(p - b[0])));
    let side_b = na.map(|n| b.map(|p| n.dot(p - a[0])));
    let beyond =
        |s: &[f64; 3]| s.iter().all(|&d| d > max_distance) || s.iter().all(|&d| d < -max_distance);
    if side_a.as_ref().is_some_and(beyond) || side_b.as_ref().is_some_and(beyond) {
        return None;
    }
    let (distance, point_a, point_b) = triangle_distance(a, b);
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

/// Squared gap between the triangles' boxes (0 when they overlap).
fn box_gap_squared(a: &[DVec3; 3], b: &[DVec3; 3]) -> f64 {
    let (amin, amax) = (a[0].min(a[1]).min(a[2]), a[0].max(a[1]).max(a[2]));
    let (bmin, bmax) = (b[0].min(b[1]).min(b[2]), b[0].max(b[1]).max(b[2]));
    (bmin - amax)
        .max(amin - bmax)
        .max(DVec3::ZERO)
        .length_squared()
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
    let mut axis = |u: DVec3| {
        let pa = a.map(|p| u.dot(p));
        let pb = b.map(|p| u.dot(p));
        let (amin, amax) = (pa[0].min(pa[1]).min(pa[2]), pa[0].max(pa[1]).max(pa[2]));
        let (bmin, bmax) = (pb[0].min(pb[1]).min(pb[2]), pb[0].max(pb[1]).max(pb[2]));
        let (up, down) = (amax - bmin, bmax - amin);
        let depth = up.min(down);
        if depth < best.0 {
            best = (depth, if up <= down { u } else { -u });
        }
    };
    na.into_iter().chain(nb).for_each(&mut axis);
    for i in 0..3 {
        let ea = a[(i + 1) % 3] - a[i];
        for j in 0..3 {
            let eb = b[(j + 1) % 3] - b[j];
            let c = ea.cross(eb);
            // Parallel edges give no axis of their own.
            if c.length_squared() > 1e-24 * ea.length_squared() * eb.length_squared() {
                axis(c.normalize());
            }
        }
    }
    best
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

/// The point of triangle `t` nearest to `p` (Ericson, Real-Time Collision
/// Detection 5.1.5); degenerate triangles fall back to their edges.
fn closest_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    if unit_normal(t).is_none() {
        return [(a, b), (b, c), (c, a)]
            .map(|(s, e)| closest_on_segment(p, s, e))
            .into_iter()
            .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
            .unwrap_or(a);
    }
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
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
