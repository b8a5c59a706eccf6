//! Automation scripts run one action per frame (a drag one step per frame),
//! each action the commands it stands for, applied as the panels' and the
//! pointer's are; each action's report entry is kept for the run's report.

use anyhow::Context as _;
use glam::DVec3;
use serde_json::Value;

use super::App;
use super::pointer::PointerDrag;
use super::report::{
    ClashesLoaded, FileEntry, PartEntry, SearchEntry, SearchedPart, selection_json, to_value,
};
use crate::command::{Outcome, ReviewCommand as R, ViewCommand as V, ViewPoint};
use crate::measure::MeasureMode;
use crate::script::Action;

/// Frames drawn before a script starts, so the layout (and the 3D view's size)
/// has settled.
const WARMUP_FRAMES: u64 = 3;

/// The script's progress.
#[derive(Debug, Default)]
pub(super) struct Runner {
    actions: Vec<Action>,
    /// Action being run and its step.
    index: usize,
    step: u32,
    /// One result per finished action, as compact JSON text (see `frames`).
    pub(super) results: Vec<Box<str>>,
    /// One record per frame while the script runs, as compact JSON text: a
    /// record held as a `Value` took ten times as much (its maps' nodes and
    /// keys), 17 kB a frame, which over a soak's thousands of frames was
    /// most of what the process grew by (issue 48).
    pub(super) frames: Vec<Box<str>>,
    /// Where the running gizmo or section drag pressed (view pixels).
    gizmo_from: ViewPoint,
}

impl Runner {
    /// Runs `actions`.
    pub(super) fn new(actions: Vec<Action>) -> Self {
        Self {
            actions,
            ..Self::default()
        }
    }
}

/// The view point through the centre of pixel `[x, y]`, where scripts aim.
fn centre([x, y]: [f64; 2]) -> ViewPoint {
    (x + 0.5, y + 0.5)
}

impl App {
    /// Runs the script's current action for this frame; the action's name
    /// and step, for the frame's record.
    pub(super) fn script_frame(&mut self) -> anyhow::Result<Option<(&'static str, u32)>> {
        if self.frames_drawn < WARMUP_FRAMES || self.export.is_some() {
            return Ok(None);
        }
        let Some(action) = self.runner.actions.get(self.runner.index).cloned() else {
            return Ok(None);
        };
        let step = self.runner.step;
        let result = self.script_step(&action, step)?;
        if let Some(e) = self.review.record_error.take() {
            anyhow::bail!("{}: {e}", action.name());
        }
        self.runner.step += 1;
        if self.runner.step >= action.frames() {
            let mut entry = result.unwrap_or_else(|| Value::Object(Default::default()));
            entry["action"] = Value::from(action.name());
            self.runner.results.push(entry.to_string().into_boxed_str());
            self.runner.index += 1;
            self.runner.step = 0;
        }
        Ok(Some((action.name(), step)))
    }

