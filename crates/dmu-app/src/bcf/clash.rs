//! One clashing pair as a BCF topic, and the camera that shows it: the same
//! from `dmu collide --bcf` and from the viewer, so a reviewer gets the same
//! title, description and framing from either.

use dmu_collide::FindingKind;
use dmu_geom::{Aabb3d, Camera, Short};
use glam::DVec3;

use super::{Topic, Viewpoint};

/// The direction a clash is looked at: from the +X, −Y, +Z side (the
/// viewer's iso view), so both parts and the gap between them show.
pub const CLASH_VIEW_FORWARD: DVec3 = DVec3::new(-1.0, 1.0, -1.0);
/// The clash camera's vertical field of view, degrees (the viewer's default).
pub const CLASH_FOV_Y_DEG: f64 = 60.0;

/// The camera of a clash: from [`CLASH_VIEW_FORWARD`] at `bounds` (both
/// parts' boxes; for an impact, the part hit and the point of impact), framed
/// as the viewer frames a selection, its near plane `near(eye)` for the
/// framed eye (the caller knows what stands near it).
pub fn clash_camera(bounds: &Aabb3d, near: impl Fn(DVec3) -> f64) -> Camera {
    let framed = |near| {
        Camera::framing(
            bounds,
            CLASH_VIEW_FORWARD,
            DVec3::Z,
            CLASH_FOV_Y_DEG.to_radians(),
            near,
        )
    };
    let first = framed(bounds.extent().length().max(1e-3) * 1e-4);
    framed(near(first.eye))
}

/// What a topic says of one clashing pair: its worst finding (hard over
/// impact over contact over soft, [`FindingKind`]'s order) in the title, the
/// other kinds it showed in the description.
#[derive(Clone, Debug, PartialEq)]
pub struct ClashIssue<'a> {
    /// The parts' names, the moved part first: the title's and the
    /// components'.
    pub parts: [&'a str; 2],
    /// How the description names each part (its path in the assembly, or
    /// its name and id).
    pub described: [String; 2],
    /// The worst finding's kind.
    pub kind: FindingKind,
    /// The worst finding's distance (0 when hard), model units.
    pub distance: f64,
    /// For an impact, the fraction of the move at which it happens.
    pub toi: Option<f64>,
    /// Where the worst finding is, world.
    pub point: DVec3,
    /// When it was seen, said after the parts in the title and the
    /// description (" at step 3 (t=3)"); empty when there is no time.
    pub when: String,
    /// The pair's other kinds, worst first, each with when it was seen
    /// ("at 2 steps from step 1 (t=1)"; empty when there is no time).
    pub others: Vec<(FindingKind, String)>,
    /// Whatever else the description ends with (how it was found, the
    /// record, the clearance).
    pub found: String,
    /// Put before the title (the record's name in a batch); empty for none.
    pub prefix: String,
}

impl ClashIssue<'_> {
    /// "hard: pump_3 × pipe_17 at step 3 (t=3)".
    pub fn title(&self) -> String {
        let [a, b] = self.parts;
        format!("{}{}: {a} × {b}{}", self.prefix, self.kind, self.when)
    }

    /// The topic (type `Clash`, labelled with every kind the pair showed and
    /// `author`), its one viewpoint `viewpoint`.
    pub fn topic(&self, author: &str, viewpoint: Viewpoint) -> Topic {
        let [a, b] = &self.described;
        let measure = match self.toi {
            Some(toi) => format!("impact at {toi:.6} of the move"),
            None => format!("distance {:.6}", self.distance),
        };
        let p = self.point;
        let mut description = format!(
            "{} between {a} and {b}{}: {measure}, at [{:.3}, {:.3}, {:.3}] (model units).",
            self.kind, self.when, p.x, p.y, p.z
        );
        for (kind, when) in &self.others {
            let space = if when.is_empty() { "" } else { " " };
            description.push_str(&format!(" Also {kind}{space}{when}."));
        }
        if !self.found.is_empty() {
            description.push(' ');
            description.push_str(&self.found);
        }
        let mut topic = Topic::new(self.title(), author);
        topic.description = description;
        topic.topic_type = "Clash".to_owned();
        topic.labels = std::iter::once(self.kind)
            .chain(self.others.iter().map(|(k, _)| *k))
            .map(|k| k.as_str().to_owned())
            .chain([author.to_owned()])
            .collect();
        topic.viewpoints.push(viewpoint);
        topic
    }
}

/// When a finding was seen in a record: " at step 3 (t=3)".
pub fn at_step(step: usize, t: f64) -> String {
    format!(" at step {step} (t={})", Short(t))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn issue() -> ClashIssue<'static> {
        ClashIssue {
            parts: ["pump_3", "pipe_17"],
            described: ["plant/pump_3".to_owned(), "plant/pipe_17".to_owned()],
            kind: FindingKind::Hard,
            distance: 0.0,
            toi: None,
            point: DVec3::new(1.0, 2.0, 3.0),
            when: at_step(7, 0.7),
            others: vec![(
                FindingKind::Soft,
                "at 2 steps from step 5 (t=0.5)".to_owned(),
            )],
            found: "Found by dmu collide.".to_owned(),
            prefix: String::new(),
        }
    }

    /// The title names the worst finding; the description and the labels
    /// list the others.
    #[test]
    fn a_topic_names_its_worst_finding_and_lists_the_others() {
        let topic = issue().topic("dmu collide", Viewpoint::new());
        assert_eq!(topic.title, "hard: pump_3 × pipe_17 at step 7 (t=0.7)");
        assert_eq!(topic.topic_type, "Clash");
        assert_eq!(topic.labels, ["hard", "soft", "dmu collide"]);
        assert_eq!(
            topic.description,
            "hard between plant/pump_3 and plant/pipe_17 at step 7 (t=0.7): distance 0.000000, \
             at [1.000, 2.000, 3.000] (model units). Also soft at 2 steps from step 5 (t=0.5). \
             Found by dmu collide."
        );
    }

    /// The clash camera sees every corner of the box it frames, from the iso
    /// side, with the near plane asked for.
    #[test]
    fn the_clash_camera_frames_the_pair() {
        let bounds = Aabb3d::new(
            DVec3::new(1e6, 1e6, 0.0),
            DVec3::new(1e6 + 20.0, 1e6 + 4.0, 3.0),
        );
        let camera = clash_camera(&bounds, |_| 0.25);
        assert_eq!(camera.near, 0.25);
        let forward = (camera.target - camera.eye).normalize();
        assert!(forward.abs_diff_eq(CLASH_VIEW_FORWARD.normalize(), 1e-9));
        let right = forward.cross(DVec3::Z).normalize();
        let up = right.cross(forward);
        let tan = (CLASH_FOV_Y_DEG.to_radians() / 2.0).tan();
        for i in 0..8 {
            let corner = DVec3::new(
                if i & 1 == 0 {
                    bounds.min.x
                } else {
                    bounds.max.x
                },
                if i & 2 == 0 {
                    bounds.min.y
                } else {
                    bounds.max.y
                },
                if i & 4 == 0 {
                    bounds.min.z
                } else {
                    bounds.max.z
                },
            );
            let d = corner - camera.eye;
            let z = d.dot(forward);
            assert!(z > camera.near, "corner {corner} behind the near plane");
            assert!(d.dot(up).abs() <= z * tan + 1e-9 && d.dot(right).abs() <= z * tan + 1e-9);
        }
    }
}
