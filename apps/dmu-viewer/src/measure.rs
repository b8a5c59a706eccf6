//! Measurement: point to point (snapped to the vertices, edges or faces
//! picked), the minimum distance between two parts with its closest points
//! (the collision check's own f64 narrow phase), and the angle between two
//! faces. Lengths are model units (millimetres in the plant).

use dmu_collide::Separation;
use dmu_scene::{PartId, Scene};
use dmu_tree::Hit;
use glam::DVec3;
use serde::Deserialize;
use serde_json::Value;

use crate::review::Review;

/// How near (pixels on screen) a picked point must be to a vertex or an edge
/// of the triangle hit to snap to it.
pub const SNAP_PX: f64 = 8.0;

/// What a click measures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MeasureMode {
    /// Clicks pick and select.
    #[default]
    Off,
    /// Two clicks: the distance between two (snapped) points.
    Points,
    /// Two clicks: the minimum distance between the two parts clicked.
    Parts,
    /// Two clicks: the angle between the two faces clicked.
    Angle,
}

/// What a picked point snapped to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SnapKind {
    /// A vertex of the triangle hit.
    Vertex,
    /// The nearest point of an edge of the triangle hit.
    Edge,
    /// The point hit on the face.
    Face,
}

impl SnapKind {
    /// `vertex`, `edge` or `face`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vertex => "vertex",
            Self::Edge => "edge",
            Self::Face => "face",
        }
    }
}

/// A picked point, snapped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snapped {
    /// The part hit.
    pub part: PartId,
    /// The world point (f64).
    pub point: DVec3,
    /// The face's unit world normal, facing the eye.
    pub normal: DVec3,
    /// What the point snapped to.
    pub snap: SnapKind,
}

/// The point of a hit snapped to the hit triangle's nearest vertex, else its
/// nearest edge, when within `tolerance` (world units) of the hit point.
pub fn snap(scene: &Scene, hit: &Hit, tolerance: f64) -> Snapped {
    let world = scene.part_world(hit.part);
    let corners = scene
        .triangle_local(scene.part(hit.part).mesh, hit.chunk, hit.triangle)
        .map(|v| world.transform_point3(v.as_dvec3()));
    let nearest = |points: &mut dyn Iterator<Item = DVec3>| {
        points.min_by(|a, b| a.distance(hit.point).total_cmp(&b.distance(hit.point)))
    };
    let vertex = nearest(&mut corners.iter().copied()).expect("three corners");
    let edge = nearest(
        &mut (0..3).map(|i| closest_on_segment(hit.point, corners[i], corners[(i + 1) % 3])),
    )
    .expect("three edges");
    let (point, snap) = if vertex.distance(hit.point) <= tolerance {
        (vertex, SnapKind::Vertex)
    } else if edge.distance(hit.point) <= tolerance {
        (edge, SnapKind::Edge)
    } else {
        (hit.point, SnapKind::Face)
    };
    Snapped {
        part: hit.part,
        point,
        normal: hit.normal,
        snap,
    }
}

/// The point of segment `a`–`b` nearest `p`.
fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 == 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
}

/// A finished measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Measurement {
    /// Between two points.
    Points(Snapped, Snapped),
    /// The minimum distance between two parts.
    Parts(PartId, PartId, Separation),
    /// Between the faces of two points.
    Angle(Snapped, Snapped),
}

impl Measurement {
    /// The two world points to draw the measurement between.
    pub fn ends(&self) -> (DVec3, DVec3) {
        match self {
            Self::Points(a, b) | Self::Angle(a, b) => (a.point, b.point),
            Self::Parts(_, _, s) => (s.point_a, s.point_b),
        }
    }

    /// The label: a distance in model units, or an angle in degrees.
    pub fn label(&self) -> String {
        match self {
            Self::Points(a, b) => format!("{:.3} mm", a.point.distance(b.point)),
            Self::Parts(_, _, s) if s.penetrating => "0 mm (the parts cross)".to_owned(),
            Self::Parts(_, _, s) => format!("{:.3} mm", s.distance),
            Self::Angle(a, b) => format!("{:.3}°", angle_degrees(a.normal, b.normal)),
        }
    }

    /// For the report of an automated run.
    pub fn json(&self, scene: &Scene) -> Value {
        let point = |s: &Snapped| PointFacts {
            part: scene.part_name(s.part),
            part_id: s.part.0,
            point: s.point.to_array(),
            normal: s.normal.to_array(),
            snap: s.snap.name(),
        };
        const UNIT: &str = "model units (mm)";
        let facts = match self {
            Self::Points(a, b) => MeasurementFacts::Points {
                a: point(a),
                b: point(b),
                distance: a.point.distance(b.point),
                unit: UNIT,
            },
            Self::Parts(a, b, s) => MeasurementFacts::Parts {
                a: scene.part_name(*a),
                b: scene.part_name(*b),
                a_id: a.0,
                b_id: b.0,
                distance: s.distance,
                point_a: s.point_a.to_array(),
                point_b: s.point_b.to_array(),
                penetrating: s.penetrating,
                unit: UNIT,
            },
            Self::Angle(a, b) => MeasurementFacts::Angle {
                a: point(a),
                b: point(b),
                degrees: angle_degrees(a.normal, b.normal),
            },
        };
        serde_json::to_value(facts).expect("plain data")
    }
}

