//! Geometry for dmu: boxes, rays, planes, frustums and robust intersection tests.
//!
//! Design choices:
//! - World positions are `f64` (`DVec3`, `DAffine3`): CAD models sit millimetres
//!   apart kilometres from the origin, where `f32` has a resolution of a millimetre
//!   or worse. Part-local geometry is `f32` (`Vec3`), where it is exact enough and
//!   half the memory.
//! - Every test is total: zero direction components, zero-extent boxes and
//!   degenerate triangles give an answer, never a NaN path.
//!
//! Conventions: right-handed, units are the model's (millimetres for CAD models),
//! triangles counter-clockwise when front-facing.

mod aabb;

pub use aabb::{Aabb3d, Aabb3f};
pub use glam;
