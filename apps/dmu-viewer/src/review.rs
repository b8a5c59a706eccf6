//! The review: the model, its cell tree, the selection, moves with undo and
//! redo, the live collision report, and saving. No window and no GPU here, so
//! every edit is testable headless.

use std::path::{Path, PathBuf};
use std::time::Instant;

use dmu_collide::{Checker, FindingKind, Report, Separation, Settings};
use dmu_geom::Ray3d;
use dmu_scene::{MeshId, PartId, Scene};
use dmu_tree::{Hit, Tree, TreeOptions};
use glam::{DAffine3, DQuat, DVec3};

use crate::on_demand::OnDemand;
use crate::record::Recorder;
use crate::section::Section;

/// Meshes a pick loads before searching again (under a memory budget).
const PICK_MESHES_AT_ONCE: usize = 8;

/// One undoable move: a part's absolute transform before and after.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Edit {
    part: PartId,
    before: DAffine3,
    after: DAffine3,
}

/// A drag in progress: every step places the part relative to where the drag
/// started, so steps never accumulate rounding.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Drag {
    part: PartId,
    start: DAffine3,
}

/// A clash in the session's list.
#[derive(Clone, Debug, PartialEq)]
pub struct ListedClash {
    /// The moved part.
    pub a: PartId,
    /// The other part.
    pub b: PartId,
    /// The pair's worst finding (an impact comes from a report of swept
    /// moves).
    pub kind: FindingKind,
    /// The other kinds the pair showed, worst first.
    pub others: Vec<FindingKind>,
    /// The smallest distance seen of the worst kind (0 for hard clashes),
    /// model units.
    pub distance: f64,
    /// A world point of the clash where that distance was seen.
    pub point: DVec3,
    /// Where the worst finding was found: `live`, or the report file and
    /// step.
    pub source: String,
}

/// Adds `clash` to `list`: an entry per pair (either order) with its worst
/// finding, as a BCF topic names it. A worse finding takes the entry over
/// (the kind it replaces joins the others), one of the same kind keeps the
/// smaller distance, a milder one joins the others.
pub fn list_clash(list: &mut Vec<ListedClash>, clash: ListedClash) {
    let same =
        |c: &&mut ListedClash| (c.a, c.b) == (clash.a, clash.b) || (c.a, c.b) == (clash.b, clash.a);
    let Some(c) = list.iter_mut().find(same) else {
        list.push(clash);
        return;
    };
    let milder = if clash.kind < c.kind {
        let old = std::mem::replace(c, clash);
        old.others.into_iter().chain([old.kind]).collect()
    } else if clash.kind == c.kind {
        if clash.distance < c.distance {
            (c.distance, c.point, c.source) = (clash.distance, clash.point, clash.source);
        }
        clash.others
    } else {
        clash.others.into_iter().chain([clash.kind]).collect()
    };
    for kind in milder {
        if kind != c.kind && !c.others.contains(&kind) {
            c.others.push(kind);
        }
    }
    c.others.sort();
}

/// Timings of the last edit, for the stats overlay.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EditTimings {
    /// Tree update of the last move step, µs.
    pub move_us: f64,
    /// Collision check of the last step, ms.
    pub check_ms: f64,
}

/// What a save wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Saved {
    /// The file written.
    pub path: PathBuf,
    /// In what format.
    pub format: dmu_store::SavedFormat,
}

/// The model under review and everything done to it.
#[derive(Debug)]
pub struct Review {
    /// The model; part transforms change as parts move.
    pub scene: Scene,
    /// Its cell tree, updated on every move step.
    pub tree: Tree,
    /// The file it came from (`None`: the built-in plant).
    pub source: Option<PathBuf>,
    /// The selected part.
    pub selected: Option<PartId>,
    /// What the selection clashes with, as of the last check.
    pub report: Report,
    /// Collision settings (clearance).
    pub settings: Settings,
    /// Whether moves check collisions.
    pub live_collision: bool,
    /// Timings of the last step.
    pub timings: EditTimings,
    /// The manipulation session being recorded, if any.
    pub recorder: Option<Recorder>,
    /// Why the recording stopped, when writing it failed.
    pub record_error: Option<String>,
    /// What cuts the model open (drawing and picking both follow it).
    pub section: Section,
    /// Every clash seen in this session (live checks and loaded reports),
    /// one entry per part pair (its worst finding), in the order first seen.
    pub clash_list: Vec<ListedClash>,
    /// Under a memory budget: where the meshes picks and checks read come
    /// from (the scene is then the store's skeleton); `None`: all loaded.
    pub geometry: Option<OnDemand>,
    /// Why loading geometry for a pick or check failed (the store changed
    /// on disk, say); the viewer ends the run with it.
    pub geometry_error: Option<String>,
    checker: Checker,
    undo: Vec<Edit>,
    redo: Vec<Edit>,
    drag: Option<Drag>,
}

