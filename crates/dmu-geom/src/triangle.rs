//! Watertight ray/triangle intersection (Woop, Benthin, Wald 2013, "Watertight
//! Ray/Triangle Intersection", JCGT 2(1)) and triangle measures.
//!
//! The ray is turned into the +z axis by a permutation and a shear, so every
//! triangle is tested in 2D by three edge functions. An edge shared by two triangles
//! is evaluated from the same projected vertices in both, with the operands swapped,
//! which rounds to exactly the negated value: a ray can never slip between them.

use glam::{DVec3, Vec3};

use crate::{Ray3d, Ray3f};

/// Where a ray meets a triangle: `ray.at(t)` equals `(1 - u - v) * v0 + u * v1 + v * v2`
/// (up to rounding), with `u, v >= 0` and `u + v <= 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit<S> {
    /// Ray parameter of the hit, in `[t_min, t_max]`.
    pub t: S,
    /// Barycentric weight of `v1`.
    pub u: S,
    /// Barycentric weight of `v2`.
    pub v: S,
}

macro_rules! ray_tri_impl {
    ($name:ident, $ray:ident, $vec:ty, $scalar:ty, $edge_exact:path, $is_degenerate:path) => {
        /// A ray prepared for watertight triangle tests: the axis permutation and
        /// shear are computed once per ray. Both faces are hit (no culling).
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct $name {
            origin: $vec,
            /// `[kx, ky, kz]`: `kz` is the dominant axis of the direction; `kx` and `ky`
            /// are swapped when it points backwards so the winding is kept.
            axes: [usize; 3],
            /// `(dir[kx] / dir[kz], dir[ky] / dir[kz], 1 / dir[kz])`.
            shear: $vec,
        }

        impl $name {
            /// Prepares `ray`. A zero direction is allowed and hits nothing.
            #[inline]
            pub fn new(ray: &$ray) -> Self {
                let kz = ray.dir.abs().max_position();
                let mut kx = (kz + 1) % 3;
                let mut ky = (kx + 1) % 3;
                if ray.dir[kz] < 0.0 {
                    std::mem::swap(&mut kx, &mut ky);
                }
                let dz = ray.dir[kz];
                Self {
                    origin: ray.origin,
                    axes: [kx, ky, kz],
                    shear: <$vec>::new(ray.dir[kx] / dz, ray.dir[ky] / dz, 1.0 / dz),
                }
            }

            /// The hit with triangle `(v0, v1, v2)` for `t` in `[t_min, t_max]`, either
            /// face. Triangles sharing an edge or a vertex leave no gap: a ray crossing
            /// a mesh there hits at least one of them. Degenerate (zero-area)
            /// triangles, rays in the triangle's plane that meet no area, and
            /// non-finite results give `None`; no NaN is ever returned.
            #[inline]
            pub fn hit(
                &self,
                v0: $vec,
                v1: $vec,
                v2: $vec,
                t_min: $scalar,
                t_max: $scalar,
            ) -> Option<TriHit<$scalar>> {
                let [kx, ky, kz] = self.axes;
                let a = v0 - self.origin;
                let b = v1 - self.origin;
                let c = v2 - self.origin;
                let (ax, ay) = (a[kx] - self.shear.x * a[kz], a[ky] - self.shear.y * a[kz]);
                let (bx, by) = (b[kx] - self.shear.x * b[kz], b[ky] - self.shear.y * b[kz]);
                let (cx, cy) = (c[kx] - self.shear.x * c[kz], c[ky] - self.shear.y * c[kz]);

                // Edge functions of (b, c), (c, a), (a, b): the unnormalized
                // barycentric weights of v0, v1, v2.
                let mut w0 = cx * by - cy * bx;
                let mut w1 = ax * cy - ay * cx;
                let mut w2 = bx * ay - by * ax;
                // A zero may be a rounded tiny value; its true sign decides which of
                // two neighbours owns the hit, so recompute exactly (the paper's
                // double-precision fallback).
                if w0 == 0.0 || w1 == 0.0 || w2 == 0.0 {
                    w0 = $edge_exact(cx, by, cy, bx);
                    w1 = $edge_exact(ax, cy, ay, cx);
                    w2 = $edge_exact(bx, ay, by, ax);
                }
                // Zero counts on both sides, so a ray exactly on an edge hits both
                // neighbours rather than neither.
                if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) && (w0 > 0.0 || w1 > 0.0 || w2 > 0.0) {
                    return None;
                }
                let det = w0 + w1 + w2;
                if det == 0.0 || !det.is_finite() {
                    return None;
                }
                let t_scaled = w0 * (self.shear.z * a[kz])
                    + w1 * (self.shear.z * b[kz])
                    + w2 * (self.shear.z * c[kz]);
                // Dividing rather than multiplying by `1 / det`: a subnormal `det`
                // would make the reciprocal infinite and `0 * inf` a NaN.
                let t = t_scaled / det;
                let in_range = t.is_finite() && (t_min..=t_max).contains(&t);
                // Exactly collinear vertices can still give a rounded non-zero `det`;
                // checked last, on the rare hit path only.
                if !in_range || $is_degenerate(v0, v1, v2) {
                    return None;
                }
                Some(TriHit {
                    t,
                    u: w1 / det,
                    v: w2 / det,
                })
            }
        }
    };
}

