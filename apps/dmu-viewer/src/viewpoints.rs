//! Named viewpoints: the camera, the selection, the hidden parts and the
//! section, saved during a review and gone back to (and written to BCF).

use dmu_scene::PartId;
use glam::DVec3;
use serde_json::Value;

use crate::nav::Navigator;
use crate::review::Review;
use crate::section::Section;

/// A saved view of the review.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    /// Its name.
    pub name: String,
    /// The eye, world.
    pub eye: DVec3,
    /// The unit view direction.
    pub forward: DVec3,
    /// Vertical field of view, radians.
    pub fov_y_rad: f64,
    /// The orbit pivot's distance ahead of the eye.
    pub pivot_distance: f64,
    /// The selected part.
    pub selected: Option<PartId>,
    /// The hidden parts.
    pub hidden: Vec<PartId>,
    /// The section.
    pub section: Section,
}

impl Viewpoint {
    /// The view as it is now.
    pub fn capture(name: &str, nav: &Navigator, review: &Review) -> Self {
        Self {
            name: name.to_owned(),
            eye: nav.eye,
            forward: nav.forward(),
            fov_y_rad: nav.fov_y_rad,
            pivot_distance: nav.pivot.distance(nav.eye),
            selected: review.selected,
            hidden: review
                .scene
                .part_ids()
                .filter(|&p| review.scene.part(p).hidden)
                .collect(),
            section: review.section.clone(),
        }
    }

    /// Goes back to the view: camera, hidden parts, section and selection
    /// (parts the model no longer has are skipped).
    pub fn apply(&self, nav: &mut Navigator, review: &mut Review) {
        nav.look_along(self.eye, self.forward, self.pivot_distance);
        if self.fov_y_rad.is_finite()
            && self.fov_y_rad > 0.0
            && self.fov_y_rad < std::f64::consts::PI
        {
            nav.fov_y_rad = self.fov_y_rad;
        }
        let parts = review.scene.parts().len();
        for p in review.scene.part_ids() {
            review.scene.set_part_hidden(p, false);
        }
        for &p in self.hidden.iter().filter(|p| p.index() < parts) {
            review.scene.set_part_hidden(p, true);
        }
        review.section = self.section.clone();
        review.select(self.selected.filter(|p| p.index() < parts));
    }

    /// For the report of an automated run.
    pub fn json(&self) -> Value {
        let facts = ViewpointFacts {
            name: &self.name,
            eye: self.eye.to_array(),
            forward: self.forward.to_array(),
            fov_y_deg: self.fov_y_rad.to_degrees(),
            selected: self.selected.map(|p| p.0),
            hidden: self.hidden.len(),
            section: self.section.describe(),
        };
        serde_json::to_value(facts).expect("plain data")
    }
}

/// A viewpoint in a report: its camera, selection, how many parts it hides
/// and its section in words.
#[derive(Debug, serde::Serialize)]
struct ViewpointFacts<'a> {
    name: &'a str,
    eye: [f64; 3],
    forward: [f64; 3],
    fov_y_deg: f64,
    selected: Option<u32>,
    hidden: usize,
    section: String,
}