impl Review {
    /// A review of `scene` (its tree is built here).
    pub fn new(scene: Scene, source: Option<PathBuf>) -> Self {
        let tree = Tree::build(&scene, TreeOptions::default());
        let checker = Checker::new(&scene);
        Self {
            scene,
            tree,
            source,
            selected: None,
            report: Report::default(),
            settings: Settings::default(),
            live_collision: true,
            timings: EditTimings::default(),
            recorder: None,
            record_error: None,
            section: Section::Off,
            clash_list: Vec::new(),
            geometry: None,
            geometry_error: None,
            checker,
            undo: Vec::new(),
            redo: Vec::new(),
            drag: None,
        }
    }

    /// The nearest visible part along `ray` (exact, f64), as `dmu pick` finds
    /// it, seeing through what the section cuts away.
    pub fn pick(&mut self, ray: &Ray3d) -> Option<Hit> {
        let planes = self.section.planes();
        if let Some(g) = self.geometry.as_mut() {
            g.begin();
        }
        loop {
            let (hit, unloaded) = self.tree.pick_loaded(&self.scene, ray, &planes);
            let Some(g) = self.geometry.as_mut() else {
                return hit;
            };
            if unloaded.is_empty() {
                return hit;
            }
            // The nearest few meshes the ray meets before the hit, then again.
            let mut meshes: Vec<MeshId> = Vec::new();
            for e in unloaded {
                let mesh = self.scene.part(self.tree.entries()[e.0 as usize].part).mesh;
                if !meshes.contains(&mesh) {
                    meshes.push(mesh);
                }
                if meshes.len() == PICK_MESHES_AT_ONCE {
                    break;
                }
            }
            if let Err(e) = g.ensure(&mut self.scene, &meshes) {
                self.geometry_error = Some(format!("{e:#}"));
                return None;
            }
        }
    }

    /// Under a memory budget, loads the meshes an exact test of `parts`
    /// reads: theirs, and with `near` those of every part whose chunk boxes
    /// come within the clearance of theirs (plus a margin for the contact
    /// tolerance). Returns false when loading failed
    /// ([`Review::geometry_error`]).
    fn load_near(&mut self, parts: &[PartId], near: bool) -> bool {
        let Some(g) = self.geometry.as_mut() else {
            return true;
        };
        g.begin();
        let mut meshes: Vec<MeshId> = Vec::new();
        for &part in parts {
            let b = self.scene.part_world_bounds(part);
            let margin = self.settings.clearance + 1e-3 * b.extent().length();
            meshes.push(self.scene.part(part).mesh);
            if !near {
                continue;
            }
            let mut near_entries = Vec::new();
            self.tree
                .entries_in_box(&b.inflated(margin), &mut near_entries);
            for e in near_entries {
                meshes.push(self.scene.part(self.tree.entries()[e.0 as usize].part).mesh);
            }
        }
        meshes.sort_unstable();
        meshes.dedup();
        match g.ensure(&mut self.scene, &meshes) {
            Ok(()) => true,
            Err(e) => {
                self.geometry_error = Some(format!("{e:#}"));
                false
            }
        }
    }

    /// The minimum distance between two parts and its closest points (f64),
    /// by the collision check's own narrow phase.
    pub fn distance(&mut self, a: PartId, b: PartId) -> Option<Separation> {
        if !self.load_near(&[a, b], false) {
            return None;
        }
        self.checker.distance(&self.scene, &self.settings, a, b)
    }

    /// Builds the collision check's whole-model index now rather than at the
    /// first check (under a memory budget, before the budget is shared out).
    pub fn prepare_checks(&mut self) {
        self.checker.prepare(&self.scene, &self.tree);
    }