ray_tri_impl!(
    RayTriTest3f,
    Ray3f,
    Vec3,
    f32,
    edge_exact_f32,
    is_degenerate
);
ray_tri_impl!(
    RayTriTest3d,
    Ray3d,
    DVec3,
    f64,
    edge_exact_f64,
    is_degenerate_f64
);

/// `a * b - c * d` with the exact sign: f32 products are exact in f64, so only the
/// final difference rounds, and rounding keeps the sign.
fn edge_exact_f32(a: f32, b: f32, c: f32, d: f32) -> f32 {
    (f64::from(a) * f64::from(b) - f64::from(c) * f64::from(d)) as f32
}

/// `a * b - c * d` with the exact sign where no wider type exists: Kahan's
/// difference of products, whose relative error is at most two ulps.
fn edge_exact_f64(a: f64, b: f64, c: f64, d: f64) -> f64 {
    let cd = c * d;
    let cd_error = (-c).mul_add(d, cd);
    a.mul_add(b, -cd) + cd_error
}

/// The unnormalized normal `(v1 - v0) × (v2 - v0)` in f64. The edges of f32 vertices
/// are exact in f64, and products of equal reals round equal, so a truly degenerate
/// triangle gives exactly zero.
fn cross_f64(v0: Vec3, v1: Vec3, v2: Vec3) -> DVec3 {
    let (v0, v1, v2) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
    (v1 - v0).cross(v2 - v0)
}

fn is_degenerate_f64(v0: DVec3, v1: DVec3, v2: DVec3) -> bool {
    (v1 - v0).cross(v2 - v0) == DVec3::ZERO
}

/// True when the triangle has zero area: coincident or collinear vertices. Exact for
/// f32 vertices (computed in f64); such a triangle is never hit.
pub fn is_degenerate(v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
    cross_f64(v0, v1, v2) == DVec3::ZERO
}

/// Unit normal of the front face (counter-clockwise `v0, v1, v2`); zero for a
/// degenerate triangle. Computed in f64 so slivers keep an accurate direction.
pub fn triangle_normal(v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    cross_f64(v0, v1, v2).normalize_or_zero().as_vec3()
}

/// Area of the triangle; zero for a degenerate one. Computed in f64.
pub fn triangle_area(v0: Vec3, v1: Vec3, v2: Vec3) -> f32 {
    (0.5 * cross_f64(v0, v1, v2).length()) as f32
}

/// The point of triangle `[a, b, c]` nearest to `p` (Ericson, Real-Time
/// Collision Detection 5.1.5: by the Voronoi region of `p`). For a triangle
/// with area; a degenerate one gives a point of one of its edges' lines.
pub fn closest_point_on_triangle(p: DVec3, [a, b, c]: [DVec3; 3]) -> DVec3 {
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
