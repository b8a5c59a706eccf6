//! Every user action as a [`Command`]: the panels' buttons, keyboard
//! shortcuts, automation scripts and the XR hands all emit one, and one
//! place applies it. What acts on the review and its tools alone
//! ([`ReviewCommand`]) is applied here, with no window ([`apply`]); what acts
//! on the view (panes, cameras, the pointer, a BCF export's frames) is a
//! [`ViewCommand`], which the application applies and hands the rest on to
//! [`apply`].

use std::path::PathBuf;

use anyhow::Context as _;
use dmu_render::Culling;
use dmu_scene::PartId;
use glam::{DAffine3, DVec3};

use crate::measure::{MeasureMode, Measurement};
use crate::nav::{Keys, Motion, Preset};
use crate::record::Recorder;
use crate::review::{Review, Saved};
use crate::script::{Axis, Overlays};
use crate::section::Section;
use crate::settings::Occlusion;
use crate::tools::Tools;
use crate::viewpoints::Viewpoint;

/// A point of a 3D pane in physical pixels (origin top-left, y down).
pub type ViewPoint = (f64, f64);

/// A user action.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// On the review and its tools ([`apply`]).
    Review(ReviewCommand),
    /// On the view (the application applies it).
    View(ViewCommand),
}

/// An action on the review (selection, moves, collision, section, files)
/// or its tools' state.
#[derive(Clone, Debug, PartialEq)]
pub enum ReviewCommand {
    /// Selects a part, or nothing.
    Select(Option<PartId>),
    /// Moves the selection by a world offset (one undoable edit).
    Translate(DVec3),
    /// Turns the selection about a world axis through its box centre.
    Rotate {
        /// The unit axis.
        axis: DVec3,
        /// The angle, degrees.
        degrees: f64,
    },
    /// Starts dragging the selection (the edit ends with [`Self::EndDrag`]).
    BeginDrag,
    /// Drags the selection to a world offset from where the drag began.
    DragTo(DVec3),
    /// Drags the selection to a world transform of where the drag began (a
    /// gizmo's drag).
    DragBy(DAffine3),
    /// Ends the drag: one undoable edit.
    EndDrag,
    /// Undoes the last edit.
    Undo,
    /// Redoes the last undone edit.
    Redo,
    /// Hides a part.
    Hide(PartId),
    /// Hides every part but one.
    Isolate(PartId),
    /// Shows every part.
    ShowAll,
    /// Sets the collision clearance (model units) and checks again.
    Clearance(f64),
    /// Turns the collision check of moves on or off, and checks again.
    LiveCollision(bool),
    /// Records the session's moves to a file, or stops recording.
    Record(Option<PathBuf>),
    /// Saves the model with its edits.
    Save(PathBuf),
    /// Adds the clashes of a `dmu collide --json` report to the list.
    LoadClashes(PathBuf),
    /// Measures the distance between two parts.
    MeasureParts(PartId, PartId),
    /// Switches what clicks measure.
    MeasureMode(MeasureMode),
    /// Sets what cuts the model open.
    Section(Section),
    /// Adds a section plane through `point`, keeping the side `normal` points to.
    SectionPlane {
        /// A world point of the plane.
        point: DVec3,
        /// The normal, toward what is kept.
        normal: DVec3,
    },
    /// Sets a section box.
    SectionBox {
        /// The low corner, world.
        min: DVec3,
        /// The high corner, world.
        max: DVec3,
    },
    /// Whether the next click places a section plane on the face under it.
    SectionOnFace(bool),
    /// Sets how drags snap (`None`: as it is).
    Snap {
        /// Offsets, model units (0: free).
        step: Option<f64>,
        /// Turns, degrees (0: free).
        degrees: Option<f64>,
    },
    /// Shows or hides the gizmo.
    ShowGizmo(bool),
    /// The axis a drag on the selection slides it along (`None`: drags orbit).
    DragAxis(Option<Axis>),
    /// Shows or hides overlays.
    Overlays(Overlays),
    /// Keeps a viewpoint (replacing its namesake).
    SaveViewpoint(Viewpoint),
}

