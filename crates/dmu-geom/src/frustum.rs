//! View frustum culling for reverse-Z cameras.

use glam::{DMat4, DVec3};

use crate::{Aabb3d, Plane};

/// How a box lies relative to a frustum.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Containment {
    /// Entirely outside one plane: invisible.
    Outside,
    /// Crosses at least one plane, or lies outside the frustum near a corner or an
    /// edge (the test is conservative there).
    Intersecting,
    /// Entirely inside every plane.
    Inside,
}

/// The six half-spaces of a camera, normals pointing into the frustum, in the order
/// left, right, bottom, top, near, far. A point is inside when its signed distance is
/// `>= 0` to every plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// Left, right, bottom, top, near, far. The far plane of an infinite projection
    /// is [`Plane::ACCEPT_ALL`].
    pub planes: [Plane; 6],
}

impl Frustum {
    /// The frustum of a world-to-clip matrix with reverse-Z depth in `[0, 1]`
    /// (wgpu clip space, depth 1 at the near plane, 0 at the far plane), by
    /// Gribb and Hartmann's row combinations: a point is inside when its clip
    /// coordinates satisfy `|x| <= w`, `|y| <= w` and `0 <= z <= w`.
    ///
    /// An infinite far plane has clip `z` constant, so its row has a zero normal;
    /// that plane, and any other that cannot be normalized (a non-finite matrix),
    /// becomes [`Plane::ACCEPT_ALL`], which only makes culling less eager, never wrong.
    pub fn from_view_proj_reverse_z(m: &DMat4) -> Frustum {
        debug_assert!(m.is_finite(), "view-projection matrix must be finite: {m}");
        let (x, y, z, w) = (m.row(0), m.row(1), m.row(2), m.row(3));
        let plane = |coefficients| Plane::normalized(coefficients).unwrap_or(Plane::ACCEPT_ALL);
        Frustum {
            planes: [w + x, w - x, w + y, w - y, w - z, z].map(plane),
        }
    }

    /// True when `p` is inside or on the boundary.
    pub fn contains_point(&self, p: DVec3) -> bool {
        self.planes
            .iter()
            .all(|plane| plane.signed_distance(p) >= 0.0)
    }

    /// Classifies `aabb` with the p-vertex/n-vertex test: per plane, only the corner
    /// furthest along the normal (p) and the one furthest against it (n) matter.
    /// `Outside` is exact for the planes (all eight corners outside one of them);
    /// a box outside only near a frustum edge is reported `Intersecting`. The empty
    /// box is `Outside`.
    pub fn test_aabb(&self, aabb: &Aabb3d) -> Containment {
        if aabb.is_empty() {
            return Containment::Outside;
        }
        let mut result = Containment::Inside;
        for plane in &self.planes {
            if plane.excludes_aabb(aabb) {
                return Containment::Outside;
            }
            let towards = plane.normal.cmpge(DVec3::ZERO);
            if plane.signed_distance(DVec3::select(towards, aabb.min, aabb.max)) < 0.0 {
                result = Containment::Intersecting;
            }
        }
        result
    }

    /// True unless `aabb` is [`Containment::Outside`]; cheaper than
    /// [`Frustum::test_aabb`] as it checks only the p-vertices.
    pub fn intersects_aabb(&self, aabb: &Aabb3d) -> bool {
        !aabb.is_empty() && !self.planes.iter().any(|plane| plane.excludes_aabb(aabb))
    }
}
