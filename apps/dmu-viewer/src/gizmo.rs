//! The 3D manipulator on the selection: arrows move it along an axis, squares
//! in a plane, rings turn it about an axis through its box centre. Offsets
//! snap to a step (model units) and turns to an angle step; a drag places the
//! part relative to where the drag began, so it never accumulates rounding.
//!
//! Handles are found and drawn in the view's pixels from the f64 camera; the
//! gizmo keeps a constant size on screen.

use dmu_geom::{Camera, Ray3d};
use glam::{DAffine3, DMat4, DQuat, DVec2, DVec3};
use serde::Deserialize;

/// Length of an arrow on screen, pixels.
pub const ARROW_PX: f64 = 90.0;
/// How close the pointer must come to a handle to grab it, pixels.
pub const GRAB_PX: f64 = 8.0;
/// Segments of a drawn ring.
const RING_SEGMENTS: usize = 48;

/// A handle of the gizmo.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Handle {
    /// Along world X.
    X,
    /// Along world Y.
    Y,
    /// Along world Z.
    Z,
    /// In the world XY plane.
    Xy,
    /// In the world YZ plane.
    Yz,
    /// In the world ZX plane.
    Zx,
    /// Turn about world X.
    Rx,
    /// Turn about world Y.
    Ry,
    /// Turn about world Z.
    Rz,
}

impl Handle {
    /// Every handle.
    pub const ALL: [Handle; 9] = [
        Self::Xy,
        Self::Yz,
        Self::Zx,
        Self::X,
        Self::Y,
        Self::Z,
        Self::Rx,
        Self::Ry,
        Self::Rz,
    ];

    /// The world axis: of the arrow, of the plane's normal, of the turn.
    pub fn axis(self) -> DVec3 {
        match self {
            Self::X | Self::Yz | Self::Rx => DVec3::X,
            Self::Y | Self::Zx | Self::Ry => DVec3::Y,
            Self::Z | Self::Xy | Self::Rz => DVec3::Z,
        }
    }

    /// What the handle does.
    pub fn kind(self) -> HandleKind {
        match self {
            Self::X | Self::Y | Self::Z => HandleKind::Arrow,
            Self::Xy | Self::Yz | Self::Zx => HandleKind::Plane,
            Self::Rx | Self::Ry | Self::Rz => HandleKind::Ring,
        }
    }

    /// Its colour: x red, y green, z blue.
    pub fn rgb(self) -> [u8; 3] {
        match self.axis() {
            a if a == DVec3::X => [230, 60, 60],
            a if a == DVec3::Y => [70, 200, 70],
            _ => [70, 120, 240],
        }
    }
}

/// Arrow, plane square or ring.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HandleKind {
    /// Moves along the axis.
    Arrow,
    /// Moves in the plane normal to the axis.
    Plane,
    /// Turns about the axis.
    Ring,
}

/// Two unit vectors spanning the plane normal to a world axis, right-handed
/// with it (`u × v = axis`).
fn plane_basis(axis: DVec3) -> (DVec3, DVec3) {
    let u = DVec3::new(axis.y, axis.z, axis.x);
    (u, axis.cross(u))
}

/// World points to the pixels of a view (y down), through a camera.
#[derive(Clone, Copy, Debug)]
pub struct Projector {
    clip_from_world: DMat4,
    size: DVec2,
}

impl Projector {
    /// The projection of `camera` in a view of `size` pixels.
    pub fn new(camera: &Camera, size: (u32, u32)) -> Self {
        let (w, h) = (f64::from(size.0.max(1)), f64::from(size.1.max(1)));
        Self {
            clip_from_world: camera.projection(w / h) * camera.view_matrix(),
            size: DVec2::new(w, h),
        }
    }

    /// A world point in view pixels, or `None` behind the eye.
    pub fn project(&self, p: DVec3) -> Option<DVec2> {
        let clip = self.clip_from_world * p.extend(1.0);
        (clip.w > 0.0).then(|| {
            let ndc = clip.truncate() / clip.w;
            DVec2::new(
                (ndc.x + 1.0) * 0.5 * self.size.x,
                (1.0 - ndc.y) * 0.5 * self.size.y,
            )
        })
    }
}