/// An action on the view: the active pane, its camera and its settings, the
/// pointer, and what takes frames (snapshots, screenshots).
#[derive(Clone, Debug, PartialEq)]
pub enum ViewCommand {
    /// Picks at a point of the active pane: selects what is hit.
    Pick(ViewPoint),
    /// Clicks: places a section plane on a face, measures, else picks.
    Click(ViewPoint),
    /// Selects a part and opens the structure tree down to it.
    Reveal(PartId),
    /// Frames the selection (picking at the point first, if one is given).
    Focus(Option<ViewPoint>),
    /// Frames the model.
    FrameAll,
    /// The pointer rests over a pane's point (`None`: over none).
    Hover(Option<(usize, ViewPoint)>),
    /// The primary button goes down: drags the selection along `axis`, a
    /// section handle or a gizmo handle, else orbits.
    Press {
        /// Where, in the active pane.
        at: ViewPoint,
        /// The axis a press on the selection slides it along.
        axis: Option<Axis>,
    },
    /// The pointer moves with the button down.
    PointerTo {
        /// Where it is now.
        at: ViewPoint,
        /// How far it moved, pixels.
        delta: ViewPoint,
        /// Without snapping (Shift held).
        free: bool,
    },
    /// The primary button comes up.
    Release,
    /// Shows a listed clash: its two parts alone, framed, measured.
    ShowClash(usize),
    /// Goes to a saved viewpoint.
    GoTo(String),
    /// Keeps the active pane's view as a viewpoint of this name.
    SaveViewpoint(String),
    /// Writes the review's issues to a BCF file (a frame per snapshot).
    ExportBcf(PathBuf),
    /// Reads a BCF file's topics as viewpoints.
    ImportBcf(PathBuf),
    /// Looks at the model from a preset direction.
    Preset(Preset),
    /// Puts the eye somewhere, looking along a direction.
    Camera {
        /// The eye, world.
        eye: DVec3,
        /// Where it looks.
        forward: DVec3,
    },
    /// Turns the active pane's view direction about its eye (mouse look)
    /// for a drag of this many pixels.
    Look(ViewPoint),
    /// Slides the active pane's eye and pivot in the screen plane: the pivot
    /// follows a drag of this many pixels.
    Pan(ViewPoint),
    /// Moves the active pane's eye toward the point under the pointer (or
    /// the pivot, over nothing), for a wheel turn.
    Zoom {
        /// The wheel's turn, points (positive: toward the scene).
        wheel: f64,
        /// Where the pointer is, in the active pane.
        at: ViewPoint,
    },
    /// Walks or flies the active pane's eye for held keys.
    Walk {
        /// Which way the keys push.
        keys: Keys,
        /// For how long, seconds.
        dt: f64,
    },
    /// Whether the active pane's keys walk or fly.
    Motion(Motion),
    /// The active pane's speed factor.
    Speed(f64),
    /// The active pane's coverage threshold: cells covering fewer pixels
    /// across are not drawn.
    MinPixels(f64),
    /// The pixels of error the active pane's simplified levels may show (0:
    /// exact).
    LodErrorPx(f64),
    /// Sets how many panes there are.
    Panes(usize),
    /// Makes a pane the active one.
    ActivePane(usize),
    /// The active pane's culling.
    Culling(Culling),
    /// The active pane's occlusion setting.
    Occlusion(Occlusion),
    /// Paints the whole window each frame, or composes from the panels.
    PaintWhole(bool),
    /// Saves the window as PNG after this frame.
    Screenshot(PathBuf),
}

impl From<ReviewCommand> for Command {
    fn from(c: ReviewCommand) -> Self {
        Self::Review(c)
    }
}

impl From<ViewCommand> for Command {
    fn from(c: ViewCommand) -> Self {
        Self::View(c)
    }
}

/// What applying a [`ReviewCommand`] gave.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Done; the state says the rest.
    Done,
    /// Whether there was something to act on (a selection to move or drag).
    Acted(bool),
    /// The part an undo or redo moved (`None`: nothing to undo or redo).
    Part(Option<PartId>),
    /// How many clashes a report added to the list.
    ClashesAdded(usize),
    /// What a save wrote.
    Saved(Saved),
    /// A measurement made.
    Measured(Measurement),
}

