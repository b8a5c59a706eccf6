//! Issues in BCF: the review's clashes and saved viewpoints as BCF topics
//! (each with its viewpoint: camera, parts, visibility, section), and BCF
//! topics from any tool as viewpoints to go to. The archive itself is
//! [`dmu_app::bcf`]'s; snapshots are taken by the app, a frame per topic.

use dmu_app::bcf::{self, ClashIssue, ClippingPlane, Component, Topic, Visibility};
use dmu_scene::PartId;
use glam::DVec3;

use crate::review::{ListedClash, Review};
use crate::section::Section;
use crate::viewpoints::Viewpoint;

/// Who the viewer's topics are by.
pub const AUTHOR: &str = "dmu-viewer";

/// A topic to write, and the view its snapshot is taken from.
#[derive(Clone, Debug, PartialEq)]
pub struct Issue {
    /// The topic (its one viewpoint's snapshot filled in once taken).
    pub topic: Topic,
    /// The view: camera, selection, hidden parts, section.
    pub view: Viewpoint,
}

/// What a topic says of a listed clash: the same as `dmu collide --bcf`
/// says of a pair (titled with its worst finding, the others listed).
fn clash_issue<'a>(review: &'a Review, c: &ListedClash) -> ClashIssue<'a> {
    let scene = &review.scene;
    ClashIssue {
        parts: [scene.part_name(c.a), scene.part_name(c.b)],
        described: [scene.part_path(c.a), scene.part_path(c.b)],
        kind: c.kind,
        distance: c.distance,
        toi: None,
        point: c.point,
        when: String::new(),
        others: c.others.iter().map(|&k| (k, String::new())).collect(),
        found: format!("Found {}.", c.source),
        prefix: String::new(),
    }
}

/// The view that shows a listed clash: its two parts alone, seen by the
/// clash camera `dmu collide --bcf` uses, the first selected.
pub fn clash_view(review: &Review, c: &ListedClash, near: f64) -> Viewpoint {
    let bounds = crate::clashes::pair_bounds(review, c.a, c.b);
    let camera = bcf::clash_camera(&bounds, |_| near);
    Viewpoint {
        name: clash_issue(review, c).title(),
        eye: camera.eye,
        forward: (camera.target - camera.eye).normalize(),
        fov_y_rad: camera.fov_y_rad,
        pivot_distance: camera.target.distance(camera.eye),
        selected: Some(c.a),
        hidden: review
            .scene
            .part_ids()
            .filter(|&p| p != c.a && p != c.b)
            .collect(),
        section: Section::Off,
    }
}

/// The issues of a review: one per listed clash (type `Clash`, its view
/// with a near plane at `near`), then one per saved viewpoint (type `Issue`).
pub fn issues(review: &Review, viewpoints: &[Viewpoint], near: f64) -> Vec<Issue> {
    let clashes = review.clash_list.iter().map(|c| {
        let view = clash_view(review, c, near);
        let topic = clash_issue(review, c).topic(AUTHOR, bcf_viewpoint(review, &view));
        Issue { topic, view }
    });
    let saved = viewpoints.iter().map(|v| {
        let mut topic = Topic::new(v.name.clone(), AUTHOR);
        topic.topic_type = "Issue".to_owned();
        topic.description = format!(
            "Viewpoint {:?} saved in dmu-viewer ({}).",
            v.name,
            v.section.describe()
        );
        topic.viewpoints.push(bcf_viewpoint(review, v));
        Issue {
            topic,
            view: v.clone(),
        }
    });
    clashes.chain(saved).collect()
}

/// A viewer viewpoint as a BCF viewpoint (no snapshot yet).
pub fn bcf_viewpoint(review: &Review, v: &Viewpoint) -> bcf::Viewpoint {
    let scene = &review.scene;
    let component = |p: PartId| Component::of(scene, p);
    let camera = dmu_geom::Camera {
        eye: v.eye,
        target: v.eye + v.forward * v.pivot_distance.max(1e-9),
        up: DVec3::Z,
        fov_y_rad: v.fov_y_rad,
        near: 1.0,
    };
    // Visibility by the shorter list: the hidden parts, or the shown ones.
    let parts = scene.parts().len();
    let visibility = if v.hidden.len() * 2 > parts {
        Visibility {
            default_visible: false,
            exceptions: scene
                .part_ids()
                .filter(|p| !v.hidden.contains(p))
                .map(component)
                .collect(),
        }
    } else {
        Visibility {
            default_visible: true,
            exceptions: v.hidden.iter().map(|&p| component(p)).collect(),
        }
    };
    let bounds = review.tree.bounds();
    let clipping_planes = v
        .section
        .planes()
        .iter()
        .zip(v.section.handles(&bounds))
        .map(|(plane, (location, _))| ClippingPlane {
            location,
            // BCF's direction points into what is hidden.
            direction: -plane.normal,
        })
        .collect();
    bcf::Viewpoint {
        camera: Some(bcf::Camera::perspective(&camera)),
        selected: v.selected.into_iter().map(component).collect(),
        visibility,
        clipping_planes,
        ..bcf::Viewpoint::new()
    }
}

/// What importing topics found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Imported {
    /// A viewpoint per topic with a perspective camera, named by its title.
    pub viewpoints: Vec<Viewpoint>,
    /// Components naming no part of the model (skipped).
    pub unknown_components: usize,
    /// Topics left out: no viewpoint, or only an orthographic camera.
    pub skipped_topics: usize,
}