/// The gizmo of a selection seen by a camera in a view of `size` pixels.
#[derive(Clone, Copy, Debug)]
pub struct Gizmo {
    /// The selection's world box centre: where the arrows start and what the
    /// rings turn about.
    pub centre: DVec3,
    /// World length of an arrow (constant on screen).
    pub length: f64,
    projector: Projector,
}

impl Gizmo {
    /// The gizmo at `centre`, or `None` when the centre is behind the eye.
    pub fn new(camera: &Camera, size: (u32, u32), centre: DVec3) -> Option<Self> {
        let depth = (centre - camera.eye).dot((camera.target - camera.eye).normalize());
        // NaN (a camera without a direction) fails this too.
        if depth.partial_cmp(&camera.near) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let world_per_px = crate::nav::world_per_pixel(camera.fov_y_rad, depth, f64::from(size.1));
        Some(Self {
            centre,
            length: ARROW_PX * world_per_px,
            projector: Projector::new(camera, size),
        })
    }

    /// A world point in view pixels (y down), or `None` behind the eye.
    pub fn project(&self, p: DVec3) -> Option<DVec2> {
        self.projector.project(p)
    }

    /// The world polyline of a handle: the arrow's shaft, the square's
    /// outline (closed) or the ring (closed).
    pub fn outline(&self, handle: Handle) -> Vec<DVec3> {
        let (c, l, axis) = (self.centre, self.length, handle.axis());
        match handle.kind() {
            HandleKind::Arrow => vec![c + axis * (0.15 * l), c + axis * l],
            HandleKind::Plane => {
                let (u, v) = plane_basis(axis);
                let (a, b) = (0.25 * l, 0.45 * l);
                vec![
                    c + u * a + v * a,
                    c + u * b + v * a,
                    c + u * b + v * b,
                    c + u * a + v * b,
                    c + u * a + v * a,
                ]
            }
            HandleKind::Ring => {
                let (u, v) = plane_basis(axis);
                (0..=RING_SEGMENTS)
                    .map(|i| {
                        let t = std::f64::consts::TAU * i as f64 / RING_SEGMENTS as f64;
                        c + (u * t.cos() + v * t.sin()) * (0.75 * l)
                    })
                    .collect()
            }
        }
    }

    /// Where a script grabs a handle: near the arrow's tip, the square's
    /// centre, or a point of the ring between two arrows.
    pub fn grab_point(&self, handle: Handle) -> Option<DVec2> {
        let (c, l, axis) = (self.centre, self.length, handle.axis());
        let (u, v) = plane_basis(axis);
        let p = match handle.kind() {
            HandleKind::Arrow => c + axis * (0.8 * l),
            HandleKind::Plane => c + (u + v) * (0.35 * l),
            // 30° round from the arrow along u, clear of arrows and squares.
            HandleKind::Ring => c + (u * 0.75f64.sqrt() + v * 0.5) * (0.75 * l),
        };
        self.project(p)
    }

    /// The handle under the pointer at `at` (view pixels), if any: the
    /// nearest within reach, a plane square counting as 0 away inside it.
    pub fn handle_at(&self, at: DVec2) -> Option<Handle> {
        Handle::ALL
            .into_iter()
            .filter_map(|h| {
                let pts: Vec<DVec2> = self
                    .outline(h)
                    .iter()
                    .map(|&p| self.project(p))
                    .collect::<Option<_>>()?;
                let distance = if h.kind() == HandleKind::Plane && inside(&pts[..4], at) {
                    0.0
                } else {
                    pts.windows(2)
                        .map(|w| segment_distance(at, w[0], w[1]))
                        .fold(f64::INFINITY, f64::min)
                };
                (distance <= GRAB_PX).then_some((distance, h))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, h)| h)
    }

    /// Starts a drag of `handle` with the pointer's world ray.
    pub fn begin(&self, handle: Handle, ray: &Ray3d) -> Option<GizmoDrag> {
        let start = position(handle, self.centre, ray)?;
        Some(GizmoDrag {
            handle,
            centre: self.centre,
            start,
        })
    }
}

