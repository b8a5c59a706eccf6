//! Rays: `Ray3d` in world space, `Ray3f` in a part's local frame.

use glam::{DAffine3, DVec3, Vec3};

macro_rules! ray_impl {
    ($name:ident, $vec:ty, $scalar:ty) => {
        /// A half-line `origin + t * dir` for `t >= 0`. `dir` need not be unit length:
        /// rays carried into a scaled local frame keep their parameter `t`, so hits from
        /// different frames compare directly.
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct $name {
            /// Start point, `t = 0`.
            pub origin: $vec,
            /// Direction; any length, zero components allowed.
            pub dir: $vec,
        }

        impl $name {
            /// A ray from its origin and direction (not normalized).
            pub const fn new(origin: $vec, dir: $vec) -> Self {
                Self { origin, dir }
            }

            /// The point at parameter `t`.
            pub fn at(&self, t: $scalar) -> $vec {
                self.origin + self.dir * t
            }
        }
    };
}

ray_impl!(Ray3d, DVec3, f64);
ray_impl!(Ray3f, Vec3, f32);

impl Ray3d {
    /// This ray under an affine transform: the origin as a point, the direction as a
    /// vector, unnormalized so that `t` means the same point before and after.
    #[must_use]
    pub fn transformed(&self, m: &DAffine3) -> Ray3d {
        Ray3d {
            origin: m.transform_point3(self.origin),
            dir: m.transform_vector3(self.dir),
        }
    }

    /// This world ray in the local frame of a part placed by `world` (local to world).
    /// The parameter `t` is the same in both frames. Callers holding the inverse
    /// already should use [`Ray3d::transformed`] with it.
    #[must_use]
    pub fn to_local(&self, world: &DAffine3) -> Ray3d {
        self.transformed(&world.inverse())
    }

    /// This ray narrowed to f32, for testing against part-local geometry. Take it to
    /// the local frame first: far from the world origin f32 has no precision left.
    pub fn as_f32(&self) -> Ray3f {
        Ray3f {
            origin: self.origin.as_vec3(),
            dir: self.dir.as_vec3(),
        }
    }
}