    /// Step `step` of `action`: the commands it stands for, applied; its
    /// report entry, where it has one.
    fn script_step(&mut self, action: &Action, step: u32) -> anyhow::Result<Option<Value>> {
        Ok(match action {
            Action::Pick(p) => self.apply_view(V::Pick(centre(*p)))?,
            Action::Select(key) => {
                let part = self.review.scene.find_part(key)?;
                self.apply_view(V::Reveal(part))?;
                Some(to_value(PartEntry {
                    part_id: Some(part.0),
                }))
            }
            Action::Search(text) => {
                let scene = &self.review.scene;
                let found = self.ui.search(scene, text);
                Some(to_value(SearchEntry {
                    count: found.len(),
                    parts: found
                        .iter()
                        .take(100)
                        .map(|&p| SearchedPart {
                            part_id: p.0,
                            name: scene.part_name(p),
                            properties: scene.node_properties(scene.part(p).node).collect(),
                        })
                        .collect(),
                }))
            }
            Action::Move(d) => {
                let moved = self.edit(R::Translate(DVec3::from_array(*d)))?;
                anyhow::ensure!(moved == Outcome::Acted(true), "move: nothing is selected");
                Some(selection_json(&self.review))
            }
            Action::Rotate(r) => {
                let (axis, degrees) = (r.axis.unit(), r.degrees);
                let turned = self.edit(R::Rotate { axis, degrees })?;
                anyhow::ensure!(
                    turned == Outcome::Acted(true),
                    "rotate: nothing is selected"
                );
                Some(selection_json(&self.review))
            }
            Action::Drag(d) => {
                if step == 0 {
                    let began = self.edit(R::BeginDrag)?;
                    anyhow::ensure!(began == Outcome::Acted(true), "drag: nothing is selected");
                }
                let steps = d.steps.max(1);
                let t = f64::from(step + 1) / f64::from(steps);
                self.edit(R::DragTo(DVec3::from_array(d.by) * t))?;
                if step + 1 < steps {
                    return Ok(None);
                }
                self.edit(R::EndDrag)?;
                Some(selection_json(&self.review))
            }
            Action::MouseDrag(d) => {
                let steps = d.steps.max(1);
                let (from, to) = (centre(d.from), centre(d.to));
                let at = |i: u32| {
                    let t = f64::from(i) / f64::from(steps);
                    (from.0 + (to.0 - from.0) * t, from.1 + (to.1 - from.1) * t)
                };
                if step == 0 {
                    let axis = Some(d.axis);
                    self.apply_view(V::Press { at: from, axis })?;
                    anyhow::ensure!(
                        matches!(self.pointer_drag, Some(PointerDrag::Part { .. })),
                        "mouse_drag: the press at {:?} is not on the selected part",
                        d.from
                    );
                } else {
                    let (prev, now) = (at(step - 1), at(step));
                    let delta = (now.0 - prev.0, now.1 - prev.1);
                    self.apply_view(V::PointerTo {
                        at: now,
                        delta,
                        free: false,
                    })?;
                }
                self.script_release(step, steps)?
                    .then(|| selection_json(&self.review))
            }
            Action::SectionDrag(d) => {
                if step == 0 {
                    let pane = &self.panes[self.active];
                    let projector =
                        crate::gizmo::Projector::new(&pane.nav.camera(), pane.view.size);
                    let (point, _) = *self
                        .review
                        .section
                        .handles(&self.review.tree.bounds())
                        .get(d.handle)
                        .with_context(|| format!("section_drag: no section handle {}", d.handle))?;
                    let from = projector
                        .project(point)
                        .context("section_drag: the handle is behind the eye")?;
                    self.script_press((from.x, from.y))?;
                    anyhow::ensure!(
                        matches!(self.pointer_drag, Some(PointerDrag::Section { index, .. }) if index == d.handle),
                        "section_drag: the press at {from} does not grab handle {} (are the tools' drawings hidden?)",
                        d.handle
                    );
                } else {
                    self.script_pointer_step(step, d.steps, d.by, false)?;
                }
                self.script_release(step, d.steps.max(1))?
                    .then(|| self.review.section.json())
            }
            Action::GizmoDrag(d) => {
                if step == 0 {
                    let g = self.gizmo(self.active).context(
                        "gizmo_drag: nothing is selected, or the gizmo is hidden or behind the eye",
                    )?;
                    let from = match d.from {
                        Some([x, y]) => glam::DVec2::new(x + 0.5, y + 0.5),
                        None => g
                            .grab_point(d.handle)
                            .context("gizmo_drag: the handle is off screen")?,
                    };
                    self.script_press((from.x, from.y))?;
                    anyhow::ensure!(
                        matches!(self.pointer_drag, Some(PointerDrag::Gizmo(g)) if g.handle == d.handle),
                        "gizmo_drag: the press at {from} does not grab the {:?} handle",
                        d.handle
                    );
                } else {
                    self.script_pointer_step(step, d.steps, d.by, d.free)?;
                }
                self.script_release(step, d.steps.max(1))?
                    .then(|| selection_json(&self.review))
            }
            Action::Snap(s) => {
                let (step, degrees) = (s.step, s.degrees);
                self.edit(R::Snap { step, degrees })?;
                None
            }
            Action::Gizmo(show) => {
                self.edit(R::ShowGizmo(*show))?;
                None
            }
            Action::SectionPlane(p) => {
                let (point, normal) = (DVec3::from_array(p.point), DVec3::from_array(p.normal));
                self.edit(R::SectionPlane { point, normal })?;
                Some(self.review.section.json())
            }
            Action::SectionFace(p) => {
                self.edit(R::SectionOnFace(true))?;
                self.apply_view(V::Click(centre(*p)))?
            }
            Action::SectionBox(b) => {
                let (min, max) = (DVec3::from_array(b.min), DVec3::from_array(b.max));
                self.edit(R::SectionBox { min, max })?;
                Some(self.review.section.json())
            }
            Action::ClearSection => {
                self.edit(R::Section(crate::section::Section::Off))?;
                None
            }
            Action::Measure(m) => {
                anyhow::ensure!(
                    m.mode != MeasureMode::Off,
                    "measure: mode \"off\" measures nothing (give points, parts or angle)"
                );
                self.edit(R::MeasureMode(m.mode))?;
                let mut last = None;
                for p in m.at {
                    let hit = self.apply_view(V::Click(centre(p)))?;
                    anyhow::ensure!(
                        hit.as_ref().is_some_and(|h| h["hit"] != false),
                        "measure: the click at {p:?} hits no part"
                    );
                    last = hit;
                }
                last
            }
            Action::MeasureParts([a, b]) => {
                let scene = &self.review.scene;
                let (a, b) = (scene.find_part(a)?, scene.find_part(b)?);
                self.edit(R::MeasureParts(a, b))?;
                let m = self.tools.measure.result.as_ref();
                m.map(|m| m.json(&self.review.scene))
            }
            Action::LoadClashes(path) => {
                let before = self.review.clash_list.len();
                self.edit(R::LoadClashes(path.clone()))?;
                let listed = self.review.clash_list.len();
                Some(to_value(ClashesLoaded {
                    added: listed - before,
                    listed,
                }))
            }
            Action::ShowClash(i) => self.apply_view(V::ShowClash(*i))?,
            Action::ExportBcf(path) => self.apply_view(V::ExportBcf(path.clone()))?,
            Action::ImportBcf(path) => self.apply_view(V::ImportBcf(path.clone()))?,
            Action::SaveViewpoint(name) => self.apply_view(V::SaveViewpoint(name.clone()))?,
            Action::Viewpoint(name) => self.apply_view(V::GoTo(name.clone()))?,
            Action::Hover(p) => self.apply_view(V::Hover(Some((self.active, centre(*p)))))?,
            Action::View(preset) => self.apply_view(V::Preset(*preset))?,
            Action::Camera(c) => {
                let (eye, forward) = (DVec3::from_array(c.eye), DVec3::from_array(c.forward));
                self.apply_view(V::Camera { eye, forward })?
            }
            Action::Panes(n) => self.apply_view(V::Panes(*n))?,
            Action::Pane(i) => self.apply_view(V::ActivePane(*i))?,
            Action::Record(path) => {
                self.edit(R::Record(path.clone()))?;
                None
            }
            Action::Clearance(c) => {
                self.edit(R::Clearance(*c))?;
                None
            }
            Action::Occlusion(o) => self.apply_view(V::Occlusion(*o))?,
            Action::Undo | Action::Redo => {
                let command = if *action == Action::Undo {
                    R::Undo
                } else {
                    R::Redo
                };
                let part = match self.edit(command)? {
                    Outcome::Part(part) => part,
                    other => unreachable!("undo and redo name a part, not {other:?}"),
                };
                Some(to_value(PartEntry {
                    part_id: part.map(|p| p.0),
                }))
            }
            Action::Focus => self.apply_view(V::Focus(None))?,
            Action::FrameAll => self.apply_view(V::FrameAll)?,
            Action::Culling(name) => {
                let culling = crate::script::culling_from_name(name).context("culling mode")?;
                self.apply_view(V::Culling(culling))?
            }
            Action::PaintWhole(whole) => self.apply_view(V::PaintWhole(*whole))?,
            Action::Overlays(o) => {
                self.edit(R::Overlays(*o))?;
                None
            }
            Action::Frames(_) => None,
            Action::Screenshot(path) => self.apply_view(V::Screenshot(path.clone()))?,
            Action::Save(path) => match self.edit(R::Save(path.clone()))? {
                Outcome::Saved(saved) => Some(to_value(FileEntry {
                    path: &saved.path,
                    topics: None,
                    format: Some(saved.format),
                })),
                other => unreachable!("a save says what it wrote, not {other:?}"),
            },
        })
    }

