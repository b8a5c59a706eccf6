//! Planes in world space, as half-space tests.

use glam::{DVec3, DVec4};

use crate::{Aabb3d, unit_vector};

/// The plane of points `p` with `normal · p + d = 0`; the side the normal points to
/// has positive signed distance. `normal` is unit length, except in
/// [`Plane::ACCEPT_ALL`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal (zero only in `ACCEPT_ALL`).
    pub normal: DVec3,
    /// Signed distance of the world origin from the plane.
    pub d: f64,
}

impl Plane {
    /// A pseudo-plane with every point at signed distance `1` on its positive side.
    /// It stands in for a plane that does not exist, such as the far plane of an
    /// infinite projection, so half-space tests need no special case.
    pub const ACCEPT_ALL: Plane = Plane {
        normal: DVec3::ZERO,
        d: 1.0,
    };

    /// The plane through `point` facing `normal` (any non-zero finite length,
    /// normalised by [`unit_vector`], so `[1e300, 0, 0]` and `[1e-320, 0, 0]`
    /// face `+X`).
    ///
    /// # Panics
    /// When `normal` is zero or not finite; [`Plane::try_from_point_normal`]
    /// answers `None` instead.
    pub fn from_point_normal(point: DVec3, normal: DVec3) -> Plane {
        Self::try_from_point_normal(point, normal)
            .expect("plane normal must be non-zero and finite, and the point finite")
    }

    /// The plane through `point` facing `normal`; `None` when `normal` is zero
    /// or anything is not finite, or the plane's offset overflows.
    pub fn try_from_point_normal(point: DVec3, normal: DVec3) -> Option<Plane> {
        let normal = unit_vector(normal)?;
        let d = -normal.dot(point);
        d.is_finite().then_some(Plane { normal, d })
    }

    /// The plane `n · p + d = 0` for `coefficients = (n, d)` of any scale, rescaled to
    /// a unit normal; `None` when `n` is zero or anything is not finite.
    pub fn normalized(coefficients: DVec4) -> Option<Plane> {
        let normal = coefficients.truncate();
        let inv_len = normal.length_recip();
        let plane = Plane {
            normal: normal * inv_len,
            d: coefficients.w * inv_len,
        };
        (plane.normal.is_finite() && plane.d.is_finite() && plane.normal != DVec3::ZERO)
            .then_some(plane)
    }

    /// Distance from the plane, positive on the side the normal points to.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) + self.d
    }

    /// True when all of `aabb` lies strictly on the negative side (its corner
    /// furthest along the normal, the p-vertex, is below the plane); the empty
    /// box counts as below. Frustum culling and section planes cull with it.
    pub fn excludes_aabb(&self, aabb: &Aabb3d) -> bool {
        let towards = self.normal.cmpge(DVec3::ZERO);
        aabb.is_empty() || self.signed_distance(DVec3::select(towards, aabb.max, aabb.min)) < 0.0
    }
}
