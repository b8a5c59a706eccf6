//! Asymmetric ("off-centre") fields of view, as head-mounted displays give
//! each eye: the four angles of the view frustum's sides.

use glam::DMat4;

use crate::{Camera, Coverage, Frustum};

/// The angles of a view frustum's four sides from the view axis, radians, as
/// OpenXR's `XrFovf` gives them: `left` and `down` negative for a frustum
/// that contains the axis, `right` and `up` positive. A symmetric camera has
/// `left = -right` and `down = -up`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fov {
    /// Angle of the left side (negative to the left of the axis).
    pub left: f64,
    /// Angle of the right side.
    pub right: f64,
    /// Angle of the bottom side (negative below the axis).
    pub down: f64,
    /// Angle of the top side.
    pub up: f64,
}

impl Fov {
    /// The symmetric field of view of `fov_y_rad` vertically at `aspect`
    /// (width over height), as [`Camera::projection`] draws it.
    pub fn symmetric(fov_y_rad: f64, aspect: f64) -> Self {
        let up = fov_y_rad * 0.5;
        let right = ((fov_y_rad * 0.5).tan() * aspect).atan();
        Self {
            left: -right,
            right,
            down: -up,
            up,
        }
    }

    /// Whether the projection is defined: finite angles inside `(-π/2, π/2)`,
    /// `left < right` and `down < up`.
    pub fn is_valid(&self) -> bool {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let ok = |a: f64| a.is_finite() && a.abs() < half_pi;
        ok(self.left)
            && ok(self.right)
            && ok(self.down)
            && ok(self.up)
            && self.left < self.right
            && self.down < self.up
    }

    /// Tangents of the sides: `[left, right, down, up]`.
    pub fn tangents(&self) -> [f64; 4] {
        [
            self.left.tan(),
            self.right.tan(),
            self.down.tan(),
            self.up.tan(),
        ]
    }

    /// Width over height of the image plane this field of view covers (a
    /// viewport of this aspect has square pixels).
    pub fn aspect(&self) -> f64 {
        let [l, r, d, u] = self.tangents();
        (r - l) / (u - d)
    }

    /// View to clip, reverse-Z with an infinite far plane, like
    /// [`crate::reverse_z_perspective`] but off-centre: view-space direction
    /// `(tan(left), ·, -1)` lands on clip x = -1, `(tan(right), ·, -1)` on
    /// +1, and likewise down and up on y; `z = -near` maps to depth 1.
    ///
    /// # Panics
    /// When the field of view is not [`Fov::is_valid`] or `near` is not
    /// positive and finite.
    pub fn projection(&self, near: f64) -> DMat4 {
        self.projection_to(near, None)
    }

    /// [`Fov::projection`] with a far plane: `z = -far` maps to depth 0 and
    /// beyond it is clipped (`None`: at infinity).
    ///
    /// # Panics
    /// As [`Fov::projection`], and when `far` is not beyond `near`.
    pub fn projection_to(&self, near: f64, far: Option<f64>) -> DMat4 {
        assert!(self.is_valid(), "invalid field of view {self:?}");
        assert!(
            near > 0.0 && near.is_finite(),
            "near plane must be positive, got {near}"
        );
        // Clip z = a z + b with w = -z: depth 1 at -near, 0 at -far.
        let (a, b) = match far {
            Some(far) => {
                assert!(
                    far > near,
                    "far plane {far} must lie beyond near plane {near}"
                );
                (near / (far - near), near * far / (far - near))
            }
            None => (0.0, near),
        };
        let [l, r, d, u] = self.tangents();
        // x_ndc = (2 x / -z - (r + l)) / (r - l); with w = -z the offset term
        // becomes (r + l) / (r - l) * z.
        DMat4::from_cols_array(&[
            2.0 / (r - l),
            0.0,
            0.0,
            0.0,
            0.0,
            2.0 / (u - d),
            0.0,
            0.0,
            (r + l) / (r - l),
            (u + d) / (u - d),
            a,
            -1.0,
            0.0,
            0.0,
            b,
            0.0,
        ])
    }

    /// The world-space culling frustum of `camera`'s pose (eye, target, up and
    /// near; its `fov_y_rad` is not used) with this field of view, out to
    /// `far` (`None`: infinity).
    pub fn frustum(&self, camera: &Camera, far: Option<f64>) -> Frustum {
        Frustum::from_view_proj_reverse_z(
            &(self.projection_to(camera.near, far) * camera.view_matrix()),
        )
    }

    /// The screen-coverage metric of `camera`'s eye with this field of view on
    /// a viewport `height_px` tall.
    pub fn coverage(&self, camera: &Camera, height_px: u32) -> Coverage {
        let [_, _, d, u] = self.tangents();
        Coverage {
            eye: camera.eye,
            eye_spread: 0.0,
            focal_px: f64::from(height_px) / (u - d),
        }
    }

    /// How far the near plane's corners lie from the eye at `near`.
    pub fn near_reach(&self, near: f64) -> f64 {
        let [l, r, d, u] = self.tangents();
        let x = l.abs().max(r.abs());
        let y = d.abs().max(u.abs());
        near * (1.0 + x * x + y * y).sqrt()
    }
}
