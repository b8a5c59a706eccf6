//! Geometry for dmu: boxes, rays, planes, frustums and robust intersection tests.
//!
//! Design choices:
//! - World positions are `f64` (`DVec3`, `DAffine3`): CAD models sit millimetres
//!   apart kilometres from the origin, where `f32` has a resolution of a millimetre
//!   or worse. Part-local geometry is `f32` (`Vec3`), where it is exact enough and
//!   half the memory.
//! - Every test is total: zero direction components, zero-extent boxes and
//!   degenerate triangles give an answer, never a NaN path.
//! - Rays are carried into a part's frame unnormalized ([`Ray3d::to_local`]), so a
//!   hit's `t` is the same in world and local frames and hits from different parts
//!   compare without converting back.
//! - Ray/triangle is watertight (Woop, Benthin, Wald 2013): a ray through a shared
//!   edge or vertex hits at least one triangle, so picking never falls through a mesh.
//! - Ray/box widens its exit distance by a few ulps (Ize 2013): a box must never be
//!   missed by a ray that hits a triangle inside it; an extra visit costs little.
//! - Per-ray work is done once in a prepared test ([`RayBoxTest3f`],
//!   [`RayTriTest3f`]) that BVH traversal reuses for every node and triangle; the
//!   tests allocate nothing.
//!
//! Conventions: right-handed, units are the model's (millimetres for CAD models),
//! triangles counter-clockwise when front-facing. Cameras look down -Z in view space;
//! projections are reverse-Z with clip depth in `[0, 1]` (1 at the near plane, 0 at
//! the far plane, which may be at infinity), as wgpu expects. Frustum plane normals
//! point inwards. Ray directions are not normalized; boundaries count as hits.
//!
//! ```
//! use dmu_geom::glam::{DAffine3, DVec3, Vec3};
//! use dmu_geom::{Aabb3f, Frustum, Ray3d, RayBoxTest3f, RayTriTest3f, look_at, reverse_z_perspective};
//!
//! // A part far from the world origin, with one triangle and its local box.
//! let world = DAffine3::from_translation(DVec3::new(1e7, 2e7, 0.0));
//! let tri = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0)];
//! let local_box = Aabb3f::from_points(tri);
//!
//! // Is it on screen?
//! let eye = DVec3::new(1e7, 2e7, 10.0);
//! let view_proj = reverse_z_perspective(1.0, 16.0 / 9.0, 0.1, None)
//!     * look_at(eye, DVec3::new(1e7, 2e7, 0.0), DVec3::Y);
//! let frustum = Frustum::from_view_proj_reverse_z(&view_proj);
//! assert!(frustum.intersects_aabb(&local_box.transformed(&world)));
//!
//! // Pick it: the world ray goes to the part's frame in f64, then to f32.
//! let ray = Ray3d::new(eye + DVec3::new(0.5, 0.5, 0.0), -DVec3::Z);
//! let local = ray.to_local(&world).as_f32();
//! let (t_enter, _) = RayBoxTest3f::new(&local).hit(&local_box, f32::INFINITY).unwrap();
//! let hit = RayTriTest3f::new(&local).hit(tri[0], tri[1], tri[2], 0.0, f32::INFINITY).unwrap();
//! assert_eq!((t_enter, hit.t), (10.0, 10.0));
//! assert_eq!((hit.u, hit.v), (0.25, 0.25));
//! ```

mod aabb;
mod camera;
mod fov;
mod frustum;
mod plane;
mod ray;
mod ray_box;
mod short;
mod stats;
mod triangle;
mod vector;

pub use aabb::{Aabb3d, Aabb3f};
pub use camera::{Camera, Coverage, look_at, reverse_z_perspective};
pub use fov::Fov;
pub use frustum::{Containment, Frustum};
pub use glam;
pub use plane::Plane;
pub use ray::{Ray3d, Ray3f};
pub use ray_box::{RayBoxTest3d, RayBoxTest3f};
pub use short::Short;
pub use stats::{median, percentile};
pub use triangle::{
    RayTriTest3d, RayTriTest3f, TriHit, closest_point_on_triangle, is_degenerate, triangle_area,
    triangle_normal,
};
pub use vector::{is_within, unit_vector};
