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
    /// A ray whose direction is safe to square: unchanged when its largest
    /// component lies in `[2^-500, 2^500]` (any direction a person or a camera
    /// makes), otherwise scaled by an exact power of two into `[1, 2)` (the
    /// point hit is the same; `t` scales by that power). `None` when the origin
    /// or direction is not finite or the direction is zero. A direction of
    /// 1e-300 or 1e160 would otherwise underflow or overflow in the squares and
    /// reciprocals of the ray tests and distances.
    pub fn with_safe_dir(origin: DVec3, dir: DVec3) -> Option<Ray3d> {
        const SAFE: f64 = 3.273_390_607_896_142e150; // 2^500
        if !(origin.is_finite() && dir.is_finite()) {
            return None;
        }
        let largest = dir.abs().max_element();
        if largest == 0.0 {
            return None;
        }
        if (1.0 / SAFE..=SAFE).contains(&largest) {
            return Some(Ray3d { origin, dir });
        }
        // floor(log2) from the bits (log2 rounds f64::MAX up to 1024); scaled in
        // two halves, as 2^1074 (for the smallest subnormal) is not an f64.
        let bits = largest.to_bits();
        let exponent = match (bits >> 52) as i32 {
            0 => -1074 + 63 - bits.leading_zeros() as i32,
            biased => biased - 1023,
        };
        let k = -exponent;
        let dir = dir * 2f64.powi(k / 2) * 2f64.powi(k - k / 2);
        Some(Ray3d { origin, dir })
    }

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