    /// Selects a part (or nothing) and checks what it clashes with.
    pub fn select(&mut self, part: Option<PartId>) {
        if self.selected != part {
            self.end_drag();
        }
        self.selected = part;
        self.check();
    }

    /// Checks the selection against everything else (clears the report when
    /// nothing is selected or live collision is off).
    pub fn check(&mut self) {
        match self.selected {
            Some(part) if self.live_collision => {
                let start = Instant::now();
                if !self.load_near(&[part], true) {
                    self.report.clear();
                    return;
                }
                self.checker.check(
                    &self.scene,
                    &self.tree,
                    &[part],
                    &self.settings,
                    &mut self.report,
                );
                self.timings.check_ms = start.elapsed().as_secs_f64() * 1e3;
                for c in &self.report.clashes {
                    list_clash(
                        &mut self.clash_list,
                        ListedClash {
                            a: c.a,
                            b: c.b,
                            kind: c.kind.into(),
                            others: Vec::new(),
                            distance: c.distance,
                            point: c.point,
                            source: "live".to_owned(),
                        },
                    );
                }
            }
            _ => self.report.clear(),
        }
    }

    /// The parts that clash with the selection, as of the last check (each
    /// once, the selection itself left out).
    pub fn clashing_parts(&self) -> Vec<PartId> {
        let mut parts = Vec::new();
        for c in &self.report.clashes {
            for p in [c.a, c.b] {
                if Some(p) != self.selected && !parts.contains(&p) {
                    parts.push(p);
                }
            }
        }
        parts
    }

    /// Places `part` at `world` (absolute), updating the tree, records the
    /// pose when recording, then checks.
    fn place(&mut self, part: PartId, world: DAffine3) {
        let start = Instant::now();
        self.tree.move_part(&mut self.scene, part, world);
        self.timings.move_us = start.elapsed().as_secs_f64() * 1e6;
        if let Some(rec) = self.recorder.as_mut()
            && let Err(e) = rec.pose(&self.scene, part, world)
        {
            self.record_error = Some(format!("recording stopped: {e:#}"));
            self.recorder = None;
        }
        if self.selected == Some(part) {
            self.check();
        }
    }

    /// Moves the selection by a world translation, as one undoable edit.
    /// Returns false when nothing is selected, an error (and moves nothing) when
    /// the result would leave the world (±1e15 model units).
    pub fn translate_selection(&mut self, delta: DVec3) -> anyhow::Result<bool> {
        let Some(part) = self.selected else {
            return Ok(false);
        };
        self.end_drag();
        let before = self.scene.part_world(part);
        let mut after = before;
        after.translation += delta;
        self.apply(Edit {
            part,
            before,
            after,
        })?;
        Ok(true)
    }

    /// Turns the selection by `degrees` about a world `axis` through the
    /// centre of its world bounds, as one undoable edit. Returns false when
    /// nothing is selected, an error (and moves nothing) when the result would
    /// leave the world (±1e15 model units). Panics on a zero or non-finite axis.
    pub fn rotate_selection(&mut self, axis: DVec3, degrees: f64) -> anyhow::Result<bool> {
        let axis = dmu_geom::unit_vector(axis)
            .unwrap_or_else(|| panic!("rotation axis {axis} must be finite and not zero"));
        let Some(part) = self.selected else {
            return Ok(false);
        };
        self.end_drag();
        let before = self.scene.part_world(part);
        let centre = self.scene.part_world_bounds(part).center();
        let turn = DAffine3::from_translation(centre)
            * DAffine3::from_quat(DQuat::from_axis_angle(axis, degrees.to_radians()))
            * DAffine3::from_translation(-centre);
        self.apply(Edit {
            part,
            before,
            after: turn * before,
        })?;
        Ok(true)
    }

    fn apply(&mut self, edit: Edit) -> anyhow::Result<()> {
        anyhow::ensure!(
            self.scene.is_valid_world(edit.part, &edit.after),
            "{}: the move would take the part beyond ±{:e} model units; not moved",
            self.scene.part_name(edit.part),
            dmu_scene::MAX_WORLD_COORDINATE
        );
        self.place(edit.part, edit.after);
        if edit.before != edit.after {
            self.undo.push(edit);
            self.redo.clear();
        }
        Ok(())
    }