/// The topics' first viewpoints as the viewer's: camera, selection (parts
/// found by `IfcGuid`, else by `AuthoringToolId`, the node name), hidden parts, and clipping
/// planes as a section. More than [`dmu_render::MAX_SECTION_PLANES`] planes
/// in a viewpoint is an error naming the topic.
pub fn import(review: &Review, topics: &[Topic], pivot_distance: f64) -> anyhow::Result<Imported> {
    let scene = &review.scene;
    let mut out = Imported::default();
    let mut find = |c: &Component| {
        let part = c.find(scene);
        if part.is_none() {
            out.unknown_components += 1;
        }
        part
    };
    let mut viewpoints = Vec::new();
    for topic in topics {
        let Some((v, camera)) = topic
            .viewpoints
            .iter()
            .find_map(|v| Some((v, v.camera?.to_view(pivot_distance, 1.0)?)))
        else {
            out.skipped_topics += 1;
            continue;
        };
        let mut section = Section::Off;
        anyhow::ensure!(
            v.clipping_planes.len() <= dmu_render::MAX_SECTION_PLANES,
            "topic {:?}: {} clipping planes, the viewer cuts with at most {}",
            topic.title,
            v.clipping_planes.len(),
            dmu_render::MAX_SECTION_PLANES
        );
        for p in &v.clipping_planes {
            section
                .add_plane(p.location, -p.direction)
                .map_err(|e| anyhow::anyhow!("topic {:?}: {e}", topic.title))?;
        }
        let listed: Vec<PartId> = v
            .visibility
            .exceptions
            .iter()
            .filter_map(&mut find)
            .collect();
        let hidden = if v.visibility.default_visible {
            listed
        } else {
            scene.part_ids().filter(|p| !listed.contains(p)).collect()
        };
        let selected = v.selected.iter().find_map(&mut find);
        viewpoints.push(Viewpoint {
            name: topic.title.clone(),
            eye: camera.eye,
            forward: (camera.target - camera.eye).normalize(),
            fov_y_rad: camera.fov_y_rad,
            pivot_distance,
            selected,
            hidden,
            section,
        });
    }
    out.viewpoints = viewpoints;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::review::list_clash;

    /// Issues written and read back give the same viewpoints: camera,
    /// selection, hidden parts and section (planes round-trip through BCF's
    /// "direction points into the hidden side").
    #[test]
    fn issues_round_trip_through_a_bcf_file() {
        let mut review = Review::new(dmu_samples::grid(3, 10.0, 4.0, 2048), None);
        let (a, b) = (PartId(0), PartId(1));
        list_clash(
            &mut review.clash_list,
            ListedClash {
                a,
                b,
                kind: dmu_collide::FindingKind::Hard,
                others: Vec::new(),
                distance: 0.0,
                point: DVec3::new(5.0, 0.0, 0.0),
                source: "live".to_owned(),
            },
        );
        let mut saved = Viewpoint {
            name: "corner".to_owned(),
            eye: DVec3::new(-30.0, -40.0, 25.0),
            forward: DVec3::new(0.6, 0.8, -0.2).normalize(),
            fov_y_rad: 50f64.to_radians(),
            pivot_distance: 40.0,
            selected: Some(PartId(4)),
            hidden: vec![PartId(2), PartId(7)],
            section: Section::Off,
        };
        saved
            .section
            .add_plane(DVec3::new(0.0, 0.0, 12.0), -DVec3::Z)
            .unwrap();
        saved
            .section
            .add_plane(DVec3::new(3.0, 1.0, 0.0), DVec3::new(1.0, 1.0, 0.0))
            .unwrap();
        let issues = issues(&review, std::slice::from_ref(&saved), 0.1);
        assert_eq!(issues.len(), 2);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("issues.bcfzip");
        let topics: Vec<Topic> = issues.iter().map(|i| i.topic.clone()).collect();
        bcf::write_bcfzip(&path, &topics, Some("grid"), 1000.0).unwrap();
        let read = bcf::read_bcfzip(&path, 1000.0).unwrap();
        let imported = import(&review, &read, 40.0).unwrap();
        assert_eq!(
            (imported.unknown_components, imported.skipped_topics),
            (0, 0)
        );
        for (got, want) in imported
            .viewpoints
            .iter()
            .zip(issues.iter().map(|i| &i.view))
        {
            assert_eq!(got.name, want.name);
            assert!(
                got.eye.abs_diff_eq(want.eye, 1e-9),
                "{} vs {}",
                got.eye,
                want.eye
            );
            assert!(got.forward.abs_diff_eq(want.forward, 1e-12));
            assert!((got.fov_y_rad - want.fov_y_rad).abs() < 1e-12);
            assert_eq!(got.selected, want.selected);
            let mut hidden = got.hidden.clone();
            hidden.sort();
            assert_eq!(hidden, want.hidden);
            let (gp, wp) = (got.section.planes(), want.section.planes());
            assert_eq!(gp.len(), wp.len());
            for (g, w) in gp.iter().zip(&wp) {
                assert!(
                    g.normal.abs_diff_eq(w.normal, 1e-12) && (g.d - w.d).abs() < 1e-9,
                    "{g:?} vs {w:?}"
                );
            }
        }
        // The clash's view shows its two parts alone.
        assert_eq!(imported.viewpoints[0].hidden.len(), 25);
    }
}