    /// A scripted drag's press at `at` (view pixels), kept for its steps.
    fn script_press(&mut self, at: ViewPoint) -> anyhow::Result<()> {
        self.runner.gizmo_from = at;
        self.apply_view(V::Press { at, axis: None })?;
        Ok(())
    }

    /// Step `step` (from 1) of `steps` of a scripted drag that moves the
    /// pointer by `by` pixels from where it pressed.
    fn script_pointer_step(
        &mut self,
        step: u32,
        steps: u32,
        by: [f64; 2],
        free: bool,
    ) -> anyhow::Result<()> {
        let steps = steps.max(1);
        let (t, prev) = (
            f64::from(step) / f64::from(steps),
            f64::from(step - 1) / f64::from(steps),
        );
        let (x, y) = self.runner.gizmo_from;
        let at = (x + by[0] * t, y + by[1] * t);
        let delta = ((t - prev) * by[0], (t - prev) * by[1]);
        self.apply_view(V::PointerTo { at, delta, free })?;
        Ok(())
    }

    /// Releases a scripted pointer drag at its last step; whether it did.
    fn script_release(&mut self, step: u32, steps: u32) -> anyhow::Result<bool> {
        if step != steps {
            return Ok(false);
        }
        self.apply_view(V::Release)?;
        Ok(true)
    }

    pub(super) fn script_done(&self) -> bool {
        self.runner.index >= self.runner.actions.len()
    }
}