    /// Starts dragging the selection (ends any drag in progress).
    pub fn begin_drag(&mut self) -> bool {
        self.end_drag();
        let Some(part) = self.selected else {
            return false;
        };
        self.drag = Some(Drag {
            part,
            start: self.scene.part_world(part),
        });
        true
    }

    /// Whether a drag of the selection is going on.
    pub fn dragging(&self) -> bool {
        self.drag.is_some()
    }

    /// One drag step: the dragged part at its start translated by `offset`
    /// (world units); the tree is updated and collisions checked. A step out
    /// of the world is refused (see [`Review::drag_by`]).
    pub fn drag_to(&mut self, offset: DVec3) -> anyhow::Result<()> {
        self.drag_by(DAffine3::from_translation(offset))
    }

    /// One drag step: the dragged part at `delta` applied (in world space) to
    /// where the drag started. A step that would take the part out of the
    /// world (±[`dmu_scene::MAX_WORLD_COORDINATE`], or not finite) is not
    /// taken and is an error saying so: the part stays where the last step
    /// left it (a drag by 1e300 did nothing, silently).
    pub fn drag_by(&mut self, delta: DAffine3) -> anyhow::Result<()> {
        let Some(drag) = self.drag else {
            return Ok(());
        };
        let world = delta * drag.start;
        anyhow::ensure!(
            self.scene.is_valid_world(drag.part, &world),
            "{}: the drag step by {} would take the part beyond ±{:e} model units; it stays where it was",
            self.scene.part_name(drag.part),
            dmu_geom::Short(world.translation - drag.start.translation),
            dmu_scene::MAX_WORLD_COORDINATE
        );
        self.place(drag.part, world);
        Ok(())
    }

    /// Ends the drag: what it did becomes one undoable edit.
    pub fn end_drag(&mut self) {
        if let Some(drag) = self.drag.take() {
            let after = self.scene.part_world(drag.part);
            if after != drag.start {
                self.undo.push(Edit {
                    part: drag.part,
                    before: drag.start,
                    after,
                });
                self.redo.clear();
            }
        }
    }

    /// Undoes the last edit; the part it moved, if any.
    pub fn undo(&mut self) -> Option<PartId> {
        self.end_drag();
        let edit = self.undo.pop()?;
        self.place(edit.part, edit.before);
        self.redo.push(edit);
        Some(edit.part)
    }

    /// Redoes the last undone edit; the part it moved, if any.
    pub fn redo(&mut self) -> Option<PartId> {
        self.end_drag();
        let edit = self.redo.pop()?;
        self.place(edit.part, edit.after);
        self.undo.push(edit);
        Some(edit.part)
    }

    /// Edits that can be undone and redone.
    pub fn history(&self) -> (usize, usize) {
        (self.undo.len(), self.redo.len())
    }

    /// Parts moved since loading (each once, in order of first move).
    pub fn moved_parts(&self) -> Vec<PartId> {
        let mut parts: Vec<PartId> = Vec::new();
        for e in &self.undo {
            if !parts.contains(&e.part) {
                parts.push(e.part);
            }
        }
        parts
    }