/// Applies `command` to the review and its tools.
pub fn apply(
    review: &mut Review,
    tools: &mut Tools,
    command: ReviewCommand,
) -> anyhow::Result<Outcome> {
    use ReviewCommand as C;
    Ok(match command {
        C::Select(part) => {
            review.select(part);
            Outcome::Done
        }
        C::Translate(by) => Outcome::Acted(review.translate_selection(by)?),
        C::Rotate { axis, degrees } => Outcome::Acted(review.rotate_selection(axis, degrees)?),
        C::BeginDrag => Outcome::Acted(review.begin_drag()),
        C::DragTo(offset) => {
            review.drag_to(offset)?;
            Outcome::Done
        }
        C::DragBy(delta) => {
            review.drag_by(delta)?;
            Outcome::Done
        }
        C::EndDrag => {
            review.end_drag();
            Outcome::Done
        }
        C::Undo => Outcome::Part(review.undo()),
        C::Redo => Outcome::Part(review.redo()),
        C::Hide(part) => {
            review.scene.set_part_hidden(part, true);
            Outcome::Done
        }
        C::Isolate(part) => {
            for p in review.scene.part_ids() {
                review.scene.set_part_hidden(p, p != part);
            }
            Outcome::Done
        }
        C::ShowAll => {
            for p in review.scene.part_ids() {
                review.scene.set_part_hidden(p, false);
            }
            Outcome::Done
        }
        C::Clearance(c) => {
            review.settings.clearance = c;
            review.check();
            Outcome::Done
        }
        C::LiveCollision(on) => {
            review.live_collision = on;
            review.check();
            Outcome::Done
        }
        C::Record(path) => {
            review.recorder = path.as_deref().map(Recorder::create).transpose()?;
            Outcome::Done
        }
        C::Save(path) => Outcome::Saved(review.save(&path)?),
        C::LoadClashes(path) => Outcome::ClashesAdded(crate::clashes::load_report(review, &path)?),
        C::MeasureParts(a, b) => {
            let s = review
                .distance(a, b)
                .context("measure_parts: a part has no triangles")?;
            let m = Measurement::Parts(a, b, s);
            tools.measure.result = Some(m);
            Outcome::Measured(m)
        }
        C::MeasureMode(mode) => {
            tools.measure.set_mode(mode);
            Outcome::Done
        }
        C::Section(section) => {
            review.section = section;
            Outcome::Done
        }
        C::SectionPlane { point, normal } => {
            review.section.add_plane(point, normal)?;
            Outcome::Done
        }
        C::SectionBox { min, max } => {
            review.section.set_box(min, max)?;
            Outcome::Done
        }
        C::SectionOnFace(on) => {
            tools.section_on_face = on;
            Outcome::Done
        }
        C::Snap { step, degrees } => {
            tools.snap = step.unwrap_or(tools.snap);
            tools.snap_deg = degrees.unwrap_or(tools.snap_deg);
            Outcome::Done
        }
        C::ShowGizmo(show) => {
            tools.show_gizmo = show;
            Outcome::Done
        }
        C::DragAxis(axis) => {
            tools.drag_axis = axis;
            Outcome::Done
        }
        C::Overlays(o) => {
            tools.set_overlays(o);
            Outcome::Done
        }
        C::SaveViewpoint(v) => {
            tools.save_viewpoint(v);
            Outcome::Done
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nav::Navigator;

    /// Which variant a command is; a variant added to [`ReviewCommand`]
    /// fails to compile here until the test below drives it too.
    fn variant(c: &ReviewCommand) -> usize {
        use ReviewCommand as C;
        match c {
            C::Select(_) => 0,
            C::Translate(_) => 1,
            C::Rotate { .. } => 2,
            C::BeginDrag => 3,
            C::DragTo(_) => 4,
            C::DragBy(_) => 5,
            C::EndDrag => 6,
            C::Undo => 7,
            C::Redo => 8,
            C::Hide(_) => 9,
            C::Isolate(_) => 10,
            C::ShowAll => 11,
            C::Clearance(_) => 12,
            C::LiveCollision(_) => 13,
            C::Record(_) => 14,
            C::Save(_) => 15,
            C::LoadClashes(_) => 16,
            C::MeasureParts(..) => 17,
            C::MeasureMode(_) => 18,
            C::Section(_) => 19,
            C::SectionPlane { .. } => 20,
            C::SectionBox { .. } => 21,
            C::SectionOnFace(_) => 22,
            C::Snap { .. } => 23,
            C::ShowGizmo(_) => 24,
            C::DragAxis(_) => 25,
            C::Overlays(_) => 26,
            C::SaveViewpoint(_) => 27,
        }
    }
    const VARIANTS: usize = 28;

    /// Every review command through the one [`apply`], each checked against
    /// the state it should leave (the grid's boxes are 4 units wide on a
    /// pitch of 10, so neighbours are 6 apart).
    #[test]
    fn every_review_command_goes_through_apply() {
        let dir = tempfile::tempdir().unwrap();
        let mut review = Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
        let mut tools = Tools::default();
        let a = review.scene.find_part("box_0_0_0").unwrap();
        let b = review.scene.find_part("box_1_0_0").unwrap();
        let at = |review: &Review| review.scene.part_world(a).translation;
        let start = at(&review);
        let mut seen = [false; VARIANTS];
        let mut run = |review: &mut Review, tools: &mut Tools, c: ReviewCommand| {
            seen[variant(&c)] = true;
            apply(review, tools, c).unwrap()
        };
        use ReviewCommand as C;

        assert_eq!(
            run(&mut review, &mut tools, C::Translate(DVec3::X)),
            Outcome::Acted(false)
        );
        assert_eq!(
            run(&mut review, &mut tools, C::Select(Some(a))),
            Outcome::Done
        );
        assert_eq!(review.selected, Some(a));
        let by = DVec3::new(0.0, 0.0, 2.5);
        assert_eq!(
            run(&mut review, &mut tools, C::Translate(by)),
            Outcome::Acted(true)
        );
        assert_eq!(at(&review), start + by);
        let turned = run(
            &mut review,
            &mut tools,
            C::Rotate {
                axis: DVec3::Z,
                degrees: 90.0,
            },
        );
        assert_eq!(turned, Outcome::Acted(true));
        let x = review.scene.part_world(a).matrix3.x_axis;
        assert!((x - DVec3::Y).length() < 1e-9, "{x}");
        let before_drag = at(&review);
        assert_eq!(
            run(&mut review, &mut tools, C::BeginDrag),
            Outcome::Acted(true)
        );
        run(
            &mut review,
            &mut tools,
            C::DragTo(DVec3::new(0.0, 1.0, 0.0)),
        );
        assert_eq!(at(&review), before_drag + DVec3::Y);
        let step = DAffine3::from_translation(DVec3::new(0.0, 0.0, 1.0));
        run(&mut review, &mut tools, C::DragBy(step));
        assert_eq!(at(&review), before_drag + DVec3::Z);
        run(&mut review, &mut tools, C::EndDrag);
        assert!(!review.dragging());
        assert_eq!(review.history(), (3, 0));
        assert_eq!(
            run(&mut review, &mut tools, C::Undo),
            Outcome::Part(Some(a))
        );
        assert_eq!(at(&review), before_drag);
        assert_eq!(
            run(&mut review, &mut tools, C::Redo),
            Outcome::Part(Some(a))
        );
        assert_eq!(at(&review), before_drag + DVec3::Z);
        assert!(review.tree.validate_against(&review.scene).is_ok());

        run(&mut review, &mut tools, C::Hide(b));
        assert!(review.scene.part(b).hidden);
        run(&mut review, &mut tools, C::Isolate(b));
        let hidden: Vec<bool> = review
            .scene
            .part_ids()
            .map(|p| review.scene.part(p).hidden)
            .collect();
        assert_eq!(hidden.iter().filter(|&&h| !h).count(), 1);
        assert!(!review.scene.part(b).hidden);
        run(&mut review, &mut tools, C::ShowAll);
        assert!(
            review
                .scene
                .part_ids()
                .all(|p| !review.scene.part(p).hidden)
        );

        run(&mut review, &mut tools, C::Clearance(5.0));
        assert_eq!(review.settings.clearance, 5.0);
        run(&mut review, &mut tools, C::LiveCollision(false));
        assert!(!review.live_collision);

        let record = dir.path().join("session.jsonl");
        run(&mut review, &mut tools, C::Record(Some(record.clone())));
        assert!(review.recorder.is_some() && record.exists());
        run(&mut review, &mut tools, C::Record(None));
        assert!(review.recorder.is_none());
        let glb = dir.path().join("edited.glb");
        let Outcome::Saved(saved) = run(&mut review, &mut tools, C::Save(glb.clone())) else {
            panic!("a save says what it wrote");
        };
        assert_eq!(saved.path, glb);
        assert!(glb.exists());
        let report = dir.path().join("collide.json");
        std::fs::write(&report, r#"{"clashes": []}"#).unwrap();
        let loaded = run(&mut review, &mut tools, C::LoadClashes(report));
        assert_eq!(loaded, Outcome::ClashesAdded(0));

        run(&mut review, &mut tools, C::Undo);
        run(&mut review, &mut tools, C::Undo);
        run(&mut review, &mut tools, C::Undo);
        assert_eq!(at(&review), start);
        let Outcome::Measured(m) = run(&mut review, &mut tools, C::MeasureParts(a, b)) else {
            panic!("two boxes measure");
        };
        let Measurement::Parts(_, _, s) = m else {
            panic!("a parts measurement");
        };
        assert!((s.distance - 6.0).abs() < 1e-6, "{}", s.distance);
        assert_eq!(tools.measure.result, Some(m));
        run(&mut review, &mut tools, C::MeasureMode(MeasureMode::Angle));
        assert_eq!(tools.measure.mode, MeasureMode::Angle);

        let (point, normal) = (DVec3::new(0.0, 0.0, 1.0), DVec3::NEG_Z);
        run(&mut review, &mut tools, C::SectionPlane { point, normal });
        assert_eq!(review.section.planes().len(), 1);
        assert!(review.section.keeps(DVec3::ZERO) && !review.section.keeps(DVec3::Z * 2.0));
        let (min, max) = (DVec3::splat(-1.0), DVec3::splat(1.0));
        run(&mut review, &mut tools, C::SectionBox { min, max });
        assert_eq!(review.section.planes().len(), 6);
        run(&mut review, &mut tools, C::Section(Section::Off));
        assert_eq!(review.section, Section::Off);
        run(&mut review, &mut tools, C::SectionOnFace(true));
        assert!(tools.section_on_face);

        run(
            &mut review,
            &mut tools,
            C::Snap {
                step: Some(5.0),
                degrees: None,
            },
        );
        assert_eq!(
            (tools.snap, tools.snap_deg),
            (5.0, Tools::default().snap_deg)
        );
        run(&mut review, &mut tools, C::ShowGizmo(false));
        assert!(!tools.show_gizmo);
        run(&mut review, &mut tools, C::DragAxis(Some(Axis::Y)));
        assert_eq!(tools.drag_axis, Some(Axis::Y));
        let shown = Overlays {
            stats: Some(true),
            clashes: None,
            tools: Some(false),
        };
        run(&mut review, &mut tools, C::Overlays(shown));
        let expected = (true, Tools::default().show_clashes, false);
        assert_eq!(
            (tools.show_stats, tools.show_clashes, tools.show_tools),
            expected
        );

        let nav = Navigator::overview(&review.scene.world_bounds());
        let v = Viewpoint::capture("pump", &nav, &review);
        run(&mut review, &mut tools, C::SaveViewpoint(v.clone()));
        run(&mut review, &mut tools, C::SaveViewpoint(v.clone()));
        assert_eq!(tools.viewpoints, vec![v]);
        assert_eq!(tools.viewpoint("pump").unwrap().name, "pump");

        let missed: Vec<usize> = (0..VARIANTS).filter(|&i| !seen[i]).collect();
        assert!(missed.is_empty(), "variants not driven: {missed:?}");
    }
}
