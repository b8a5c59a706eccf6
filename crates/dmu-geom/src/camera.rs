//! Camera matrices for the conventions of this crate: right-handed, looking down
//! -Z in view space, reverse-Z depth in `[0, 1]`.

use glam::dcamera::rh::{proj::directx, view};
use glam::{DMat4, DVec3};

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