/// The pointer's position along (arrow), in (plane) or around (ring) a
/// handle about `centre`: an offset (in every component), a point relative to
/// the centre, or an angle in radians (in every component).
fn position(handle: Handle, centre: DVec3, ray: &Ray3d) -> Option<DVec3> {
    let axis = handle.axis();
    match handle.kind() {
        HandleKind::Arrow => crate::nav::axis_offset(centre, axis, ray).map(DVec3::splat),
        HandleKind::Plane | HandleKind::Ring => {
            let d = ray.dir.normalize();
            let denom = d.dot(axis);
            if denom.abs() < 1e-6 {
                return None;
            }
            let t = (centre - ray.origin).dot(axis) / denom;
            let p = ray.origin + d * t - centre;
            if handle.kind() == HandleKind::Plane {
                return Some(p);
            }
            let (u, v) = plane_basis(axis);
            Some(DVec3::splat(p.dot(v).atan2(p.dot(u))))
        }
    }
}

/// Snapping of gizmo drags.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snap {
    /// Offsets snap to multiples of this, model units (0: free).
    pub step: f64,
    /// Turns snap to multiples of this, degrees (0: free).
    pub degrees: f64,
}

impl Snap {
    /// Offset steps other than 0 (free): a step below this snaps to nothing a
    /// person can see, and one of 1e-320 turned every offset into infinity.
    pub const STEPS: std::ops::RangeInclusive<f64> = 1e-9..=1e12;
    /// Turn steps other than 0 (free), degrees.
    pub const DEGREES: std::ops::RangeInclusive<f64> = 1e-6..=360.0;

    /// Refuses steps that are neither 0 (free) nor in [`Snap::STEPS`] and
    /// [`Snap::DEGREES`]; `None` leaves a step as it is.
    pub fn check(step: Option<f64>, degrees: Option<f64>) -> anyhow::Result<()> {
        for (value, range, unit) in [
            (step, Self::STEPS, "model units"),
            (degrees, Self::DEGREES, "degrees"),
        ] {
            if let Some(v) = value {
                anyhow::ensure!(
                    v == 0.0 || range.contains(&v),
                    "snap step {} {unit}: give 0 (free) or {} to {}",
                    dmu_geom::Short(v),
                    dmu_geom::Short(*range.start()),
                    dmu_geom::Short(*range.end())
                );
            }
        }
        Ok(())
    }
}

/// `value` rounded to a multiple of `step` (unchanged for a step of 0, and
/// where the multiple is not a finite number).
pub fn snap_to(value: f64, step: f64) -> f64 {
    let snapped = (value / step).round() * step;
    if step > 0.0 && snapped.is_finite() {
        snapped
    } else {
        value
    }
}

/// A drag of a handle in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GizmoDrag {
    /// The handle dragged.
    pub handle: Handle,
    /// The gizmo's centre when the drag began (rings turn about it).
    pub centre: DVec3,
    /// The pointer's position on the handle when it began.
    start: DVec3,
}

impl GizmoDrag {
    /// The world transform that takes the part from where the drag began to
    /// where the pointer's `ray` puts it, snapped (`None`: free), or `None`
    /// when the ray runs parallel to the handle.
    pub fn delta(&self, ray: &Ray3d, snap: Option<Snap>) -> Option<DAffine3> {
        let now = position(self.handle, self.centre, ray)?;
        let snap = snap.unwrap_or(Snap {
            step: 0.0,
            degrees: 0.0,
        });
        let axis = self.handle.axis();
        Some(match self.handle.kind() {
            HandleKind::Arrow => {
                DAffine3::from_translation(axis * snap_to(now.x - self.start.x, snap.step))
            }
            HandleKind::Plane => {
                let (u, v) = plane_basis(axis);
                let d = now - self.start;
                DAffine3::from_translation(
                    u * snap_to(d.dot(u), snap.step) + v * snap_to(d.dot(v), snap.step),
                )
            }
            HandleKind::Ring => {
                let mut turn = now.x - self.start.x;
                // The shorter way round: atan2 jumps by a full turn at ±π.
                turn -= std::f64::consts::TAU * (turn / std::f64::consts::TAU).round();
                let degrees = snap_to(turn.to_degrees(), snap.degrees);
                turn_about(self.centre, axis, degrees)
            }
        })
    }
}

