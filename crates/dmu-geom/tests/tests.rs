//! The one test binary of dmu-geom.

mod aabb;
mod camera;
mod fov;
mod frustum;
mod ray_box;
mod triangle;
mod vector;
