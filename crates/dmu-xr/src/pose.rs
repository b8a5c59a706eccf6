//! Eye poses in the tracking space (metres, Y up) as dmu cameras in the model
//! world (model units, Z up).

use dmu_geom::glam::{DAffine3, DMat3, DQuat, DVec3};
use dmu_geom::{Camera, Fov};

/// A pose in the tracking space: metres, right-handed, Y up, -Z forward
/// (OpenXR's convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Position, metres.
    pub position: DVec3,
    /// Orientation (unit quaternion).
    pub orientation: DQuat,
}

impl Pose {
    /// The tracking space's origin, looking down -Z.
    pub const IDENTITY: Self = Self {
        position: DVec3::ZERO,
        orientation: DQuat::IDENTITY,
    };

    /// From OpenXR's pose (f32).
    pub fn from_xr(p: &openxr::Posef) -> Self {
        let (o, q) = (p.position, p.orientation);
        Self {
            position: DVec3::new(f64::from(o.x), f64::from(o.y), f64::from(o.z)),
            orientation: DQuat::from_xyzw(
                f64::from(q.x),
                f64::from(q.y),
                f64::from(q.z),
                f64::from(q.w),
            )
            .normalize(),
        }
    }
}

/// From OpenXR's field of view (f32 angles).
pub fn fov_from_xr(f: &openxr::Fovf) -> Fov {
    Fov {
        left: f64::from(f.angle_left),
        right: f64::from(f.angle_right),
        down: f64::from(f.angle_down),
        up: f64::from(f.angle_up),
    }
}

/// Where the tracking space stands in the model: the world point under its
/// origin, its heading, and the model's units per metre. The tracking space's
/// Y (up) becomes world Z; with `heading_rad` 0 its -Z (forward) is world +Y.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// World position of the tracking origin, model units.
    pub origin: DVec3,
    /// Turn about world Z, radians (counter-clockwise seen from above).
    pub heading_rad: f64,
    /// Model units per metre (1000 for millimetres).
    pub units_per_metre: f64,
}

impl Placement {
    /// Tracking space to world: positions in metres to model units.
    pub fn to_world(&self) -> DAffine3 {
        // Columns: tracking x, y, z in world axes (x stays, y up is world z,
        // z backward is world -y).
        let y_up_to_z_up = DMat3::from_cols(DVec3::X, DVec3::Z, DVec3::NEG_Y);
        DAffine3::from_translation(self.origin)
            * DAffine3::from_rotation_z(self.heading_rad)
            * DAffine3::from_mat3(y_up_to_z_up)
            * DAffine3::from_scale(DVec3::splat(self.units_per_metre))
    }

    /// A tracking-space position in the world.
    pub fn point(&self, position: DVec3) -> DVec3 {
        self.to_world().transform_point3(position)
    }

    /// A tracking-space direction in the world (unit length kept).
    pub fn direction(&self, direction: DVec3) -> DVec3 {
        self.to_world().transform_vector3(direction) / self.units_per_metre
    }

    /// The camera of an eye at `pose` with `fov`: the eye's position, its
    /// forward (-Z) and up (+Y) carried into the world, `near` in model
    /// units. Its `fov_y_rad` is the vertical span of `fov`, which
    /// `dmu_render::View::fov` then replaces for projection.
    pub fn eye_camera(&self, pose: &Pose, fov: &Fov, near: f64) -> Camera {
        let eye = self.point(pose.position);
        let forward = self.direction(pose.orientation * DVec3::NEG_Z);
        let up = self.direction(pose.orientation * DVec3::Y);
        Camera {
            eye,
            target: eye + forward * self.units_per_metre,
            up,
            fov_y_rad: fov.up - fov.down,
            near,
        }
    }
}

/// Where world point `p` lands in an eye's image of `size` pixels (x right,
/// y down, pixel centres at half-integers), seen by `camera` with `fov`;
/// `None` behind the eye.
pub fn eye_pixel(camera: &Camera, fov: &Fov, size: (u32, u32), p: DVec3) -> Option<(f64, f64)> {
    let clip = fov.projection(camera.near) * camera.view_matrix() * p.extend(1.0);
    (clip.w > 0.0).then(|| {
        let (x, y) = (clip.x / clip.w, clip.y / clip.w);
        (
            (x + 1.0) * 0.5 * f64::from(size.0),
            (1.0 - y) * 0.5 * f64::from(size.1),
        )
    })
}

/// The world ray from `camera`'s eye through image point `(x, y)` (pixels,
/// y down) of an eye with `fov` and image `size`; its direction is not
/// normalized.
pub fn eye_ray(camera: &Camera, fov: &Fov, size: (u32, u32), x: f64, y: f64) -> dmu_geom::Ray3d {
    let [l, r, d, u] = fov.tangents();
    let tx = l + (r - l) * x / f64::from(size.0);
    let ty = u - (u - d) * y / f64::from(size.1);
    let f = (camera.target - camera.eye).normalize();
    let s = f.cross(camera.up.normalize()).normalize();
    let up = s.cross(f);
    dmu_geom::Ray3d::new(camera.eye, f + s * tx + up * ty)
}
