//! Navigation: an eye with a heading and a pitch, orbiting about a pivot,
//! walking or flying, and the f64 pick ray through a pixel.
//!
//! Everything is f64 in world units, Z up (the plant's convention); the camera
//! handed to the renderer is formed from this state each frame.

use dmu_geom::{Aabb3d, Ray3d};
use dmu_render::Camera;
use glam::{DQuat, DVec3};

/// Pitch stays short of straight up or down, so Z is never the view direction.
const MAX_PITCH: f64 = 89.0 * std::f64::consts::PI / 180.0;

/// Walking keeps the eye's height (moves in the horizontal plane); flying
/// moves along the view direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// W/S move horizontally, Q/E change height.
    Walk,
    /// W/S move along the view direction.
    Fly,
}

/// A standard view direction, framing the model ([`Navigator::preset`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Looking down (-Z), +Y up on screen.
    Top,
    /// Looking along +Y (from the front, -Y side).
    Front,
    /// Looking along -X (from the right, +X side).
    Side,
    /// Isometric: from the +X, -Y, +Z corner toward the centre, every axis
    /// equally foreshortened.
    Iso,
}

impl Preset {
    /// Every preset, in menu order.
    pub const ALL: [Self; 4] = [Self::Top, Self::Front, Self::Side, Self::Iso];

    /// `top`, `front`, `side` or `iso`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Top => "top",
            Self::Front => "front",
            Self::Side => "side",
            Self::Iso => "iso",
        }
    }

    /// Heading and pitch of the view direction, radians. Top stops at the
    /// pitch limit, so Z up on screen stays defined (the view is 1° off
    /// vertical).
    fn yaw_pitch(self) -> (f64, f64) {
        let iso_pitch = -(1.0 / 2f64.sqrt()).atan();
        match self {
            Self::Top => (90f64.to_radians(), -MAX_PITCH),
            Self::Front => (90f64.to_radians(), 0.0),
            Self::Side => (180f64.to_radians(), 0.0),
            Self::Iso => (135f64.to_radians(), iso_pitch),
        }
    }
}

/// Which way the keys push this frame: each component in `[-1, 1]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Keys {
    /// Forward (+) or back (-).
    pub forward: f64,
    /// Right (+) or left (-).
    pub right: f64,
    /// Up (+) or down (-).
    pub up: f64,
    /// Speed factor this frame (e.g. 4 while Shift is held).
    pub boost: f64,
}

/// The viewer's camera state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Navigator {
    /// Eye position, world units.
    pub eye: DVec3,
    /// Heading: angle of the view direction about Z from +X, radians.
    pub yaw: f64,
    /// Angle of the view direction above the horizontal, radians.
    pub pitch: f64,
    /// The point orbiting turns about (the last picked point).
    pub pivot: DVec3,
    /// Vertical field of view, radians.
    pub fov_y_rad: f64,
    /// Near plane, world units.
    pub near: f64,
    /// Walking speed at factor 1, world units per second (scales with the model).
    pub base_speed: f64,
    /// The user's speed factor.
    pub speed_factor: f64,
    /// Walk or fly.
    pub motion: Motion,
    /// The model's diagonal, which scales speeds and distances.
    model_size: f64,
}

impl Navigator {
    /// A view of `bounds` from an elevated corner, the whole model in sight.
    pub fn overview(bounds: &Aabb3d) -> Self {
        let size = if bounds.is_empty() {
            1.0
        } else {
            bounds.extent().length().max(1e-9)
        };
        let mut nav = Self {
            eye: DVec3::ZERO,
            yaw: 45f64.to_radians(),
            pitch: -30f64.to_radians(),
            pivot: DVec3::ZERO,
            fov_y_rad: 60f64.to_radians(),
            // Reverse-Z with f32 depth keeps precision far beyond this ratio.
            near: (size * 1e-5).max(1e-6),
            base_speed: size / 20.0,
            speed_factor: 1.0,
            motion: Motion::Walk,
            model_size: size,
        };
        nav.frame(bounds);
        nav
    }

    /// The unit view direction.
    pub fn forward(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(cp * cy, cp * sy, sp)
    }