/// A turn of `degrees` about `axis` through `centre`, as a world transform.
pub fn turn_about(centre: DVec3, axis: DVec3, degrees: f64) -> DAffine3 {
    DAffine3::from_translation(centre)
        * DAffine3::from_quat(DQuat::from_axis_angle(axis, degrees.to_radians()))
        * DAffine3::from_translation(-centre)
}

/// Whether `p` is inside the convex polygon `poly` (either winding).
fn inside(poly: &[DVec2], p: DVec2) -> bool {
    let side = |i: usize| {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        (b - a).perp_dot(p - a)
    };
    let sides: Vec<f64> = (0..poly.len()).map(side).collect();
    sides.iter().all(|&s| s >= 0.0) || sides.iter().all(|&s| s <= 0.0)
}

/// Distance from `p` to the segment `a`–`b`.
fn segment_distance(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            eye: DVec3::new(4e6 + 300.0, 5e6 - 400.0, 250.0),
            target: DVec3::new(4e6, 5e6, 0.0),
            up: DVec3::Z,
            fov_y_rad: 50f64.to_radians(),
            near: 1.0,
        }
    }

    fn ray_at(camera: &Camera, size: (u32, u32), p: DVec2) -> Ray3d {
        crate::nav::ray_through(camera, size, p.x, p.y)
    }

    /// Each handle is found under its own grab point, 1e6 from the origin.
    #[test]
    fn grab_points_find_their_handles() {
        let (cam, size) = (camera(), (800, 600));
        let g = Gizmo::new(&cam, size, DVec3::new(4e6, 5e6, 0.0)).unwrap();
        for h in Handle::ALL {
            let at = g.grab_point(h).unwrap();
            assert_eq!(g.handle_at(at), Some(h), "{h:?} at {at}");
        }
        assert_eq!(g.handle_at(DVec2::new(5.0, 5.0)), None);
    }

    /// An arrow drag moves by the snapped offset along its axis only; a plane
    /// drag in its plane only; a ring turns by a multiple of the angle step.
    #[test]
    fn drags_follow_the_pointer_and_snap() {
        let (cam, size) = (camera(), (800, 600));
        let g = Gizmo::new(&cam, size, DVec3::new(4e6, 5e6, 0.0)).unwrap();
        let snap = Some(Snap {
            step: 5.0,
            degrees: 15.0,
        });
        for h in Handle::ALL {
            let from = g.grab_point(h).unwrap();
            let drag = g.begin(h, &ray_at(&cam, size, from)).unwrap();
            let still = drag.delta(&ray_at(&cam, size, from), snap).unwrap();
            assert_eq!(still, DAffine3::IDENTITY, "{h:?} unmoved");
            let to = from + DVec2::new(60.0, -35.0);
            let d = drag.delta(&ray_at(&cam, size, to), snap).unwrap();
            match h.kind() {
                HandleKind::Arrow => {
                    let s = d.translation.dot(h.axis());
                    assert!(s != 0.0 && (s / 5.0).fract() == 0.0, "{h:?}: {s}");
                    assert_eq!(d.translation, h.axis() * s);
                }
                HandleKind::Plane => {
                    assert_eq!(d.translation.dot(h.axis()), 0.0, "{h:?}");
                    for c in d.translation.to_array() {
                        assert_eq!((c / 5.0).fract(), 0.0, "{h:?}: {c}");
                    }
                    assert!(d.translation.length() > 0.0);
                }
                HandleKind::Ring => {
                    let (axis, angle) = DQuat::from_mat3(&d.matrix3).to_axis_angle();
                    let degrees = angle.to_degrees();
                    assert!(
                        (degrees / 15.0 - (degrees / 15.0).round()).abs() < 1e-9,
                        "{h:?}: {degrees}"
                    );
                    assert!(degrees > 1.0, "{h:?} turned");
                    assert!(axis.cross(h.axis()).length() < 1e-9);
                    // The centre stays put.
                    assert!(d.transform_point3(g.centre).abs_diff_eq(g.centre, 1e-6));
                }
            }
        }
    }
}