/// A measurement in a report, by kind.
#[derive(Debug, serde::Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
enum MeasurementFacts<'a> {
    Points {
        a: PointFacts<'a>,
        b: PointFacts<'a>,
        distance: f64,
        unit: &'static str,
    },
    Parts {
        a: &'a str,
        b: &'a str,
        a_id: u32,
        b_id: u32,
        distance: f64,
        point_a: [f64; 3],
        point_b: [f64; 3],
        penetrating: bool,
        unit: &'static str,
    },
    Angle {
        a: PointFacts<'a>,
        b: PointFacts<'a>,
        degrees: f64,
    },
}

/// A snapped point in a report.
#[derive(Debug, serde::Serialize)]
struct PointFacts<'a> {
    part: &'a str,
    part_id: u32,
    point: [f64; 3],
    normal: [f64; 3],
    snap: &'static str,
}

/// The angle between two unit normals, degrees (0 to 180).
pub fn angle_degrees(a: DVec3, b: DVec3) -> f64 {
    // atan2 of the cross and dot products stays exact near 0 and 180.
    a.cross(b).length().atan2(a.dot(b)).to_degrees()
}

/// The measuring tool: its mode, the first point of a measurement in
/// progress, and the last result.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeasureTool {
    /// What clicks measure.
    pub mode: MeasureMode,
    /// The first click of a measurement in progress.
    pub first: Option<Snapped>,
    /// The last measurement.
    pub result: Option<Measurement>,
}

impl MeasureTool {
    /// Switches the mode (forgetting a half-made measurement).
    pub fn set_mode(&mut self, mode: MeasureMode) {
        self.mode = mode;
        self.first = None;
    }

    /// A click that hit `point`: the first of a pair is kept, the second
    /// completes the measurement, which is returned. Two parts with no
    /// distance (no triangles) measure nothing.
    pub fn click(&mut self, review: &mut Review, point: Snapped) -> Option<Measurement> {
        let Some(first) = self.first.take() else {
            self.first = Some(point);
            return None;
        };
        let m = match self.mode {
            MeasureMode::Off => return None,
            MeasureMode::Points => Measurement::Points(first, point),
            MeasureMode::Angle => Measurement::Angle(first, point),
            MeasureMode::Parts => {
                let s = review.distance(first.part, point.part)?;
                Measurement::Parts(first.part, point.part, s)
            }
        };
        self.result = Some(m);
        Some(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmu_geom::Ray3d;

    /// A hit near a corner snaps to it, near an edge to the edge, else stays.
    #[test]
    fn picks_snap_to_vertices_then_edges() {
        let mut review = Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
        // Box box_0_0_0 spans -2..2; look down at its top face (z = 2) from
        // below the layer above.
        let mut shot = |x: f64, y: f64| {
            let hit = review
                .pick(&Ray3d::new(DVec3::new(x, y, 5.0), -DVec3::Z))
                .expect("hit");
            snap(&review.scene, &hit, 0.3)
        };
        let corner = shot(1.9, 1.85);
        assert_eq!(corner.snap, SnapKind::Vertex);
        assert_eq!(corner.point, DVec3::new(2.0, 2.0, 2.0));
        let edge = shot(1.9, 0.5);
        assert_eq!(edge.snap, SnapKind::Edge);
        assert!(edge.point.abs_diff_eq(DVec3::new(2.0, 0.5, 2.0), 1e-12));
        let face = shot(0.3, -0.4);
        assert_eq!(face.snap, SnapKind::Face);
        assert!(face.point.abs_diff_eq(DVec3::new(0.3, -0.4, 2.0), 1e-12));
        assert!(face.normal.abs_diff_eq(DVec3::Z, 1e-12));
    }

    /// Two parts measure their gap (the boxes' faces 6 apart); faces at right
    /// angles measure 90°, parallel ones 0°.
    #[test]
    fn parts_and_angles() {
        let mut review = Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
        let top = |review: &mut Review, x: f64| {
            let hit = review
                .pick(&Ray3d::new(DVec3::new(x, 0.0, 5.0), -DVec3::Z))
                .unwrap();
            snap(&review.scene, &hit, 0.0)
        };
        let side = {
            let hit = review
                .pick(&Ray3d::new(DVec3::new(-50.0, 0.0, 0.5), DVec3::X))
                .unwrap();
            snap(&review.scene, &hit, 0.0)
        };
        let mut tool = MeasureTool::default();
        // Clicks the top face at `x` (picking it first).
        let mut click_top = |tool: &mut MeasureTool, x: f64| {
            let p = top(&mut review, x);
            tool.click(&mut review, p)
        };
        tool.set_mode(MeasureMode::Parts);
        assert!(click_top(&mut tool, 0.0).is_none());
        let m = click_top(&mut tool, 10.0).unwrap();
        let Measurement::Parts(_, _, s) = m else {
            panic!("{m:?}")
        };
        assert!((s.distance - 6.0).abs() < 1e-12, "{s:?}");
        assert!((s.point_a.x - 2.0).abs() < 1e-12 && (s.point_b.x - 8.0).abs() < 1e-12);
        tool.set_mode(MeasureMode::Angle);
        click_top(&mut tool, 0.0);
        let right = tool.click(&mut review, side).unwrap();
        assert!((angle_degrees(DVec3::Z, -DVec3::X) - 90.0).abs() < 1e-12);
        assert_eq!(right.label(), "90.000°");
        let mut click_top = |tool: &mut MeasureTool, x: f64| {
            let p = top(&mut review, x);
            tool.click(&mut review, p)
        };
        click_top(&mut tool, 0.0);
        assert_eq!(click_top(&mut tool, 10.0).unwrap().label(), "0.000°");
    }
}
