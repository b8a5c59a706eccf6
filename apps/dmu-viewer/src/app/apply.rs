//! The one place a [`Command`] takes effect: the panels, keyboard
//! shortcuts, the pointer and scripts all come here; review commands go on
//! to the library's [`dmu_viewer::command::apply`], which the XR hands use
//! too.

use anyhow::Context as _;
use serde_json::Value;

use super::App;
use super::report::{
    ClashShown, FacePlane, FileEntry, FirstPoint, Missed, PartEntry, PickEntry, RayFacts,
    camera_json, to_value,
};
use crate::command::{Command, Outcome, ReviewCommand, ViewCommand, ViewPoint};
use crate::measure::{MeasureMode, Measurement, SNAP_PX};
use crate::ui::ViewInput;
use crate::viewpoints::Viewpoint;

impl App {
    /// Applies `command` from the panels, keys or pointer: a failure, or a
    /// file read or written, is said on the status line. (A script applies
    /// the two kinds through [`App::edit`] and [`App::apply_view`], whose
    /// results its report keeps.)
    pub(super) fn apply(&mut self, command: impl Into<Command>) {
        let result = match command.into() {
            Command::Review(c) => self.edit_and_say(c),
            Command::View(c) => self.apply_view(c).map(drop),
        };
        if let Err(e) = result {
            self.ui.status = format!("{e:#}");
        }
    }

    /// Applies a review command, saying a save's or a clash report's
    /// outcome on the status line.
    fn edit_and_say(&mut self, command: ReviewCommand) -> anyhow::Result<()> {
        let loaded = match &command {
            ReviewCommand::LoadClashes(path) => Some(path.display().to_string()),
            _ => None,
        };
        let failed = match &command {
            ReviewCommand::Save(_) => "save failed",
            ReviewCommand::Record(Some(_)) => "record failed",
            _ => "",
        };
        match self.edit(command) {
            Ok(Outcome::Saved(saved)) => {
                self.ui.status = format!("saved {} ({})", saved.path.display(), saved.format);
            }
            Ok(Outcome::ClashesAdded(n)) => {
                let path = loaded.unwrap_or_default();
                self.ui.status = format!("{n} clashes added from {path}");
            }
            Ok(_) => {}
            Err(e) if !failed.is_empty() => return Err(e.context(failed)),
            Err(e) => return Err(e),
        }
        Ok(())
    }

    /// Applies a review command: the library's one apply, on this review
    /// and these tools.
    pub(super) fn edit(&mut self, command: ReviewCommand) -> anyhow::Result<Outcome> {
        dmu_viewer::command::apply(&mut self.review, &mut self.tools, command)
    }

    /// Applies a view command; its report entry, where it has one.
    pub(super) fn apply_view(&mut self, command: ViewCommand) -> anyhow::Result<Option<Value>> {
        use ViewCommand as V;
        Ok(match command {
            V::Pick(at) => Some(self.pick(at)?),
            V::Click(at) => Some(self.click(at)?),
            V::Reveal(part) => {
                self.edit(ReviewCommand::Select(Some(part)))?;
                self.ui.reveal = Some(part);
                None
            }
            V::Focus(at) => {
                self.focus(at)?;
                None
            }
            V::FrameAll => {
                self.frame_all();
                None
            }
            V::Hover(at) => {
                self.hover(at);
                let part_id = self.hovered.map(|p| p.0);
                Some(to_value(PartEntry { part_id }))
            }
            V::Press { at, axis } => {
                self.begin_pointer_drag(at, axis)?;
                None
            }
            V::PointerTo { at, delta, free } => {
                self.pointer_drag_to(at, delta, free)?;
                None
            }
            V::Release => {
                self.end_pointer_drag()?;
                None
            }
            V::ShowClash(index) => Some(self.show_clash(index)?),
            V::SaveViewpoint(name) => {
                let v = Viewpoint::capture(&name, &self.panes[self.active].nav, &self.review);
                let entry = v.json();
                self.edit(ReviewCommand::SaveViewpoint(v))?;
                Some(entry)
            }
            V::GoTo(name) => {
                let v = self.tools.viewpoint(&name)?.clone();
                self.go_to(&v);
                Some(v.json())
            }
            V::ExportBcf(path) if self.export.is_none() => {
                let topics = self.start_export(path.clone())?;
                Some(to_value(FileEntry {
                    path: &path,
                    topics: Some(topics),
                    format: None,
                }))
            }
            // One export at a time: a second would drop the first's snapshots.
            V::ExportBcf(path) => anyhow::bail!(
                "{}: a BCF export is still being written; export again when it is done",
                path.display()
            ),
            V::ImportBcf(path) => Some(self.import_bcf(&path)?),
            V::Preset(preset) => {
                let pane = &mut self.panes[self.active];
                pane.nav.preset(preset, &self.review.tree.bounds());
                pane.view.reset_visibility();
                None
            }
            V::Camera { eye, forward } => {
                let pivot = self.pivot_distance();
                let pane = &mut self.panes[self.active];
                anyhow::ensure!(
                    pane.nav.look_along(eye, forward, pivot),
                    "camera: no direction to look along"
                );
                pane.view.reset_visibility();
                Some(camera_json(&pane.nav))
            }
            V::Look((dx, dy)) => {
                self.nav()
                    .look(-dx * super::TURN_PER_PIXEL, -dy * super::TURN_PER_PIXEL);
                None
            }
            V::Pan((dx, dy)) => {
                let height = f64::from(self.panes[self.active].view.size.1);
                self.nav().pan(dx, dy, height);
                None
            }
            V::Zoom { wheel, at } => {
                let toward = self
                    .review
                    .pick(&self.ray_at(at))
                    .map_or(self.panes[self.active].nav.pivot, |h| h.point);
                self.nav()
                    .dolly_toward(toward, (wheel / 400.0).clamp(-0.5, 0.5));
                None
            }
            V::Walk { keys, dt } => {
                self.nav().walk(keys, dt);
                None
            }
            V::Motion(motion) => {
                self.nav().motion = motion;
                None
            }
            V::Speed(factor) => {
                self.nav().speed_factor = factor;
                None
            }
            V::MinPixels(px) => {
                self.panes[self.active].view.options.min_pixels = px;
                None
            }
            V::LodErrorPx(px) => {
                self.panes[self.active].view.options.lod_error_px = px;
                None
            }
            V::Panes(n) => {
                anyhow::ensure!(
                    (1..=crate::panes::MAX_PANES).contains(&n),
                    "panes: {n} is not 1 to {}",
                    crate::panes::MAX_PANES
                );
                crate::panes::set_count(&mut self.panes, n, &self.review.tree.bounds());
                self.active = self.active.min(n - 1);
                None
            }
            V::ActivePane(i) => {
                anyhow::ensure!(
                    i < self.panes.len(),
                    "pane {i}: there are {}",
                    self.panes.len()
                );
                self.active = i;
                None
            }
            V::Culling(culling) => {
                self.panes[self.active].view.culling = culling;
                None
            }
            V::Occlusion(o) => {
                o.apply(&mut self.panes[self.active].view);
                None
            }
            V::PaintWhole(whole) => {
                if let Some(gfx) = self.gfx.as_mut() {
                    gfx.set_compose(!whole);
                }
                None
            }
            V::Screenshot(path) => {
                let entry = to_value(FileEntry {
                    path: &path,
                    topics: None,
                    format: None,
                });
                self.screenshot = Some(path);
                Some(entry)
            }
        })
    }