    /// The unit screen-right direction (horizontal).
    pub fn right(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        DVec3::new(sy, -cy, 0.0)
    }

    /// The unit screen-up direction.
    pub fn up(&self) -> DVec3 {
        self.right().cross(self.forward())
    }

    /// The renderer's camera for this state.
    pub fn camera(&self) -> Camera {
        Camera {
            eye: self.eye,
            // Any point along the view direction will do; a model-sized offset
            // keeps the direction exact to f64 rounding far from the origin.
            target: self.eye + self.forward() * self.model_size,
            up: DVec3::Z,
            fov_y_rad: self.fov_y_rad,
            near: self.near,
        }
    }

    /// Turns the eye and the view direction together about the pivot: the pivot
    /// stays where it is on screen. `yaw` turns about Z, `pitch` about the
    /// screen's right axis (clamped short of the vertical).
    pub fn orbit(&mut self, yaw: f64, pitch: f64) {
        let new_pitch = (self.pitch + pitch).clamp(-MAX_PITCH, MAX_PITCH);
        let pitch = new_pitch - self.pitch;
        let offset = DQuat::from_rotation_z(yaw) * (self.eye - self.pivot);
        self.yaw += yaw;
        let offset = DQuat::from_axis_angle(self.right(), pitch) * offset;
        self.pitch = new_pitch;
        self.eye = self.pivot + offset;
    }

    /// Turns the view direction about the eye (mouse look).
    pub fn look(&mut self, yaw: f64, pitch: f64) {
        self.yaw += yaw;
        self.pitch = (self.pitch + pitch).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Current speed, world units per second.
    pub fn speed(&self) -> f64 {
        self.base_speed * self.speed_factor
    }

    /// Moves the eye for `dt` seconds of held keys.
    pub fn walk(&mut self, keys: Keys, dt: f64) {
        let ahead = match self.motion {
            Motion::Walk => {
                let (sy, cy) = self.yaw.sin_cos();
                DVec3::new(cy, sy, 0.0)
            }
            Motion::Fly => self.forward(),
        };
        let step = ahead * keys.forward + self.right() * keys.right + DVec3::Z * keys.up;
        let boost = if keys.boost > 0.0 { keys.boost } else { 1.0 };
        let delta = step * self.speed() * boost * dt;
        self.eye += delta;
        self.pivot += delta;
    }

    /// Slides eye and pivot in the screen plane by a drag of `dx, dy` pixels in a
    /// view `height` pixels tall: the pivot follows the cursor.
    pub fn pan(&mut self, dx: f64, dy: f64, height: f64) {
        let distance = (self.pivot - self.eye).length().max(self.near);
        let per_pixel = world_per_pixel(self.fov_y_rad, distance, height);
        let delta = (-self.right() * dx + self.up() * dy) * per_pixel;
        self.eye += delta;
        self.pivot += delta;
    }

    /// Moves the eye toward `point` by `fraction` of the distance (negative:
    /// away), stopping short of it; the pivot becomes `point`.
    pub fn dolly_toward(&mut self, point: DVec3, fraction: f64) {
        let fraction = fraction.min(0.9);
        self.eye += (point - self.eye) * fraction;
        self.pivot = point;
    }

    /// Keeps the view direction and moves back until `bounds` fill the view;
    /// the pivot becomes its centre.
    pub fn frame(&mut self, bounds: &Aabb3d) {
        if bounds.is_empty() {
            return;
        }
        let camera =
            dmu_geom::Camera::framing(bounds, self.forward(), DVec3::Z, self.fov_y_rad, self.near);
        self.eye = camera.eye;
        self.pivot = camera.target;
    }

    /// Puts the eye at `eye` looking along `forward` (any length; roll is not
    /// kept: the view stays upright, its pitch short of the vertical), the
    /// pivot `pivot_distance` ahead. `false` (nothing changed) for a forward
    /// that is zero or not finite, or an eye outside the world
    /// (±[`dmu_scene::MAX_WORLD_COORDINATE`]).
    pub fn look_along(&mut self, eye: DVec3, forward: DVec3, pivot_distance: f64) -> bool {
        let Some(f) = dmu_geom::unit_vector(forward)
            .filter(|_| dmu_geom::is_within(eye, dmu_scene::MAX_WORLD_COORDINATE))
        else {
            return false;
        };
        self.eye = eye;
        self.yaw = f.y.atan2(f.x);
        self.pitch = f.z.clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH);
        self.pivot = eye + self.forward() * pivot_distance.max(self.near);
        true
    }

