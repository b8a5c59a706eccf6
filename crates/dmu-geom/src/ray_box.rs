//! Ray against axis-aligned box: the slab test, made total for zero direction
//! components and conservative under rounding.

use glam::{DVec3, Vec3};

use crate::{Aabb3d, Aabb3f, Ray3d, Ray3f};

macro_rules! ray_box_impl {
    ($name:ident, $ray:ident, $aabb:ident, $vec:ty, $scalar:ty) => {
        /// A ray prepared for many slab tests (one per BVH node): the reciprocal of the
        /// direction is computed once.
        ///
        /// A zero direction component gives a reciprocal of `±inf`; when the origin
        /// lies exactly on that axis' slab plane the slab distance is `0 * inf = NaN`.
        /// The test compares so that a NaN never narrows the interval, which makes
        /// that axis unconstrained: a ray running inside a face plane hits the box.
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct $name {
            origin: $vec,
            inv_dir: $vec,
        }

        impl $name {
            /// Rounding of the reciprocal, subtraction and product each move a slab
            /// distance by at most one ulp; widening the exit distance by `1 + 2γ₃`
            /// (Ize 2013, "Robust BVH Ray Traversal") keeps a box from being
            /// missed by a ray that truly touches it, at the cost of accepting rays
            /// that miss by that relative margin.
            const EXIT_SLACK: $scalar = {
                let unit_roundoff = <$scalar>::EPSILON * 0.5;
                let gamma3 = 3.0 * unit_roundoff / (1.0 - 3.0 * unit_roundoff);
                1.0 + 2.0 * gamma3
            };

            /// Prepares `ray` for slab tests.
            #[inline]
            pub fn new(ray: &$ray) -> Self {
                Self {
                    origin: ray.origin,
                    inv_dir: ray.dir.recip(),
                }
            }

            /// The parameter interval `(t_enter, t_exit)` where the ray is inside
            /// `aabb`, clipped to `[0, t_max]`; `None` when it misses. Boundaries count
            /// as inside: touching a face, an edge or a zero-extent box is a hit, with
            /// `t_enter == t_exit` possible. An origin inside the box gives
            /// `t_enter = 0`. The `EMPTY` box is never hit.
            #[inline]
            pub fn hit(&self, aabb: &$aabb, t_max: $scalar) -> Option<($scalar, $scalar)> {
                let mut t_enter: $scalar = 0.0;
                let mut t_exit = t_max;
                for axis in 0..3 {
                    let inv = self.inv_dir[axis];
                    let origin = self.origin[axis];
                    // Choosing the near plane by the sign of the reciprocal (not by
                    // min/max of both distances) keeps each NaN on its own side.
                    let (near_plane, far_plane) = if inv.is_sign_negative() {
                        (aabb.max[axis], aabb.min[axis])
                    } else {
                        (aabb.min[axis], aabb.max[axis])
                    };
                    let near = (near_plane - origin) * inv;
                    let far = (far_plane - origin) * inv * Self::EXIT_SLACK;
                    // Written as comparisons, not `max`/`min`, so a NaN visibly fails
                    // them and leaves the interval as it was.
                    if near > t_enter {
                        t_enter = near;
                    }
                    if far < t_exit {
                        t_exit = far;
                    }
                }
                // `t_enter = inf` means a parallel ray outside some slab (with
                // `t_max = inf` the interval would otherwise look non-empty).
                (t_enter <= t_exit && t_enter < <$scalar>::INFINITY).then_some((t_enter, t_exit))
            }
        }
    };
}

ray_box_impl!(RayBoxTest3d, Ray3d, Aabb3d, DVec3, f64);
ray_box_impl!(RayBoxTest3f, Ray3f, Aabb3f, Vec3, f32);