    /// How far ahead of the eye a camera put somewhere orbits: a tenth of
    /// the model's size.
    pub(super) fn pivot_distance(&self) -> f64 {
        let bounds = self.review.tree.bounds();
        if bounds.is_empty() {
            1.0
        } else {
            bounds.extent().length() * 0.1
        }
    }

    /// Goes to viewpoint `v` in the active pane.
    pub(super) fn go_to(&mut self, v: &Viewpoint) {
        let pane = &mut self.panes[self.active];
        v.apply(&mut pane.nav, &mut self.review);
        pane.view.reset_visibility();
    }

    /// Shows clash `index` of the list in the active pane: its two parts
    /// alone, framed, their closest points measured. Its report entry.
    fn show_clash(&mut self, index: usize) -> anyhow::Result<Value> {
        let review = &mut self.review;
        let (a, b, separation) = crate::clashes::show(review, index)?;
        self.frame_in_active(&crate::clashes::pair_bounds(&self.review, a, b));
        if let Some(s) = separation {
            self.tools.measure.result = Some(Measurement::Parts(a, b, s));
        }
        let review = &self.review;
        let c = &review.clash_list[index];
        Ok(to_value(ClashShown {
            a: review.scene.part_name(a),
            b: review.scene.part_name(b),
            kind: &c.kind,
            source: &c.source,
            distance: separation.map(|s| s.distance),
            point_a: separation.map(|s| s.point_a.to_array()),
            point_b: separation.map(|s| s.point_b.to_array()),
        }))
    }

    /// Frames the model in the active pane: what a section box keeps of it.
    fn frame_all(&mut self) {
        let bounds = self.review.section.kept_bounds(self.review.tree.bounds());
        self.frame_in_active(&bounds);
    }

    /// Frames `bounds` in the active pane, whose visibility starts afresh.
    fn frame_in_active(&mut self, bounds: &dmu_geom::Aabb3d) {
        let pane = &mut self.panes[self.active];
        pane.nav.frame(bounds);
        pane.view.reset_visibility();
    }

    /// Picks at a view point: selects what is hit (or nothing), orbits about
    /// the hit point from now on. Returns the ray and the report entry.
    fn pick(&mut self, at: ViewPoint) -> anyhow::Result<Value> {
        let ray = self.ray_at(at);
        let hit = self.review.pick(&ray);
        self.edit(ReviewCommand::Select(hit.map(|h| h.part)))?;
        if let Some(h) = hit {
            self.nav().pivot = h.point;
            self.ui.reveal = Some(h.part);
        }
        let scene = &self.review.scene;
        let length = ray.dir.length();
        Ok(to_value(PickEntry {
            pixel: [at.0, at.1],
            viewport: self.active_rect().into(),
            pane: self.active,
            ray: RayFacts {
                origin: ray.origin.to_array(),
                dir: ray.dir.to_array(),
            },
            hit: hit.map_or_else(
                || to_value(Missed { hit: false }),
                |h| dmu_app::hits::hit_json(scene, &h, length),
            ),
        }))
    }

