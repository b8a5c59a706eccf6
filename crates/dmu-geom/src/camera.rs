//! Camera matrices for the conventions of this crate: right-handed, looking down
//! -Z in view space, reverse-Z depth in `[0, 1]`.

use glam::dcamera::rh::{proj::directx, view};
use glam::{DMat4, DVec3};

use crate::{Aabb3d, Frustum};

/// A perspective camera in world coordinates (f64), the one camera of dmu: the
/// renderer draws through it and the store's walks decide what to load with
/// it. Paths on disk carry the field of view in degrees (`dmu_store::CameraFrame`)
/// and convert into this.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// Point looked at.
    pub target: DVec3,
    /// Screen up direction (any length, not parallel to the view direction).
    pub up: DVec3,
    /// Vertical field of view, radians.
    pub fov_y_rad: f64,
    /// Near plane distance, world units; the far plane is at infinity.
    pub near: f64,
}

impl Camera {
    /// Whether the matrices below are defined: finite, eye off the target, up
    /// not along the view direction, field of view in `(0, π)`, near positive.
    pub fn is_valid(&self) -> bool {
        let forward = self.target - self.eye;
        self.eye.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && forward.cross(self.up) != DVec3::ZERO
            && self.fov_y_rad > 0.0
            && self.fov_y_rad < std::f64::consts::PI
            && self.near > 0.0
            && self.near.is_finite()
    }

    /// The camera looking along `forward` at the centre of `bounds` from just
    /// far enough back that the box's bounding sphere (radius at least ten
    /// near distances) fits the vertical field of view with 5 % to spare, so
    /// all of the box is in view on any screen at least as wide as it is tall.
    /// How the viewer frames a selection and `dmu collide --bcf` frames a
    /// clash.
    pub fn framing(bounds: &Aabb3d, forward: DVec3, up: DVec3, fov_y_rad: f64, near: f64) -> Self {
        let target = bounds.center();
        let radius = (bounds.extent().length() * 0.5).max(near * 10.0);
        let distance = radius / (fov_y_rad * 0.5).sin() * 1.05;
        Self {
            eye: target - forward.normalize() * distance,
            target,
            up,
            fov_y_rad,
            near,
        }
    }

    /// Where this camera will be `steps` steps on when each step moves and
    /// turns it as the last did (from `previous` to this one): the eye on
    /// along the same displacement; the view direction's heading about `up`
    /// and its elevation over the horizon each on by `steps` times the same
    /// change (the heading at most a quarter turn on, the elevation within
    /// 89 degrees of the horizon); the rest as this camera's. This camera
    /// itself where `steps` is not a finite, positive number or the result
    /// would not be valid.
    pub fn extrapolated(&self, previous: &Camera, steps: f64) -> Camera {
        use std::f64::consts::{FRAC_PI_2, PI, TAU};
        if !(steps.is_finite() && steps > 0.0) {
            return *self;
        }
        let up = self.up.normalize_or_zero();
        let (a, b) = up.any_orthonormal_pair();
        let angles = |d: DVec3| {
            let d = d.normalize_or_zero();
            (d.dot(b).atan2(d.dot(a)), d.dot(up).clamp(-1.0, 1.0).asin())
        };
        let now = self.target - self.eye;
        let (h0, e0) = angles(previous.target - previous.eye);
        let (h1, e1) = angles(now);
        // The heading's change the short way round.
        let turn = (h1 - h0 + PI).rem_euclid(TAU) - PI;
        let heading = h1 + (turn * steps).clamp(-FRAC_PI_2, FRAC_PI_2);
        let limit = 89f64.to_radians();
        let elevation = (e1 + (e1 - e0) * steps).clamp(-limit, limit);
        let forward =
            (a * heading.cos() + b * heading.sin()) * elevation.cos() + up * elevation.sin();
        let eye = self.eye + (self.eye - previous.eye) * steps;
        let moved = Camera {
            eye,
            target: eye + forward * now.length(),
            ..*self
        };
        if moved.is_valid() { moved } else { *self }
    }

    /// World to view (right-handed, looking down -Z).
    pub fn view_matrix(&self) -> DMat4 {
        look_at(self.eye, self.target, self.up)
    }

    /// View to clip, reverse-Z with an infinite far plane.
    pub fn projection(&self, aspect: f64) -> DMat4 {
        reverse_z_perspective(self.fov_y_rad, aspect, self.near, None)
    }