    /// Looks from a standard direction and frames `bounds`.
    pub fn preset(&mut self, preset: Preset, bounds: &Aabb3d) {
        (self.yaw, self.pitch) = preset.yaw_pitch();
        self.frame(bounds);
    }

    /// The world ray through the point `(x, y)` of a view `size` pixels wide and
    /// tall (pixel `(i, j)` spans `[i, i+1) x [j, j+1)`, y down), formed in f64
    /// from the same basis as the renderer's view matrix.
    pub fn ray(&self, size: (u32, u32), x: f64, y: f64) -> Ray3d {
        ray_through(&self.camera(), size, x, y)
    }
}

/// The world length a pixel spans at `depth` ahead of the eye in a view
/// `height` pixels tall with a vertical field of view of `fov_y_rad`.
pub fn world_per_pixel(fov_y_rad: f64, depth: f64, height: f64) -> f64 {
    2.0 * depth * (fov_y_rad * 0.5).tan() / height.max(1.0)
}

/// The world ray from `camera`'s eye through the point `(x, y)` of a view
/// `size` pixels in size (y down), in f64: the basis is the one
/// [`dmu_geom::look_at`] builds, scaled by the projection's tangents.
pub fn ray_through(camera: &Camera, size: (u32, u32), x: f64, y: f64) -> Ray3d {
    let (w, h) = (f64::from(size.0), f64::from(size.1));
    let f = (camera.target - camera.eye).normalize();
    let s = f.cross(camera.up.normalize()).normalize();
    let u = s.cross(f);
    let tan = (camera.fov_y_rad * 0.5).tan();
    let nx = (2.0 * x / w - 1.0) * tan * (w / h);
    let ny = (1.0 - 2.0 * y / h) * tan;
    Ray3d::new(camera.eye, f + s * nx + u * ny)
}