    /// A click in the active pane: places a section plane on the face under
    /// it when one is being placed, measures in a measuring mode, else picks.
    /// The report entry of what it did.
    fn click(&mut self, at: ViewPoint) -> anyhow::Result<Value> {
        if self.tools.section_on_face {
            self.edit(ReviewCommand::SectionOnFace(false))?;
            let hit = self
                .review
                .pick(&self.ray_at(at))
                .context("section on a face: nothing there to place the plane on")?;
            // The plane keeps what lies behind the face, away from the eye.
            self.edit(ReviewCommand::SectionPlane {
                point: hit.point,
                normal: -hit.normal,
            })?;
            return Ok(to_value(FacePlane {
                point: hit.point.to_array(),
                normal: (-hit.normal).to_array(),
                section: self.review.section.describe(),
            }));
        }
        if self.tools.measure.mode == MeasureMode::Off {
            return self.pick(at);
        }
        let ray = self.ray_at(at);
        let Some(hit) = self.review.pick(&ray) else {
            return Ok(to_value(Missed { hit: false }));
        };
        // Snap within SNAP_PX pixels at the hit's depth.
        let pane = &self.panes[self.active];
        let depth = (hit.point - pane.nav.eye).dot(pane.nav.forward());
        let px =
            crate::nav::world_per_pixel(pane.nav.fov_y_rad, depth, f64::from(pane.view.size.1));
        let point = crate::measure::snap(&self.review.scene, &hit, SNAP_PX * px);
        let result = self.tools.measure.click(&mut self.review, point);
        Ok(match result {
            Some(m) => {
                self.ui.status = format!("measured {}", m.label());
                m.json(&self.review.scene)
            }
            None => to_value(FirstPoint {
                first: point.point.to_array(),
                snap: point.snap.name(),
            }),
        })
    }

    /// Frames the selection (or the point under `at`, picking it first).
    fn focus(&mut self, at: Option<ViewPoint>) -> anyhow::Result<()> {
        if let Some(at) = at {
            self.pick(at)?;
        }
        if let Some(part) = self.review.selected {
            let bounds = self.review.scene.part_world_bounds(part);
            self.frame_in_active(&bounds);
        }
        Ok(())
    }

    /// The part under a view point, for the hover tint (nothing while a
    /// primary drag goes on).
    pub(super) fn hover(&mut self, at: Option<(usize, ViewPoint)>) {
        if self.export.is_some() {
            return;
        }
        self.tools.gizmo_hot =
            at.and_then(|(pane, (x, y))| self.gizmo(pane)?.handle_at(glam::DVec2::new(x, y)));
        self.hovered = match at {
            Some((pane, at)) if self.pointer_drag.is_none() && pane < self.panes.len() => {
                self.review.pick(&self.ray_in(pane, at)).map(|h| h.part)
            }
            _ => None,
        };
    }

    /// Applies the pointer and keys of this frame as commands: clicks,
    /// presses, drags, looking, panning, the wheel and walking.
    pub(super) fn apply_view_input(&mut self, input: &ViewInput, dt: f64) {
        // A press, drag or wheel makes its pane the active one (not while a
        // drag that began elsewhere goes on).
        if let Some(pane) = input.pane.filter(|&p| p < self.panes.len())
            && (self.pointer_drag.is_none() || input.drag_started.is_some())
        {
            self.apply(ViewCommand::ActivePane(pane));
        }
        if input.hover != self.pointer_at {
            self.pointer_at = input.hover;
            self.apply(ViewCommand::Hover(input.hover));
        }
        if let Some(at) = input.double_clicked {
            self.apply(ViewCommand::Focus(Some(at)));
        } else if let Some(at) = input.clicked {
            self.apply(ViewCommand::Click(at));
        }
        if let Some(at) = input.drag_started {
            let axis = self.tools.drag_axis;
            self.apply(ViewCommand::Press { at, axis });
        }
        if let Some((at, delta)) = input.dragging {
            let free = input.free;
            self.apply(ViewCommand::PointerTo { at, delta, free });
        }
        if input.drag_stopped {
            self.apply(ViewCommand::Release);
        }
        if input.look != (0.0, 0.0) {
            self.apply(ViewCommand::Look(input.look));
        }
        if input.pan != (0.0, 0.0) {
            self.apply(ViewCommand::Pan(input.pan));
        }
        if let Some((wheel, at)) = input.wheel {
            self.apply(ViewCommand::Zoom { wheel, at });
        }
        if input.keys != Default::default() {
            let keys = input.keys;
            self.apply(ViewCommand::Walk { keys, dt });
        }
        if input.focus {
            self.apply(ViewCommand::Focus(None));
        }
        if input.frame_all {
            self.apply(ViewCommand::FrameAll);
        }
    }
}

#[cfg(test)]
mod tests;
