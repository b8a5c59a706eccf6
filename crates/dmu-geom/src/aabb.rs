//! Axis-aligned bounding boxes: `Aabb3f` for part-local geometry, `Aabb3d` for world space.

use glam::{DAffine3, DVec3, Vec3};
use serde::{Deserialize, Serialize};

macro_rules! aabb_impl {
    ($name:ident, $vec:ty, $scalar:ty) => {
        /// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`, so that
        /// growing it by any point gives that point's zero-extent box. A zero-extent box
        /// (`min == max` on some axis) is valid and not empty.
        #[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
        pub struct $name {
            /// Smallest corner; `min[i] <= max[i]` on every axis unless the box is empty.
            pub min: $vec,
            /// Largest corner.
            pub max: $vec,
        }

        impl Default for $name {
            fn default() -> Self {
                Self::EMPTY
            }
        }

        impl $name {
            /// The box that contains nothing; the identity of `union`.
            pub const EMPTY: Self = Self {
                min: <$vec>::splat(<$scalar>::INFINITY),
                max: <$vec>::splat(<$scalar>::NEG_INFINITY),
            };

            /// A box from its corners (not reordered).
            pub const fn new(min: $vec, max: $vec) -> Self {
                Self { min, max }
            }

            /// The smallest box holding every point; `EMPTY` for no points.
            pub fn from_points(points: impl IntoIterator<Item = $vec>) -> Self {
                points.into_iter().fold(Self::EMPTY, |b, p| b.grown(p))
            }

            /// True when the box holds no point (any `min > max`).
            pub fn is_empty(&self) -> bool {
                self.min.cmpgt(self.max).any()
            }

            /// This box grown to hold `p`.
            #[must_use]
            pub fn grown(self, p: $vec) -> Self {
                Self {
                    min: self.min.min(p),
                    max: self.max.max(p),
                }
            }

            /// The smallest box holding both.
            #[must_use]
            pub fn union(self, other: Self) -> Self {
                Self {
                    min: self.min.min(other.min),
                    max: self.max.max(other.max),
                }
            }

            /// The overlap of both boxes (possibly empty).
            #[must_use]
            pub fn intersection(self, other: Self) -> Self {
                Self {
                    min: self.min.max(other.min),
                    max: self.max.min(other.max),
                }
            }

            /// The box inflated by `margin` on every side.
            #[must_use]
            pub fn inflated(self, margin: $scalar) -> Self {
                Self {
                    min: self.min - <$vec>::splat(margin),
                    max: self.max + <$vec>::splat(margin),
                }
            }

            /// Centre point; meaningless for the empty box.
            pub fn center(&self) -> $vec {
                (self.min + self.max) * 0.5
            }

            /// Size along each axis; zero for the empty box.
            pub fn extent(&self) -> $vec {
                (self.max - self.min).max(<$vec>::ZERO)
            }

            /// Surface area, the SAH cost measure; zero for empty and flat-to-a-line boxes.
            pub fn surface_area(&self) -> $scalar {
                let e = self.extent();
                2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
            }

            /// True when the boxes share at least one point (touching counts).
            pub fn overlaps(&self, other: &Self) -> bool {
                self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
            }

            /// True when `p` is inside or on the boundary.
            pub fn contains_point(&self, p: $vec) -> bool {
                self.min.cmple(p).all() && p.cmple(self.max).all()
            }

            /// True when `other` lies entirely inside (or on the boundary of) this box.
            /// Every box contains the empty box.
            pub fn contains(&self, other: &Self) -> bool {
                other.is_empty()
                    || (self.min.cmple(other.min).all() && other.max.cmple(self.max).all())
            }

            /// The eight corners (index bit 0 = x max, bit 1 = y max, bit 2 = z max).
            pub fn corners(&self) -> [$vec; 8] {
                std::array::from_fn(|i| {
                    <$vec>::new(
                        if i & 1 == 0 { self.min.x } else { self.max.x },
                        if i & 2 == 0 { self.min.y } else { self.max.y },
                        if i & 4 == 0 { self.min.z } else { self.max.z },
                    )
                })
            }

            /// True when every coordinate is finite (the empty box is not finite).
            pub fn is_finite(&self) -> bool {
                self.min.is_finite() && self.max.is_finite()
            }
        }
    };
}

aabb_impl!(Aabb3f, Vec3, f32);
aabb_impl!(Aabb3d, DVec3, f64);

impl Aabb3f {
    /// This box widened to f64 (exact).
    #[inline]
    pub fn as_dvec(&self) -> Aabb3d {
        Aabb3d {
            min: self.min.as_dvec3(),
            max: self.max.as_dvec3(),
        }
    }

    /// The world box of this local box under an f64 transform: tight for the box
    /// (Arvo's method), computed in f64 so far-from-origin parts stay exact.
    pub fn transformed(&self, world: &DAffine3) -> Aabb3d {
        self.as_dvec().transformed(world)
    }
}

impl Aabb3d {
    /// The box enclosing this box after an affine transform (Arvo 1990), without
    /// enumerating corners; padded by a few ulps so that it always encloses the
    /// transformed corners despite rounding.
    pub fn transformed(&self, m: &DAffine3) -> Aabb3d {
        if self.is_empty() {
            return Aabb3d::EMPTY;
        }
        let c = m.transform_point3(self.center());
        let h = self.extent() * 0.5;
        let a = m.matrix3;
        let r = DVec3::new(
            a.x_axis.x.abs() * h.x + a.y_axis.x.abs() * h.y + a.z_axis.x.abs() * h.z,
            a.x_axis.y.abs() * h.x + a.y_axis.y.abs() * h.y + a.z_axis.y.abs() * h.z,
            a.x_axis.z.abs() * h.x + a.y_axis.z.abs() * h.y + a.z_axis.z.abs() * h.z,
        );
        // Rounding in the centre, the radius and the final sums can leave the box an
        // ulp or two short of a transformed corner; pad outwards by a few ulps of
        // the magnitudes involved so the box always encloses (trees and ray tests
        // rely on it). The magnitudes are the terms summed, not the sum: a
        // translation that cancels the rotated centre leaves a small centre
        // with the rounding of the large terms. Deterministic: the same
        // transform gives the same box.
        let p = self.center().abs();
        let terms = a.x_axis.abs() * p.x
            + a.y_axis.abs() * p.y
            + a.z_axis.abs() * p.z
            + m.translation.abs();
        let pad = (terms + r) * (8.0 * f64::EPSILON);
        Aabb3d {
            min: c - r - pad,
            max: c + r + pad,
        }
    }

    /// This box narrowed to f32, rounded outwards so the result still encloses it.
    pub fn as_vec_outward(&self) -> Aabb3f {
        let down = |v: f64| {
            let f = v as f32;
            if f64::from(f) > v { f.next_down() } else { f }
        };
        let up = |v: f64| {
            let f = v as f32;
            if f64::from(f) < v { f.next_up() } else { f }
        };
        Aabb3f {
            min: Vec3::new(down(self.min.x), down(self.min.y), down(self.min.z)),
            max: Vec3::new(up(self.max.x), up(self.max.y), up(self.max.z)),
        }
    }
}