/// The offset along a drag axis that brings the axis point under `ray`: the
/// parameter `s` of the point `origin + s * axis` (unit `axis`) closest to the
/// ray, or `None` when the ray is nearly parallel to the axis.
pub fn axis_offset(origin: DVec3, axis: DVec3, ray: &Ray3d) -> Option<f64> {
    let d = ray.dir.normalize();
    let w = origin - ray.origin;
    let b = axis.dot(d);
    let denom = 1.0 - b * b;
    if denom < 1e-6 {
        return None;
    }
    let (e, f) = (axis.dot(w), d.dot(w));
    Some((b * f - e) / denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each preset looks the way it says and frames the model's centre in the
    /// middle of the view.
    #[test]
    fn presets_look_their_way_and_frame_the_model() {
        let mut nav = nav();
        let bounds = Aabb3d::new(
            DVec3::new(4.5e6, 5.3e6, 1.2e4),
            DVec3::new(4.6e6, 5.4e6, 4.2e4),
        );
        let iso = DVec3::new(-1.0, 1.0, -1.0).normalize();
        for (preset, dir, tol) in [
            (Preset::Top, -DVec3::Z, 1.01f64.to_radians()),
            (Preset::Front, DVec3::Y, 1e-12),
            (Preset::Side, -DVec3::X, 1e-12),
            (Preset::Iso, iso, 1e-12),
        ] {
            nav.preset(preset, &bounds);
            let angle = nav.forward().angle_between(dir);
            assert!(angle <= tol, "{}: off by {angle} rad", preset.name());
            let centre = nav.ray((800, 600), 400.0, 300.0);
            let to_centre = (bounds.center() - centre.origin).normalize();
            assert!(centre.dir.normalize().angle_between(to_centre) < 1e-9);
            assert_eq!(nav.pivot, bounds.center());
        }
    }

    fn nav() -> Navigator {
        let bounds = Aabb3d::new(
            DVec3::new(4.5e6, 5.3e6, 1.2e4),
            DVec3::new(4.6e6, 5.4e6, 4.2e4),
        );
        Navigator::overview(&bounds)
    }

    /// The ray through a pixel projects back onto that pixel with the
    /// renderer's own matrices.
    #[test]
    fn ray_projects_back_to_its_pixel() {
        let n = nav();
        let size = (640, 360);
        let camera = n.camera();
        let clip_from_world = camera.projection(640.0 / 360.0) * camera.view_matrix();
        for (x, y) in [(0.5, 0.5), (320.0, 180.0), (600.25, 17.75)] {
            let ray = n.ray(size, x, y);
            let p = clip_from_world.project_point3(ray.at(1000.0));
            let px = (p.x + 1.0) * 0.5 * 640.0;
            let py = (1.0 - p.y) * 0.5 * 360.0;
            assert!(
                (px - x).abs() < 1e-6 && (py - y).abs() < 1e-6,
                "{x},{y} -> {px},{py}"
            );
        }
    }

    /// Orbiting keeps the pivot on the view axis when it was there, keeps the
    /// distance, and the inverse orbit comes back.
    #[test]
    fn orbit_turns_about_the_pivot() {
        let mut n = nav();
        let start = n;
        let distance = (n.pivot - n.eye).length();
        n.orbit(0.3, 0.2);
        assert!(((n.pivot - n.eye).length() - distance).abs() < 1e-6 * distance);
        let to_pivot = (n.pivot - n.eye).normalize();
        assert!(to_pivot.dot(n.forward()) > 1.0 - 1e-12);
        n.orbit(0.0, -0.2);
        n.orbit(-0.3, 0.0);
        assert!((n.eye - start.eye).length() < 1e-6);
        assert!((n.yaw - start.yaw).abs() < 1e-12 && (n.pitch - start.pitch).abs() < 1e-12);
    }

    #[test]
    fn pitch_stops_short_of_vertical() {
        let mut n = nav();
        n.orbit(0.0, 10.0);
        assert!(n.pitch <= MAX_PITCH);
        n.look(0.0, -10.0);
        assert!(n.pitch >= -MAX_PITCH);
        assert!(n.forward().cross(DVec3::Z).length() > 0.01);
    }

    /// Walking keeps the height; speed scales with the model.
    #[test]
    fn walking_keeps_height_and_scales() {
        let mut n = nav();
        let z = n.eye.z;
        let before = n.eye;
        n.walk(
            Keys {
                forward: 1.0,
                ..Keys::default()
            },
            0.5,
        );
        assert_eq!(n.eye.z, z);
        let moved = (n.eye - before).length();
        assert!((moved - n.speed() * 0.5).abs() < 1e-6 * moved);
        let small = Navigator::overview(&Aabb3d::new(DVec3::ZERO, DVec3::splat(10.0)));
        assert!(small.speed() < n.speed() / 1000.0);
    }

    /// The axis offset puts the axis point under the ray.
    #[test]
    fn axis_offset_finds_the_point_under_the_ray() {
        let origin = DVec3::new(1e6, 2e6, 3.0);
        let target = origin + DVec3::X * 123.5;
        let eye = DVec3::new(1e6 + 50.0, 2e6 - 400.0, 300.0);
        let ray = Ray3d::new(eye, target - eye);
        let s = axis_offset(origin, DVec3::X, &ray).unwrap();
        assert!((s - 123.5).abs() < 1e-6, "{s}");
        let along = Ray3d::new(origin - DVec3::X, DVec3::X);
        assert!(axis_offset(origin, DVec3::X, &along).is_none());
    }

    /// Framing a box puts its centre on the view axis and all of it in view.
    #[test]
    fn framing_fits_the_box() {
        let mut n = nav();
        let b = Aabb3d::new(DVec3::new(10.0, 20.0, 30.0), DVec3::new(12.0, 21.0, 33.0));
        n.frame(&b);
        assert_eq!(n.pivot, b.center());
        let f = n.camera().frustum(1.0);
        for c in b.corners() {
            assert!(f.planes.iter().all(|p| p.signed_distance(c) >= -1e-9));
        }
    }
}