    /// The world-space culling frustum.
    pub fn frustum(&self, aspect: f64) -> Frustum {
        Frustum::from_view_proj_reverse_z(&(self.projection(aspect) * self.view_matrix()))
    }

    /// The screen-coverage metric of this camera on a viewport `height_px` tall.
    pub fn coverage(&self, height_px: u32) -> Coverage {
        Coverage {
            eye: self.eye,
            eye_spread: 0.0,
            focal_px: f64::from(height_px) / (2.0 * (self.fov_y_rad * 0.5).tan()),
        }
    }
}

/// Screen coverage of boxes seen from an eye: the one metric behind every
/// `min_pixels` threshold (the renderer's culling and the loader's wanted set).
///
/// A box's size on screen is its diagonal over the distance from the eye to
/// the box's nearest point, in pixels. That is conservative: it is never less
/// than the projected extent of the box's bounding sphere seen from its
/// centre, and never smaller for a box than for a box inside it, so a subtree
/// can be cut on its root's size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coverage {
    /// The eye, or the midpoint of a stereo pair's eyes.
    pub eye: DVec3,
    /// Every eye lies within this distance of `eye` (0 for a single eye).
    pub eye_spread: f64,
    /// Pixels per unit of size at unit distance: `height / (2 tan(fov_y / 2))`.
    pub focal_px: f64,
}

impl Coverage {
    /// Projected size of `b` in pixels from the nearest eye; infinite when an
    /// eye may be in the box.
    pub fn size_px(&self, b: &Aabb3d) -> f64 {
        let nearest = self.eye.clamp(b.min, b.max);
        let distance = self.eye.distance(nearest) - self.eye_spread;
        if distance <= 0.0 {
            return f64::INFINITY;
        }
        (b.max - b.min).length() / distance * self.focal_px
    }

    /// Whether a stand-in for `b` that lies at most `error` world units from
    /// what it stands for shows within `max_error_px` pixels: the error's
    /// share of the box's diagonal, times the box's [`Coverage::size_px`]
    /// (what chunk levels and merged proxies are drawn by).
    pub fn error_fits(&self, b: &Aabb3d, error: f64, max_error_px: f64) -> bool {
        let diagonal = (b.max - b.min).length();
        diagonal > 0.0 && self.size_px(b) * error / diagonal <= max_error_px
    }
}

/// A right-handed perspective projection with reverse-Z depth: view-space
/// `z = -near` maps to depth 1, `z = -far` to depth 0, and `far = None` puts the far
/// plane at infinity (depth tends to 0). Clip y points up and depth spans `[0, 1]`,
/// as wgpu expects.
///
/// # Panics
/// When `fov_y_rad` is not in `(0, π)`, `aspect` is not positive, `near` is not
/// positive, or `far` is not beyond `near`.
pub fn reverse_z_perspective(fov_y_rad: f64, aspect: f64, near: f64, far: Option<f64>) -> DMat4 {
    assert!(
        fov_y_rad > 0.0 && fov_y_rad < std::f64::consts::PI,
        "vertical field of view must be in (0, pi) radians, got {fov_y_rad}"
    );
    assert!(
        aspect > 0.0 && aspect.is_finite(),
        "aspect ratio must be positive, got {aspect}"
    );
    assert!(
        near > 0.0 && near.is_finite(),
        "near plane must be positive, got {near}"
    );
    match far {
        // Swapping near and far in a forward [0, 1] projection reverses the depth.
        Some(far) => {
            assert!(
                far > near,
                "far plane {far} must lie beyond near plane {near}"
            );
            directx::perspective(fov_y_rad, aspect, far, near)
        }
        None => directx::perspective_infinite_reverse(fov_y_rad, aspect, near),
    }
}

/// A right-handed view matrix (world to view) for an eye at `eye` looking at
/// `target`, with `up` (any length) giving the screen's upward direction.
///
/// # Panics
/// When `eye == target` or `up` is parallel to the view direction.
pub fn look_at(eye: DVec3, target: DVec3, up: DVec3) -> DMat4 {
    let forward = target - eye;
    assert!(
        forward.cross(up) != DVec3::ZERO,
        "look_at needs eye != target and up not parallel to the view direction"
    );
    view::look_at_mat4(eye, target, up.normalize())
}