    /// Writes the model with its current transforms to `path`: back into the
    /// store it was opened from (`.dmu`, [`dmu_store::save_edits`]), a new
    /// store (`.dmu`), or glTF (`.glb`, `.gltf`). Every format is written to a
    /// temporary file and renamed over `path`.
    pub fn save(&mut self, path: &Path) -> anyhow::Result<Saved> {
        self.end_drag();
        if let Some(rec) = &self.recorder
            && rec.path().canonicalize().ok() == path.canonicalize().ok()
        {
            anyhow::bail!(
                "{}: this is the session's recording; save the model under another name",
                path.display()
            );
        }
        let format = dmu_store::save_scene(&mut self.scene, self.source.as_deref(), path)?;
        Ok(Saved {
            path: path.to_owned(),
            format,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmu_store::SavedFormat;

    fn review() -> Review {
        Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None)
    }

    proptest::proptest! {
        /// The list holds an entry per pair, named by its worst finding with
        /// that kind's smallest distance, and the pair's other kinds: against
        /// a brute force over the findings listed, in any order.
        #[test]
        fn the_list_names_each_pair_by_its_worst_finding(
            findings in proptest::collection::vec((0u32..4, 0u32..4, 0usize..4, 0u32..100), 0..40)
        ) {
            let mut list = Vec::new();
            let findings: Vec<_> = findings.into_iter().filter(|f| f.0 != f.1).collect();
            for (i, &(a, b, kind, d)) in findings.iter().enumerate() {
                list_clash(&mut list, ListedClash {
                    a: PartId(a),
                    b: PartId(b),
                    kind: FindingKind::ALL[kind],
                    others: Vec::new(),
                    distance: f64::from(d),
                    point: DVec3::splat(f64::from(d)),
                    source: i.to_string(),
                });
            }
            let pair = |a: u32, b: u32| (a.min(b), a.max(b));
            let mut pairs: Vec<_> = findings.iter().map(|f| pair(f.0, f.1)).collect();
            pairs.sort();
            pairs.dedup();
            proptest::prop_assert_eq!(list.len(), pairs.len());
            for c in &list {
                let of_pair: Vec<_> =
                    findings.iter().filter(|f| pair(f.0, f.1) == pair(c.a.0, c.b.0)).collect();
                let worst = of_pair.iter().map(|f| f.2).min().unwrap();
                let mut others: Vec<_> = of_pair.iter().map(|f| f.2).filter(|&k| k != worst).collect();
                others.sort();
                others.dedup();
                let distance = of_pair.iter().filter(|f| f.2 == worst).map(|f| f.3).min().unwrap();
                // Where that distance was first seen.
                let source = findings
                    .iter()
                    .position(|f| pair(f.0, f.1) == pair(c.a.0, c.b.0) && f.2 == worst && f.3 == distance)
                    .unwrap();
                proptest::prop_assert_eq!(c.kind, FindingKind::ALL[worst]);
                proptest::prop_assert_eq!(&c.others, &others.iter().map(|&k| FindingKind::ALL[k]).collect::<Vec<_>>());
                proptest::prop_assert_eq!(c.distance, f64::from(distance));
                proptest::prop_assert_eq!(c.point, DVec3::splat(f64::from(distance)));
                proptest::prop_assert_eq!(&c.source, &source.to_string());
            }
        }
    }

    /// A drag and typed moves undo and redo exactly, and the tree follows.
    #[test]
    fn moves_undo_and_redo_exactly() {
        let mut r = review();
        let part = r.scene.find_part("box_0_0_0").unwrap();
        let start = r.scene.part_world(part);
        r.select(Some(part));
        assert!(r.begin_drag());
        for i in 1..=10 {
            r.drag_to(DVec3::new(0.37 * f64::from(i), 0.0, 0.0))
                .unwrap();
        }
        r.end_drag();
        assert!(r.translate_selection(DVec3::new(0.0, 0.0, 100.0)).unwrap());
        assert_eq!(r.history(), (2, 0));
        let end = r.scene.part_world(part);
        assert_eq!(
            end.translation,
            start.translation + DVec3::new(3.7, 0.0, 100.0)
        );
        assert_eq!(r.undo(), Some(part));
        assert_eq!(r.undo(), Some(part));
        assert_eq!(r.undo(), None);
        assert_eq!(r.scene.part_world(part), start);
        r.tree.validate_against(&r.scene).unwrap();
        assert_eq!(r.redo(), Some(part));
        assert_eq!(r.redo(), Some(part));
        assert_eq!(r.scene.part_world(part), end);
        r.tree.validate_against(&r.scene).unwrap();
        assert_eq!(r.moved_parts(), vec![part]);
    }

    /// A typed rotation turns the part about its box centre, keeps the centre,
    /// four quarter turns come back, and undo restores it bit for bit.
    #[test]
    fn rotations_turn_about_the_box_centre_and_undo() {
        let mut r = review();
        let part = r.scene.find_part("box_1_0_1").unwrap();
        let start = r.scene.part_world(part);
        let centre = r.scene.part_world_bounds(part).center();
        r.select(Some(part));
        assert!(r.rotate_selection(DVec3::Z, 30.0).unwrap());
        let turned = r.scene.part_world(part);
        let (_, rotation, _) = turned.to_scale_rotation_translation();
        let (axis, angle) = rotation.to_axis_angle();
        assert!((angle - 30f64.to_radians()).abs() < 1e-12, "{angle}");
        assert!(axis.abs_diff_eq(DVec3::Z, 1e-12));
        // The centre is a fixed point of the turn.
        let moved_centre = turned.transform_point3(start.inverse().transform_point3(centre));
        assert!(moved_centre.abs_diff_eq(centre, 1e-9), "{moved_centre}");
        r.tree.validate_against(&r.scene).unwrap();
        assert_eq!(r.undo(), Some(part));
        assert_eq!(r.scene.part_world(part), start);
        for _ in 0..4 {
            r.rotate_selection(DVec3::X, 90.0).unwrap();
        }
        let back = r.scene.part_world(part);
        assert!(back.matrix3.abs_diff_eq(start.matrix3, 1e-12));
        assert!(back.translation.abs_diff_eq(start.translation, 1e-9));
        assert_eq!(r.history(), (4, 0), "a new edit clears the redo");
        r.select(None);
        assert!(!r.rotate_selection(DVec3::Z, 10.0).unwrap());
    }

    /// The live check sees the neighbour when the selection is pushed into it.
    #[test]
    fn moving_into_a_neighbour_clashes() {
        let mut r = review();
        let part = r.scene.find_part("box_0_0_0").unwrap();
        r.select(Some(part));
        assert!(r.report.clashes.is_empty());
        r.translate_selection(DVec3::new(7.0, 0.0, 0.0)).unwrap();
        let clash = r.report.clashes.first().expect("a clash");
        assert_eq!(r.scene.part_name(clash.b), "box_1_0_0");
        assert_eq!(r.clashing_parts(), vec![clash.b]);
        r.undo();
        assert!(r.report.clashes.is_empty());
        assert!(r.clashing_parts().is_empty());
    }

    /// A move out of the world (past f64's range it panicked in the scene's
    /// transform check) is refused and changes nothing; a drag step out of it
    /// is not taken.
    #[test]
    fn issue_20_moves_out_of_the_world_are_refused() {
        let mut r = review();
        let part = r.scene.find_part("box_0_0_0").unwrap();
        r.select(Some(part));
        assert!(r.translate_selection(DVec3::new(1e14, 0.0, 0.0)).unwrap());
        let far = r.scene.part_world(part);
        let err = r
            .translate_selection(DVec3::new(1e15, 0.0, 0.0))
            .unwrap_err();
        assert!(err.to_string().contains("beyond"), "{err}");
        assert_eq!(r.scene.part_world(part), far);
        assert_eq!(r.history(), (1, 0));
        r.begin_drag();
        // Issue 48: refused out loud (it did nothing, silently).
        let err = r.drag_to(DVec3::new(1e300, 0.0, 0.0)).unwrap_err();
        assert!(
            err.to_string().contains("1e300") && err.to_string().len() < 200,
            "{err}"
        );
        assert_eq!(r.scene.part_world(part), far);
        r.end_drag();
        r.tree.validate_against(&r.scene).unwrap();
    }

    /// Saving to glTF writes the moved transform, which reads back exactly.
    #[test]
    fn saves_gltf_and_dmu() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = review();
        let part = r.scene.find_part("box_1_1_1").unwrap();
        r.select(Some(part));
        r.translate_selection(DVec3::new(100.0, 0.0, 0.0)).unwrap();
        let glb = dir.path().join("out.glb");
        assert_eq!(r.save(&glb).unwrap().format, SavedFormat::Gltf);
        let (back, _) = dmu_scene::import_gltf(&glb, &Default::default()).unwrap();
        let id = back.find_part(&r.scene.part_path(part)).unwrap();
        assert_eq!(back.part_world(id), r.scene.part_world(part));
        let store = dir.path().join("out.dmu");
        assert_eq!(r.save(&store).unwrap().format, SavedFormat::Store);
        let back = dmu_store::Store::open(&store)
            .unwrap()
            .load_scene()
            .unwrap();
        assert_eq!(back.part_world(part), r.scene.part_world(part));
        assert!(r.save(&dir.path().join("out.obj")).is_err());
    }
}
